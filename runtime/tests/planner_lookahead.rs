//! Streaming look-ahead: how close a bounded window of N moves gets to the offline plan on a
//! long path of many short segments, and proof that every committed speed could still stop
//! within the window.

use lase_runtime::planner::{AxisLimits, Move, Plan, PlannerConfig, ProfileKind, plan};

/// 4000 chords of 0.1 mm along a circle of radius 30 mm: corners of 0.19°, so junctions
/// barely slow the head, and stopping from the 200 mm/s feed takes about 100 segments.
fn spiral() -> Vec<Move> {
    let r = 30.0;
    let step = 0.1 / r;
    let mut q = [r, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut moves = Vec::new();
    for k in 1..=4000 {
        let phi = k as f64 * step;
        let target = [r * phi.cos(), r * phi.sin(), 0.0, 0.0, 0.0, 0.0];
        moves.push(Move::linear(q, target, 200.0));
        q = target;
    }
    moves
}

fn limits() -> AxisLimits {
    AxisLimits {
        v: [300.0; 6],
        a: [2000.0; 6],
        j: [40_000.0; 6],
    }
}

fn run(profile: ProfileKind, lookahead: Option<usize>) -> Plan {
    let cfg = PlannerConfig {
        profile,
        junction_deviation: 0.01,
        lookahead,
        n_axes: 2,
        ..PlannerConfig::default()
    };
    plan([30.0, 0.0, 0.0, 0.0, 0.0, 0.0], &spiral(), &limits(), &cfg).unwrap()
}

#[test]
fn window_ratios_approach_offline() {
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let full = run(profile, None).duration();
        let mut ratios = Vec::new();
        for n in [16, 64, 256] {
            let p = run(profile, Some(n));
            ratios.push(p.duration() / full);
        }
        println!(
            "{profile:?}: offline {full:.4} s; duration ratio N=16: {:.4}, N=64: {:.4}, N=256: {:.6}",
            ratios[0], ratios[1], ratios[2]
        );
        // A window never beats knowing everything, and a longer window is never worse.
        assert!(ratios[0] >= ratios[1] && ratios[1] >= ratios[2] && ratios[2] >= 1.0 - 1e-12);
        assert!(
            ratios[0] > 1.5,
            "a 1.6 mm window must cost speed: {}",
            ratios[0]
        );
        if profile == ProfileKind::Trapezoid {
            // 256 moves (25.6 mm) exceed the 10 mm stopping distance: as good as offline.
            assert!(
                ratios[2] < 1.0 + 1e-9,
                "N=256 covers the stopping distance: {}",
                ratios[2]
            );
        }
    }
}

/// Path acceleration limit of segment `i`: the tightest axis along its direction.
fn path_accel(p: &Plan, i: usize) -> f64 {
    let u = p.direction(i);
    2000.0 / u.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

#[test]
fn committed_speed_can_stop_inside_the_window() {
    let n = 16;
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let p = run(profile, Some(n));
        let segs = p.segments();
        let mut tightest = 0.0f64;
        for k in 0..segs.len() {
            // Braking at each move's full acceleration over the n known moves removes
            // v² = Σ 2 a_i L_i; jerk limits only make the stop longer, so this bounds both
            // profiles, and the trapezoid meets it with equality.
            let budget: f64 = (k + 1..(k + 1 + n).min(segs.len()))
                .map(|i| 2.0 * path_accel(&p, i) * segs[i].length)
                .sum();
            let v2 = segs[k].v_exit * segs[k].v_exit;
            assert!(
                v2 <= budget * (1.0 + 1e-9),
                "move {k}: v² = {v2} > {budget}"
            );
            if budget > 0.0 {
                tightest = tightest.max(v2 / budget);
            }
        }
        println!(
            "{profile:?}, N={n}: committed speeds use up to {tightest:.4} of the window's braking budget"
        );
        if profile == ProfileKind::Trapezoid {
            assert!(tightest > 1.0 - 1e-9, "{tightest}");
        }
    }
}

#[test]
fn streaming_matches_offline_when_the_window_covers_the_program() {
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let a = run(profile, None);
        let b = run(profile, Some(10_000));
        assert_eq!(a, b);
    }
}
