//! The plan summary: cycle time, lengths, laser time, pulse count and the peak axis speed,
//! acceleration and jerk, computed exactly from the plan's segments.

use super::pulses::sections;
use super::{dwell_lit, round_sig, segment_is_rapid, segment_laser};
use crate::axes::to_external;
use crate::motion::Job;
use crate::program::Ramp;
use serde::Serialize;
use std::collections::BTreeMap;

/// What a job does, in numbers. Serialized in this field order; numbers are rounded to 9
/// significant digits so goldens are stable across platforms.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    pub recipe: String,
    pub machine: String,
    pub ramp: Ramp,
    /// Job time including the standstill before the first move, s: lase's own plan, the
    /// one that places lead-ins, overscan and power coupling.
    pub cycle_time_s: f64,
    /// The cycle time of the controller that runs the program, by the model of its planner
    /// (`link::estimate`); `lase plan` fills it in, [`summarize`] alone does not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub controller: Option<ControllerCycle>,
    /// All motion, rapids included (the plan's path length), mm.
    pub path_length_mm: f64,
    pub rapid_length_mm: f64,
    pub laser_on_length_mm: f64,
    /// Beam-on time: lit motion plus dwells between lit moves, s.
    pub laser_on_time_s: f64,
    pub pulses: u64,
    /// Of `pulses`: fired while the spot moves (lit moves with a pulse setting) …
    pub pulses_moving: u64,
    /// … and fired at standstill (dot-mode windows), where no lit length or time accrues.
    pub pulses_standstill: u64,
    /// Gate time of the dot-mode windows, s (the spot stands; not in `laser_on_time_s`).
    pub standstill_fire_time_s: f64,
    /// Moves handed to the planner (arcs count once per chord).
    pub blocks: usize,
    /// Ops of the process program.
    pub ops: usize,
    /// Peaks reached per machine axis, by axis name.
    pub axes: BTreeMap<String, AxisPeaks>,
}

/// How long the controller that runs a job takes for it (issue 13): lase's plan is ideal, the
/// controller plans the NC program its own way.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ControllerCycle {
    /// The NC dialect the program is written in for it (`linuxcnc`, `grbl`, …).
    pub dialect: String,
    /// The model the time comes from, or `lase's own plan` where there is none.
    pub model: String,
    /// Its cycle time, s.
    pub cycle_time_s: f64,
    /// Its beam-on time, s, where the model tells it (LinuxCNC's).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub beam_on_s: Option<f64>,
    /// What the model counted (`34 segments, 6 stops`), for the text report.
    #[serde(skip)]
    pub detail: String,
    /// Why lase's own plan stands in for the controller: it has no model, or the model
    /// cannot run the program.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Peak magnitudes one axis reaches, in mm (deg for a rotary axis) per s, s², s³.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisPeaks {
    pub v_max: f64,
    pub a_max: f64,
    /// `None` (JSON `null`) for trapezoid ramps: their acceleration steps, so jerk is
    /// unbounded (a Dirac at every phase change).
    pub j_max: Option<f64>,
}

/// Pulses of the dot-mode fire windows and how long their gates are open in all.
fn fire_pulses(job: &Job) -> (u64, f64) {
    job.program
        .ops
        .iter()
        .fold((0, 0.0), |(n, t), o| match o.kind {
            crate::program::OpKind::Fire {
                count, window_s, ..
            } => (n + u64::from(count), t + window_s),
            _ => (n, t),
        })
}

/// Summarizes a planned job.
///
/// Axis peaks: along a straight move `q(s) = q0 + u·s`, so every axis quantity is `|u_k|`
/// times the path quantity, and the path peaks of a segment are its `v_peak`, its ramp
/// accelerations and, for an S-curve, the jerk `a_p / t_j` of its jerk phases. Speed jumps at
/// junctions (the corner model) are not counted as acceleration.
pub fn summarize(job: &Job) -> Summary {
    let plan = &job.plan;
    let machine = &job.program.machine;
    let segs = plan.segments();
    let scurve = job.program.planner.ramp == Ramp::Scurve;
    let n_axes = machine.axes.len();
    let mut v = vec![0.0f64; n_axes];
    let mut a = vec![0.0f64; n_axes];
    let mut j = vec![0.0f64; n_axes];
    let (mut rapid, mut lit_len, mut lit_time) = (0.0, 0.0, 0.0);
    for (i, seg) in segs.iter().enumerate() {
        if segment_is_rapid(job, i) {
            rapid += seg.length;
        }
        if segment_laser(job, i).is_some() {
            lit_len += seg.length;
            lit_time += seg.motion_duration();
            if dwell_lit(job, i) {
                lit_time += seg.dwell;
            }
        }
        let u = plan.direction(i);
        let acc = seg.accel_peak().max(seg.decel_peak());
        let jerk = {
            let up = if seg.t_j1 > 0.0 {
                seg.accel_peak() / seg.t_j1
            } else {
                0.0
            };
            let down = if seg.t_j2 > 0.0 {
                seg.decel_peak() / seg.t_j2
            } else {
                0.0
            };
            up.max(down)
        };
        for k in 0..n_axes {
            let uk = u[k].abs();
            v[k] = v[k].max(uk * seg.v_peak);
            a[k] = a[k].max(uk * acc);
            j[k] = j[k].max(uk * jerk);
        }
    }
    let axes = machine
        .axes
        .iter()
        .enumerate()
        .map(|(k, axis)| {
            let ext = |x: f64| round_sig(to_external(axis.kind, x));
            (
                axis.name.clone(),
                AxisPeaks {
                    v_max: ext(v[k]),
                    a_max: ext(a[k]),
                    j_max: scurve.then(|| ext(j[k])),
                },
            )
        })
        .collect();
    let moving = sections(job).iter().map(|s| s.count()).sum::<u64>();
    let (standstill, fire_time) = fire_pulses(job);
    Summary {
        recipe: job.program.recipe.clone(),
        machine: machine.name.clone(),
        ramp: job.program.planner.ramp,
        cycle_time_s: round_sig(job.cycle_time()),
        controller: None,
        path_length_mm: round_sig(plan.length()),
        rapid_length_mm: round_sig(rapid),
        laser_on_length_mm: round_sig(lit_len),
        laser_on_time_s: round_sig(lit_time),
        pulses: moving + standstill,
        pulses_moving: moving,
        pulses_standstill: standstill,
        standstill_fire_time_s: round_sig(fire_time),
        // One block per planned move: a move blended at its corners is up to three segments
        // (`planner::blend`), all with the move's index.
        blocks: job
            .plan
            .segments()
            .iter()
            .enumerate()
            .filter(|(i, s)| *i == 0 || job.plan.segments()[i - 1].move_index != s.move_index)
            .count(),
        ops: job.program.ops.len(),
        axes,
    }
}

/// Where a job's cycle time goes, s: lit motion (and dwells between lit moves), unlit motion
/// at a feed (a scan's overscan, lead-ins and -outs, the approach to a row), rapid travel, and
/// standstill (unlit dwells, stops, the wait before the first move). The four add up to the
/// cycle time. `lase plan` prints it, so a job whose time goes mostly to overscan shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeSplit {
    pub lit_s: f64,
    pub unlit_feed_s: f64,
    pub rapid_s: f64,
    pub still_s: f64,
}

impl TimeSplit {
    /// Unlit motion, feed and rapid.
    pub fn unlit_motion_s(&self) -> f64 {
        self.unlit_feed_s + self.rapid_s
    }
}

/// The [`TimeSplit`] of a planned job, from the same segments and rules as [`summarize`]'s
/// laser-on time (so `lit_s` is its `laser_on_time_s`).
pub fn time_split(job: &Job) -> TimeSplit {
    let (mut lit, mut feed, mut rapid) = (0.0, 0.0, 0.0);
    for (i, seg) in job.plan.segments().iter().enumerate() {
        let t = seg.motion_duration();
        if segment_laser(job, i).is_some() {
            lit += t;
            if dwell_lit(job, i) {
                lit += seg.dwell;
            }
        } else if segment_is_rapid(job, i) {
            rapid += t;
        } else {
            feed += t;
        }
    }
    TimeSplit {
        lit_s: lit,
        unlit_feed_s: feed,
        rapid_s: rapid,
        still_s: (job.cycle_time() - lit - feed - rapid).max(0.0),
    }
}
