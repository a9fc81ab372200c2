//! GRBL 1.1's motion model as plain math on plain data: how long the firmware takes to run a
//! program and where the machine is at each moment. The simulated controller executes its
//! planner blocks with it, and `lase plan` prints the cycle time of a program streamed to a
//! GRBL or grblHAL machine with it.
//!
//! What it takes from the firmware (gnea/grbl `planner.c`, `motion_control.c`, `gcode.c`,
//! `config.h`; grblHAL/core `planner.c`):
//! - a block per line segment, its length from the step-rounded targets (`$100`…), blocks of
//!   zero steps dropped; its acceleration and rapid rate the largest the axes allow along its
//!   direction (`limit_value_by_axis_maximum` over `$120`… and `$110`…); its nominal speed the
//!   programmed feed (or, under G93, its length over its time) capped by the rapid rate and
//!   never under `MINIMUM_FEED_RATE` (1 mm/min); `G0` at the rapid rate;
//! - the junction speed by `$11`: `v² = a_j·δ·sin(θ/2)/(1 − sin(θ/2))` with `a_j` the
//!   acceleration limit along the difference of the two unit vectors, 0 for a reversal, no
//!   limit for a straight continuation, capped by both blocks' nominal speeds; a block that
//!   enters an empty planner starts from rest;
//! - look-ahead over the planner buffer only (15 usable blocks on GRBL, `BLOCK_BUFFER_SIZE`
//!   less one): the last buffered block always plans to stop. Lines are assumed to arrive
//!   faster than the machine runs them, so the buffer is full whenever a block starts and a
//!   slot frees only when the running block ends;
//! - trapezoids at the block's acceleration (GRBL has no jerk limit);
//! - arcs split into chords by `$12` as `mc_arc` does;
//! - syncs (the planner empties, the machine stops): `G4` (then the dwell, in whole 50 ms
//!   steps as `delay_sec` waits, [`gcode::dwell_s`]), every spindle state change
//!   (`M3`/`M4`/`M5`, even in laser mode), `S` changes without motion, coolant — exactly the steps the simulator's G-code interpreter ([`super::gcode`]) asks for; `S`
//!   changes carried on moves in laser mode do not stop;
//! - the restart after a stop (`protocol.c`, `motion_control.c`): blocks queued while the
//!   machine stands do not start until the protocol loop calls `protocol_auto_cycle_start` —
//!   when a line finds the planner full (`mc_line`), at the next sync
//!   (`protocol_buffer_synchronize`), or when the RX buffer runs dry (the end of a streamed
//!   program). Until then the machine stands while the loop reads the bytes of the lines in
//!   between (comments, spaces and newlines too), each at [`Limits::byte_s`]; the same wait
//!   comes before the first motion and before a dwell the loop reaches at rest. While the
//!   machine moves, reading is assumed to keep ahead of it.
//!
//! What it leaves out, each well under a millisecond per stop: the stepper's first interrupt
//! after `st_wake_up` waits for Timer1's compare value left from the last segment (at most one
//! step period of the deceleration's last segment), the step timing inside a segment (the
//! segment generator keeps each segment's time exact, `dt_remainder`), and Timer1's CTC period
//! of `OCR1A + 1` ticks (0.06 % at 20 mm/s and 250 steps/mm). `$1` (the stepper idle lock,
//! 25 ms by default, `st_go_idle`'s `delay_ms` inside the stepper interrupt) holds the cycle
//! stop on the firmware, but grbl-sim's simulated clock stands still while its interrupt
//! sleeps, so the measured times do not contain it; the model leaves it out too.
//!
//! Speeds here are mm/s and accelerations mm/s² (degrees for rotary axes, as grblHAL counts
//! them); GRBL's own units (mm/min, mm/min²) are converted where settings are read.

use super::gcode::{self, Gc, Step};
use crate::link::{AxisPos, MAX_AXES, Plane};
use std::collections::{BTreeMap, VecDeque};
use std::fmt;

mod stream;
pub use stream::ModelStream;

/// GRBL's `MINIMUM_FEED_RATE` (config.h): 1 mm/min.
pub const MINIMUM_FEED_RATE: f64 = 1.0 / 60.0;
/// GRBL's `MINIMUM_JUNCTION_SPEED` (config.h): 0.
pub const MINIMUM_JUNCTION_SPEED: f64 = 0.0;
/// GRBL's `ARC_ANGULAR_TRAVEL_EPSILON` (config.h).
const ARC_ANGULAR_TRAVEL_EPSILON: f64 = 5e-7;

/// The firmware's motion limits, from its `$` settings.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Axes of the build (3 on GRBL).
    pub axes: usize,
    /// `$100`…: steps per mm (or degree).
    pub steps: [f64; MAX_AXES],
    /// `$110`…, converted to mm/s.
    pub max_rate: [f64; MAX_AXES],
    /// `$120`…, mm/s².
    pub accel: [f64; MAX_AXES],
    /// `$11`, mm.
    pub junction_deviation: f64,
    /// `$12`, mm.
    pub arc_tolerance: f64,
    /// Usable planner blocks, the look-ahead window (GRBL: 15).
    pub planner_blocks: usize,
    /// `$32`.
    pub laser_mode: bool,
    /// Seconds the protocol loop spends per byte it reads while the machine stands
    /// ([`super::Firmware::byte_s`]); 0 from settings alone.
    pub byte_s: f64,
}

impl Limits {
    /// From `$` settings (GRBL's numbering and units).
    pub fn from_settings(s: &BTreeMap<u32, f64>, axes: usize, planner_blocks: usize) -> Limits {
        let get = |id: u32, default: f64| s.get(&id).copied().unwrap_or(default);
        Limits {
            axes: axes.clamp(1, MAX_AXES),
            steps: std::array::from_fn(|k| get(100 + k as u32, 250.0).max(1e-6)),
            max_rate: std::array::from_fn(|k| get(110 + k as u32, 500.0).max(1e-6) / 60.0),
            accel: std::array::from_fn(|k| get(120 + k as u32, 10.0).max(1e-6)),
            junction_deviation: get(11, 0.01).max(0.0),
            arc_tolerance: get(12, 0.002).max(1e-6),
            planner_blocks: planner_blocks.max(1),
            laser_mode: get(32, 0.0) == 1.0,
            byte_s: 0.0,
        }
    }

    /// GRBL's `limit_value_by_axis_maximum`: the largest value along `unit` that keeps every
    /// axis within its own limit.
    fn along(&self, per_axis: &[f64; MAX_AXES], unit: &AxisPos) -> f64 {
        (0..self.axes)
            .filter(|&k| unit[k] != 0.0)
            .map(|k| per_axis[k] / unit[k].abs())
            .fold(f64::INFINITY, f64::min)
    }
}

/// The points a move passes through, after its start: one for a line, the chord ends of an
/// arc split by the arc tolerance as GRBL's `mc_arc` splits it (the other axes of a helix move
/// linearly).
pub fn chord_points(mv: &gcode::Move, tolerance: f64) -> Vec<AxisPos> {
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
        let radius = r0[0].hypot(r0[1]);
        // mc_arc's angular travel, a full circle when start and end coincide.
        let mut ang = (r0[0] * r1[1] - r0[1] * r1[0]).atan2(r0[0] * r1[0] + r0[1] * r1[1]);
        if arc.ccw {
            if ang <= ARC_ANGULAR_TRAVEL_EPSILON {
                ang += std::f64::consts::TAU;
            }
        } else if ang >= -ARC_ANGULAR_TRAVEL_EPSILON {
            ang -= std::f64::consts::TAU;
        }
        let tol = tolerance.max(1e-6);
        let seg_len = (tol * (2.0 * radius - tol)).max(1e-12).sqrt();
        let n = ((0.5 * ang.abs() * radius / seg_len).floor() as usize).clamp(1, 100_000);
        let a_start = r0[1].atan2(r0[0]);
        for i in 1..n {
            let f = i as f64 / n as f64;
            let a = a_start + ang * f;
            let mut p: AxisPos =
                std::array::from_fn(|k| mv.from[k] + (mv.target[k] - mv.from[k]) * f);
            p[a0] = c[a0] + radius * a.cos();
            p[a1] = c[a1] + radius * a.sin();
            points.push(p);
        }
    }
    points.push(mv.target);
    points
}

/// A planned block: one line segment as the planner holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    /// The line it came from (1-based, as [`run_program`] counts lines).
    pub line: u64,
    pub from: AxisPos,
    pub to: AxisPos,
    /// mm (degrees count as mm), from the step-rounded targets.
    pub len: f64,
    /// mm/s.
    pub nominal: f64,
    /// mm/s².
    pub accel: f64,
    /// The largest entry speed squared the junction and both nominal speeds allow.
    pub max_entry_sq: f64,
    pub rapid: bool,
    /// Laser power (S) while it moves, 0 when dark.
    pub laser_s: f64,
}

/// The planner's memory of the last block it took (GRBL's `pl`): where it ended in steps,
/// its unit vector and nominal speed.
#[derive(Debug, Clone, PartialEq)]
pub struct Planner {
    pub limits: Limits,
    position: [i64; MAX_AXES],
    /// Where the last block ends as programmed (`position` is it rounded to steps).
    target: AxisPos,
    prev_unit: AxisPos,
    prev_nominal: f64,
}

/// One segment a move asks for, before the planner makes it a block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    pub target: AxisPos,
    pub rapid: bool,
    /// mm/s when fed; under G93 the segment's own time instead.
    pub rate: f64,
    pub inverse_time_s: Option<f64>,
    pub laser_s: f64,
}

impl Planner {
    pub fn new(limits: Limits, at: AxisPos) -> Planner {
        let mut p = Planner {
            limits,
            position: [0; MAX_AXES],
            target: at,
            prev_unit: [0.0; MAX_AXES],
            prev_nominal: 0.0,
        };
        p.sync_position(at);
        p
    }

    /// GRBL's `plan_sync_position`: the planner's position after a reset or a jog.
    pub fn sync_position(&mut self, at: AxisPos) {
        self.position = std::array::from_fn(|k| (at[k] * self.limits.steps[k]).round() as i64);
        self.target = at;
    }

    /// The segments of a move: arcs split into chords, a G93 move's time shared by length.
    pub fn segments(&self, mv: &gcode::Move) -> Vec<Segment> {
        let points = chord_points(mv, self.limits.arc_tolerance);
        let mut prev = mv.from;
        let lens: Vec<f64> = points
            .iter()
            .map(|p| {
                let d = dist(prev, *p);
                prev = *p;
                d
            })
            .collect();
        let total: f64 = lens.iter().sum();
        points
            .iter()
            .zip(&lens)
            .map(|(p, len)| Segment {
                target: *p,
                rapid: mv.rapid,
                rate: mv.feed_mm_min / 60.0,
                inverse_time_s: mv
                    .inverse_time_s
                    .map(|t| if total > 0.0 { t * len / total } else { t }),
                laser_s: mv.laser_s,
            })
            .collect()
    }

    /// GRBL's `plan_buffer_line`: the block for a segment (`None` for zero steps), its
    /// junction with the block before; `empty`: the planner holds nothing (start from rest).
    /// `feed_ov` and `rapid_ov` are the overrides in percent.
    pub fn block(
        &mut self,
        line: u64,
        seg: &Segment,
        empty: bool,
        feed_ov: f64,
        rapid_ov: f64,
    ) -> Option<Block> {
        let lim = &self.limits;
        let target: [i64; MAX_AXES] =
            std::array::from_fn(|k| (seg.target[k] * lim.steps[k]).round() as i64);
        if (0..MAX_AXES).all(|k| target[k] == self.position[k]) {
            // No steps: GRBL drops the block (the parser's position still moves).
            self.target = seg.target;
            return None;
        }
        let delta: AxisPos =
            std::array::from_fn(|k| (target[k] - self.position[k]) as f64 / lim.steps[k]);
        let len = delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        let unit: AxisPos = std::array::from_fn(|k| delta[k] / len);
        let accel = lim.along(&lim.accel, &unit);
        let rapid_rate = lim.along(&lim.max_rate, &unit);
        let programmed = match seg.inverse_time_s {
            Some(t) if t > 0.0 => len / t,
            _ => seg.rate,
        };
        let nominal = if seg.rapid {
            rapid_rate * rapid_ov / 100.0
        } else {
            (programmed * feed_ov / 100.0).min(rapid_rate)
        }
        .max(MINIMUM_FEED_RATE);
        let junction_sq = if empty {
            0.0
        } else {
            let cos = -(0..MAX_AXES)
                .map(|k| self.prev_unit[k] * unit[k])
                .sum::<f64>();
            if cos > 0.999999 {
                MINIMUM_JUNCTION_SPEED * MINIMUM_JUNCTION_SPEED
            } else if cos < -0.999999 {
                f64::INFINITY
            } else {
                let d: AxisPos = std::array::from_fn(|k| unit[k] - self.prev_unit[k]);
                let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
                let ju: AxisPos = std::array::from_fn(|k| d[k] / n);
                let ja = lim.along(&lim.accel, &ju);
                let sin_half = (0.5 * (1.0 - cos)).sqrt();
                (ja * lim.junction_deviation * sin_half / (1.0 - sin_half))
                    .max(MINIMUM_JUNCTION_SPEED * MINIMUM_JUNCTION_SPEED)
            }
        };
        let max_entry_sq = (nominal.min(self.prev_nominal)).powi(2).min(junction_sq);
        // Timing comes from the steps; positions stay as programmed (under a step apart).
        let (from, to) = (self.target, seg.target);
        self.target = seg.target;
        self.prev_unit = unit;
        self.prev_nominal = nominal;
        self.position = target;
        Some(Block {
            line,
            from,
            to,
            len,
            nominal,
            accel,
            max_entry_sq,
            rapid: seg.rapid,
            laser_s: seg.laser_s,
        })
    }
}

/// The exit speed of the running block, `first_len` still to go at `entry` with acceleration
/// `first_accel`, with the blocks buffered behind it: GRBL's reverse pass from a stop after the
/// last buffered block (the buffer ends there, or a sync follows), then the forward limit of
/// the running block.
pub fn exit_speed<'a>(
    entry: f64,
    first_len: f64,
    first_accel: f64,
    behind: impl Iterator<Item = &'a Block>,
) -> f64 {
    let behind: Vec<&Block> = behind.collect();
    let mut next_entry_sq = 0.0;
    for b in behind.iter().rev() {
        next_entry_sq = b.max_entry_sq.min(next_entry_sq + 2.0 * b.accel * b.len);
    }
    next_entry_sq
        .min(entry * entry + 2.0 * first_accel * first_len)
        .max(0.0)
        .sqrt()
}

/// A trapezoid over a length: entry, exit, the speed it cruises at (or peaks at, when it
/// never reaches its nominal speed), one acceleration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    pub len: f64,
    pub entry: f64,
    pub exit: f64,
    pub peak: f64,
    pub accel: f64,
}

impl Trapezoid {
    pub fn new(len: f64, entry: f64, exit: f64, nominal: f64, accel: f64) -> Trapezoid {
        let a = accel.max(1e-9);
        // Reachable speeds only: never more than the length allows from either end.
        let entry = entry.min((exit * exit + 2.0 * a * len).sqrt());
        let exit = exit.min((entry * entry + 2.0 * a * len).sqrt());
        let peak_sq = (2.0 * a * len + entry * entry + exit * exit) / 2.0;
        let peak = nominal.min(peak_sq.sqrt()).max(entry.max(exit));
        Trapezoid {
            len,
            entry,
            exit,
            peak,
            accel: a,
        }
    }

    fn phases(&self) -> (f64, f64, f64, f64, f64) {
        let a = self.accel;
        let t1 = (self.peak - self.entry) / a;
        let d1 = (self.peak * self.peak - self.entry * self.entry) / (2.0 * a);
        let t3 = (self.peak - self.exit) / a;
        let d3 = (self.peak * self.peak - self.exit * self.exit) / (2.0 * a);
        let d2 = (self.len - d1 - d3).max(0.0);
        let t2 = if self.peak > 0.0 { d2 / self.peak } else { 0.0 };
        (t1, d1, t2, d2, t3)
    }

    pub fn duration(&self) -> f64 {
        let (t1, _, t2, _, t3) = self.phases();
        t1 + t2 + t3
    }

    /// Distance and speed `t` seconds after the start.
    pub fn at(&self, t: f64) -> (f64, f64) {
        let (t1, d1, t2, d2, t3) = self.phases();
        let a = self.accel;
        if t <= 0.0 {
            (0.0, self.entry)
        } else if t < t1 {
            (self.entry * t + 0.5 * a * t * t, self.entry + a * t)
        } else if t < t1 + t2 {
            (d1 + self.peak * (t - t1), self.peak)
        } else if t < t1 + t2 + t3 {
            let u = t - t1 - t2;
            (
                (d1 + d2 + self.peak * u - 0.5 * a * u * u).min(self.len),
                self.peak - a * u,
            )
        } else {
            (self.len, self.exit)
        }
    }
}

/// What the machine does during a stretch of the timeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Activity {
    /// Moving along a block.
    Move { profile: Trapezoid, rapid: bool },
    /// At rest: a dwell or waiting.
    Rest,
}

/// A stretch of the executed timeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Span {
    pub t0: f64,
    pub duration: f64,
    pub from: AxisPos,
    pub to: AxisPos,
    pub activity: Activity,
    /// Laser power (S) during it, 0 when dark.
    pub laser_s: f64,
    /// The line it came from.
    pub line: u64,
}

impl Span {
    /// The machine standing at `at` from `t0` for `duration`, the beam at `laser_s`.
    fn rest(t0: f64, duration: f64, at: AxisPos, laser_s: f64) -> Span {
        Span {
            t0,
            duration,
            from: at,
            to: at,
            activity: Activity::Rest,
            laser_s,
            line: 0,
        }
    }
}

/// The beam switched: when, where and how fast the machine moved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamEdge {
    pub t: f64,
    pub pos: AxisPos,
    /// mm/s.
    pub speed: f64,
    /// Power after the edge (S), 0 = off.
    pub power_s: f64,
}

/// A sample of the timeline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub pos: AxisPos,
    pub speed: f64,
    pub laser_s: f64,
}

/// The executed timeline of a program.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Timeline {
    pub spans: Vec<Span>,
    pub edges: Vec<BeamEdge>,
    /// Time spent moving, s.
    pub motion_s: f64,
    /// Everything, dwells included, s.
    pub total_s: f64,
    /// Planner blocks executed.
    pub blocks: usize,
    /// Times the planner emptied and the machine stopped for a sync.
    pub syncs: usize,
}

impl Timeline {
    /// Position, speed and beam at time `t`.
    pub fn at(&self, t: f64) -> Sample {
        let i = self.spans.partition_point(|s| s.t0 + s.duration < t);
        let Some(s) = self.spans.get(i).or(self.spans.last()) else {
            return Sample {
                pos: [0.0; MAX_AXES],
                speed: 0.0,
                laser_s: 0.0,
            };
        };
        match s.activity {
            Activity::Move { profile, .. } => {
                let (d, v) = profile.at(t - s.t0);
                Sample {
                    pos: lerp(s.from, s.to, d / profile.len.max(1e-12)),
                    speed: v,
                    laser_s: s.laser_s,
                }
            }
            Activity::Rest => Sample {
                pos: s.to,
                speed: 0.0,
                laser_s: s.laser_s,
            },
        }
    }

    fn push(&mut self, span: Span) {
        let before = self.spans.last().map_or(0.0, |s| s.laser_s);
        if span.laser_s != before {
            let speed = match span.activity {
                Activity::Move { profile, .. } => profile.entry,
                Activity::Rest => 0.0,
            };
            self.edges.push(BeamEdge {
                t: span.t0,
                pos: span.from,
                speed,
                power_s: span.laser_s,
            });
        }
        self.total_s = span.t0 + span.duration;
        if let Activity::Move { .. } = span.activity {
            self.motion_s += span.duration;
            self.blocks += 1;
        }
        self.spans.push(span);
    }
}

/// A G-code line the model could not run: its 1-based number and GRBL's error code.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError {
    pub line: u64,
    pub code: u32,
    pub text: String,
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "line {}: `{}` gives error:{} on GRBL",
            self.line, self.text, self.code
        )
    }
}

impl std::error::Error for ModelError {}

/// What the planner buffer receives, in order.
#[derive(Debug)]
enum Item {
    Block(Block),
    /// The planner empties and the machine stops.
    Sync,
    Dwell(f64),
    /// The beam at rest changes.
    Rest(f64),
    /// The machine stands while the protocol loop reads up to the cycle start (or a dwell).
    Wait(f64),
}

/// GRBL's protocol loop while the machine stands (protocol.c): the bytes it has read since the
/// stop and the blocks it has queued, which start only at `protocol_auto_cycle_start`.
struct Gate {
    open: bool,
    bytes: u64,
    queued: usize,
    /// Where the wait before the first queued block goes in the items.
    wait_at: Option<usize>,
}

impl Gate {
    fn at_rest() -> Gate {
        Gate {
            open: true,
            bytes: 0,
            queued: 0,
            wait_at: None,
        }
    }

    /// `protocol_auto_cycle_start`: the queued blocks start once the bytes read so far are.
    fn start(&mut self, items: &mut Items, byte_s: f64) {
        if self.open
            && let Some(k) = self.wait_at
        {
            // The wait is still buffered: the executor stops before a wait the gate holds.
            items.q[k - items.base] = Item::Wait(self.bytes as f64 * byte_s);
        }
        self.open = false;
    }
}

/// What the planner buffer has received and not yet executed, indexed from the first item
/// ever received (the gate points back at the wait it fills in).
#[derive(Default)]
struct Items {
    q: VecDeque<Item>,
    /// The index of `q[0]`.
    base: usize,
}

impl Items {
    /// Items received so far.
    fn count(&self) -> usize {
        self.base + self.q.len()
    }

    fn push(&mut self, item: Item) {
        self.q.push_back(item);
    }
}

/// GRBL's protocol loop and parser reading a program line by line into planner items.
struct Reader<'a> {
    limits: &'a Limits,
    gc: Gc,
    planner: Planner,
    pending_blocks: usize,
    gate: Gate,
    lines: u64,
}

impl<'a> Reader<'a> {
    fn new(limits: &'a Limits, start: AxisPos) -> Reader<'a> {
        Reader {
            limits,
            gc: Gc::new(start, limits.axes),
            planner: Planner::new(limits.clone(), start),
            pending_blocks: 0,
            // The machine stands at the start: nothing moves before the first cycle start.
            gate: Gate::at_rest(),
            lines: 0,
        }
    }

    /// The next line, through the simulator's interpreter as GRBL's protocol loop would hand
    /// it over (comments and spaces dropped, upper-cased), into the planner.
    fn line(&mut self, raw: &str, items: &mut Items) -> Result<(), ModelError> {
        let limits = self.limits;
        self.lines += 1;
        let line_no = self.lines;
        if self.gate.open {
            // Every byte of the line, its newline too, goes through `serial_read`.
            self.gate.bytes += raw.len() as u64 + 1;
        }
        let line = strip(raw);
        if line.is_empty() || line.starts_with(b"$") {
            return Ok(());
        }
        let block =
            gcode::execute(&line, &self.gc, limits.laser_mode).map_err(|code| ModelError {
                line: line_no,
                code,
                text: raw.trim().to_string(),
            })?;
        for step in &block.steps {
            match step {
                Step::Sync => {
                    if self.pending_blocks > 0 {
                        // `protocol_buffer_synchronize` starts what is queued, then waits.
                        self.gate.start(items, limits.byte_s);
                        items.push(Item::Sync);
                        self.gate = Gate::at_rest();
                    }
                    self.pending_blocks = 0;
                }
                Step::LaserAtRest(s) => items.push(Item::Rest(*s)),
                Step::Dwell(t) => {
                    // `mc_dwell` (after its sync): the dwell begins once the loop has read
                    // the bytes before it; the loop reads on from its end.
                    if self.gate.open && self.gate.bytes > 0 {
                        items.push(Item::Wait(self.gate.bytes as f64 * limits.byte_s));
                    }
                    items.push(Item::Dwell(*t));
                    self.gate = Gate::at_rest();
                }
                Step::Move(mv) => {
                    for seg in self.planner.segments(mv) {
                        if let Some(b) = self.planner.block(
                            line_no,
                            &seg,
                            self.pending_blocks == 0,
                            100.0,
                            100.0,
                        ) {
                            let gate = &mut self.gate;
                            if gate.open {
                                if gate.queued == limits.planner_blocks {
                                    // `mc_line` finds the planner full: cycle start.
                                    gate.start(items, limits.byte_s);
                                } else {
                                    if gate.queued == 0 {
                                        gate.wait_at = Some(items.count());
                                        items.push(Item::Wait(0.0));
                                    }
                                    gate.queued += 1;
                                }
                            }
                            self.pending_blocks += 1;
                            items.push(Item::Block(b));
                        }
                    }
                }
                Step::Coolant { .. } | Step::ProgramEnd | Step::Pause => {}
            }
        }
        // The beam at rest after the line: M3 in G1 keeps it lit in laser mode.
        let rest = gcode::rest_power(&block.next.modal, limits.laser_mode);
        items.push(Item::Rest(rest));
        self.gc = block.next;
        Ok(())
    }

    /// After the last line: the RX buffer runs dry, what is queued starts.
    fn finish(&mut self, items: &mut Items) {
        self.gate.start(items, self.limits.byte_s);
    }

    /// Whether item `k` is the wait before queued blocks whose length the gate does not know
    /// yet (it is read until the cycle starts).
    fn waits_at(&self, k: usize) -> bool {
        self.gate.open && self.gate.wait_at == Some(k)
    }
}

/// Runs a G-code program (as lase streams it) through the model from `start`: each line
/// through the simulator's interpreter, as GRBL's protocol loop would hand it over (comments
/// and spaces dropped, upper-cased), then planned and executed.
pub fn run_program(program: &str, limits: &Limits, start: AxisPos) -> Result<Timeline, ModelError> {
    let mut reader = Reader::new(limits, start);
    let mut items = Items::default();
    for raw in program.lines() {
        reader.line(raw, &mut items)?;
    }
    reader.finish(&mut items);
    Ok(execute(
        items.q.make_contiguous(),
        limits.planner_blocks,
        start,
    ))
}

/// The machine executing planner items ([`execute`], and [`ModelStream`] as they arrive).
#[derive(Debug)]
struct Exec {
    tl: Timeline,
    t: f64,
    v: f64,
    pos: AxisPos,
    rest_s: f64,
}

impl Exec {
    fn new(start: AxisPos) -> Exec {
        Exec {
            tl: Timeline::default(),
            t: 0.0,
            v: 0.0,
            pos: start,
            rest_s: 0.0,
        }
    }

    /// Executes one item; `ahead`: the buffered blocks from it on (it first) that its
    /// look-ahead sees, up to the buffer's size or the next sync.
    fn step<'a>(&mut self, item: &Item, mut ahead: impl Iterator<Item = &'a Block>) {
        match item {
            Item::Block(b) => {
                ahead.next();
                let exit = exit_speed(self.v, b.len, b.accel, ahead);
                let profile = Trapezoid::new(b.len, self.v, exit, b.nominal, b.accel);
                let d = profile.duration();
                self.tl.push(Span {
                    t0: self.t,
                    duration: d,
                    from: b.from,
                    to: b.to,
                    activity: Activity::Move {
                        profile,
                        rapid: b.rapid,
                    },
                    laser_s: b.laser_s,
                    line: b.line,
                });
                self.t += d;
                self.v = profile.exit;
                self.pos = b.to;
            }
            Item::Sync => {
                self.tl.syncs += 1;
                self.v = 0.0;
            }
            Item::Dwell(d) => {
                self.v = 0.0;
                self.tl.push(Span::rest(self.t, *d, self.pos, self.rest_s));
                self.t += d;
            }
            Item::Wait(d) => {
                if *d > 0.0 {
                    self.tl.push(Span::rest(self.t, *d, self.pos, self.rest_s));
                    self.t += d;
                }
            }
            Item::Rest(s) => {
                if *s != self.rest_s && self.v == 0.0 {
                    // The beam switches at rest: a zero-length stretch marks the edge.
                    self.tl.push(Span::rest(self.t, 0.0, self.pos, *s));
                }
                self.rest_s = *s;
            }
        }
    }
}

/// The blocks item `items[i]`'s look-ahead sees: from it, up to `window` of them, stopping at
/// the next sync or dwell (where the machine stops).
fn ahead<'a>(
    items: impl Iterator<Item = &'a Item>,
    window: usize,
) -> impl Iterator<Item = &'a Block> {
    items
        .take_while(|it| !matches!(it, Item::Sync | Item::Dwell(_)))
        .filter_map(|it| match it {
            Item::Block(b) => Some(b),
            _ => None,
        })
        .take(window)
}

/// Executes planned items: each block with the exit speed its look-ahead window allows (the
/// window ends at the buffer size or at the next sync, where the machine stops).
fn execute(items: &[Item], window: usize, start: AxisPos) -> Timeline {
    let mut exec = Exec::new(start);
    for i in 0..items.len() {
        exec.step(&items[i], ahead(items[i..].iter(), window));
    }
    exec.tl
}

/// A line as GRBL's protocol loop hands it to the parser: no comments, no spaces, upper case.
fn strip(raw: &str) -> Vec<u8> {
    let mut out = Vec::new();
    let mut paren = false;
    for c in raw.bytes() {
        match c {
            b';' if !paren => break,
            b'(' => paren = true,
            b')' if paren => paren = false,
            _ if paren || c <= b' ' => {}
            _ => out.push(c.to_ascii_uppercase()),
        }
    }
    out
}

fn dist(a: AxisPos, b: AxisPos) -> f64 {
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

fn lerp(a: AxisPos, b: AxisPos, f: f64) -> AxisPos {
    let f = f.clamp(0.0, 1.0);
    std::array::from_fn(|k| a[k] + (b[k] - a[k]) * f)
}

/// The cycle time of the controller that runs a job: its NC in the dialect lase streams to
/// the machine, through the firmware's model with the settings the machine file implies.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerTime {
    /// Which model: `GRBL 1.1 planner model` or the grblHAL one.
    pub model: &'static str,
    pub timeline: Timeline,
}

/// The model's name for a firmware.
pub fn model_name(firmware: super::Firmware) -> &'static str {
    match firmware {
        super::Firmware::Grbl => "GRBL 1.1 planner model",
        super::Firmware::GrblHal { .. } => "grblHAL planner model",
    }
}

/// How long the GRBL or grblHAL controller a machine streams to takes for `job`; `None` when
/// the machine has no post for that family (it is not run by GRBL), `Err` with the reason when
/// its program cannot be written or run there.
pub fn controller_time(job: &crate::motion::Job) -> Option<Result<ControllerTime, String>> {
    controller_time_in(job, crate::link::live_dialect(&job.program.machine))
}

/// [`controller_time`] for the program in `dialect` (`grbl` or `grblhal`; any other is
/// `None`): GRBL 1.1's model for `grbl`, grblHAL's with the machine's axes (at least X Y Z)
/// for `grblhal`, as `lase plan --dialect` asks.
pub fn controller_time_in(
    job: &crate::motion::Job,
    dialect: crate::emit::Dialect,
) -> Option<Result<ControllerTime, String>> {
    controller_time_from(job, None, dialect)
}

/// [`controller_time_in`] of a job planned whole (`facts` `None`) or in windows (`facts` from
/// them), streamed through [`ModelStream`]: the timeline keeps its totals, not its spans.
pub fn controller_time_from(
    job: &crate::motion::Job,
    facts: Option<&crate::emit::PlanFacts>,
    dialect: crate::emit::Dialect,
) -> Option<Result<ControllerTime, String>> {
    let machine = &job.program.machine;
    let firmware = match dialect {
        crate::emit::Dialect::Grbl => super::Firmware::Grbl,
        crate::emit::Dialect::GrblHal => super::Firmware::GrblHal {
            axes: crate::link::controller_axes(machine).max(3),
        },
        _ => return None,
    };
    dialect.lookup(&machine.post)?;
    Some((|| {
        let mut cfg = super::ControllerConfig::for_machine(machine);
        cfg.firmware = firmware;
        cfg.planner_blocks = firmware.planner_blocks();
        let limits = cfg.firmware.limits(&cfg.settings, cfg.planner_blocks);
        // Line by line from the emitter into the model: the program is never held.
        let mut model = ModelStream::new(&limits, cfg.home(), false);
        crate::emit::emit_nc_lines(job, facts, dialect, &mut |l| {
            model.line(l).map_err(|e| e.to_string())
        })?;
        Ok(ControllerTime {
            model: model_name(cfg.firmware),
            timeline: model.finish(),
        })
    })())
}
