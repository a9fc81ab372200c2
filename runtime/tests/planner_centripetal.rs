//! The centripetal cap on curves split into chords (Klipper's "approximated centripetal
//! velocity", `planner::junction`): sampled at 1 kHz, a plan along the chords of a circle keeps
//! the centripetal acceleration implied by the chords' turning, the tangential one and both
//! together within the acceleration limit, and it still gets close to the circle's own limit
//! `v = √(a R)`.

use lase_runtime::planner::{
    AxisLimits, CURVE_SHARE, MAX_AXES, Move, PlannerConfig, ProfileKind, plan,
};
use std::f64::consts::TAU;

const INF: f64 = f64::INFINITY;

/// A 20 mm line tangent into a circle of radius `r` (centre at the origin, entered at (r, 0)
/// counter-clockwise), `turns` turns split into chords whose sagitta is at most `tol` (as
/// `motion::arc_points` splits arcs), and a 20 mm line tangent out of it. Returns the moves,
/// the start and the chords' turning angle φ.
fn circle(r: f64, tol: f64, turns: usize) -> (Vec<Move>, [f64; MAX_AXES], f64) {
    let step = 2.0 * (1.0 - tol / r).acos();
    polygon(r, (TAU / step).ceil() as usize, turns)
}

/// [`circle`] with `per_turn` chords per turn.
fn polygon(r: f64, per_turn: usize, turns: usize) -> (Vec<Move>, [f64; MAX_AXES], f64) {
    let phi = TAU / per_turn as f64;
    let pt = |x: f64, y: f64| {
        let mut q = [0.0; MAX_AXES];
        q[0] = x;
        q[1] = y;
        q
    };
    let at = |k: usize| pt(r * (k as f64 * phi).cos(), r * (k as f64 * phi).sin());
    let start = pt(r, -20.0);
    let mut moves = vec![Move::linear(start, at(0), INF)];
    moves.extend((1..=per_turn * turns).map(|k| Move::linear(at(k - 1), at(k), INF)));
    moves.push(Move::linear(at(per_turn * turns), pt(r, 20.0), INF));
    (moves, start, phi)
}

/// Max over the 1 kHz samples of the speed on the chords, the tangential acceleration
/// everywhere, and, on the chords, the centripetal acceleration `v²·κ` and the total `√(a_t² + (v²κ)²)`. A chord's curvature
/// is the turning of the path at its two ends, half of each attributed to it, over its length:
/// `κ = (φ_in + φ_out) / (2 L)` (φ/2 where a chord meets a tangent line).
fn peaks(moves: &[Move], start: [f64; MAX_AXES], phi: f64, cfg: &PlannerConfig) -> [f64; 4] {
    let limits = AxisLimits {
        v: [INF; MAX_AXES],
        a: [INF; MAX_AXES],
        j: [INF; MAX_AXES],
    };
    let p = plan(start, moves, &limits, cfg).expect("the circle plans");
    let n = p.segments().len();
    assert_eq!(n, moves.len());
    let mut peak = [0.0f64; 4];
    let ticks = (p.duration() * 1000.0).ceil() as usize;
    for k in 0..=ticks {
        let s = p.sample(k as f64 * 1e-3);
        let i = s.segment;
        peak[1] = peak[1].max(s.a.abs());
        if i == 0 || i + 1 == n {
            continue;
        }
        peak[0] = peak[0].max(s.v);
        let turn_in = if i == 1 { 0.5 * phi } else { phi };
        let turn_out = if i + 2 == n { 0.5 * phi } else { phi };
        let kappa = 0.5 * (turn_in + turn_out) / p.segments()[i].length;
        let ac = s.v * s.v * kappa;
        peak[2] = peak[2].max(ac);
        peak[3] = peak[3].max(s.a.hypot(ac));
    }
    peak
}

fn cfg(profile: ProfileKind, a: f64) -> PlannerConfig {
    PlannerConfig {
        profile,
        junction_deviation: 0.01,
        path_v: 250.0,
        path_a: a,
        path_j: 50_000.0,
        n_axes: 2,
        ..PlannerConfig::default()
    }
}

#[test]
fn chords_of_a_circle_keep_centripetal_acceleration_within_the_limit() {
    let (r, a) = (5.0, 2000.0);
    let (moves, start, phi) = circle(r, 0.002, 2);
    assert!(moves.len() > 200, "fine chords: {}", moves.len());
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let [v, at, ac, total] = peaks(&moves, start, phi, &cfg(profile, a));
        assert!(at <= a * (1.0 + 1e-9), "{profile:?}: tangential {at}");
        assert!(ac <= a * (1.0 + 1e-9), "{profile:?}: centripetal {ac}");
        assert!(total <= a * (1.0 + 1e-9), "{profile:?}: total {total}");
        // The circle's own limit is v² = a R; the chords keep CURVE_SHARE (95 %) of it for the
        // centripetal acceleration (the rest is for speed changes), within the model's cos(φ/2)
        // (φ = 0.057 rad here: 4e-4 in v²). The trapezoid gets there; the S-curve stays
        // well below on 0.28 mm chords: every S-curve move starts and ends at zero
        // acceleration (the planner module's known limit).
        let v_curve = (CURVE_SHARE * a * r).sqrt();
        assert!(
            v <= v_curve,
            "{profile:?}: {v} above √(share · aR) = {v_curve}"
        );
        if profile == ProfileKind::Trapezoid {
            assert!(v >= v_curve * (1.0 - 1e-3), "{v} far below √(share · aR)");
        }
    }
}

#[test]
fn coarse_chords_are_capped_too() {
    // A 24-gon with 0.2 mm junction deviation: junction deviation alone allows
    // v² = a δ sin(θ/2)/(1 − sin(θ/2)) ≈ 4.6e4 here; the centripetal cap holds the chords to
    // v² = share · a R cos(φ/2) = share · 9915 (`CURVE_SHARE`: the planner's centripetal share
    // on curves).
    let (r, a) = (5.0, 2000.0);
    let (moves, start, phi) = polygon(r, 24, 3);
    let c = PlannerConfig {
        junction_deviation: 0.2,
        ..cfg(ProfileKind::Trapezoid, a)
    };
    let [v, at, ac, total] = peaks(&moves, start, phi, &c);
    assert!(
        at <= a * (1.0 + 1e-9) && ac <= a * (1.0 + 1e-9),
        "{at} {ac}"
    );
    assert!(total <= a * (1.0 + 1e-9), "{total}");
    let want = (CURVE_SHARE * a * r * (0.5 * phi).cos()).sqrt();
    assert!(v <= want * (1.0 + 1e-12), "{v} vs {want}");
    let limits = AxisLimits {
        v: [INF; MAX_AXES],
        a: [INF; MAX_AXES],
        j: [INF; MAX_AXES],
    };
    let p = plan(start, &moves, &limits, &c).unwrap();
    let chord_peak = p.segments()[1..moves.len() - 1]
        .iter()
        .map(|s| s.v_peak)
        .fold(0.0, f64::max);
    assert!(
        (chord_peak - want).abs() <= 1e-9 * want,
        "{chord_peak} vs {want}"
    );
}

#[test]
fn zero_and_infinite_deviation_keep_their_meaning() {
    // δ = 0 stops at every corner; δ = ∞ takes every corner at the moves' full speed, which on
    // this circle is the path speed limit.
    let (moves, _, phi) = circle(5.0, 0.002, 2);
    let moves = &moves[1..moves.len() - 1];
    let start = moves[0].target.0;
    let moves = &moves[1..];
    let stop = PlannerConfig {
        junction_deviation: 0.0,
        ..cfg(ProfileKind::Trapezoid, 2000.0)
    };
    let limits = AxisLimits {
        v: [INF; MAX_AXES],
        a: [INF; MAX_AXES],
        j: [INF; MAX_AXES],
    };
    let p = plan(start, moves, &limits, &stop).unwrap();
    assert!(p.segments().iter().all(|s| s.v_exit == 0.0));
    let free = PlannerConfig {
        junction_deviation: INF,
        ..stop
    };
    let [v, ..] = peaks(moves, start, phi, &free);
    assert!((v - 250.0).abs() < 1e-9, "{v}");
}
