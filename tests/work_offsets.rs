//! Named work offsets (issue 20): `--origin g55` runs the recipe in the controller's G55,
//! selected by the program and never written, with the travel checked at the machine positions
//! the job reaches (machine = work + offset). `lase run` reads the offset from the controller
//! (`$#`, here the built-in simulator's, which applies it as GRBL does); `lase emit` takes it
//! from `--work-offset` or the machine file's `[work_offsets]`, and says so when it has none.

mod link_support;

use link_support::*;
use std::path::PathBuf;
use std::time::Duration;

#[path = "common/rs274.rs"]
mod rs274;

/// A bed of X [0, 300] mm, Y [0, 200] mm whose machine file knows G55 at X100 Y50 and G56 at
/// X280 Y50, and a 30 x 20 mm rectangle at (5, 5).
fn setup(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lase-offsets-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    write_bed(
        &dir,
        "[\"0 mm\", \"300 mm\"]",
        "[\"0 mm\", \"200 mm\"]",
        "\n[work_offsets]\ng55 = { X = \"100 mm\", Y = \"50 mm\" }\n\
         g56 = { X = \"280 mm\", Y = \"50 mm\" }\n",
    );
    std::fs::write(
        dir.join("square.lase"),
        "machine \"bed.toml\"\nlaser { power 20 W }\n\
         follow profile rect((5 mm, 5 mm), 30 mm, 20 mm) at 20 mm/s\nmove to (5 mm, 5 mm) rapid\n",
    )
    .unwrap();
    dir
}

/// The X and Y words of the program's motion blocks, in work coordinates.
fn xy_words(nc: &str) -> Vec<(Option<f64>, Option<f64>)> {
    let word = |l: &str, c: char| {
        l.split_whitespace()
            .find_map(|w| w.strip_prefix(c).and_then(|v| v.parse::<f64>().ok()))
    };
    nc.lines()
        // ISO numbers its blocks (`N120 G1 X5`).
        .map(|l| {
            l.trim_start_matches(|c: char| c == 'N' || c.is_ascii_digit())
                .trim()
        })
        .filter(|l| l.starts_with('G') || l.starts_with('X') || l.starts_with('Y'))
        .map(|l| (word(l, 'X'), word(l, 'Y')))
        .filter(|(x, y)| x.is_some() || y.is_some())
        .collect()
}

#[test]
fn emit_selects_g55_and_checks_the_travel_at_machine_positions() {
    let dir = setup("emit");
    let square = dir.join("square.lase");
    let square = square.to_str().unwrap();
    for dialect in ["linuxcnc", "grbl", "grblhal", "iso"] {
        let (code, nc, err) = lase(&["emit", square, "--origin", "g55", "--dialect", dialect]);
        assert_eq!(code, 0, "{dialect}: {err}");
        assert!(!err.contains("warning"), "the offset is known: {err}");
        let lines: Vec<&str> = nc
            .lines()
            .map(|l| {
                l.trim_start_matches(|c: char| c == 'N' || c.is_ascii_digit())
                    .trim()
            })
            .collect();
        let at = lines.iter().position(|l| l.starts_with("G21 G90")).unwrap();
        assert!(
            lines[at + 1].contains("origin: work offset G55 X100 Y50"),
            "{nc}"
        );
        assert_eq!(lines[at + 2], "G55", "{dialect}: {nc}");
        assert!(
            !nc.contains("G10"),
            "the operator's offset is never written: {nc}"
        );
        // Work coordinates as the recipe wrote them; with the offset, the machine positions
        // (X105..135, Y55..75) lie inside the bed.
        let words = xy_words(&nc);
        let xs: Vec<f64> = words.iter().filter_map(|w| w.0).collect();
        let ys: Vec<f64> = words.iter().filter_map(|w| w.1).collect();
        for want in [5.0, 35.0] {
            assert!(
                xs.iter().any(|x| (x - want).abs() < 1e-9),
                "{dialect}: X{want}"
            );
        }
        let machine_x: Vec<f64> = xs.iter().map(|x| x + 100.0).collect();
        let machine_y: Vec<f64> = ys.iter().map(|y| y + 50.0).collect();
        assert!(
            machine_x.iter().all(|x| (100.0..=300.0).contains(x)),
            "{machine_x:?}"
        );
        assert!(
            machine_y.iter().all(|y| (50.0..=200.0).contains(y)),
            "{machine_y:?}"
        );
        if dialect == "linuxcnc" {
            // LinuxCNC's interpreter selects G55 (its offset is the controller's: zero here)
            // and runs the cut in it.
            let ngc = dir.join("square.ngc");
            std::fs::write(&ngc, &nc).unwrap();
            let out = rs274::rs274_g(&ngc).unwrap();
            let text = String::from_utf8_lossy(&out.stdout);
            assert!(out.status.success(), "rs274: {text}");
            // G55 is selected before the first move and stays until M2 (which restores G54).
            let g55 = text.find("SET_G5X_OFFSET(2,").expect("G55 selected");
            let cut = text.find("STRAIGHT_FEED(35.0000, 5.0000").expect("the cut");
            let first_move = text.find("STRAIGHT_TRAVERSE").expect("a move");
            assert!(g55 < first_move && first_move < cut, "{text}");
            assert!(!text[g55..cut].contains("SET_G5X_OFFSET(1,"), "{text}");
        }
    }
    // --work-offset overrides the machine file's.
    let (code, nc, err) = lase(&[
        "emit",
        square,
        "--origin",
        "g55",
        "--work-offset",
        "X10 Y20",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(nc.contains("(origin: work offset G55 X10 Y20)"), "{nc}");
}

#[test]
fn emit_refuses_a_job_the_offset_puts_outside_the_travel() {
    let dir = setup("refuse");
    let square = dir.join("square.lase");
    let (code, out, err) = lase(&["emit", square.to_str().unwrap(), "--origin", "g56"]);
    assert_eq!(code, 1, "{out}");
    // X280 + 35 = 315, past the bed's 300.
    assert!(
        err.contains("lase::plan::travel") && err.contains("35 mm outside [-280 mm, 20 mm]"),
        "{err}"
    );
    assert!(
        err.contains("lase::origin::offset") && err.contains("G56 (X280 Y50)"),
        "{err}"
    );
    assert!(out.is_empty(), "nothing written: {out}");
}

#[test]
fn emit_without_the_offset_warns_and_set_origin_writes_g10_l20_p2() {
    let dir = setup("unknown");
    let square = dir.join("square.lase");
    let square = square.to_str().unwrap();
    let (code, nc, err) = lase(&["emit", square, "--origin", "g57"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains("warning: the work offset G57 is not known here")
            && err.contains("not at machine positions"),
        "{err}"
    );
    assert!(nc.lines().any(|l| l == "G57"), "{nc}");
    let (code, nc, err) = lase(&["emit", square, "--origin", "g55", "--set-origin"]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = nc.lines().collect();
    let at = lines
        .iter()
        .position(|l| *l == "G10 L20 P2 X0 Y0")
        .expect("G10 L20 P2");
    assert_eq!(lines[at + 1], "G55", "{nc}");
    let (code, _, err) = lase(&["emit", square, "--origin", "current", "--set-origin"]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::origin::set_origin"), "{err}");
}

/// The simulator of the bed, holding G55 at X100 Y50 and G56 at X280 Y50 (as `$#` reports).
fn offsets_sim(dir: &std::path::Path) -> lase_runtime::link::sim::SimHandle {
    let mut work_offsets = [[0.0; 6]; 6];
    work_offsets[1][..2].copy_from_slice(&[100.0, 50.0]);
    work_offsets[2][..2].copy_from_slice(&[280.0, 50.0]);
    bed_sim(dir, work_offsets)
}

#[test]
fn run_reads_g55_from_the_controller_and_the_job_runs_there() {
    let dir = setup("run");
    // The machine file's offsets are not the controller's: run must use what `$#` says.
    let bed = dir.join("bed.toml");
    let text = std::fs::read_to_string(&bed).unwrap();
    std::fs::write(
        &bed,
        text.replace("g55 = { X = \"100 mm\"", "g55 = { X = \"1 mm\""),
    )
    .unwrap();
    let sim = offsets_sim(&dir);
    let square = dir.join("square.lase");
    let (code, _, err) = lase(&[
        "run",
        square.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--origin",
        "g55",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("work offset G55 X100 Y50"), "{err}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    assert!(
        gcode_lines(&rec).iter().any(|l| l == "G55"),
        "the program selects G55"
    );
    // The lit rectangle, (5, 5) to (35, 25) in the recipe, ran at (105, 55) to (135, 75) in
    // machine coordinates: the executed blocks' own.
    let b = lit_extent(&rec);
    for (got, want) in b.iter().zip([105.0, 55.0, 135.0, 75.0]) {
        assert!((got - want).abs() < 1e-3, "lit extent {b:?}");
    }
}

#[test]
fn run_refuses_a_job_the_controllers_offset_puts_outside_the_travel_before_sending() {
    let dir = setup("run-refuse");
    let sim = offsets_sim(&dir);
    let square = dir.join("square.lase");
    let (code, _, err) = lase(&[
        "run",
        square.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--origin",
        "g56",
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::plan::travel"), "{err}");
    assert!(
        err.contains("lase::origin::offset") && err.contains("G56 (X280 Y50)"),
        "{err}"
    );
    assert!(sim.wait_quiet(Duration::from_secs(2)));
    let rec = sim.stop();
    assert!(gcode_lines(&rec).is_empty(), "nothing of the job was sent");
}
