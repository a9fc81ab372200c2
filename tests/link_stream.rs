//! Streaming jobs to the simulated GRBL controller over real TCP sockets on 127.0.0.1: every
//! example, exactly once, executing its plan; hold and resume; an injected error; settings
//! that do not fit the plan; a controller that is not idle; check mode; garbage from the
//! controller; the `lase sim` server.

mod link_support;

use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::sim::{Faults, SimOptions, TimeScale};
use lase_runtime::link::stream::{self, Control, Outcome, Progress, StreamOptions};
use lase_runtime::link::transport::TcpTransport;
use lase_runtime::link::{ConnectOptions, Event, Link, MachineState, Realtime, Reply};
use link_support::*;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn max_sim() -> SimOptions {
    SimOptions {
        time_scale: TimeScale::Max,
        ..SimOptions::default()
    }
}

#[test]
fn every_example_streams_exactly_once_and_executes_its_plan() {
    let dir = tempfile::tempdir().unwrap();
    for ex in examples() {
        let c = compile(&ex);
        let sim = sim_for(&c.job, max_sim());
        let journal = dir.path().join("job.journal");
        let _ = std::fs::remove_file(&journal);
        let (code, out, err) = lase(&[
            "run",
            ex.to_str().unwrap(),
            "--link",
            &url(&sim),
            "--journal",
            journal.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{}: {err}", ex.display());
        assert!(sim.wait_quiet(Duration::from_secs(5)));
        let rec = sim.stop();
        // The lines `lase emit` writes in the machine's live dialect (grbl, or grblhal for
        // rotary axes), each received exactly once, in order.
        let dialect = lase_runtime::link::live_dialect(&c.job.program.machine).to_string();
        let (_, emitted, _) = lase(&["emit", ex.to_str().unwrap(), "--dialect", &dialect]);
        let emitted: Vec<String> = emitted.lines().map(str::to_string).collect();
        let texts: Vec<String> = c.lines.iter().map(|l| l.text.clone()).collect();
        assert_eq!(texts, emitted, "library and binary emit the same lines");
        assert_eq!(gcode_lines(&rec), emitted, "{}", ex.display());
        assert!(
            rec.lines
                .iter()
                .all(|l| l.result != lase_runtime::link::sim::LineResult::Error(0))
        );
        assert_eq!(rec.rx_overflows, 0, "{:?}", rec.overflow_log);
        // Never more than the controller's RX buffer less one: GRBL's 128 bytes, grblHAL's
        // 1024 (what `$I` reports and the link counts against).
        let rx = lase_runtime::link::sim::Firmware::for_machine(&c.job.program.machine).rx_buffer();
        assert!(rec.max_rx_fill < rx, "{} of {rx} bytes", rec.max_rx_fill);
        assert!(
            out.contains(&format!("{} lines acknowledged", emitted.len())),
            "{out}"
        );
        let seqs = job_line_seqs(&c, &rec, &[]);
        assert_trajectory_matches(&c, &rec, &seqs);
        // The laser ends off and the journal says the job is done.
        assert_eq!(rec.laser.last().map_or(0.0, |e| e.power_s), 0.0);
        let j = lase_runtime::link::journal::read(&journal).unwrap();
        assert_eq!(j.end.as_deref(), Some("done"));
        assert_eq!(j.acked, emitted.len());
    }
}

fn connect(h: &lase_runtime::link::sim::SimHandle) -> GrblLink {
    let a = h.addr().unwrap();
    let t = TcpTransport::connect(&a.ip().to_string(), a.port()).unwrap();
    GrblLink::connect(Box::new(t), url(h), &ConnectOptions::default()).unwrap()
}

#[test]
fn hold_and_resume_mid_job() {
    let c = compile(&root().join("examples/frame_marking.lase"));
    // 20 s of plan at ×40: half a second of streaming, time to hold in the middle.
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Factor(40.0),
            ..SimOptions::default()
        },
    );
    let mut link = connect(&sim);
    let lines: Vec<String> = c.lines.iter().map(|l| l.text.clone()).collect();
    let mut held_at: Option<(Instant, Vec<f64>)> = None;
    let mut held_positions = Vec::new();
    let mut resumed = false;
    let report = stream::stream(
        &mut link,
        &stream::StreamJob::new(&lines),
        None,
        &StreamOptions {
            status_interval: Duration::from_millis(20),
            ..StreamOptions::default()
        },
        &mut |p: &Progress, e: Option<&Event>| {
            if held_at.is_none() && !resumed && p.acked >= lines.len() / 3 {
                held_at = Some((Instant::now(), Vec::new()));
                return Some(Control::Hold);
            }
            if let (Some((since, _)), Some(Event::Status(s))) = (&held_at, e)
                && !resumed
                && s.state == (MachineState::Hold { complete: true })
            {
                held_positions.push(s.mpos.clone().unwrap());
                if since.elapsed() > Duration::from_millis(150) {
                    resumed = true;
                    return Some(Control::Resume);
                }
            }
            None
        },
    );
    assert_eq!(report.outcome, Outcome::Done);
    assert!(resumed, "the hold completed and the job resumed");
    assert!(held_positions.len() >= 2, "{held_positions:?}");
    assert!(
        held_positions.windows(2).all(|w| w[0] == w[1]),
        "the machine stands still while held: {held_positions:?}"
    );
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    assert!(rec.holds >= 1);
    // The laser was off while held.
    let held_pos = &held_positions[0];
    assert!(
        rec.laser
            .iter()
            .any(|e| e.power_s == 0.0 && (0..3).all(|i| (e.pos[i] - held_pos[i]).abs() < 1e-3)),
        "{:?}",
        rec.laser
    );
    assert_eq!(gcode_lines(&rec), lines);
    assert_trajectory_matches(&c, &rec, &job_line_seqs(&c, &rec, &[]));
}

#[test]
fn an_injected_error_stops_the_job_and_names_the_recipe_line() {
    let ex = root().join("examples/frame_marking.lase");
    let c = compile(&ex);
    // A lit move of the second pass: the second `G1 X40`.
    let index = c
        .lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.text == "G1 X40")
        .map(|(i, _)| i)
        .nth(1)
        .unwrap();
    // The controller counts every line it receives: `$G` (the connection's barrier), `$I`
    // (its buffer size) and `$$` (the settings check) come first.
    let k = index as u64 + 4;
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Factor(20.0),
            faults: Faults {
                error_at_line: vec![(k, 33)],
                ..Faults::default()
            },
            ..SimOptions::default()
        },
    );
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("j");
    let (code, _out, err) = lase(&[
        "run",
        ex.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::link::rejected"), "{err}");
    assert!(
        err.contains(&format!("rejected line {} `G1 X40`", index + 1)),
        "{err}"
    );
    assert!(err.contains("error 33"), "{err}");
    assert!(err.contains("the motion command"), "{err}");
    // The label sits on the recipe statement that produced the line (frame_marking.lase:11).
    assert!(err.contains("frame_marking.lase:11"), "{err}");
    assert!(
        err.contains("follow translate(path, (0, i * pitch))"),
        "{err}"
    );
    assert!(
        err.contains("this statement produced the rejected line"),
        "{err}"
    );
    assert!(err.contains("soft reset"), "{err}");
    assert!(sim.wait_quiet(Duration::from_secs(5)));
    let rec = sim.stop();
    // Stopped: a hold, then a reset that emptied the buffers; the laser is off and the
    // controller executed no job line past the ones it had when the error came back.
    assert!(rec.holds >= 1 && rec.resets >= 1, "{rec:?}");
    assert_eq!(rec.laser.last().map_or(0.0, |e| e.power_s), 0.0);
    let received = gcode_lines(&rec).len();
    assert!(received < c.lines.len(), "the job did not run to its end");
    let j = lase_runtime::link::journal::read(&journal).unwrap();
    assert_eq!(j.end, Some(format!("error {index} 33")));
}

#[test]
fn settings_that_do_not_fit_the_plan_stop_the_job_before_it_starts() {
    let ex = root().join("examples/frame_marking.lase");
    let c = compile(&ex);
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Max,
            settings: vec![(32, 0.0), (110, 600.0), (121, 500.0)],
            ..SimOptions::default()
        },
    );
    let (code, _out, err) = lase(&["run", ex.to_str().unwrap(), "--link", &url(&sim)]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::link::setting"), "{err}");
    assert!(
        err.contains("$32 (laser mode) is 0, the job needs 1"),
        "{err}"
    );
    assert!(err.contains("$110 (X max rate, mm/min) is 600,"), "{err}");
    assert!(err.contains("$121 (Y acceleration, mm/s²) is 500"), "{err}");
    assert!(err.contains("3 errors"), "{err}");
    let rec = sim.stop();
    assert!(gcode_lines(&rec).is_empty(), "nothing was sent");
}

/// A controller in alarm (here woken from `$SLP` by a reset, as GRBL wakes) has lost its
/// position: `lase run` refuses to start, sends no program line and writes no journal, as
/// the REPL's `:run` does.
#[test]
fn a_controller_that_is_not_idle_is_refused_before_the_job_starts() {
    let ex = root().join("examples/frame_marking.lase");
    let c = compile(&ex);
    let sim = sim_for(&c.job, max_sim());
    {
        let mut link = connect(&sim);
        assert_eq!(link.send("$SLP").unwrap(), Reply::Ok);
        link.realtime(Realtime::SoftReset).unwrap();
        let deadline = Instant::now() + Duration::from_secs(5);
        while link.query_status(Duration::from_secs(2)).unwrap().state != MachineState::Alarm {
            assert!(
                Instant::now() < deadline,
                "the simulator did not enter alarm"
            );
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("j");
    let (code, _out, err) = lase(&[
        "run",
        ex.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    // The diagnostic as words, whatever the width it was wrapped at.
    let words: Vec<&str> = err.split_whitespace().filter(|w| *w != "│").collect();
    let said = words.join(" ");
    assert!(said.contains("lase::link::not_ready"), "{err}");
    assert!(
        said.contains("it reports `Alarm | X0 Y0`, not Idle: no program line was sent"),
        "{err}"
    );
    assert!(said.contains("clear the alarm"), "{err}");
    assert!(!journal.exists());
    let rec = sim.stop();
    assert!(gcode_lines(&rec).is_empty(), "{:?}", gcode_lines(&rec));
}

#[test]
fn check_mode_parses_every_line_and_moves_nothing() {
    let ex = root().join("examples/dial_marks.lase");
    let c = compile(&ex);
    let sim = sim_for(&c.job, max_sim());
    let (code, out, err) = lase(&["run", ex.to_str().unwrap(), "--link", &url(&sim), "--check"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains(&format!("accepted all {} lines", c.lines.len())),
        "{out}"
    );
    let rec = sim.stop();
    assert_eq!(gcode_lines(&rec).len(), c.lines.len());
    assert!(rec.blocks.is_empty(), "check mode executes nothing");
}

#[test]
fn garbage_from_the_controller_is_a_clear_error() {
    let ex = root().join("examples/dial_marks.lase");
    let c = compile(&ex);
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Factor(10.0),
            faults: Faults {
                garbage_after_lines: vec![20],
                ..Faults::default()
            },
            ..SimOptions::default()
        },
    );
    let (code, _out, err) = lase(&["run", ex.to_str().unwrap(), "--link", &url(&sim)]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::link::protocol"), "{err}");
    assert!(err.contains("does not understand"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let rec = sim.stop();
    assert!(rec.resets >= 1, "the job was stopped with a reset");
}

#[test]
fn a_silent_or_truncated_controller_fails_cleanly() {
    use std::io::{Read, Write};
    // A fake controller that answers the status query with a truncated report.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let mut buf = [0u8; 64];
        let _ = s.read(&mut buf);
        let _ = s.write_all(b"Grbl 1.1h ['$' for help]\r\n<Idle|MPos:0.000,0.0\r\n");
        std::thread::sleep(Duration::from_millis(300));
    });
    let (code, _out, err) = lase(&[
        "run",
        "examples/frame_marking.lase",
        "--link",
        &format!("tcp://{addr}"),
        "--journal",
        tempfile::tempdir()
            .unwrap()
            .path()
            .join("j")
            .to_str()
            .unwrap(),
    ]);
    server.join().unwrap();
    assert_eq!(code, 1);
    assert!(err.contains("lase::link::protocol"), "{err}");
    assert!(err.contains("truncated"), "{err}");
    // Nobody listening: a connection error with help.
    let (code, _out, err) = lase(&[
        "run",
        "examples/frame_marking.lase",
        "--link",
        &format!("tcp://{addr}"),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::link::connect"), "{err}");
}

/// A link lost while connecting (here right after `$$`) is a job that never started: no
/// journal to resume, and the message says nothing was sent.
#[test]
fn a_link_lost_before_the_job_starts_says_nothing_was_sent() {
    let c = compile(&root().join("examples/frame_marking.lase"));
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Max,
            faults: Faults {
                drop_after_lines: vec![3],
                ..Faults::default()
            },
            ..SimOptions::default()
        },
    );
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("j");
    let (code, _out, err) = lase(&[
        "run",
        "examples/frame_marking.lase",
        "--link",
        &url(&sim),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no program line was sent"), "{err}");
    assert!(!err.contains("--resume"), "{err}");
    assert!(!journal.exists());
    let rec = sim.stop();
    assert!(gcode_lines(&rec).is_empty(), "{:?}", gcode_lines(&rec));
}

#[test]
fn lase_sim_serves_over_tcp() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_lase"))
        .args([
            "sim",
            "--listen",
            "127.0.0.1:0",
            "--machine",
            "xy_table",
            "--time-scale",
            "max",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut first = String::new();
    // The reader lives until the run is over: dropping it would close the pipe, and the
    // simulator's next line (its `lase run` hint) would end it on the broken pipe.
    let mut reader = BufReader::new(child.stdout.take().unwrap());
    reader.read_line(&mut first).unwrap();
    let addr = first
        .split("listening on ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .unwrap_or_else(|| panic!("{first}"))
        .to_string();
    let (code, out, err) = lase(&[
        "run",
        "examples/dial_marks.lase",
        "--link",
        &format!("tcp://{addr}"),
        "--journal",
        tempfile::tempdir()
            .unwrap()
            .path()
            .join("j")
            .to_str()
            .unwrap(),
    ]);
    let _ = child.kill();
    let _ = child.wait();
    drop(reader);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("done"), "{out}");
    // Not on a public address unless asked.
    let (code, _, err) = lase(&["sim", "--listen", "0.0.0.0:0"]);
    assert_eq!(code, 1);
    assert!(err.contains("--allow-remote"), "{err}");
}

/// An abort on the notcher (axes X and Z) reports where the machine stopped on its own axes:
/// `controller now Idle | X… Z…`, never the `Y0` of an axis it does not have.
#[test]
fn an_abort_reports_the_machines_own_axes() {
    let c = compile(&root().join("examples/conrod_notch.lase"));
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Factor(20.0),
            ..SimOptions::default()
        },
    );
    let mut link = connect(&sim);
    let lines: Vec<String> = c.lines.iter().map(|l| l.text.clone()).collect();
    let letters = lase_runtime::link::ControllerAxes::of(&c.job.program.machine)
        .letters()
        .to_vec();
    assert_eq!(letters, ['X', 'Z']);
    let report = stream::stream(
        &mut link,
        &stream::StreamJob {
            letters: &letters,
            ..stream::StreamJob::new(&lines)
        },
        None,
        &StreamOptions::default(),
        &mut |p: &Progress, _| (p.acked >= lines.len() / 3).then_some(Control::Abort),
    );
    assert_eq!(report.outcome, Outcome::Aborted);
    let note = report.stop_note.unwrap();
    let now = note
        .split("controller now ")
        .nth(1)
        .unwrap_or_else(|| panic!("{note}"));
    let words: Vec<char> = now
        .split(" | ")
        .nth(1)
        .unwrap()
        .split_whitespace()
        .map(|w| w.chars().next().unwrap())
        .collect();
    assert_eq!(words, ['X', 'Z'], "{note}");
    sim.stop();
}
