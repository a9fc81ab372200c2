//! What the simulated controller did, for tests to read: each line with its result and
//! effect (modal changes, motion, dwell, program flow), each executed block, laser switching,
//! overflows and alarms.

use crate::link::sim::gcode::Gc;
use crate::link::{AxisPos, MotionMode};

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
    /// Simulated time at its start and end, s.
    pub t_start: f64,
    pub t_end: f64,
    /// How long it moved, s (along its trapezoid; a hold's stop included).
    pub duration: f64,
    /// Speed entering and leaving it, mm/s (degrees per second count as mm/s).
    pub entry_mm_s: f64,
    pub exit_mm_s: f64,
}

/// The laser output changed.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserEvent {
    pub t: f64,
    pub power_s: f64,
    pub pos: AxisPos,
    /// Speed along the path at the edge, mm/s.
    pub speed_mm_s: f64,
}

/// What the simulated controller did.
///
/// Tests keep everything (the default). A job of millions of lines through `lase run` keeps
/// only the last [`Recording::keep`] lines, blocks and laser edges, and counts the rest, so
/// the simulator's memory does not grow with the job.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recording {
    /// Lines received (when [`Recording::keep`] is set, only the most recent ones).
    pub lines: Vec<LineRecord>,
    /// Every line received, counted, also those no longer in `lines`.
    pub lines_received: u64,
    /// Of those, G-code lines (not `$` system commands).
    pub gcode_lines: u64,
    /// Every block executed, counted, also those no longer in `blocks`.
    pub blocks_executed: u64,
    /// Keep at most about this many of the latest lines, blocks and laser edges (between
    /// `keep` and `2 keep`, trimmed in batches so a push stays O(1)); `None` keeps all.
    pub keep: Option<usize>,
    /// When the last block or dwell ended, simulated s: the executed time of a program run
    /// from power-up.
    pub executed_s: f64,
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
    /// Where the table was when each row's first pulse fired (the first lit feed block since
    /// the table stood still or ran a rapid), commanded and actual (issue 15).
    pub row_starts: Vec<crate::link::sim::poserr::RowStartRecord>,
}

impl Recording {
    /// A recording that keeps only the latest `keep` entries of each list.
    pub fn bounded(keep: usize) -> Recording {
        Recording {
            keep: Some(keep.max(1)),
            ..Recording::default()
        }
    }

    pub(super) fn push_line(&mut self, l: LineRecord) {
        self.lines_received += 1;
        if l.result != LineResult::System {
            self.gcode_lines += 1;
        }
        push_bounded(&mut self.lines, l, self.keep);
    }

    pub(super) fn push_block(&mut self, b: ExecutedBlock) {
        self.blocks_executed += 1;
        push_bounded(&mut self.blocks, b, self.keep);
    }

    pub(super) fn push_laser(&mut self, e: LaserEvent) {
        push_bounded(&mut self.laser, e, self.keep);
    }
}

/// Pushes `item`; with a bound `k`, drops the oldest entries once there are `2k`, leaving `k`
/// (amortized O(1) per push, at most `2k` entries held).
fn push_bounded<T>(v: &mut Vec<T>, item: T, keep: Option<usize>) {
    if let Some(k) = keep
        && v.len() >= 2 * k
    {
        v.drain(..v.len() - k + 1);
    }
    v.push(item);
}

/// The modal changes between two parser states, as an [`Effect`].
pub(super) fn effect_of(before: &Gc, after: &Gc) -> Effect {
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
