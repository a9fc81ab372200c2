//! The process program: what a recipe means, independent of any machine's axes or any NC
//! dialect. A flat list of operations in part coordinates (mm, s, rad, W), each carrying the
//! recipe span that produced it so a planning error or a controller's complaint can point at
//! the recipe line.
//!
//! [`ProcessProgram::validate`] holds the laser's limits (power, pulse rate) for every op: the
//! one rule the evaluator applies while it runs and the pipeline applies again to the finished
//! program, after any override of power or speed (the REPL's `:set`).

use crate::machine::Machine;
use lase_lang::Span;
use lase_lang::units::{self, Dim, format_quantity};
use miette::Diagnostic;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A point in part coordinates, mm.
pub type P3 = [f64; 3];

/// Cruise time before the first pulse of a section with pulses by distance: its lead-in is
/// longer than the ramp by this long at the feed, so the planner (which ramps as early as it
/// can) is at cruise that long before the first pulse, and every pulse fires at the programmed
/// speed with room for a controller whose ramp ends a few servo periods late (LinuxCNC's edges
/// land within 2–3 periods of 1 ms). Without it the first spot of each dot row sat exactly where
/// the ramp ends: the 1 ms before it averaged 19.95 of 20 mm/s on `texture_array`. A margin in
/// a separate move before the lead-in would not do: each planned move starts and ends its
/// S-curve ramp at zero acceleration, so a ramp split in two ends later.
pub const PULSE_CRUISE_MARGIN_S: f64 = 0.005;

/// Straight-line distance between two spots, mm.
pub fn dist(a: P3, b: P3) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Laser state of a lit move.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Laser {
    pub power_w: f64,
    pub spot_mm: f64,
    pub pulse: Option<Pulse>,
    /// How power follows the motion (`laser { couple speed }`).
    #[serde(default)]
    pub couple: Coupling,
    /// Width of the cut, mm (`laser { kerf }`): half of it is added outward on outlines and
    /// inward on holes when the job's paths are ordered (`eval::order`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub kerf_mm: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// Whether laser power follows the planned speed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Coupling {
    /// Constant power while the beam is on.
    #[default]
    None,
    /// Constant energy per length (PROCESS.md §1, `Q ∝ P / (D · v)`): where the planned path
    /// speed `v(t)` ramps with the beam on, the power is `P(t) = P_set · v(t) / v_programmed`.
    Speed,
}

impl Laser {
    /// The power at planned path speed `v_mm_s` on a move programmed at `feed_mm_s`: `P_set`,
    /// or `P_set · v / feed` when coupled to speed (never above `P_set`, 0 for a rapid).
    pub fn power_at(&self, v_mm_s: f64, feed_mm_s: f64) -> f64 {
        match self.couple {
            Coupling::None => self.power_w,
            Coupling::Speed if feed_mm_s > 0.0 && feed_mm_s.is_finite() => {
                self.power_w * (v_mm_s / feed_mm_s).clamp(0.0, 1.0)
            }
            Coupling::Speed => 0.0,
        }
    }
}

/// How pulses are fired while the laser is on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Pulse {
    pub mode: PulseMode,
    pub width_s: Option<f64>,
    pub energy_j: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum PulseMode {
    /// One pulse every `pitch_mm` of lit path, the first at the start of the lit section
    /// (position-synchronized output).
    Distance { pitch_mm: f64 },
    /// One pulse every `period_s` of lit time, the first at the start of the lit section.
    Time { period_s: f64 },
}

/// How the head stands to the part at the end of a move, on machines that orient the beam
/// (cam X-ω-B, arm): the beam direction (a unit vector in part coordinates, pointing from the
/// head to the spot) and the standoff, the distance from the head's reference point to the
/// spot along the beam. `None` on a move means the machine's default: beam along −z, no
/// standoff (a flat-bed machine), or the previous move's orientation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Orient {
    pub beam: [f64; 3],
    pub standoff_mm: f64,
}

/// What one op does. A program holds one per move of the recipe (a million short moves from a
/// `for` loop are a million ops), so its size is a job's largest cost per move (issue 18):
/// what every lit op carries but few differ in (the laser, 80 bytes) is shared (`Arc`, one per
/// laser setting, `eval::Evaluator::shared_laser`), and what only some machines use (a beam
/// orientation, 32 bytes) is boxed: 64 bytes, not 160.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum OpKind {
    /// Positioning at the machine's top speed, laser off.
    Rapid {
        to: P3,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        orient: Option<Box<Orient>>,
    },
    /// A straight move at a programmed feed (a straight line of the spot in part coordinates;
    /// on an oriented machine the beam direction turns uniformly along it).
    Line {
        to: P3,
        feed_mm_s: f64,
        #[serde(default, with = "shared")]
        laser: Option<Arc<Laser>>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        orient: Option<Box<Orient>>,
        /// An image row's pixel runs along this line (`scan image`): planned as one straight
        /// lit move, written as one block per run (see [`PixelRow`]).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        row: Option<Box<PixelRow>>,
    },
    /// A circular arc in the XY plane (z may change linearly: a helix).
    Arc {
        to: P3,
        center: [f64; 2],
        ccw: bool,
        feed_mm_s: f64,
        #[serde(default, with = "shared")]
        laser: Option<Arc<Laser>>,
    },
    /// Standstill.
    Dwell { seconds: f64 },
    /// A raw M-function; the machine stops for it.
    MCode { code: u32, comment: Option<String> },
    /// A named machine event (head swing, shutter ...), translated by the machine's post.
    Event { name: String },
    /// A machine output (`[outputs.NAME]`) switched on or off; `stops`: the table stops for
    /// it (on the strictest of the output's dialects, `OutputPost::stops`).
    Output { name: String, on: bool, stops: bool },
    /// Dot mode: the spot at rest where it stands, the beam fires `count` pulses `period_s`
    /// apart (the first at the start) in a gate window of `window_s` (`count · period_s`
    /// rounded up to the NC programs' 0.1 ms); the machine stands still for the window.
    Fire {
        count: u32,
        period_s: f64,
        window_s: f64,
        #[serde(with = "shared::one")]
        laser: Arc<Laser>,
    },
}

/// The pixel runs of one image row, carried by the single lit `Line` that crosses the row.
///
/// Why not one `Line` per run: a 1000 × 1000 photo has about a million runs, and an op costs
/// some 480 B through evaluation, lead-ins, planning and poses; a run here costs 8 B. The
/// planner sees the row as what it is for the machine, one straight move at constant speed
/// (the runs only change the power), and the emitter expands it into one block per run at
/// write time. Run ends are kept as pixel columns, not lengths, so each block's end is
/// computed exactly as a `Line` per run would have been (`Frame::to_part` of the column).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PixelRow {
    /// The image frame: its lower-left corner (part mm) and the row direction (rad from +x).
    pub origin: [f64; 2],
    pub angle: f64,
    /// This row's `v` in the frame, the pixel size along `u` and the row's shift along `u`
    /// (`line_offset` on a backward row), mm.
    pub v: f64,
    pub px: f64,
    pub shift: f64,
    /// Power of shade 1..=255 between these (shade 0 is 0 W: a white run kept lit), W.
    pub min_w: f64,
    pub max_w: f64,
    /// In scan order: the pixel column where each run ends, and its shade.
    pub runs: Vec<(u32, u8)>,
}

impl PixelRow {
    /// The power of a shade (see [`PixelRow::min_w`]).
    pub fn power_w(&self, shade: u8) -> f64 {
        match shade {
            0 => 0.0,
            s => self.min_w + (self.max_w - self.min_w) * f64::from(s) / 255.0,
        }
    }

    /// The power set where the row passes part point `p` (x, y): the shade of the run over
    /// it (the first or last run's before or past the row's ends).
    pub fn power_w_at(&self, p: [f64; 2]) -> f64 {
        let (sin, cos) = self.angle.sin_cos();
        let (dx, dy) = (p[0] - self.origin[0], p[1] - self.origin[1]);
        // In pixel columns along the row, the row's shift taken off.
        let col = ((dx * cos + dy * sin) - self.shift) / self.px;
        let backward = self.runs.len() > 1 && self.runs[1].0 < self.runs[0].0;
        let run = self
            .runs
            .iter()
            .find(|r| {
                if backward {
                    f64::from(r.0) < col
                } else {
                    f64::from(r.0) > col
                }
            })
            .or(self.runs.last());
        run.map_or(0.0, |r| self.power_w(r.1))
    }

    /// The part point (x, y) where a run ending at column `c` ends.
    pub fn end_of(&self, c: u32) -> [f64; 2] {
        let f = crate::raster::Frame::new(
            crate::geometry::V2::new(self.origin[0], self.origin[1]),
            self.angle,
        );
        let p = f.to_part(f64::from(c) * self.px + self.shift, self.v);
        [p.x, p.y]
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Op {
    pub kind: OpKind,
    pub span: Span,
}

impl Op {
    pub fn laser(&self) -> Option<&Laser> {
        self.shared_laser().map(|l| &**l)
    }

    /// [`Op::laser`] as the op holds it, shared with the ops that carry the same laser: a
    /// stage that makes ops from ops (leads, kerf offsets) shares it on.
    pub fn shared_laser(&self) -> Option<&Arc<Laser>> {
        match &self.kind {
            OpKind::Line { laser, .. } | OpKind::Arc { laser, .. } => laser.as_ref(),
            _ => None,
        }
    }

    /// The orientation a motion op ends in, if it sets one.
    pub fn orient(&self) -> Option<Orient> {
        match &self.kind {
            OpKind::Rapid { orient, .. } | OpKind::Line { orient, .. } => {
                orient.as_deref().copied()
            }
            _ => None,
        }
    }

    /// The end point of a motion op.
    pub fn target(&self) -> Option<P3> {
        match &self.kind {
            OpKind::Rapid { to, .. } | OpKind::Line { to, .. } | OpKind::Arc { to, .. } => {
                Some(*to)
            }
            _ => None,
        }
    }

    /// A lit feed move's programmed feed (mm/s) and laser; `None` for any other op.
    pub fn lit_feed(&self) -> Option<(f64, &Laser)> {
        match &self.kind {
            OpKind::Line {
                feed_mm_s,
                laser: Some(l),
                ..
            }
            | OpKind::Arc {
                feed_mm_s,
                laser: Some(l),
                ..
            } => Some((*feed_mm_s, l)),
            _ => None,
        }
    }

    /// Whether this motion op moves the spot from `from` (a zero-length line is no move: emit
    /// writes nothing for it, since G0/G1 without axis words is an error in rs274ngc, and the
    /// planner drops it).
    pub fn moves_from(&self, from: P3) -> bool {
        match &self.kind {
            OpKind::Arc { .. } => true,
            OpKind::Rapid { to, .. } | OpKind::Line { to, .. } => {
                (0..3).any(|k| (to[k] - from[k]).abs() > 1e-12)
            }
            _ => false,
        }
    }

    /// An arc op's circle as seen from `from`: radius, start angle and signed sweep (rad).
    pub fn arc_from(&self, from: P3) -> Option<(f64, f64, f64)> {
        let OpKind::Arc {
            to, center, ccw, ..
        } = &self.kind
        else {
            return None;
        };
        Some(arc_circle(from, *to, *center, *ccw))
    }

    /// Length of this motion op from `from`, mm (part space; a helix for an arc that climbs);
    /// 0 for an op that does not move.
    pub fn length_from(&self, from: P3) -> f64 {
        match (self.arc_from(from), self.target()) {
            (Some((r, _, sweep)), Some(to)) => (r * sweep).hypot(to[2] - from[2]),
            (None, Some(to)) => dist(from, to),
            _ => 0.0,
        }
    }
}

// The memory budget per move (`runtime/tests/plan_memory.rs`) counts on it.
const _: () = assert!(std::mem::size_of::<Op>() <= 72);

/// Serde for a shared laser: written as the laser itself, as before it was shared (a program's
/// JSON does not change), and read back into a new `Arc` per op.
mod shared {
    use super::{Arc, Laser};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(l: &Option<Arc<Laser>>, s: S) -> Result<S::Ok, S::Error> {
        l.as_deref().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Arc<Laser>>, D::Error> {
        Ok(Option::<Laser>::deserialize(d)?.map(Arc::new))
    }

    /// The same for a laser that is always there (`OpKind::Fire`).
    pub mod one {
        use super::{Arc, Deserialize, Deserializer, Laser, Serialize, Serializer};

        pub fn serialize<S: Serializer>(l: &Arc<Laser>, s: S) -> Result<S::Ok, S::Error> {
            (**l).serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Arc<Laser>, D::Error> {
            Laser::deserialize(d).map(Arc::new)
        }
    }
}

/// An arc from `from` to `to` about `center` (ccw or not) as radius, start angle and signed
/// sweep (rad): what lowering it into chords, cutting it into sub-blocks and measuring it need.
pub fn arc_circle(from: P3, to: P3, center: [f64; 2], ccw: bool) -> (f64, f64, f64) {
    let r = (from[0] - center[0]).hypot(from[1] - center[1]);
    let a0 = (from[1] - center[1]).atan2(from[0] - center[0]);
    let a1 = (to[1] - center[1]).atan2(to[0] - center[0]);
    (r, a0, arc_sweep(a0, a1, ccw, from, to))
}

/// The signed sweep from angle `a0` to `a1` in the given direction; a full turn when the end
/// equals the start.
pub fn arc_sweep(a0: f64, a1: f64, ccw: bool, from: P3, to: P3) -> f64 {
    use std::f64::consts::TAU;
    let same = (from[0] - to[0]).abs() < 1e-9 && (from[1] - to[1]).abs() < 1e-9;
    if same {
        return if ccw { TAU } else { -TAU };
    }
    let mut d = a1 - a0;
    if ccw {
        while d <= 0.0 {
            d += TAU;
        }
    } else {
        while d >= 0.0 {
            d -= TAU;
        }
    }
    d
}

pub use crate::machine::Ramp;

/// Planner settings in force for the program (machine defaults, overridden by `planner`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannerSettings {
    pub ramp: Ramp,
    pub junction_deviation_mm: f64,
    pub arc_tolerance_mm: f64,
    pub lookahead: Option<usize>,
    /// Lead-ins and lead-outs around lit sections (`planner { leadin auto|none }`).
    #[serde(default)]
    pub leadin: LeadIn,
    /// The order the job's paths are cut in (`planner { order ... }`).
    #[serde(default, skip_serializing_if = "CutOrder::is_source")]
    pub order: CutOrder,
    /// Where the recipe's zero is on the machine (`planner { origin ... }`; the binary's
    /// `--origin` overrides it).
    #[serde(default, skip_serializing_if = "JobOrigin::is_absolute")]
    pub origin: JobOrigin,
}

/// Where a job's zero is (issue 20): the controller's coordinates, or the spot's position when
/// the job starts.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JobOrigin {
    #[default]
    Absolute,
    Current,
    /// A named work offset, G54 … G59 by its G number (issue 20).
    Work(u8),
}

impl JobOrigin {
    fn is_absolute(&self) -> bool {
        *self == JobOrigin::Absolute
    }
}

/// The order a job's paths are cut in (`planner { order source|nearest|inner_first }`; see
/// `eval::order`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CutOrder {
    /// As written.
    #[default]
    Source,
    /// Nearest path next, each entered where it is nearest.
    Nearest,
    /// As `Nearest`, with every path inside a closed path cut before it.
    InnerFirst,
}

impl CutOrder {
    fn is_source(&self) -> bool {
        *self == CutOrder::Source
    }
}

/// Whether lase adds lead-ins and lead-outs so that the beam is only on at the programmed speed
/// (PROCESS.md §4, transition points).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LeadIn {
    /// Lengths from the active profile and limits (see `motion::leadin`).
    #[default]
    Auto,
    /// The program as written: the beam is on while the speed ramps (`leadin none`).
    Off,
}

/// Per-axis limits in force (machine limits, tightened by `limits`), internal units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxisLimit {
    pub v: f64,
    pub a: f64,
    pub j: f64,
}

impl AxisLimit {
    /// A machine's own limits, one per axis (before any `limits` statement).
    pub fn of_machine(machine: &Machine) -> Vec<AxisLimit> {
        machine
            .axes
            .iter()
            .map(|a| AxisLimit {
                v: a.v_max,
                a: a.a_max,
                j: a.j_max,
            })
            .collect()
    }
}

/// Extra limits along the path (`limits { path: ... }`); infinite when not given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathLimits {
    pub v: f64,
    pub a: f64,
    pub j: f64,
}

impl Default for PathLimits {
    fn default() -> Self {
        PathLimits {
            v: f64::INFINITY,
            a: f64::INFINITY,
            j: f64::INFINITY,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProcessProgram {
    /// The recipe's file name, for headers and reports.
    pub recipe: String,
    pub machine: Machine,
    /// Limits per machine axis, in the machine's axis order.
    pub limits: Vec<AxisLimit>,
    pub path_limits: PathLimits,
    pub planner: PlannerSettings,
    /// Where the spot is when the program starts (part coordinates).
    pub start: P3,
    pub ops: Vec<Op>,
    /// What `planner { order ... }` did, when it ordered the paths.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ordering: Option<OrderReport>,
    /// Row starts to settle in a closed loop before the row fires (`scan … { settle }`),
    /// in op order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub settles: Vec<Settle>,
}

/// The travel of a job's paths as written and as ordered (`planner { order ... }`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OrderReport {
    /// Paths (a rapid and the cut after it) the order moved among.
    pub paths: usize,
    /// Length of the rapids in source order, mm.
    pub source_travel_mm: f64,
    /// Length of the rapids as ordered, mm.
    pub travel_mm: f64,
}

impl ProcessProgram {
    /// The program with its part coordinates moved by `by` (issue 20's job origin at the
    /// controller's current position: the recipe's zero is where the spot stands when the
    /// job starts). Every position moves, arc centres and the start included; nothing else
    /// changes, so the plan and the NC are the same job in another place.
    pub fn translated(mut self, by: P3) -> ProcessProgram {
        let add = |p: &mut P3| {
            for (c, d) in p.iter_mut().zip(by) {
                *c += d;
            }
        };
        add(&mut self.start);
        for op in &mut self.ops {
            match &mut op.kind {
                OpKind::Rapid { to, .. } | OpKind::Line { to, .. } => add(to),
                OpKind::Arc { to, center, .. } => {
                    add(to);
                    center[0] += by[0];
                    center[1] += by[1];
                }
                _ => {}
            }
        }
        self
    }

    /// The frame of the lit work (`lase frame`, issue 20): the bounding box of every lit move
    /// (arcs by their extreme points, not their ends only), traced once with the beam off at
    /// `feed_mm_s` from the corner nearest the start, then a rapid back to the start, so the
    /// operator sees where the job will burn before it does. `None` when nothing is lit.
    /// `pointer_w`: the trace lit at the machine's pointer power (`[laser] pointer`), so the
    /// operator sees the spot go round, instead of dark.
    pub fn frame(&self, feed_mm_s: f64, pointer_w: Option<f64>) -> Option<ProcessProgram> {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        let mut grow = |p: [f64; 2]| {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        };
        let mut at = self.start;
        let mut first: Option<(P3, Span)> = None;
        for op in &self.ops {
            if op.lit_feed().is_some() {
                first.get_or_insert((at, op.span));
                grow([at[0], at[1]]);
                let to = op.target().unwrap_or(at);
                grow([to[0], to[1]]);
                if let (Some((r, a0, sweep)), OpKind::Arc { center, .. }) =
                    (op.arc_from(at), &op.kind)
                {
                    // The circle's extreme points (0°, 90°, 180°, 270°) the sweep passes.
                    for q in -6..=6 {
                        let a = f64::from(q) * std::f64::consts::FRAC_PI_2;
                        let t = (a - a0) / sweep;
                        if t > 0.0 && t < 1.0 {
                            grow([center[0] + r * a.cos(), center[1] + r * a.sin()]);
                        }
                    }
                }
            }
            if let Some(t) = op.target() {
                at = t;
            }
        }
        let (z_at, span) = first?;
        let z = z_at[2];
        let corners = [
            [lo[0], lo[1], z],
            [hi[0], lo[1], z],
            [hi[0], hi[1], z],
            [lo[0], hi[1], z],
        ];
        let k0 = (0..4)
            .min_by(|&i, &j| dist(corners[i], self.start).total_cmp(&dist(corners[j], self.start)))
            .unwrap_or(0);
        let mut ops = vec![Op {
            kind: OpKind::Rapid {
                to: corners[k0],
                orient: None,
            },
            span,
        }];
        for k in 1..=4 {
            ops.push(Op {
                kind: OpKind::Line {
                    to: corners[(k0 + k) % 4],
                    feed_mm_s,
                    laser: pointer_w.map(|w| {
                        Arc::new(Laser {
                            power_w: w,
                            spot_mm: 0.0,
                            pulse: None,
                            couple: Coupling::None,
                            kerf_mm: 0.0,
                        })
                    }),
                    row: None,
                    orient: None,
                },
                span,
            });
        }
        ops.push(Op {
            kind: OpKind::Rapid {
                to: self.start,
                orient: None,
            },
            span,
        });
        Some(ProcessProgram {
            ops,
            ordering: None,
            ..self.clone()
        })
    }
}

/// One row start to position from the controller's reading before its row fires (PROCESS.md
/// §3): the table stops where op `op` ends, and corrective steps bring the reading within
/// the window. Errors are counted from the programmed position (from the origin A, never
/// from the previous row), so they cannot accumulate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Settle {
    /// The op that brings the table to the row start.
    pub op: usize,
    /// The first op after the row's moves (exclusive end): the ops `op + 1 .. end` are the
    /// row, which a live link writes relative to its settled start (`emit`'s `G91` rows), so
    /// the row fires where the scale said it started.
    #[serde(default)]
    pub end: usize,
    /// The row's direction of travel, a unit vector in part x, y: "along" is measured on it,
    /// "across" on it turned +90°.
    pub dir: [f64; 2],
    /// Accepted error along the row (low, high), mm.
    pub window_mm: (f64, f64),
    /// Accepted error across the row, either way, mm.
    pub across_mm: f64,
    /// One corrective step, mm.
    pub step_mm: f64,
    pub max_steps: u32,
    pub timeout_s: f64,
    /// Pass and row (from 0), for reports.
    pub pass: u32,
    pub row: u32,
    /// The recipe's `settle` setting (or the scan, when only `settle_*` turned it on).
    pub span: Span,
}

impl Settle {
    /// The error (along, across) of a position `dx`, `dy` mm from the target.
    pub fn error(&self, dx: f64, dy: f64) -> (f64, f64) {
        let [ux, uy] = self.dir;
        (dx * ux + dy * uy, -dx * uy + dy * ux)
    }

    /// Whether an error (along, across) is within the window.
    pub fn within(&self, along: f64, across: f64) -> bool {
        const EPS: f64 = 1e-9;
        along >= self.window_mm.0 - EPS
            && along <= self.window_mm.1 + EPS
            && across.abs() <= self.across_mm + EPS
    }

    /// The corrective move (dx, dy) for an error: one step back along the row when past the
    /// window, forward when short; the same across. `None` when within.
    pub fn correction(&self, along: f64, across: f64) -> Option<(f64, f64)> {
        if self.within(along, across) {
            return None;
        }
        let s = self.step_mm;
        let a = if along < self.window_mm.0 {
            s
        } else if along > self.window_mm.1 {
            -s
        } else {
            0.0
        };
        let c = if across < -self.across_mm {
            s
        } else if across > self.across_mm {
            -s
        } else {
            0.0
        };
        let [ux, uy] = self.dir;
        Some((a * ux - c * uy, a * uy + c * ux))
    }
}

/// An op that asks more of the machine's laser than it can give. The codes and wording are
/// the evaluator's (it reports the same rule while it runs, as `EvalError`), so a recipe reads
/// the same diagnostic whichever phase finds it.
#[derive(Debug, Clone, PartialEq, thiserror::Error, Diagnostic)]
pub enum LaserLimit {
    #[error("laser power {value} is above the machine's {limit}")]
    #[diagnostic(code(lase::eval::above_machine))]
    Power {
        value: String,
        limit: String,
        #[label("too high for this machine")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("pulse rate {rate} is above the laser's maximum {max}")]
    #[diagnostic(code(lase::eval::pulse_rate))]
    PulseRate {
        rate: String,
        max: String,
        #[label("{label}")]
        span: Span,
        /// "at this speed" for pulses by distance (the evaluator's label in every case).
        label: String,
        #[help]
        help: Option<String>,
    },

    #[error("the program would fire about {count} pulses, above the {max} lase handles")]
    #[diagnostic(code(lase::eval::too_large))]
    Pulses {
        count: String,
        max: String,
        #[label("the pulses pass the budget here")]
        span: Span,
        #[help]
        help: Option<String>,
    },
}

impl LaserLimit {
    pub fn span(&self) -> Span {
        match self {
            LaserLimit::Power { span, .. }
            | LaserLimit::PulseRate { span, .. }
            | LaserLimit::Pulses { span, .. } => *span,
        }
    }
}

/// Pulses a program may fire: ten times a million-dimple texture. Planning, the pulse report
/// and the emitter walk every pulse, so the count is held before anything is planned (a pulse
/// every 1e-12 mm over 10 mm would be 1e13 of them).
pub const MAX_PULSES: f64 = 10_000_000.0;

/// About how many pulses `op` fires from `from`: a lower bound (the lit length over the
/// pitch, or the lit time at the programmed feed over the period, plus the first), since
/// ramps only lengthen the lit time.
fn pulses_of(op: &Op, from: P3) -> f64 {
    let (feed, laser) = match (&op.kind, op.lit_feed()) {
        (_, Some(lit)) => lit,
        (OpKind::Fire { count, .. }, _) => return f64::from(*count),
        _ => return 0.0,
    };
    let length = op.length_from(from);
    match laser.pulse.as_ref().map(|p| p.mode) {
        Some(PulseMode::Distance { pitch_mm }) => length / pitch_mm + 1.0,
        Some(PulseMode::Time { period_s }) => length / feed / period_s + 1.0,
        None => 0.0,
    }
}

/// Limits are met within this relative margin, so a value computed to equal the limit
/// (`rate = feed / pitch` at the fastest allowed feed) passes.
const LIMIT_MARGIN: f64 = 1e-12;

/// Laser power `power_w` within what `machine`'s laser gives.
pub fn check_power(power_w: f64, machine: &Machine, span: Span) -> Result<(), LaserLimit> {
    let max = machine.laser.max_power_w;
    if power_w > max * (1.0 + LIMIT_MARGIN) {
        return Err(LaserLimit::Power {
            value: format_quantity(power_w, Dim::POWER),
            limit: format_quantity(max, Dim::POWER),
            span,
            help: Some(format!(
                "`{}`'s laser gives at most {}",
                machine.name,
                format_quantity(max, Dim::POWER)
            )),
        });
    }
    Ok(())
}

/// A pulse rate within the laser's maximum: `rate_hz` is `feed / pitch` for pulses by distance
/// (`pitch_mm` given: the help then names the fastest feed allowed) or `1 / period` by time.
pub fn check_pulse_rate(
    rate_hz: f64,
    pitch_mm: Option<f64>,
    machine: &Machine,
    span: Span,
) -> Result<(), LaserLimit> {
    let max = machine.laser.max_pulse_rate_hz;
    if rate_hz > max * (1.0 + LIMIT_MARGIN) {
        let (label, help) = match pitch_mm {
            Some(pitch) => (
                "at this speed",
                format!(
                    "with pulses every {} the fastest allowed speed is {}",
                    format_quantity(pitch, Dim::LENGTH),
                    format_quantity(max * pitch, Dim::SPEED)
                ),
            ),
            None => (
                "pulses by time too close together",
                format!(
                    "`{}`'s laser fires at most {}: lower `rate`, or lengthen `interval`",
                    machine.name,
                    format_quantity(max, Dim::FREQUENCY)
                ),
            ),
        };
        return Err(LaserLimit::PulseRate {
            rate: format_quantity(rate_hz, Dim::FREQUENCY),
            max: format_quantity(max, Dim::FREQUENCY),
            span,
            label: label.into(),
            help: Some(help),
        });
    }
    Ok(())
}

impl Laser {
    /// The pulse rate of this laser's pulses on a move at `feed_mm_s`, held to the laser's
    /// maximum (no pulses, or pulses by time with no period yet: nothing to hold).
    pub fn check_pulse_rate(
        &self,
        feed_mm_s: f64,
        machine: &Machine,
        span: Span,
    ) -> Result<(), LaserLimit> {
        match self.pulse.as_ref().map(|p| p.mode) {
            Some(PulseMode::Distance { pitch_mm }) => {
                check_pulse_rate(feed_mm_s / pitch_mm, Some(pitch_mm), machine, span)
            }
            Some(PulseMode::Time { period_s }) if period_s > 0.0 && period_s.is_finite() => {
                check_pulse_rate(1.0 / period_s, None, machine, span)
            }
            _ => Ok(()),
        }
    }
}

impl ProcessProgram {
    /// Holds every lit op to the machine's laser: power within its range, the pulse rate
    /// (pulses by distance at the op's feed, by time, or a dot-mode fire window) within its
    /// maximum. Each problem is reported once per recipe statement (the ops of one `follow`
    /// share its span), at that statement.
    pub fn validate(&self) -> Result<(), Vec<LaserLimit>> {
        let m = &self.machine;
        let mut errors: Vec<LaserLimit> = Vec::new();
        let mut note = |e: LaserLimit| {
            let same = |o: &LaserLimit| {
                o.span() == e.span() && std::mem::discriminant(o) == std::mem::discriminant(&e)
            };
            if !errors.iter().any(same) {
                errors.push(e);
            }
        };
        let (mut pulses, mut over) = (0.0, false);
        let mut at = self.start;
        for op in &self.ops {
            pulses += pulses_of(op, at);
            at = op.target().unwrap_or(at);
            if !(pulses <= MAX_PULSES) && !over {
                over = true;
                // Once: the first op past the budget is where the recipe asks too much.
                note(LaserLimit::Pulses {
                    count: units::format_number(pulses.round()),
                    max: units::format_number(MAX_PULSES),
                    span: op.span,
                    help: Some(
                        "lengthen the pulse `interval` (or lower the `rate`), or shorten the \
                         lit path; a job this size belongs in several recipes"
                            .into(),
                    ),
                });
            }
            let r = match (&op.kind, op.lit_feed()) {
                (_, Some((feed, l))) => [
                    check_power(l.power_w, m, op.span),
                    l.check_pulse_rate(feed, m, op.span),
                ],
                (
                    OpKind::Fire {
                        period_s, laser, ..
                    },
                    _,
                ) => [
                    check_power(laser.power_w, m, op.span),
                    check_pulse_rate(1.0 / period_s, None, m, op.span),
                ],
                _ => continue,
            };
            for e in r.into_iter().filter_map(Result::err) {
                note(e);
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors)
        }
    }
}

#[cfg(test)]
mod tests;

#[cfg(test)]
mod frame_tests;
