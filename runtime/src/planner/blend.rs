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
//! lead-ins add it: `motion::leadin`) — except between two lit moves (`MoveInfo::lit_before`),
//! which no lead-in ends at: there only the halves bound it, so the blends of a lit arc's
//! chords abut (the smoothstep's jerk, `1.5·|Δu|·v³/ℓ²`, falls with ℓ², and a flat bed's lit
//! arc keeps its speed where blends of `4·δ` would slow it; dial_marks' circle keeps 40 mm/s).
//!
//! **Limits along it.** With path speed `v`, acceleration `a`, jerk `j`, axis k moves at
//! `q'_k v`, accelerates at `q''_k v² + q'_k a` and jerks at `q'''_k v³ + 3 q''_k v a + q'_k j`.
//! The blend gets its own speed cap, path acceleration and path jerk so that each of those is
//! within the axis's limit everywhere on the blend ([`limits`]): the curvature terms get at
//! most [`SHARE`] of each axis's acceleration and jerk, the path's own changes what is left.
//! A corner the plan cannot round (δ = 0, a reversal on a Cartesian path) is a stop.
//!
//! **Runs of chords.** Where the blends of a curve's chords abut (each reaches half of every
//! chord, so the path is curved throughout), their curvature returns to zero at every chord
//! midpoint: `0 → 1.5κ → 0` per chord, a jerk of about `6·v³·κ/L` that would hold a lit arc
//! below its feed. There two abutting blends that sample one smooth curve (`curve_like`: their
//! mean curvatures `Δu/2ℓ` differ by at most half) share the axis curvature at the midpoint
//! between them ([`shared_curvature`], the central difference of the chords' rates): each
//! blend's rate gets the quartic terms `2ℓ·(g0·p(x) − g1·p(1 − x))`, `p(x) = x(1 − x)²(1 −
//! 5x/2)`, which set `q''` to `g0` at its start and `g1` at its end without moving its ends or
//! changing their rates, so each axis's acceleration is continuous across the run and, on a
//! circle's chords, the blends bend like the circle (`q'''` about `6·κ²` per unit path³ instead
//! of `3·κ/ℓ`). The curvature ramps in over the first and last `LEVELS − 1` midpoints of a run
//! (`Blend::shared` keeps the level at each end), runs shorter than `MIN_RUN` midpoints keep
//! the smoothstep (their ramps would cost more than they gain), and a shared curvature is used
//! only where both blends stay within δ of their corners with it (`|3/16·ℓ·Δu + ℓ²/16·(g0 +
//! g1)|`, whatever the other ends share). On a Cartesian path that is the spot's distance; where
//! a length is a part-space chord of mm and rad axes (oriented machines) the same bound is
//! taken in part space, to first order, from the spot's part-space directions of the three
//! moves (`judge::part_blend`: `J·Δq/length` is the spot's unit direction, so the Jacobian maps
//! the axis-space offset and shared curvature to those of the part-space rates; exact on the
//! rotary attachment's linear map, 0.06 δ at most through the arm's forward kinematics on its
//! section at 6 mm/s, `trace_axis_limits`). Two blends abut where their reaches cover the chord between them to
//! within [`ABUT`]: a spline's chords are equal in its parameter, not in length, and leave a
//! straight piece of a few 1e-9 of the chord between half-chord reaches (the acceleration dip
//! across it lasts under 1e-6·L/v and moves no axis measurably). Each blend's limits come from
//! its own largest `|q'|`, `|q''|`, `|q'''|` (`Blend::bounds`).
//!
//! **In the plan.** `prepare` splits each move into the second half of the blend at its start,
//! its straight middle, and the first half of the blend at its end; all three keep the move's
//! tag, so every op keeps its path length and its segments. The corner point itself (σ = 0) is
//! a segment boundary, where the plan switches ops exactly as before.

use super::lookahead::Kin;
use super::plan::{NO_BLEND, Segment};
use super::{Axes, AxisLimits, MAX_AXES, Prepared};

mod expand;
mod judge;
mod table;
use judge::Whole;
pub(super) use judge::{MoveSource, READS_AHEAD, READS_BEHIND, junction_at};
pub use table::Blends;

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

/// Relative slack on "two blends abut": their reaches add up to the length of the chord
/// between them (each is at most half of it). A spline's chords, equal in its parameter, differ
/// in length by up to 2e-7 of a chord from one to the next on the arm's sections (1e-9 left
/// almost every run unshared there).
const ABUT: f64 = 1e-6;

/// Cosine of a reversal on a Cartesian path (stop there).
const REVERSAL_COS: f64 = -1.0 + 1e-9;

/// One blend: its corner, its reach along each move, the two moves' `Δq / length`, and
/// whether it shares its end curvatures with the blends beside it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blend {
    pub corner: Axes,
    pub reach: f64,
    pub u: Axes,
    pub w: Axes,
    /// How much of the curvature it shares with the blend before it (low four bits) and after
    /// it (high four bits), in steps of `1 / LEVELS` ([`Blend::levels`]): 0 where that end
    /// is the smoothstep's (zero curvature), `LEVELS` where the move between the two is a
    /// chord wholly inside both and they bend there like the curve the chords sample
    /// ([`shared_curvature`]), less where a run of chords ramps into that curvature.
    pub shared: u8,
}

/// Steps of [`Blend::shared`]: a run of chords ramps into its curvature over `LEVELS − 1`
/// midpoints from each end.
pub const LEVELS: u8 = 3;

/// Fewest midpoints a run of chords shares its curvature over: in a shorter one (a glyph's
/// curve of a few chords) the ramps at its ends, which need more jerk than the smoothstep,
/// would cost more than its middle gains.
const MIN_RUN: usize = 8;

impl Blend {
    /// The levels of curvature shared at the start and the end (`shared`).
    pub fn levels(&self) -> (u8, u8) {
        (self.shared & 0x0f, self.shared >> 4)
    }
}

/// [`shared_curvature`] at `level` of [`LEVELS`].
pub fn shared_at(prev: &Blend, next: &Blend, level: u8) -> Axes {
    let g = shared_curvature(prev, next);
    let scale = f64::from(level) / f64::from(LEVELS);
    let mut out = Axes::ZERO;
    for k in 0..MAX_AXES {
        out[k] = g[k] * scale;
    }
    out
}

/// The axis curvature `q''` two abutting blends share where they meet, at the midpoint of the
/// chord between their corners: the central difference of the rates of the chords before and
/// after it, `(w_next − u_prev) / (2ℓ_prev + 2ℓ_next)`. On the chords of a circle of radius R
/// turning by φ each it is the curvature `cos(φ/2)/R` towards the centre, the same at every
/// chord, so the blends of a run of chords bend like the curve they sample.
pub fn shared_curvature(prev: &Blend, next: &Blend) -> Axes {
    let mut g = Axes::ZERO;
    let span = 2.0 * (prev.reach + next.reach);
    for k in 0..MAX_AXES {
        g[k] = (next.w[k] - prev.u[k]) / span;
    }
    g
}

/// Whether two abutting blends sample one smooth curve: their mean curvatures `Δu / 2ℓ` differ
/// by at most [`CURVE_LIKE`] of the larger (on the chords of a circle turning by φ each, by
/// `2·sin(φ/2)`). Elsewhere (the corners of a glyph's short strokes) sharing the curvature
/// would only bend the blends harder than their own turns; they keep the smoothstep.
fn curve_like(a: &Blend, b: &Blend, n: usize) -> bool {
    let (mut diff, mut ka, mut kb) = (0.0f64, 0.0f64, 0.0f64);
    for k in 0..n {
        let ca = (a.w[k] - a.u[k]) / (2.0 * a.reach);
        let cb = (b.w[k] - b.u[k]) / (2.0 * b.reach);
        diff += (cb - ca) * (cb - ca);
        ka += ca * ca;
        kb += cb * cb;
    }
    diff.sqrt() <= CURVE_LIKE * ka.max(kb).sqrt()
}

/// How much the mean curvatures of two abutting blends may differ, relative to the larger, for
/// them to share their curvature (`curve_like`).
const CURVE_LIKE: f64 = 0.5;

/// `(P, p, p', p'')` at `x`: `p(x) = x(1 − x)²(1 − 5x/2)`, the rate term that gives a blend the
/// axis curvature `g0` at its start without moving its ends or changing its end rates:
/// `p(0) = p(1) = 0`, `∫₀¹ p = 0`, `p'(0) = 1`, `p'(1) = 0`; `P = ∫₀ˣ p`. Its mirror
/// `−p(1 − x)` does the same for `g1` at the end.
#[inline]
fn ramp(x: f64) -> (f64, f64, f64, f64) {
    let (x2, x3) = (x * x, x * x * x);
    (
        0.5 * x2 - 1.5 * x3 + 1.5 * x2 * x2 - 0.5 * x2 * x3,
        x - 4.5 * x2 + 6.0 * x3 - 2.5 * x2 * x2,
        1.0 - 9.0 * x + 18.0 * x2 - 10.0 * x3,
        -9.0 + 36.0 * x - 30.0 * x2,
    )
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
    /// Axis positions at `x = (σ + ℓ)/(2ℓ)`, clamped to `[0, 1]`, of the smoothstep blend
    /// (zero curvature at both ends; [`Blend::point_curved`] with the shared curvatures).
    pub fn point(&self, x: f64) -> Axes {
        self.point_curved(x, &Axes::ZERO, &Axes::ZERO)
    }

    /// Axis positions at `x`, with axis curvature `g0` at the start and `g1` at the end:
    /// `q = C − uℓ + 2ℓ·(u·x + Δu·H(x) + 2ℓ·(g0·P(x) + g1·P(1 − x)))` (`ramp`).
    pub fn point_curved(&self, x: f64, g0: &Axes, g1: &Axes) -> Axes {
        let x = x.clamp(0.0, 1.0);
        let (hh, ..) = smoothstep(x);
        let (p0, ..) = ramp(x);
        let (p1, ..) = ramp(1.0 - x);
        let l2 = 2.0 * self.reach;
        let mut q = Axes::ZERO;
        for k in 0..MAX_AXES {
            let du = self.w[k] - self.u[k];
            let curved = l2 * (g0[k] * p0 + g1[k] * p1);
            q[k] =
                self.corner[k] - self.u[k] * self.reach + l2 * (self.u[k] * x + du * hh + curved);
        }
        q
    }

    /// Axis positions, velocities, accelerations and jerks at `x` along the smoothstep blend,
    /// at path speed `v`, acceleration `a` and jerk `j`.
    pub fn state(&self, x: f64, v: f64, a: f64, j: f64) -> [Axes; 4] {
        self.state_curved(x, v, a, j, &Axes::ZERO, &Axes::ZERO)
    }

    /// [`Blend::state`] with axis curvature `g0` at the start and `g1` at the end.
    #[allow(clippy::too_many_arguments)] // the path state and both end curvatures
    pub fn state_curved(&self, x: f64, v: f64, a: f64, j: f64, g0: &Axes, g1: &Axes) -> [Axes; 4] {
        let x = x.clamp(0.0, 1.0);
        let mut out = [
            self.point_curved(x, g0, g1),
            Axes::ZERO,
            Axes::ZERO,
            Axes::ZERO,
        ];
        for k in 0..MAX_AXES {
            let [d1, d2, d3] = self.rates(k, x, g0[k], g1[k]);
            out[1][k] = d1 * v;
            out[2][k] = d2 * v * v + d1 * a;
            out[3][k] = d3 * v * v * v + 3.0 * d2 * v * a + d1 * j;
        }
        out
    }

    /// Axis `k`'s `q'`, `q''`, `q'''` (per unit path) at `x`, with end curvatures `g0`, `g1`.
    #[inline]
    fn rates(&self, k: usize, x: f64, g0: f64, g1: f64) -> [f64; 3] {
        let (_, h, h1, h2) = smoothstep(x);
        let (_, p0, p0d, p0dd) = ramp(x);
        let (_, p1, p1d, p1dd) = ramp(1.0 - x);
        let l = self.reach;
        let du = self.w[k] - self.u[k];
        [
            self.u[k] + du * h + 2.0 * l * (g0 * p0 - g1 * p1),
            du * h1 / (2.0 * l) + g0 * p0d + g1 * p1d,
            du * h2 / (4.0 * l * l) + (g0 * p0dd - g1 * p1dd) / (2.0 * l),
        ]
    }

    /// Per axis, the largest `|q'|`, `|q''|` and `|q'''|` along the blend with end curvatures
    /// `g0`, `g1`: `q''` is a cubic in `x` and `q'''` a quadratic, so both are taken at the ends
    /// and at their stationary points; `|q'|` (a quartic) at 65 points, plus the most it can
    /// rise between two of them, `ℓ·max|q''|/64`. For the smoothstep these are `max(|u|, |w|)`,
    /// `0.75·|Δu|/ℓ` and `1.5·|Δu|/ℓ²` (module doc).
    fn bounds(&self, g0: &Axes, g1: &Axes, n: usize) -> [[f64; 3]; MAX_AXES] {
        let l = self.reach;
        let mut out = [[0.0; 3]; MAX_AXES];
        for k in 0..n {
            let du = self.w[k] - self.u[k];
            if g0[k] == 0.0 && g1[k] == 0.0 {
                out[k] = [
                    self.u[k].abs().max(self.w[k].abs()),
                    0.75 * du.abs() / l,
                    1.5 * du.abs() / (l * l),
                ];
                continue;
            }
            // d q''/dx = c0 + c1·x + c2·x²: A·h''(x) + g0·p''(x) − g1·p''(1 − x), A = Δu/(2ℓ).
            let aa = du / (2.0 * l);
            let (a, b) = (g0[k], g1[k]);
            let c = [
                6.0 * aa - 9.0 * a + 3.0 * b,
                -12.0 * aa + 36.0 * a - 24.0 * b,
                -30.0 * a + 30.0 * b,
            ];
            let mut xs = [0.0, 1.0, -1.0, -1.0, -1.0];
            if c[2] != 0.0 {
                let disc = c[1] * c[1] - 4.0 * c[2] * c[0];
                if disc >= 0.0 {
                    let r = disc.sqrt();
                    xs[2] = (-c[1] + r) / (2.0 * c[2]);
                    xs[3] = (-c[1] - r) / (2.0 * c[2]);
                }
                xs[4] = -c[1] / (2.0 * c[2]);
            } else if c[1] != 0.0 {
                xs[2] = -c[0] / c[1];
            }
            let (mut m2, mut m3) = (0.0f64, 0.0f64);
            for &x in xs.iter().filter(|x| (0.0..=1.0).contains(*x)) {
                let [_, d2, d3] = self.rates(k, x, a, b);
                m2 = m2.max(d2.abs());
                m3 = m3.max(d3.abs());
            }
            let mut m1 = 0.0f64;
            for i in 0..=64 {
                m1 = m1.max(self.rates(k, i as f64 / 64.0, a, b)[0].abs());
            }
            out[k] = [m1 + l * m2 / 64.0, m2, m3];
        }
        out
    }

    /// How far the blend passes from its corner (at σ = 0), in axis space:
    /// `|3/16·ℓ·Δu + ℓ²/16·(g0 + g1)|` (`H(½) = 3/32`, `P(½) = 1/64`).
    fn deviation(&self, g0: &Axes, g1: &Axes, n: usize) -> f64 {
        let l = self.reach;
        (0..n)
            .map(|k| {
                let d = DEVIATION * l * (self.w[k] - self.u[k]) + l * l / 16.0 * (g0[k] + g1[k]);
                d * d
            })
            .sum::<f64>()
            .sqrt()
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

/// A junction that is not rounded: what `shape` says instead of a blend (small, so that its
/// `Result` stays small).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Unrounded {
    Straight,
    Stop,
    Stepped,
}

impl From<Unrounded> for Junction {
    fn from(u: Unrounded) -> Junction {
        match u {
            Unrounded::Straight => Junction::Straight,
            Unrounded::Stop => Junction::Stop,
            Unrounded::Stepped => Junction::Stepped,
        }
    }
}

/// The moves on either side of a junction: `Δq / length`, length, speed and path limits
/// (`Kin`), and whether the length is the axis-space length (`euclidean`).
pub(crate) struct Side<'a> {
    pub dir: &'a Axes,
    pub kin: &'a Kin,
    pub euclidean: bool,
}

/// Largest reach of a blend along each of its moves: [`REACH_MAX`]`·δ`, so that a lead-in
/// loses at most that much of its straight ramp, except between two lit moves (no lead-in
/// there), where only the moves' halves bound it.
fn reach_cap(delta: f64, lit: bool) -> f64 {
    if lit {
        f64::INFINITY
    } else {
        REACH_MAX * delta
    }
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
/// `part_turn` bounds the spot's turn where the moves' lengths are not axis-space lengths;
/// `lit`: both moves are lit (`reach_cap`). A blend is the smoothstep here; `split` gives the
/// blends of a run of chords their shared curvatures.
#[cfg(test)]
#[allow(clippy::too_many_arguments)] // the corner, its two moves and the machine
pub(crate) fn junction(
    corner: &Axes,
    prev: Side<'_>,
    next: Side<'_>,
    delta: f64,
    part_turn: f64,
    lit: bool,
    limits: &AxisLimits,
    n_axes: usize,
) -> Junction {
    match shape(corner, &prev, &next, delta, part_turn, lit, n_axes) {
        Ok(blend) => with_limits(
            blend,
            &Axes::ZERO,
            &Axes::ZERO,
            prev.kin,
            next.kin,
            limits,
            n_axes,
        ),
        Err(other) => other.into(),
    }
}

/// The blend that rounds the junction (module doc: its reach), or what the junction is
/// instead: straight, a stop.
#[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
fn shape(
    corner: &Axes,
    prev: &Side<'_>,
    next: &Side<'_>,
    delta: f64,
    part_turn: f64,
    lit: bool,
    n_axes: usize,
) -> Result<Blend, Unrounded> {
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
        return Err(Unrounded::Straight);
    }
    let euclidean = prev.euclidean && next.euclidean;
    if delta == 0.0 || (euclidean && cos <= REVERSAL_COS) {
        return Err(Unrounded::Stop);
    }
    let turn = if euclidean { du2.sqrt() } else { part_turn };
    let reach = (delta / (DEVIATION * turn))
        .min(reach_cap(delta, lit))
        .min(0.5 * prev.kin.len.min(next.kin.len));
    if !(reach > 0.0 && reach.is_finite()) {
        return Err(Unrounded::Stop);
    }
    Ok(Blend {
        corner: *corner,
        reach,
        u: *u,
        w: *w,
        shared: 0,
    })
}

/// `blend` with end curvatures `g0`, `g1`, and the limits that keep every axis within its own
/// along it (`limits_along`); a stop where none are left.
fn with_limits(
    blend: Blend,
    g0: &Axes,
    g1: &Axes,
    prev: &Kin,
    next: &Kin,
    limits: &AxisLimits,
    n_axes: usize,
) -> Junction {
    let n = n_axes.min(MAX_AXES);
    let bounds = blend.bounds(g0, g1, n);
    let v_moves = prev.v.min(next.v);
    let a_moves = prev.a.min(next.a);
    let j_moves = prev.j.min(next.j);
    let (v, a, j) = limits_along(&bounds, v_moves, a_moves, j_moves, limits, n);
    if !(v > 0.0 && a > 0.0 && j > 0.0) {
        return Junction::Stop;
    }
    Junction::Blend { blend, v, a, j }
}

/// Speed cap, path acceleration and path jerk of a blend whose axis k has at most
/// `c1 = |q'_k|`, `c2 = |q''_k|`, `c3 = |q'''_k|` along it (`bounds[k]`, `Blend::bounds`; for
/// the smoothstep `c1 = max(|u_k|, |w_k|)`, `c2 = 0.75·|Δu_k|/ℓ`, `c3 = 1.5·|Δu_k|/ℓ²`):
/// `c2·v² ≤ SHARE·a_k`, `c3·v³ + 3·c2·v·a₀ ≤ SHARE·j_k` and `c1·v ≤ v_k` give the cap
/// (`a₀ = (1 − SHARE)·min a_k/c1`, the least the path keeps); at the highest speed `v` the
/// blend can then be taken at, the path acceleration is what is left of every axis's,
/// `a = min (a_k − c2·v²)/c1`, no more than the jerk budget allows
/// (`3·c2·v·a ≤ SHARE·j_k − c3·v³`), and the path jerk what is left of every axis's,
/// `j = min (j_k − c3·v³ − 3·c2·v·a)/c1`. Each is at least `(1 − SHARE)` of the axis's limit
/// over `c1`. The moves' own limits (`v_moves`, …) bound the results; an infinite `j_moves`
/// (trapezoid plans) leaves jerk out.
#[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
pub(crate) fn limits_along(
    bounds: &[[f64; 3]; MAX_AXES],
    v_moves: f64,
    a_moves: f64,
    j_moves: f64,
    limits: &AxisLimits,
    n: usize,
) -> (f64, f64, f64) {
    let scurve = j_moves.is_finite();
    let mut a0 = a_moves;
    for k in 0..n {
        let m = bounds[k][0];
        if m > 0.0 {
            a0 = a0.min((1.0 - SHARE) * limits.a[k] / m);
        }
    }
    let mut v = v_moves;
    for k in 0..n {
        let [m, c2, c3] = bounds[k];
        if m > 0.0 {
            v = v.min(limits.v[k] / m);
        }
        if c2 == 0.0 && c3 == 0.0 {
            continue;
        }
        if c2 > 0.0 {
            v = v.min((SHARE * limits.a[k] / c2).sqrt());
        }
        if scurve && limits.j[k].is_finite() {
            let a_term = if a0.is_finite() { a0 } else { 0.0 };
            let g = |v: f64| c3 * v * v * v + 3.0 * c2 * v * a_term;
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
        let [m, c2, c3] = bounds[k];
        if m > 0.0 {
            a = a.min((limits.a[k] - c2 * v * v) / m);
        }
        if scurve && c2 > 0.0 && v > 0.0 && limits.j[k].is_finite() {
            let left = SHARE * limits.j[k] - c3 * v * v * v;
            a = a.min(left / (3.0 * c2 * v));
        }
    }
    if !scurve {
        return (v, a, j_moves);
    }
    let mut j = j_moves;
    for k in 0..n {
        let [m, c2, c3] = bounds[k];
        if m > 0.0 && limits.j[k].is_finite() {
            let used = c3 * v * v * v + 3.0 * c2 * v * a;
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
    /// The move and the one before it are lit (`Along::lit`): their blend is not bounded by
    /// [`REACH_MAX`].
    pub lit_before: bool,
}

impl MoveInfo {
    /// A standstill (a dwell before any motion).
    pub(crate) const REST: MoveInfo = MoveInfo {
        euclidean: true,
        stop_before: true,
        part_dir: [0.0; 3],
        stepped_before: false,
        lit_before: false,
    };
}

/// The [`MoveInfo`] of every segment `prepare` made, a byte a move where every length is the
/// axis-space length (every Cartesian job; a `MoveInfo` is 32 bytes, issue 18): a move's
/// part-space direction only counts at a junction where a length is not (`junction`'s
/// `part_turn`), so directions are kept from the move before the first such move on.
#[derive(Default)]
pub(crate) struct MoveInfos {
    /// `EUCLIDEAN | STOP_BEFORE | STEPPED_BEFORE | LIT_BEFORE` of each move.
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
const LIT_BEFORE: u8 = 8;

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
                | bit(m.stepped_before, STEPPED_BEFORE)
                | bit(m.lit_before, LIT_BEFORE),
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
            lit_before: f & LIT_BEFORE != 0,
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
    // How many segments and blends the split makes at most (`expand::bound`: a blend's limits
    // leave a corner a stop only where the axis limits allow no motion at all, and
    // `junction_at` decides each corner in the split).
    let bound = expand::bound(
        &Whole {
            p: &p,
            info,
            start,
            n,
        },
        delta,
        n,
    );
    if bound.1 == 0 {
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
    // The split segments are written into the prepared moves' own table (`expand`).
    expand::split_in_place(p, info, start, delta, limits, n, bound)
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
        // A half of a blend keeps no point (`at: None`): it starts on its blend
        // (`Plan::segment_start`).
        let push = |out: &mut Prepared,
                    len: f64,
                    lim: (f64, f64, f64),
                    cap: f64,
                    blend: u32,
                    at: Option<Axes>| {
            let mut s = seg;
            let (v, a, j) = lim;
            s.set_kin(&Kin { len, v, a, j, cap });
            s.dwell = 0.0;
            s.blend = blend;
            out.segments.push(s);
            if let Some(at) = at {
                out.points.extend_from_slice(&at[..n]);
            }
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
        if let Some((_, index, bv, ba, bj)) = self.blend_in {
            let v = k.v.min(bv);
            let lim = (v, k.a.min(ba), k.j.min(bj));
            push(out, l_in, lim, v.min(self.prev_v), 2 * index + 1, None);
            self.prev_v = v;
        }
        let mid = k.len - l_in - l_out;
        if mid > 1e-9 * k.len {
            let (cap, from) = match self.blend_in {
                Some((b, ..)) => (k.v.min(self.prev_v), b.point(1.0)),
                None => (cap_before, *at),
            };
            push(out, mid, (k.v, k.a, k.j), cap, NO_BLEND, Some(from));
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
            push(out, l_out, lim, cap, 2 * index, None);
            self.prev_v = v;
            self.blend_in = Some((blend, index, bv, ba, bj));
        }
        if let Some(last) = out.segments.last_mut() {
            last.dwell = seg.dwell;
        }
    }
}

#[cfg(test)]
mod tests;
