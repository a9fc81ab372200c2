//! Corner blends: the curve the plan follows through a corner taken at speed, and the limits
//! that keep every axis within its own velocity, acceleration and jerk along it.
//!
//! **Why.** Two straight moves meeting at a kink cannot be passed at a speed `v > 0` by any
//! machine: each axis's velocity would jump by `v·Δu_k` in no time (`Δu = w − u`, the moves'
//! `Δq / length`). Junction deviation (`junction`) caps that jump but still plans it; a 1 kHz
//! trace of such a plan shows `Δv / 1 ms` in the sampled acceleration (26× the limit at the
//! cam's rapid → lead-in junction, issue 13). So a corner is passed either at rest or along a
//! blend whose axis velocity and acceleration are continuous, planned with limits that hold
//! along it — the plan is what the machine does.
//!
//! **The curve.** Around the corner `C` (path parameter `σ ∈ [−ℓ, ℓ]`, σ = 0 at the corner),
//! the axis rate `q'(σ)` goes from `u` to `w` along the smoothstep `h(x) = 3x² − 2x³`,
//! `x = (σ + ℓ)/(2ℓ)`:
//!
//! `q(σ) = C − uℓ + 2ℓ·(u·x + Δu·H(x))`, `H(x) = x³ − x⁴/2` (so `H' = h`),
//!
//! which leaves the incoming move at `σ = −ℓ` and joins the outgoing one at `σ = ℓ` with equal
//! position, rate and zero second derivative (`h'(0) = h'(1) = 0`): position, axis velocity
//! and axis acceleration are continuous, as an S-curve plan needs (a quintic-in-time
//! counterpart of LinuxCNC's parabolic and arc blends; the parabola's curvature jumps at its
//! ends, which the jerk of a 1 kHz trace would show). Bounds used below: `|q'_k|` stays between
//! `|u_k|` and `|w_k|` (h ∈ [0, 1]), `|q''_k| ≤ 0.75·|Δu_k|/ℓ` (max h' = 1.5 at x = ½),
//! `|q'''_k| ≤ 1.5·|Δu_k|/ℓ²` (max |h''| = 6).
//!
//! **How far from the corner.** The blend's distance from the two straight moves is largest at
//! `σ = 0`: `|q(0) − C| = 3/16 · ℓ · |Δu|`. On a Cartesian machine (length = axis-space
//! length, unit directions) that is the spot's distance, and `ℓ ≤ δ / (3/16 · |Δu|)` keeps it
//! within the corner tolerance δ (`planner { corner }`). Where a move's length is a part-space
//! chord of mm and rad axes (oriented machines), the spot follows the part-space blend to first
//! order: `ℓ ≤ δ / (3/16 · |Δt|)` with `Δt` the change of the spot's part-space direction
//! (`plan_along`; for a rapid, whose spot path is not a straight line, or where it is not
//! known, the largest there is, 2). Every blend also stays
//! within the halves of both moves (so neighbouring blends never overlap; on the chords of an
//! arc they abut and the path is curved throughout), and within [`REACH_MAX`]`·δ` of the
//! corner along each move, so a lead-in loses at most that much of its straight ramp (the
//! lead-ins add it: `motion::leadin`).
//!
//! **Limits along it.** With path speed `v`, acceleration `a`, jerk `j`, axis k moves at
//! `q'_k v`, accelerates at `q''_k v² + q'_k a` and jerks at `q'''_k v³ + 3 q''_k v a + q'_k j`.
//! The blend gets its own speed cap, path acceleration and path jerk so that each of those is
//! within the axis's limit everywhere on the blend ([`limits`]): the curvature terms get at
//! most [`SHARE`] of each axis's acceleration and jerk, the path's own changes what is left.
//! A corner the plan cannot round (δ = 0, a reversal on a Cartesian path) is a stop.
//!
//! **In the plan.** `prepare` splits each move into the second half of the blend at its start,
//! its straight middle, and the first half of the blend at its end; all three keep the move's
//! tag, so every op keeps its path length and its segments. The corner point itself (σ = 0) is
//! a segment boundary, where the plan switches ops exactly as before.

use super::lookahead::Kin;
use super::plan::{NO_BLEND, Segment};
use super::{Axes, AxisLimits, MAX_AXES, Prepared};

/// Share of each axis's acceleration (and jerk) the blend's curvature may use; the rest is for
/// changing the path speed on it.
pub const SHARE: f64 = 0.75;

/// Largest reach ℓ of a blend along each of its moves, in units of the corner tolerance δ.
pub const REACH_MAX: f64 = 4.0;

/// `|q(0) − C| / (ℓ·|Δu|)`: the blend's deviation from its corner per unit reach and turn.
pub const DEVIATION: f64 = 3.0 / 16.0;

/// Below this `max_k |Δu_k| / max_k |u_k|`, a junction is straight: no blend, no cap. The
/// velocity step left there is below what a 1 kHz trace can tell from rounding (`v·1e-12`).
const STRAIGHT: f64 = 1e-12;

/// Cosine of a reversal on a Cartesian path (stop there).
const REVERSAL_COS: f64 = -1.0 + 1e-9;

/// One blend: its corner, its reach along each move and the two moves' `Δq / length`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend {
    pub corner: Axes,
    pub reach: f64,
    pub u: Axes,
    pub w: Axes,
}

/// `(H, h, h', h'')` at `x ∈ [0, 1]`: `h = 3x² − 2x³` and its integral and derivatives.
#[inline]
pub(crate) fn smoothstep(x: f64) -> (f64, f64, f64, f64) {
    let x2 = x * x;
    (
        x2 * x - 0.5 * x2 * x2,
        3.0 * x2 - 2.0 * x2 * x,
        6.0 * x - 6.0 * x2,
        6.0 - 12.0 * x,
    )
}

impl Blend {
    /// Axis positions at `x = (σ + ℓ)/(2ℓ)`, clamped to `[0, 1]`.
    pub fn point(&self, x: f64) -> Axes {
        let x = x.clamp(0.0, 1.0);
        let (hh, ..) = smoothstep(x);
        let l2 = 2.0 * self.reach;
        let mut q = Axes::ZERO;
        for k in 0..MAX_AXES {
            let du = self.w[k] - self.u[k];
            q[k] = self.corner[k] - self.u[k] * self.reach + l2 * (self.u[k] * x + du * hh);
        }
        q
    }

    /// Axis positions, velocities, accelerations and jerks at `x` along the blend, at path
    /// speed `v`, acceleration `a` and jerk `j`.
    #[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
    pub fn state(&self, x: f64, v: f64, a: f64, j: f64) -> [Axes; 4] {
        let x = x.clamp(0.0, 1.0);
        let (_, h, h1, h2) = smoothstep(x);
        let l = self.reach;
        let mut out = [self.point(x), Axes::ZERO, Axes::ZERO, Axes::ZERO];
        for k in 0..MAX_AXES {
            let du = self.w[k] - self.u[k];
            let d1 = self.u[k] + du * h;
            let d2 = du * h1 / (2.0 * l);
            let d3 = du * h2 / (4.0 * l * l);
            out[1][k] = d1 * v;
            out[2][k] = d2 * v * v + d1 * a;
            out[3][k] = d3 * v * v * v + 3.0 * d2 * v * a + d1 * j;
        }
        out
    }
}

/// What happens at the junction of two moves that the plan passes without a stop point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Junction {
    /// The moves continue each other: no blend, no cap beyond their speeds.
    Straight,
    /// The corner cannot be rounded: the plan stops there.
    Stop,
    /// The junction-deviation model's velocity step, capped by `prepare` (`Along::step_corners`).
    Stepped,
    /// Rounded by `blend`, whose halves get at most these limits.
    Blend {
        blend: Blend,
        v: f64,
        a: f64,
        j: f64,
    },
}

/// The moves on either side of a junction: `Δq / length`, length, speed and path limits
/// (`Kin`), and whether the length is the axis-space length (`euclidean`).
pub(crate) struct Side<'a> {
    pub dir: &'a Axes,
    pub kin: &'a Kin,
    pub euclidean: bool,
}

/// `|d_next − d_prev|` of two known part-space unit directions; 2 (the largest) when either is
/// unknown.
fn part_turn(prev: &[f64; 3], next: &[f64; 3]) -> f64 {
    let known = |d: &[f64; 3]| d.iter().any(|&x| x != 0.0);
    if !(known(prev) && known(next)) {
        return 2.0;
    }
    let t2: f64 = (0..3).map(|i| (next[i] - prev[i]).powi(2)).sum();
    t2.sqrt().min(2.0)
}

/// The junction at `corner` from `prev` into `next`, with corner tolerance `delta`;
/// `part_turn` bounds the spot's turn where the moves' lengths are not axis-space lengths.
#[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
pub(crate) fn junction(
    corner: &Axes,
    prev: Side<'_>,
    next: Side<'_>,
    delta: f64,
    part_turn: f64,
    limits: &AxisLimits,
    n_axes: usize,
) -> Junction {
    let (u, w) = (prev.dir, next.dir);
    let n = n_axes.min(MAX_AXES);
    let (mut d_max, mut m_max, mut du2, mut cos) = (0.0f64, 0.0f64, 0.0, 0.0);
    for k in 0..n {
        let d = w[k] - u[k];
        d_max = d_max.max(d.abs());
        m_max = m_max.max(u[k].abs()).max(w[k].abs());
        du2 += d * d;
        cos += u[k] * w[k];
    }
    if d_max <= STRAIGHT * m_max {
        return Junction::Straight;
    }
    let euclidean = prev.euclidean && next.euclidean;
    if delta == 0.0 || (euclidean && cos <= REVERSAL_COS) {
        return Junction::Stop;
    }
    let turn = if euclidean { du2.sqrt() } else { part_turn };
    let reach = (delta / (DEVIATION * turn))
        .min(REACH_MAX * delta)
        .min(0.5 * prev.kin.len.min(next.kin.len));
    if !(reach > 0.0 && reach.is_finite()) {
        return Junction::Stop;
    }
    let v_moves = prev.kin.v.min(next.kin.v);
    let a_moves = prev.kin.a.min(next.kin.a);
    let j_moves = prev.kin.j.min(next.kin.j);
    let (v, a, j) = limits_along(u, w, reach, v_moves, a_moves, j_moves, limits, n);
    if !(v > 0.0 && a > 0.0 && j > 0.0) {
        return Junction::Stop;
    }
    Junction::Blend {
        blend: Blend {
            corner: *corner,
            reach,
            u: *u,
            w: *w,
        },
        v,
        a,
        j,
    }
}

/// Speed cap, path acceleration and path jerk of a blend of reach `reach` from `u` into `w`
/// (module doc): per axis k with `D = |Δu_k|`, `m = max(|u_k|, |w_k|)`,
/// `0.75·D·v²/ℓ ≤ SHARE·a_k` and `1.5·D·v³/ℓ² + 2.25·D·v·a₀/ℓ ≤ SHARE·j_k` give the cap
/// (`a₀ = (1 − SHARE)·min a_k/m`, the least the path keeps); at the highest speed `v` the blend
/// can then be taken at, the path acceleration is what is left of every axis's,
/// `a = min (a_k − 0.75·D·v²/ℓ)/m`, no more than the jerk budget allows
/// (`2.25·D·v·a/ℓ ≤ SHARE·j_k − 1.5·D·v³/ℓ²`), and the path jerk what is left of every axis's,
/// `j = min (j_k − 1.5·D·v³/ℓ² − 2.25·D·v·a/ℓ)/m`. Each is at least `(1 − SHARE)` of the
/// axis's limit over `m`. The moves' own limits (`v_moves`, …) bound the results; an infinite
/// `j_moves` (trapezoid plans) leaves jerk out.
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
pub(crate) fn limits_along(
    u: &Axes,
    w: &Axes,
    reach: f64,
    v_moves: f64,
    a_moves: f64,
    j_moves: f64,
    limits: &AxisLimits,
    n: usize,
) -> (f64, f64, f64) {
    let scurve = j_moves.is_finite();
    let l = reach;
    let mut a0 = a_moves;
    for k in 0..n {
        let m = u[k].abs().max(w[k].abs());
        if m > 0.0 {
            a0 = a0.min((1.0 - SHARE) * limits.a[k] / m);
        }
    }
    let mut v = v_moves;
    for k in 0..n {
        let d = (w[k] - u[k]).abs();
        if d == 0.0 {
            continue;
        }
        v = v.min((SHARE * limits.a[k] * l / (0.75 * d)).sqrt());
        if scurve && limits.j[k].is_finite() {
            let a_term = if a0.is_finite() { a0 } else { 0.0 };
            let g = |v: f64| 1.5 * d * v * v * v / (l * l) + 2.25 * d * v * a_term / l;
            let budget = SHARE * limits.j[k];
            if g(v) > budget {
                // g is increasing in v: bisect for the largest speed within the budget.
                let (mut lo, mut hi) = (0.0, v);
                for _ in 0..100 {
                    let mid = 0.5 * (lo + hi);
                    if g(mid) <= budget {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                v = lo;
            }
        }
    }
    let mut a = a_moves;
    for k in 0..n {
        let m = u[k].abs().max(w[k].abs());
        let d = (w[k] - u[k]).abs();
        if m > 0.0 {
            a = a.min((limits.a[k] - 0.75 * d * v * v / l) / m);
        }
        if scurve && d > 0.0 && v > 0.0 && limits.j[k].is_finite() {
            let left = SHARE * limits.j[k] - 1.5 * d * v * v * v / (l * l);
            a = a.min(left * l / (2.25 * d * v));
        }
    }
    if !scurve {
        return (v, a, j_moves);
    }
    let mut j = j_moves;
    for k in 0..n {
        let m = u[k].abs().max(w[k].abs());
        let d = (w[k] - u[k]).abs();
        if m > 0.0 && limits.j[k].is_finite() {
            let used = 1.5 * d * v * v * v / (l * l) + 2.25 * d * v * a / l;
            j = j.min((limits.j[k] - used) / m);
        }
    }
    (v, a, j)
}

/// What `split` needs to know of each segment `prepare` made.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MoveInfo {
    /// The length is the axis-space length.
    pub euclidean: bool,
    /// A stop point lies before the move.
    pub stop_before: bool,
    /// The spot's unit direction in part space, zero when unknown (`plan_along`).
    pub part_dir: [f64; 3],
    /// The corner before the move keeps the velocity-step model (`Along::step_corners`):
    /// `prepare` capped its entry already.
    pub stepped_before: bool,
}

impl MoveInfo {
    /// A standstill (a dwell before any motion).
    pub(crate) const REST: MoveInfo = MoveInfo {
        euclidean: true,
        stop_before: true,
        part_dir: [0.0; 3],
        stepped_before: false,
    };
}

/// The [`MoveInfo`] of every segment `prepare` made, a byte a move where every length is the
/// axis-space length (every Cartesian job; a `MoveInfo` is 32 bytes, issue 18): a move's
/// part-space direction only counts at a junction where a length is not (`junction`'s
/// `part_turn`), so directions are kept from the move before the first such move on.
#[derive(Default)]
pub(crate) struct MoveInfos {
    /// `EUCLIDEAN | STOP_BEFORE | STEPPED_BEFORE` of each move.
    flags: Vec<u8>,
    /// Each move's `part_dir` from `dirs_from` on (empty until a length is not Euclidean).
    dirs: Vec<[f64; 3]>,
    dirs_from: usize,
    /// The index of the move `flags[0]` belongs to (`forget_before`).
    first: usize,
    /// The last move's `part_dir`, for the move after it.
    last_dir: [f64; 3],
}

const EUCLIDEAN: u8 = 1;
const STOP_BEFORE: u8 = 2;
const STEPPED_BEFORE: u8 = 4;

impl MoveInfos {
    /// Room for `moves` moves' flags.
    pub(crate) fn with_capacity(moves: usize) -> MoveInfos {
        MoveInfos {
            flags: Vec::with_capacity(moves),
            ..MoveInfos::default()
        }
    }

    pub(crate) fn push(&mut self, m: MoveInfo) {
        let i = self.first + self.flags.len();
        if self.dirs.is_empty() && !m.euclidean {
            // From the move before this one: the first junction that may read a direction.
            self.dirs_from = i.saturating_sub(1);
            if i > 0 {
                self.dirs.push(self.last_dir);
            }
        }
        if !self.dirs.is_empty() || !m.euclidean {
            self.dirs.push(m.part_dir);
        }
        self.last_dir = m.part_dir;
        let bit = |on: bool, b: u8| if on { b } else { 0 };
        self.flags.push(
            bit(m.euclidean, EUCLIDEAN)
                | bit(m.stop_before, STOP_BEFORE)
                | bit(m.stepped_before, STEPPED_BEFORE),
        );
    }

    /// Move `i`'s info (`part_dir` zero where no junction reads it).
    #[inline]
    pub(crate) fn get(&self, i: usize) -> MoveInfo {
        let f = self.flags[i - self.first];
        let part_dir = i
            .checked_sub(self.dirs_from)
            .and_then(|k| self.dirs.get(k))
            .copied()
            .unwrap_or([0.0; 3]);
        MoveInfo {
            euclidean: f & EUCLIDEAN != 0,
            stop_before: f & STOP_BEFORE != 0,
            part_dir,
            stepped_before: f & STEPPED_BEFORE != 0,
        }
    }

    /// Drops what moves before `i` had (the planner in windows has judged their junctions),
    /// keeping the last direction kept, so that `get` answers for later moves as it would have.
    pub(crate) fn forget_before(&mut self, i: usize) {
        let k = i.saturating_sub(self.first).min(self.flags.len());
        self.flags.drain(..k);
        self.first += k;
        let d = i
            .saturating_sub(self.dirs_from)
            .min(self.dirs.len().saturating_sub(1));
        self.dirs.drain(..d);
        self.dirs_from += d;
    }
}

/// What [`junction_at`] reads of the moves `prepare` made: each move's look-ahead data, start
/// point and flags, by its index among them; `count` once every move is known (`usize::MAX`
/// before: the planner in windows judges a junction only once both its moves and the one after
/// them are in).
pub(super) trait MoveSource {
    fn count(&self) -> usize;
    fn kin(&self, i: usize) -> Kin;
    /// Start point of move `i`; the end of the last move for `i == count`.
    fn point(&self, i: usize) -> Axes;
    fn info(&self, i: usize) -> MoveInfo;
}

/// The whole program `prepare` made.
struct Whole<'a> {
    p: &'a Prepared,
    info: &'a MoveInfos,
    start: Axes,
    n: usize,
}

impl MoveSource for Whole<'_> {
    fn count(&self) -> usize {
        self.p.segments.len()
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self.p.segments[i].kin()
    }

    #[inline]
    fn point(&self, i: usize) -> Axes {
        if i >= self.count() {
            return self.p.end;
        }
        let mut q = self.start;
        q[..self.n].copy_from_slice(&self.p.points[i * self.n..(i + 1) * self.n]);
        q
    }

    #[inline]
    fn info(&self, i: usize) -> MoveInfo {
        self.info.get(i)
    }
}

/// The junction after move `i`. Computed where it is needed instead of kept in a table: a
/// `Junction` with its blend is about 220 bytes, more than the plan's own segment, kin and
/// point of a move together (issue 18's memory per move). It reads moves `i` and `i + 1` and
/// the start of `i + 2`.
#[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
pub(super) fn junction_at(
    src: &impl MoveSource,
    i: usize,
    delta: f64,
    limits: &AxisLimits,
    n: usize,
) -> Junction {
    let count = src.count();
    if i.saturating_add(1) >= count || src.kin(i).len == 0.0 || src.kin(i + 1).len == 0.0 {
        return Junction::Stop;
    }
    let (info_i, info_next) = (src.info(i), src.info(i + 1));
    if info_next.stop_before {
        return Junction::Stop;
    }
    if info_next.stepped_before {
        return Junction::Stepped;
    }
    // `Δq / length` of move k, from the points (as `prepare` computed it: not kept, it would
    // be 48 bytes a move).
    let rate = |k: usize| -> Axes {
        let (a, b) = (src.point(k), src.point(k + 1));
        let len = src.kin(k).len;
        let mut r = Axes::ZERO;
        for axis in 0..n {
            r[axis] = (b[axis] - a[axis]) / len;
        }
        r
    };
    let (rate_i, rate_next) = (rate(i), rate(i + 1));
    let (kin_i, kin_next) = (src.kin(i), src.kin(i + 1));
    let turn = part_turn(&info_i.part_dir, &info_next.part_dir);
    junction(
        &src.point(i + 1),
        Side {
            dir: &rate_i,
            kin: &kin_i,
            euclidean: info_i.euclidean,
        },
        Side {
            dir: &rate_next,
            kin: &kin_next,
            euclidean: info_next.euclidean,
        },
        delta,
        turn,
        limits,
        n,
    )
}

/// Splits every move of `p` at the blends of its corners (module doc): the second half of the
/// blend at its start, its straight middle, the first half of the blend at its end, each with
/// its limits and entry cap; corners that cannot be rounded get entry cap 0 (a stop).
pub(super) fn split(
    mut p: Prepared,
    info: &MoveInfos,
    start: Axes,
    delta: f64,
    limits: &AxisLimits,
    n_axes: usize,
) -> Prepared {
    let n = n_axes;
    let count = p.segments.len();
    let junction_after = |p: &Prepared, i: usize| {
        let src = Whole { p, info, start, n };
        junction_at(&src, i, delta, limits, n)
    };
    let extra = (0..count)
        .filter(|&i| matches!(junction_after(&p, i), Junction::Blend { .. }))
        .count();
    if extra == 0 {
        // Nothing to round: only the entry caps change, in place (no second copy of the plan).
        // A move's cap is written after the junction before it is judged, and a junction reads
        // no cap. The same caps as `Splitter::split_move` gives a move without blends.
        let mut prev_v = 0.0f64;
        let mut before = Junction::Stop;
        for i in 0..count {
            let k = p.segments[i].kin();
            if k.len == 0.0 {
                prev_v = 0.0;
            } else {
                let cap = match before {
                    Junction::Straight => k.v.min(prev_v),
                    Junction::Stepped => k.cap.min(prev_v),
                    _ => 0.0,
                };
                p.segments[i].set_kin(&Kin { cap, ..k });
                prev_v = k.v;
            }
            before = junction_after(&p, i);
        }
        return p;
    }
    let mut out = Prepared {
        segments: Vec::with_capacity(count + 2 * extra),
        points: Vec::with_capacity((count + 2 * extra) * n),
        end: p.end,
        blends: Vec::with_capacity(extra),
    };
    let mut splitter = Splitter::default();
    for i in 0..count {
        let after = junction_after(&p, i);
        let at = Whole {
            p: &p,
            info,
            start,
            n,
        }
        .point(i);
        splitter.split_move(p.segments[i], &at, after, &mut out, n);
    }
    out
}

/// `split`, one move at a time: what it remembers of the moves before.
pub(super) struct Splitter {
    /// The speed limit of the sub-segment emitted last (0: at rest).
    prev_v: f64,
    /// The blend the previous move ended in, its index among the plan's blends, and its limits.
    blend_in: Option<(Blend, u32, f64, f64, f64)>,
    /// The junction before the next move.
    before: Junction,
    /// How many blends were made.
    pub(super) blends: u32,
}

impl Default for Splitter {
    fn default() -> Self {
        Splitter {
            prev_v: 0.0,
            blend_in: None,
            before: Junction::Stop,
            blends: 0,
        }
    }
}

impl Splitter {
    /// Splits the next move, `seg` from `at`, whose end junction is `after`, into `out`
    /// (blends go to `out.blends`, numbered from the first this splitter made).
    pub(super) fn split_move(
        &mut self,
        seg: Segment,
        at: &Axes,
        after: Junction,
        out: &mut Prepared,
        n: usize,
    ) {
        let before = std::mem::replace(&mut self.before, after);
        let k = seg.kin();
        if k.len == 0.0 {
            out.segments.push(seg);
            out.points.extend_from_slice(&at[..n]);
            self.prev_v = 0.0;
            self.blend_in = None;
            return;
        }
        let first = out.segments.len();
        let push =
            |out: &mut Prepared, len: f64, lim: (f64, f64, f64), cap: f64, blend: u32, at: Axes| {
                let mut s = seg;
                let (v, a, j) = lim;
                s.set_kin(&Kin { len, v, a, j, cap });
                s.dwell = 0.0;
                s.blend = blend;
                out.segments.push(s);
                out.points.extend_from_slice(&at[..n]);
            };
        let l_in = self.blend_in.map_or(0.0, |(b, ..)| b.reach);
        let (l_out, out_limits) = match after {
            Junction::Blend { blend, v, a, j } => (blend.reach, Some((blend, v, a, j))),
            _ => (0.0, None),
        };
        // Entry cap of the move's first sub-segment, when no blend leads into it.
        let cap_before = match before {
            Junction::Straight => k.v.min(self.prev_v),
            Junction::Stepped => k.cap.min(self.prev_v),
            _ => 0.0,
        };
        if let Some((b, index, bv, ba, bj)) = self.blend_in {
            let v = k.v.min(bv);
            let lim = (v, k.a.min(ba), k.j.min(bj));
            push(
                out,
                l_in,
                lim,
                v.min(self.prev_v),
                2 * index + 1,
                b.point(0.5),
            );
            self.prev_v = v;
        }
        let mid = k.len - l_in - l_out;
        if mid > 1e-9 * k.len {
            let (cap, from) = match self.blend_in {
                Some((b, ..)) => (k.v.min(self.prev_v), b.point(1.0)),
                None => (cap_before, *at),
            };
            push(out, mid, (k.v, k.a, k.j), cap, NO_BLEND, from);
            self.prev_v = k.v;
        }
        self.blend_in = None;
        if let Some((blend, bv, ba, bj)) = out_limits {
            let index = self.blends;
            self.blends += 1;
            out.blends.push(blend);
            let v = k.v.min(bv);
            let cap = if out.segments.len() == first {
                cap_before
            } else {
                v.min(self.prev_v)
            };
            let lim = (v, k.a.min(ba), k.j.min(bj));
            push(out, l_out, lim, cap, 2 * index, blend.point(0.0));
            self.prev_v = v;
            self.blend_in = Some((blend, index, bv, ba, bj));
        }
        if let Some(last) = out.segments.last_mut() {
            last.dwell = seg.dwell;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn axes(x: f64, y: f64) -> Axes {
        Axes::from([x, y, 0.0, 0.0, 0.0, 0.0])
    }

    fn xy(a: f64, j: f64) -> AxisLimits {
        AxisLimits {
            v: [200.0; MAX_AXES],
            a: [a; MAX_AXES],
            j: [j; MAX_AXES],
        }
    }

    #[test]
    fn the_blend_joins_both_moves_smoothly_and_passes_3_16_of_its_turn_from_the_corner() {
        let b = Blend {
            corner: axes(10.0, 0.0),
            reach: 0.04,
            u: axes(1.0, 0.0),
            w: axes(0.0, 1.0),
        };
        let s0 = b.state(0.0, 1.0, 0.0, 0.0);
        let s1 = b.state(1.0, 1.0, 0.0, 0.0);
        assert!((s0[0][0] - 9.96).abs() < 1e-12 && s0[0][1].abs() < 1e-12);
        assert!((s1[0][0] - 10.0).abs() < 1e-12 && (s1[0][1] - 0.04).abs() < 1e-12);
        // Rate u at the start, w at the end; no curvature at either end.
        assert_eq!((s0[1][0], s0[1][1]), (1.0, 0.0));
        assert_eq!((s1[1][0], s1[1][1]), (0.0, 1.0));
        assert_eq!((s0[2][0], s1[2][1]), (0.0, 0.0));
        let mid = b.point(0.5);
        let dev = ((mid[0] - 10.0).powi(2) + mid[1].powi(2)).sqrt();
        let want = DEVIATION * 0.04 * 2f64.sqrt();
        assert!((dev - want).abs() < 1e-12, "{dev} vs {want}");
    }

    #[test]
    fn a_right_angle_is_rounded_within_the_tolerance_at_a_speed_every_axis_can_follow() {
        let (a_max, j_max, delta) = (2000.0, 50_000.0, 0.01);
        let lim = xy(a_max, j_max);
        let kin = Kin {
            len: 10.0,
            v: 100.0,
            a: a_max,
            j: j_max,
            cap: 0.0,
        };
        let (u, w) = (axes(1.0, 0.0), axes(0.0, 1.0));
        let side = |dir| Side {
            dir,
            kin: &kin,
            euclidean: true,
        };
        let Junction::Blend { blend, v, a, j } =
            junction(&axes(10.0, 0.0), side(&u), side(&w), delta, 2.0, &lim, 2)
        else {
            panic!("a right angle at δ = 0.01 is blended");
        };
        assert!(DEVIATION * blend.reach * 2f64.sqrt() <= delta * (1.0 + 1e-12));
        // Sample the blend densely at its caps: every axis within a, j.
        for i in 0..=1000 {
            let x = i as f64 / 1000.0;
            for sa in [-a, a] {
                for sj in [-j, j] {
                    let st = blend.state(x, v, sa, sj);
                    for k in 0..2 {
                        assert!(st[2][k].abs() <= a_max * (1.0 + 1e-9), "a at {x}: {st:?}");
                        assert!(st[3][k].abs() <= j_max * (1.0 + 1e-9), "j at {x}: {st:?}");
                    }
                }
            }
        }
        assert!(v > 1.0 && a > 0.0 && j > 0.0, "{v} {a} {j}");
    }

    #[test]
    fn straight_continuations_reversals_and_zero_tolerance() {
        let lim = xy(2000.0, 50_000.0);
        let kin = Kin {
            len: 1.0,
            v: 50.0,
            a: 2000.0,
            j: 50_000.0,
            cap: 0.0,
        };
        let side = |dir| Side {
            dir,
            kin: &kin,
            euclidean: true,
        };
        let (u, r) = (axes(1.0, 0.0), axes(-1.0, 0.0));
        let c = axes(0.0, 0.0);
        assert_eq!(
            junction(&c, side(&u), side(&u), 0.01, 2.0, &lim, 2),
            Junction::Straight
        );
        assert_eq!(
            junction(&c, side(&u), side(&r), 0.01, 2.0, &lim, 2),
            Junction::Stop
        );
        let w = axes(0.0, 1.0);
        assert_eq!(
            junction(&c, side(&u), side(&w), 0.0, 2.0, &lim, 2),
            Junction::Stop
        );
    }
}
