//! The planned timeline: compact per-move segments and exact sampling of them.
//!
//! A [`Segment`] stores only what cannot be recomputed cheaply: its start time and path
//! distance, the three characteristic speeds, the phase durations and its corner blend, if any
//! (120 bytes). Peak
//! acceleration and jerk follow from those (`a_p = Δv / (t_j + t_a)`, `J = a_p / t_j`), and so
//! do axis quantities through the move's direction `u = Δq / length` (q(s) = q0 + u·s). The
//! axis positions live beside the segments in one flat table of the axes in use (a 2-axis plan
//! stores 16 bytes per segment, not 48): a segment starts at its point and ends where the next
//! one starts (the plan's end for the last). The halves of corner blends keep no point: they
//! start on their blend ([`Plan::segment_start`] computes the point the split started them at),
//! and `Plan::halves` counts them every 32 segments so that the others' points are found in
//! constant time (a lit zigzag blends every corner: two of its 2.5 segments a move are halves,
//! 32 bytes a move less). The blends themselves are kept compactly ([`Blends`]).
//! [`Plan::sample`] finds the segment by binary search on `t_start` and evaluates the phase
//! polynomials in closed form.

use super::blend::{Blend, Blends, shared_at};
use super::lookahead::{Kin, KinTable};
use super::profile::Shape;
use super::{Axes, MAX_AXES};

/// One move of the plan: where it starts, how fast it goes, how long each phase lasts.
///
/// Phases in order: jerk-up `t_j1`, constant acceleration `t_a1`, jerk-down `t_j1` (together
/// the ramp from `v_entry` to `v_peak`), cruise `t_cruise`, then the mirrored ramp down
/// `t_j2`, `t_a2`, `t_j2` to `v_exit`, then `dwell` of standstill. Trapezoid segments have
/// `t_j1 = t_j2 = 0`. Times in s, speeds in path units/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// Start time of the segment on the plan's timeline.
    pub t_start: f64,
    /// Path distance from the program start to this segment's start.
    pub s_start: f64,
    /// Path length of the move.
    pub length: f64,
    /// Path speed at the start.
    pub v_entry: f64,
    /// Cruise speed, or the peak speed of a move too short to cruise.
    pub v_peak: f64,
    /// Path speed at the end of the motion (0 before a dwell or stop).
    pub v_exit: f64,
    /// Duration of each jerk phase of the ramp up.
    pub t_j1: f64,
    /// Duration of the constant-acceleration phase of the ramp up.
    pub t_a1: f64,
    /// Duration of the cruise.
    pub t_cruise: f64,
    /// Duration of each jerk phase of the ramp down.
    pub t_j2: f64,
    /// Duration of the constant-deceleration phase of the ramp down.
    pub t_a2: f64,
    /// Standstill after the motion.
    pub dwell: f64,
    /// Programmed path speed of the move (f64::INFINITY for a rapid).
    pub feed: f64,
    /// The caller's tag of the move.
    pub tag: u32,
    /// Index of the move in the input slice (zero-length moves are merged, so indices can skip).
    pub move_index: u32,
    /// The corner blend this segment follows ([`Plan::blend_of`]), or [`NO_BLEND`] for a
    /// straight piece: `2·index` for the half before the corner, `2·index + 1` after it.
    pub blend: u32,
}

/// [`Segment::blend`] of a straight segment.
pub const NO_BLEND: u32 = u32::MAX;

// The memory budget of a plan (`planner` module doc) counts on it.
const _: () = assert!(std::mem::size_of::<Segment>() == 120);

/// Until the look-ahead times a segment, its timing fields hold what the passes need of its
/// move ([`Kin`]: speed, acceleration and jerk limits and entry cap, with `length` its path
/// length); committing the segment overwrites them with its timing. A plan is planned in its
/// own table, with no scratch table beside it (issue 18: 40 bytes a move).
impl KinTable for [Segment] {
    #[inline]
    fn count(&self) -> usize {
        self.len()
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self[i].kin()
    }

    #[inline]
    fn set_cap(&mut self, i: usize, cap: f64) {
        self[i].v_entry = cap;
    }
}

impl Segment {
    /// The look-ahead's data of a segment not yet timed ([`KinTable`] for segments).
    #[inline]
    pub(crate) fn kin(&self) -> Kin {
        Kin {
            len: self.length,
            v: self.v_peak,
            a: self.t_a1,
            j: self.t_j1,
            cap: self.v_entry,
        }
    }

    /// Keeps `k` in a segment not yet timed: its length becomes `k.len`.
    #[inline]
    pub(crate) fn set_kin(&mut self, k: &Kin) {
        self.length = k.len;
        self.v_peak = k.v;
        self.t_a1 = k.a;
        self.t_j1 = k.j;
        self.v_entry = k.cap;
    }

    #[inline]
    pub(crate) fn shape(&self) -> Shape {
        Shape {
            v0: self.v_entry,
            vp: self.v_peak,
            v1: self.v_exit,
            t_j1: self.t_j1,
            t_a1: self.t_a1,
            t_c: self.t_cruise,
            t_j2: self.t_j2,
            t_a2: self.t_a2,
        }
    }

    /// Duration of the motion, without the dwell.
    #[inline]
    pub fn motion_duration(&self) -> f64 {
        self.shape().duration()
    }

    /// Duration of motion plus dwell.
    #[inline]
    pub fn duration(&self) -> f64 {
        self.motion_duration() + self.dwell
    }

    /// End time on the plan's timeline.
    #[inline]
    pub fn t_end(&self) -> f64 {
        self.t_start + self.duration()
    }

    /// Peak path acceleration of the ramp up (0 without one).
    pub fn accel_peak(&self) -> f64 {
        let t = self.t_j1 + self.t_a1;
        if t > 0.0 {
            (self.v_peak - self.v_entry) / t
        } else {
            0.0
        }
    }

    /// Peak path deceleration of the ramp down, as a positive number (0 without one).
    pub fn decel_peak(&self) -> f64 {
        let t = self.t_j2 + self.t_a2;
        if t > 0.0 {
            (self.v_peak - self.v_exit) / t
        } else {
            0.0
        }
    }

    /// Where along the move (local path distance from its start) the cruise at `v_peak`
    /// begins and ends; empty (`begin == end`) when the move never cruises. A cut that must
    /// run at constant speed (PROCESS.md §4) lies inside this span.
    pub fn cruise_span(&self) -> (f64, f64) {
        let begin = 0.5 * (self.v_entry + self.v_peak) * (2.0 * self.t_j1 + self.t_a1);
        (begin, begin + self.v_peak * self.t_cruise)
    }

    /// Path state (s, v, a, j) at `t_local` after the segment start; s is local to the move.
    #[inline]
    pub fn path_state(&self, t_local: f64) -> (f64, f64, f64, f64) {
        let motion = self.motion_duration();
        if t_local >= motion {
            return (self.length, self.v_exit, 0.0, 0.0);
        }
        self.shape().eval(self.length, t_local.max(0.0))
    }
}

/// The state of the machine at one instant of the plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Time on the plan's timeline.
    pub t: f64,
    /// Index of the segment the instant belongs to.
    pub segment: usize,
    /// Tag of that segment's move.
    pub tag: u32,
    /// Path distance from the program start.
    pub s: f64,
    /// Path speed.
    pub v: f64,
    /// Path acceleration.
    pub a: f64,
    /// Path jerk.
    pub j: f64,
    /// Axis positions.
    pub pos: Axes,
    /// Axis speeds.
    pub vel: Axes,
    /// Axis accelerations.
    pub acc: Axes,
    /// Axis jerks.
    pub jerk: Axes,
    /// The instant lies in a dwell (standstill after a move).
    pub dwelling: bool,
}

/// A timed motion program. Built by [`plan`](fn@super::plan).
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub(crate) segments: Vec<Segment>,
    /// Start positions of the segments, `n_axes` values each (the axes in use only; the
    /// others never move and keep their values from `start`).
    pub(crate) points: Vec<f64>,
    pub(crate) start: Axes,
    pub(crate) end: Axes,
    pub(crate) duration: f64,
    pub(crate) n_axes: usize,
    /// The corner blends segments refer to (`Segment::blend`).
    pub(crate) blends: Blends,
    /// The number of the plan's first blend: 0 for a whole plan, that of the first blend a
    /// window's segments refer to for a window (`planner::plan_along_windows`).
    pub(crate) blend_base: u32,
    /// Where a segment's point is in `points` ([`half_ranks`]): empty where every segment has
    /// one (no blends), else the number of halves of blends (which keep none) before every
    /// [`RANK_BLOCK`]-th segment.
    pub(crate) halves: Vec<u64>,
}

/// Segments per entry of `Plan::halves`: finding a point reads the `blend` of at most
/// `RANK_BLOCK − 1` segments beside it.
const RANK_BLOCK: usize = 32;

/// Where a half of blend `b` starts (`after`: the half after the corner): the point
/// `blend::Splitter` started it at, on the `n` axes in use; `rest` on the others.
pub(crate) fn half_start(b: &Blend, after: bool, rest: &Axes, n: usize) -> Axes {
    let p = b.point(if after { 0.5 } else { 0.0 });
    let mut q = *rest;
    q[..n].copy_from_slice(&p[..n]);
    q
}

/// `Plan::halves` of `segments`: a half of a blend starts on its blend
/// (`Plan::segment_start`), so the points are kept for the other segments only (a lit zigzag
/// blends every corner: 2 of its 2.5 segments a move are halves).
pub(crate) fn half_ranks(segments: &[Segment]) -> Vec<u64> {
    if segments.iter().all(|s| s.blend == NO_BLEND) {
        return Vec::new();
    }
    let mut out = Vec::with_capacity(segments.len().div_ceil(RANK_BLOCK));
    let mut halves = 0u64;
    for (i, s) in segments.iter().enumerate() {
        if i % RANK_BLOCK == 0 {
            out.push(halves);
        }
        halves += u64::from(s.blend != NO_BLEND);
    }
    out
}

impl Plan {
    /// A plan of no segments that says where a program planned in windows starts and ends and
    /// how long it takes (`motion::plan_program_windows`: its windows were handed on).
    pub fn summary(start: Axes, end: Axes, duration: f64, n_axes: usize) -> Plan {
        Plan {
            segments: Vec::new(),
            points: Vec::new(),
            start,
            end,
            duration,
            n_axes,
            blends: Blends::new(n_axes, start),
            blend_base: 0,
            halves: Vec::new(),
        }
    }

    /// [`Plan::summary`] of `plan`.
    pub fn without_segments(plan: &Plan) -> Plan {
        Plan::summary(plan.start, plan.end, plan.duration, plan.n_axes)
    }

    /// Total duration in s, dwells included.
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// One segment per planned move, in order.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Axis positions at the program start.
    pub fn start(&self) -> Axes {
        self.start
    }

    /// Axis positions at the program end (the last move's target).
    pub fn end(&self) -> Axes {
        self.end
    }

    /// Number of axes in use.
    pub fn n_axes(&self) -> usize {
        self.n_axes
    }

    /// Path length of the whole program.
    pub fn length(&self) -> f64 {
        self.segments.last().map_or(0.0, |s| s.s_start + s.length)
    }

    /// Axis positions at the start of segment `i` (the plan's end past the last segment). A
    /// half of a blend starts on its blend (the point `blend::Splitter` started it at, computed
    /// again); the others' points are kept.
    pub fn segment_start(&self, i: usize) -> Axes {
        let n = self.n_axes;
        let Some(seg) = self.segments.get(i) else {
            return self.end;
        };
        if seg.blend != NO_BLEND {
            return match self.blend_of(i) {
                Some((b, after)) => half_start(&b, after, &self.start, n),
                None => self.start,
            };
        }
        let mut q = self.start;
        let k = match self.halves.get(i / RANK_BLOCK) {
            Some(&h) => {
                let from = i - i % RANK_BLOCK;
                let more = self.segments[from..i]
                    .iter()
                    .filter(|s| s.blend != NO_BLEND)
                    .count();
                i - (h as usize + more)
            }
            None => i,
        };
        match self.points.get(k * n..(k + 1) * n) {
            Some(p) => {
                q[..n].copy_from_slice(p);
                q
            }
            None => self.end,
        }
    }

    /// Axis positions at the end of segment `i` (clamped to the last segment).
    pub fn segment_target(&self, i: usize) -> Axes {
        self.segment_start((i + 1).min(self.segments.len()))
    }

    /// The corner blend segment `i` follows, and whether it is the half after the corner.
    pub fn blend_of(&self, i: usize) -> Option<(Blend, bool)> {
        let b = self.segments.get(i)?.blend;
        if b == NO_BLEND {
            return None;
        }
        let k = (b / 2).checked_sub(self.blend_base)?;
        Some((self.blends.get(k as usize)?, b % 2 == 1))
    }

    /// The axis curvatures `q''` at the start and the end of blend `b` (numbered in the whole
    /// plan): shared with the blend before or after it where they abut on a chord of a curve
    /// (`Blend::shared`), else zero. A window (`plan_along_windows`) holds the blends its own
    /// segments follow and the one before them where the planner still had it; a neighbour
    /// it lacks counts as unshared, so sample a plan planned whole where that matters (traces).
    pub fn blend_curvatures(&self, b: usize) -> (Axes, Axes) {
        let Some(b) = b.checked_sub(self.blend_base as usize) else {
            return (Axes::ZERO, Axes::ZERO);
        };
        let Some(blend) = self.blends.get(b) else {
            return (Axes::ZERO, Axes::ZERO);
        };
        let (l0, l1) = blend.levels();
        let g0 = match b.checked_sub(1).and_then(|p| self.blends.get(p)) {
            Some(prev) if l0 > 0 => shared_at(&prev, &blend, l0),
            _ => Axes::ZERO,
        };
        let g1 = match self.blends.get(b + 1) {
            Some(next) if l1 > 0 => shared_at(&blend, &next, l1),
            _ => Axes::ZERO,
        };
        (g0, g1)
    }

    /// Bytes the segments' points hold on the heap (with `Plan::halves`, which finds them).
    pub fn point_heap_bytes(&self) -> usize {
        8 * (self.points.capacity() + self.halves.capacity())
    }

    /// Every corner blend of the plan, in order.
    pub fn blends(&self) -> &Blends {
        &self.blends
    }

    /// Axis motion per unit path of segment `i`, `u = Δq / length` (zero for a standstill).
    pub fn direction(&self, i: usize) -> Axes {
        let Some(seg) = self.segments.get(i) else {
            return Axes::ZERO;
        };
        let (q0, q1) = (self.segment_start(i), self.segment_target(i));
        let mut u = Axes::ZERO;
        if seg.length > 0.0 {
            for k in 0..MAX_AXES {
                u[k] = (q1[k] - q0[k]) / seg.length;
            }
        }
        u
    }

    /// State at time `t`, clamped to `[0, duration]` (NaN counts as 0). O(log n).
    pub fn sample(&self, t: f64) -> Sample {
        let t = if t.is_nan() {
            0.0
        } else {
            t.clamp(0.0, self.duration)
        };
        if self.segments.is_empty() {
            return self.rest_sample(t);
        }
        let last = self.segments.len() - 1;
        if t >= self.duration {
            // Exactly the end state, not a state a rounding error before it.
            return self.sample_segment(last, f64::INFINITY);
        }
        // Last segment that starts at or before t.
        let i = self
            .segments
            .partition_point(|s| s.t_start <= t)
            .saturating_sub(1);
        self.sample_segment(i, t - self.segments[i].t_start)
    }

    /// State at `t_local` after the start of segment `i`; both are clamped into range.
    #[allow(clippy::needless_range_loop)] // one index over five parallel axis arrays
    pub fn sample_segment(&self, i: usize, t_local: f64) -> Sample {
        let Some(last) = self.segments.len().checked_sub(1) else {
            return self.rest_sample(0.0);
        };
        let i = i.min(last);
        let seg = &self.segments[i];
        let t_local = if t_local.is_nan() {
            0.0
        } else {
            t_local.clamp(0.0, seg.duration())
        };
        let motion = seg.motion_duration();
        let dwelling = seg.dwell > 0.0 && t_local >= motion;
        let (s, v, a, j) = seg.path_state(t_local);
        let blend = self.blend_of(i);
        // A blend's axes come from the blend (on the axes not in use, the plan's start).
        let (q0, q1) = match blend {
            Some(_) => (self.start, self.start),
            None => (self.segment_start(i), self.segment_target(i)),
        };
        let mut out = Sample {
            t: seg.t_start + t_local,
            segment: i,
            tag: seg.tag,
            s: seg.s_start + s,
            v,
            a,
            j,
            pos: q0,
            vel: Axes::ZERO,
            acc: Axes::ZERO,
            jerk: Axes::ZERO,
            dwelling,
        };
        if let Some((b, after)) = blend {
            // x = (σ + ℓ)/(2ℓ): the half before the corner runs σ from −ℓ to 0, the one after
            // from 0 to ℓ (`blend`).
            let x = 0.5 * (s / b.reach) + if after { 0.5 } else { 0.0 };
            let (g0, g1) = self.blend_curvatures((seg.blend / 2) as usize);
            let [pos, vel, acc, jerk] = b.state_curved(x, v, a, j, &g0, &g1);
            for k in 0..self.n_axes {
                out.pos[k] = pos[k];
                out.vel[k] = vel[k];
                out.acc[k] = acc[k];
                out.jerk[k] = jerk[k];
            }
        } else if seg.length > 0.0 {
            // q(s) = q0 + (s / length)·Δq, exact at both ends of the move.
            let frac = s / seg.length;
            for k in 0..MAX_AXES {
                let dq = q1[k] - q0[k];
                let u = dq / seg.length;
                out.pos[k] = if s >= seg.length {
                    q1[k]
                } else {
                    q0[k] + frac * dq
                };
                out.vel[k] = u * v;
                out.acc[k] = u * a;
                out.jerk[k] = u * j;
            }
        }
        out
    }

    fn rest_sample(&self, t: f64) -> Sample {
        Sample {
            t,
            segment: 0,
            tag: 0,
            s: 0.0,
            v: 0.0,
            a: 0.0,
            j: 0.0,
            pos: self.start,
            vel: Axes::ZERO,
            acc: Axes::ZERO,
            jerk: Axes::ZERO,
            dwelling: false,
        }
    }
}
