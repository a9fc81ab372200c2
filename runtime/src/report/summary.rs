//! The plan summary: cycle time, lengths, laser time, pulse count and the peak axis speed,
//! acceleration and jerk, computed exactly from the plan's segments.

use super::pulses::Section;
use super::round_sig;
use crate::axes::to_external;
use crate::motion::Job;
use crate::planner::{Plan, Segment};
use crate::program::{Laser, OpKind, ProcessProgram, Pulse, Ramp};
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

/// Summarizes a planned job: [`PlanTotals`] over its whole plan.
///
/// Axis peaks: along a straight move `q(s) = q0 + u·s`, so every axis quantity is `|u_k|`
/// times the path quantity, and the path peaks of a segment are its `v_peak`, its ramp
/// accelerations and, for an S-curve, the jerk `a_p / t_j` of its jerk phases. Speed jumps at
/// junctions (the corner model) are not counted as acceleration.
pub fn summarize(job: &Job) -> Summary {
    PlanTotals::of(job).summary(job)
}

/// What the summary and the time split count, gathered segment by segment as the plan passes:
/// whole ([`PlanTotals::of`]) or a window at a time (issue 18: `lase plan` of a job of millions
/// of moves, `motion::plan_program_windows`), in the same order and with the same arithmetic,
/// so both give the same numbers to the last bit. A segment is counted once the next one has
/// arrived: whether the beam stays on through its dwell, and whether its lit section goes on,
/// depend on the next segment's laser.
#[derive(Debug)]
pub struct PlanTotals {
    scurve: bool,
    /// Peak speed, acceleration and jerk per axis.
    peaks: Vec<[f64; 3]>,
    rapid_len: f64,
    lit_len: f64,
    /// Lit time in the summary's order of sums; the time split's parts.
    lit_time: f64,
    split: [f64; 3],
    blocks: usize,
    last_move: Option<u32>,
    /// The segment waiting for the next one.
    waiting: Option<Segment>,
    /// The lit section with pulses that is open: its first segment's pulse, start time and
    /// path distance.
    section: Option<(Pulse, f64, f64)>,
    pulses_moving: u64,
    /// Path length, once known.
    length: f64,
}

impl PlanTotals {
    /// Ready for the segments of `program`'s plan.
    pub fn new(program: &ProcessProgram) -> PlanTotals {
        PlanTotals {
            scurve: program.planner.ramp == Ramp::Scurve,
            peaks: vec![[0.0; 3]; program.machine.axes.len()],
            rapid_len: 0.0,
            lit_len: 0.0,
            lit_time: 0.0,
            split: [0.0; 3],
            blocks: 0,
            last_move: None,
            waiting: None,
            section: None,
            pulses_moving: 0,
            length: 0.0,
        }
    }

    /// The totals of a job planned whole.
    pub fn of(job: &Job) -> PlanTotals {
        let mut t = PlanTotals::new(&job.program);
        t.window(&job.program, &job.plan);
        t.finish(&job.program, job.plan.length());
        t
    }

    /// Counts a window of `program`'s plan (its segments in order, after the last window's).
    pub fn window(&mut self, program: &ProcessProgram, plan: &Plan) {
        for (i, seg) in plan.segments().iter().enumerate() {
            // One block per planned move: a move blended at its corners is up to three
            // segments (`planner::blend`), all with the move's index.
            if self.last_move != Some(seg.move_index) {
                self.blocks += 1;
                self.last_move = Some(seg.move_index);
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
            for (k, p) in self.peaks.iter_mut().enumerate() {
                let uk = u[k].abs();
                p[0] = p[0].max(uk * seg.v_peak);
                p[1] = p[1].max(uk * acc);
                p[2] = p[2].max(uk * jerk);
            }
            if let Some(prev) = self.waiting.take() {
                self.count(program, &prev, laser_of(program, seg));
            }
            self.waiting = Some(*seg);
        }
    }

    /// After the last window: `length` is the plan's path length.
    pub fn finish(&mut self, program: &ProcessProgram, length: f64) {
        if let Some(prev) = self.waiting.take() {
            self.count(program, &prev, None);
        }
        self.length = length;
    }

    /// Counts segment `seg`, `next` the laser of the one after it.
    fn count(&mut self, program: &ProcessProgram, seg: &Segment, next: Option<&Laser>) {
        let laser = laser_of(program, seg);
        let rapid = program
            .ops
            .get(seg.tag as usize)
            .is_some_and(|op| matches!(op.kind, OpKind::Rapid { .. }));
        // The beam stays on through the dwell between two lit moves.
        let dwell_lit = laser.is_some() && next.is_some();
        if rapid {
            self.rapid_len += seg.length;
        }
        let t = seg.motion_duration();
        if laser.is_some() {
            self.lit_len += seg.length;
            self.lit_time += t;
            if dwell_lit {
                self.lit_time += seg.dwell;
            }
            self.split[0] += t;
            if dwell_lit {
                self.split[0] += seg.dwell;
            }
        } else if rapid {
            self.split[2] += t;
        } else {
            self.split[1] += t;
        }
        // Lit sections with pulses (`pulses::sections`): one opens at a lit segment with a
        // pulse setting and goes on while the beam stays on into a segment with the same one.
        let pulse = laser.and_then(|l| l.pulse.as_ref());
        if self.section.is_none()
            && let Some(p) = pulse
        {
            self.section = Some((p.clone(), seg.t_start, seg.s_start));
        }
        if let Some((p, t0, s0)) = &self.section {
            let goes_on = dwell_lit && next.and_then(|l| l.pulse.as_ref()) == Some(p);
            if !goes_on {
                self.pulses_moving += Section {
                    mode: p.mode,
                    t0: *t0,
                    t1: seg.t_start + seg.motion_duration(),
                    s0: *s0,
                    s1: seg.s_start + seg.length,
                }
                .count();
                self.section = None;
            }
        }
    }

    /// The time split of the job whose plan was counted.
    pub fn time_split(&self, job: &Job) -> TimeSplit {
        let [lit, feed, rapid] = self.split;
        TimeSplit {
            lit_s: lit,
            unlit_feed_s: feed,
            rapid_s: rapid,
            still_s: (job.cycle_time() - lit - feed - rapid).max(0.0),
        }
    }

    /// The summary of the job whose plan was counted.
    pub fn summary(&self, job: &Job) -> Summary {
        let machine = &job.program.machine;
        let axes = machine
            .axes
            .iter()
            .zip(&self.peaks)
            .map(|(axis, p)| {
                let ext = |x: f64| round_sig(to_external(axis.kind, x));
                (
                    axis.name.clone(),
                    AxisPeaks {
                        v_max: ext(p[0]),
                        a_max: ext(p[1]),
                        j_max: self.scurve.then(|| ext(p[2])),
                    },
                )
            })
            .collect();
        let (standstill, fire_time) = fire_pulses(job);
        let moving = self.pulses_moving;
        Summary {
            recipe: job.program.recipe.clone(),
            machine: machine.name.clone(),
            ramp: job.program.planner.ramp,
            cycle_time_s: round_sig(job.cycle_time()),
            controller: None,
            path_length_mm: round_sig(self.length),
            rapid_length_mm: round_sig(self.rapid_len),
            laser_on_length_mm: round_sig(self.lit_len),
            laser_on_time_s: round_sig(self.lit_time),
            pulses: moving + standstill,
            pulses_moving: moving,
            pulses_standstill: standstill,
            standstill_fire_time_s: round_sig(fire_time),
            blocks: self.blocks,
            ops: job.program.ops.len(),
            axes,
        }
    }
}

/// The laser of `seg`'s op (None when unlit).
fn laser_of<'p>(program: &'p ProcessProgram, seg: &Segment) -> Option<&'p Laser> {
    program.ops.get(seg.tag as usize)?.laser()
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
    PlanTotals::of(job).time_split(job)
}
