//! The REPL driven through a pseudo-terminal, as an operator types: completion, multi-line
//! input, an error followed by a correct line, `:run` against the built-in simulator, and
//! Ctrl-C during a run, checked against what a simulator on a real socket recorded.
//!
//! Every wait is an expectation with a generous timeout (or a poll of the simulator's
//! recording with a deadline), never a sleep, so the tests hold on a loaded machine.

mod common;

use common::root;
use lase_runtime::link::sim::{self, SimOptions, TimeScale};
use rexpect::reader::{Options, ReadUntil};
use rexpect::session::{PtySession, spawn_with_options};
use std::process::Command;
use std::time::{Duration, Instant};

const TIMEOUT_MS: u64 = 120_000;

/// Starts `lase repl ARGS` on a pseudo-terminal and waits for its first prompt.
fn repl(args: &[&str], color: bool) -> (PtySession, tempfile::TempDir) {
    let home = tempfile::tempdir().unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lase"));
    cmd.arg("repl")
        .args(args)
        .current_dir(root())
        .env("TERM", "xterm")
        .env("HOME", home.path())
        .env("LASE_HISTORY", home.path().join("history"));
    if color {
        cmd.env_remove("NO_COLOR");
    } else {
        cmd.env("NO_COLOR", "1");
    }
    let mut p = spawn_with_options(
        cmd,
        Options::new()
            .timeout_ms(Some(TIMEOUT_MS))
            .strip_ansi_escape_codes(!color),
    )
    .unwrap();
    prompt(&mut p);
    (p, home)
}

/// Waits for a fresh prompt: one drawn after a line break, not a redraw of the input being
/// edited. (Type-ahead is dropped when the editor takes the terminal back, so every input
/// waits for its prompt.)
fn prompt(p: &mut PtySession) {
    // Escape sequences (colours, cursor moves) may stand between.
    p.exp_regex(r"\n(\r|\x1b\[[0-9;?]*[a-zA-Z])*lase> ")
        .unwrap();
}

/// Types a line and presses Enter.
fn enter(p: &mut PtySession, line: &str) {
    p.send(line).unwrap();
    p.send("\r").unwrap();
    p.flush().unwrap();
}

fn quit(mut p: PtySession) {
    // A Ctrl-D typed in the moment before the editor reads is lost like any type-ahead (seen
    // once on a loaded machine: the REPL drew its prompt again and waited); then it is
    // pressed again. The session must end on Ctrl-D, at the latest on the third.
    for _ in 0..3 {
        p.send_control('d').unwrap();
        let (_, got) = p
            .exp_any(vec![ReadUntil::EOF, ReadUntil::String("lase> ".into())])
            .unwrap();
        if !got.ends_with("lase> ") {
            return;
        }
    }
    panic!("the REPL did not exit on Ctrl-D");
}

#[test]
fn tab_completes_names_units_functions_and_commands() {
    let (mut p, home) = repl(&[], false);
    enter(&mut p, "let radius = 5 mm");
    prompt(&mut p);
    // A name bound in the session.
    p.send("rad\t").unwrap();
    p.flush().unwrap();
    p.exp_string("radius").unwrap();
    enter(&mut p, " * 3");
    p.exp_string("15 mm").unwrap();
    prompt(&mut p);
    // A unit after a number.
    p.send("3000 mm/mi\t").unwrap();
    p.flush().unwrap();
    p.exp_string("mm/min").unwrap();
    enter(&mut p, "");
    p.exp_string("50 mm/s").unwrap();
    prompt(&mut p);
    // A stdlib function, with its parameters as a hint.
    p.send("sqr\t").unwrap();
    p.flush().unwrap();
    p.exp_string("sqrt(").unwrap();
    enter(&mut p, "81)");
    p.exp_string("9").unwrap();
    prompt(&mut p);
    // A command.
    p.send(":hel\t").unwrap();
    p.flush().unwrap();
    enter(&mut p, "offset");
    p.exp_string("offset(profile, distance").unwrap();
    p.exp_string("The equidistant curve").unwrap();
    quit(p);
    // The history file keeps what was typed.
    let history = std::fs::read_to_string(home.path().join("history")).unwrap();
    assert!(history.contains("let radius = 5 mm"), "{history}");
}

#[test]
fn open_braces_continue_the_input_on_the_next_line() {
    let (mut p, _home) = repl(&[], false);
    enter(&mut p, "machine xy_table");
    prompt(&mut p);
    enter(&mut p, "laser { power 20 W }");
    prompt(&mut p);
    // Three lines, one input: evaluated only once the brace closes.
    enter(&mut p, "fn ring(r: length) {");
    enter(
        &mut p,
        "    follow profile circle(center: (0, 0), radius: r) at 10 mm/s",
    );
    enter(&mut p, "}");
    prompt(&mut p);
    enter(&mut p, "let pts = [");
    enter(&mut p, "  (0, 0),");
    enter(&mut p, "  (1 mm, 0)]");
    prompt(&mut p);
    enter(&mut p, "len(pts)");
    p.exp_string("2").unwrap();
    prompt(&mut p);
    enter(&mut p, "ring(5 mm)");
    prompt(&mut p);
    enter(&mut p, ":plan");
    p.exp_regex(r"\d+ ops( \+ \d+ lead-ins/outs)?, cycle time [0-9.]+ s")
        .unwrap();
    prompt(&mut p);
    quit(p);
}

#[test]
fn an_error_is_shown_as_a_diagnostic_and_the_session_goes_on() {
    let (mut p, _home) = repl(&[], false);
    enter(&mut p, "let a = 10 mm + 5 mm/s");
    p.exp_string("lase::check::unit_mismatch").unwrap();
    p.exp_string("this is a speed").unwrap();
    prompt(&mut p);
    enter(&mut p, "let a = 10 mm");
    prompt(&mut p);
    enter(&mut p, "a * 2");
    p.exp_string("20 mm").unwrap();
    prompt(&mut p);
    // Commands fail the same way and the session still goes on.
    enter(&mut p, ":jog x 5 parsecs");
    p.exp_string("unknown unit").unwrap();
    prompt(&mut p);
    enter(&mut p, "a + 1 mm");
    p.exp_string("11 mm").unwrap();
    quit(p);
}

#[test]
fn run_streams_to_the_built_in_simulator() {
    let (mut p, _home) = repl(&[], false);
    enter(&mut p, "machine xy_table");
    prompt(&mut p);
    enter(&mut p, "laser { power 20 W }");
    prompt(&mut p);
    enter(
        &mut p,
        "follow profile circle(center: (0, 0), radius: 5 mm) at 10 mm/s",
    );
    prompt(&mut p);
    enter(&mut p, ":run");
    p.exp_regex(r"repl: \d+ lines to sim").unwrap();
    // (The pty reader sees bytes, so the dash between is matched as any non-space.)
    p.exp_regex(r"repl: done \S+ \d+ lines, controller Idle \| X5\.\d+ Y0\.\d+")
        .unwrap();
    prompt(&mut p);
    // The session's motion ran; jog from where it ended.
    enter(&mut p, ":jog x -2 mm");
    p.exp_regex(r"Idle \| X3\.\d+").unwrap();
    prompt(&mut p);
    enter(&mut p, ":status");
    p.exp_string("laser off").unwrap();
    quit(p);
}

#[test]
fn ctrl_c_during_a_run_holds_with_the_laser_off_then_asks() {
    let machine = {
        let text = lase_stdlib::machine("xy_table").unwrap();
        lase_runtime::machine::parse_machine(text, 0).unwrap()
    };
    let sim = sim::serve(
        &machine,
        "127.0.0.1:0".parse().unwrap(),
        SimOptions {
            time_scale: TimeScale::Real,
            ..SimOptions::default()
        },
    )
    .unwrap();
    let url = format!("tcp://{}", sim.addr().unwrap());
    let (mut p, _home) = repl(&["--link", &url], false);
    enter(&mut p, "machine xy_table");
    prompt(&mut p);
    enter(&mut p, "laser { power 20 W }");
    prompt(&mut p);
    // A ring that takes about 13 s in real time.
    enter(
        &mut p,
        "follow profile circle(center: (0, 0), radius: 10 mm) at 5 mm/s",
    );
    prompt(&mut p);
    enter(&mut p, ":run");
    p.exp_string("Ctrl-C = feed hold").unwrap();
    // Wait until the simulator has the beam on.
    let deadline = Instant::now() + Duration::from_secs(120);
    while !sim.recording().laser.iter().any(|e| e.power_s > 0.0) {
        assert!(Instant::now() < deadline, "the laser never came on");
        std::thread::sleep(Duration::from_millis(20));
    }
    p.send_control('c').unwrap();
    p.exp_string("held:").unwrap();
    p.exp_string("r = resume, a = abort").unwrap();
    let rec = sim.recording();
    assert_eq!(rec.holds, 1, "one feed hold: {rec:?}");
    let last = rec.laser.last().unwrap();
    assert_eq!(
        last.power_s, 0.0,
        "the laser is off while held: {:?}",
        rec.laser
    );
    assert!(rec.resets == 0 && rec.alarms.is_empty(), "{rec:?}");
    // Resume, then Ctrl-C again and abort.
    p.send("r").unwrap();
    p.flush().unwrap();
    p.exp_string("resumed").unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while sim
        .recording()
        .laser
        .last()
        .is_none_or(|e| e.power_s == 0.0)
    {
        assert!(Instant::now() < deadline, "the laser never came back on");
        std::thread::sleep(Duration::from_millis(20));
    }
    p.send_control('c').unwrap();
    p.exp_string("held:").unwrap();
    assert_eq!(sim.recording().holds, 2);
    p.send("a").unwrap();
    p.flush().unwrap();
    p.exp_string("aborted after").unwrap();
    prompt(&mut p);
    let rec = sim.recording();
    assert_eq!(rec.resets, 1, "stopped with a soft reset: {rec:?}");
    assert!(
        rec.alarms.is_empty(),
        "stopped at rest, no alarm: {:?}",
        rec.alarms
    );
    assert_eq!(rec.laser.last().map(|e| e.power_s), Some(0.0));
    // The operator is back at the prompt with an idle controller.
    enter(&mut p, ":status");
    p.exp_string("Idle").unwrap();
    quit(p);
}

#[test]
fn a_terminal_gets_colours() {
    let (mut p, _home) = repl(&[], true);
    p.send("let x = 2 mm").unwrap();
    p.flush().unwrap();
    // The keyword and the unit are coloured as they are typed.
    p.exp_string("\x1b[1;35mlet").unwrap();
    p.exp_string("\x1b[36mmm").unwrap();
    p.send("\r").unwrap();
    p.flush().unwrap();
    prompt(&mut p);
    enter(&mut p, "x + 1 mm");
    p.exp_string("3 mm").unwrap();
    quit(p);
}

/// `lase run` on a terminal: the key hint names Ctrl-C; Ctrl-C holds the job with the laser
/// off (the simulator records one feed hold and no reset), `r` resumes, and a second Ctrl-C
/// while held aborts it at rest with a soft reset, as in the REPL.
#[test]
fn ctrl_c_in_lase_run_holds_and_a_second_one_aborts() {
    let machine = {
        let text = lase_stdlib::machine("xy_table").unwrap();
        lase_runtime::machine::parse_machine(text, 0).unwrap()
    };
    let sim = sim::serve(
        &machine,
        "127.0.0.1:0".parse().unwrap(),
        SimOptions {
            time_scale: TimeScale::Real,
            ..SimOptions::default()
        },
    )
    .unwrap();
    let home = tempfile::tempdir().unwrap();
    let url = format!("tcp://{}", sim.addr().unwrap());
    let journal = home.path().join("run.journal");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lase"));
    cmd.args(["run", "examples/frame_marking.lase", "--link", &url])
        .arg("--journal")
        .arg(&journal)
        .current_dir(root())
        .env("TERM", "xterm")
        .env("HOME", home.path())
        .env("NO_COLOR", "1");
    let mut p = spawn_with_options(
        cmd,
        Options::new()
            .timeout_ms(Some(TIMEOUT_MS))
            .strip_ansi_escape_codes(true),
    )
    .unwrap();
    p.exp_string("a second Ctrl-C = abort").unwrap();
    // The bar runs on planned time: its ETA counts down from the plan's cycle time (22.094 s
    // since the lit rounded corners are blended, issue 13 item 3).
    p.exp_regex(r"% ETA [0-9.]+ s of 22\.1 s planned").unwrap();
    // The controller says `Run` while the job moves, on the machine's own axes.
    p.exp_regex(r"lines \| Run \| X-?[0-9.]+ Y-?[0-9.]+")
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !sim.recording().laser.iter().any(|e| e.power_s > 0.0) {
        assert!(Instant::now() < deadline, "the laser never came on");
        std::thread::sleep(Duration::from_millis(20));
    }
    p.send_control('c').unwrap();
    p.exp_string("^C feed hold").unwrap();
    let deadline = Instant::now() + Duration::from_secs(120);
    while sim.recording().holds < 1 {
        assert!(
            Instant::now() < deadline,
            "no feed hold reached the controller"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let rec = sim.recording();
    assert!(
        rec.resets == 0 && rec.alarms.is_empty(),
        "held, not stopped: {rec:?}"
    );
    assert_eq!(rec.laser.last().map(|e| e.power_s), Some(0.0), "{rec:?}");
    // The second Ctrl-C aborts: feed hold (already), soft reset, the job over.
    std::thread::sleep(Duration::from_millis(300));
    p.send_control('c').unwrap();
    p.exp_string("aborted after").unwrap();
    p.exp_eof().unwrap();
    let rec = sim.recording();
    assert_eq!(rec.resets, 1, "stopped with a soft reset: {rec:?}");
    assert!(rec.alarms.is_empty(), "stopped at rest: {:?}", rec.alarms);
}
