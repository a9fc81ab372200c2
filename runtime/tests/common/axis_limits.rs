//! Per-axis feasibility of a planned job as a controller's servo loop would see it: the job
//! sampled on a fixed grid (1 kHz for the tests) through `report::beam_at`, the sampling
//! `lase plan --trace` prints, each axis's velocity, acceleration and (S-curve plans) jerk
//! recomputed from its *positions* by backward differences — never from the plan's own `v`,
//! `a` or per-axis columns — and the worst ratio to each axis's limit, with where it happens.

use lase_runtime::axes::{external_unit, to_external};
use lase_runtime::motion::Job;
use lase_runtime::program::Ramp;
use lase_runtime::report::beam_at;

/// The worst sample of one derivative of one axis.
#[derive(Debug, Clone, Copy, Default)]
pub struct Worst {
    /// |derivative| in external units (mm or deg per s, s², s³).
    pub value: f64,
    /// The axis's limit in the same units.
    pub limit: f64,
    /// value / limit.
    pub ratio: f64,
    /// Job time of the sample, s.
    pub t: f64,
    /// Op of the sample (`job.program.ops[tag]`).
    pub tag: u32,
}

impl Worst {
    fn take(&mut self, value: f64, limit: f64, t: f64, tag: u32) {
        let ratio = value.abs() / limit;
        if ratio > self.ratio {
            *self = Worst {
                value: value.abs(),
                limit,
                ratio,
                t,
                tag,
            };
        }
    }
}

/// The worst velocity, acceleration and jerk of one axis.
#[derive(Debug, Clone)]
pub struct AxisWorst {
    pub axis: String,
    pub unit: &'static str,
    pub v: Worst,
    pub a: Worst,
    /// Checked for S-curve plans only (a trapezoid has no jerk limit).
    pub j: Option<Worst>,
}

/// Samples `job` every `period` s over its whole cycle and returns each axis's worst
/// finite-difference velocity, acceleration and jerk against the job's axis limits.
pub fn worst_per_axis(job: &Job, period: f64) -> Vec<AxisWorst> {
    worst_per_axis_outside(job, period, &[])
}

/// [`worst_per_axis`] without the samples whose differences reach within 4 periods of one of
/// the job times `skip` (sorted).
pub fn worst_per_axis_outside(job: &Job, period: f64, skip: &[f64]) -> Vec<AxisWorst> {
    let machine = &job.program.machine;
    let n_axes = machine.axes.len();
    let scurve = job.program.planner.ramp == Ramp::Scurve;
    let mut out: Vec<AxisWorst> = machine
        .axes
        .iter()
        .map(|a| AxisWorst {
            axis: a.name.clone(),
            unit: external_unit(a.kind),
            v: Worst::default(),
            a: Worst::default(),
            j: scurve.then(Worst::default),
        })
        .collect();
    let total = job.cycle_time();
    let n = (total / period).ceil() as usize;
    // Per axis: last position, velocity and acceleration (backward differences).
    let mut x0 = vec![0.0f64; n_axes];
    let mut v0 = vec![0.0f64; n_axes];
    let mut a0 = vec![0.0f64; n_axes];
    for k in 0..=n {
        let t = (k as f64 * period).min(total);
        let (s, _, _) = beam_at(job, t);
        for (i, (axis, w)) in machine.axes.iter().zip(&mut out).enumerate() {
            let lim = &job.program.limits[i];
            let ext = |x: f64| to_external(axis.kind, x);
            let x = s.pos[i];
            if k == 0 {
                x0[i] = x;
                continue;
            }
            let v = (x - x0[i]) / period;
            let a = (v - v0[i]) / period;
            let j = (a - a0[i]) / period;
            let near = skip
                .get(skip.partition_point(|&s| s < t - 4.0 * period))
                .is_some_and(|&s| s <= t + 4.0 * period);
            if near {
                (x0[i], v0[i], a0[i]) = (x, v, a);
                continue;
            }
            w.v.take(ext(v), ext(lim.v), t, s.tag);
            w.a.take(ext(a), ext(lim.a), t, s.tag);
            // Differences before the first sample start from rest, as a job does.
            if let Some(wj) = &mut w.j {
                wj.take(ext(j), ext(lim.j), t, s.tag);
            }
            (x0[i], v0[i], a0[i]) = (x, v, a);
        }
    }
    out
}
