//! The simulated controller's firmware: GRBL 1.1's protocol loop, planner buffer and motion
//! execution on a simulated clock, without any IO. Bytes come in one at a time through
//! [`Controller::receive`] (real-time commands are picked out on arrival, the rest go to a
//! bounded RX buffer), time passes through [`Controller::run`], answers go out through
//! [`Controller::take_output`].
//!
//! As in GRBL: a line is read from the RX buffer as soon as the protocol loop is free; its
//! `ok` is sent once its motion is in the planner (which holds `planner_blocks` blocks, arcs
//! split into chords by `$12`), so a full planner holds the answer back; spindle and coolant
//! changes, dwells and program ends first wait for the planner to empty. Moves run as GRBL's
//! planner and stepper run them ([`super::motion`]: junction deviation, trapezoids at the
//! block's acceleration, look-ahead over the buffer; `exec`), a feed hold decelerates.
//! Soft limits (`$20=1`, the machine file's travel) raise ALARM:2; a soft reset
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
//!
//! This file holds the controller's state, the byte-level protocol loop, real-time commands,
//! reset and the simulated clock; `blocks` turns G-code lines into planner blocks, `exec`
//! moves the machine along them, `system`
//! answers `$` commands, jogs and status reports, `record` is what tests read, `config` the
//! firmware build and settings.

mod blocks;
mod config;
mod exec;
mod record;
mod system;

pub use config::{BANNER, BANNER_HAL, ControllerConfig, Firmware, settings_for, travel_for};
pub use record::{
    Effect, ExecutedBlock, LaserEvent, LineRecord, LineResult, MotionEffect, Recording,
};

use super::gcode::Gc;
use super::motion::{self, Planner};
use crate::link::grbl::codes::realtime_of;
use crate::link::{AxisPos, OverrideStep, Realtime};
use std::collections::{BTreeMap, VecDeque};

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
    /// The block as GRBL's planner holds it (what is left of it after a hold).
    b: motion::Block,
    /// Laser power at rest once this block ends (M3 in G1 keeps the beam on).
    rest_after: f64,
}

#[derive(Debug, Clone)]
enum Work {
    Sync,
    LaserAtRest(f64),
    Coolant(bool, bool),
    /// `begun`: the protocol loop has reached it (its wait for the bytes before it added).
    Dwell {
        left: f64,
        total: f64,
        begun: bool,
    },
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
    /// GRBL's planner state (`pl`): the last block's end in steps, unit vector, speed.
    pl: Planner,
    /// The running block's progress.
    exec: Option<exec::Exec>,
    /// Speed at the end of the last block run, mm/s (0 at rest).
    v: f64,
    /// `~` arrived while a hold was still decelerating.
    resume_asked: bool,
    /// While the machine stands: when the protocol loop will have read every byte it took
    /// since the stop (GRBL's restart, [`motion`]'s module doc); `None` while it moves.
    reading: Option<f64>,
    /// `protocol_auto_cycle_start` came while the loop was still reading: the queued blocks
    /// start at this simulated time.
    start_at: Option<f64>,
    /// The last `run…` was `run_while_blocked` (the client streams on).
    streaming: bool,
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
    /// The table's positioning error (`ControllerConfig::position_error`).
    perr: Option<super::poserr::PositionError>,
    /// The table stood still or ran a rapid since the last lit block: the next lit block
    /// starts a row.
    row_pending: bool,
    /// Lines answered so far.
    pub lines_completed: u64,
    reset_after_reply: bool,
}

impl Controller {
    pub fn new(cfg: ControllerConfig) -> Controller {
        let settings = cfg.settings.clone();
        let rec = match cfg.keep {
            Some(k) => Recording::bounded(k),
            None => Recording::default(),
        };
        let limits = cfg.firmware.limits(&settings, cfg.planner_blocks);
        // The simulator starts homed at the origin (clamped into the travel).
        let mpos = cfg.home();
        let axes = cfg.firmware.axes();
        let offsets = cfg.work_offsets;
        let perr = cfg
            .position_error
            .map(|c| super::poserr::PositionError::new(c, mpos));
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
            gc: Gc {
                offsets,
                ..Gc::new(mpos, axes)
            },
            planner: VecDeque::new(),
            pl: Planner::new(limits, mpos),
            exec: None,
            v: 0.0,
            resume_asked: false,
            reading: Some(0.0),
            start_at: None,
            streaming: false,
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
            rec,
            perr,
            row_pending: true,
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
        if self.exec.is_some() {
            self.front_position().unwrap_or(self.mpos)
        } else {
            self.mpos
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

    /// A client connected: GRBL's welcome, as network GRBL controllers greet each connection;
    /// grblHAL greets a TCP client with nothing (its `$I` says what it is).
    pub fn connected(&mut self) {
        self.connection += 1;
        self.rec.connections += 1;
        if self.cfg.firmware == Firmware::Grbl {
            self.say(self.cfg.firmware.banner());
        }
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
                    self.begin_hold();
                }
                St::Idle => {
                    self.state = St::Hold { complete: true };
                    self.rec.holds += 1;
                }
                St::Jog => self.jog_cancel(),
                _ => {}
            },
            Realtime::CycleStart => {
                if self.state == (St::Hold { complete: false }) {
                    self.resume_asked = true;
                } else if let St::Hold { .. } = self.state {
                    if self.planner.is_empty() {
                        self.come_to_rest();
                    } else {
                        self.state = St::Cycle;
                        self.reading = None;
                        self.start_at = None;
                    }
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
        self.stop_motion();
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
        self.stop_motion();
        self.rx.clear();
        self.rx_conn.clear();
        self.line.clear();
        self.raw.clear();
        self.in_paren = false;
        self.in_semicolon = false;
        self.overflow = false;
        self.pending = None;
        self.gc = Gc {
            offsets: self.cfg.work_offsets,
            ..Gc::new(self.mpos, self.cfg.firmware.axes())
        };
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
    pub fn run(&mut self, dt: f64) {
        self.run_until(dt, false);
    }

    /// As fast as possible while a client streams: simulated time passes only while the
    /// protocol loop waits (a line held back by a full planner, a sync, a dwell), so the
    /// planner holds what a client streaming faster than the machine moves would give it.
    pub fn run_while_blocked(&mut self) {
        self.run_until(f64::INFINITY, true);
    }

    /// Nothing received is waiting to be read or executed by the protocol loop.
    pub fn input_drained(&self) -> bool {
        self.rx.is_empty() && self.pending.is_none()
    }

    /// The machine stands with nothing to run: the protocol loop reads on from now.
    pub(super) fn come_to_rest(&mut self) {
        self.state = St::Idle;
        self.reading = Some(self.now);
        self.start_at = None;
    }

    /// GRBL's `protocol_auto_cycle_start` (a line found the planner full, a sync, or the RX
    /// buffer ran dry): what stands queued starts once the loop has read what it took.
    pub(super) fn auto_cycle_start(&mut self) {
        if self.state == St::Idle && !self.planner.is_empty() && self.start_at.is_none() {
            let ready = self.reading.take().unwrap_or(self.now);
            self.start_at = Some(ready.max(self.now));
        }
    }

    /// The protocol loop's turn: read what it can; with nothing left to read (and the client
    /// not streaming on, `only_blocked`) start what is queued; start it when it is due.
    fn protocol_turn(&mut self, only_blocked: bool) {
        self.service();
        if !only_blocked && self.rx.is_empty() && self.pending.is_none() {
            self.auto_cycle_start();
        }
        if self.state == St::Idle && self.start_at.is_some_and(|t| t <= self.now + 1e-9) {
            self.start_at = None;
            self.state = St::Cycle;
        }
        if self.state == St::Cycle && self.planner.is_empty() {
            self.come_to_rest();
        }
    }

    fn run_until(&mut self, mut dt: f64, only_blocked: bool) {
        self.streaming = only_blocked;
        for _ in 0..10_000_000 {
            self.protocol_turn(only_blocked);
            self.start_front();
            if self.state == (St::Hold { complete: false }) && self.exec.is_none() {
                // Nothing was moving: the hold is complete at once.
                self.v = 0.0;
                self.state = St::Hold { complete: true };
                self.resume_if_asked();
            }
            self.note_laser();
            if only_blocked && self.pending.is_none() {
                break;
            }
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
        self.protocol_turn(only_blocked);
        self.note_laser();
        if self.status_request {
            self.status_request = false;
            let r = self.status_report();
            self.say(&r);
        }
    }

    fn time_to_event(&self) -> f64 {
        match self.state {
            St::Cycle | St::Jog | St::Hold { complete: false } => self.motion_event(),
            St::Idle => {
                let dwell = match self.pending.as_ref().and_then(|p| p.work.front()) {
                    Some(Work::Dwell { left, .. }) if self.planner.is_empty() => left.max(0.0),
                    _ => f64::INFINITY,
                };
                let start = self
                    .start_at
                    .map_or(f64::INFINITY, |t| (t - self.now).max(0.0));
                dwell.min(start)
            }
            _ => f64::INFINITY,
        }
    }

    fn elapse(&mut self, dt: f64) {
        self.now += dt;
        match self.state {
            St::Cycle | St::Jog | St::Hold { complete: false } => self.advance_motion(dt),
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
            // The stepper keeps driving the beam while a hold decelerates; laser mode turns it
            // off once the machine stands.
            St::Hold { complete: true } | St::Alarm { .. } | St::Sleep | St::Check => 0.0,
            St::Cycle | St::Hold { complete: false } => self
                .planner
                .front()
                .map_or(self.rest_laser, |b| b.b.laser_s),
            St::Jog => 0.0,
            St::Idle => self.rest_laser,
        }
    }

    fn note_laser(&mut self) {
        let p = self.laser_now();
        if p != self.last_laser {
            self.last_laser = p;
            let pos = self.position();
            let speed_mm_s = self.speed();
            self.rec.push_laser(LaserEvent {
                t: self.now,
                power_s: p,
                pos,
                speed_mm_s,
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
            if let Some(t) = self.reading {
                // `serial_read`: each byte read while the machine stands takes its time.
                self.reading = Some(t.max(self.now) + self.pl.limits.byte_s);
            }
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
        self.rec.push_line(LineRecord {
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
