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

/// `lase frame --pointer` on a machine that allows a pointer power (`[laser] pointer`): the
/// box is traced lit at that power only (0.5 W of 100 W: S5 of 1000), and nothing else is lit;
/// a machine without one refuses `--pointer`.
#[test]
fn frame_at_the_pointer_power_lights_only_the_box_at_that_power() {
    let dir = std::env::temp_dir().join(format!("lase-pointer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stock = std::fs::read_to_string(root().join("stdlib/machines/xy_table.toml")).unwrap();
    let machine = stock.replace(
        "max_pulse_rate = \"100 kHz\"",
        "max_pulse_rate = \"100 kHz\"\npointer = \"0.5 W\"",
    );
    std::fs::write(dir.join("pointer.toml"), &machine).unwrap();
    let recipe = dir.join("plate.lase");
    std::fs::write(
        &recipe,
        "machine \"pointer.toml\"\nlaser { power 40 W }\n\
         follow profile rect((10 mm, 10 mm), 30 mm, 20 mm) at 20 mm/s\n",
    )
    .unwrap();
    let c = compile(&recipe);
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Max,
            ..SimOptions::default()
        },
    );
    let (code, _, err) = lase(&[
        "frame",
        recipe.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--pointer",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    let lit: Vec<_> = rec.blocks.iter().filter(|b| b.laser_s > 0.0).collect();
    assert!(!lit.is_empty(), "the trace is lit");
    for b in &lit {
        assert!(
            (b.laser_s - 5.0).abs() < 1e-9,
            "S{} on a lit block",
            b.laser_s
        );
        // On the box from (10, 10) to (40, 30): one coordinate on an edge, the other inside.
        for p in [b.from, b.to] {
            let on_x = (p[0] - 10.0).abs() < 1e-3 || (p[0] - 40.0).abs() < 1e-3;
            let on_y = (p[1] - 10.0).abs() < 1e-3 || (p[1] - 30.0).abs() < 1e-3;
            assert!(on_x || on_y, "lit off the box at {p:?}");
        }
    }
    let lit_len: f64 = lit
        .iter()
        .map(|b| (b.to[0] - b.from[0]).hypot(b.to[1] - b.from[1]))
        .sum();
    assert!(
        (lit_len - 100.0).abs() < 1e-3,
        "the box's 100 mm lit, {lit_len}"
    );
    let (code, _, err) = lase(&["frame", "examples/nested_parts.lase", "--pointer"]);
    assert_eq!(code, 1);
    assert!(err.contains("allows no pointer power"), "{err}");
}
