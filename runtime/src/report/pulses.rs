//! Exact pulse times and positions (program.rs gives the semantics): in `Distance` mode one
//! pulse at the start of each lit section and every `pitch_mm` of lit path after it; in `Time`
//! mode the same every `period_s` of lit time. The instant a distance is reached is solved on
//! the plan's closed-form path law, to 1e-12 s.

use super::{dwell_lit, segment_laser, standstills};
use crate::motion::Job;
use crate::planner::Segment;
use crate::program::{OpKind, P3, Pulse, PulseMode};

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

/// A lit section on the plan's timeline: segments `first..=last`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Section {
    pub first: usize,
    pub last: usize,
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

/// Lit sections with pulses, in time order.
pub(super) fn sections(job: &Job) -> Vec<Section> {
    let segs = job.plan.segments();
    let mut out = Vec::new();
    let mut i = 0;
    while i < segs.len() {
        let Some(Pulse { mode, .. }) = segment_laser(job, i).and_then(|l| l.pulse.as_ref()) else {
            i += 1;
            continue;
        };
        let pulse = segment_laser(job, i).and_then(|l| l.pulse.as_ref());
        let mut last = i;
        while dwell_lit(job, last)
            && segment_laser(job, last + 1).and_then(|l| l.pulse.as_ref()) == pulse
        {
            last += 1;
        }
        let end: &Segment = &segs[last];
        out.push(Section {
            first: i,
            last,
            mode: *mode,
            t0: segs[i].t_start,
            t1: end.t_start + end.motion_duration(),
            s0: segs[i].s_start,
            s1: end.s_start + end.length,
        });
        i = last + 1;
    }
    out
}

/// The pulses of a job, in time order. Lazy: a texturing job's millions of pulses are never
/// stored (dot-mode windows, which need an op each, are).
pub fn pulse_events(job: &Job) -> PulseEvents<'_> {
    PulseEvents {
        job,
        fires: fire_events(job),
        fire: 0,
        pending: None,
        sections: sections(job),
        section: 0,
        k: 0,
        seg: 0,
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
        for k in 0..*count {
            out.push(PulseEvent {
                t: st.t + f64::from(k) * period_s,
                s,
                pos,
                op: st.op as u32,
            });
        }
    }
    out
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
    sections: Vec<Section>,
    section: usize,
    /// Index of the next pulse in the current section.
    k: u64,
    /// Segment cursor (targets grow monotonically within a section).
    seg: usize,
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
        loop {
            let sec = *self.sections.get(self.section)?;
            if self.k == 0 {
                self.seg = sec.first;
            }
            if self.k >= sec.count() {
                self.section += 1;
                self.k = 0;
                continue;
            }
            let k = self.k as f64;
            self.k += 1;
            let segs = self.job.plan.segments();
            let (i, t_local) = match sec.mode {
                PulseMode::Distance { pitch_mm } => {
                    let target = (sec.s0 + k * pitch_mm).min(sec.s1);
                    while self.seg < sec.last
                        && segs[self.seg].s_start + segs[self.seg].length < target
                    {
                        self.seg += 1;
                    }
                    let seg = &segs[self.seg];
                    (self.seg, solve_s(seg, target - seg.s_start))
                }
                PulseMode::Time { period_s } => {
                    let t = (sec.t0 + k * period_s).min(sec.t1);
                    while self.seg < sec.last && segs[self.seg].t_end() <= t {
                        self.seg += 1;
                    }
                    (self.seg, t - segs[self.seg].t_start)
                }
            };
            let sample = self.job.plan.sample_segment(i, t_local);
            let spot = self.job.spot(&sample.pos, sample.tag);
            return Some(PulseEvent {
                t: self.job.initial_dwell_s + sample.t,
                s: sample.s,
                pos: [spot[0], spot[1], spot[2]],
                op: segs[i].tag,
            });
        }
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
