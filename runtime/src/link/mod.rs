//! Controller links: where a job goes when lase drives a machine live.
//!
//! Architecture invariant: this is the only code that knows a controller protocol or a
//! socket. Layers, bottom up:
//!
//! - [`transport`]: bytes in and out, with a timed read (TCP, serial, an in-memory pipe to the
//!   in-process simulator).
//! - [`Link`]: one controller protocol over a transport: program lines under the protocol's
//!   flow control, their answers in order, real-time commands, status, settings, check mode
//!   and the lines that restore a modal state. [`grbl::GrblLink`] speaks GRBL 1.1 (and so
//!   drives grblHAL, its six-axis successor); a LinuxCNC
//!   or Marlin link is another implementation of the same trait.
//! - [`stream`]: a job over any `Link`, nothing lost and nothing repeated: a write-ahead
//!   [`journal`] on disk, the stop sequence on an error, and the resume logic that finds the
//!   last executed line from the controller's state ([`modal`] predicts it line by line).
//! - [`job`]: starting a job, the one safety sequence `lase run` and the REPL share:
//!   preflight (every line sendable, settings fit the plan, controller idle), then journal,
//!   resume point and send guards, then [`stream`].
//! - [`sim`]: a simulated GRBL 1.1 (or grblHAL) controller, a real implementation of the protocol that the
//!   tests talk to over real sockets, with fault injection and a record of what it executed.
//!
//! The path of one line: `emit` writes it (with its op index) → [`stream::Streamer`] journals
//! it as about to be sent → [`Link::send_line`] writes it when the controller's input buffer
//! has room → the controller's `ok` comes back through [`Link::poll`] as [`Event::Ack`] → the
//! journal records the acknowledgement. An `error:N` comes back as [`Event::Rejected`] for the
//! same line, and the caller maps the line to its op and the op to its recipe span.

pub mod estimate;
pub mod eta;
pub mod grbl;
pub mod job;
pub mod journal;
pub mod linuxcnc;
pub mod modal;
pub(crate) mod requirements;
pub(crate) mod resume;
pub mod settle;
pub mod sim;
pub mod stream;
pub mod transport;
mod url;

pub use crate::emit::modal::{ModalState, MotionMode, Plane, Spindle};
pub use crate::emit::reapproach::Reapproach;
pub use requirements::{AxisNeed, Requirements, SettingMismatch};
pub use url::{LinkUrl, SimUrlOptions};

use lase_lang::Span;
use std::time::Duration;

/// Most axes a GRBL-family controller has: grblHAL builds with up to six, reported and
/// addressed in this order (GRBL 1.1 has the first three).
pub const MAX_AXES: usize = 6;

/// The NC letters of those axes, in report order.
pub const AXIS_LETTERS: [char; MAX_AXES] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// A controller position: mm for X, Y, Z, degrees for rotary A, B, C; axes a controller
/// lacks stay 0. The neutral [`crate::axes::ControllerPos`], under the link's name.
pub type AxisPos = crate::axes::ControllerPos;

/// Where an axis letter is in a controller's position (`X` 0 … `C` 5).
pub fn axis_index(letter: char) -> Option<usize> {
    let l = letter.to_ascii_uppercase();
    AXIS_LETTERS.iter().position(|&c| c == l)
}

/// A machine axis's controller unit per internal unit: 1 for mm, degrees per radian for a
/// rotary axis (GRBL-family controllers take rotary positions, rates and accelerations in
/// degrees): the external units of [`crate::axes`].
pub fn controller_scale(kind: crate::machine::AxisKind) -> f64 {
    crate::axes::external_scale(kind)
}

/// How a machine's axes sit in a GRBL-family controller's position: by letter (X Y Z A B C),
/// rotary axes in degrees. An axis whose name is not one of those letters has no place (the
/// dialect check refuses such machines before anything is sent).
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerAxes {
    /// Per machine axis: its index in a controller position and its kind (for its unit).
    slots: Vec<Option<(usize, crate::machine::AxisKind)>>,
    letters: Vec<char>,
}

impl ControllerAxes {
    pub fn of(machine: &crate::machine::Machine) -> ControllerAxes {
        let letters: Vec<char> = machine
            .axes
            .iter()
            .map(|a| a.name.chars().next().unwrap_or('X').to_ascii_uppercase())
            .collect();
        let slots = machine
            .axes
            .iter()
            .zip(&letters)
            .map(|(a, &l)| {
                (a.name.chars().count() == 1)
                    .then(|| axis_index(l))
                    .flatten()
                    .map(|i| (i, a.kind))
            })
            .collect();
        ControllerAxes { slots, letters }
    }

    /// Each machine axis's NC letter, in the machine's order.
    pub fn letters(&self) -> &[char] {
        &self.letters
    }

    /// Machine axis positions (mm, rad) as a controller position (mm, degrees).
    pub fn to_controller(&self, q: &crate::axes::Axes) -> AxisPos {
        let mut p = [0.0; MAX_AXES];
        for (slot, v) in self.slots.iter().zip(q.iter()) {
            if let Some((i, kind)) = slot {
                p[*i] = crate::axes::to_external(*kind, *v);
            }
        }
        p
    }

    /// A controller position (mm, degrees; missing axes 0) as machine axis positions (mm,
    /// rad).
    pub fn from_controller(&self, p: &[f64]) -> crate::axes::Axes {
        let mut q = crate::axes::Axes::ZERO;
        for (k, slot) in self.slots.iter().enumerate().take(q.len()) {
            if let Some((i, kind)) = slot {
                q[k] = crate::axes::from_external(*kind, p.get(*i).copied().unwrap_or(0.0));
            }
        }
        q
    }
}

/// How many axes a GRBL-family controller needs for a machine: 3 (GRBL 1.1) when its axes
/// are linear X, Y, Z; else as many as its highest letter, at least 4 (a grblHAL build; a
/// machine with C needs all six). Axis names outside X Y Z A B C count as six: the dialect
/// check names them.
pub fn controller_axes(machine: &crate::machine::Machine) -> usize {
    let mut n = 3;
    for a in &machine.axes {
        let mut chars = a.name.chars();
        let k = match (chars.next().and_then(axis_index), chars.next()) {
            (Some(k), None) => k,
            _ => MAX_AXES - 1,
        };
        let rotary = a.kind == crate::machine::AxisKind::Rotary;
        if k >= 3 || rotary {
            n = n.max((k + 1).max(4));
        }
    }
    n
}

/// The NC dialect a job streamed to a machine takes: GRBL's when the machine's axes are X,
/// Y, Z, grblHAL's otherwise.
pub fn live_dialect(machine: &crate::machine::Machine) -> crate::emit::Dialect {
    if controller_axes(machine) > 3 {
        crate::emit::Dialect::GrblHal
    } else {
        crate::emit::Dialect::Grbl
    }
}

/// What a controller said about a line sent with [`Link::send`] (send-response).
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    Ok,
    /// The controller refused the line (GRBL's `error:N`), with its reason.
    Error {
        code: u32,
        message: String,
    },
}

/// The controller's run state, as GRBL 1.1 names them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MachineState {
    #[default]
    Idle,
    Run,
    /// Feed hold; `complete` once motion has stopped (GRBL `Hold:0`), else decelerating
    /// (`Hold:1`).
    Hold {
        complete: bool,
    },
    Jog,
    Alarm,
    /// Safety door with GRBL's sub-state (0 closed and ready … 3 resuming).
    Door(u8),
    Check,
    Home,
    Sleep,
}

impl MachineState {
    pub fn name(self) -> String {
        match self {
            MachineState::Idle => "Idle".into(),
            MachineState::Run => "Run".into(),
            MachineState::Hold { complete } => format!("Hold:{}", if complete { 0 } else { 1 }),
            MachineState::Jog => "Jog".into(),
            MachineState::Alarm => "Alarm".into(),
            MachineState::Door(n) => format!("Door:{n}"),
            MachineState::Check => "Check".into(),
            MachineState::Home => "Home".into(),
            MachineState::Sleep => "Sleep".into(),
        }
    }
}

/// Planner and input-buffer room a controller reports (GRBL `Bf:`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferState {
    pub planner_free: u32,
    pub rx_free: u32,
}

/// A real-time status report, every field GRBL 1.1 defines. Positions are in mm (lase requires
/// `$13=0`); `None` where the report left a field out.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Status {
    pub state: MachineState,
    pub mpos: Option<Vec<f64>>,
    pub wpos: Option<Vec<f64>>,
    /// Work coordinate offset: `WPos = MPos − WCO`.
    pub wco: Option<Vec<f64>>,
    pub buffer: Option<BufferState>,
    /// Line number being executed (`Ln:`, only with N words and a build that reports them).
    pub line: Option<u32>,
    /// Current feed, mm/min.
    pub feed: Option<f64>,
    /// Current spindle speed (laser S value).
    pub spindle: Option<f64>,
    /// Triggered input pins (`Pn:`), letters as reported.
    pub pins: Option<String>,
    /// Feed, rapid and spindle overrides, percent.
    pub overrides: Option<[u32; 3]>,
    /// Accessory state (`A:`): S, C, F, M.
    pub accessories: Option<String>,
}

impl Status {
    /// Work position, from `WPos` or from `MPos − WCO` with the last known offset.
    pub fn work_position(&self, last_wco: Option<&[f64]>) -> Option<Vec<f64>> {
        if let Some(w) = &self.wpos {
            return Some(w.clone());
        }
        let m = self.mpos.as_ref()?;
        let wco = self.wco.as_deref().or(last_wco);
        Some(
            m.iter()
                .enumerate()
                .map(|(i, v)| v - wco.and_then(|o| o.get(i)).copied().unwrap_or(0.0))
                .collect(),
        )
    }

    /// The work position as a controller position (axes it does not report are 0), from the
    /// report's own work offset: where a job starts, for its journal.
    pub fn work_axes(&self) -> AxisPos {
        let pos = self.work_position(self.wco.as_deref()).unwrap_or_default();
        std::array::from_fn(|i| pos.get(i).copied().unwrap_or(0.0))
    }

    /// One line for people: `Idle | X10 Y0 Z0`.
    pub fn summary(&self) -> String {
        self.summary_for(None, &[])
    }

    /// [`Status::summary`] with the last known work offset, showing only the axes `letters`
    /// names (a machine's own: `Idle | X158 C-360 B0` on a six-axis grblHAL), or every axis
    /// reported when `letters` is empty.
    pub fn summary_for(&self, last_wco: Option<&[f64]>, letters: &[char]) -> String {
        let pos = self.work_position(last_wco).unwrap_or_default();
        let word = |l: char, v: f64| format!("{l}{}", lase_lang::units::format_number(v));
        let words: Vec<String> = if letters.is_empty() {
            pos.iter()
                .zip(AXIS_LETTERS)
                .map(|(v, l)| word(l, *v))
                .collect()
        } else {
            letters
                .iter()
                .filter_map(|&l| {
                    let i = axis_index(l)?;
                    pos.get(i).map(|v| word(l.to_ascii_uppercase(), *v))
                })
                .collect()
        };
        format!("{} | {}", self.state.name(), words.join(" "))
    }
}

/// Something the controller said, in the order it said it.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    /// The oldest line in flight was accepted (GRBL `ok`).
    Ack,
    /// The oldest line in flight was refused and not executed (GRBL `error:N`).
    Rejected {
        code: u32,
        message: String,
    },
    /// The controller stopped everything (GRBL `ALARM:N`).
    Alarm {
        code: u32,
        message: String,
    },
    Status(Status),
    /// Feedback: `[MSG:…]` and other bracketed messages, settings lines, startup lines.
    Message(String),
    /// The controller (re)started: lines in flight are gone.
    Reset {
        banner: String,
    },
}

/// Real-time commands: single bytes that bypass the line buffer and act at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Realtime {
    StatusQuery,
    FeedHold,
    CycleStart,
    SoftReset,
    SafetyDoor,
    JogCancel,
    /// Feed override: reset to 100 %, ±10 %, ±1 %.
    Feed(OverrideStep),
    /// Rapid override: 100, 50 or 25 %.
    Rapid(u8),
    Spindle(OverrideStep),
    /// Toggles the spindle (laser) off and on again during a hold.
    SpindleStop,
    FloodToggle,
    MistToggle,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverrideStep {
    Reset,
    Plus10,
    Minus10,
    Plus1,
    Minus1,
}

/// A controller connection speaking one protocol.
///
/// Lines are answered in the order they were sent. A streaming caller checks
/// [`Link::can_send`], calls [`Link::send_line`] and collects answers with [`Link::poll`];
/// setup commands use [`Link::send`], which waits for the answer (send-response) and keeps
/// whatever else arrives meanwhile for the next `poll`.
pub trait Link: Send {
    /// `tcp://127.0.0.1:5000 (Grbl 1.1h)`.
    fn describe(&self) -> String;
    /// Whether a program line can go over this link as written (e.g. no GRBL real-time
    /// characters inside a comment). Checked for the whole job before anything is sent.
    fn validate_line(&self, line: &str) -> Result<(), String>;
    /// Whether `line` can be sent now without overrunning the controller's input buffer.
    fn can_send(&self, line: &str) -> bool;
    /// Sends one program line (without its newline).
    fn send_line(&mut self, line: &str) -> Result<(), LinkError>;
    /// Lines sent and not yet answered.
    fn in_flight(&self) -> usize;
    /// Bytes written to the controller so far (for link utilization).
    fn bytes_sent(&self) -> u64;
    /// The next thing the controller said, waiting at most `timeout`.
    fn poll(&mut self, timeout: Duration) -> Result<Option<Event>, LinkError>;
    /// Sends a real-time command.
    fn realtime(&mut self, cmd: Realtime) -> Result<(), LinkError>;
    /// Sends one line and waits for its answer. Only when no streamed line is in flight.
    fn send(&mut self, line: &str) -> Result<Reply, LinkError>;
    /// The last known state, one line for people, with the axes `letters` names (every axis
    /// the controller reports when empty).
    fn status(&self, letters: &[char]) -> String;
    /// The last status report received.
    fn last_status(&self) -> Option<&Status>;
    /// Asks for a status report and waits for it.
    fn query_status(&mut self, timeout: Duration) -> Result<Status, LinkError>;
    /// The interpreter's modal state (GRBL `$G`).
    fn modal_state(&mut self) -> Result<ModalState, LinkError>;
    /// Reads the controller's settings and compares them with what the job needs; one
    /// diagnostic per setting that would make the job run differently from its plan.
    fn check_settings(&mut self, needs: &Requirements) -> Result<Vec<SettingMismatch>, LinkError>;
    /// Check mode: the controller parses every line and moves nothing (GRBL `$C`).
    fn set_check_mode(&mut self, on: bool) -> Result<(), LinkError>;
    /// Lines that bring the controller, at rest, from any state to `state` at `position`
    /// (work coordinates, one value per machine axis letter): the safe re-approach of a
    /// resumed job.
    fn reapproach(&self, state: &ModalState, letters: &[char], position: &[f64]) -> Reapproach;
    /// How to send `line` after a re-approach that restored `state`: a GRBL controller cannot
    /// be put in G2/G3 without an arc, so the first modal arc line needs its motion word.
    fn continue_line(&self, state: &ModalState, line: &str) -> Continue;
    /// A jog of `dx`, `dy` mm relative to where the machine stands, at `feed` mm/min, that
    /// leaves the program's modal state alone (row-start settling); `None` when the
    /// controller has no such command.
    fn jog_line(&self, dx: f64, dy: f64, feed: f64) -> Option<String> {
        let _ = (dx, dy, feed);
        None
    }
    /// The work offset G`g` (54–59) as the controller holds it, X Y Z A B C as it reports
    /// them (mm, deg): machine = work + offset. `None` when the controller cannot say (GRBL
    /// answers `$#`; issue 20's named origins check the travel with it).
    fn work_offset(&mut self, g: u8) -> Result<Option<Vec<f64>>, LinkError> {
        let _ = g;
        Ok(None)
    }
}

/// How a line after a re-approach relates to the restored state (see [`Link::continue_line`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Continue {
    /// The line does not depend on the motion mode; later lines may.
    Pending,
    /// Send the line as written; no later line depends on the restored state.
    Settled,
    /// Send this text instead (the same block with an explicit motion word).
    Replace(String),
}

/// Link-level failures: transport, protocol, settings, journal and resume.
#[derive(Debug, Clone, thiserror::Error, miette::Diagnostic, PartialEq)]
pub enum LinkError {
    #[error("unsupported controller link `{url}`")]
    #[diagnostic(code(lase::link::unsupported))]
    Unsupported {
        url: String,
        #[help]
        help: Option<String>,
    },

    #[error("bad controller link `{url}`: {reason}")]
    #[diagnostic(
        code(lase::link::url),
        help(
            "links are `sim`, `sim://?time-scale=real`, `tcp://HOST:PORT`, `serial:///dev/ttyUSB0?baud=115200` or `linuxcnc://HOST:PORT`"
        )
    )]
    BadUrl { url: String, reason: String },

    #[error("cannot connect to {url}: {reason}")]
    #[diagnostic(code(lase::link::connect))]
    Connect {
        url: String,
        reason: String,
        #[help]
        help: Option<String>,
    },

    #[error("the link to the controller was lost: {reason}")]
    #[diagnostic(
        code(lase::link::lost),
        help(
            "the job journal knows what was sent and acknowledged: reconnect and continue with `lase run --resume JOURNAL`"
        )
    )]
    Lost { reason: String },

    #[error("the controller did not answer within {seconds} s while {waiting_for}")]
    #[diagnostic(
        code(lase::link::timeout),
        help("check the cable or network, the baud rate, and that the controller is powered")
    )]
    Timeout { waiting_for: String, seconds: f64 },

    #[error("the controller sent something lase does not understand: `{text}` ({reason})")]
    #[diagnostic(
        code(lase::link::protocol),
        help(
            "lase speaks GRBL 1.1; check the baud rate (garbage usually means a wrong one) and that the device is a GRBL 1.1 compatible controller (GRBL, grblHAL)"
        )
    )]
    Protocol { text: String, reason: String },

    #[error("line {line_no} cannot be sent over this link: {reason}")]
    #[diagnostic(code(lase::link::unsendable))]
    Unsendable {
        line_no: usize,
        line: String,
        reason: String,
        #[label("this statement produced the line")]
        span: Span,
        #[help]
        help: String,
    },

    #[error("{message}")]
    #[diagnostic(code(lase::link::unsettled))]
    Unsettled {
        message: String,
        #[label("row-start settling asked here")]
        span: lase_lang::Span,
        #[help]
        help: String,
    },

    #[error("the controller is not ready: {reason}")]
    #[diagnostic(code(lase::link::not_ready))]
    NotReady {
        reason: String,
        #[help]
        help: String,
    },

    #[error("job journal {path}: {reason}")]
    #[diagnostic(code(lase::link::journal))]
    Journal {
        path: String,
        reason: String,
        #[help]
        help: Option<String>,
    },

    #[error("cannot resume: {reason}")]
    #[diagnostic(code(lase::link::resume))]
    Resume {
        reason: String,
        #[help]
        help: String,
    },
}

/// A rejected setup command, as an error.
pub fn reply_error(line: &str, reply: Reply) -> Result<(), LinkError> {
    match reply {
        Reply::Ok => Ok(()),
        Reply::Error { code, message } => Err(LinkError::NotReady {
            reason: format!("`{line}` was refused: error {code}, {message}"),
            help: "check the controller's state (an alarm must be cleared with `$X` or homing)"
                .into(),
        }),
    }
}

/// Options of a connection, whatever the transport.
#[derive(Debug, Clone)]
pub struct ConnectOptions {
    /// The controller's serial input buffer, bytes; `None` (the default) counts against what
    /// the controller reports in `$I` (`[OPT:…,blocks,rx]`: GRBL 128, grblHAL 1024), and
    /// 128 if it does not say.
    pub rx_buffer: Option<usize>,
    /// Send-response instead of character counting: one line in flight at a time.
    pub send_response: bool,
    /// How long to wait for the controller to answer at all when connecting.
    pub connect_timeout: Duration,
    /// How long to wait, when connecting, for a controller to finish the lines an earlier
    /// connection sent it.
    pub busy_wait: Duration,
}

impl Default for ConnectOptions {
    fn default() -> Self {
        ConnectOptions {
            rx_buffer: None,
            send_response: false,
            connect_timeout: Duration::from_secs(5),
            busy_wait: Duration::from_secs(600),
        }
    }
}

/// Opens a link: connects the transport the URL names and greets the controller. `sim`
/// starts the simulated controller in this process for `machine`.
pub fn connect(
    url: &LinkUrl,
    machine: &crate::machine::Machine,
    options: &ConnectOptions,
) -> Result<Box<dyn Link>, LinkError> {
    let transport: Box<dyn transport::Transport> = match url {
        LinkUrl::Sim(o) => {
            let (_handle, t) =
                sim::spawn_in_process(machine, o.to_options()).map_err(|reason| {
                    LinkError::Connect {
                        url: url.to_string(),
                        reason,
                        help: None,
                    }
                })?;
            t
        }
        LinkUrl::Tcp { host, port } => Box::new(transport::TcpTransport::connect(host, *port)?),
        LinkUrl::Serial { path, baud } => Box::new(transport::SerialTransport::open(path, *baud)?),
        // LinuxCNC runs files, not streamed lines: `lase run` drives it through
        // `linuxcnc::job`; a line-by-line session (the REPL) would not blend.
        LinkUrl::LinuxCnc { .. } => {
            return Err(LinkError::Unsupported {
                url: url.to_string(),
                help: Some(
                    "LinuxCNC runs whole programs: use `lase run RECIPE --link linuxcnc://HOST:PORT` (line-by-line MDI does not blend)"
                        .into(),
                ),
            });
        }
    };
    let link = grbl::GrblLink::connect(transport, url.to_string(), options)?;
    Ok(Box::new(link))
}
