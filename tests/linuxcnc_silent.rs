//! `lase run --link linuxcnc://…` when LinuxCNC stops answering mid-job, without LinuxCNC: a
//! fake linuxcncrsh (a TCP server in this test) answers the greeting and the job's start as
//! LinuxCNC 2.9 does, then fails in one of the ways a real one was seen to: it goes silent,
//! it closes the connection, or its task (milltask) dies, which leaves linuxcncrsh answering
//! every `get` from a status frozen at RUNNING while no `set` is answered any more. Every one
//! must end `lase run` with the link-lost diagnostic (what was waited for, the last line seen
//! done, how to go on) and a non-zero exit within a few timeouts, never a hang.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

/// How the fake linuxcncrsh fails once the program runs.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    /// Answers nothing after the greeting.
    SilentAfterGreeting,
    /// Closes the connection after this many polls of the running program.
    ClosesAfterPolls(usize),
    /// Its task dies after this many polls: `get` answers stay frozen (RUNNING, same line and
    /// position), `set` gets no answer.
    TaskDiesAfterPolls(usize),
}

/// Serves one session on a free port; returns the port.
fn fake_linuxcncrsh(fault: Fault) -> u16 {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        let Ok((stream, _)) = listener.accept() else {
            return;
        };
        serve(stream, fault);
    });
    port
}

fn serve(stream: TcpStream, fault: Fault) {
    let mut out = stream.try_clone().unwrap();
    let mut greeted = 0;
    let mut running = false;
    let mut polls = 0usize;
    for line in BufReader::new(stream).lines() {
        let Ok(line) = line else { return };
        let line = line.trim().to_string();
        let words: Vec<&str> = line.split_whitespace().collect();
        if greeted < 4 {
            greeted += 1;
            let reply = match greeted {
                1 => "HELLO ACK EMCNETSVR 1.1".to_string(),
                2 => line.clone(),
                _ => format!("SET {} ACK", words[1].to_uppercase()),
            };
            let _ = write!(out, "{reply}\r\n");
            continue;
        }
        if fault == Fault::SilentAfterGreeting {
            continue;
        }
        let dead = match fault {
            Fault::TaskDiesAfterPolls(n) => polls >= n,
            _ => false,
        };
        if let Fault::ClosesAfterPolls(n) = fault
            && polls >= n
        {
            return; // the connection closes with the stream
        }
        let reply = match (words[0], words.get(1).copied().unwrap_or("")) {
            // A dead task takes no command: linuxcncrsh waits for it without end.
            ("set", _) if dead => continue,
            ("set", "run") => {
                running = true;
                "SET RUN ACK".to_string()
            }
            ("set", what) => format!("SET {} ACK", what.to_uppercase()),
            ("get", "program_status") => {
                if running {
                    polls += 1;
                }
                format!(
                    "PROGRAM_STATUS {}",
                    if running { "RUNNING" } else { "IDLE" }
                )
            }
            // Line 12 of the program is running (and stays so once the task is dead).
            ("get", "program_line") => format!("PROGRAM_LINE {}", if running { 12 } else { 0 }),
            ("get", "abs_act_pos") => "ABS_ACT_POS 1.5 2.5 0 0 0 0".into(),
            ("get", "joint_pos") => "JOINT_POS 1.5 2.5".into(),
            ("get", "error") => "ERROR OK".into(),
            ("get", "optional_stop") => "OPTIONAL_STOP 0".into(),
            ("get", "estop") => "ESTOP OFF".into(),
            ("get", "machine") => "MACHINE ON".into(),
            (_, key) => format!("{} NAK", key.to_uppercase()),
        };
        if write!(out, "{reply}\r\n").is_err() {
            return;
        }
    }
}

/// `lase run frame_marking` against the fake on `port` with a 1 s timeout; exit code, output
/// and how long it took.
fn run_against(port: u16) -> (i32, String, Duration) {
    let dir = std::env::temp_dir().join(format!("lase-silent-{port}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let url = format!(
        "linuxcnc://127.0.0.1:{port}?dir={}&timeout=1",
        dir.display()
    );
    let t0 = Instant::now();
    let (code, out, err) = common::lase(&[
        "run",
        "examples/frame_marking.lase",
        "--link",
        &url,
        "--journal",
        &dir.join("job.journal").display().to_string(),
    ]);
    let took = t0.elapsed();
    let _ = std::fs::remove_dir_all(&dir);
    // One line: miette wraps the diagnostic at the terminal's width, with `│` margins.
    let text = format!("{err}{out}")
        .replace('│', " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    (code, text, took)
}

#[test]
fn a_linuxcncrsh_silent_after_the_greeting_ends_the_run_with_a_diagnostic() {
    let (code, out, took) = run_against(fake_linuxcncrsh(Fault::SilentAfterGreeting));
    assert_ne!(code, 0, "{out}");
    // The first command after the greeting asks where the machine stands, for the journal.
    assert!(out.contains("lase::link::not_ready"), "{out}");
    assert!(
        out.contains("waiting for linuxcncrsh's reply to `get program_status`"),
        "{out}"
    );
    assert!(out.contains("restart LinuxCNC"), "{out}");
    assert!(took < Duration::from_secs(20), "took {took:?}: {out}");
}

#[test]
fn a_linuxcncrsh_closing_mid_job_ends_the_run_with_a_diagnostic() {
    let (code, out, took) = run_against(fake_linuxcncrsh(Fault::ClosesAfterPolls(5)));
    assert_ne!(code, 0, "{out}");
    assert!(out.contains("lase::link::lost"), "{out}");
    assert!(out.contains("connection closed"), "{out}");
    // Line 12 running: line 11 is the last seen done, named with its text.
    assert!(out.contains("after 11 of"), "{out}");
    assert!(out.contains("the last line seen done was 11: `"), "{out}");
    assert!(out.contains("lase run --resume"), "{out}");
    assert!(took < Duration::from_secs(20), "took {took:?}: {out}");
}

#[test]
fn a_linuxcnc_whose_task_died_mid_job_ends_the_run_with_a_diagnostic() {
    // RUNNING forever at line 12, nothing moving, and no `set` answered: once the status has
    // stood still for the timeout, lase asks the task to take a command that changes nothing,
    // and its answer not coming ends the run.
    let (code, out, took) = run_against(fake_linuxcncrsh(Fault::TaskDiesAfterPolls(5)));
    assert_ne!(code, 0, "{out}");
    assert!(out.contains("lase::link::lost"), "{out}");
    assert!(
        out.contains("RUNNING at line 12 with nothing moving"),
        "{out}"
    );
    assert!(out.contains("`set optional_stop 0`"), "{out}");
    assert!(out.contains("milltask"), "{out}");
    assert!(out.contains("the last line seen done was 11: `"), "{out}");
    assert!(took < Duration::from_secs(20), "took {took:?}: {out}");
}
