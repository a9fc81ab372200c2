//! The REPL driven through piped input: a scripted session (with an error in the middle that
//! the session survives, overrides, a process run by name, jogging and status on the built-in
//! simulator) whose whole output is a golden file. The pseudo-terminal tests are in
//! `repl_pty.rs`.

mod common;

use common::*;
use std::io::Write;
use std::process::{Command, Stdio};

fn session(input: &str) -> (i32, String, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lase"))
        .arg("repl")
        .current_dir(root())
        .env("NO_COLOR", "1")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child
        .stdin
        .take()
        .unwrap()
        .write_all(input.as_bytes())
        .unwrap();
    let out = child.wait_with_output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn scripted_session_matches_its_golden() {
    let input = std::fs::read_to_string(root().join("tests/repl/session.txt")).unwrap();
    let (code, out, err) = session(&input);
    assert_eq!(code, 0, "{err}");
    // The error in the middle is reported and the session goes on.
    assert!(err.contains("lase::check::unit_mismatch"), "{err}");
    assert!(out.contains("10 mm"), "{out}");
    assert!(
        out.contains("profile (2 segments, closed, 31.415927 mm)"),
        "{out}"
    );
    // Two rings were planned: 2π·5 + 2π·10 mm lit (arcs run as chords within the 2 µm chord
    // tolerance, so a little shorter).
    let lit = std::f64::consts::TAU * 15.0;
    let reported: f64 = out
        .split("laser on ")
        .nth(1)
        .and_then(|r| r.split(" mm").next())
        .and_then(|n| n.parse().ok())
        .expect("the :plan line reports the lit length");
    assert!((reported - lit).abs() < 1e-3 * lit, "{reported} vs {lit}");
    // After :run the session's motion was sent and cleared.
    assert!(out.contains("0 ops"), "{out}");
    assert!(out.contains("repl: done"), "{out}");
    // The power override changes what is emitted and run: 20 W is S200, 30 W is S300 on
    // the xy_table (S 1000 = 100 W).
    let after = out.split("power 30 W for the next runs").nth(1).unwrap();
    assert!(
        after.contains(" S300") && !after.contains("S200"),
        "{after}"
    );
    assert!(out.contains("pass: done"), "{out}");
    // An override the laser cannot give is refused.
    assert!(err.contains("above the 100 W"), "{err}");
    assert!(err.contains("unknown command `:frobnicate`"), "{err}");
    golden(
        &root().join("tests/repl/session.out"),
        &format!("--- stdout\n{out}--- stderr\n{err}"),
    );
}

/// At a rotary machine: `:jog` turns C by an angle and B at an angular speed (sent in
/// degrees), refuses a length for a rotary axis, and `:run` streams the cam recipe to the
/// simulated grblHAL.
#[test]
fn rotary_axes_jog_by_angles_and_the_cam_job_runs() {
    let input = "\
machine cam_xwb
:jog c 90 deg
:jog b -0.5 rad at 30 deg/s
:jog c 5 mm
:status
:run examples/cam_hardening.lase
";
    let (code, out, err) = session(input);
    assert_eq!(code, 0, "{err}");
    let all = format!("{out}{err}");
    assert!(
        all.contains("axis c is rotary: the distance is an angle"),
        "{all}"
    );
    // -0.5 rad = -28.648 deg, and C at 90 deg (status rounds to the controller's 3 decimals).
    assert!(all.contains("B-28.648") && all.contains("C90"), "{all}");
    // grblHAL sends no banner; the link names it from `$I`.
    assert!(all.contains("(grblHAL)"), "{all}");
    assert!(all.contains("cam_hardening.lase: done"), "{all}");
}

/// After a jog the machine is not where the session left it: the pending moves are planned
/// from where it is (a first cut would otherwise be planned from the old position).
#[test]
fn moves_after_a_jog_start_from_where_the_machine_is() {
    let input = "\
machine xy_table
:jog x 3 mm
move to (10 mm, 0 mm) at 5 mm/s
:run
:status
";
    let (code, out, err) = session(input);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("the machine is at (3, 0, 0), not at (0, 0, 0)"),
        "{out}"
    );
    assert!(out.contains("Idle | X10 Y0"), "{out}");
}

/// `:frame` traces the box of the pending work dark and returns to where the session stands;
/// the work itself stays pending for `:run`.
#[test]
fn frame_traces_the_pending_work_and_returns_to_the_start() {
    let input = "\
machine xy_table
laser { power 10 W }
follow profile rect((10 mm, 5 mm), 20 mm, 10 mm) at 20 mm/s
:frame
:status
:run
";
    let (code, out, err) = session(input);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("frame: done"), "{out}");
    // Back at the start after the frame; the cut then runs and ends at its corner.
    assert!(out.contains("Idle | X0 Y0"), "{out}");
    assert!(out.contains("repl: done"), "{out}");
}

/// A job the REPL streams keeps a journal: when the link drops mid-job, a new job is refused
/// until the operator decides, and `:resume` reconnects, finds where the controller stopped
/// and cuts the rest — every lit millimetre exactly once.
#[test]
fn a_job_interrupted_by_a_lost_link_continues_with_resume() {
    use lase_runtime::link::sim::{self, Faults, SimOptions, TimeScale};
    let m =
        lase_runtime::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    let h = sim::serve(
        &m,
        "127.0.0.1:0".parse().unwrap(),
        SimOptions {
            time_scale: TimeScale::Factor(20.0),
            // `$G`, `$I`, `$$` and then the job's first lines.
            faults: Faults {
                drop_after_lines: vec![14],
                ..Faults::default()
            },
            ..SimOptions::default()
        },
    )
    .unwrap();
    let input = format!(
        "\
:connect tcp://{}
machine xy_table
laser {{ power 20 W }}
follow profile rect((10 mm, 10 mm), 10 mm, 10 mm) at 10 mm/s
follow profile circle(center: (40 mm, 20 mm), radius: 5 mm) at 10 mm/s
:run
move to (0 mm, 0 mm) at 20 mm/s
:run
:resume
:run
:status
",
        h.addr().unwrap()
    );
    let (code, out, err) = session(&input);
    assert_eq!(code, 0, "{err}");
    let all = format!("{out}{err}");
    assert!(all.contains("the link to the controller was lost"), "{all}");
    // Said once per loss, not "lost after …: the link to the controller was lost: …".
    assert!(
        !all.contains("was lost after")
            || all.matches("link to the controller was lost").count()
                == all.matches("was lost after").count(),
        "{all}"
    );
    assert!(
        all.contains("`repl` was interrupted by a lost link: `:resume` continues it"),
        "{all}"
    );
    assert!(all.contains("lines had run; re-approach"), "{all}");
    // 21 lines: the laser armed once (M3 S0) and switched by S words, not M3/M5 per ring.
    assert!(all.contains("repl: done — 21 lines"), "{all}");
    // The refused job ran after the resumed one.
    assert!(all.contains("Idle | X0 Y0"), "{all}");
    assert!(h.wait_quiet(std::time::Duration::from_secs(10)));
    let rec = h.stop();
    assert_eq!(rec.rx_overflows, 0);
    // The square's 40 mm and the circle's 31.416 mm, lit once (the resume re-approaches dark).
    let lit: f64 = rec
        .blocks
        .iter()
        .filter(|b| b.laser_s > 0.0)
        .map(|b| {
            (0..3)
                .map(|i| (b.to[i] - b.from[i]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .sum();
    let want = 40.0 + std::f64::consts::TAU * 5.0;
    assert!((lit - want).abs() < 0.01, "lit {lit} mm, planned {want} mm");
}

/// `use` works line by line: an extension module's functions and a preset's values come into
/// the session, a cam profile generated in Rhai is hardened on the cam machine, and a `use`
/// of a missing file is a diagnostic the session survives.
#[test]
fn use_loads_extensions_and_presets_into_the_session() {
    let input = "\
machine cam_xwb
use stdlib::cams
law_lift(\"cycloidal\", 0.5)
use stdlib::presets::cam_hardening
standoff
use \"no_such_extension.rhai\"
laser { power 1 kW, spot spot, standoff standoff }
follow disc_cam(30 mm, 10 mm, 120 deg, 40 deg, 120 deg, \"cycloidal\") at 0.95 * speed { step 0.5 mm }
:run
";
    let (code, out, err) = session(input);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("0.5\n"), "{out}");
    assert!(out.contains("12 mm"), "{out}");
    assert!(err.contains("lase::ext::load"), "{err}");
    assert!(err.contains("no_such_extension.rhai"), "{err}");
    assert!(out.contains("repl: done"), "{out}");
    // One turn of the cam, back at C = −360° after the lead-out. At 95 % of the preset's
    // 8 mm/s: LinuxCNC holds 7.81 mm/s on this cam's shortest blocks (`motion::parabolic`),
    // and the lead-out at 7.6 mm/s ends at −360.444° (−360.468° at 8 mm/s).
    assert!(out.contains("C-360.444"), "{out}");
}

/// A speed override multiplies the pulse rate of pulses by distance: `:set speed 200%` on a
/// cut at 60 % of the laser's maximum rate asks 120 % of it. The job is refused with the
/// diagnostic a recipe written at that speed gets, at the recipe line, before anything runs;
/// without the override it plans. (The REPL used to recheck power only.)
#[test]
fn a_speed_override_that_exceeds_the_pulse_rate_is_refused() {
    let input = "\
machine xy_table
laser { power 20 W }
pulse interval 1 um
follow profile line((0, 0), (10 mm, 0)) at 60 mm/s
:plan
:set speed 200%
:plan
:run
:set speed 150%
:plan
:set speed off
:plan
";
    let (code, out, err) = session(input);
    assert_eq!(code, 0, "{err}");
    // 60 mm/s every 1 µm is 60 kHz; doubled, 120 kHz on a 100 kHz laser.
    assert_eq!(err.matches("lase::eval::pulse_rate").count(), 2, "{err}");
    assert!(
        err.contains("pulse rate 120000 Hz is above the laser's maximum 100000 Hz"),
        "{err}"
    );
    assert!(
        err.contains("the fastest allowed speed is 100 mm/s"),
        "{err}"
    );
    assert!(
        err.contains("follow profile line((0, 0), (10 mm, 0)) at 60 mm/s"),
        "{err}"
    );
    assert!(
        err.contains("with the overrides (speed 200%) the job asks more than the laser can give"),
        "{err}"
    );
    // Nothing ran; 150 % (90 kHz) and no override plan.
    assert!(!out.contains("repl: done"), "{out}");
    assert_eq!(out.matches(", cycle time ").count(), 3, "{out}");
}

/// A 1 MB input line of chained operators once overflowed the REPL's stack (exit 134); now it
/// is one diagnostic, shown in part with its line:col, and the session goes on.
#[test]
fn a_megabyte_line_of_operators_is_a_diagnostic_and_the_session_goes_on() {
    let line = format!("let a = 1 mm{}\n", " + 1 mm".repeat(150_000));
    assert!(line.len() > 1_000_000);
    let (code, out, err) = session(&format!("{line}let b = 2 mm\nb * 3\n"));
    assert!(!err.contains("panicked"), "{err}");
    assert!(code == 0 || code == 1, "exit {code}");
    assert!(err.contains("lase::parse::too_deep"), "{err}");
    // `let a = ` and the first operand, then 499 ` + 1 mm`: the 500th `+`.
    assert!(err.contains("<repl:1>:1:3507]"), "{err}");
    assert!(err.lines().all(|l| l.chars().count() < 200));
    assert!(out.contains("6 mm"), "{out}");
}

/// `:load` and `:plan` count the same ops: the ones the recipe wrote (28 for frame_marking),
/// and `:plan` names the lead-ins/outs the planner adds, which together make the summary's
/// `ops` (34).
#[test]
fn load_and_plan_count_the_same_ops() {
    let (code, out, err) = session(":load examples/frame_marking.lase\n:plan\n");
    assert_eq!(code, 0, "{err}");
    let loaded: usize = out
        .lines()
        .find_map(|l| l.strip_prefix("loaded examples/frame_marking.lase: "))
        .and_then(|l| l.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    let plan = out.lines().find(|l| l.contains("cycle time")).unwrap();
    let w: Vec<&str> = plan.split_whitespace().collect();
    // `28 ops + 6 lead-ins/outs, cycle time …`
    assert_eq!(w[0].parse::<usize>().unwrap(), loaded, "{out}");
    assert_eq!(w[1], "ops", "{plan}");
    let leads: usize = w[3].parse().unwrap();
    assert_eq!(w[4], "lead-ins/outs,", "{plan}");
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let (code, _, err) = lase(&[
        "plan",
        "examples/frame_marking.lase",
        "-o",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(s["ops"].as_u64().unwrap() as usize, loaded + leads);
    assert!(leads > 0 && loaded == 28, "{plan}");
}

/// `:help scan` and `:help machine` show what `lase doc` shows: both scan kinds with their
/// settings, and every stock machine.
#[test]
fn help_documents_scan_and_the_stock_machines() {
    let (code, out, err) = session(":help scan\n:help machine\n");
    assert_eq!(code, 0, "{err}");
    for needle in [
        "scan dots REGION",
        "scan raster REGION",
        "  overscan ",
        "  cross ",
    ] {
        assert!(out.contains(needle), "{needle}:\n{out}");
    }
    for m in lase_stdlib::machine_names() {
        assert!(out.contains(m), "{m}:\n{out}");
    }
}
