//! Job origin (issue 20): `lase run --origin current` reads the controller's position, puts
//! the recipe's zero there and checks the travel at the machine positions the job will reach.
//! Against the built-in simulator over a real socket, on a bed whose travel starts at X20 Y10
//! (where the simulator stands after its reset: zero clamped into the travel).

mod link_support;

use link_support::*;
use std::path::PathBuf;
use std::time::Duration;

/// A bed of X [20, 320] mm, Y [10, 210] mm, and two recipes on it: a 30 x 20 mm rectangle at
/// (5, 5) and one 310 mm wide.
fn setup(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lase-origin-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_bed(
        &dir,
        "[\"20 mm\", \"320 mm\"]",
        "[\"10 mm\", \"210 mm\"]",
        "",
    );
    let recipe = |w: &str, at: &str| {
        format!(
            "machine \"bed.toml\"\nlaser {{ power 20 W }}\n\
             follow profile rect({at}, {w}, 20 mm) at 20 mm/s\nmove to {at} rapid\n"
        )
    };
    std::fs::write(dir.join("square.lase"), recipe("30 mm", "(5 mm, 5 mm)")).unwrap();
    std::fs::write(dir.join("wide.lase"), recipe("310 mm", "(5 mm, 5 mm)")).unwrap();
    // The origin chosen in the recipe.
    std::fs::write(
        dir.join("placed.lase"),
        recipe("30 mm", "(5 mm, 5 mm)").replacen("\n", "\nplanner { origin current }\n", 1),
    )
    .unwrap();
    dir
}

#[test]
fn current_origin_streams_the_job_at_the_controllers_position() {
    let dir = setup("ok");
    let sim = bed_sim(&dir, [[0.0; 6]; 6]);
    let square = dir.join("square.lase");
    let square = square.to_str().unwrap();
    // Absolute, the rectangle at (5, 5) lies outside the travel.
    let (code, _, err) = lase(&["run", square, "--link", &url(&sim)]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::plan::travel"), "{err}");
    let (code, _, err) = lase(&["run", square, "--link", &url(&sim), "--origin", "current"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("position X20 Y10"), "{err}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    // The lit rectangle runs from (5, 5) to (35, 25) in the recipe: (25, 15) to (55, 35) on
    // the machine, the streamed lines' own coordinates.
    let runs = executed_lit_runs(&rec);
    assert_eq!(runs.len(), 1, "{runs:?}");
    let b = lit_extent(&rec);
    for (got, want) in b.iter().zip([25.0, 15.0, 55.0, 35.0]) {
        assert!((got - want).abs() < 1e-3, "lit extent {b:?}");
    }
    assert!((runs[0].2 - 100.0).abs() < 1e-3, "perimeter {}", runs[0].2);
    let g = gcode_lines(&rec);
    assert!(
        g.iter().any(|l| l.contains("X55") && l.contains("S")),
        "{g:#?}"
    );
    // It ends at its `move to (5, 5) rapid`: (25, 15).
    let end = rec.blocks.last().unwrap().to;
    assert!(
        (end[0] - 25.0).abs() < 1e-3 && (end[1] - 15.0).abs() < 1e-3,
        "{end:?}"
    );
}

#[test]
fn current_origin_refuses_a_job_that_would_leave_the_travel_before_sending() {
    let dir = setup("wide");
    let sim = bed_sim(&dir, [[0.0; 6]; 6]);
    let wide = dir.join("wide.lase");
    let (code, _, err) = lase(&[
        "run",
        wide.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--origin",
        "current",
    ]);
    assert_eq!(code, 1, "{err}");
    // 5 + 310 mm from X20: the far side at X335, past the travel's 320.
    assert!(
        err.contains("lase::plan::travel") && err.contains("335 mm outside [20 mm, 320 mm]"),
        "{err}"
    );
    assert!(
        err.contains("lase::origin::placed") && err.contains("X20 Y10"),
        "{err}"
    );
    assert!(
        err.contains("wide.lase:3:1"),
        "the span is the follow: {err}"
    );
    assert!(sim.wait_quiet(Duration::from_secs(2)));
    let rec = sim.stop();
    assert!(gcode_lines(&rec).is_empty(), "nothing of the job was sent");
}

#[path = "common/rs274.rs"]
mod rs274;

/// `lase emit --origin current`: the recipe's own coordinates in a work frame the header sets
/// where the operator has jogged (`G10 L20 P1 X0 Y0`, `G54`, right after the units and
/// distance mode), accepted by LinuxCNC's interpreter; absolute, the same job leaves the bed.
#[test]
fn emit_current_writes_the_work_frame_and_its_setup() {
    let dir = setup("emit");
    let square = dir.join("square.lase");
    let square = square.to_str().unwrap();
    let (code, _, err) = lase(&["emit", square]);
    assert_eq!(code, 1, "absolute, (5, 5) lies outside X [20, 320]: {err}");
    for dialect in ["linuxcnc", "grbl", "grblhal"] {
        let (code, nc, err) = lase(&["emit", square, "--origin", "current", "--dialect", dialect]);
        assert_eq!(code, 0, "{dialect}: {err}");
        let lines: Vec<&str> = nc.lines().collect();
        let at = lines.iter().position(|l| l.starts_with("G21 G90")).unwrap();
        assert!(
            lines[at + 1].starts_with("(origin: current position"),
            "{nc}"
        );
        assert_eq!(lines[at + 2], "G10 L20 P1 X0 Y0", "{dialect}");
        assert_eq!(lines[at + 3], "G54", "{dialect}");
        // The rectangle's corners as the recipe wrote them: X5..35, Y5..25.
        let xs: Vec<f64> = lines
            .iter()
            .flat_map(|l| l.split_whitespace())
            .filter_map(|w| w.strip_prefix('X').and_then(|v| v.parse().ok()))
            .collect();
        for want in [5.0, 35.0] {
            assert!(
                xs.iter().any(|x| (x - want).abs() < 1e-9),
                "{dialect}: X{want}: {nc}"
            );
        }
        assert!(
            xs.iter().all(|x| (-1.0..=36.0).contains(x)),
            "{dialect}: {xs:?}"
        );
        if dialect == "linuxcnc" {
            let ngc = dir.join("square.ngc");
            std::fs::write(&ngc, &nc).unwrap();
            let out = rs274::rs274_g(&ngc).unwrap();
            let text = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "rs274: {text}");
            // It ran past the setup: the comment, G10's offset and the cut after it.
            let setup = text
                .find("COMMENT(\"origin: current position")
                .expect("setup");
            assert!(text[setup..].contains("SET_G5X_OFFSET(1,"), "{text}");
            assert!(
                text[setup..].contains("STRAIGHT_FEED(35.0000, 5.0000"),
                "{text}"
            );
        }
    }
    // Larger than the travel: no start fits it.
    let wide = dir.join("wide.lase");
    let (code, _, err) = lase(&["emit", wide.to_str().unwrap(), "--origin", "current"]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::origin::too_large"), "{err}");
    let (code, _, err) = lase(&["emit", square, "--origin", "current", "--dialect", "iso"]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::origin::dialect"), "{err}");
}

/// `planner { origin current }` in the recipe chooses the same as `--origin current`, and
/// `--origin absolute` on the command line overrides it.
#[test]
fn the_recipe_chooses_the_origin_and_the_command_line_overrides_it() {
    let dir = setup("recipe");
    let placed = dir.join("placed.lase");
    let placed = placed.to_str().unwrap();
    let (code, nc, err) = lase(&["emit", placed]);
    assert_eq!(code, 0, "{err}");
    assert!(nc.lines().any(|l| l == "G10 L20 P1 X0 Y0"), "{nc}");
    let (code, _, err) = lase(&["emit", placed, "--origin", "absolute"]);
    assert_eq!(code, 1, "absolute, (5, 5) lies outside X [20, 320]: {err}");
    assert!(err.contains("lase::plan::travel"), "{err}");
    let sim = bed_sim(&dir, [[0.0; 6]; 6]);
    let (code, _, err) = lase(&["run", placed, "--link", &url(&sim)]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("position X20 Y10"), "{err}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    let end = rec.blocks.last().unwrap().to;
    assert!(
        (end[0] - 25.0).abs() < 1e-3 && (end[1] - 15.0).abs() < 1e-3,
        "{end:?}"
    );
}
