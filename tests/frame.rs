//! `lase frame` against the built-in simulator over a real socket (issue 20): the controller
//! executes only dark moves, traces the bounding box of the recipe's lit work and ends where
//! the job starts.

mod link_support;

use lase_runtime::link::sim::{SimOptions, TimeScale};
use link_support::*;
use std::time::Duration;

#[test]
fn frame_traces_the_lit_extent_dark_and_returns_to_the_start() {
    let ex = root().join("examples/nested_parts.lase");
    let c = compile(&ex);
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Max,
            ..SimOptions::default()
        },
    );
    let (code, out, err) = lase(&["frame", ex.to_str().unwrap(), "--link", &url(&sim)]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("done"), "{out}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    assert!(!rec.blocks.is_empty());
    // Beam off throughout: no block lit, no laser edge above 0.
    assert!(rec.blocks.iter().all(|b| b.laser_s == 0.0));
    assert!(rec.laser.iter().all(|e| e.power_s == 0.0));
    // The extent of the lit work: six 30 x 20 mm plates, their outlines moved 0.1 mm out by
    // the kerf, from (-100, -60) to (90, 60) mm.
    let want = [-100.1, -60.1, 90.1, 60.1];
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for blk in &rec.blocks {
        for p in [blk.from, blk.to] {
            b = [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ];
        }
    }
    for (got, w) in b.iter().zip(want) {
        assert!((got - w).abs() < 1e-3, "framed {b:?}, lit extent {want:?}");
    }
    // Every corner of the box is visited, and the last move ends where the job starts.
    for corner in [
        [want[0], want[1]],
        [want[2], want[1]],
        [want[2], want[3]],
        [want[0], want[3]],
    ] {
        assert!(
            rec.blocks
                .iter()
                .any(|blk| (blk.to[0] - corner[0]).abs() < 1e-3
                    && (blk.to[1] - corner[1]).abs() < 1e-3),
            "corner {corner:?} not visited"
        );
    }
    let end = rec.blocks.last().unwrap().to;
    let start = to_controller(&c.job.program.machine)(&c.job.start);
    assert!(
        (end[0] - start[0]).abs() < 1e-3 && (end[1] - start[1]).abs() < 1e-3,
        "ends at {end:?}"
    );
}

#[test]
fn frame_refuses_a_machine_that_orients_the_beam() {
    let (code, _, err) = lase(&["frame", "examples/cam_hardening.lase"]);
    assert_eq!(code, 1);
    assert!(err.contains("orients the beam"), "{err}");
}
