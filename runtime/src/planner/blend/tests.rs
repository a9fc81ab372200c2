//! Tests of the corner blends: the smoothstep's ends and deviation, a right angle within every
//! axis limit, the junctions that are no blends, and a run of chords sharing its curvature.

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
        shared: 0,
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
    let Junction::Blend { blend, v, a, j } = junction(
        &axes(10.0, 0.0),
        side(&u),
        side(&w),
        delta,
        2.0,
        false,
        &lim,
        2,
    ) else {
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
        junction(&c, side(&u), side(&u), 0.01, 2.0, false, &lim, 2),
        Junction::Straight
    );
    assert_eq!(
        junction(&c, side(&u), side(&r), 0.01, 2.0, false, &lim, 2),
        Junction::Stop
    );
    let w = axes(0.0, 1.0);
    assert_eq!(
        junction(&c, side(&u), side(&w), 0.0, 2.0, false, &lim, 2),
        Junction::Stop
    );
}

/// The lit chords of a circle (R = 4 mm, 0.1 rad each, 0.4 mm long) blended one by one
/// with the smoothstep could be taken at about 21 mm/s within 50 m/s³ (`1.5·|Δu|·v³/ℓ²`
/// within 75 % of it);
/// with the curvature shared across the run the blends bend like the circle, and the
/// middle of the run is planned at the 30 mm/s programmed. Sampled every 0.1 ms, each
/// axis's position, velocity and acceleration are continuous (the jerk recomputed from
/// the sampled acceleration stays within the limit), and the path stays within the chord
/// sagitta of the circle.
#[test]
fn a_run_of_chords_shares_its_curvature_and_holds_the_programmed_speed() {
    use crate::planner::{Along, Corners, Move, PlannerConfig, ProfileKind, plan_along};
    let (r, phi, n_chords) = (4.0f64, 0.1f64, 60);
    let at = |i: usize| {
        let t = phi * i as f64;
        axes(r * t.cos(), r * t.sin())
    };
    let mut moves = Vec::new();
    let mut along = Vec::new();
    for i in 1..=n_chords {
        moves.push(Move::linear(at(i - 1), at(i), 30.0));
        along.push(Along {
            lit: true,
            ..Along::default()
        });
    }
    let cfg = PlannerConfig {
        profile: ProfileKind::SCurve,
        junction_deviation: 0.01,
        n_axes: 2,
        corners: Corners::Blend,
        ..PlannerConfig::default()
    };
    let lim = xy(2000.0, 50_000.0);
    let plan = plan_along(at(0), &moves, &along, &lim, &cfg).unwrap();
    let shared = plan
        .blends()
        .iter()
        .filter(|b| b.levels() == (LEVELS, LEVELS))
        .count();
    // 59 blends; the three at each end of the run ramp into the curvature (levels 0 → 3).
    assert_eq!(
        shared,
        n_chords - 7,
        "every blend but the run's ends shares both ends"
    );
    let mid = plan.sample(0.5 * plan.duration());
    assert!((mid.v - 30.0).abs() < 1e-9, "{} mm/s in the middle", mid.v);
    let dt = 1e-4;
    let steps = (plan.duration() / dt) as usize;
    let (mut prev_acc, mut worst_j, mut worst_r) = (None::<Axes>, 0.0f64, 0.0f64);
    let sagitta = r * (1.0 - (0.5 * phi).cos());
    for i in 0..=steps {
        let s = plan.sample(i as f64 * dt);
        if let Some(pa) = prev_acc {
            for k in 0..2 {
                worst_j = worst_j.max((s.acc[k] - pa[k]).abs() / dt);
            }
        }
        prev_acc = Some(s.acc);
        let radius = s.pos[0].hypot(s.pos[1]);
        worst_r = worst_r.max(r - radius);
    }
    assert!(worst_j <= 50_000.0 * 1.001, "jerk {worst_j} mm/s³");
    assert!(
        worst_r <= sagitta * 1.01,
        "{worst_r} inside the circle, sagitta {sagitta}"
    );
}
