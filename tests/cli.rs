//! The command line as a user meets it: flags named alike across commands and documented in
//! `--help`, and what `lase plan` says about where the cycle goes.

mod common;

use common::*;

/// Every command that writes a file names it with `-o`; `--help` says so, and the old
/// `lase plan --summary` still works (scripts use it).
#[test]
fn output_flags_are_consistent_and_documented() {
    for cmd in ["emit", "plan", "plot"] {
        let (code, out, err) = lase(&[cmd, "--help"]);
        assert_eq!(code, 0, "{err}");
        let line = out
            .lines()
            .find(|l| l.trim_start().starts_with("-o, --output <OUTPUT>"))
            .unwrap_or_else(|| panic!("`lase {cmd} --help` has no -o:\n{out}"));
        // Help text on the same line, after the flag.
        let text = line.trim_start()["-o, --output <OUTPUT>".len()..].trim();
        assert!(text.len() > 10, "`lase {cmd} -o` has no help text: {line}");
    }
    let (_, out, _) = lase(&["plan", "--help"]);
    for flag in ["--trace", "--pulses", "--period"] {
        assert!(
            out.contains(flag),
            "`lase plan --help` lacks {flag}:\n{out}"
        );
    }
    assert!(
        !out.contains("--summary <"),
        "--summary is a hidden alias:\n{out}"
    );
    let dir = tempfile::tempdir().unwrap();
    for flag in ["-o", "--output", "--summary"] {
        let json = dir.path().join(format!("s{flag}.json"));
        let (code, _, err) = lase(&[
            "plan",
            "examples/frame_marking.lase",
            flag,
            json.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{flag}: {err}");
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert!(v["cycle_time_s"].as_f64().unwrap() > 19.0, "{flag}: {v}");
    }
}

/// `time split  lit X s (P %), unlit feed X s (P %), rapid X s (P %), still X s` → the four
/// times.
fn time_split(out: &str) -> [f64; 4] {
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("time split"))
        .unwrap_or_else(|| panic!("no time split:\n{out}"));
    let nums: Vec<f64> = line
        .split_whitespace()
        .zip(line.split_whitespace().skip(1))
        .filter(|(_, unit)| *unit == "s" || unit.starts_with("s,") || *unit == "s,")
        .map(|(n, _)| n.parse().unwrap())
        .collect();
    assert_eq!(nums.len(), 4, "{line}");
    [nums[0], nums[1], nums[2], nums[3]]
}

/// The split adds up to the cycle time, its lit part is the summary's laser-on time, and a
/// hatch fill whose rows are mostly overscan (4 mm lit, 2 × 20 mm overscan) gets the hint,
/// while frame_marking (97 % lit) does not.
#[test]
fn plan_says_how_much_of_the_cycle_is_unlit_and_hints_when_it_dominates() {
    let dir = tempfile::tempdir().unwrap();
    for (recipe, hinted) in [
        ("tests/cli/hatch_overscan.lase", true),
        ("examples/frame_marking.lase", false),
    ] {
        let json = dir.path().join("s.json");
        let (code, out, err) = lase(&["plan", recipe, "-o", json.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let [lit, feed, rapid, still] = time_split(&out);
        let cycle = s["cycle_time_s"].as_f64().unwrap();
        assert!(
            (lit + feed + rapid + still - cycle).abs() < 5e-4,
            "{recipe}: {lit} + {feed} + {rapid} + {still} ≠ {cycle}"
        );
        assert!(
            (lit - s["laser_on_time_s"].as_f64().unwrap()).abs() < 1e-4,
            "{recipe}: {out}"
        );
        assert_eq!(out.contains("hint:"), hinted, "{recipe}:\n{out}");
        if hinted {
            // 80 mm lit at 100 mm/s; each of the 20 rows runs 44 mm, 40 of them overscan.
            assert!((lit - 0.8).abs() < 1e-3, "{out}");
            assert!(feed > 8.0 * lit, "{out}");
            assert!(out.contains("overscan"), "{out}");
        }
    }
}
