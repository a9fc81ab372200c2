//! One-dimensional speed profiles along a move's path parameter `s`: closed forms for the
//! trapezoid and the 7-phase jerk-limited S-curve, the reachable-speed relation the look-ahead
//! passes use, the peak-speed solve of one move, and exact evaluation at any instant.
//!
//! Both profile kinds are built from one block, the *ramp*: a symmetric velocity change from
//! `v_lo` up to `v_lo + dv` that starts and ends with zero acceleration. A trapezoid ramp is the
//! same block with infinite jerk. A move is `ramp up (v_entry → v_peak)`, `cruise`, and a
//! time-reversed `ramp up (v_exit → v_peak)`, i.e. the seven S-curve phases of PROCESS.md §4.
//!
//! Everything here is plain `f64` arithmetic without allocation; inputs are assumed validated
//! by the caller (limits > 0, at most one of `a`, `j` infinite, finite speeds and lengths).

/// Phase durations of one ramp: `t_j` for each of the two jerk phases, `t_a` for the
/// constant-acceleration phase between them.
///
/// Velocity change profile (PROCESS.md §4, T1 = T3 = a_max / J, T2 = v / a_max − a_max / J):
/// when `dv ≥ a²/J` the ramp reaches `a`: `t_j = a/J`, `t_a = dv/a − a/J`; otherwise it never
/// reaches `a`: `t_j = √(dv/J)`, `t_a = 0`. Infinite jerk (trapezoid) gives `t_j = 0`.
#[inline]
pub(crate) fn ramp_times(dv: f64, a: f64, j: f64) -> (f64, f64) {
    if dv.is_nan() || dv <= 0.0 {
        return (0.0, 0.0);
    }
    if j == f64::INFINITY {
        return (0.0, dv / a);
    }
    // a²/J is infinite when a is unlimited: a jerk-only ramp never has a constant phase.
    let threshold = a * a / j;
    if dv >= threshold {
        let t_j = a / j;
        (t_j, (dv / a - t_j).max(0.0))
    } else {
        ((dv / j).sqrt(), 0.0)
    }
}

/// Distance covered by a ramp from `v_lo` to `v_lo + dv`. The symmetric jerk pattern makes the
/// mean speed exactly `(v_lo + v_hi) / 2`, so `D = (2 v_lo + dv) / 2 · (2 t_j + t_a)`.
#[inline]
pub(crate) fn ramp_distance(v_lo: f64, dv: f64, a: f64, j: f64) -> f64 {
    let (t_j, t_a) = ramp_times(dv, a, j);
    0.5 * (2.0 * v_lo + dv) * (2.0 * t_j + t_a)
}

/// Ramp distance and its derivative with respect to `dv` (for the Newton solve of the peak).
#[inline]
fn ramp_distance_slope(v_lo: f64, dv: f64, a: f64, j: f64) -> (f64, f64) {
    if dv <= 0.0 {
        // The derivative is +inf (jerk-limited) or (v_lo)/a (trapezoid) at dv = 0; the caller
        // only uses it as a Newton slope, where "very steep" is the safe answer.
        let slope = if j == f64::INFINITY {
            v_lo / a
        } else {
            f64::INFINITY
        };
        return (0.0, slope);
    }
    let w = 2.0 * v_lo + dv;
    if j == f64::INFINITY {
        // The general branch with a/J = 0, without the division (x + 0 = x exactly).
        let t = dv / a;
        (0.5 * w * t, 0.5 * t + 0.5 * w / a)
    } else if dv < a * a / j {
        // No constant-acceleration phase: D = w · √(dv/J).
        let y = (dv / j).sqrt();
        (w * y, y + w / (2.0 * j * y))
    } else {
        let t = dv / a + a / j;
        (0.5 * w * t, 0.5 * t + 0.5 * w / a)
    }
}

/// Highest speed reachable from `v0` over `len` with one ramp (the look-ahead relation).
///
/// It is also the highest speed from which one can slow to `v0` over `len`, because ramps are
/// symmetric. Trapezoid ramps (`J = ∞`): `v² = v0² + 2 a len`. Jerk-limited ramps are solved in
/// closed form too, not with the trapezoid formula:
/// * with `x = dv ≥ a²/J` the distance condition `(2 v0 + x)(x/a + a/J) = 2 len` is a quadratic
///   in `x`, solved in the cancellation-free form `x = 2|c| / (b + √(b² + 4|c|))`;
/// * with `x < a²/J` and `y = √(x/J)` it is the cubic `J y³ + 2 v0 y = len`, solved with
///   Cardano's formula written as `y = q / (A² + p/3 + (p/3A)²)` so no terms cancel.
#[inline]
pub(crate) fn reach(v0: f64, len: f64, a: f64, j: f64) -> f64 {
    if len.is_nan() || len <= 0.0 {
        return v0;
    }
    if j == f64::INFINITY {
        // Trapezoid ramps: v² = v0² + 2 a len, a sum of positive terms (nothing cancels) and
        // one square root, no division: the look-ahead passes run this once per move each, in
        // a chain where every move waits for the next one's result.
        let v = (v0 * v0 + 2.0 * a * len).sqrt();
        return if v.is_finite() { v.max(v0) } else { v0 };
    }
    let threshold = a * a / j;
    // Distance of the ramp that just reaches `a` (2 t_j at mean speed v0 + a²/2J).
    let d_threshold = if j == f64::INFINITY {
        0.0
    } else {
        (2.0 * v0 + threshold) * (a / j)
    };
    let dv = if len <= d_threshold {
        let p = 2.0 * v0 / j;
        let q = len / j;
        let big_a = (0.5 * q + (0.25 * q * q + p * p * p / 27.0).sqrt()).cbrt();
        let b = p / (3.0 * big_a);
        let y = q / (big_a * big_a + p / 3.0 + b * b);
        j * y * y
    } else {
        let b = threshold + 2.0 * v0;
        let c_abs = 2.0 * len * a - 2.0 * v0 * threshold;
        2.0 * c_abs / (b + (b * b + 4.0 * c_abs).sqrt())
    };
    if dv.is_finite() { v0 + dv.max(0.0) } else { v0 }
}

/// Highest entry speed of a move of length `len` from which its exit can be brought to *some*
/// speed `≤ e` (the look-ahead's backward relation).
///
/// For a trapezoid this is `reach(e, len)`. For jerk-limited ramps that start and end at zero
/// acceleration it is not: `reach(v0, len)` first *falls* as `v0` grows (while the ramp's
/// `dv > 2 v0`, resp. `v0 < a²/2J`; a ramp that starts faster has less time, and its speed gain
/// shrinks faster than `v0` grows), so slowing all the way to rest can take less distance than
/// slowing to a low speed. The set of entries that can end at or below `e` is therefore
/// `[0, max(reach(e), reach(0))]`; taking that maximum keeps the relation monotone in `e`,
/// which the streaming window relies on (a longer window only ever raises caps).
///
/// `reach(e)` is not computed where it cannot win: where the ramp from `e` up to `reach(0)`
/// needs more than `len` (by a relative margin of 1e-9, some five orders of magnitude above
/// the rounding of either side), `reach(e) < reach(0)` and the maximum is `reach(0)`, bit for
/// bit. A ramp's distance costs one root, `reach` a root, a cube root and three divisions, and
/// on cornered paths of short moves the slow corners put most entries in that dip
/// (`bench_plan`'s cornered path: 74 % of the backward pass's moves).
#[inline]
pub(crate) fn entry_limit(e: f64, len: f64, a: f64, j: f64) -> f64 {
    if j == f64::INFINITY {
        return reach(e, len, a, j);
    }
    let r0 = reach(0.0, len, a, j);
    if e < r0 && ramp_distance(e, r0 - e, a, j) > len * (1.0 + 1e-9) {
        return r0;
    }
    reach(e, len, a, j).max(r0)
}

/// The exit speed the forward pass commits: the highest speed `≤ e` that a move of length
/// `len` entered at `v_in` can end at. Requires `v_in ≤ entry_limit(e, len)` (up to rounding).
///
/// Accelerating: `min(e, reach(v_in))`. Slowing: `e` itself when the ramp `e → v_in` fits;
/// otherwise `v_in` was admitted through the `reach(0)` branch of [`entry_limit`], and the
/// answer is the largest `w < e` whose ramp `w → v_in` fits, found by bisection on
/// `ramp_distance(w, v_in − w) ≤ len`, which holds on `[0, w_lo]` below `e` ([`bisect_fit`]).
#[inline]
pub(crate) fn exit_speed(v_in: f64, e: f64, len: f64, a: f64, j: f64) -> f64 {
    if v_in <= e {
        return e.min(reach(v_in, len, a, j));
    }
    // Compare with the very expression the backward pass used, not with a recomputed ramp
    // distance: `v_in − e` of two nearby speeds loses digits, and a short ramp's distance
    // `∝ √dv` amplifies that loss far beyond any fixed tolerance.
    if j == f64::INFINITY || v_in <= reach(e, len, a, j) {
        return e;
    }
    let len_ok = len * (1.0 + 1e-12);
    if !(ramp_distance(0.0, v_in, a, j) <= len_ok) {
        // `v_in ≤ reach(0, len)` up to rounding; rest is the closest admissible answer.
        return 0.0;
    }
    bisect_fit(v_in, e, len_ok, a, j, fit_band(v_in, e, len_ok, a, j))
}

/// No band: every step of [`bisect_fit`] computes its ramp.
const NO_BAND: (f64, f64) = (f64::NEG_INFINITY, f64::INFINITY);

/// The bisection of [`exit_speed`]: the largest `w` in `[0, e]` (to `1e-15 · e`) with
/// `ramp_distance(w, v_in − w) ≤ len_ok`, from `fits(0)`. Inside `band = (lo, hi)` each step
/// computes the ramp; below `lo` it fits and above `hi` it does not without computing it
/// ([`fit_band`] proves both), so the steps go the very same way and the answer is the same.
fn bisect_fit(v_in: f64, e: f64, len_ok: f64, a: f64, j: f64, band: (f64, f64)) -> f64 {
    let fits = |w: f64| {
        if w <= band.0 {
            true
        } else if w >= band.1 {
            false
        } else {
            ramp_distance(w, v_in - w, a, j) <= len_ok
        }
    };
    let (mut lo, mut hi) = (0.0, e);
    for _ in 0..64 {
        let mid = 0.5 * (lo + hi);
        if fits(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * e {
            break;
        }
    }
    lo
}

/// Relative margin on a computed ramp distance in [`fit_band`]: about a hundred times the
/// rounding of `ramp_distance` (a few operations, each within half an ulp; its input
/// `v_in − w` rounds within one, which moves the distance by at most 1.5 ulps).
const FIT_MARGIN: f64 = 1e-13;

/// `(lo, hi)` within `[0, e]` such that `ramp_distance(w, v_in − w) ≤ len_ok` as computed holds
/// for every `w ≤ lo` and fails for every `w ≥ hi`, close around the crossing; [`NO_BAND`]
/// where that cannot be shown. The bisection then computes about 5 ramps instead of about 50
/// (3 % of the S-curve moves of `bench_plan`'s cornered path bisect, 50 steps each: as many
/// ramp distances as all other moves' look-ahead together).
///
/// Why it holds: `g(w) = ramp_distance(w, v_in − w)` is concave on `[0, v_in]` (each of its two
/// pieces is, and it is C¹ where they meet: `lead_distance`), so each of its superlevel sets
/// `{g > c}` is an interval. The crossing is bracketed by regula falsi (Illinois), then widened
/// to `lo`, `hi` (by what g's slope there needs to change by the margin), and checked: `g(lo) ≤ len_ok · (1 − m)` puts `lo` outside
/// `{g > len_ok · (1 − m/2)}`, while `g(hi) ≥ len_ok · (1 + m)` puts `hi > lo` inside it, so the
/// whole interval lies above `lo` and every `w ≤ lo` has `g(w)` at least `m/2` below `len_ok`,
/// far more than rounding. Likewise `g(hi)` and `g(e)` both `≥ len_ok · (1 + m)` put `[hi, e]`
/// inside `{g > len_ok · (1 + m/2)}`.
fn fit_band(v_in: f64, e: f64, len_ok: f64, a: f64, j: f64) -> (f64, f64) {
    let g = |w: f64| ramp_distance(w, v_in - w, a, j) - len_ok;
    let (below, above) = (-FIT_MARGIN * len_ok, FIT_MARGIN * len_ok);
    let (mut x0, mut f0) = (0.0, g(0.0));
    let (mut x1, mut f1) = (e, g(e));
    if !(f0 <= below && f1 >= above) {
        return NO_BAND;
    }
    let f_e = f1;
    let mut last = 0i8;
    for _ in 0..16 {
        let x = x1 - f1 * (x1 - x0) / (f1 - f0);
        if !(x > x0 && x < x1) {
            break;
        }
        let fx = g(x);
        if fx <= 0.0 {
            (x0, f0) = (x, fx);
            if last < 0 {
                f1 *= 0.5;
            }
            last = -1;
        } else {
            (x1, f1) = (x, fx);
            if last > 0 {
                f0 *= 0.5;
            }
            last = 1;
        }
        if x1 - x0 <= 1e-14 * e {
            break;
        }
    }
    // Wide enough that g changes by twice the margin on either side: by concavity g's slope
    // at the crossing is at least that of the chord from there to e.
    let slope = f_e / (e - x1);
    let step = (4.0 * above / slope).max(1e-13 * e);
    let (lo, hi) = ((x0 - step).max(0.0), (x1 + step).min(e));
    if lo < hi && g(lo) <= below && g(hi) >= above {
        (lo, hi)
    } else {
        NO_BAND
    }
}

/// Timing of one move along its path: ramp up from `v0` to `vp`, cruise at `vp`, ramp down
/// from `vp` to `v1`. Durations in s, speeds in path units/s.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct Shape {
    pub v0: f64,
    pub vp: f64,
    pub v1: f64,
    pub t_j1: f64,
    pub t_a1: f64,
    pub t_c: f64,
    pub t_j2: f64,
    pub t_a2: f64,
}

/// A move of length `len` is surely too short to ramp from `v0` up to `vmax ≥ max(v0, v1)` and
/// back to `v1`, without computing the ramps: even constant-acceleration ramps, shorter than
/// any jerk-limited one (`t_j ≥ 0` adds distance; without a constant phase
/// `(2v + dv)·√(dv/J) ≥ (2v + dv)·dv/2a` as `dv ≤ a²/J`), need
/// `((vmax² − v0²) + (vmax² − v1²)) / 2a` more than `len`, by a relative 1e-9 that rounding
/// (a few ulps: the differences of squares are formed as products of exact-ish differences)
/// cannot reach. Most moves of a cornered path are far too short to reach their feed, and this
/// spares `shape` two ramp distances each (a root and divisions) before it solves their peak.
#[inline]
fn too_short_to_cruise(len: f64, v0: f64, v1: f64, vmax: f64, a: f64) -> bool {
    let d = (vmax - v0) * (vmax + v0) + (vmax - v1) * (vmax + v1);
    d > 2.0 * a * len * (1.0 + 1e-9)
}

/// Relative tolerance of the peak-speed solve on the distance equation.
const PEAK_REL_TOL: f64 = 1e-14;

/// The fastest profile over `len` from `v0` to `v1` that never exceeds `vmax`, `a`, `j`.
///
/// The caller guarantees that `v1` is reachable from `v0` (the look-ahead passes do); rounding
/// beyond that is absorbed by clamping the cruise to zero.
pub(crate) fn shape(len: f64, v0: f64, v1: f64, vmax: f64, a: f64, j: f64) -> Shape {
    let hi = v0.max(v1);
    let vmax = vmax.max(hi);
    let vp = if len <= 0.0 {
        hi
    } else if vmax.is_finite()
        && !too_short_to_cruise(len, v0, v1, vmax, a)
        && ramp_distance(v0, vmax - v0, a, j) + ramp_distance(v1, vmax - v1, a, j) <= len
    {
        vmax
    } else {
        peak_speed(len, v0, v1, vmax, a, j)
    };
    let (t_j1, t_a1) = ramp_times(vp - v0, a, j);
    let (t_j2, t_a2) = ramp_times(vp - v1, a, j);
    let d1 = 0.5 * (v0 + vp) * (2.0 * t_j1 + t_a1);
    let d2 = 0.5 * (v1 + vp) * (2.0 * t_j2 + t_a2);
    // A residue of rounding is no cruise: snap it so triangles stay exact triangles.
    let rest = len - d1 - d2;
    let t_c = if vp > 0.0 && rest > 8.0 * f64::EPSILON * len {
        rest / vp
    } else {
        0.0
    };
    Shape {
        v0,
        vp,
        v1,
        t_j1,
        t_a1,
        t_c,
        t_j2,
        t_a2,
    }
}

/// Peak speed of a move too short to cruise at `vmax`: the root of
/// `F(vp) = D(v0 → vp) + D(v1 → vp) − len`, which increases with `vp`.
///
/// Trapezoids have the closed form `vp² = (2 a len + v0² + v1²) / 2`. Jerk-limited moves with
/// equal end speeds (every rest-to-rest move) have the closed form `vp = reach(v0, len/2)`,
/// which is what makes rest-to-rest moves time-optimal to rounding. Otherwise a safeguarded
/// Newton iteration (Newton inside a shrinking bracket, bisection when Newton leaves it) finds
/// the root; the trapezoid peak `√((2 a len + v0² + v1²)/2)` bounds it from above, since
/// limiting jerk only lengthens ramps.
fn peak_speed(len: f64, v0: f64, v1: f64, vmax: f64, a: f64, j: f64) -> f64 {
    let hi_v = v0.max(v1);
    if j == f64::INFINITY {
        // Trapezoid: (vp² − v0²)/2a + (vp² − v1²)/2a = len in closed form. Below hi_v the
        // move is one ramp between its end speeds.
        let vp = (0.5 * (2.0 * a * len + v0 * v0 + v1 * v1)).sqrt();
        return if vp.is_finite() {
            vp.clamp(hi_v, vmax)
        } else {
            hi_v
        };
    }
    let f = |vp: f64| {
        ramp_distance_slope(v0, vp - v0, a, j).0 + ramp_distance_slope(v1, vp - v1, a, j).0 - len
    };
    if f(hi_v) >= 0.0 {
        // The whole move is one ramp between the end speeds (or rounding says so).
        return hi_v;
    }
    if v0 == v1 {
        return reach(v0, 0.5 * len, a, j).min(vmax);
    }
    let mut lo = hi_v;
    // Rounding can put the bound a hair below hi_v when the move is one ramp end to end.
    let mut up = (0.5 * (2.0 * a * len + v0 * v0 + v1 * v1))
        .sqrt()
        .min(vmax)
        .max(hi_v);
    if !up.is_finite() {
        // Jerk-only limits and no speed limit: grow a bracket.
        up = (2.0 * hi_v).max(1.0);
        let mut guard = 0;
        while f(up) < 0.0 && guard < 2100 {
            lo = up;
            up *= 2.0;
            guard += 1;
        }
        if !up.is_finite() {
            return lo;
        }
    }
    let tol = PEAK_REL_TOL * len;
    let mut x = up;
    // F at the current x, when known (the loop usually stops right after evaluating it).
    let mut fx_at_x = None;
    for _ in 0..100 {
        let (d0, s0) = ramp_distance_slope(v0, x - v0, a, j);
        let (d1, s1) = ramp_distance_slope(v1, x - v1, a, j);
        let fx = d0 + d1 - len;
        if fx < 0.0 {
            lo = x;
        } else {
            up = x;
        }
        if fx.abs() <= tol || up - lo <= 1e-15 * up {
            fx_at_x = Some(fx);
            break;
        }
        let newton = x - fx / (s0 + s1);
        x = if newton > lo && newton < up {
            newton
        } else {
            0.5 * (lo + up)
        };
    }
    // Never return a peak whose ramps overrun the move.
    if fx_at_x.unwrap_or_else(|| f(x)) > tol {
        lo
    } else {
        x.clamp(hi_v, vmax)
    }
}

/// Exact state of a ramp from `v_lo` by `dv` at time `t` after its start: (s, v, a, j).
///
/// Phase 1 (jerk +J): `s = v_lo t + J t³/6`; phase 2 (acceleration a_p): the quadratic
/// continuation; phase 3 is evaluated backwards from the ramp's end so the end state is exact.
#[inline]
pub(crate) fn ramp_eval(v_lo: f64, dv: f64, t_j: f64, t_a: f64, t: f64) -> (f64, f64, f64, f64) {
    let total = 2.0 * t_j + t_a;
    if total <= 0.0 || t <= 0.0 {
        return (0.0, v_lo, 0.0, 0.0);
    }
    let a_p = dv / (t_j + t_a);
    if t < t_j {
        let jj = a_p / t_j;
        return (
            v_lo * t + jj * t * t * t / 6.0,
            v_lo + 0.5 * jj * t * t,
            jj * t,
            jj,
        );
    }
    if t < t_j + t_a {
        let tau = t - t_j;
        let v_1 = v_lo + 0.5 * a_p * t_j;
        let s_1 = v_lo * t_j + a_p * t_j * t_j / 6.0;
        return (
            s_1 + v_1 * tau + 0.5 * a_p * tau * tau,
            v_1 + a_p * tau,
            a_p,
            0.0,
        );
    }
    let v_hi = v_lo + dv;
    let s_total = 0.5 * (v_lo + v_hi) * total;
    let tau = (total - t).max(0.0);
    if t_j > 0.0 {
        let jj = a_p / t_j;
        (
            s_total - (v_hi * tau - jj * tau * tau * tau / 6.0),
            v_hi - 0.5 * jj * tau * tau,
            jj * tau,
            -jj,
        )
    } else {
        (s_total, v_hi, 0.0, 0.0)
    }
}

impl Shape {
    /// Duration of the ramp up.
    #[inline]
    pub(crate) fn t_up(&self) -> f64 {
        2.0 * self.t_j1 + self.t_a1
    }

    /// Duration of the ramp down.
    #[inline]
    pub(crate) fn t_down(&self) -> f64 {
        2.0 * self.t_j2 + self.t_a2
    }

    /// Duration of the motion (without any dwell).
    #[inline]
    pub(crate) fn duration(&self) -> f64 {
        self.t_up() + self.t_c + self.t_down()
    }

    /// Path state (s, v, a, j) at `t` ∈ [0, duration] of a move of length `len`.
    ///
    /// The ramp down is the ramp up from `v1` run backwards in time, so it is evaluated from the
    /// move's end: `s = len − s_r(τ)`, `v = v_r(τ)`, `a = −a_r(τ)`, `j = j_r(τ)` with τ the time
    /// left. That makes the end state (`s = len`, `v = v1`, `a = 0`) exact.
    #[inline]
    pub(crate) fn eval(&self, len: f64, t: f64) -> (f64, f64, f64, f64) {
        let t_up = self.t_up();
        if t < t_up {
            return ramp_eval(self.v0, self.vp - self.v0, self.t_j1, self.t_a1, t);
        }
        let t_cruise_end = t_up + self.t_c;
        if t < t_cruise_end {
            let s_up = 0.5 * (self.v0 + self.vp) * t_up;
            return (s_up + self.vp * (t - t_up), self.vp, 0.0, 0.0);
        }
        let tau = (t_cruise_end + self.t_down() - t).max(0.0);
        let (s, v, a, j) = ramp_eval(self.v1, self.vp - self.v1, self.t_j2, self.t_a2, tau);
        (len - s, v, -a, j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const INF: f64 = f64::INFINITY;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1.0)
    }

    #[test]
    fn trapezoid_triangle_rest_to_rest_is_two_sqrt_l_over_a() {
        let (l, a) = (2.0, 500.0);
        let sh = shape(l, 0.0, 0.0, INF, a, INF);
        assert!(close(sh.duration(), 2.0 * (l / a).sqrt(), 1e-12), "{sh:?}");
        assert!(close(sh.vp, (l * a).sqrt(), 1e-12));
        assert_eq!(sh.t_c, 0.0);
    }

    #[test]
    fn trapezoid_with_cruise_is_l_over_v_plus_v_over_a() {
        let (l, v, a) = (100.0, 50.0, 500.0);
        let sh = shape(l, 0.0, 0.0, v, a, INF);
        assert!(close(sh.duration(), l / v + v / a, 1e-12), "{sh:?}");
        assert_eq!(sh.vp, v);
        let (s, vv, aa, _) = sh.eval(l, sh.duration());
        assert!(close(s, l, 1e-12) && vv.abs() < 1e-12 && aa == 0.0);
    }

    #[test]
    fn full_s_curve_is_l_over_v_plus_v_over_a_plus_a_over_j() {
        let (l, v, a, j) = (100.0, 50.0, 500.0, 10_000.0);
        let sh = shape(l, 0.0, 0.0, v, a, j);
        assert!(close(sh.duration(), l / v + v / a + a / j, 1e-12), "{sh:?}");
        // T1 = a/J and T2 = v/a − a/J (PROCESS.md §4).
        assert!(close(sh.t_j1, a / j, 1e-12));
        assert!(close(sh.t_a1, v / a - a / j, 1e-12));
    }

    #[test]
    fn s01_s02_s03_match_process_formulas() {
        let (v, a, j) = (50.0, 500.0, 10_000.0);
        let t1 = a / j;
        let t2 = v / a - a / j;
        let (tj, ta) = ramp_times(v, a, j);
        assert!(close(tj, t1, 1e-12) && close(ta, t2, 1e-12));
        let s01 = j * t1.powi(3) / 6.0;
        let s02 = s01 + j * t1 * t1 * t2 / 2.0 + j * t1 * t2 * t2 / 2.0;
        let s03 = s02 + 5.0 / 6.0 * j * t1.powi(3) + j * t1 * t1 * t2;
        let at = |t: f64| ramp_eval(0.0, v, tj, ta, t);
        assert!(close(at(t1).0, s01, 1e-9), "{} vs {s01}", at(t1).0);
        assert!(
            close(at(t1 + t2).0, s02, 1e-9),
            "{} vs {s02}",
            at(t1 + t2).0
        );
        assert!(
            close(at(2.0 * t1 + t2).0, s03, 1e-9),
            "{} vs {s03}",
            at(2.0 * t1 + t2).0
        );
        assert!(close(ramp_distance(0.0, v, a, j), s03, 1e-12));
        // Just inside phase 2 the acceleration is a_max; at the end it is 0 at speed v.
        assert!(close(at(t1 + 0.5 * t2).2, a, 1e-12));
        let end = at(2.0 * t1 + t2);
        assert!(close(end.1, v, 1e-12) && end.2 == 0.0);
    }

    #[test]
    fn no_constant_acceleration_phase_when_v_below_a2_over_j() {
        // v < a²/J: T2 = 0 and the peak acceleration √(vJ) stays below a.
        let (l, v, a, j) = (100.0, 10.0, 500.0, 10_000.0);
        assert!(v < a * a / j);
        let sh = shape(l, 0.0, 0.0, v, a, j);
        let tj = (v / j).sqrt();
        assert!(close(sh.t_j1, tj, 1e-12) && sh.t_a1 == 0.0);
        assert!(close(sh.duration(), l / v + 2.0 * tj, 1e-12), "{sh:?}");
        let (_, _, peak_a, _) = sh.eval(l, tj);
        assert!(close(peak_a, (v * j).sqrt(), 1e-12) && peak_a < a);
    }

    #[test]
    fn short_s_curve_finds_peak_without_constant_phase() {
        // Rest to rest, too short for a or v: T = 4 (L / 2J)^(1/3), peak speed J t_j².
        let (l, j) = (0.01, 10_000.0);
        let sh = shape(l, 0.0, 0.0, 100.0, 500.0, j);
        let tj = (l / (2.0 * j)).cbrt();
        assert!(close(sh.duration(), 4.0 * tj, 1e-12), "{sh:?}");
        assert!(close(sh.vp, j * tj * tj, 1e-12));
    }

    #[test]
    fn short_s_curve_reaching_a_but_not_v() {
        // Rest to rest with a reached, no cruise: vp solves vp²/a + vp a/J = L.
        let (l, a, j) = (5.0, 500.0, 10_000.0);
        let sh = shape(l, 0.0, 0.0, 1000.0, a, j);
        let b = a / j;
        let vp = 0.5 * (-b * a + ((b * a).powi(2) + 4.0 * a * l).sqrt());
        assert!(close(sh.vp, vp, 1e-12), "{} vs {vp}", sh.vp);
        assert!(close(sh.duration(), 2.0 * (vp / a + a / j), 1e-12));
    }

    #[test]
    fn reach_inverts_ramp_distance_in_both_regimes() {
        for &(v0, len) in &[
            (0.0, 1e-4),
            (3.0, 0.05),
            (3.0, 40.0),
            (80.0, 0.2),
            (0.0, 1e3),
        ] {
            for &(a, j) in &[(500.0, 10_000.0), (500.0, INF), (INF, 10_000.0), (2.0, 1e7)] {
                let v1 = reach(v0, len, a, j);
                let d = ramp_distance(v0, v1 - v0, a, j);
                assert!(close(d, len, 1e-11), "v0={v0} len={len} a={a} j={j}: {d}");
            }
        }
    }

    #[test]
    fn jerk_limited_reach_is_not_monotone_but_entry_limit_is() {
        // From rest a ramp gains (L² J)^(1/3); the minimum over v0 is 3 (L² J / 32)^(1/3) at
        // v0 = (L² J / 32)^(1/3) (where dv = 2 v0), about 5.5 % lower.
        let (l, a, j): (f64, f64, f64) = (1.0, 1e9, 1000.0);
        let v_star = (l * l * j / 32.0).cbrt();
        assert!(close(reach(0.0, l, a, j), (l * l * j).cbrt(), 1e-12));
        assert!(close(reach(v_star, l, a, j), 3.0 * v_star, 1e-12));
        assert!(reach(v_star, l, a, j) < reach(0.0, l, a, j));
        let mut last = 0.0;
        for k in 0..200 {
            let e = k as f64 * 0.2;
            let lim = entry_limit(e, l, a, j);
            assert!(lim >= last);
            last = lim;
            // Every entry up to the limit can end at or below e, within the length.
            for f in [0.3, 0.9, 1.0] {
                let v_in = f * lim;
                let w = exit_speed(v_in, e, l, a, j);
                assert!(w <= e);
                let d = ramp_distance(w.min(v_in), (w - v_in).abs(), a, j);
                assert!(d <= l * (1.0 + 1e-12), "e={e} v_in={v_in} w={w} d={d}");
            }
        }
    }

    /// Deterministic uniform numbers in [0, 1) (xorshift64).
    fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    #[test]
    fn entry_limit_is_the_larger_reach_bit_for_bit() {
        // Lengths from 1 µm to 1 m, a and J over four decades (and unlimited a), exit caps
        // from 0 to twice the speed reached from rest: every answer is the very max of the two
        // reaches, whether or not `entry_limit` computed both.
        let mut rnd = uniform(0x2545_f491_4f6c_dd1d);
        let (mut skipped, cases) = (0, 200_000);
        for k in 0..cases {
            let len = 10f64.powf(-3.0 + 6.0 * rnd());
            let a = if k % 10 == 0 {
                INF
            } else {
                10f64.powf(1.0 + 4.0 * rnd())
            };
            let j = 10f64.powf(3.0 + 4.0 * rnd());
            let r0 = reach(0.0, len, a, j);
            let e = if k % 7 == 0 { 0.0 } else { 2.0 * r0 * rnd() };
            let want = reach(e, len, a, j).max(r0);
            assert_eq!(
                entry_limit(e, len, a, j).to_bits(),
                want.to_bits(),
                "e={e} len={len} a={a} j={j}"
            );
            if e < r0 && ramp_distance(e, r0 - e, a, j) > len * (1.0 + 1e-9) {
                skipped += 1;
            }
        }
        // The shortcut was taken often enough to be tested (29 507 of 200 000 here: caps drawn
        // up to twice reach(0), so most lie above the dip).
        assert!(
            skipped > cases / 10,
            "{skipped} of {cases} skipped reach(e)"
        );
    }

    #[test]
    fn banded_bisection_is_the_plain_one_bit_for_bit() {
        // Moves entered faster than their exit cap allows to keep, admitted through reach(0)
        // (`entry_limit`): the bisection with its band ends where the plain one does.
        let mut rnd = uniform(0x9e37_79b9_7f4a_7c15);
        let (mut banded, mut cases) = (0, 0);
        while cases < 20_000 {
            let len = 10f64.powf(-3.0 + 5.0 * rnd());
            let a = if rnd() < 0.1 {
                INF
            } else {
                10f64.powf(1.0 + 4.0 * rnd())
            };
            let j = 10f64.powf(3.0 + 4.0 * rnd());
            let r0 = reach(0.0, len, a, j);
            let v_in = r0 * rnd().sqrt();
            let e = v_in * rnd();
            let len_ok = len * (1.0 + 1e-12);
            if v_in <= reach(e, len, a, j) || ramp_distance(0.0, v_in, a, j) > len_ok {
                continue;
            }
            cases += 1;
            let band = fit_band(v_in, e, len_ok, a, j);
            banded += usize::from(band != NO_BAND);
            let plain = bisect_fit(v_in, e, len_ok, a, j, NO_BAND);
            assert_eq!(
                exit_speed(v_in, e, len, a, j).to_bits(),
                plain.to_bits(),
                "v_in={v_in} e={e} len={len} a={a} j={j} band={band:?}"
            );
        }
        assert!(banded > cases * 9 / 10, "{banded} of {cases} banded");
    }

    #[test]
    fn moves_too_short_to_cruise_could_not_cruise() {
        // Wherever the shortcut says a move cannot cruise at vmax, its ramps as computed need
        // more than its length; and it does say so for most short moves.
        let mut rnd = uniform(0x5851_f42d_4c95_7f2d);
        let (mut said, cases) = (0, 100_000);
        for _ in 0..cases {
            let len = 10f64.powf(-3.0 + 5.0 * rnd());
            let a = 10f64.powf(1.0 + 4.0 * rnd());
            let j = if rnd() < 0.2 {
                INF
            } else {
                10f64.powf(3.0 + 4.0 * rnd())
            };
            let vmax = 10f64.powf(4.0 * rnd());
            let (v0, v1) = (vmax * rnd(), vmax * rnd());
            if too_short_to_cruise(len, v0, v1, vmax, a) {
                said += 1;
                let d = ramp_distance(v0, vmax - v0, a, j) + ramp_distance(v1, vmax - v1, a, j);
                assert!(
                    d > len,
                    "len={len} v0={v0} v1={v1} vmax={vmax} a={a} j={j}: {d}"
                );
            }
        }
        assert!(said > cases / 4, "{said} of {cases}");
    }

    #[test]
    fn nonzero_end_speeds_fill_the_length_exactly() {
        for &(l, v0, v1, vmax, a, j) in &[
            (1.0, 5.0, 20.0, 100.0, 500.0, 1e4),
            (1.0, 20.0, 5.0, 100.0, 500.0, 1e4),
            (0.5, 12.0, 3.0, 100.0, 500.0, 1e4),
            (10.0, 12.0, 3.0, 30.0, 500.0, 1e4),
            (0.3, 0.0, 7.0, 1e9, 500.0, INF),
            (0.3, 1.0, 7.0, INF, INF, 1e5),
        ] {
            let sh = shape(l, v0, v1, vmax, a, j);
            let (s, v, acc, _) = sh.eval(l, sh.duration());
            let d =
                0.5 * (v0 + sh.vp) * sh.t_up() + sh.vp * sh.t_c + 0.5 * (v1 + sh.vp) * sh.t_down();
            assert!(close(d, l, 1e-12), "{sh:?} covers {d}, not {l}");
            assert!(close(s, l, 1e-12) && close(v, v1, 1e-12) && acc == 0.0);
            assert!(sh.vp <= vmax);
            // Time-reversal symmetry: swapping end speeds gives the same duration.
            let rev = shape(l, v1, v0, vmax, a, j);
            assert!(close(rev.duration(), sh.duration(), 1e-10));
        }
    }

    #[test]
    fn eval_is_continuous_at_phase_boundaries() {
        let sh = shape(3.0, 2.0, 1.0, 40.0, 300.0, 5000.0);
        let bounds = [
            sh.t_j1,
            sh.t_j1 + sh.t_a1,
            sh.t_up(),
            sh.t_up() + sh.t_c,
            sh.t_up() + sh.t_c + sh.t_j2,
            sh.t_up() + sh.t_c + sh.t_j2 + sh.t_a2,
        ];
        for b in bounds {
            let e = 1e-9;
            let (s0, v0, a0, _) = sh.eval(3.0, b - e);
            let (s1, v1, a1, _) = sh.eval(3.0, b + e);
            assert!((s0 - s1).abs() < 1e-7 && (v0 - v1).abs() < 1e-5 && (a0 - a1).abs() < 1e-2);
        }
    }
}
