//! Property tests of the planner on random multi-axis paths: every limit holds at every
//! sampled instant, the motion is continuous across moves, and stops are real stops.

#![allow(clippy::needless_range_loop)]

use lase_runtime::planner::{Axes, AxisLimits, Move, Plan, PlannerConfig, ProfileKind, plan};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

const INF: f64 = f64::INFINITY;
/// Relative slack on limits: rounding only.
const LIM: f64 = 1.0 + 1e-9;

/// One random move, relative to the previous one.
#[derive(Clone, Debug)]
struct Spec {
    delta: [f64; 3],
    /// Continue straight in the previous direction (tests straight junctions).
    straight: bool,
    /// Path length = factor · Euclidean distance (part-space chords differ from axis space).
    length_factor: f64,
    feed: f64,
    stop: bool,
    dwell: f64,
    /// A zero-length move carrying only the stop/dwell.
    zero: bool,
}

fn spec() -> impl Strategy<Value = Spec> {
    (
        prop::array::uniform3(-10.0f64..10.0),
        prop::bool::weighted(0.3),
        prop_oneof![3 => Just(1.0), 1 => 0.5f64..2.0],
        prop_oneof![1 => Just(INF), 4 => 20.0f64..300.0],
        prop::bool::weighted(0.15),
        prop_oneof![9 => Just(0.0), 1 => 0.001f64..0.2],
        prop::bool::weighted(0.05),
        prop_oneof![3 => Just(1.0), 1 => 0.001f64..0.1],
    )
        .prop_map(
            |(delta, straight, length_factor, feed, stop, dwell, zero, scale)| Spec {
                delta: delta.map(|d| d * scale),
                straight,
                length_factor,
                feed,
                stop,
                dwell,
                zero,
            },
        )
}

#[derive(Clone, Debug)]
struct Case {
    n_axes: usize,
    limits: AxisLimits,
    path: (f64, f64, f64),
    junction_deviation: f64,
    lookahead: Option<usize>,
    specs: Vec<Spec>,
}

fn case() -> impl Strategy<Value = Case> {
    (
        2usize..=3,
        prop::array::uniform3((20.0f64..500.0, 100.0f64..5000.0, 1000.0f64..100_000.0)),
        (
            prop_oneof![2 => Just(INF), 1 => 20.0f64..400.0],
            prop_oneof![2 => Just(INF), 1 => 100.0f64..4000.0],
            prop_oneof![2 => Just(INF), 1 => 1000.0f64..80_000.0],
        ),
        prop_oneof![Just(0.0), 0.001f64..0.2],
        prop_oneof![3 => Just(None), 1 => (0usize..8).prop_map(Some)],
        prop::collection::vec(spec(), 5..40),
    )
        .prop_map(
            |(n_axes, lim, path, junction_deviation, lookahead, specs)| {
                let mut limits = AxisLimits {
                    v: [INF; 6],
                    a: [INF; 6],
                    j: [INF; 6],
                };
                for (i, &(v, a, j)) in lim.iter().enumerate() {
                    limits.v[i] = v;
                    limits.a[i] = a;
                    limits.j[i] = j;
                }
                Case {
                    n_axes,
                    limits,
                    path,
                    junction_deviation,
                    lookahead,
                    specs,
                }
            },
        )
}

fn build_moves(c: &Case) -> Vec<Move> {
    let mut q = Axes::ZERO;
    let mut last_dir = [1.0, 0.0, 0.0];
    let mut moves = Vec::new();
    for (k, s) in c.specs.iter().enumerate() {
        let mut target = q;
        if !s.zero {
            let mut d = s.delta;
            if s.straight {
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(0.01);
                d = last_dir.map(|u| u * n);
            }
            for i in 0..c.n_axes {
                target[i] = q[i] + d[i];
            }
        }
        let mut dist2 = 0.0;
        for i in 0..6 {
            dist2 += (target[i] - q[i]).powi(2);
        }
        let dist = dist2.sqrt();
        if dist > 0.0 {
            for i in 0..3 {
                last_dir[i] = (target[i] - q[i]) / dist;
            }
        }
        moves.push(Move {
            target,
            length: dist * s.length_factor,
            feed: s.feed,
            stop_after: s.stop,
            dwell_after: s.dwell,
            tag: k as u32,
        });
        q = target;
    }
    moves
}

/// Limits of segment `i` computed independently from its direction.
fn seg_limits(p: &Plan, i: usize, c: &Case, feed: f64) -> (f64, f64, f64) {
    let u = p.direction(i);
    let (mut v, mut a, mut j) = (feed.min(c.path.0), c.path.1, c.path.2);
    for k in 0..c.n_axes {
        if u[k] != 0.0 {
            v = v.min(c.limits.v[k] / u[k].abs());
            a = a.min(c.limits.a[k] / u[k].abs());
            j = j.min(c.limits.j[k] / u[k].abs());
        }
    }
    (v, a, j)
}

fn check(c: &Case, moves: &[Move], profile: ProfileKind) -> Result<(), TestCaseError> {
    let cfg = PlannerConfig {
        profile,
        junction_deviation: c.junction_deviation,
        path_v: c.path.0,
        path_a: c.path.1,
        path_j: c.path.2,
        lookahead: c.lookahead,
        n_axes: c.n_axes,
        corners: lase_runtime::planner::Corners::JunctionDeviation,
    };
    let p =
        plan([0.0; 6], moves, &c.limits, &cfg).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let scurve = profile == ProfileKind::SCurve;
    let segs = p.segments();
    prop_assert!(!segs.is_empty());

    // Stops: a segment must end at rest if any move merged into it asked for a stop.
    for (i, seg) in segs.iter().enumerate() {
        let next_move = segs
            .get(i + 1)
            .map_or(moves.len(), |s| s.move_index as usize);
        let stop = moves[seg.move_index as usize..next_move]
            .iter()
            .any(|m| m.stop_after || m.dwell_after > 0.0);
        if stop || i + 1 == segs.len() {
            prop_assert_eq!(seg.v_exit, 0.0, "segment {} must stop", i);
            let end = p.sample_segment(i, seg.duration());
            prop_assert_eq!(end.v, 0.0);
        }
        if seg.dwell > 0.0 {
            let mid = p.sample(seg.t_start + seg.motion_duration() + 0.5 * seg.dwell);
            prop_assert!(mid.dwelling && mid.v == 0.0 && mid.segment == i);
        }
        prop_assert!(seg.v_peak >= seg.v_entry.max(seg.v_exit), "{:?}", seg);
    }

    // Every instant at 1 kHz plus every segment boundary, checked against the limits of its
    // own segment.
    let mut times: Vec<f64> = Vec::new();
    let n_ticks = (p.duration() * 1000.0).ceil() as usize;
    times.extend((0..=n_ticks).map(|k| k as f64 * 1e-3));
    for seg in segs {
        times.push(seg.t_start);
        times.push(seg.t_start + seg.motion_duration());
    }
    for &t in &times {
        let smp = p.sample(t);
        let i = smp.segment;
        let seg = &segs[i];
        let (vl, al, jl) = seg_limits(&p, i, c, seg.feed);
        prop_assert!(
            smp.v >= -1e-12 && smp.v <= vl * LIM + 1e-12,
            "t={} v={} limit {}",
            t,
            smp.v,
            vl
        );
        prop_assert!(smp.a.abs() <= al * LIM, "t={} a={} limit {}", t, smp.a, al);
        if scurve {
            prop_assert!(smp.j.abs() <= jl * LIM, "t={} j={} limit {}", t, smp.j, jl);
        }
        for k in 0..c.n_axes {
            prop_assert!(
                smp.vel[k].abs() <= c.limits.v[k] * LIM,
                "axis {} vel {}",
                k,
                smp.vel[k]
            );
            prop_assert!(
                smp.acc[k].abs() <= c.limits.a[k] * LIM,
                "axis {} acc {}",
                k,
                smp.acc[k]
            );
            if scurve {
                prop_assert!(
                    smp.jerk[k].abs() <= c.limits.j[k] * LIM,
                    "axis {} jerk {}",
                    k,
                    smp.jerk[k]
                );
            }
        }
    }

    // Continuity across every boundary: the end of segment i equals the start of i + 1.
    for i in 0..segs.len() - 1 {
        let end = p.sample_segment(i, segs[i].duration());
        let start = p.sample_segment(i + 1, 0.0);
        for k in 0..6 {
            prop_assert!(
                (end.pos[k] - start.pos[k]).abs() <= 1e-9,
                "pos jump at {}: {:?} vs {:?}\n{:?}",
                i,
                end,
                start,
                segs
            );
        }
        prop_assert!(
            (end.v - start.v).abs() <= 1e-9,
            "speed jump at {}: {} vs {}",
            i,
            end.v,
            start.v
        );
        prop_assert!((end.s - start.s).abs() <= 1e-9);
        prop_assert!((end.t - start.t).abs() <= 1e-9);
        // S-curve: acceleration is continuous where the path goes straight on. The path
        // acceleration is 0 at both sides; approaching from inside, it changes at most at the
        // jerk limit.
        let (u0, u1) = (p.direction(i), p.direction(i + 1));
        let n0 = u0.iter().map(|x| x * x).sum::<f64>().sqrt();
        let n1 = u1.iter().map(|x| x * x).sum::<f64>().sqrt();
        let cos = if n0 > 0.0 && n1 > 0.0 {
            u0.iter().zip(&u1).map(|(a, b)| a * b).sum::<f64>() / (n0 * n1)
        } else {
            0.0
        };
        if scurve && cos > 1.0 - 1e-9 && segs[i].dwell == 0.0 {
            prop_assert!(end.a == 0.0 && start.a == 0.0);
            for k in 0..6 {
                prop_assert!((end.acc[k] - start.acc[k]).abs() <= 1e-9);
            }
            let h = 1e-6;
            let left = p.sample(segs[i + 1].t_start - h);
            let right = p.sample(segs[i + 1].t_start + h);
            let (_, _, j0) = seg_limits(&p, i, c, segs[i].feed);
            let (_, _, j1) = seg_limits(&p, i + 1, c, segs[i + 1].feed);
            prop_assert!((left.a - right.a).abs() <= (j0 + j1) * h * LIM + 1e-9);
        }
    }

    // Starts at rest at the start, ends at rest on the last target.
    let first = p.sample(0.0);
    prop_assert_eq!(first.v, 0.0);
    let last = p.sample(p.duration());
    prop_assert_eq!(last.v, 0.0);
    let target = moves.last().unwrap().target;
    for k in 0..6 {
        prop_assert!((last.pos[k] - target[k]).abs() <= 1e-9);
        prop_assert_eq!(p.end()[k], target[k]);
    }
    let total: f64 = segs.iter().map(|s| s.duration()).sum();
    prop_assert!((total - p.duration()).abs() <= 1e-9 * total.max(1.0));
    Ok(())
}

proptest! {
    // 64 cases keep the debug run to seconds; PROPTEST_CASES=N runs a longer hunt.
    #![proptest_config(ProptestConfig {
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(64),
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_paths_respect_limits_and_continuity(c in case()) {
        let moves = build_moves(&c);
        check(&c, &moves, ProfileKind::Trapezoid)?;
        check(&c, &moves, ProfileKind::SCurve)?;
    }
}
