//! LinuxCNC 2.9 over linuxcncrsh (its telnet-style "EMCRSH" server, TCP 5007 by default).
//!
//! LinuxCNC is not a line-streaming controller like GRBL: its trajectory planner blends only
//! what its interpreter reads from a file, and line-by-line MDI does not blend (the cam job
//! took 69 s instead of 30 s). So a LinuxCNC job is a *file the controller opens*: lase writes
//! the program where the controller can read it (a shared folder, see [`job`]), then drives
//! AUTO mode with `set open`, `set run [line]`, `set pause`/`resume`/`abort`, and follows it by
//! polling `get program_status`, `get program_line`, `get abs_act_pos`, `get joint_pos` and
//! `get error`. This is the only code that knows linuxcncrsh's words (emcrsh.cc):
//!
//! - `hello EMC <name> 1.0` → `HELLO ACK EMCNETSVR 1.1` (or `HELLO NAK`).
//! - `set echo off` is itself echoed (echo is still on when it arrives); after
//!   `set verbose on` every `set` is answered `SET <CMD> ACK` or `SET <CMD> NAK`; without
//!   verbose a `set` that works says nothing, so lase turns verbose on first.
//! - `set enable EMCTOO`: one client holds control (the last to enable wins).
//! - `get KEY` → `KEY value…` (`PROGRAM_STATUS IDLE|RUNNING|PAUSED`, `PROGRAM_LINE 44`,
//!   `ABS_ACT_POS x y z a b c`, `JOINT_POS …`), or `KEY NAK`.
//! - `set run` is ACKed even when the program then fails (a file it cannot read, a word the
//!   interpreter refuses): errors come after the ACK and are read with `get error`, one message
//!   per read, `ERROR OK` when none.
//! - Replies end in `\r\n` or `\n` depending on the reply: any run of CR/LF ends a line.

pub mod config;
pub mod job;
pub mod tp;

use super::LinkError;
use super::transport::{TcpTransport, Transport};
use std::time::{Duration, Instant};

/// The default linuxcncrsh port.
pub const DEFAULT_PORT: u16 = 5007;

/// How long a reply may take by default: linuxcncrsh answers from its own loop, and `set`
/// commands wait for the task to receive them (its default wait mode).
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(10);

/// How long `lase run` waits for linuxcncrsh by default (`linuxcnc://…?timeout=SECONDS`):
/// for each reply, and for a running program's status to change before it asks whether
/// LinuxCNC's task still takes commands ([`Rsh::probe_task`]). LinuxCNC's user interface runs
/// beside motion without real-time priority: a silence of seconds is load, not a lost link.
pub const LIVE_TIMEOUT: Duration = Duration::from_secs(30);

/// What `get program_status` says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProgramStatus {
    Idle,
    Running,
    Paused,
}

/// One poll of a running program.
#[derive(Debug, Clone, PartialEq)]
pub struct RunStatus {
    pub program: ProgramStatus,
    /// The file line the interpreter reports (1-based; 0 before a program ran).
    pub line: u32,
    /// Commanded position in machine coordinates, X Y Z A B C (mm, degrees).
    pub abs_pos: [f64; 6],
    /// Joint positions, joint 0… (mm or degrees, as the INI's joint types say).
    pub joints: Vec<f64>,
}

/// A linuxcncrsh session holding control of the controller (`set enable EMCTOO`).
pub struct Rsh {
    transport: Box<dyn Transport>,
    pending: Vec<u8>,
    url: String,
    reply_timeout: Duration,
    /// The last command written: what a reply that does not come was waited for.
    last_sent: String,
}

impl std::fmt::Debug for Rsh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Rsh").field("url", &self.url).finish()
    }
}

fn protocol(text: &str, reason: &str) -> LinkError {
    LinkError::Protocol {
        text: text.to_string(),
        reason: format!("{reason} (linuxcncrsh)"),
    }
}

impl Rsh {
    /// Connects to linuxcncrsh at `host:port` and takes control: hello, echo off, verbose on,
    /// enable.
    pub fn connect(host: &str, port: u16) -> Result<Rsh, LinkError> {
        Rsh::connect_with(host, port, REPLY_TIMEOUT)
    }

    /// As [`Rsh::connect`], each reply (the greeting's too) within `reply_timeout`.
    pub fn connect_with(host: &str, port: u16, reply_timeout: Duration) -> Result<Rsh, LinkError> {
        let url = format!("linuxcnc://{host}:{port}");
        let t = TcpTransport::connect(host, port).map_err(|e| match e {
            LinkError::Connect { reason, .. } => LinkError::Connect {
                url: url.clone(),
                reason,
                help: Some(
                    "is LinuxCNC running with `DISPLAY = linuxcncrsh` (or linuxcncrsh started by hand) listening on that port?"
                        .into(),
                ),
            },
            e => e,
        })?;
        Rsh::over_with(Box::new(t), url, reply_timeout)
    }

    /// The session over any transport (tests use a pipe or a failing wrapper).
    pub fn over(transport: Box<dyn Transport>, url: String) -> Result<Rsh, LinkError> {
        Rsh::over_with(transport, url, REPLY_TIMEOUT)
    }

    fn over_with(
        transport: Box<dyn Transport>,
        url: String,
        reply_timeout: Duration,
    ) -> Result<Rsh, LinkError> {
        let mut rsh = Rsh {
            transport,
            pending: Vec::new(),
            url,
            reply_timeout,
            last_sent: String::new(),
        };
        rsh.write("hello EMC lase 1.0")?;
        let hello = rsh.line()?;
        if !hello.starts_with("HELLO ACK") {
            return Err(LinkError::Connect {
                url: rsh.url.clone(),
                reason: format!("linuxcncrsh refused the greeting: `{hello}`"),
                help: Some("linuxcncrsh was started with a connect password (-w): lase sends the default `EMC`".into()),
            });
        }
        // Echo is still on for this one command: its echo is its only answer.
        rsh.write("set echo off")?;
        let echo = rsh.line()?;
        if !echo.eq_ignore_ascii_case("set echo off") && !echo.starts_with("SET ECHO") {
            return Err(protocol(&echo, "expected the echo of `set echo off`"));
        }
        rsh.set("verbose on")?;
        rsh.set("enable EMCTOO")?;
        Ok(rsh)
    }

    pub fn describe(&self) -> String {
        self.url.clone()
    }

    /// How long to wait for each reply from now on (a controller on a loaded computer, as
    /// a non-realtime LinuxCNC sharing two cores with compilers, can stall for seconds).
    pub fn set_reply_timeout(&mut self, timeout: Duration) {
        self.reply_timeout = timeout;
    }

    /// How long each reply may take.
    pub fn reply_timeout(&self) -> Duration {
        self.reply_timeout
    }

    /// The last command sent to linuxcncrsh.
    pub fn last_sent(&self) -> &str {
        &self.last_sent
    }

    fn write(&mut self, command: &str) -> Result<(), LinkError> {
        self.last_sent = command.to_string();
        let mut bytes = command.as_bytes().to_vec();
        bytes.extend_from_slice(b"\r\n");
        self.transport
            .write_all(&bytes)
            .map_err(|e| LinkError::Lost {
                reason: format!("sending `{command}` to linuxcncrsh: {e}"),
            })
    }

    /// The next reply line (any run of CR/LF ends one; empty lines are skipped).
    fn line(&mut self) -> Result<String, LinkError> {
        let deadline = Instant::now() + self.reply_timeout;
        loop {
            if let Some(end) = self.pending.iter().position(|&b| b == b'\r' || b == b'\n') {
                let text = String::from_utf8_lossy(&self.pending[..end])
                    .trim()
                    .to_string();
                let rest = self.pending[end..]
                    .iter()
                    .position(|&b| b != b'\r' && b != b'\n')
                    .map_or(self.pending.len(), |k| end + k);
                self.pending.drain(..rest);
                if !text.is_empty() {
                    return Ok(text);
                }
                continue;
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(LinkError::Timeout {
                    waiting_for: format!("waiting for linuxcncrsh's reply to `{}`", self.last_sent),
                    seconds: self.reply_timeout.as_secs_f64(),
                });
            }
            let mut buf = [0u8; 1024];
            let n = self
                .transport
                .read(&mut buf, left.min(Duration::from_millis(100)))
                .map_err(|e| LinkError::Lost {
                    reason: format!(
                        "linuxcncrsh: {e} while lase waited for its reply to `{}`",
                        self.last_sent
                    ),
                })?;
            if self.pending.len() + n > 64 * 1024 {
                return Err(protocol(
                    "…",
                    "a reply longer than 64 KiB without a line end",
                ));
            }
            self.pending.extend_from_slice(&buf[..n]);
        }
    }

    /// `set WHAT…`: ACK, or the NAK as a refusal with the controller's own error when it gives
    /// one.
    pub fn set(&mut self, what: &str) -> Result<(), LinkError> {
        self.write(&format!("set {what}"))?;
        let reply = self.line()?;
        let head = what.split_whitespace().next().unwrap_or("").to_uppercase();
        if reply == format!("SET {head} ACK") {
            return Ok(());
        }
        if reply == format!("SET {head} NAK") {
            let why = self.error()?.unwrap_or_else(|| "no reason given".into());
            return Err(LinkError::NotReady {
                reason: format!("LinuxCNC refused `set {what}`: {why}"),
                help: "another client may hold control (`set enable`), the machine may be in E-stop, or the program may not be readable on the controller".into(),
            });
        }
        Err(protocol(&reply, &format!("expected SET {head} ACK or NAK")))
    }

    /// `get KEY`: the reply's words after the key.
    pub fn get(&mut self, key: &str) -> Result<String, LinkError> {
        self.write(&format!("get {key}"))?;
        let reply = self.line()?;
        let upper = key.to_uppercase();
        let rest = reply
            .strip_prefix(upper.as_str())
            .map(str::trim)
            .ok_or_else(|| protocol(&reply, &format!("expected a {upper} reply")))?;
        if rest == "NAK" {
            return Err(protocol(&reply, &format!("LinuxCNC refused `get {key}`")));
        }
        Ok(rest.to_string())
    }

    /// `get error`: the oldest error message not yet read, `None` for `ERROR OK`.
    pub fn error(&mut self) -> Result<Option<String>, LinkError> {
        let e = self.get("error")?;
        Ok((e != "OK").then_some(e))
    }

    /// Every pending error message (linuxcncrsh hands out one per read).
    pub fn errors(&mut self) -> Result<Vec<String>, LinkError> {
        let mut out = Vec::new();
        while let Some(e) = self.error()? {
            out.push(e);
            if out.len() > 100 {
                break;
            }
        }
        Ok(out)
    }

    /// Out of E-stop, machine on, AUTO mode: ready for `set open` and `set run`.
    pub fn start_auto(&mut self) -> Result<(), LinkError> {
        self.set("estop off")?;
        self.set("machine on")?;
        self.set("mode auto")
    }

    pub fn status(&mut self) -> Result<RunStatus, LinkError> {
        let program = match self.get("program_status")?.as_str() {
            "IDLE" => ProgramStatus::Idle,
            "RUNNING" => ProgramStatus::Running,
            "PAUSED" => ProgramStatus::Paused,
            other => return Err(protocol(other, "unknown PROGRAM_STATUS")),
        };
        let line_text = self.get("program_line")?;
        let line = line_text
            .parse()
            .map_err(|_| protocol(&line_text, "PROGRAM_LINE is not a line number"))?;
        let abs = numbers(&self.get("abs_act_pos")?)?;
        let joints = numbers(&self.get("joint_pos")?)?;
        let abs_pos = std::array::from_fn(|i| abs.get(i).copied().unwrap_or(0.0));
        Ok(RunStatus {
            program,
            line,
            abs_pos,
            joints,
        })
    }

    /// Whether LinuxCNC's task still takes commands: `set optional_stop` with the value it
    /// has (`get optional_stop`), so nothing changes. linuxcncrsh answers every `get` from the
    /// last status the task published, so a task that has died (seen: milltask gone, its
    /// program RUNNING forever) still "answers" them; a `set`, though, waits until the task
    /// has received it (emcrsh.cc, `sendSetOptionalStop` → `emcCommandWaitReceived`, with no
    /// time limit of its own), so its reply not coming within the reply timeout is the sign.
    /// A refusal (NAK) is an answer: the task is there.
    pub fn probe_task(&mut self) -> Result<(), LinkError> {
        let value = self.get("optional_stop")?;
        let value = if value.trim() == "1" { "1" } else { "0" };
        match self.set(&format!("optional_stop {value}")) {
            Ok(()) | Err(LinkError::NotReady { .. }) => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Asks LinuxCNC itself to shut down (linuxcncrsh `shutdown`): how a harness that started
    /// it stops it. The connection ends with it.
    pub fn shutdown(mut self) -> Result<(), LinkError> {
        self.write("shutdown")
    }

    /// One MDI line (the caller has put the controller in MDI mode), waiting until it is done.
    pub fn mdi(&mut self, line: &str) -> Result<(), LinkError> {
        self.set(&format!("mdi {line}"))?;
        self.wait_idle(Duration::from_secs(120))
    }

    /// Waits until the interpreter is idle again (after MDI or an abort).
    pub fn wait_idle(&mut self, limit: Duration) -> Result<(), LinkError> {
        let deadline = Instant::now() + limit;
        while self.get("program_status")? != "IDLE" {
            if Instant::now() > deadline {
                return Err(LinkError::Timeout {
                    waiting_for: "LinuxCNC to become idle".into(),
                    seconds: limit.as_secs_f64(),
                });
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }
}

fn numbers(text: &str) -> Result<Vec<f64>, LinkError> {
    text.split_whitespace()
        .map(|w| w.parse().map_err(|_| protocol(text, "expected numbers")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::transport::pipe;

    /// A scripted linuxcncrsh: answers each command line with the replies of a transcript of
    /// LinuxCNC 2.9's, line endings as it sends them.
    fn scripted(script: Vec<(&'static str, &'static str)>) -> Rsh {
        let (mut ours, theirs) = pipe("rsh");
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            for (expect, reply) in script {
                loop {
                    if let Some(end) = buf.iter().position(|&b| b == b'\n') {
                        let line = String::from_utf8_lossy(&buf[..end]).trim().to_string();
                        buf.drain(..=end);
                        assert_eq!(line, expect);
                        break;
                    }
                    let mut b = [0u8; 256];
                    match ours.read(&mut b, Duration::from_secs(5)) {
                        Ok(n) => buf.extend_from_slice(&b[..n]),
                        Err(_) => return,
                    }
                }
                ours.write_all(reply.as_bytes()).unwrap();
            }
        });
        Rsh::over(Box::new(theirs), "linuxcnc://test:5007".into()).unwrap()
    }

    const HANDSHAKE: [(&str, &str); 4] = [
        ("hello EMC lase 1.0", "HELLO ACK EMCNETSVR 1.1\r\n"),
        ("set echo off", "set echo off\r\n"),
        ("set verbose on", "SET VERBOSE ACK\r\n"),
        ("set enable EMCTOO", "SET ENABLE ACK\r\n"),
    ];

    #[test]
    fn a_transcript_of_linuxcnc_29_parses() {
        let mut script = HANDSHAKE.to_vec();
        script.extend([
            ("get program_status", "PROGRAM_STATUS RUNNING\n"),
            ("get program_line", "PROGRAM_LINE 44\r\n"),
            (
                "get abs_act_pos",
                "ABS_ACT_POS 9.203683 21.900000 0.000000 0.000000 0.000000 0.000000\r\n",
            ),
            ("get joint_pos", "JOINT_POS 9.203683 21.900000\r\n"),
            ("get error", "ERROR OK\r\n"),
            ("set run", "SET RUN ACK\r\n"),
            (
                "get error",
                "ERROR Near line 3 of /x.ngc: Unknown g code used\r\n",
            ),
            ("get error", "ERROR OK\r\n"),
        ]);
        let mut rsh = scripted(script);
        let st = rsh.status().unwrap();
        assert_eq!(st.program, ProgramStatus::Running);
        assert_eq!(st.line, 44);
        assert_eq!(st.abs_pos[0], 9.203683);
        assert_eq!(st.joints, vec![9.203683, 21.9]);
        assert_eq!(rsh.error().unwrap(), None);
        rsh.set("run").unwrap();
        assert_eq!(
            rsh.errors().unwrap(),
            vec!["Near line 3 of /x.ngc: Unknown g code used".to_string()]
        );
    }

    #[test]
    fn a_nak_is_a_refusal_with_the_controllers_reason() {
        let mut script = HANDSHAKE.to_vec();
        script.extend([
            ("set mode auto", "SET MODE NAK\r\n"),
            ("get error", "ERROR machine is in estop\r\n"),
        ]);
        let mut rsh = scripted(script);
        let e = rsh.set("mode auto").unwrap_err().to_string();
        assert!(e.contains("machine is in estop"), "{e}");
    }

    #[test]
    fn a_refused_greeting_is_a_connect_error() {
        let (mut ours, theirs) = pipe("rsh");
        std::thread::spawn(move || {
            let mut b = [0u8; 64];
            let _ = ours.read(&mut b, Duration::from_secs(5));
            ours.write_all(b"HELLO NAK\r\n").unwrap();
            std::thread::sleep(Duration::from_millis(100));
        });
        let e = Rsh::over(Box::new(theirs), "linuxcnc://t:1".into()).unwrap_err();
        assert!(matches!(e, LinkError::Connect { .. }), "{e:?}");
    }
}
