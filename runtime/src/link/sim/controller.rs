//! The simulated controller's firmware: GRBL 1.1's protocol loop, planner buffer and motion
//! execution on a simulated clock, without any IO. Bytes come in one at a time through
//! [`Controller::receive`] (real-time commands are picked out on arrival, the rest go to a
//! bounded RX buffer), time passes through [`Controller::run`], answers go out through
//! [`Controller::take_output`].
//!
//! As in GRBL: a line is read from the RX buffer as soon as the protocol loop is free; its
//! `ok` is sent once its motion is in the planner (which holds `planner_blocks` blocks, arcs
//! split into chords by `$12`), so a full planner holds the answer back; spindle and coolant
//! changes, dwells and program ends first wait for the planner to empty. Moves run at their
//! feed (clamped by `$110`–`$112`, scaled by the overrides); acceleration is not modelled
//! in time. Soft limits (`$20=1`, the machine file's travel) raise ALARM:2; a soft reset
//! while moving raises ALARM:3. In laser mode (`$32=1`) the laser fires on G1/G2/G3 moves
//! with M3/M4 and S > 0, stays on at rest with M3 in G1/G2/G3, and is off during a hold.
//!
//! Everything observable is recorded in a [`Recording`]: each line received with its result
//! and effect, each executed block with its laser power, laser switching, overflows.
//!
//! The firmware is GRBL 1.1 (X, Y, Z) or, for a machine with axes beyond X, Y, Z, a grblHAL
//! build with up to six (X Y Z A B C, rotary axes in degrees): the same protocol, with more
//! axis words, position fields and axis settings (`$110`–`$115`, …), its own banner, and the
//! axis count in `$I`'s `[OPT:…]`, as grblHAL reports it.

use super::gcode::{self, Gc, Step};
use crate::link::grbl::codes::realtime_of;
use crate::link::{
    AXIS_LETTERS, AxisPos, MAX_AXES, MotionMode, OverrideStep, Plane, Realtime, Spindle,
};
use crate::machine::Machine;
use std::collections::{BTreeMap, VecDeque};

/// GRBL's version string.
pub const BANNER: &str = "Grbl 1.1h ['$' for help]";

/// grblHAL's version string.
pub const BANNER_HAL: &str = "GrblHAL 1.1f ['$' or '$HELP' for help]";

/// The firmware the simulator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// GRBL 1.1: X, Y, Z.
    Grbl,
    /// grblHAL with `axes` axes (4 to 6): X Y Z A B C, the first `axes` of them.
    GrblHal { axes: usize },
}

impl Firmware {
    /// The firmware a machine file needs: GRBL when its axes are X, Y, Z, else grblHAL with as
    /// many axes as its highest letter (a machine with C has all six).
    pub fn for_machine(machine: &Machine) -> Firmware {
        match crate::link::controller_axes(machine) {
            3 => Firmware::Grbl,
            axes => Firmware::GrblHal { axes },
        }
    }

    pub fn axes(self) -> usize {
        match self {
            Firmware::Grbl => 3,
            Firmware::GrblHal { axes } => axes.clamp(3, MAX_AXES),
        }
    }

    /// The line buffer with its terminating zero (the simulator counts the characters it
    /// keeps, as GRBL does).
    pub fn line_buffer(self) -> usize {
        match self {
            Firmware::Grbl => crate::link::grbl::LINE_BUFFER,
            Firmware::GrblHal { .. } => crate::link::grbl::LINE_BUFFER_HAL,
        }
    }

    pub fn banner(self) -> &'static str {
        match self {
            Firmware::Grbl => BANNER,
            Firmware::GrblHal { .. } => BANNER_HAL,
        }
    }
}

/// A line the controller received, with what became of it.
#[derive(Debug, Clone, PartialEq)]
pub struct LineRecord {
    /// 1-based count of lines received since power-up.
    pub seq: u64,
    /// Which connection delivered its line end (1 = the first).
    pub connection: u32,
    /// As received, without the line end.
    pub text: String,
    pub result: LineResult,
    /// What the line did, for G-code lines that were accepted.
    pub effect: Option<Effect>,
}

#[derive(Debug, Clone, PartialEq)]
pub enum LineResult {
    Ok,
    Error(u32),
    Alarm(u32),
    /// A `$` system command.
    System,
}

/// What an accepted G-code line did: modal changes (other than the motion mode), motion,
/// dwell, program flow. Two lines with equal effects did the same thing.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Effect {
    pub changes: Vec<String>,
    pub motion: Option<MotionEffect>,
    pub dwell_s: Option<f64>,
    pub flow: Option<&'static str>,
}

impl Effect {
    /// The line changed nothing (comments, repeated modal words, zero-length moves).
    pub fn is_noop(&self) -> bool {
        self.changes.is_empty()
            && self.motion.is_none()
            && self.dwell_s.is_none()
            && self.flow.is_none()
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct MotionEffect {
    pub mode: MotionMode,
    pub target: AxisPos,
    pub center: Option<AxisPos>,
    pub laser_s: f64,
    /// The move's own time in inverse-time mode (G93's F is the block's, not modal state).
    pub inverse_time_s: Option<f64>,
}

/// A block the machine finished moving.
#[derive(Debug, Clone, PartialEq)]
pub struct ExecutedBlock {
    /// The line (`LineRecord::seq`) it came from.
    pub seq: u64,
    pub from: AxisPos,
    pub to: AxisPos,
    pub rapid: bool,
    /// Laser power (S) during the move, 0 when dark.
    pub laser_s: f64,
    /// Simulated time at its end, s.
    pub t_end: f64,
    /// How long it moved, s (at the feed, or its share of a G93 block's time).
    pub duration: f64,
}

/// The laser output changed.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserEvent {
    pub t: f64,
    pub power_s: f64,
    pub pos: AxisPos,
}

/// What the simulated controller did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    pub lines: Vec<LineRecord>,
    pub blocks: Vec<ExecutedBlock>,
    pub laser: Vec<LaserEvent>,
    /// Dwells run: line, seconds.
    pub dwells: Vec<(u64, f64)>,
    /// Bytes that arrived with the RX buffer full: a client flow-control bug.
    pub rx_overflows: u64,
    pub overflow_log: Vec<String>,
    pub alarms: Vec<u32>,
    pub resets: u32,
    pub holds: u32,
    pub connections: u32,
    pub max_rx_fill: usize,
    pub max_planner_fill: usize,
    pub bytes_received: u64,
}

/// How the controller is built and configured.
#[derive(Debug, Clone)]
pub struct ControllerConfig {
    /// Serial RX buffer size (GRBL: 128, of which 127 usable).
    pub rx_buffer: usize,
    /// Planner blocks (GRBL on an Uno: 15 usable).
    pub planner_blocks: usize,
    pub firmware: Firmware,
    /// Travel per axis X Y Z A B C, mm or degrees; `None` for an axis the machine lacks (it
    /// cannot move).
    pub travel: [Option<(f64, f64)>; MAX_AXES],
    pub settings: BTreeMap<u32, f64>,
    /// Answer `error:CODE` to line `K` (1-based count of lines received) instead of running it.
    pub error_at_line: Vec<(u64, u32)>,
}

impl ControllerConfig {
    /// A machine's controller: its firmware, travel and settings.
    pub fn for_machine(machine: &Machine) -> ControllerConfig {
        ControllerConfig {
            rx_buffer: 128,
            planner_blocks: 15,
            firmware: Firmware::for_machine(machine),
            travel: travel_for(machine),
            settings: settings_for(machine),
            error_at_line: Vec::new(),
        }
    }

    /// Where the machine is after power-up or homing: the origin, clamped into the travel.
    pub fn home(&self) -> AxisPos {
        std::array::from_fn(|k| self.travel[k].map_or(0.0, |(lo, hi)| 0.0f64.clamp(lo, hi)))
    }
}

/// GRBL settings matching a machine file: rates and accelerations from each axis's limits
/// (in mm or degrees), travel, laser mode, S of full power from the post of its firmware.
pub fn settings_for(machine: &Machine) -> BTreeMap<u32, f64> {
    let mut s: BTreeMap<u32, f64> = [
        (0, 10.0),
        (1, 25.0),
        (2, 0.0),
        (3, 0.0),
        (4, 0.0),
        (5, 0.0),
        (6, 0.0),
        (10, 3.0),
        (11, machine.junction_deviation_mm),
        (12, machine.arc_tolerance_mm.max(0.001)),
        (13, 0.0),
        (20, 1.0),
        (21, 0.0),
        (22, 1.0),
        (23, 0.0),
        (24, 25.0),
        (25, 500.0),
        (26, 250.0),
        (27, 1.0),
        (30, 1000.0),
        (31, 0.0),
        (32, 1.0),
    ]
    .into_iter()
    .collect();
    let firmware = Firmware::for_machine(machine);
    if let Some((_, p)) = crate::link::live_dialect(machine).lookup(&machine.post) {
        s.insert(30, p.s_max);
    }
    for (k, letter) in AXIS_LETTERS[..firmware.axes()].iter().enumerate() {
        let k = k as u32;
        let axis = machine
            .axes
            .iter()
            .find(|a| a.name.eq_ignore_ascii_case(&letter.to_string()));
        let unit = axis.map_or(1.0, |a| crate::link::controller_scale(a.kind));
        s.insert(100 + k, 250.0);
        s.insert(110 + k, axis.map_or(500.0, |a| a.v_max * 60.0 * unit));
        s.insert(120 + k, axis.map_or(10.0, |a| a.a_max * unit));
        s.insert(130 + k, axis.map_or(0.0, |a| (a.max - a.min) * unit));
    }
    s
}

/// Travel per axis X Y Z A B C from a machine file, mm or degrees.
pub fn travel_for(machine: &Machine) -> [Option<(f64, f64)>; MAX_AXES] {
    std::array::from_fn(|k| {
        machine
            .axes
            .iter()
            .find(|a| a.name.eq_ignore_ascii_case(&AXIS_LETTERS[k].to_string()))
            .map(|a| {
                let unit = crate::link::controller_scale(a.kind);
                (a.min * unit, a.max * unit)
            })
    })
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum St {
    Idle,
    Cycle,
    Hold {
        complete: bool,
    },
    /// `critical`: a limit alarm, nothing but a reset is accepted.
    Alarm {
        critical: bool,
    },
    Check,
    Jog,
    Sleep,
}

#[derive(Debug, Clone)]
struct PBlock {
    seq: u64,
    from: AxisPos,
    to: AxisPos,
    duration: f64,
    feed_mm_min: f64,
    laser_s: f64,
    rapid: bool,
    /// Laser power at rest once this block ends (M3 in G1 keeps the beam on).
    rest_after: f64,
}

#[derive(Debug, Clone)]
enum Work {
    Sync,
    LaserAtRest(f64),
    Coolant(bool, bool),
    Dwell { left: f64, total: f64 },
    Blocks(VecDeque<PBlock>),
    ProgramEnd,
    Pause,
}

#[derive(Debug, Clone)]
struct Pending {
    seq: u64,
    work: VecDeque<Work>,
}

/// The simulated GRBL controller.
#[derive(Debug, Clone)]
pub struct Controller {
    cfg: ControllerConfig,
    settings: BTreeMap<u32, f64>,
    rx: VecDeque<u8>,
    /// The connection each byte in `rx` came from.
    rx_conn: VecDeque<u32>,
    line_conn: u32,
    line: Vec<u8>,
    raw: Vec<u8>,
    in_paren: bool,
    in_semicolon: bool,
    overflow: bool,
    pending: Option<Pending>,
    gc: Gc,
    planner: VecDeque<PBlock>,
    exec_t: f64,
    mpos: AxisPos,
    state: St,
    now: f64,
    out: Vec<u8>,
    status_request: bool,
    reports: u64,
    rest_laser: f64,
    last_laser: f64,
    overrides: [u32; 3],
    seq: u64,
    connection: u32,
    rec: Recording,
    /// Lines answered so far.
    pub lines_completed: u64,
    reset_after_reply: bool,
}

impl Controller {
    pub fn new(cfg: ControllerConfig) -> Controller {
        let settings = cfg.settings.clone();
        // The simulator starts homed at the origin (clamped into the travel).
        let mpos = cfg.home();
        let axes = cfg.firmware.axes();
        Controller {
            cfg,
            settings,
            rx: VecDeque::new(),
            rx_conn: VecDeque::new(),
            line_conn: 0,
            line: Vec::new(),
            raw: Vec::new(),
            in_paren: false,
            in_semicolon: false,
            overflow: false,
            pending: None,
            gc: Gc::new(mpos, axes),
            planner: VecDeque::new(),
            exec_t: 0.0,
            mpos,
            state: St::Idle,
            now: 0.0,
            out: Vec::new(),
            status_request: false,
            reports: 0,
            rest_laser: 0.0,
            last_laser: 0.0,
            overrides: [100, 100, 100],
            seq: 0,
            connection: 0,
            rec: Recording::default(),
            lines_completed: 0,
            reset_after_reply: false,
        }
    }

    pub fn recording(&self) -> &Recording {
        &self.rec
    }

    /// Simulated time, s.
    pub fn now(&self) -> f64 {
        self.now
    }

    /// Position now, mm (degrees for rotary axes).
    pub fn position(&self) -> AxisPos {
        match (self.state, self.planner.front()) {
            (_, Some(b)) if b.duration > 0.0 => {
                let f = (self.exec_t / b.duration).clamp(0.0, 1.0);
                std::array::from_fn(|i| b.from[i] + f * (b.to[i] - b.from[i]))
            }
            _ => self.mpos,
        }
    }

    /// Lines received so far (complete lines, any kind).
    pub fn lines_received(&self) -> u64 {
        self.seq
    }

    /// Idle with nothing buffered or running.
    pub fn is_quiet(&self) -> bool {
        self.planner.is_empty()
            && self.pending.is_none()
            && self.rx.is_empty()
            && !matches!(self.state, St::Cycle | St::Jog)
    }

    /// A client connected: GRBL's welcome, as network controllers greet each connection.
    pub fn connected(&mut self) {
        self.connection += 1;
        self.rec.connections += 1;
        self.say(self.cfg.firmware.banner());
        if matches!(self.state, St::Alarm { .. }) {
            self.say("[MSG:'$H'|'$X' to unlock]");
        }
    }

    /// What the controller sent since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    fn say(&mut self, s: &str) {
        self.out.extend_from_slice(s.as_bytes());
        self.out.extend_from_slice(b"\r\n");
    }

    fn setting(&self, id: u32) -> f64 {
        self.settings.get(&id).copied().unwrap_or(0.0)
    }

    fn laser_mode(&self) -> bool {
        self.setting(32) == 1.0
    }

    /// A byte arrives from the host.
    pub fn receive(&mut self, b: u8) {
        self.rec.bytes_received += 1;
        if let Some(rt) = realtime_of(b) {
            self.realtime(rt);
            return;
        }
        if b >= 0x80 {
            return;
        }
        // The ring buffer keeps one slot free.
        if self.rx.len() >= self.cfg.rx_buffer.saturating_sub(1) {
            self.rec.rx_overflows += 1;
            if self.rec.overflow_log.len() < 20 {
                self.rec.overflow_log.push(format!(
                    "RX buffer overflow at t = {:.6} s: byte {:?} arrived with {} of {} bytes in use (line {})",
                    self.now,
                    b as char,
                    self.rx.len(),
                    self.cfg.rx_buffer,
                    self.seq + 1
                ));
            }
            return;
        }
        self.rx.push_back(b);
        self.rx_conn.push_back(self.connection);
        self.rec.max_rx_fill = self.rec.max_rx_fill.max(self.rx.len());
    }

    fn realtime(&mut self, rt: Realtime) {
        match rt {
            Realtime::StatusQuery => {
                if self.state != (St::Alarm { critical: true }) {
                    self.status_request = true;
                }
            }
            Realtime::FeedHold | Realtime::SafetyDoor => match self.state {
                St::Cycle => {
                    self.state = St::Hold { complete: false };
                    self.rec.holds += 1;
                }
                St::Idle => {
                    self.state = St::Hold { complete: true };
                    self.rec.holds += 1;
                }
                St::Jog => self.jog_cancel(),
                _ => {}
            },
            Realtime::CycleStart => {
                if let St::Hold { .. } = self.state {
                    self.state = if self.planner.is_empty() {
                        St::Idle
                    } else {
                        St::Cycle
                    };
                }
            }
            Realtime::SoftReset => self.reset(),
            Realtime::JogCancel => {
                if self.state == St::Jog {
                    self.jog_cancel();
                }
            }
            Realtime::Feed(s) => self.overrides[0] = step_override(self.overrides[0], s, 10, 200),
            Realtime::Rapid(p) => self.overrides[1] = u32::from(p),
            Realtime::Spindle(s) => {
                self.overrides[2] = step_override(self.overrides[2], s, 10, 200)
            }
            Realtime::SpindleStop => {}
            Realtime::FloodToggle => self.gc.modal.flood = !self.gc.modal.flood,
            Realtime::MistToggle => self.gc.modal.mist = !self.gc.modal.mist,
        }
        self.note_laser();
    }

    fn jog_cancel(&mut self) {
        self.mpos = self.position();
        self.planner.clear();
        self.exec_t = 0.0;
        self.gc.pos = self.mpos;
        self.state = St::Idle;
    }

    /// Soft reset (Ctrl-X): buffers emptied, parser state to defaults, laser off; position
    /// kept unless the machine was moving (ALARM:3).
    pub fn reset(&mut self) {
        let moving = matches!(
            self.state,
            St::Cycle | St::Hold { complete: false } | St::Jog
        ) && !self.planner.is_empty();
        self.mpos = self.position();
        self.rx.clear();
        self.rx_conn.clear();
        self.line.clear();
        self.raw.clear();
        self.in_paren = false;
        self.in_semicolon = false;
        self.overflow = false;
        self.pending = None;
        self.planner.clear();
        self.exec_t = 0.0;
        self.gc = Gc::new(self.mpos, self.cfg.firmware.axes());
        self.rest_laser = 0.0;
        self.overrides = [100, 100, 100];
        self.status_request = false;
        self.rec.resets += 1;
        if moving {
            self.say("ALARM:3");
            self.rec.alarms.push(3);
        }
        let alarm = moving || matches!(self.state, St::Alarm { .. } | St::Sleep);
        self.state = if alarm {
            St::Alarm { critical: false }
        } else {
            St::Idle
        };
        self.say(self.cfg.firmware.banner());
        if alarm {
            self.say("[MSG:'$H'|'$X' to unlock]");
        }
        self.reports = 0;
        self.note_laser();
    }

    /// Lets `dt` seconds of simulated time pass (`f64::INFINITY`: until nothing is left to
    /// do), running the protocol loop between events.
    pub fn run(&mut self, mut dt: f64) {
        for _ in 0..10_000_000 {
            self.service();
            if self.state == St::Cycle && self.planner.is_empty() {
                self.state = St::Idle;
            }
            if self.state == (St::Hold { complete: false }) {
                // Deceleration is not modelled: the hold completes at once.
                self.mpos = self.position();
                self.state = St::Hold { complete: true };
            }
            self.note_laser();
            let te = self.time_to_event();
            if te > dt || te.is_infinite() {
                if dt.is_finite() && dt > 0.0 {
                    self.elapse(dt);
                }
                break;
            }
            self.elapse(te);
            dt -= te;
        }
        self.service();
        if self.state == St::Cycle && self.planner.is_empty() {
            self.state = St::Idle;
        }
        self.note_laser();
        if self.status_request {
            self.status_request = false;
            let r = self.status_report();
            self.say(&r);
        }
    }

    fn time_to_event(&self) -> f64 {
        match self.state {
            St::Cycle | St::Jog => match self.planner.front() {
                Some(b) => (b.duration - self.exec_t).max(0.0),
                None => f64::INFINITY,
            },
            St::Idle => match self.pending.as_ref().and_then(|p| p.work.front()) {
                Some(Work::Dwell { left, .. }) if self.planner.is_empty() => left.max(0.0),
                _ => f64::INFINITY,
            },
            _ => f64::INFINITY,
        }
    }

    fn elapse(&mut self, dt: f64) {
        self.now += dt;
        match self.state {
            St::Cycle | St::Jog => {
                let Some(b) = self.planner.front() else {
                    return;
                };
                self.exec_t += dt;
                if self.exec_t >= b.duration - 1e-12 {
                    let b = self.planner.pop_front().unwrap_or_else(|| unreachable!());
                    self.exec_t = 0.0;
                    self.mpos = b.to;
                    self.rest_laser = b.rest_after;
                    if self.state == St::Jog {
                        self.gc.pos = self.mpos;
                    } else {
                        self.rec.blocks.push(ExecutedBlock {
                            seq: b.seq,
                            from: b.from,
                            to: b.to,
                            rapid: b.rapid,
                            laser_s: b.laser_s,
                            t_end: self.now,
                            duration: b.duration,
                        });
                    }
                    if self.planner.is_empty() {
                        self.state = St::Idle;
                    }
                }
            }
            St::Idle => {
                if let Some(Work::Dwell { left, .. }) =
                    self.pending.as_mut().and_then(|p| p.work.front_mut())
                {
                    *left -= dt;
                }
            }
            _ => {}
        }
        self.note_laser();
    }

    fn laser_now(&self) -> f64 {
        match self.state {
            St::Hold { .. } | St::Alarm { .. } | St::Sleep | St::Check => 0.0,
            St::Cycle => self.planner.front().map_or(self.rest_laser, |b| b.laser_s),
            St::Jog => 0.0,
            St::Idle => self.rest_laser,
        }
    }

    fn note_laser(&mut self) {
        let p = self.laser_now();
        if p != self.last_laser {
            self.last_laser = p;
            let pos = self.position();
            self.rec.laser.push(LaserEvent {
                t: self.now,
                power_s: p,
                pos,
            });
        }
    }

    /// GRBL's protocol loop: finish the line in progress, then read more.
    fn service(&mut self) {
        loop {
            if matches!(self.state, St::Alarm { critical: true } | St::Sleep) {
                return;
            }
            if self.pending.is_some() && !self.progress_pending() {
                return;
            }
            let Some(c) = self.rx.pop_front() else {
                return;
            };
            self.line_conn = self.rx_conn.pop_front().unwrap_or(self.connection);
            self.protocol_char(c);
        }
    }

    fn protocol_char(&mut self, c: u8) {
        if c == b'\n' || c == b'\r' {
            self.end_line();
            return;
        }
        if self.raw.len() < 256 {
            self.raw.push(c);
        }
        if self.in_paren {
            if c == b')' {
                self.in_paren = false;
            }
        } else if self.in_semicolon || self.overflow {
        } else if c <= b' ' || c == b'/' {
            // Whitespace and control characters are dropped; block delete is not supported.
        } else if c == b'(' {
            self.in_paren = true;
        } else if c == b';' {
            self.in_semicolon = true;
        } else if self.line.len() >= self.cfg.firmware.line_buffer() - 1 {
            self.overflow = true;
        } else {
            self.line.push(c.to_ascii_uppercase());
        }
    }

    fn record(&mut self, seq: u64, text: String, result: LineResult, effect: Option<Effect>) {
        self.rec.lines.push(LineRecord {
            seq,
            connection: self.line_conn,
            text,
            result,
            effect,
        });
    }

    fn reply(&mut self, result: Result<(), u32>) {
        match result {
            Ok(()) => self.say("ok"),
            Err(code) => {
                let s = format!("error:{code}");
                self.say(&s);
            }
        }
        self.lines_completed += 1;
    }

    fn end_line(&mut self) {
        self.seq += 1;
        let seq = self.seq;
        let text = String::from_utf8_lossy(&self.raw).into_owned();
        let line = std::mem::take(&mut self.line);
        let overflow = self.overflow;
        self.raw.clear();
        self.in_paren = false;
        self.in_semicolon = false;
        self.overflow = false;
        if let Some(&(_, code)) = self.cfg.error_at_line.iter().find(|(k, _)| *k == seq) {
            self.record(seq, text, LineResult::Error(code), None);
            self.reply(Err(code));
            return;
        }
        if overflow {
            self.record(seq, text, LineResult::Error(11), None);
            self.reply(Err(11));
        } else if line.is_empty() {
            self.record(seq, text, LineResult::Ok, Some(Effect::default()));
            self.reply(Ok(()));
        } else if line[0] == b'$' {
            self.record(seq, text, LineResult::System, None);
            let r = self.system(&line);
            self.reply(r);
            if std::mem::take(&mut self.reset_after_reply) {
                self.reset();
            }
        } else if matches!(self.state, St::Alarm { .. } | St::Jog) {
            self.record(seq, text, LineResult::Error(9), None);
            self.reply(Err(9));
        } else {
            self.gcode(seq, text, &line);
        }
    }

    fn chords(&self, seq: u64, mv: &gcode::Move, rest_after: f64) -> VecDeque<PBlock> {
        let mut points = Vec::new();
        if let Some(arc) = mv.arc {
            let (a0, a1) = match arc.plane {
                Plane::Xy => (0, 1),
                Plane::Zx => (2, 0),
                Plane::Yz => (1, 2),
            };
            let c = arc.center;
            let r0 = [mv.from[a0] - c[a0], mv.from[a1] - c[a1]];
            let r1 = [mv.target[a0] - c[a0], mv.target[a1] - c[a1]];
            let others: Vec<usize> = (0..MAX_AXES).filter(|&k| k != a0 && k != a1).collect();
            let radius = r0[0].hypot(r0[1]);
            // GRBL's mc_arc: the angular travel, a full circle when start and end coincide.
            let mut ang = (r0[0] * r1[1] - r0[1] * r1[0]).atan2(r0[0] * r1[0] + r0[1] * r1[1]);
            let tol = self.setting(12).max(1e-6);
            if arc.ccw {
                if ang <= 1e-6 {
                    ang += std::f64::consts::TAU;
                }
            } else if ang >= -1e-6 {
                ang -= std::f64::consts::TAU;
            }
            let seg_len = (tol * (2.0 * radius - tol)).max(1e-12).sqrt();
            let n = ((0.5 * ang.abs() * radius / seg_len).floor() as usize).clamp(1, 100_000);
            let a_start = r0[1].atan2(r0[0]);
            for i in 1..n {
                let f = i as f64 / n as f64;
                let a = a_start + ang * f;
                let mut p = [0.0; MAX_AXES];
                p[a0] = c[a0] + radius * a.cos();
                p[a1] = c[a1] + radius * a.sin();
                // The other axes move linearly (a helix along the plane's normal).
                for &k in &others {
                    p[k] = mv.from[k] + (mv.target[k] - mv.from[k]) * f;
                }
                points.push(p);
            }
        }
        points.push(mv.target);
        let total_len: f64 = {
            let mut prev = mv.from;
            points
                .iter()
                .map(|p| {
                    let d = dist(prev, *p);
                    prev = *p;
                    d
                })
                .sum()
        };
        let mut out = VecDeque::new();
        let mut prev = mv.from;
        for p in points {
            let len = dist(prev, p);
            if len <= 1e-9 {
                prev = p;
                continue;
            }
            let dir: AxisPos = std::array::from_fn(|i| (p[i] - prev[i]).abs() / len);
            // The fastest the axes allow along this direction, mm/min (degrees count as mm,
            // as grblHAL counts them).
            let axis_cap = (0..self.cfg.firmware.axes())
                .filter(|&i| dir[i] > 1e-12)
                .map(|i| self.setting(110 + i as u32) / dir[i])
                .fold(f64::INFINITY, f64::min);
            let (rate, duration) = match mv.inverse_time_s {
                Some(t) if total_len > 0.0 => {
                    let d = t * len / total_len;
                    (len / d * 60.0, d)
                }
                _ => {
                    let rate = if mv.rapid {
                        axis_cap * f64::from(self.overrides[1]) / 100.0
                    } else {
                        mv.feed_mm_min.min(axis_cap) * f64::from(self.overrides[0]) / 100.0
                    };
                    let rate = if rate.is_finite() && rate > 0.0 {
                        rate
                    } else {
                        1000.0
                    };
                    (rate, len / (rate / 60.0))
                }
            };
            out.push_back(PBlock {
                seq,
                from: prev,
                to: p,
                duration,
                feed_mm_min: rate,
                laser_s: mv.laser_s,
                rapid: mv.rapid,
                rest_after,
            });
            prev = p;
        }
        out
    }

    fn outside_travel(&self, p: AxisPos) -> bool {
        if self.setting(20) != 1.0 {
            return false;
        }
        (0..MAX_AXES).any(|k| match self.cfg.travel[k] {
            Some((lo, hi)) => p[k] < lo - 1e-6 || p[k] > hi + 1e-6,
            None => p[k].abs() > 1e-6,
        })
    }

    fn gcode(&mut self, seq: u64, text: String, line: &[u8]) {
        let laser_mode = self.laser_mode();
        let block = match gcode::execute(line, &self.gc, laser_mode) {
            Ok(b) => b,
            Err(code) => {
                self.record(seq, text, LineResult::Error(code), None);
                self.reply(Err(code));
                return;
            }
        };
        let rest_after = gcode::rest_power(&block.next.modal, laser_mode);
        let mut work = VecDeque::new();
        let mut effect = effect_of(&self.gc, &block.next);
        for step in &block.steps {
            work.push_back(match step {
                Step::Sync => Work::Sync,
                Step::LaserAtRest(s) => Work::LaserAtRest(*s),
                Step::Coolant { flood, mist } => Work::Coolant(*flood, *mist),
                Step::Dwell(t) => {
                    effect.dwell_s = Some(*t);
                    Work::Dwell {
                        left: *t,
                        total: *t,
                    }
                }
                Step::Move(mv) => {
                    let chords = self.chords(seq, mv, rest_after);
                    if chords.iter().any(|b| self.outside_travel(b.to)) {
                        self.record(seq, text, LineResult::Alarm(2), None);
                        self.soft_limit();
                        return;
                    }
                    if !chords.is_empty() || mv.arc.is_some() {
                        effect.motion = Some(MotionEffect {
                            mode: block.next.modal.motion,
                            target: mv.target,
                            center: mv.arc.map(|a| a.center),
                            laser_s: mv.laser_s,
                            inverse_time_s: mv.inverse_time_s,
                        });
                    }
                    Work::Blocks(chords)
                }
                Step::ProgramEnd => {
                    effect.flow = Some("end");
                    Work::ProgramEnd
                }
                Step::Pause => {
                    effect.flow = Some("pause");
                    Work::Pause
                }
            });
        }
        self.gc = block.next;
        self.record(seq, text, LineResult::Ok, Some(effect));
        if self.state == St::Check {
            self.reply(Ok(()));
            return;
        }
        self.pending = Some(Pending { seq, work });
        self.progress_pending();
    }

    fn soft_limit(&mut self) {
        self.mpos = self.position();
        self.planner.clear();
        self.exec_t = 0.0;
        self.pending = None;
        self.rest_laser = 0.0;
        self.say("ALARM:2");
        self.say("[MSG:Reset to continue]");
        self.rec.alarms.push(2);
        self.state = St::Alarm { critical: true };
        self.note_laser();
    }

    /// Moves the line in progress along; `true` once it is answered.
    fn progress_pending(&mut self) -> bool {
        let Some(mut p) = self.pending.take() else {
            return true;
        };
        while let Some(w) = p.work.front_mut() {
            match w {
                Work::Sync => {
                    if !self.planner.is_empty() || matches!(self.state, St::Hold { .. }) {
                        self.pending = Some(p);
                        return false;
                    }
                    p.work.pop_front();
                }
                Work::LaserAtRest(s) => {
                    self.rest_laser = *s;
                    p.work.pop_front();
                    self.note_laser();
                }
                Work::Coolant(f, m) => {
                    let _ = (f, m);
                    p.work.pop_front();
                }
                Work::Dwell { left, total } => {
                    if *left > 0.0 {
                        self.pending = Some(p);
                        return false;
                    }
                    self.rec.dwells.push((p.seq, *total));
                    p.work.pop_front();
                }
                Work::Blocks(q) => {
                    while self.planner.len() < self.cfg.planner_blocks {
                        let Some(b) = q.pop_front() else { break };
                        self.planner.push_back(b);
                        if self.state == St::Idle {
                            self.state = St::Cycle;
                        }
                    }
                    self.rec.max_planner_fill = self.rec.max_planner_fill.max(self.planner.len());
                    if !q.is_empty() {
                        self.pending = Some(p);
                        return false;
                    }
                    p.work.pop_front();
                }
                Work::ProgramEnd => {
                    self.say("[MSG:Pgm End]");
                    p.work.pop_front();
                }
                Work::Pause => {
                    self.state = St::Hold { complete: true };
                    p.work.pop_front();
                }
            }
        }
        self.reply(Ok(()));
        true
    }

    fn system(&mut self, line: &[u8]) -> Result<(), u32> {
        let cmd = std::str::from_utf8(&line[1..]).map_err(|_| 3u32)?;
        let busy = matches!(self.state, St::Cycle | St::Hold { .. } | St::Jog);
        match cmd {
            "" => {
                self.say("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]")
            }
            "$" => {
                if busy {
                    return Err(8);
                }
                let lines: Vec<String> = self
                    .settings
                    .iter()
                    .map(|(id, v)| {
                        if matches!(id, 11 | 12 | 24 | 25 | 27 | 100..=135) {
                            format!("${id}={v:.3}")
                        } else {
                            format!("${id}={}", *v as i64)
                        }
                    })
                    .collect();
                for l in lines {
                    self.say(&l);
                }
            }
            "G" => {
                let r = self.gc.report();
                self.say(&r);
            }
            "#" => {
                let zeros = vec!["0.000"; self.cfg.firmware.axes()].join(",");
                for name in [
                    "G54", "G55", "G56", "G57", "G58", "G59", "G28", "G30", "G92",
                ] {
                    self.say(&format!("[{name}:{zeros}]"));
                }
                self.say("[TLO:0.000]");
                self.say(&format!("[PRB:{zeros}:0]"));
            }
            "I" => {
                let opt = match self.cfg.firmware {
                    Firmware::Grbl => {
                        self.say("[VER:1.1h.20190825:lase sim]");
                        format!(
                            "[OPT:V,{},{}]",
                            self.cfg.planner_blocks + 1,
                            self.cfg.rx_buffer
                        )
                    }
                    // grblHAL adds the axis count to OPT.
                    Firmware::GrblHal { axes } => {
                        self.say("[VER:1.1f.20250101:lase sim]");
                        format!(
                            "[OPT:V,{},{},{axes}]",
                            self.cfg.planner_blocks + 1,
                            self.cfg.rx_buffer
                        )
                    }
                };
                self.say(&opt);
            }
            "N" => {
                self.say("$N0=");
                self.say("$N1=");
            }
            "C" => match self.state {
                St::Check => {
                    // Leaving check mode resets the controller, after the `ok`.
                    self.say("[MSG:Disabled]");
                    self.reset_after_reply = true;
                }
                St::Idle => {
                    self.state = St::Check;
                    self.say("[MSG:Enabled]");
                }
                _ => return Err(8),
            },
            "X" => {
                if let St::Alarm { .. } = self.state {
                    self.say("[MSG:Caution: Unlocked]");
                    self.state = St::Idle;
                }
            }
            "H" => {
                if self.setting(22) != 1.0 {
                    return Err(5);
                }
                if !matches!(self.state, St::Idle | St::Alarm { .. }) {
                    return Err(8);
                }
                self.mpos = self.cfg.home();
                self.gc.pos = self.mpos;
                self.state = St::Idle;
            }
            "SLP" => {
                self.say("[MSG:Sleeping]");
                self.state = St::Sleep;
            }
            _ if cmd.starts_with("J=") => return self.jog(&line[3..]),
            _ if cmd.starts_with("RST=") => {
                self.say("[MSG:Restoring defaults]");
                self.settings = self.cfg.settings.clone();
            }
            _ => {
                let (id, value) = cmd.split_once('=').ok_or(3u32)?;
                let id: u32 = id.parse().map_err(|_| 3u32)?;
                let value: f64 = value.parse().map_err(|_| 2u32)?;
                if busy {
                    return Err(8);
                }
                if !self.settings.contains_key(&id) {
                    return Err(3);
                }
                if value < 0.0 {
                    return Err(4);
                }
                self.settings.insert(id, value);
            }
        }
        Ok(())
    }

    fn jog(&mut self, body: &[u8]) -> Result<(), u32> {
        if !matches!(self.state, St::Idle | St::Jog) {
            return Err(8);
        }
        // Only G20/G21, G90/G91, G53, axis words and F.
        let mut i = 0;
        let mut has_f = false;
        while i < body.len() {
            let c = body[i];
            i += 1;
            let start = i;
            while i < body.len() && !body[i].is_ascii_uppercase() {
                i += 1;
            }
            let v: f64 = std::str::from_utf8(&body[start..i])
                .ok()
                .and_then(|s| s.parse().ok())
                .ok_or(2u32)?;
            match (c, v) {
                (b'G', g) if [20.0, 21.0, 90.0, 91.0, 53.0].contains(&g) => {}
                (c, _) if AXIS_LETTERS[..self.cfg.firmware.axes()].contains(&(c as char)) => {}
                (b'F', _) => has_f = true,
                _ => return Err(16),
            }
        }
        if !has_f {
            return Err(22);
        }
        let mut jog_gc = self.gc.clone();
        jog_gc.modal.motion = MotionMode::Linear;
        let mut text = b"G1".to_vec();
        text.extend_from_slice(body);
        let block = gcode::execute(&text, &jog_gc, false).map_err(|_| 16u32)?;
        for step in block.steps {
            if let Step::Move(mut mv) = step {
                if self.outside_travel(mv.target) {
                    return Err(15);
                }
                mv.laser_s = 0.0;
                let chords = self.chords(self.seq, &mv, self.rest_laser);
                self.planner.extend(chords);
                self.state = St::Jog;
                self.gc.pos = mv.target;
            }
        }
        Ok(())
    }

    fn status_report(&mut self) -> String {
        let state = match self.state {
            St::Idle => "Idle".to_string(),
            St::Cycle => "Run".into(),
            St::Hold { complete } => format!("Hold:{}", if complete { 0 } else { 1 }),
            St::Alarm { .. } => "Alarm".into(),
            St::Check => "Check".into(),
            St::Jog => "Jog".into(),
            St::Sleep => "Sleep".into(),
        };
        let p = self.position();
        let mask = self.setting(10) as u32;
        let n = self.cfg.firmware.axes();
        let pos: Vec<String> = p[..n].iter().map(|v| format!("{v:.3}")).collect();
        let mut s = format!(
            "<{state}|{}:{}",
            if mask & 1 == 1 { "MPos" } else { "WPos" },
            pos.join(",")
        );
        if mask & 2 == 2 {
            s.push_str(&format!(
                "|Bf:{},{}",
                self.cfg.planner_blocks - self.planner.len().min(self.cfg.planner_blocks),
                self.cfg.rx_buffer.saturating_sub(1) - self.rx.len()
            ));
        }
        let feed = match (self.state, self.planner.front()) {
            (St::Cycle | St::Jog, Some(b)) => b.feed_mm_min,
            _ => 0.0,
        };
        let spindle = if self.gc.modal.spindle == Spindle::Off {
            0.0
        } else {
            self.gc.modal.s
        };
        s.push_str(&format!("|FS:{:.0},{:.0}", feed, spindle));
        if self.reports.is_multiple_of(10) {
            s.push_str("|WCO:");
            s.push_str(&vec!["0.000"; n].join(","));
        } else if self.reports % 10 == 1 {
            let [f, r, sp] = self.overrides;
            s.push_str(&format!("|Ov:{f},{r},{sp}"));
            let mut a = String::new();
            match self.gc.modal.spindle {
                Spindle::Cw => a.push('S'),
                Spindle::Ccw => a.push('C'),
                Spindle::Off => {}
            }
            if self.gc.modal.flood {
                a.push('F');
            }
            if self.gc.modal.mist {
                a.push('M');
            }
            if !a.is_empty() {
                s.push_str(&format!("|A:{a}"));
            }
        }
        self.reports += 1;
        s.push('>');
        s
    }
}

fn step_override(v: u32, s: OverrideStep, min: u32, max: u32) -> u32 {
    let n = match s {
        OverrideStep::Reset => 100,
        OverrideStep::Plus10 => v + 10,
        OverrideStep::Minus10 => v.saturating_sub(10),
        OverrideStep::Plus1 => v + 1,
        OverrideStep::Minus1 => v.saturating_sub(1),
    };
    n.clamp(min, max)
}

fn dist(a: AxisPos, b: AxisPos) -> f64 {
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn effect_of(before: &Gc, after: &Gc) -> Effect {
    let (b, a) = (&before.modal, &after.modal);
    let mut changes = Vec::new();
    let mut diff = |name: &str, x: String, y: String| {
        if x != y {
            changes.push(format!("{name}={y}"));
        }
    };
    diff("units", format!("{}", b.inches), format!("{}", a.inches));
    diff(
        "incremental",
        format!("{}", b.incremental),
        format!("{}", a.incremental),
    );
    diff(
        "inverse_time",
        format!("{}", b.inverse_time),
        format!("{}", a.inverse_time),
    );
    diff("plane", format!("{:?}", b.plane), format!("{:?}", a.plane));
    diff(
        "spindle",
        format!("{:?}", b.spindle),
        format!("{:?}", a.spindle),
    );
    diff("flood", format!("{}", b.flood), format!("{}", a.flood));
    diff("mist", format!("{}", b.mist), format!("{}", a.mist));
    // In G93 the F word is the block's own (its move's time, in the motion effect).
    if !a.inverse_time {
        diff("F", format!("{}", b.feed), format!("{}", a.feed));
    }
    diff("S", format!("{}", b.s), format!("{}", a.s));
    Effect {
        changes,
        ..Effect::default()
    }
}
