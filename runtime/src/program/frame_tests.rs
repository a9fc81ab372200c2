//! Unit tests of `ProcessProgram::frame` (the job's bounding box, traced for `lase frame`).

use super::*;

#[test]
fn a_frame_bounds_arcs_by_their_extreme_points_and_returns_to_the_start() {
    let laser = Laser {
        power_w: 10.0,
        spot_mm: 0.1,
        pulse: None,
        couple: Coupling::None,
        kerf_mm: 0.0,
    };
    let arc = |to: P3| Op {
        kind: OpKind::Arc {
            to,
            center: [10.0, 0.0],
            ccw: true,
            feed_mm_s: 5.0,
            laser: Some(std::sync::Arc::new(laser.clone())),
        },
        span: Span::default(),
    };
    let rapid = Op {
        kind: OpKind::Rapid {
            to: [15.0, 0.0, 0.0],
            orient: None,
        },
        span: Span::default(),
    };
    // A circle of radius 5 about (10, 0) in two half turns: its ends alone span y = 0.
    let p = super::tests::program(vec![rapid, arc([5.0, 0.0, 0.0]), arc([15.0, 0.0, 0.0])]);
    let f = p.frame(20.0, None).unwrap();
    // The box, without the rapid back to the start.
    let pts: Vec<P3> = f.ops[..f.ops.len() - 1]
        .iter()
        .filter_map(Op::target)
        .collect();
    let (lo, hi) = pts
        .iter()
        .fold(([f64::MAX; 2], [f64::MIN; 2]), |(lo, hi), q| {
            (
                [lo[0].min(q[0]), lo[1].min(q[1])],
                [hi[0].max(q[0]), hi[1].max(q[1])],
            )
        });
    assert_eq!((lo, hi), ([5.0, -5.0], [15.0, 5.0]));
    assert!(f.ops.iter().all(|o| o.laser().is_none()));
    assert_eq!(f.ops.last().and_then(Op::target), Some([0.0; 3]));
    // The frame starts at the corner nearest the start, (5, -5).
    assert_eq!(f.ops[0].target(), Some([5.0, -5.0, 0.0]));
}
