//! Corner speeds: the junction-deviation model of GRBL and Klipper.
//!
//! The corner between two moves is rounded, in the model only, by an arc that deviates
//! `δ = junction_deviation` from the corner point; the junction speed is the speed at which that
//! arc's centripetal acceleration equals the acceleration limit. With `θ` the angle between the
//! reversed incoming and the outgoing direction (GRBL's `junction_cos_theta`),
//! `v² = a · δ · sin(θ/2) / (1 − sin(θ/2))`. Directions are unit vectors in axis space.

use super::{Axes, MAX_AXES};

/// Tolerance on the cosine for "straight through" and "full reversal".
const COS_TOL: f64 = 1e-9;

/// Highest speed at the junction from direction `prev` into direction `next` (unit vectors in
/// axis space), given the smaller of the two moves' path accelerations `a` and the deviation
/// `delta`. The caller also caps the result by both moves' speed limits.
///
/// A straight-through junction keeps full speed (infinite here); a reversal needs a stop.
#[inline]
pub(crate) fn junction_speed(prev: &Axes, next: &Axes, n_axes: usize, a: f64, delta: f64) -> f64 {
    let mut cos_between = 0.0;
    for i in 0..n_axes.min(MAX_AXES) {
        cos_between += prev[i] * next[i];
    }
    if cos_between >= 1.0 - COS_TOL {
        return f64::INFINITY;
    }
    if cos_between <= -1.0 + COS_TOL || delta == 0.0 {
        return 0.0;
    }
    // GRBL: junction_cos_theta = −(prev · next); sin(θ/2) = √((1 − cos θ) / 2).
    let junction_cos_theta = -cos_between;
    let sin_theta_d2 = (0.5 * (1.0 - junction_cos_theta)).sqrt();
    let v2 = a * delta * sin_theta_d2 / (1.0 - sin_theta_d2);
    if v2.is_nan() { 0.0 } else { v2.sqrt() }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(x: f64, y: f64) -> Axes {
        let n = (x * x + y * y).sqrt();
        [x / n, y / n, 0.0, 0.0, 0.0, 0.0]
    }

    #[test]
    fn right_angle_matches_grbl_formula() {
        // θ = 90°: sin 45° = √½, v² = a δ √½ / (1 − √½).
        let v = junction_speed(&dir(1.0, 0.0), &dir(0.0, 1.0), 2, 1000.0, 0.01);
        let s = 0.5f64.sqrt();
        assert!((v - (1000.0 * 0.01 * s / (1.0 - s)).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn straight_keeps_speed_and_reversal_stops() {
        assert_eq!(
            junction_speed(&dir(1.0, 1.0), &dir(1.0, 1.0), 2, 1e3, 0.01),
            f64::INFINITY
        );
        assert_eq!(
            junction_speed(&dir(1.0, 1.0), &dir(-1.0, -1.0), 2, 1e3, 0.01),
            0.0
        );
        // Zero deviation makes every real corner a stop.
        assert_eq!(
            junction_speed(&dir(1.0, 0.0), &dir(1.0, 0.1), 2, 1e3, 0.0),
            0.0
        );
    }

    #[test]
    fn shallow_corners_are_faster_than_sharp_ones() {
        let base = dir(1.0, 0.0);
        let shallow = junction_speed(&base, &dir(1.0, 0.1), 2, 1e3, 0.01);
        let sharp = junction_speed(&base, &dir(-1.0, 0.5), 2, 1e3, 0.01);
        assert!(shallow > sharp && sharp > 0.0);
    }
}
