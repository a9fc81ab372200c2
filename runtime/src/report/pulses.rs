//! Exact pulse times and positions (program.rs gives the semantics): in `Distance` mode one
//! pulse at the start of each lit section and every `pitch_mm` of lit path after it; in `Time`
//! mode the same every `period_s` of lit time. The instant a distance is reached is solved on
//! the plan's closed-form path law, to 1e-12 s.
//!
//! One generator serves a whole plan ([`pulse_events`]) and a plan made in windows
//! ([`PulseStream`]: `emit`'s pulse budget, issue 18): [`SectionCursor`] walks the lit sections'
//! pulses segment by segment, each segment read once the one after it is known (whether the
//! beam stays on into it), and `StandCursor` times the dot-mode windows as their ops pass.

use super::{StandCursor, Standstill, is_standstill, segment_laser, standstills};
use crate::motion::Job;
use crate::planner::{Plan, Segment};
use crate::program::{Laser, OpKind, P3, ProcessProgram, Pulse, PulseMode};
use std::collections::VecDeque;

/// One laser pulse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PulseEvent {
    /// Job time, s (the plan's time plus `job.initial_dwell_s`).
    pub t: f64,
    /// Path distance from the program start, mm.
    pub s: f64,
    /// Spot position, part coordinates, mm.
    pub pos: P3,
    /// The op whose move fires it.
    pub op: u32,
}

/// A lit section on the plan's timeline.
#[derive(Debug, Clone, Copy)]
pub(super) struct Section {
    pub mode: PulseMode,
    /// Plan time of the start and of the end of the beam-on interval.
    pub t0: f64,
    pub t1: f64,
    /// Path distance at the start and at the end.
    pub s0: f64,
    pub s1: f64,
}

impl Section {
    /// Pulses in the section: k = 0, 1, … while the k-th stays within it. The slack keeps a
    /// pulse that lands on the end by construction (10 mm, 1 mm pitch: 11 pulses) from being
    /// lost to rounding.
    pub fn count(&self) -> u64 {
        let (span, step) = match self.mode {
            PulseMode::Distance { pitch_mm } => (self.s1 - self.s0, pitch_mm),
            PulseMode::Time { period_s } => (self.t1 - self.t0, period_s),
        };
        if !(step > 0.0) || !step.is_finite() || !(span >= 0.0) {
            return 1;
        }
        ((span / step) * (1.0 + 1e-12) + 1e-9).floor() as u64 + 1
    }
}

/// The pulses of each lit section, read segment by segment in plan order (module doc): a
/// section opens at a lit segment with a pulse setting and goes on while the beam stays on into
/// a segment with the same one (`report`'s laser model); pulse k of a section lies on the first
/// of its segments that reaches it (`Distance`: its path distance, `Time`: its time), or on its
/// last.
#[derive(Debug, Default)]
pub(super) struct SectionCursor {
    open: Option<Open>,
}

/// The section being read.
#[derive(Debug)]
struct Open {
    pulse: Pulse,
    /// Plan time and path distance where it starts.
    t0: f64,
    s0: f64,
    /// Index of the next pulse.
    k: u64,
    /// Once the segment being read is its last: where it ends (time, distance) and its pulses.
    end: Option<(f64, f64, u64)>,
}

impl SectionCursor {
    /// Segment `seg` is read next: lit with `laser`, and the one after it with `next`.
    pub(super) fn enter(&mut self, seg: &Segment, laser: Option<&Laser>, next: Option<&Laser>) {
        if self.open.is_none()
            && let Some(p) = laser.and_then(|l| l.pulse.as_ref())
        {
            self.open = Some(Open {
                pulse: p.clone(),
                t0: seg.t_start,
                s0: seg.s_start,
                k: 0,
                end: None,
            });
        }
        if let Some(o) = &mut self.open {
            let goes_on = laser.is_some() && next.and_then(|l| l.pulse.as_ref()) == Some(&o.pulse);
            if !goes_on {
                let (t1, s1) = (
                    seg.t_start + seg.motion_duration(),
                    seg.s_start + seg.length,
                );
                let count = Section {
                    mode: o.pulse.mode,
                    t0: o.t0,
                    t1,
                    s0: o.s0,
                    s1,
                }
                .count();
                o.end = Some((t1, s1, count));
            }
        }
    }

    /// The next pulse on `seg`, the segment last entered: its time after the segment's start
    /// (what `Plan::sample_segment` takes). `None` once the segment has no more.
    pub(super) fn next(&mut self, seg: &Segment) -> Option<f64> {
        let o = self.open.as_mut()?;
        let k = o.k as f64;
        let t_local = match (o.pulse.mode, o.end) {
            (mode, Some((t1, s1, count))) => {
                if o.k >= count {
                    self.open = None;
                    return None;
                }
                match mode {
                    PulseMode::Distance { pitch_mm } => {
                        solve_s(seg, (o.s0 + k * pitch_mm).min(s1) - seg.s_start)
                    }
                    PulseMode::Time { period_s } => (o.t0 + k * period_s).min(t1) - seg.t_start,
                }
            }
            (PulseMode::Distance { pitch_mm }, None) => {
                let target = o.s0 + k * pitch_mm;
                if seg.s_start + seg.length < target {
                    return None;
                }
                solve_s(seg, target - seg.s_start)
            }
            (PulseMode::Time { period_s }, None) => {
                let t = o.t0 + k * period_s;
                if seg.t_end() <= t {
                    return None;
                }
                t - seg.t_start
            }
        };
        o.k += 1;
        Some(t_local)
    }
}

/// The pulses of a job, in time order. Lazy: a texturing job's millions of pulses are never
/// stored (dot-mode windows, which need an op each, are).
pub fn pulse_events(job: &Job) -> PulseEvents<'_> {
    PulseEvents {
        job,
        fires: fire_events(job),
        fire: 0,
        pending: None,
        cursor: SectionCursor::default(),
        seg: None,
    }
}

/// Writes every pulse of `job` as CSV, streamed: `t,px,py,pz,v,op` — job time (s), the spot
/// (part coordinates, mm), the path speed when it fires (mm/s; 0 in a dot-mode window) and
/// the op that fires it. Numbers with 9 decimals (1 nm, 1 ns), so tests can measure with them.
pub fn write_pulses(job: &Job, out: &mut dyn std::io::Write) -> std::io::Result<()> {
    out.write_all(b"t,px,py,pz,v,op\n")?;
    for p in pulse_events(job) {
        let v = if matches!(
            job.program.ops.get(p.op as usize).map(|o| &o.kind),
            Some(OpKind::Fire { .. })
        ) {
            0.0
        } else {
            job.plan.sample((p.t - job.initial_dwell_s).max(0.0)).v
        };
        writeln!(
            out,
            "{:.9},{:.9},{:.9},{:.9},{:.9},{}",
            p.t, p.pos[0], p.pos[1], p.pos[2], v, p.op
        )?;
    }
    Ok(())
}

/// Pulses of dot-mode fire windows (`OpKind::Fire`): the window opens when the motion before
/// it has ended and the standstills between (dwells, events, earlier windows) have passed;
/// pulse k fires `k · period_s` later, where the spot stands.
pub(super) fn fire_events(job: &Job) -> Vec<PulseEvent> {
    let ops = &job.program.ops;
    let segs = job.plan.segments();
    let mut out = Vec::new();
    for st in standstills(job) {
        let OpKind::Fire {
            count, period_s, ..
        } = &ops[st.op].kind
        else {
            continue;
        };
        let j = segs.partition_point(|s| (s.tag as usize) < st.op);
        let (s, q, tag) = match j.checked_sub(1) {
            Some(j) => (
                segs[j].s_start + segs[j].length,
                job.plan.segment_target(j),
                segs[j].tag,
            ),
            None => (0.0, job.start, 0),
        };
        let pos = job.spot(&q, tag);
        for t in fire_times(&st, *count, *period_s) {
            out.push(PulseEvent {
                t,
                s,
                pos,
                op: st.op as u32,
            });
        }
    }
    out
}

/// The job times of the pulses of a dot-mode window that begins at `st`: pulse k fires
/// `k · period_s` after it opens.
fn fire_times(st: &Standstill, count: u32, period_s: f64) -> impl Iterator<Item = f64> {
    let t = st.t;
    (0..count).map(move |k| t + f64::from(k) * period_s)
}

/// Iterator of [`pulse_events`].
#[derive(Debug)]
pub struct PulseEvents<'j> {
    job: &'j Job,
    /// Dot-mode pulses, merged into the stream by time.
    fires: Vec<PulseEvent>,
    fire: usize,
    /// The next pulse of the lit sections, taken but not yet returned.
    pending: Option<PulseEvent>,
    cursor: SectionCursor,
    /// The segment the cursor reads.
    seg: Option<usize>,
}

impl Iterator for PulseEvents<'_> {
    type Item = PulseEvent;

    fn next(&mut self) -> Option<PulseEvent> {
        if self.pending.is_none() {
            self.pending = self.next_in_section();
        }
        match (self.pending, self.fires.get(self.fire)) {
            (Some(p), Some(f)) if f.t < p.t => {
                self.fire += 1;
                Some(*f)
            }
            (Some(p), _) => {
                self.pending = None;
                Some(p)
            }
            (None, Some(f)) => {
                self.fire += 1;
                Some(*f)
            }
            (None, None) => None,
        }
    }
}

impl PulseEvents<'_> {
    fn next_in_section(&mut self) -> Option<PulseEvent> {
        let segs = self.job.plan.segments();
        loop {
            if let Some(i) = self.seg
                && let Some(t_local) = self.cursor.next(&segs[i])
            {
                let sample = self.job.plan.sample_segment(i, t_local);
                let spot = self.job.spot(&sample.pos, sample.tag);
                return Some(PulseEvent {
                    t: self.job.initial_dwell_s + sample.t,
                    s: sample.s,
                    pos: [spot[0], spot[1], spot[2]],
                    op: segs[i].tag,
                });
            }
            let i = self.seg.map_or(0, |i| i + 1);
            let seg = segs.get(i)?;
            let (laser, next) = (segment_laser(self.job, i), segment_laser(self.job, i + 1));
            self.cursor.enter(seg, laser, next);
            self.seg = Some(i);
        }
    }
}

/// A pulse's job time and the op that fires it: what `emit`'s pulse budget reads of a pulse.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PulseTime {
    pub t: f64,
    pub op: u32,
}

/// The pulses of a plan made in windows (`motion::plan_program_windows`), handed on in the
/// order and with the times of [`pulse_events`] as the windows pass, none kept but the dot-mode
/// pulses that wait for a later lit pulse to be merged by time. Feed it every window with
/// [`window`](Self::window), then [`finish`](Self::finish).
#[derive(Debug, Default)]
pub struct PulseStream {
    cursor: SectionCursor,
    stand: StandCursor,
    /// The segment waiting for the next one (whether the beam stays on into it), its number.
    waiting: Option<(Segment, usize)>,
    seen: usize,
    /// Ops below this one have had their standstills timed.
    next_op: usize,
    /// The job's standstill before its first move, once the first segment was read.
    initial_dwell_s: f64,
    /// Dot-mode pulses not yet handed on: each waits for the first lit pulse later than it
    /// (`PulseEvents`' merge gives a lit pulse at the same time first).
    fires: VecDeque<PulseTime>,
}

impl PulseStream {
    pub fn new() -> PulseStream {
        PulseStream::default()
    }

    /// Reads a window of `program`'s plan (its segments in order, after the last window's),
    /// handing each pulse that is due to `each`.
    pub fn window(
        &mut self,
        program: &ProcessProgram,
        plan: &Plan,
        each: &mut dyn FnMut(PulseTime),
    ) {
        for seg in plan.segments() {
            if let Some((prev, at)) = self.waiting.take() {
                self.read(program, &prev, at, Some(seg), each);
            }
            self.waiting = Some((*seg, self.seen));
            self.seen += 1;
        }
    }

    /// After the last window: the last segment's pulses and every dot-mode pulse left.
    pub fn finish(&mut self, program: &ProcessProgram, each: &mut dyn FnMut(PulseTime)) {
        match self.waiting.take() {
            Some((prev, at)) => self.read(program, &prev, at, None, each),
            // No motion at all: every standstill comes before the first move.
            None => self.stand_until(program, None, program.ops.len()),
        }
        for f in self.fires.drain(..) {
            each(f);
        }
    }

    /// Reads segment `seg` (number `at`), `next` the one after it: first the standstills
    /// before it (before the first move only) and after it, whose dot-mode pulses may come
    /// before its own, then its lit pulses, each after the dot-mode pulses earlier than it.
    fn read(
        &mut self,
        program: &ProcessProgram,
        seg: &Segment,
        at: usize,
        next: Option<&Segment>,
        each: &mut dyn FnMut(PulseTime),
    ) {
        if at == 0 {
            self.stand_until(program, None, seg.tag as usize);
            self.initial_dwell_s = self.stand.end_before_motion();
        }
        self.next_op = self.next_op.max(seg.tag as usize + 1);
        let end = next.map_or(program.ops.len(), |n| n.tag as usize);
        self.stand_until(program, Some((at, seg)), end);
        let laser = |s: &Segment| program.ops.get(s.tag as usize).and_then(|o| o.laser());
        self.cursor.enter(seg, laser(seg), next.and_then(laser));
        while let Some(t_local) = self.cursor.next(seg) {
            // `Plan::sample_segment`'s time.
            let t_local = if t_local.is_nan() {
                0.0
            } else {
                t_local.clamp(0.0, seg.duration())
            };
            let t = self.initial_dwell_s + (seg.t_start + t_local);
            while let Some(f) = self.fires.front().copied().filter(|f| f.t < t) {
                self.fires.pop_front();
                each(f);
            }
            each(PulseTime { t, op: seg.tag });
        }
    }

    /// Times the standstills of the ops from `next_op` up to `end` (after segment `before`),
    /// keeping the pulses of their dot-mode windows.
    fn stand_until(
        &mut self,
        program: &ProcessProgram,
        before: Option<(usize, &Segment)>,
        end: usize,
    ) {
        for i in self.next_op..end {
            let op = &program.ops[i];
            if !is_standstill(op) {
                continue;
            }
            let st = self.stand.at(program, i, before, self.initial_dwell_s);
            if let OpKind::Fire {
                count, period_s, ..
            } = op.kind
            {
                let op = i as u32;
                self.fires
                    .extend(fire_times(&st, count, period_s).map(|t| PulseTime { t, op }));
            }
        }
        self.next_op = self.next_op.max(end);
    }
}

/// The first local time at which the segment's path distance reaches `target` (clamped to
/// the motion), to 1e-12 s: Newton's method on s(t) − target, kept inside a bisection bracket
/// (s is non-decreasing, and v = 0 at rest points defeats plain Newton).
fn solve_s(seg: &Segment, target: f64) -> f64 {
    let motion = seg.motion_duration();
    if target <= 0.0 || motion <= 0.0 {
        return 0.0;
    }
    if target >= seg.length {
        // The earliest instant the end is reached is the end of the motion.
        return motion;
    }
    let (mut lo, mut hi) = (0.0, motion);
    let mut t = motion * target / seg.length;
    for _ in 0..200 {
        let (s, v, _, _) = seg.path_state(t);
        let f = s - target;
        if f < 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        if hi - lo <= 1e-12 || f.abs() <= v * 1e-13 {
            break;
        }
        let newton = if v > 0.0 { t - f / v } else { f64::NAN };
        t = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
    }
    t
}
