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
        let lines: Vec<&str> = out.lines().collect();
        let at = lines
            .iter()
            .position(|l| l.trim_start().starts_with("-o, --output <OUTPUT>"))
            .unwrap_or_else(|| panic!("`lase {cmd} --help` has no -o:\n{out}"));
        let line = lines[at];
        // Help text on the same line after the flag, or on the next when clap lays the options
        // out with their help below them (as it does once one option's help is long).
        let mut text = line.trim_start()["-o, --output <OUTPUT>".len()..].trim();
        if text.is_empty() {
            text = lines.get(at + 1).map_or("", |l| l.trim());
        }
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

/// The `done` line: `NAME: done — N lines acknowledged in T s (…)` → T.
fn run_seconds(out: &str) -> f64 {
    let t = out
        .split("acknowledged in ")
        .nth(1)
        .unwrap_or_else(|| panic!("{out}"));
    t.split_whitespace().next().unwrap().parse().unwrap()
}

/// The built-in simulator's clock is `--time-scale`: `real` by default (a job takes the
/// firmware's time, as at a machine), `max` streams at once (what tests use), a factor of 40
/// takes about 20 s / 40; it is documented in `--help` and refused for a real controller's
/// link.
#[test]
fn run_time_scale_sets_the_simulators_clock() {
    let (_, help, _) = lase(&["run", "--help"]);
    assert!(
        help.contains("--time-scale") && help.contains("`real` (the default"),
        "{help}"
    );
    // A 1 s job (20 mm at 20 mm/s, plus the ramps) at the default clock takes its time.
    let dir = tempfile::tempdir().unwrap();
    let line = dir.path().join("line.lase");
    std::fs::write(
        &line,
        "machine xy_table\nlaser { power 10 W }\n\
         follow profile polyline [(0, 0), (20 mm, 0)] at 20 mm/s\n",
    )
    .unwrap();
    let (code, out, err) = lase(&["run", line.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let real = run_seconds(&out);
    assert!(real > 0.9, "the default clock ran a 1 s job in {real} s");
    let (code, out, err) = lase(&["run", "examples/frame_marking.lase", "--time-scale", "max"]);
    assert_eq!(code, 0, "{err}");
    let fast = run_seconds(&out);
    let (code, out, err) = lase(&["run", "examples/frame_marking.lase", "--time-scale", "40"]);
    assert_eq!(code, 0, "{err}");
    let scaled = run_seconds(&out);
    // frame_marking plans 20.0 s: at ×40 at least 0.5 s of motion, less the last few blocks
    // the controller still runs after the final `ok`.
    assert!(scaled > 0.4, "×40 took {scaled} s");
    assert!(fast < scaled, "max {fast} s, ×40 {scaled} s");
    let (code, _, err) = lase(&[
        "run",
        "examples/frame_marking.lase",
        "--link",
        "tcp://127.0.0.1:9",
        "--time-scale",
        "real",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("--time-scale"), "{err}");
}

/// Ctrl-C from outside a terminal (SIGINT to a script's `lase run`) is a feed hold too; with
/// nobody to resume it, the held job is then stopped at rest, and lase exits 1 with the abort
/// diagnostic, never killed mid-move with the controller still running.
#[test]
fn sigint_holds_then_stops_a_run_without_a_terminal() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_lase"))
        .args(["run", "examples/frame_marking.lase", "--time-scale", "real"])
        .current_dir(root())
        .env("NO_COLOR", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut header = String::new();
    err.read_line(&mut header).unwrap();
    assert!(header.contains("lines to"), "{header}");
    std::thread::sleep(std::time::Duration::from_millis(500));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(1), "{rest}");
    assert!(rest.contains("feed hold"), "{rest}");
    assert!(rest.contains("aborted after"), "{rest}");
}

/// `lase run … | head -1` once panicked on the closed pipe when printing how the job ended;
/// a reader that stops early ends lase quietly, as for `lase emit`.
#[test]
fn run_into_a_closed_pipe_does_not_panic() {
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_lase"))
        .args(["run", "examples/frame_marking.lase", "--time-scale", "max"])
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(out.status.code(), Some(101), "{err}");
}

/// `lase sim --listen` on an address that is not this machine's said only `lase::io`; it names
/// the address and the reason, and exits 1.
#[test]
fn a_listen_address_that_is_not_ours_is_named_with_the_reason() {
    let (code, _, err) = lase(&["sim", "--listen", "192.0.2.1:7993", "--allow-remote"]);
    assert_eq!(code, 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("cannot listen on 192.0.2.1:7993"), "{err}");
    assert!(err.contains("os error"), "{err}");
}
