//! `lase emit` over the controller's pulse budget (issue 15): a miette diagnostic at the scan
//! (file:line:col, label, help) and exit code 1, no program; the same scan slower is written.

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
