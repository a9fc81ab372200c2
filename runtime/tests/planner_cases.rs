//! Planner behaviour on small hand-made programs: junction speeds, dwells, zero-length moves,
//! per-axis limits, sampling edge cases, the notch program of PROCESS.md §4, and refusals.

use lase_runtime::planner::{
    Axes, AxisLimits, Move, PlanError, PlannerConfig, ProfileKind, Segment, plan,
    speed_change_distance,
};

const INF: f64 = f64::INFINITY;

fn at(x: f64, y: f64, z: f64) -> Axes {
    Axes([x, y, z, 0.0, 0.0, 0.0])
}

fn limits(v: f64, a: f64, j: f64) -> AxisLimits {
    AxisLimits {
        v: [v; 6],
        a: [a; 6],
        j: [j; 6],
    }
}

fn cfg(profile: ProfileKind) -> PlannerConfig {
    PlannerConfig {
        profile,
        ..PlannerConfig::default()
    }
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

#[test]
fn segment_is_compact() {
    let size = std::mem::size_of::<Segment>();
    println!("size_of::<Segment>() = {size} bytes");
    assert!(size <= 200, "{size}");
}

#[test]
fn right_angle_corner_uses_grbl_junction_speed() {
    let moves = [
        Move::linear(at(0., 0., 0.), at(50., 0., 0.), 100.0),
        Move::linear(at(50., 0., 0.), at(50., 50., 0.), 100.0),
    ];
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let c = PlannerConfig {
            junction_deviation: 0.05,
            ..cfg(profile)
        };
        let p = plan([0.0; 6], &moves, &limits(200.0, 1000.0, 20_000.0), &c).unwrap();
        let s = 0.5f64.sqrt();
        let expect = (1000.0 * 0.05 * s / (1.0 - s)).sqrt();
        assert!(
            close(p.segments()[0].v_exit, expect, 1e-12),
            "{}",
            p.segments()[0].v_exit
        );
        assert!(close(p.segments()[0].v_peak, 100.0, 1e-12));
    }
}

#[test]
fn straight_junction_keeps_speed_and_reversal_stops() {
    let straight = [
        Move::linear(at(0., 0., 0.), at(30., 0., 0.), 50.0),
        Move::linear(at(30., 0., 0.), at(60., 0., 0.), 50.0),
    ];
    let p = plan(
        [0.0; 6],
        &straight,
        &limits(200.0, 1000.0, 1e5),
        &cfg(ProfileKind::SCurve),
    )
    .unwrap();
    assert_eq!(p.segments()[0].v_exit, 50.0);
    // As one 60 mm rest-to-rest S-curve move (v ≥ a²/J): T = L/v + v/a + a/J.
    assert!(close(
        p.duration(),
        60.0 / 50.0 + 50.0 / 1000.0 + 1000.0 / 1e5,
        1e-12
    ));
    let back = [
        Move::linear(at(0., 0., 0.), at(30., 0., 0.), 50.0),
        Move::linear(at(30., 0., 0.), at(0., 0., 0.), 50.0),
    ];
    let c = PlannerConfig {
        junction_deviation: INF,
        ..cfg(ProfileKind::Trapezoid)
    };
    let p = plan([0.0; 6], &back, &limits(200.0, 1000.0, 1e4), &c).unwrap();
    assert_eq!(p.segments()[0].v_exit, 0.0);
}

#[test]
fn diagonal_move_is_limited_by_its_tightest_axis() {
    // u = (0.6, 0.8): v ≤ min(100/0.6, 40/0.8) = 50, a ≤ min(1000/0.6, 400/0.8) = 500.
    let lim = AxisLimits {
        v: [100.0, 40.0, 1.0, 1.0, 1.0, 1.0],
        a: [1000.0, 400.0, 1.0, 1.0, 1.0, 1.0],
        j: [INF; 6],
    };
    let mv = [Move::linear([0.0; 6], at(60., 80., 0.), INF)];
    let p = plan(
        [0.0; 6],
        &mv,
        &lim,
        &PlannerConfig {
            n_axes: 2,
            ..cfg(ProfileKind::Trapezoid)
        },
    )
    .unwrap();
    assert!(close(p.segments()[0].v_peak, 50.0, 1e-12));
    assert!(close(p.duration(), 100.0 / 50.0 + 50.0 / 500.0, 1e-12));
    let mid = p.sample(1.0);
    assert!(close(mid.vel[1], 40.0, 1e-12) && close(mid.vel[0], 30.0, 1e-12));
    // A part-space length twice the axis distance halves u and doubles the path limits.
    let chord = [Move {
        length: 200.0,
        ..mv[0]
    }];
    let p = plan(
        [0.0; 6],
        &chord,
        &lim,
        &PlannerConfig {
            n_axes: 2,
            ..cfg(ProfileKind::Trapezoid)
        },
    )
    .unwrap();
    assert!(close(p.segments()[0].v_peak, 100.0, 1e-12));
    let end = p.sample(p.duration());
    assert_eq!(end.pos, at(60., 80., 0.));
    assert!(close(end.s, 200.0, 1e-12));
}

#[test]
fn dwell_is_standstill_on_the_timeline() {
    let mut first = Move::linear([0.0; 6], at(10., 0., 0.), 50.0);
    first.dwell_after = 0.25;
    first.tag = 7;
    let moves = [first, Move::linear(at(10., 0., 0.), at(20., 0., 0.), 50.0)];
    let p = plan(
        [0.0; 6],
        &moves,
        &limits(100.0, 1000.0, 1e4),
        &cfg(ProfileKind::Trapezoid),
    )
    .unwrap();
    let seg = p.segments()[0];
    let single = 10.0 / 50.0 + 50.0 / 1000.0;
    assert!(close(seg.motion_duration(), single, 1e-12) && seg.dwell == 0.25);
    assert!(close(p.duration(), 2.0 * single + 0.25, 1e-12));
    let s = p.sample(single + 0.1);
    assert!(s.dwelling && s.v == 0.0 && s.tag == 7 && s.pos == at(10., 0., 0.));
    assert!(!p.sample(single + 0.3).dwelling);
}

#[test]
fn zero_length_moves_merge_and_a_leading_dwell_gets_a_segment() {
    let mut pause = Move::new([0.0; 6], 0.0, 10.0);
    pause.dwell_after = 0.5;
    let mut stop = Move::new(at(10., 0., 0.), 0.0, 10.0);
    stop.stop_after = true;
    let moves = [
        pause,
        Move::linear([0.0; 6], at(10., 0., 0.), 50.0),
        stop,
        Move::linear(at(10., 0., 0.), at(20., 0., 0.), 50.0),
    ];
    let p = plan(
        [0.0; 6],
        &moves,
        &limits(100.0, 1000.0, 1e4),
        &cfg(ProfileKind::SCurve),
    )
    .unwrap();
    let segs = p.segments();
    assert_eq!(segs.len(), 3);
    assert_eq!(
        (segs[0].length, segs[0].dwell, segs[0].move_index),
        (0.0, 0.5, 0)
    );
    assert!(p.sample(0.2).dwelling);
    // The zero-length stop after move 1 makes move 1 end at rest.
    assert_eq!(segs[1].v_exit, 0.0);
    assert_eq!(segs[2].move_index, 3);
}

#[test]
fn sampling_clamps_out_of_range_input() {
    let moves = [Move::linear([0.0; 6], at(5., 0., 0.), 20.0)];
    let p = plan(
        [0.0; 6],
        &moves,
        &limits(100.0, 1000.0, 1e4),
        &cfg(ProfileKind::SCurve),
    )
    .unwrap();
    assert_eq!(p.sample(-3.0).pos, [0.0; 6]);
    assert_eq!(p.sample(f64::NAN).t, 0.0);
    assert_eq!(p.sample(1e9).pos, at(5., 0., 0.));
    assert_eq!(p.sample_segment(99, 1e9).pos, at(5., 0., 0.));
    let empty = plan(
        at(1., 2., 3.),
        &[],
        &limits(1.0, 1.0, 1.0),
        &cfg(ProfileKind::SCurve),
    )
    .unwrap();
    assert_eq!(
        (empty.duration(), empty.sample(4.0).pos),
        (0.0, at(1., 2., 3.))
    );
}

#[test]
fn path_limits_cap_every_move() {
    let moves = [Move::linear([0.0; 6], at(100., 0., 0.), INF)];
    let c = PlannerConfig {
        path_v: 40.0,
        path_a: 400.0,
        path_j: 8000.0,
        ..cfg(ProfileKind::SCurve)
    };
    let p = plan([0.0; 6], &moves, &limits(1000.0, 1e4, 1e6), &c).unwrap();
    assert!(close(
        p.duration(),
        100.0 / 40.0 + 40.0 / 400.0 + 400.0 / 8000.0,
        1e-12
    ));
}

/// The notch program of PROCESS.md §4 (feeds in mm/min), with a stop at every M-function.
#[test]
fn notch_program_stops_at_m_functions_and_cuts_at_constant_feed() {
    let mm_min = |f: f64| f / 60.0;
    let x = 0usize;
    let z = 2usize;
    let mut q = [0.0; 6];
    let mut moves = Vec::new();
    let mut go = |axis: usize, value: f64, feed: f64, stop: bool, tag: u32| {
        let mut t = q;
        t[axis] = value;
        let mut m = Move::linear(q, t, feed);
        m.stop_after = stop;
        m.tag = tag;
        moves.push(m);
        q = t;
    };
    go(x, 68.5, mm_min(3000.0), true, 10); // N10, then M24 head swing
    go(z, -15.53, mm_min(5000.0), true, 30); // N30, then M27 laser on
    go(z, -33.63, mm_min(950.0), false, 50); // N50: the cut
    go(x, 73.5, mm_min(3000.0), true, 60); // N60, then M25
    let (a, j) = (500.0, 10_000.0);
    let c = PlannerConfig {
        junction_deviation: 0.01,
        ..cfg(ProfileKind::SCurve)
    };
    let p = plan([0.0; 6], &moves, &limits(100.0, a, j), &c).unwrap();
    let segs = p.segments();
    for i in [0, 1, 3] {
        assert_eq!(segs[i].v_exit, 0.0);
        assert_eq!(p.sample(segs[i].t_start + segs[i].motion_duration()).v, 0.0);
    }
    // N10 is a full rest-to-rest S-curve: T = L/v + v/a + a/J.
    let v10 = mm_min(3000.0);
    assert!(close(
        segs[0].motion_duration(),
        68.5 / v10 + v10 / a + a / j,
        1e-12
    ));
    // The cut starts from rest (laser on), reaches 950 mm/min after S03 = F/2 (F/a + a/J), and
    // cruises at exactly that feed.
    let cut = segs[2];
    let f = mm_min(950.0);
    assert_eq!(cut.v_peak, f);
    let (begin, end) = cut.cruise_span();
    assert!(close(begin, speed_change_distance(0.0, f, a, j), 1e-12));
    assert!(
        close(begin, 0.5 * f * (2.0 * (f / j).sqrt()), 1e-12),
        "F < a²/J: no constant-accel phase"
    );
    assert!(end > begin && end < cut.length);
    let mid = p.sample(cut.t_start + cut.motion_duration() * 0.5);
    assert_eq!((mid.tag, mid.v), (50, f));
}

#[test]
fn invalid_input_is_refused_not_panicked_on() {
    let good = Move::linear([0.0; 6], at(1., 0., 0.), 10.0);
    let lim = limits(100.0, 1000.0, 1e4);
    let c = cfg(ProfileKind::SCurve);
    let run = |moves: &[Move], lim: &AxisLimits, c: &PlannerConfig| {
        plan([0.0; 6], moves, lim, c).unwrap_err()
    };
    assert!(matches!(
        run(
            &[Move {
                target: at(f64::NAN, 0., 0.),
                ..good
            }],
            &lim,
            &c
        ),
        PlanError::BadMove {
            field: "target",
            ..
        }
    ));
    assert!(matches!(
        run(&[Move { feed: 0.0, ..good }], &lim, &c),
        PlanError::BadMove { field: "feed", .. }
    ));
    assert!(matches!(
        run(
            &[Move {
                length: -1.0,
                ..good
            }],
            &lim,
            &c
        ),
        PlanError::BadMove {
            field: "length",
            ..
        }
    ));
    assert!(matches!(
        run(
            &[Move {
                dwell_after: f64::NAN,
                ..good
            }],
            &lim,
            &c
        ),
        PlanError::BadMove {
            field: "dwell_after",
            ..
        }
    ));
    assert!(matches!(
        run(
            &[Move {
                length: 0.0,
                ..good
            }],
            &lim,
            &c
        ),
        PlanError::ZeroLengthWithMotion { axis: 0, .. }
    ));
    assert!(matches!(
        run(&[Move::new([0.0; 6], 2.0, 10.0)], &lim, &c),
        PlanError::LengthWithoutMotion { .. }
    ));
    assert!(matches!(
        run(
            &[Move::linear([0.0; 6], [0., 0., 0., 1., 0., 0.], 10.0)],
            &lim,
            &c
        ),
        PlanError::UnusedAxis { axis: 3, .. }
    ));
    let mut neg = lim;
    neg.a[1] = -5.0;
    assert!(matches!(
        run(&[good], &neg, &c),
        PlanError::BadLimit {
            axis: 1,
            kind: "acceleration",
            ..
        }
    ));
    let unlimited = limits(100.0, INF, 1e4);
    assert!(matches!(
        run(&[good], &unlimited, &cfg(ProfileKind::Trapezoid)),
        PlanError::Unbounded { .. }
    ));
    assert!(matches!(
        run(&[good], &limits(100.0, INF, INF), &c),
        PlanError::Unbounded { .. }
    ));
    // A jerk-only S-curve (acceleration unlimited) is fine.
    assert!(plan([0.0; 6], &[good], &unlimited, &c).is_ok());
    assert!(matches!(
        run(&[good], &lim, &PlannerConfig { n_axes: 0, ..c }),
        PlanError::BadConfig {
            field: "n_axes",
            ..
        }
    ));
    assert!(matches!(
        run(&[good], &lim, &PlannerConfig { path_v: 0.0, ..c }),
        PlanError::BadConfig {
            field: "path_v",
            ..
        }
    ));
    assert!(matches!(
        run(
            &[good],
            &lim,
            &PlannerConfig {
                junction_deviation: -1.0,
                ..c
            }
        ),
        PlanError::BadConfig { .. }
    ));
    assert!(matches!(
        plan(at(INF, 0., 0.), &[good], &lim, &c).unwrap_err(),
        PlanError::BadStart { axis: 0, .. }
    ));
    // Diagnostics carry stable codes.
    use miette::Diagnostic;
    let e = run(&[Move { feed: 0.0, ..good }], &lim, &c);
    assert_eq!(e.code().unwrap().to_string(), "lase::plan::bad_move");
}
