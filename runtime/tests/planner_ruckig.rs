//! Rest-to-rest moves must be time-optimal: the planner's duration of a single-axis move
//! equals the one Ruckig computes (fixtures from `scripts/ruckig_fixture.py`).

use lase_runtime::planner::{AxisLimits, Move, PlannerConfig, ProfileKind, plan};

const INF: f64 = f64::INFINITY;

struct Case {
    line: usize,
    distance: f64,
    v: f64,
    a: f64,
    j: f64,
    duration: f64,
    regime: String,
}

fn parse(csv: &str) -> Vec<Case> {
    let mut out = Vec::new();
    for (i, line) in csv.lines().enumerate() {
        if line.starts_with('#') || line.starts_with("distance") || line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 6, "line {}: {line}", i + 1);
        let num = |s: &str| -> f64 { if s == "inf" { INF } else { s.parse().unwrap() } };
        out.push(Case {
            line: i + 1,
            distance: num(f[0]),
            v: num(f[1]),
            a: num(f[2]),
            j: num(f[3]),
            duration: num(f[4]),
            regime: f[5].to_string(),
        });
    }
    out
}

/// Plans every case and returns the largest relative duration deviation from Ruckig.
fn check(csv: &str, profile: ProfileKind) -> f64 {
    let cases = parse(csv);
    let mut worst = 0.0f64;
    for c in &cases {
        let limits = AxisLimits {
            v: [c.v, INF, INF, INF, INF, INF],
            a: [c.a, INF, INF, INF, INF, INF],
            j: [c.j, INF, INF, INF, INF, INF],
        };
        let cfg = PlannerConfig {
            profile,
            n_axes: 1,
            ..PlannerConfig::default()
        };
        let mv = Move::new([c.distance, 0.0, 0.0, 0.0, 0.0, 0.0], c.distance.abs(), INF);
        let p = plan([0.0; 6], &[mv], &limits, &cfg).unwrap();
        let rel = (p.duration() - c.duration).abs() / c.duration;
        assert!(
            rel <= 1e-6,
            "line {} ({}): planner {} s, ruckig {} s, rel {rel:e}",
            c.line,
            c.regime,
            p.duration(),
            c.duration
        );
        let end = p.sample(p.duration());
        assert!((end.pos[0] - c.distance).abs() <= 1e-9 * c.distance.abs().max(1.0));
        worst = worst.max(rel);
    }
    worst
}

#[test]
fn s_curve_rest_to_rest_matches_ruckig() {
    let csv = include_str!("fixtures/ruckig_rest_to_rest.csv");
    let cases = parse(csv);
    assert!(cases.len() >= 50);
    // The fixture covers every S-curve regime.
    for r in [
        "cruise_const_acc",
        "cruise_no_const_acc",
        "peak_const_acc",
        "peak_no_const_acc",
    ] {
        assert!(cases.iter().any(|c| c.regime == r), "no {r} case");
    }
    let worst = check(csv, ProfileKind::SCurve);
    println!(
        "S-curve: max relative deviation from Ruckig {worst:e} over {} cases",
        cases.len()
    );
}

#[test]
fn trapezoid_rest_to_rest_matches_ruckig_with_infinite_jerk() {
    let csv = include_str!("fixtures/ruckig_rest_to_rest_trapezoid.csv");
    let worst = check(csv, ProfileKind::Trapezoid);
    // The S-curve profile with unlimited jerk degenerates to the same trapezoid.
    let worst_s = check(csv, ProfileKind::SCurve);
    println!(
        "trapezoid: max relative deviation from Ruckig {worst:e} (S-curve, J = inf: {worst_s:e})"
    );
}
