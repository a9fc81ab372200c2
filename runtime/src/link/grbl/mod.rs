//! The GRBL 1.1 serial protocol over any [`Transport`]: the client side, for GRBL and for
//! grblHAL (the same protocol with up to six axes, a longer line buffer and a larger RX
//! buffer).
//!
//! Flow control is character counting, as grbl's `stream.py` does it: the controller's serial
//! RX buffer (as `$I` reports it, else GRBL's 128 bytes; one slot kept free by its ring
//! buffer) holds whole lines waiting to be parsed; every line sent and not yet answered with
//! `ok`/`error:N` counts against it, so the buffer can never overflow and the controller never
//! waits for the host. Send-response (one line in flight) is the fallback for links that lose
//! bytes under load.
//!
//! Answers come in the order lines were sent; everything else (status reports, alarms,
//! feedback) is pushed by the controller at any time and passed on as [`Event`]s. Any line
//! this module cannot parse is a [`LinkError::Protocol`]: once the byte stream is not
//! understood, the character count cannot be trusted either.

pub mod codes;
pub mod response;
pub mod settings;

use super::transport::Transport;
use super::{
    ConnectOptions, Continue, Event, Link, LinkError, ModalState, MotionMode, Realtime, Reapproach,
    Reply, Requirements, Status,
};
use response::Response;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// GRBL's line buffer: 80 bytes with the terminating zero, counted after it strips spaces
/// and comments.
pub const LINE_BUFFER: usize = 80;

/// GRBL 1.1's serial RX buffer, bytes: the assumption when the controller does not say.
pub const DEFAULT_RX_BUFFER: usize = 128;

/// grblHAL's line buffer: 257 bytes with the terminating zero, counting spaces and comments
/// (only leading blanks are dropped).
pub const LINE_BUFFER_HAL: usize = 257;

/// The GRBL decision behind [`Link::continue_line`].
pub fn continuation(state: &ModalState, line: &str) -> Continue {
    let Ok(ws) = super::modal::words(line) else {
        return Continue::Settled;
    };
    let motion_word = ws
        .iter()
        .any(|&(c, v)| c == 'G' && [0.0, 1.0, 2.0, 3.0, 80.0].contains(&v));
    if motion_word {
        return Continue::Settled;
    }
    if !ws.iter().any(|&(c, _)| super::axis_index(c).is_some()) {
        return Continue::Pending;
    }
    match state.motion {
        MotionMode::ArcCw | MotionMode::ArcCcw => Continue::Replace(
            crate::emit::reapproach::with_motion_word(state.motion, line),
        ),
        _ => Continue::Settled,
    }
}

/// A GRBL 1.1 controller.
pub struct GrblLink {
    t: Box<dyn Transport>,
    url: String,
    rx_capacity: usize,
    send_response: bool,
    /// Byte counts of the lines in flight, oldest first.
    inflight: VecDeque<usize>,
    inflight_bytes: usize,
    partial: Vec<u8>,
    events: VecDeque<Event>,
    banner: Option<String>,
    /// `$I` said `[FIRMWARE:grblHAL]` (grblHAL sends no banner to a TCP client).
    hal_build: bool,
    last_status: Option<Status>,
    statuses: u64,
    wco: Option<Vec<f64>>,
    bytes_sent: u64,
    /// After a soft reset, answers to lines sent before it are dropped until the banner.
    resetting: bool,
    /// Until the connection's barrier (`$G`) is answered, answers belong to lines an earlier
    /// connection sent, and are dropped.
    stale: bool,
    /// A `send` waits for its answer: `ok`/`error` go here instead of the event queue.
    command: Option<Option<Reply>>,
    collected: Vec<Response>,
}

impl std::fmt::Debug for GrblLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblLink")
            .field("url", &self.url)
            .field("in_flight", &self.inflight.len())
            .finish()
    }
}

fn lost(e: std::io::Error) -> LinkError {
    LinkError::Lost {
        reason: e.to_string(),
    }
}

/// What `$I` told about the controller.
#[derive(Debug, Default)]
struct BuildInfo {
    rx_buffer: Option<usize>,
    grblhal: bool,
}

impl GrblLink {
    /// Greets the controller: asks for status until one arrives. A USB GRBL resets when the
    /// port opens and answers after its boot loader, so the question is repeated.
    pub fn connect(
        t: Box<dyn Transport>,
        url: String,
        options: &ConnectOptions,
    ) -> Result<GrblLink, LinkError> {
        let mut link = GrblLink {
            t,
            url,
            rx_capacity: options.rx_buffer.unwrap_or(DEFAULT_RX_BUFFER).max(16),
            send_response: options.send_response,
            inflight: VecDeque::new(),
            inflight_bytes: 0,
            partial: Vec::new(),
            events: VecDeque::new(),
            banner: None,
            hal_build: false,
            last_status: None,
            statuses: 0,
            wco: None,
            bytes_sent: 0,
            resetting: false,
            // Until the barrier, answers may belong to an earlier connection's lines.
            stale: true,
            command: None,
            collected: Vec::new(),
        };
        link.query_status(options.connect_timeout)
            .map_err(|e| match e {
                LinkError::Timeout { .. } => LinkError::Connect {
                    url: link.url.clone(),
                    reason: "the controller does not answer status queries".into(),
                    help: Some(
                        "check the baud rate and that the device is a GRBL 1.1 controller".into(),
                    ),
                },
                other => other,
            })?;
        link.barrier(options.busy_wait)?;
        let info = link.build_info()?;
        // grblHAL greets no TCP client with a banner; its `$I` says what it is.
        link.hal_build = info.grblhal;
        if options.rx_buffer.is_none()
            && let Some(rx) = info.rx_buffer
        {
            link.rx_capacity = rx;
        }
        // What came before (banner, unlock reminders, stale answers) is history.
        link.events.clear();
        Ok(link)
    }

    /// What the controller's `$I` says: the RX buffer (`[OPT:codes,blocks,rx…]`, GRBL 1.1 and
    /// grblHAL alike) when plausible, and whether it is grblHAL (`[FIRMWARE:grblHAL]`). A
    /// controller that refuses `$I` or leaves a field out keeps GRBL's 128 and GRBL's limits.
    fn build_info(&mut self) -> Result<BuildInfo, LinkError> {
        let got = match self.command_collect("$I", Duration::from_secs(3)) {
            Ok((Reply::Ok, got)) => got,
            Ok((Reply::Error { .. }, _)) | Err(LinkError::Timeout { .. }) => {
                return Ok(BuildInfo::default());
            }
            Err(e) => return Err(e),
        };
        let rx_buffer = got.iter().find_map(|r| match r {
            Response::Feedback { kind, body } if kind == "OPT" => body
                .split(',')
                .nth(2)
                .and_then(|v| v.trim().parse::<usize>().ok())
                .filter(|rx| (16..=1 << 16).contains(rx)),
            _ => None,
        });
        let grblhal = got.iter().any(|r| {
            matches!(r, Response::Feedback { kind, body } if kind == "FIRMWARE" && body == "grblHAL")
        });
        Ok(BuildInfo { rx_buffer, grblhal })
    }

    /// The input buffer lines are counted against, bytes.
    pub fn rx_buffer(&self) -> usize {
        self.rx_capacity
    }

    /// Waits until the controller has answered every line sent before this connection: a
    /// controller goes on with what it received when a link drops, and its answers arrive on
    /// the next connection. GRBL answers in order, so everything before the `[GC:…]` of a `$G`
    /// sent now is stale. A line the drop cut in half merges with that `$G` into an invalid
    /// block, which GRBL refuses whole (a `$` is no G-code word); once the controller is idle
    /// with an empty input buffer and no `[GC:…]` came, the `$G` is sent again.
    fn barrier(&mut self, busy_wait: Duration) -> Result<(), LinkError> {
        let deadline = Instant::now() + busy_wait;
        let mut attempts = 0;
        loop {
            attempts += 1;
            if attempts > 4 {
                return Err(LinkError::NotReady {
                    reason: "the controller does not answer `$G`".into(),
                    help: "reset the controller (Ctrl-X) and check that it runs GRBL 1.1".into(),
                });
            }
            self.inflight.clear();
            self.inflight_bytes = 0;
            self.stale = true;
            self.collected.clear();
            self.command = Some(None);
            self.send_line("$G")?;
            let mut asked = Instant::now() - Duration::from_secs(1);
            let mut quiet_since: Option<Instant> = None;
            let seen = self.statuses;
            loop {
                if let Some(Some(reply)) = &self.command {
                    let reply = reply.clone();
                    self.command = None;
                    return super::reply_error("$G", reply);
                }
                let now = Instant::now();
                if now >= deadline {
                    self.command = None;
                    return Err(LinkError::Timeout {
                        waiting_for: "waiting for the controller to finish what it had received"
                            .into(),
                        seconds: busy_wait.as_secs_f64(),
                    });
                }
                if now.duration_since(asked) >= Duration::from_millis(100) {
                    self.write(&[codes::realtime_byte(Realtime::StatusQuery)])?;
                    asked = now;
                }
                self.read_some(Duration::from_millis(20))?;
                if self.statuses > seen
                    && let Some(s) = &self.last_status
                {
                    let at_rest = matches!(
                        s.state,
                        super::MachineState::Idle
                            | super::MachineState::Alarm
                            | super::MachineState::Check
                    );
                    let rx_empty = s
                        .buffer
                        .is_none_or(|b| b.rx_free as usize + 1 >= self.rx_capacity);
                    if at_rest && rx_empty && self.stale {
                        let since = *quiet_since.get_or_insert(now);
                        let settle = if s.buffer.is_some() { 300 } else { 2000 };
                        if now.duration_since(since) >= Duration::from_millis(settle) {
                            break;
                        }
                    } else {
                        quiet_since = None;
                    }
                }
            }
        }
    }

    /// The controller's banner, when it printed one since the connection opened.
    pub fn banner(&self) -> Option<&str> {
        self.banner.as_deref()
    }

    /// Whether the controller greeted as grblHAL (a longer line buffer; unknown means GRBL's
    /// limits, the stricter ones).
    pub fn is_grblhal(&self) -> bool {
        self.hal_build
            || self
                .banner
                .as_deref()
                .is_some_and(|b| b.starts_with("GrblHAL "))
    }

    fn read_some(&mut self, timeout: Duration) -> Result<usize, LinkError> {
        let mut buf = [0u8; 4096];
        let n = self.t.read(&mut buf, timeout).map_err(lost)?;
        for &b in &buf[..n] {
            if b == b'\n' {
                let mut line = std::mem::take(&mut self.partial);
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                self.handle_line(&line)?;
            } else {
                self.partial.push(b);
                if self.partial.len() > response::MAX_RESPONSE {
                    let text = response::printable(&self.partial);
                    self.partial.clear();
                    return Err(LinkError::Protocol {
                        text,
                        reason: "no line end after 256 bytes".into(),
                    });
                }
            }
        }
        Ok(n)
    }

    fn answer(&mut self, reply: Reply) -> Result<(), LinkError> {
        if self.resetting || self.stale {
            return Ok(());
        }
        let Some(n) = self.inflight.pop_front() else {
            return Err(LinkError::Protocol {
                text: match &reply {
                    Reply::Ok => "ok".into(),
                    Reply::Error { code, .. } => format!("error:{code}"),
                },
                reason: "an answer with no line in flight".into(),
            });
        };
        self.inflight_bytes -= n;
        match (&mut self.command, reply) {
            (Some(slot @ None), r) => *slot = Some(r),
            (_, Reply::Ok) => self.events.push_back(Event::Ack),
            (_, Reply::Error { code, message }) => {
                self.events.push_back(Event::Rejected { code, message })
            }
        }
        Ok(())
    }

    fn handle_line(&mut self, line: &[u8]) -> Result<(), LinkError> {
        let r = response::parse(line).map_err(|m| LinkError::Protocol {
            text: m.text,
            reason: m.reason,
        })?;
        if self.command.is_some() {
            self.collected.push(r.clone());
        }
        match r {
            Response::Empty => {}
            Response::Ok => self.answer(Reply::Ok)?,
            Response::Error(code) => self.answer(Reply::Error {
                code,
                message: codes::error_message(code).into(),
            })?,
            Response::Alarm(code) => self.events.push_back(Event::Alarm {
                code,
                message: codes::alarm_message(code).into(),
            }),
            Response::Status(s) => {
                if let Some(w) = &s.wco {
                    self.wco = Some(w.clone());
                }
                self.statuses += 1;
                self.last_status = Some(s.clone());
                self.events.push_back(Event::Status(s));
            }
            Response::Banner { text, .. } => {
                self.resetting = false;
                self.inflight.clear();
                self.inflight_bytes = 0;
                self.banner = Some(text.clone());
                self.events.push_back(Event::Reset { banner: text });
            }
            Response::Message(m) => self.events.push_back(Event::Message(format!("[MSG:{m}]"))),
            Response::ParserState(_) => self.stale = false,
            Response::Setting { .. } | Response::StartupLineSetting { .. } => {}
            // A message neither GRBL nor grblHAL documents (a plugin's, a newer build's) is
            // shown and ignored: it says nothing about the lines in flight.
            Response::Feedback { kind, body } if !response::documented_feedback(&kind) => {
                self.events.push_back(Event::Message(format!(
                    "warning: ignored a controller message lase does not know: [{kind}:{body}]"
                )))
            }
            Response::Feedback { kind, body } => self
                .events
                .push_back(Event::Message(format!("[{kind}:{body}]"))),
            Response::StartupLine { line, error } => {
                self.events.push_back(Event::Message(match error {
                    None => format!("startup line `{line}` ran"),
                    Some(c) => format!("startup line `{line}` failed: error {c}"),
                }))
            }
        }
        Ok(())
    }

    fn write(&mut self, bytes: &[u8]) -> Result<(), LinkError> {
        self.t.write_all(bytes).map_err(lost)?;
        self.bytes_sent += bytes.len() as u64;
        Ok(())
    }

    fn settings(&mut self) -> Result<settings::Settings, LinkError> {
        let (reply, got) = self.command_collect("$$", Duration::from_secs(5))?;
        super::reply_error("$$", reply)?;
        Ok(got
            .into_iter()
            .filter_map(|r| match r {
                Response::Setting { id, value } => Some((id, value)),
                _ => None,
            })
            .collect())
    }

    /// Sends a line and waits for its answer, returning the feedback that came with it.
    fn command_collect(
        &mut self,
        line: &str,
        timeout: Duration,
    ) -> Result<(Reply, Vec<Response>), LinkError> {
        if !self.inflight.is_empty() {
            return Err(LinkError::NotReady {
                reason: format!(
                    "`{line}` while {} job lines are in flight",
                    self.inflight.len()
                ),
                help: "wait for the job to finish or stop it first".into(),
            });
        }
        self.collected.clear();
        self.command = Some(None);
        let result = (|| {
            self.send_line(line)?;
            let deadline = Instant::now() + timeout;
            loop {
                if let Some(Some(r)) = &self.command {
                    return Ok(r.clone());
                }
                let now = Instant::now();
                if now >= deadline {
                    return Err(LinkError::Timeout {
                        waiting_for: format!("waiting for the answer to `{line}`"),
                        seconds: timeout.as_secs_f64(),
                    });
                }
                self.read_some((deadline - now).min(Duration::from_millis(50)))?;
            }
        })();
        self.command = None;
        let collected = std::mem::take(&mut self.collected);
        result.map(|r| (r, collected))
    }
}

impl Link for GrblLink {
    /// GRBL 1.1's jog (`$J=`): its own G91 and feed, the parser's modal state untouched.
    fn jog_line(&self, dx: f64, dy: f64, feed: f64) -> Option<String> {
        Some(format!("$J=G91 G21 X{dx:.4} Y{dy:.4} F{feed:.0}"))
    }

    fn describe(&self) -> String {
        match &self.banner {
            Some(b) => format!("{} ({})", self.url, b.split(" [").next().unwrap_or(b)),
            // grblHAL greets a TCP client with no banner; its `$I` named it.
            None if self.hal_build => format!("{} (grblHAL)", self.url),
            None => self.url.clone(),
        }
    }

    fn validate_line(&self, line: &str) -> Result<(), String> {
        if let Some(c) = line
            .bytes()
            .find(|b| !(b' '..=b'~').contains(b) || matches!(b, b'?' | b'!' | b'~'))
        {
            return Err(match c {
                b'?' => "`?` is GRBL's status query: the controller takes it out of the line, even inside a comment".into(),
                b'!' => "`!` is GRBL's feed hold: the controller would stop the machine at this line".into(),
                b'~' => "`~` is GRBL's cycle start: the controller takes it out of the line".into(),
                c => format!("byte {c:#04x} is not printable ASCII (GRBL reads bytes ≥ 0x80 as real-time commands)"),
            });
        }
        if self.is_grblhal() {
            let kept = line.trim_start().len();
            if kept >= LINE_BUFFER_HAL - 1 {
                return Err(format!(
                    "{kept} characters: grblHAL's line buffer holds {}",
                    LINE_BUFFER_HAL - 2
                ));
            }
        } else {
            // GRBL counts the characters it keeps: no spaces, no comments.
            let mut kept = 0;
            let mut depth = false;
            for c in line.bytes() {
                match c {
                    b'(' => depth = true,
                    b')' => depth = false,
                    b';' if !depth => break,
                    c if !depth && c > b' ' => kept += 1,
                    _ => {}
                }
            }
            if kept >= LINE_BUFFER {
                return Err(format!(
                    "{kept} characters: GRBL's line buffer holds {}",
                    LINE_BUFFER - 1
                ));
            }
        }
        if line.len() + 1 > self.rx_capacity - 1 {
            return Err(format!(
                "{} bytes with its newline: the controller's {}-byte input buffer cannot hold it",
                line.len() + 1,
                self.rx_capacity
            ));
        }
        Ok(())
    }

    fn can_send(&self, line: &str) -> bool {
        if self.send_response {
            return self.inflight.is_empty();
        }
        self.inflight.is_empty() || self.inflight_bytes + line.len() + 1 < self.rx_capacity
    }

    fn send_line(&mut self, line: &str) -> Result<(), LinkError> {
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line.as_bytes());
        bytes.push(b'\n');
        self.write(&bytes)?;
        self.inflight.push_back(bytes.len());
        self.inflight_bytes += bytes.len();
        Ok(())
    }

    fn in_flight(&self) -> usize {
        self.inflight.len()
    }

    fn bytes_sent(&self) -> u64 {
        self.bytes_sent
    }

    fn poll(&mut self, timeout: Duration) -> Result<Option<Event>, LinkError> {
        if let Some(e) = self.events.pop_front() {
            return Ok(Some(e));
        }
        let deadline = Instant::now() + timeout;
        loop {
            self.read_some(deadline.saturating_duration_since(Instant::now()))?;
            if let Some(e) = self.events.pop_front() {
                return Ok(Some(e));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
        }
    }

    fn realtime(&mut self, cmd: Realtime) -> Result<(), LinkError> {
        self.write(&[codes::realtime_byte(cmd)])?;
        if cmd == Realtime::SoftReset {
            // The controller empties its buffers: lines in flight will never be answered.
            self.resetting = true;
            self.inflight.clear();
            self.inflight_bytes = 0;
        }
        Ok(())
    }

    fn send(&mut self, line: &str) -> Result<Reply, LinkError> {
        self.command_collect(line, Duration::from_secs(10))
            .map(|(r, _)| r)
    }

    fn status(&self, letters: &[char]) -> String {
        match &self.last_status {
            Some(s) => s.summary_for(self.wco.as_deref(), letters),
            None => "no status yet".into(),
        }
    }

    fn last_status(&self) -> Option<&Status> {
        self.last_status.as_ref()
    }

    fn query_status(&mut self, timeout: Duration) -> Result<Status, LinkError> {
        let start = Instant::now();
        let seen = self.statuses;
        let mut asked = None::<Instant>;
        loop {
            // GRBL ignores a `?` while one is pending and may drop one during a reset.
            if asked.is_none_or(|t| t.elapsed() >= Duration::from_millis(250)) {
                self.realtime(Realtime::StatusQuery)?;
                asked = Some(Instant::now());
            }
            if self.statuses > seen
                && let Some(s) = &self.last_status
            {
                return Ok(s.clone());
            }
            let left = timeout.saturating_sub(start.elapsed());
            if left.is_zero() {
                return Err(LinkError::Timeout {
                    waiting_for: "waiting for a status report".into(),
                    seconds: timeout.as_secs_f64(),
                });
            }
            self.read_some(left.min(Duration::from_millis(20)))?;
        }
    }

    /// `$#` (report.c `report_ngc_parameters`): one `[G54:x,y,z]` … `[G59:…]` line per
    /// coordinate system, then G28, G30, G92, TLO and PRB; grblHAL adds its axes' values.
    fn work_offset(&mut self, g: u8) -> Result<Option<Vec<f64>>, LinkError> {
        let (reply, got) = self.command_collect("$#", Duration::from_secs(5))?;
        super::reply_error("$#", reply)?;
        let kind = format!("G{g}");
        let Some(body) = got.iter().find_map(|r| match r {
            Response::Feedback { kind: k, body } if *k == kind => Some(body.clone()),
            _ => None,
        }) else {
            return Ok(None);
        };
        response::parse_offset(&body)
            .map(Some)
            .map_err(|reason| LinkError::Protocol {
                text: format!("[{kind}:{body}]"),
                reason,
            })
    }

    fn modal_state(&mut self) -> Result<ModalState, LinkError> {
        let (reply, got) = self.command_collect("$G", Duration::from_secs(5))?;
        super::reply_error("$G", reply)?;
        let body = got
            .iter()
            .find_map(|r| match r {
                Response::ParserState(b) => Some(b.clone()),
                _ => None,
            })
            .ok_or_else(|| LinkError::Protocol {
                text: "$G".into(),
                reason: "no [GC:…] parser state in the answer".into(),
            })?;
        response::parse_parser_state(&body).map_err(|reason| LinkError::Protocol {
            text: format!("[GC:{body}]"),
            reason,
        })
    }

    fn check_settings(
        &mut self,
        needs: &Requirements,
    ) -> Result<Vec<super::SettingMismatch>, LinkError> {
        let s = self.settings()?;
        let axes = self
            .last_status
            .as_ref()
            .and_then(|st| st.mpos.as_ref().or(st.wpos.as_ref()))
            .map(Vec::len);
        Ok(settings::compare(&s, needs, axes))
    }

    fn set_check_mode(&mut self, on: bool) -> Result<(), LinkError> {
        let state = self.query_status(Duration::from_secs(2))?.state;
        if (state == super::MachineState::Check) == on {
            return Ok(());
        }
        let reply = self.send("$C")?;
        super::reply_error("$C", reply)?;
        if !on {
            // Leaving check mode resets the controller; wait for its banner.
            let deadline = Instant::now() + Duration::from_secs(3);
            while Instant::now() < deadline {
                if let Some(Event::Reset { .. }) = self.poll(Duration::from_millis(50))? {
                    break;
                }
            }
            self.events.clear();
        }
        Ok(())
    }

    fn reapproach(&self, state: &ModalState, letters: &[char], position: &[f64]) -> Reapproach {
        crate::emit::reapproach::grbl_reapproach(state, letters, position)
    }

    fn continue_line(&self, state: &ModalState, line: &str) -> Continue {
        continuation(state, line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arcs_continue_with_their_motion_word() {
        let mut s = ModalState {
            motion: MotionMode::ArcCcw,
            ..ModalState::default()
        };
        assert_eq!(
            continuation(&s, "X30 Y0 I30 J0"),
            Continue::Replace("G3 X30 Y0 I30 J0".into())
        );
        assert_eq!(continuation(&s, "S300"), Continue::Pending);
        assert_eq!(continuation(&s, "G1 X3"), Continue::Settled);
        s.motion = MotionMode::Linear;
        assert_eq!(continuation(&s, "X3"), Continue::Settled);
    }
}
