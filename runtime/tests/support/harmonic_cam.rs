//! The harmonic test cam of issue 13 item 5, exactly: base radius 20 mm, lift 10 mm by the
//! harmonic law s(u) = (1 − cos πu)/2, rise 0–60°, top dwell 60–120°, return 120–180°, base
//! dwell after. Its acceleration (curvature) jumps at the ends of rise and return. Shared by
//! `runtime/tests/cam_laws.rs` and `tests/oriented_physics.rs`, which both check lase's cam
//! against this closed form.

use std::f64::consts::{PI, TAU};

/// r(θ) and dr/dθ of the cam (θ in rad, r in mm).
pub fn radius(theta: f64) -> (f64, f64) {
    let deg = theta.rem_euclid(TAU).to_degrees();
    let beta = PI / 3.0;
    let rise = |u: f64| {
        (
            5.0 * (1.0 - (PI * u).cos()),
            5.0 * PI * (PI * u).sin() / beta,
        )
    };
    let (lift, d) = if deg < 60.0 {
        rise(deg / 60.0)
    } else if deg < 120.0 {
        (10.0, 0.0)
    } else if deg < 180.0 {
        let (l, d) = rise((deg - 120.0) / 60.0);
        (10.0 - l, -d)
    } else {
        (0.0, 0.0)
    };
    (20.0 + lift, d)
}
