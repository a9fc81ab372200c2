//! `lase plan`'s axis peaks speak each axis's unit (mm for a linear axis, deg for a rotary
//! one, per s, s², s³), and the numbers are the plan summary's own.

mod common;

use common::lase;

#[test]
fn axis_peaks_carry_their_units_and_match_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let (code, out, err) = lase(&[
        "plan",
        "examples/cam_hardening.lase",
        "--summary",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut seen = Vec::new();
    for line in out.lines().filter(|l| l.trim_start().starts_with("axis ")) {
        let w: Vec<&str> = line.split_whitespace().collect();
        // axis NAME v V UNIT/s a A UNIT/s² j J UNIT/s³
        let (name, unit) = (w[1], if "ABC".contains(w[1]) { "deg" } else { "mm" });
        assert_eq!(w[4], format!("{unit}/s"), "{line}");
        assert_eq!(w[7], format!("{unit}/s²"), "{line}");
        assert_eq!(w[10], format!("{unit}/s³"), "{line}");
        let peaks = &summary["axes"][name];
        let v: f64 = w[3].parse().unwrap();
        let a: f64 = w[6].parse().unwrap();
        assert!(
            (v - peaks["v_max"].as_f64().unwrap()).abs() < 1e-3,
            "{line}"
        );
        assert!(
            (a - peaks["a_max"].as_f64().unwrap()).abs() < 1e-3,
            "{line}"
        );
        seen.push(name.to_string());
    }
    assert_eq!(seen, ["B", "C", "X"]);
}
