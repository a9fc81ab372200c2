//! `lase emit` over the controller's pulse budget (issue 15): a miette diagnostic at the scan
//! (file:line:col, label, help) and exit code 1, no program; the same scan slower is written.
//! `lase check` refuses it the same way for the controller that runs the program.

mod common;

use common::*;

#[test]
fn emit_refuses_pulses_faster_than_linuxcnc_triggers_at_the_scan() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = |speed: &str| {
        write_file(
            dir.path(),
            &format!("dense_{speed}.lase"),
            &format!(
                "machine xy_table\nlaser {{ power 20 W, spot 40 um }}\npulse {{ rate 20 kHz }}\n\
                 scan dots (0, 0) {{ rows 2, cols 11, pitch 0.02 mm, speed {speed} mm/s }}\n"
            ),
        )
    };
    let fast = recipe("20");
    let (code, out, err) = lase(&["emit", "--dialect", "linuxcnc", fast.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("lase::emit::pulse_budget"), "{err}");
    assert!(err.contains("dense_20.lase:4:1"), "{err}");
    assert!(
        err.contains("pulses at 1000 Hz are faster than LinuxCNC triggers them (500 Hz at most)"),
        "{err}"
    );
    assert!(
        err.contains("the fastest speed LinuxCNC triggers is 10"),
        "{err}"
    );
    let slow = recipe("10");
    let (code, out, err) = lase(&["emit", "--dialect", "linuxcnc", slow.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.matches("M62 P1").count(), 22, "one trigger per spot");
}

#[test]
fn check_refuses_what_emit_refuses_for_the_machines_controller() {
    let dir = tempfile::tempdir().unwrap();
    let fast = write_file(
        dir.path(),
        "dense.lase",
        "machine xy_table\nlaser { power 20 W, spot 40 um }\npulse { rate 20 kHz }\n\
         scan dots (0, 0) { rows 2, cols 11, pitch 0.02 mm, speed 20 mm/s }\n",
    );
    let path = fast.to_str().unwrap();
    // xy_table names no dialect: LinuxCNC's budget, as `lase emit` without --dialect.
    let (_, _, emit_err) = lase(&["emit", path]);
    let (code, out, err) = lase(&["check", path]);
    assert_eq!(code, 1, "{err}");
    assert!(out.is_empty(), "{out}");
    assert!(err.contains("lase::emit::pulse_budget"), "{err}");
    assert!(err.contains("dense.lase:4:1"), "{err}");
    assert!(
        err.contains("pulses at 1000 Hz are faster than LinuxCNC triggers them (500 Hz at most)"),
        "{err}"
    );
    assert_eq!(err, emit_err, "check and emit say the same");
    // GRBL's budget is lower still (300 Hz); an ISO controller has none.
    let (code, _, err) = lase(&["check", "--dialect", "grbl", path]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("faster than GRBL triggers them (300 Hz at most)"),
        "{err}"
    );
    let (code, out, err) = lase(&["check", "--dialect", "iso", path]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("dense.lase: ok"), "{out}");
    let (code, _, err) = lase(&["check", "--dialect", "fanuc", path]);
    assert_eq!(code, 1);
    assert!(err.contains("unknown dialect `fanuc`"), "{err}");
}
