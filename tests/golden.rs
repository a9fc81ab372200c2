//! Golden tests: every example recipe's NC program in each dialect and its plan summary are
//! pinned under tests/golden/. `UPDATE_GOLDEN=1 cargo test` rewrites them.
//!
//! Goldens pin behaviour; the physical tests in `physics.rs` prove it right.

mod common;

use common::*;

#[test]
fn examples_match_their_goldens() {
    let examples = lase_files(&root().join("examples"));
    assert!(examples.len() >= 3, "examples/ holds the example recipes");
    for ex in examples {
        let rel = relative(&ex);
        let stem = ex.file_stem().unwrap().to_string_lossy().into_owned();
        for dialect in ["linuxcnc", "grbl", "grblhal", "iso"] {
            let (code, out, err) = lase(&["emit", &rel, "--dialect", dialect]);
            let ext = match dialect {
                "linuxcnc" => "ngc",
                _ => "nc",
            };
            if dialect == "grbl" && code != 0 && err.contains("rotary") {
                // GRBL drives X, Y and Z only: for a machine with rotary axes the refusal is
                // the behaviour to pin.
                golden(&root().join(format!("tests/golden/{stem}.grbl.err")), &err);
                continue;
            }
            assert_eq!(
                code, 0,
                "lase emit {rel} --dialect {dialect} failed:\n{err}"
            );
            golden(
                &root().join(format!("tests/golden/{stem}.{dialect}.{ext}")),
                &out,
            );
        }
        let dir = tempfile::tempdir().unwrap();
        let summary = dir.path().join("summary.json");
        let (code, _, err) = lase(&["plan", &rel, "--summary", summary.to_str().unwrap()]);
        assert_eq!(code, 0, "lase plan {rel} failed:\n{err}");
        let text = std::fs::read_to_string(&summary).unwrap();
        golden(
            &root().join(format!("tests/golden/{stem}.summary.json")),
            &text,
        );
    }
}

/// LinuxCNC's own interpreter accepts every example's LinuxCNC program. `rs274` comes with
/// Debian's linuxcnc-uspace, which `.ci/run` installs; without it (outside CI) the test says so
/// and checks nothing.
#[test]
fn linuxcnc_interpreter_accepts_every_example() {
    let rs274 = std::process::Command::new("rs274").arg("-h").output();
    if rs274.is_err() {
        assert!(
            std::env::var_os("CI").is_none(),
            "rs274 (linuxcnc-uspace) must be installed in CI"
        );
        eprintln!("rs274 not found: skipping the LinuxCNC interpreter check");
        return;
    }
    for ex in lase_files(&root().join("examples")) {
        let rel = relative(&ex);
        let dir = tempfile::tempdir().unwrap();
        let ngc = dir.path().join("job.ngc");
        let (code, _, err) = lase(&["emit", &rel, "-o", ngc.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        let out = rs274_g(&ngc).unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && !text.contains("Unknown") && !text.contains("error"),
            "rs274 rejected {rel}:\n{text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // The interpreter ran the whole program.
        assert!(
            text.contains("PROGRAM_END"),
            "rs274 did not reach the end of {rel}:\n{text}"
        );
    }
}

/// GRBL accepts a small, fixed word set: only those words, and lines of at most 80 characters
/// (GRBL's line buffer). Mirrors grbl's gcode.c.
#[test]
fn grbl_programs_use_only_words_grbl_knows() {
    check_grbl_family("grbl", 80, "XYZ");
}

/// grblHAL reads GRBL's words plus the A, B and C axes, in lines of up to 256 characters
/// (`LINE_BUFFER_SIZE` 257 with the terminator, grblHAL's protocol.h); every example runs on
/// it, the rotary ones included.
#[test]
fn grblhal_programs_use_only_words_grblhal_knows() {
    let checked = check_grbl_family("grblhal", 256, "XYZABC");
    let all = lase_files(&root().join("examples")).len();
    assert_eq!(checked, all, "grblhal emits every example");
}

/// Emits every example for `dialect` (GRBL or grblHAL) and checks each line against the GRBL
/// word set with the axis letters `axes` and the line limit `max_line`. Returns how many
/// examples were emitted (a refused rotary machine on GRBL is skipped: the golden pins it).
fn check_grbl_family(dialect: &str, max_line: usize, axes: &str) -> usize {
    let mut checked = 0;
    for ex in lase_files(&root().join("examples")) {
        let rel = relative(&ex);
        let (code, out, err) = lase(&["emit", &rel, "--dialect", dialect]);
        if dialect == "grbl" && code != 0 && err.contains("rotary") {
            // A machine with rotary axes: refused, and pinned as such by the golden test.
            continue;
        }
        assert_eq!(code, 0, "{err}");
        checked += 1;
        for line in out.lines() {
            assert!(
                line.len() <= max_line,
                "{rel}: line longer than {dialect}'s buffer: {line}"
            );
            for (c, v) in nc_words(line) {
                match c {
                    'G' => assert!(
                        [
                            0.0, 1.0, 2.0, 3.0, 4.0, 17.0, 18.0, 19.0, 20.0, 21.0, 90.0, 91.0,
                            93.0, 94.0
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
    }
    checked
}

/// grblHAL runs GRBL programs: for every example GRBL can run, the grblHAL program is the
/// GRBL one but for the header's dialect name (the stock machines' grblHAL posts are GRBL's).
#[test]
fn grblhal_programs_are_grbl_programs_where_grbl_can_run_them() {
    let mut compared = 0;
    for ex in lase_files(&root().join("examples")) {
        let rel = relative(&ex);
        let (code, grbl, _) = lase(&["emit", &rel, "--dialect", "grbl"]);
        if code != 0 {
            continue;
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
        compared += 1;
    }
    assert!(compared >= 3, "{compared}");
}
