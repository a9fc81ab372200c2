//! What a planned job does, for people and for tests: the plan summary (JSON), a sampled trace
//! (CSV), a plot (SVG) and the exact pulse positions.
//!
//! Everything here reads a [`Job`] and nothing else: the plan's segments give exact times,
//! speeds and peaks; the program's ops (by each segment's tag) say which moves are lit.
//!
//! Times are on the job's timeline: 0 is the program start, so the plan's time 0 lies
//! `job.initial_dwell_s` later (dwells and events before the first move).
//!
//! Laser model (the same as `emit`'s): the beam is on during the motion of lit moves and
//! during a dwell that sits between two lit moves; it is off during rapids, unlit moves and
//! every other standstill. A lit section is a maximal run of consecutive lit moves with the
//! same pulse setting; pulses are counted from the start of each section.

mod plot;
mod pulses;
mod summary;
mod trace;

pub use plot::{DOT_LIMIT, PNG_SCALE, PlotOptions, SpeedUnit, plot_png, plot_svg, svg_to_png};
pub use pulses::{PulseEvent, PulseEvents, PulseStream, PulseTime, pulse_events, write_pulses};
pub use summary::{
    AxisPeaks, ControllerCycle, PlanTotals, Summary, TimeSplit, summarize, time_split,
};
pub use trace::write_trace;

use crate::motion::Job;
use crate::planner::{Sample, Segment};
use crate::program::{Laser, OpKind, ProcessProgram};

/// The laser setting of segment `i`'s move (None when unlit or out of range).
fn segment_laser(job: &Job, i: usize) -> Option<&Laser> {
    let seg = job.plan.segments().get(i)?;
    job.program.ops.get(seg.tag as usize)?.laser()
}

/// Whether segment `i`'s move is a rapid.
fn segment_is_rapid(job: &Job, i: usize) -> bool {
    job.plan
        .segments()
        .get(i)
        .and_then(|s| job.program.ops.get(s.tag as usize))
        .is_some_and(|op| matches!(op.kind, OpKind::Rapid { .. }))
}

/// Whether the beam stays on through the dwell after segment `i` (it sits between two lit
/// moves).
fn dwell_lit(job: &Job, i: usize) -> bool {
    segment_laser(job, i).is_some() && segment_laser(job, i + 1).is_some()
}

/// Whether the beam is on at `t_local` after the start of segment `i`. Lit intervals are
/// half-open, so the instant a lit run ends counts as off.
fn lit_at(job: &Job, i: usize, t_local: f64) -> bool {
    let Some(seg) = job.plan.segments().get(i) else {
        return false;
    };
    if segment_laser(job, i).is_none() {
        return false;
    }
    t_local < seg.motion_duration() || (dwell_lit(job, i) && t_local < seg.duration())
}

/// The plan's state at job time `t`, whether the beam is on, and its power in W (0 when off;
/// `P_set · v / F` when the laser is coupled to speed, PROCESS.md §1 eq. 1). Exact: what the
/// trace prints rounded.
pub fn beam_at(job: &Job, t: f64) -> (Sample, bool, f64) {
    let t_plan = t - job.initial_dwell_s;
    let sample = job.plan.sample(t_plan.max(0.0));
    let segs = job.plan.segments();
    let lit = t_plan >= 0.0
        && !segs.is_empty()
        && lit_at(job, sample.segment, sample.t - segs[sample.segment].t_start);
    let power = match (lit, segs.get(sample.segment)) {
        (true, Some(seg)) => {
            segment_laser(job, sample.segment).map_or(0.0, |l| l.power_at(sample.v, seg.feed))
        }
        _ => 0.0,
    };
    (sample, lit, power)
}

/// A standstill op (dwell, M-function, machine event, dot-mode window) and when it begins.
#[derive(Debug, Clone, Copy)]
pub(super) struct Standstill {
    /// The op's index.
    pub op: usize,
    /// Job time at which it begins, s.
    pub t: f64,
    /// How long the machine stands for it, s (0 for an M-function).
    pub duration: f64,
}

/// How long the machine stands still for op `i` (0 for motion ops).
fn stand_s(program: &ProcessProgram, i: usize) -> f64 {
    match &program.ops[i].kind {
        OpKind::Dwell { seconds } => *seconds,
        OpKind::Fire { window_s, .. } => *window_s,
        OpKind::Event { name } => program.machine.events.get(name).map_or(0.0, |e| e.dwell_s),
        _ => 0.0,
    }
}

/// Whether op `op` is a standstill op ([`Standstill`]).
fn is_standstill(op: &crate::program::Op) -> bool {
    matches!(
        op.kind,
        OpKind::Dwell { .. } | OpKind::MCode { .. } | OpKind::Event { .. } | OpKind::Fire { .. }
    )
}

/// Every standstill op with its start time, in op order. A standstill begins when the motion
/// before it has ended and the standstills between (which the plan folds into that segment's
/// dwell, or into `initial_dwell_s` before the first move) have passed.
pub(super) fn standstills(job: &Job) -> Vec<Standstill> {
    let ops = &job.program.ops;
    let segs = job.plan.segments();
    let mut cursor = StandCursor::default();
    let mut out = Vec::new();
    for (i, op) in ops.iter().enumerate() {
        if !is_standstill(op) {
            continue;
        }
        let j = segs
            .partition_point(|s| (s.tag as usize) < i)
            .checked_sub(1);
        let before = j.map(|j| (j, &segs[j]));
        out.push(cursor.at(&job.program, i, before, job.initial_dwell_s));
    }
    out
}

/// The running sum behind [`standstills`], shared with the pulses of a plan made in windows
/// (`pulses::PulseStream`), which meets the standstills as their segments pass: consecutive
/// standstills after one segment continue the sum instead of summing from the segment again.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct StandCursor {
    /// The segment before, the next op not yet summed and the time reached.
    at: Option<(Option<usize>, usize, f64)>,
}

impl StandCursor {
    /// Standstill op `i` of `program`, after segment `before` (its index in the plan and the
    /// segment: the last one with a lower tag; `None` before the first move), on a plan whose
    /// time 0 is `initial_dwell_s` into the job.
    pub(super) fn at(
        &mut self,
        program: &ProcessProgram,
        i: usize,
        before: Option<(usize, &Segment)>,
        initial_dwell_s: f64,
    ) -> Standstill {
        let j = before.map(|(j, _)| j);
        let (from, t) = match self.at {
            Some((cj, next, t)) if cj == j => (next, t),
            _ => match before {
                Some((_, seg)) => (
                    seg.tag as usize + 1,
                    initial_dwell_s + seg.t_start + seg.motion_duration(),
                ),
                None => (0, 0.0),
            },
        };
        let t = t + (from..i).map(|k| stand_s(program, k)).sum::<f64>();
        let duration = stand_s(program, i);
        self.at = Some((j, i + 1, t + duration));
        Standstill { op: i, t, duration }
    }

    /// Where the standstills summed so far end, before the first move: the job's
    /// `initial_dwell_s` once every op before the first move was summed (`motion`'s lowering
    /// adds the same durations in the same order).
    pub(super) fn end_before_motion(&self) -> f64 {
        match self.at {
            Some((None, _, t)) => t,
            _ => 0.0,
        }
    }
}

/// Rounds to 9 significant digits, so goldens do not change with the last bits of a platform's
/// libm.
pub fn round_sig(x: f64) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    let r: f64 = format!("{x:.8e}").parse().unwrap_or(x);
    if r == 0.0 { 0.0 } else { r }
}

/// A number with at most 6 decimals, trailing zeros trimmed, never `-0`.
fn fixed6(x: f64) -> String {
    let mut s = format!("{x:.6}");
    if s.contains('.') {
        let t = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(t);
    }
    if s == "-0" { "0".to_string() } else { s }
}
