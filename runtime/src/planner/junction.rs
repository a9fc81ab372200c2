//! Corner speeds: the junction-deviation model of GRBL and Klipper with Klipper's centripetal
//! cap where the path parameter is arc length in axis space, and a per-axis rule where it is not.
//!
//! **Which rule.** A move's direction `u = Δq / length` is a unit vector only when its length is
//! its Euclidean length in axis space: the caller then says that axis space is the space the
//! path lives in (every Cartesian machine: X, Y, Z in mm, length the spot's distance), angles
//! between directions mean something, and the GRBL/Klipper rule below is kept as it always was.
//! A multi-axis chord of an oriented machine (X in mm, joints in rad) has the spot's part-space
//! distance as its length: `u` then mixes mm/mm and rad/mm, the "angle" between two such
//! directions depends on the choice of units, and only the per-axis rule is meaningful. A
//! junction gets the per-axis rule as soon as one of its moves is of that kind (`prepare` decides
//! per move, with a relative tolerance of 1e-9 on the length).
//!
//! **Junction deviation.** The corner between two moves is rounded, in the model only, by an arc
//! that deviates `δ = junction_deviation` from the corner point; the junction speed is the speed
//! at which that arc's centripetal acceleration equals the acceleration limit. With `θ` the
//! angle between the reversed incoming and the outgoing direction (GRBL's
//! `junction_cos_theta`), `v² = a · δ · sin(θ/2) / (1 − sin(θ/2))`.
//!
//! **Centripetal cap** (Klipper `toolhead.py`, "approximated centripetal velocity":
//! `move_centripetal_v2 = .5 * move_d * tan_theta_d2 * accel`). Junction deviation alone lets a
//! curve split into short chords run far too fast: each chord turns by a small angle, so each
//! rounding arc of radius `δ·sin/(1 − sin)` is huge, although the chords together turn like a
//! circle of the curve's radius. The rounding circle must instead touch both moves no further
//! from the corner than their midpoints. Derivation: a circle tangent to both lines of a corner
//! with interior angle `θ` has its centre on the bisector, and touches each line at distance
//! `d = r / tan(θ/2)` from the corner. With `d = ½·min(L_prev, L_next)`, the largest circle
//! that stays within the moves' halves has `r = ½·min(L_prev, L_next)·tan(θ/2)`, and the corner
//! speed obeys `v² ≤ a_n · r`, with `a_n` the acceleration the axes allow along the circle's
//! normal at the corner (the direction `next − prev`). On the chords of a circle of radius `R`
//! turning by `φ` each (`L = 2R sin(φ/2)`, `θ = π − φ`), this circle passes through the chord
//! midpoints: `r = R sin(φ/2) · cot(φ/2) = R cos(φ/2) ≤ R`, so `v² ≤ a_n R`, the arc's own
//! limit, however finely the arc is split.
//!
//! **Per-axis rule.** With `u`, `w` the incoming and outgoing `Δq / length` (axis units per unit
//! of path) and the path speed `v` continuous through the junction, axis k's velocity jumps by
//! `v·Δu_k`, `Δu_k = w_k − u_k`. Each axis is judged in its own units against its own
//! acceleration `a_k`, never against another axis. The model rounds the jump with a parabolic
//! blend: over the path window `s ∈ [−ℓ, ℓ]` around the corner `C`, `q'(s)` goes linearly from
//! `u` to `w`, i.e. `q(s) = C + ½(u + w)·s + Δu·s²/(4ℓ) + Δu·ℓ/4`, which leaves the incoming
//! move at `s = −ℓ` and joins the outgoing one at `s = ℓ` with matching slopes. At path speed
//! `v` axis k then accelerates at `v²·|Δu_k|/(2ℓ)` for a time `T = 2ℓ/v`, and passes the corner
//! `|Δu_k|·ℓ/4` away from it. Two bounds on the window give the two caps:
//!
//! - *Curve cap* (the counterpart of the centripetal cap): the blend stays within the halves of
//!   both moves, `2ℓ ≤ min(L_prev, L_next)`, so `v² ≤ a_k·min(L)/|Δu_k|` for every k. On chords
//!   that sample a smooth axis curve `q(s)`, `Δu_k/L ≈ q_k''`, and the cap reads
//!   `v²·|q_k''| ≤ a_k`: axis k's acceleration along the curve at that speed, whatever it is
//!   measured in. (The shorter move, not the mean, sets the window: a blend centred on the
//!   corner must fit on both sides.) A slow axis that reverses at a tiny rate has a tiny
//!   `|Δu_k|` and costs nothing, as it physically does not.
//! - *Corner cap* (junction deviation): how far the axes' blend takes the spot from the corner
//!   depends on the kinematics, which the planner does not know, but how long it lasts does not.
//!   In path space a blend at the path acceleration `A` that lasts `T` passes `A·T²/8` from the
//!   corner (the formula above with `a = v²|Δu|/(2ℓ)`, `T = 2ℓ/v`); keeping that within `δ`
//!   limits the blend to `τ = √(8δ/A)`, with `A = min(a_prev, a_next)` the moves' path
//!   accelerations (as GRBL takes them). δ and A are both path quantities (mm, mm/s²), so `τ` is
//!   a plain time, and in that time axis k can change its velocity by `a_k·τ` in its own units:
//!   `v·|Δu_k| ≤ a_k·τ`, `v² ≤ 8δ·a_k² / (A·Δu_k²)`. On a Cartesian machine (unit directions,
//!   one `a`) a corner turning by a small angle `φ` has `|Δu| ≈ φ` and this is
//!   `v² ≤ 8aδ/φ²`, GRBL's junction speed `aδ·sin(θ/2)/(1 − sin(θ/2))` to leading order.
//!
//! Both caps come from one number per junction, `W = max_k |Δu_k|/a_k`:
//! `v² ≤ min(min(L)/W, 8δ/(A·W²))`. Taken at speed `v`, the blend needs only `ℓ = v²·W/2` on
//! each side (the window in which the tightest axis uses all of its acceleration); `prepare`
//! uses that reach, not `½·min(L)`, to tell a chord of a curve (wholly inside its corners'
//! blends) from a short move beside a corner that barely turns or is taken far below its cap.
//! An axis reversal is no special case (the blend overshoots and comes back within the same
//! bounds); `δ = 0` still stops at every corner and `δ = ∞` still takes every corner at the
//! moves' full speed. The path acceleration limit (`path_a`) bounds `s̈`, which is continuous
//! through the blend, so it does not enter the per-axis caps.

use super::MAX_AXES;

/// A unit direction (or rate per unit path) in axis space, machine order.
type Dir = [f64; MAX_AXES];

/// Tolerance on the cosine for "straight through" and "full reversal".
const COS_TOL: f64 = 1e-9;

/// Speed caps of one corner, as squared speeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Corner {
    /// Highest squared speed through the corner (junction deviation and centripetal cap).
    pub v2: f64,
    /// The centripetal cap alone, `a_n · r`, or the per-axis curve cap `min(L)/W` (infinite for
    /// a straight-through corner, or one taken at rest, where nothing turns at speed).
    pub centripetal_v2: f64,
    /// Judged per axis: there the blend's and the tangential acceleration add up per axis,
    /// instead of being perpendicular as on a Euclidean path (`curve_limits`).
    pub per_axis: bool,
}

impl Corner {
    /// A corner passed at rest (program start, after a stop): nothing turns at speed.
    pub(crate) const AT_REST: Corner = Corner {
        v2: 0.0,
        centripetal_v2: f64::INFINITY,
        per_axis: false,
    };

    /// No cap at all (straight through, or `δ = ∞`).
    const FREE: Corner = Corner {
        v2: f64::INFINITY,
        centripetal_v2: f64::INFINITY,
        per_axis: false,
    };
}

/// What the corner model needs to know about the machine, computed once per plan.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CornerModel {
    /// Junction deviation δ.
    pub delta: f64,
    /// `1 / a_i` per axis (0 for an unlimited axis).
    pub inv_a: [f64; MAX_AXES],
    /// Path acceleration limit.
    pub path_a: f64,
    pub n_axes: usize,
}

impl CornerModel {
    /// Caps of the corner from direction `prev` (a move of length `len_prev` and path
    /// acceleration `a_prev`) into `next` (length `len_next`, acceleration `a_next`).
    ///
    /// A straight-through corner keeps full speed (infinite here); a reversal, or a junction
    /// deviation of 0, needs a stop; a junction deviation of `f64::INFINITY` takes every other
    /// corner at full speed (no cap at all). The caller also caps the result by both moves' speed
    /// limits.
    #[inline]
    pub(crate) fn corner(
        &self,
        prev: &Dir,
        next: &Dir,
        a_prev: f64,
        a_next: f64,
        len_prev: f64,
        len_next: f64,
    ) -> Corner {
        let n = self.n_axes.min(MAX_AXES);
        let mut cos_between = 0.0;
        for i in 0..n {
            cos_between += prev[i] * next[i];
        }
        let free = Corner::FREE;
        if cos_between >= 1.0 - COS_TOL {
            return free;
        }
        if cos_between <= -1.0 + COS_TOL || self.delta == 0.0 {
            return Corner { v2: 0.0, ..free };
        }
        if self.delta == f64::INFINITY {
            return free;
        }
        // GRBL: junction_cos_theta = −(prev · next); sin(θ/2) = √((1 − cos θ) / 2).
        let junction_cos_theta = -cos_between;
        let sin_theta_d2 = (0.5 * (1.0 - junction_cos_theta)).sqrt();
        let jd_v2 = a_prev.min(a_next) * self.delta * sin_theta_d2 / (1.0 - sin_theta_d2);
        // Centripetal: v² ≤ a_n · r with r = ½ min(L) · tan(θ/2). The normal is
        // n = (next − prev)/|next − prev|, and the tightest axis along it allows
        // a_n = min_i a_i / |n_i| = |next − prev| / max_i(|next_i − prev_i| / a_i). For unit
        // vectors |next − prev| · tan(θ/2) = |next + prev| (2 sin(φ/2) · cot(φ/2) = 2 cos(φ/2),
        // φ the turning angle), so a_n · tan(θ/2) = |next + prev| / max_i(...): one square root
        // and one division, and no cancellation on the shallow corners of fine chords.
        let mut diff2 = 0.0;
        let mut sum2 = 0.0;
        let mut worst = 0.0f64;
        for i in 0..n {
            let d = next[i] - prev[i];
            let m = next[i] + prev[i];
            diff2 += d * d;
            sum2 += m * m;
            worst = worst.max(d.abs() * self.inv_a[i]);
        }
        let sum = sum2.sqrt();
        let mut a_tan = sum / worst;
        if self.path_a < f64::INFINITY {
            // The path limit along the normal: path_a · tan(θ/2) = path_a · |sum| / |diff|.
            a_tan = a_tan.min(self.path_a * sum / diff2.sqrt());
        }
        let centripetal_v2 = 0.5 * len_prev.min(len_next) * a_tan;
        let v2 = jd_v2.min(centripetal_v2);
        if centripetal_v2.is_nan() {
            return Corner {
                v2: if v2.is_nan() { 0.0 } else { v2 },
                ..free
            };
        }
        Corner {
            v2: if v2.is_nan() { 0.0 } else { v2 },
            centripetal_v2,
            per_axis: false,
        }
    }

    /// Caps of the corner from `u` into `w`, each a move's `Δq / length` in axis units per unit
    /// of path, by the per-axis rule of the module doc: `v² ≤ min(min(L)/W, 8δ/(A·W²))` with
    /// `W = max_k |w_k − u_k| / a_k` and `A = min(a_prev, a_next)`. The caller also caps the
    /// result by both moves' speed limits.
    #[inline]
    pub(crate) fn corner_per_axis(
        &self,
        u: &Dir,
        w: &Dir,
        a_prev: f64,
        a_next: f64,
        len_prev: f64,
        len_next: f64,
    ) -> Corner {
        let n = self.n_axes.min(MAX_AXES);
        let mut worst = 0.0f64;
        for i in 0..n {
            worst = worst.max((w[i] - u[i]).abs() * self.inv_a[i]);
        }
        // No axis changes its rate (or only unlimited ones do), or δ = ∞: nothing to cap.
        // W > 0 means an axis with a finite a_k moves in one of the two moves, so A is finite.
        if !(worst > 0.0) || self.delta == f64::INFINITY {
            return Corner::FREE;
        }
        let curve_v2 = len_prev.min(len_next) / worst;
        let corner_v2 = 8.0 * self.delta / (a_prev.min(a_next) * worst * worst);
        Corner {
            v2: corner_v2.min(curve_v2),
            centripetal_v2: curve_v2,
            per_axis: true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(x: f64, y: f64) -> Dir {
        let n = (x * x + y * y).sqrt();
        [x / n, y / n, 0.0, 0.0, 0.0, 0.0]
    }

    fn model(a: f64, delta: f64) -> CornerModel {
        CornerModel {
            delta,
            inv_a: [1.0 / a; MAX_AXES],
            path_a: f64::INFINITY,
            n_axes: 2,
        }
    }

    /// Junction-deviation speed with long moves (the centripetal cap does not bind).
    fn jd_speed(prev: &Dir, next: &Dir, a: f64, delta: f64) -> f64 {
        model(a, delta).corner(prev, next, a, a, 1e9, 1e9).v2.sqrt()
    }

    #[test]
    fn right_angle_matches_grbl_formula() {
        // θ = 90°: sin 45° = √½, v² = a δ √½ / (1 − √½).
        let v = jd_speed(&dir(1.0, 0.0), &dir(0.0, 1.0), 1000.0, 0.01);
        let s = 0.5f64.sqrt();
        assert!((v - (1000.0 * 0.01 * s / (1.0 - s)).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn straight_keeps_speed_and_reversal_stops() {
        assert_eq!(
            jd_speed(&dir(1.0, 1.0), &dir(1.0, 1.0), 1e3, 0.01),
            f64::INFINITY
        );
        assert_eq!(jd_speed(&dir(1.0, 1.0), &dir(-1.0, -1.0), 1e3, 0.01), 0.0);
        // Zero deviation makes every real corner a stop.
        assert_eq!(jd_speed(&dir(1.0, 0.0), &dir(1.0, 0.1), 1e3, 0.0), 0.0);
        // Infinite deviation takes every corner at full speed.
        assert_eq!(
            jd_speed(&dir(1.0, 0.0), &dir(0.0, 1.0), 1e3, f64::INFINITY),
            f64::INFINITY
        );
    }

    #[test]
    fn shallow_corners_are_faster_than_sharp_ones() {
        let base = dir(1.0, 0.0);
        let shallow = jd_speed(&base, &dir(1.0, 0.1), 1e3, 0.01);
        let sharp = jd_speed(&base, &dir(-1.0, 0.5), 1e3, 0.01);
        assert!(shallow > sharp && sharp > 0.0);
    }

    #[test]
    fn chords_of_a_circle_are_capped_at_a_r_cos_half_step() {
        // Chords of a circle of radius R turning by φ: the rounding circle through the chord
        // midpoints has radius R cos(φ/2), so v² = a R cos(φ/2) (the normal bisects the two
        // directions; along it the per-axis limit is a / max(|n_x|, |n_y|)).
        let (r, a) = (5.0, 2000.0);
        for (heading, phi) in [(0.3f64, 0.05f64), (1.0, 0.2), (0.0, 0.01)] {
            let u = dir(heading.cos(), heading.sin());
            let w = dir((heading + phi).cos(), (heading + phi).sin());
            let len = 2.0 * r * (0.5 * phi).sin();
            let c = model(a, 0.01).corner(&u, &w, a, a, len, len);
            let normal = heading + 0.5 * phi + std::f64::consts::FRAC_PI_2;
            let a_n = a / normal.cos().abs().max(normal.sin().abs());
            let want = a_n * r * (0.5 * phi).cos();
            assert!(
                (c.centripetal_v2 - want).abs() < 1e-9 * want,
                "{} vs {want}",
                c.centripetal_v2
            );
            // On fine chords junction deviation alone would allow far more; on coarser ones
            // (φ = 0.2 at δ = 0.01) it is the tighter cap.
            assert!(c.v2 <= c.centripetal_v2);
            if phi <= 0.05 {
                assert_eq!(c.v2, c.centripetal_v2);
            }
        }
    }

    #[test]
    fn centripetal_cap_uses_the_slow_axis_along_the_normal() {
        // Moving along x and turning slightly: the centripetal acceleration points along y,
        // so y's limit (100) applies although the moves' own limit is x's (10 000).
        let m = CornerModel {
            delta: 0.01,
            inv_a: [1.0 / 10_000.0, 1.0 / 100.0, 0.0, 0.0, 0.0, 0.0],
            path_a: f64::INFINITY,
            n_axes: 2,
        };
        let (u, w) = (dir(1.0, -0.01), dir(1.0, 0.01));
        let c = m.corner(&u, &w, 10_000.0, 10_000.0, 1.0, 1.0);
        let tan_half =
            ((1.0 + u[0] * w[0] + u[1] * w[1]) / (1.0 - u[0] * w[0] - u[1] * w[1])).sqrt();
        let want = 100.0 * 0.5 * tan_half;
        assert!((c.centripetal_v2 - want).abs() < 1e-9 * want);
    }

    /// The arm of `examples/surface_hardening_arm.lase`: X in mm, A, B, C in rad, limits of
    /// `stdlib/machines/arm_3r.toml`.
    fn arm() -> CornerModel {
        let (ab, c) = (900f64.to_radians(), 1800f64.to_radians());
        CornerModel {
            delta: 0.01,
            inv_a: [1.0 / 500.0, 1.0 / ab, 1.0 / ab, 1.0 / c, 0.0, 0.0],
            path_a: f64::INFINITY,
            n_axes: 4,
        }
    }

    /// The move's path acceleration, as `move_limits` derives it.
    fn path_a(m: &CornerModel, u: &Dir) -> f64 {
        (0..m.n_axes)
            .filter(|&k| u[k] != 0.0)
            .map(|k| 1.0 / (m.inv_a[k] * u[k].abs()))
            .fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn per_axis_matches_grbl_on_small_cartesian_turns() {
        // Unit directions and one acceleration: the per-axis corner cap 8δ·a²/(A·Δu²) with
        // |Δu| = sin φ (moving along x) against GRBL's aδ·cos(φ/2)/(1 − cos(φ/2)). Both are
        // 8aδ/φ² to leading order; they differ by a factor 1 + φ²/2.
        let (a, delta) = (2000.0, 0.01);
        for phi in [1e-3f64, 1e-2, 3e-2] {
            let (u, w) = (dir(1.0, 0.0), dir(phi.cos(), phi.sin()));
            let grbl = jd_speed(&u, &w, a, delta).powi(2);
            let per_axis = model(a, delta)
                .corner_per_axis(&u, &w, a, a / phi.cos(), 1e9, 1e9)
                .v2;
            assert!(
                (per_axis / grbl - 1.0).abs() <= 0.6 * phi * phi,
                "φ = {phi}: {per_axis} vs {grbl}"
            );
        }
    }

    #[test]
    fn a_slow_joint_reversing_costs_nothing_per_axis() {
        // The arm's chord junction where C reverses (0.43 mm chords, rates in rad per mm of
        // surface): the direction in axis space turns by 0.5 rad, so the axis-space rule
        // (applied to the normalized directions, as it was) caps the corner near 5 mm/s;
        // per axis, C's rate changes by 1.3e-3 rad/mm, which at 10 mm/s is 0.13 rad/s² of
        // curvature acceleration against C's 31 rad/s².
        let m = arm();
        let u = [0.0, 0.00057, 0.00244, 0.00104, 0.0, 0.0];
        let w = [0.0, 0.00064, 0.00277, -0.00023, 0.0, 0.0];
        let len = 0.4284;
        let (a_u, a_w) = (path_a(&m, &u), path_a(&m, &w));
        let c = m.corner_per_axis(&u, &w, a_u, a_w, len, len);
        let worst = (0..4)
            .map(|k| (w[k] - u[k]).abs() * m.inv_a[k])
            .fold(0.0, f64::max);
        assert_eq!(c.centripetal_v2, len / worst);
        assert_eq!(
            c.v2,
            c.centripetal_v2
                .min(8.0 * 0.01 / (a_u.min(a_w) * worst * worst))
        );
        assert!(c.v2.sqrt() > 50.0, "{}", c.v2.sqrt());
        let unit = |x: &Dir| {
            let n = x.iter().map(|v| v * v).sum::<f64>().sqrt();
            x.map(|v| v / n)
        };
        let old = m.corner(&unit(&u), &unit(&w), a_u, a_w, len, len);
        assert!(old.v2.sqrt() < 6.0, "{}", old.v2.sqrt());
    }

    #[test]
    fn a_genuine_corner_per_axis_is_the_blend_time_times_the_axis_acceleration() {
        // B's rate jumps from 0.05 to −0.05 rad/mm at one junction: the corner cap binds, and
        // B's velocity jump at the corner speed is exactly a_B·τ, τ = √(8δ/A).
        let m = arm();
        let u = [0.0, 0.002, 0.05, 0.0, 0.0, 0.0];
        let w = [0.0, 0.002, -0.05, 0.0, 0.0, 0.0];
        let a = path_a(&m, &u);
        let c = m.corner_per_axis(&u, &w, a, a, 0.5, 0.5);
        assert!(c.v2 < c.centripetal_v2);
        let tau = (8.0 * 0.01 / a).sqrt();
        let a_b = 1.0 / m.inv_a[2];
        assert!((c.v2.sqrt() * 0.1 - a_b * tau).abs() <= 1e-12 * a_b * tau);
        assert!(c.per_axis);
    }

    #[test]
    fn per_axis_keeps_the_meaning_of_zero_and_infinite_deviation() {
        let u = [0.0, 0.001, 0.002, 0.001, 0.0, 0.0];
        let w = [0.0, 0.001, 0.002, -0.001, 0.0, 0.0];
        let stop = CornerModel {
            delta: 0.0,
            ..arm()
        };
        assert_eq!(stop.corner_per_axis(&u, &w, 1e3, 1e3, 0.5, 0.5).v2, 0.0);
        let free = CornerModel {
            delta: f64::INFINITY,
            ..arm()
        };
        let c = free.corner_per_axis(&u, &w, 1e3, 1e3, 0.5, 0.5);
        assert_eq!((c.v2, c.centripetal_v2), (f64::INFINITY, f64::INFINITY));
        // No axis changes its rate: straight through, even at δ = 0.
        let c = stop.corner_per_axis(&u, &u, 1e3, 1e3, 0.5, 0.5);
        assert_eq!(c.v2, f64::INFINITY);
    }
}
