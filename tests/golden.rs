//! Golden tests: every example recipe's NC program in each dialect and its plan summary are
//! pinned under tests/golden/. `UPDATE_GOLDEN=1 cargo test` rewrites them.
//!
//! One trial per example and check (`goldens::frame_marking::grbl`, `rs274::dial_marks`, ...),
//! so `cargo test --test golden frame_marking` runs one example's; see `common::cases`.
//!
//! Goldens pin behaviour; the physical tests in `physics.rs` prove it right.

mod common;

use common::cases::{per_file, run, stem, trial};
use common::*;
use std::path::{Path, PathBuf};

const DIALECTS: [&str; 4] = ["linuxcnc", "grbl", "grblhal", "iso"];

fn main() {
    let examples = lase_files(&root().join("examples"));
    let mut trials = vec![
        trial("examples_are_there", || {
            let n = lase_files(&root().join("examples")).len();
            assert!(n >= 3, "examples/ holds the example recipes");
        }),
        trial(
            "three_examples_or_more_run_on_grbl",
            at_least_three_examples_run_on_grbl,
        ),
    ];
    for dialect in DIALECTS {
        trials.extend(per_file(
            &format!("goldens::{dialect}"),
            &examples,
            move |ex| nc_matches_its_golden(ex, dialect),
        ));
    }
    trials.extend(per_file(
        "goldens::summary",
        &examples,
        summary_matches_its_golden,
    ));
    trials.extend(per_file(
        "rs274",
        &examples,
        linuxcnc_interpreter_accepts_the_example,
    ));
    trials.extend(per_file("grbl_words", &examples, |ex| {
        check_grbl_family(ex, "grbl", 80, "XYZ");
    }));
    trials.extend(per_file("grblhal_words", &examples, |ex| {
        // grblHAL runs every example, the rotary ones included.
        assert!(
            check_grbl_family(ex, "grblhal", 256, "XYZABC"),
            "grblhal emits every example"
        )
    }));
    trials.extend(per_file(
        "grblhal_is_grbl",
        &examples,
        grblhal_program_is_the_grbl_program,
    ));
    run(trials)
}

/// The example's NC program in `dialect` matches `tests/golden/NAME.DIALECT.{ngc,nc}`.
fn nc_matches_its_golden(ex: &Path, dialect: &str) {
    let rel = relative(ex);
    let stem = stem(ex);
    let (code, out, err) = lase(&["emit", &rel, "--dialect", dialect]);
    let ext = match dialect {
        "linuxcnc" => "ngc",
        _ => "nc",
    };
    if dialect == "grbl" && code != 0 && err.contains("rotary") {
        // GRBL drives X, Y and Z only: for a machine with rotary axes the refusal is the
        // behaviour to pin.
        golden(&golden_path(&format!("{stem}.grbl.err")), &err);
        return;
    }
    assert_eq!(
        code, 0,
        "lase emit {rel} --dialect {dialect} failed:\n{err}"
    );
    golden(&golden_path(&format!("{stem}.{dialect}.{ext}")), &out);
}

/// The example's plan summary matches `tests/golden/NAME.summary.json`.
fn summary_matches_its_golden(ex: &Path) {
    let rel = relative(ex);
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("summary.json");
    let (code, _, err) = lase(&["plan", &rel, "--summary", summary.to_str().unwrap()]);
    assert_eq!(code, 0, "lase plan {rel} failed:\n{err}");
    let text = std::fs::read_to_string(&summary).unwrap();
    golden(&golden_path(&format!("{}.summary.json", stem(ex))), &text);
}

fn golden_path(name: &str) -> PathBuf {
    root().join("tests/golden").join(name)
}

/// LinuxCNC's own interpreter accepts the example's LinuxCNC program. `rs274` comes with
/// Debian's linuxcnc-uspace, which `.ci/run` installs; without it (outside CI) the test says so
/// and checks nothing.
fn linuxcnc_interpreter_accepts_the_example(ex: &Path) {
    let rs274 = std::process::Command::new("rs274").arg("-h").output();
    if rs274.is_err() {
        assert!(
            std::env::var_os("CI").is_none(),
            "rs274 (linuxcnc-uspace) must be installed in CI"
        );
        eprintln!("rs274 not found: skipping the LinuxCNC interpreter check");
        return;
    }
    let rel = relative(ex);
    let dir = tempfile::tempdir().unwrap();
    let ngc = dir.path().join("job.ngc");
    let (code, _, err) = lase(&["emit", &rel, "-o", ngc.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let out = rs274_g(&ngc).unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && !text.contains("Unknown") && !text.contains("error"),
        "rs274 rejected {rel} ({}):\n{text}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    // The interpreter ran the whole program.
    assert!(
        text.contains("PROGRAM_END"),
        "rs274 did not reach the end of {rel}:\n{text}"
    );
}

/// GRBL accepts a small, fixed word set: only those words, and lines of at most 80 characters
/// (GRBL's line buffer). Mirrors grbl's gcode.c. grblHAL reads GRBL's words plus the A, B and
/// C axes, in lines of up to 256 characters (`LINE_BUFFER_SIZE` 257 with the terminator,
/// grblHAL's protocol.h).
///
/// Emits the example for `dialect` (GRBL or grblHAL) and checks each line against the GRBL
/// word set with the axis letters `axes` and the line limit `max_line`. Returns whether the
/// example was emitted (a refused rotary machine on GRBL is skipped: the golden pins it).
fn check_grbl_family(ex: &Path, dialect: &str, max_line: usize, axes: &str) -> bool {
    let rel = relative(ex);
    let (code, out, err) = lase(&["emit", &rel, "--dialect", dialect]);
    if dialect == "grbl" && code != 0 && err.contains("rotary") {
        // A machine with rotary axes: refused, and pinned as such by the golden test.
        return false;
    }
    assert_eq!(code, 0, "{err}");
    for line in out.lines() {
        assert!(
            line.len() <= max_line,
            "{rel}: line longer than {dialect}'s buffer: {line}"
        );
        for (c, v) in nc_words(line) {
            match c {
                'G' => assert!(
                    [
                        0.0, 1.0, 2.0, 3.0, 4.0, 17.0, 18.0, 19.0, 20.0, 21.0, 90.0, 91.0, 93.0,
                        94.0
                    ]
                    .contains(&v),
                    "{rel}: {dialect} does not know G{v}: {line}"
                ),
                'M' => assert!(
                    [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 7.0, 8.0, 9.0, 30.0].contains(&v),
                    "{rel}: {dialect} does not know M{v}: {line}"
                ),
                'F' | 'S' | 'I' | 'J' | 'K' | 'P' | 'N' => {}
                a if axes.contains(a) => {}
                other => panic!("{rel}: {dialect} does not know the word {other}: {line}"),
            }
        }
    }
    true
}

/// grblHAL runs GRBL programs: where GRBL can run the example, the grblHAL program is the
/// GRBL one but for the header's dialect name (the stock machines' grblHAL posts are GRBL's).
fn grblhal_program_is_the_grbl_program(ex: &Path) {
    let rel = relative(ex);
    let (code, grbl, _) = lase(&["emit", &rel, "--dialect", "grbl"]);
    if code != 0 {
        return;
    }
    let (code, hal, err) = lase(&["emit", &rel, "--dialect", "grblhal"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        hal.starts_with("(generated by lase ")
            && hal.lines().next().unwrap().ends_with(" for grblhal)")
    );
    assert_eq!(
        grbl.lines().skip(1).collect::<Vec<_>>(),
        hal.lines().skip(1).collect::<Vec<_>>(),
        "{rel}"
    );
}

/// The grblHAL-is-GRBL comparison above means something only if GRBL can run enough of the
/// examples: at least three.
fn at_least_three_examples_run_on_grbl() {
    let compared = lase_files(&root().join("examples"))
        .iter()
        .filter(|ex| lase(&["emit", &relative(ex), "--dialect", "grbl"]).0 == 0)
        .count();
    assert!(compared >= 3, "{compared}");
}
