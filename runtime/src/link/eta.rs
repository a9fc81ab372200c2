//! Progress on the plan's timeline while a job streams: how much of the planned cycle time
//! is done, from the lines the controller acknowledged and the position it reports.
//!
//! An acknowledged line is parsed, not executed: the controller's planner holds the next few
//! blocks. So the acknowledged lines give an upper bound on progress, and the reported
//! position, matched against the planned segments of the last lines, says where in them the
//! machine is.

use super::{AxisPos, ControllerAxes, MAX_AXES};
use crate::emit::NcLine;
use crate::motion::Job;

/// How far back from the last acknowledged line the position is searched, in planned
/// segments (a GRBL planner holds 15 blocks; arcs become many segments).
const WINDOW: usize = 256;

#[derive(Debug, Clone)]
pub struct Eta {
    /// Planned job time when each line's op has finished, s, run-length: (first line, time)
    /// wherever it changes (from 0 s at line 0). By ops, not by lines: a job of millions of
    /// lines has far fewer ops.
    line_end: Vec<(usize, f64)>,
    /// Lines in the job.
    lines: usize,
    /// Planned segments: job time at start and end of motion, start and end point in the
    /// controller's X Y Z A B C (machine axes mapped by letter), mm and degrees.
    segs: Vec<(f64, f64, AxisPos, AxisPos)>,
    total: f64,
    /// Pulses fired by the end of each planned segment (pulses at rest after a segment count
    /// toward the next one), and in the whole job.
    pulses_by: Vec<u64>,
    pulses: u64,
    /// The machine's axis letters, as status lines show them.
    letters: Vec<char>,
    /// Controller seconds per planned second ([`Eta::counted_in`]); 1 on lase's own plan.
    scale: f64,
}

impl Eta {
    /// The progress of `job` streamed as `lines`.
    pub fn new(job: &Job, lines: &[NcLine]) -> Eta {
        let mut runs: Vec<(usize, Option<u32>)> = Vec::new();
        for (i, l) in lines.iter().enumerate() {
            if runs.last().is_none_or(|r| r.1 != l.op) {
                runs.push((i, l.op));
            }
        }
        Eta::from_runs(job, &runs, lines.len())
    }

    /// The progress of `job` streamed as `n_lines` lines whose ops are `runs`: (first line,
    /// op) wherever the op changes (`link::job::JobLines::runs`).
    pub fn from_runs(job: &Job, runs: &[(usize, Option<u32>)], n_lines: usize) -> Eta {
        let plan = &job.plan;
        let t0 = job.initial_dwell_s;
        let axes = ControllerAxes::of(&job.program.machine);
        let map = |q: &crate::axes::Axes| axes.to_controller(q);
        let mut op_end = vec![f64::NAN; job.program.ops.len()];
        let mut segs = Vec::with_capacity(plan.segments().len());
        for (i, s) in plan.segments().iter().enumerate() {
            if let Some(e) = op_end.get_mut(s.tag as usize) {
                *e = t0 + s.t_end();
            }
            segs.push((
                t0 + s.t_start,
                t0 + s.t_start + s.motion_duration(),
                map(&plan.segment_start(i)),
                map(&plan.segment_target(i)),
            ));
        }
        let mut line_end = Vec::new();
        let mut t = 0.0f64;
        for &(first, op) in runs {
            if let Some(e) = op
                .and_then(|o| op_end.get(o as usize))
                .filter(|e| !e.is_nan())
                && *e > t
            {
                t = *e;
                line_end.push((first, t));
            }
        }
        // Pulses by segment, in one pass over the (lazy, time-ordered) pulse events.
        let mut pulses_by = vec![0u64; segs.len()];
        let mut pulses = 0u64;
        let mut k = 0;
        for p in crate::report::pulse_events(job) {
            while k + 1 < segs.len() && p.t > segs[k].1 + 1e-9 {
                k += 1;
            }
            if let Some(n) = pulses_by.get_mut(k) {
                *n += 1;
            }
            pulses += 1;
        }
        let mut sum = 0;
        for n in &mut pulses_by {
            sum += *n;
            *n = sum;
        }
        Eta {
            line_end,
            lines: n_lines,
            segs,
            total: job.cycle_time(),
            pulses_by,
            pulses,
            letters: axes.letters().to_vec(),
            scale: 1.0,
        }
    }

    /// The same progress counted in the time of the controller that runs the job
    /// (`estimate::controller_cycle`, `total_s`): the plan still says where in the job the
    /// machine is, and each planned second counts as `total_s` over the planned cycle time,
    /// so the ETA ends when the controller's model says the job ends.
    pub fn counted_in(mut self, total_s: f64) -> Eta {
        if self.total > 0.0 && total_s.is_finite() && total_s > 0.0 {
            self.scale = total_s / self.total;
        }
        self
    }

    /// Pulses the job fires in all.
    pub fn pulses(&self) -> u64 {
        self.pulses
    }

    /// Pulses fired by job time `t` (as [`Eta::done`] counts it), within the segment then running counted in
    /// proportion to its time.
    pub fn pulses_done(&self, t: f64) -> u64 {
        let t = t / self.scale;
        let k = self.segs.partition_point(|s| s.1 < t);
        let Some(&(ta, tb, _, _)) = self.segs.get(k) else {
            return self.pulses;
        };
        let before = k.checked_sub(1).map_or(0, |j| self.pulses_by[j]);
        let within = self.pulses_by[k] - before;
        let f = if tb > ta {
            ((t - ta) / (tb - ta)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        before + (within as f64 * f).floor() as u64
    }

    /// The machine's axis letters (what a status line shows).
    pub fn letters(&self) -> &[char] {
        &self.letters
    }

    /// The cycle time, s (the controller's after [`Eta::counted_in`]).
    pub fn total(&self) -> f64 {
        self.total * self.scale
    }

    /// Planned job time done: at most what the acknowledged lines account for, placed by the
    /// controller's position (work coordinates X Y Z A B C) when it is known. Degrees count
    /// as mm in the distance to a segment, as a GRBL-family controller counts them.
    pub fn done(&self, acked: usize, pos: Option<&[f64]>) -> f64 {
        self.done_planned(acked, pos) * self.scale
    }

    /// [`Eta::done`] on lase's own plan's clock.
    fn done_planned(&self, acked: usize, pos: Option<&[f64]>) -> f64 {
        let upper = match acked.checked_sub(1).filter(|&i| i < self.lines) {
            Some(i) => {
                let k = self.line_end.partition_point(|r| r.0 <= i);
                k.checked_sub(1).map_or(0.0, |k| self.line_end[k].1)
            }
            None if acked == 0 => return 0.0,
            None => self.total,
        };
        let Some(pos) = pos else {
            return upper;
        };
        let last = self.segs.partition_point(|s| s.0 < upper);
        let first = last.saturating_sub(WINDOW);
        let mut best = (f64::INFINITY, upper);
        for &(ta, tb, a, b) in &self.segs[first..last] {
            let d: AxisPos = std::array::from_fn(|i| b[i] - a[i]);
            let len2: f64 = d.iter().map(|x| x * x).sum();
            let f = if len2 > 0.0 {
                ((0..MAX_AXES)
                    .map(|i| (pos.get(i).copied().unwrap_or(0.0) - a[i]) * d[i])
                    .sum::<f64>()
                    / len2)
                    .clamp(0.0, 1.0)
            } else {
                1.0
            };
            let dist2: f64 = (0..MAX_AXES)
                .map(|i| (a[i] + f * d[i] - pos.get(i).copied().unwrap_or(0.0)).powi(2))
                .sum();
            // Later segments win ties: a path that passes a point twice is further along.
            if dist2 <= best.0 + 1e-12 {
                best = (dist2, ta + f * (tb - ta));
            }
        }
        best.1.min(upper)
    }
}
