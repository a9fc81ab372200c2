//! Corner speeds: the junction-deviation model of GRBL and Klipper, and Klipper's centripetal cap.
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
//! Directions are unit vectors in axis space.

use super::{Axes, MAX_AXES};

/// Tolerance on the cosine for "straight through" and "full reversal".
const COS_TOL: f64 = 1e-9;

/// Speed caps of one corner, as squared speeds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Corner {
    /// Highest squared speed through the corner (junction deviation and centripetal cap).
    pub v2: f64,
    /// The centripetal cap alone, `a_n · r` (infinite for a straight-through corner, or one
    /// taken at rest, where nothing turns at speed).
    pub centripetal_v2: f64,
}

impl Corner {
    /// A corner passed at rest (program start, after a stop): nothing turns at speed.
    pub(crate) const AT_REST: Corner = Corner {
        v2: 0.0,
        centripetal_v2: f64::INFINITY,
    };
}

/// What the corner model needs to know about the machine, computed once per plan.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CornerModel {
    /// Junction deviation δ.
    pub delta: f64,
    /// `1 / a_i` per axis (0 for an unlimited axis).
    pub inv_a: Axes,
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
        prev: &Axes,
        next: &Axes,
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
        let free = Corner {
            v2: f64::INFINITY,
            centripetal_v2: f64::INFINITY,
        };
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
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(x: f64, y: f64) -> Axes {
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
    fn jd_speed(prev: &Axes, next: &Axes, a: f64, delta: f64) -> f64 {
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
}
