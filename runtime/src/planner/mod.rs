//! Look-ahead motion planner: timed motion from a sequence of straight moves in axis space.
//!
//! Owns the time law of the machine: per-move speed/acceleration/jerk limits, corner speeds,
//! look-ahead, and the trapezoid and 7-phase S-curve velocity profiles of PROCESS.md §4. It is
//! pure math on plain data: no IO, no recipe syntax, no G-code; the caller hands in moves with
//! axis targets and path lengths and gets back a [`Plan`] it can sample at any instant.
//!
//! The path of one move through [`plan`]:
//! 1. `prepare` validates it, merges a zero-length move into its predecessor, and derives its
//!    limits from its direction `u = Δq / length`: `v ≤ min_i v_i / |u_i|` (likewise `a`, `j`),
//!    the path limits and the feed. Corners taken at speed are planned by one of two models
//!    ([`Corners`]):
//!    - `Blend` (what lase plans its jobs with): each corner is rounded by a curve within the
//!      corner tolerance whose axis velocity and acceleration are continuous, with its own
//!      speed, acceleration and jerk limits so that every axis stays within its limits along
//!      it (`blend`); a corner that cannot be rounded is a stop. Each move is split into the
//!      half-blend after its start corner, its straight middle and the half-blend before its
//!      end corner, all three with the move's tag. A corner between two moves that both keep
//!      the velocity step (`Along::step_corners`: the lit chords of an oriented machine whose
//!      blended plan could not hold the lit speed) is planned as under `JunctionDeviation`;
//!      every other corner, lit or not, is blended.
//!    - `JunctionDeviation` (GRBL's model, kept for comparison and its own tests): the entry
//!      speed is capped by the corner model (`junction`: GRBL's junction deviation and
//!      Klipper's centripetal cap where the length is the axis-space arc length, as on
//!      Cartesian machines; otherwise, as for the part-space chords of oriented machines, each
//!      axis's velocity jump against that axis's own acceleration), and a move that lies
//!      wholly on the rounding curves of its two corners (a chord of a curve) gets a speed and
//!      acceleration budget shared between centripetal and tangential acceleration
//!      (`curve_limits`). Axis velocities step at corners.
//! 2. `lookahead` chooses entry and exit speeds with a backward and a forward pass, over the
//!    whole program or through a bounded streaming window.
//! 3. As the forward pass commits each move's end speeds, `profile` turns (length, entry, exit,
//!    limits) into the fastest ramp-cruise-ramp shape.
//! 4. The result is stored as a compact [`Segment`] (120 bytes) plus its start point in a flat
//!    table of the axes in use; [`Plan::sample`] evaluates it exactly (on a blend, along the
//!    blend curve).
//!
//! In windows ([`plan_along_windows`], `window`): the same steps run as the moves come in,
//! each on a small buffer, and the look-ahead hands on a prefix of segments once no later move
//! can change it, so the caller reads the plan a window at a time and it never exists whole;
//! the windows are the whole plan, bit for bit.
//!
//! Memory of a whole plan: 120 bytes of segment and `8 · n_axes` of points per move (136 bytes
//! for two axes, 168 for six), and nothing else per move: the look-ahead reads each move's limits from its
//! segment before timing it (`lookahead::KinTable`), and the corner blends' per-move input is
//! a byte of flags (`blend::MoveInfos`) while the corners are judged. A blended corner adds two
//! segments, which keep no point, and its blend, `(2·n_axes + 1)·8 + 1` bytes ([`Blends`]: 41
//! for two axes); the split makes them in the prepared moves' own table (`blend/expand.rs`).
//!
//! Known limit: every S-curve move starts and ends at zero path acceleration, so acceleration
//! is continuous everywhere, but a run of very short moves gains speed in small jerk-limited
//! steps (0.1 mm chords at 40 000 mm/s³ plan about 3× slower than trapezoids). Spreading one
//! jerk-limited ramp over several straight-enough moves would lift that.
//!
//! Module map: `error` (diagnostics), `junction` (corner speeds), `lookahead` (speed passes),
//! `profile` (1-D closed forms), `plan` (segments and sampling), `blend` (corner blends),
//! `window` (planning in windows).

mod blend;
mod error;
mod junction;
mod lookahead;
mod plan;
mod profile;
mod window;

pub use blend::{Blend, Blends, REACH_MAX as BLEND_REACH_MAX};
pub use error::PlanError;
pub use plan::{Plan, Sample, Segment};
pub use window::{MIN_WINDOW, Planned, plan_along_windows, plan_along_windows_sized};

use lookahead::Kin;

/// Positions and per-axis quantities are machine axes in internal units (mm, rad).
pub use crate::axes::{Axes, MAX_AXES};

/// Which velocity profile every move gets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ProfileKind {
    /// Constant-acceleration ramps (jerk unlimited); a triangle when a move is too short.
    #[default]
    Trapezoid,
    /// 7-phase jerk-limited profile (PROCESS.md §4).
    SCurve,
}

/// How corners taken at speed are planned.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Corners {
    /// GRBL's and Klipper's model: the path runs through the corner point and each axis's
    /// velocity steps there, within the junction-deviation and centripetal caps (`junction`).
    /// What a GRBL controller does; not feasible per axis at every instant.
    #[default]
    JunctionDeviation,
    /// Every corner passed at speed follows a blend curve within the corner tolerance, planned
    /// so that each axis keeps its velocity, acceleration and jerk limits along it (`blend`);
    /// corners it cannot round are stops. What lase plans its jobs with (issue 13).
    Blend,
}

/// Per-axis limits, in machine units per s, s², s³. Axes in use need values > 0;
/// `f64::INFINITY` means unlimited.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisLimits {
    pub v: [f64; MAX_AXES],
    pub a: [f64; MAX_AXES],
    pub j: [f64; MAX_AXES],
}

/// How to plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlannerConfig {
    pub profile: ProfileKind,
    /// Corner deviation δ of the GRBL/Klipper junction model, in path units (mm); the per-axis
    /// rule of oriented moves turns it into a blend time with the path acceleration
    /// (`junction`). 0 stops at every corner; `f64::INFINITY` takes corners at the moves' full
    /// speed.
    pub junction_deviation: f64,
    /// Path speed limit (`f64::INFINITY` = none).
    pub path_v: f64,
    /// Path acceleration limit (`f64::INFINITY` = none).
    pub path_a: f64,
    /// Path jerk limit (`f64::INFINITY` = none).
    pub path_j: f64,
    /// `None`: look ahead over the whole program (offline). `Some(n)`: a streaming controller
    /// that commits each move's exit speed knowing only the next `n` moves, and the last of
    /// them must be able to stop (see the `lookahead` module).
    pub lookahead: Option<usize>,
    /// How many of the [`MAX_AXES`] axes are in use (1..=6).
    pub n_axes: usize,
    /// How corners taken at speed are planned; `junction_deviation` is their tolerance.
    pub corners: Corners,
}

impl Default for PlannerConfig {
    /// Trapezoid, offline, 3 axes, GRBL's default junction deviation of 0.01 mm, no path
    /// limits.
    fn default() -> Self {
        PlannerConfig {
            profile: ProfileKind::Trapezoid,
            junction_deviation: 0.01,
            path_v: f64::INFINITY,
            path_a: f64::INFINITY,
            path_j: f64::INFINITY,
            lookahead: None,
            n_axes: 3,
            corners: Corners::JunctionDeviation,
        }
    }
}

/// One straight move in axis space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Move {
    /// Axis positions at the end of the move (mm or rad).
    pub target: Axes,
    /// Path length; the path parameter s runs 0..length and `q(s) = q0 + (s/length)·Δq`.
    /// Euclidean for Cartesian moves, the part-space distance for multi-axis chords.
    /// Length 0 without axis change: merged into the previous move; with a change: an error.
    pub length: f64,
    /// Programmed path speed (path units/s); `f64::INFINITY` = rapid.
    pub feed: f64,
    /// Stop point after the move: speed exactly 0 at its end.
    pub stop_after: bool,
    /// Standstill after the move, in s (implies `stop_after` when > 0).
    pub dwell_after: f64,
    /// Caller's id of what produced the move.
    pub tag: u32,
}

impl Move {
    /// A move to `target` over `length` at `feed`, without stop or dwell, tag 0.
    pub fn new(target: impl Into<Axes>, length: f64, feed: f64) -> Move {
        Move {
            target: target.into(),
            length,
            feed,
            stop_after: false,
            dwell_after: 0.0,
            tag: 0,
        }
    }

    /// A move whose length is the Euclidean distance in axis space from `from`.
    pub fn linear(from: impl Into<Axes>, target: impl Into<Axes>, feed: f64) -> Move {
        let (from, target) = (from.into(), target.into());
        let mut d2 = 0.0;
        for i in 0..MAX_AXES {
            d2 += (target[i] - from[i]) * (target[i] - from[i]);
        }
        Move::new(target, d2.sqrt(), feed)
    }
}

/// Path distance a jerk-limited speed change from `v_from` to `v_to` needs (either
/// direction), with path acceleration `a` and jerk `j` (`j = f64::INFINITY` for a trapezoid
/// ramp). PROCESS.md §4's look-ahead preprocessing uses it to place the point where a cut reaches
/// its feed: from rest to feed `F` takes `speed_change_distance(0, F, a, j)`, which for a full
/// S-curve ramp is `S03 = F/2 · (F/a + a/J)`. Returns NaN for negative or NaN inputs.
pub fn speed_change_distance(v_from: f64, v_to: f64, a: f64, j: f64) -> f64 {
    if !(v_from >= 0.0 && v_to >= 0.0 && a > 0.0 && j > 0.0) {
        return f64::NAN;
    }
    profile::ramp_distance(v_from.min(v_to), (v_to - v_from).abs(), a, j)
}

/// Path limits `(v, a, j)` of a straight move with axis motion `dq` over path length `length`
/// at programmed `feed`: the tightest axis along the direction `u = Δq / length` sets each
/// (`v ≤ min_i v_i / |u_i|`, likewise `a`, `j`), then the path limits and the feed. `j` is
/// infinite for the trapezoid profile. This is the very computation [`plan`] makes for each
/// move, so a caller that places transition points (PROCESS.md §4 look-ahead preprocessing)
/// works with the limits the plan will use.
// One index over the parallel axis arrays.
#[allow(clippy::needless_range_loop)]
pub fn move_limits(
    dq: &[f64; MAX_AXES],
    length: f64,
    feed: f64,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> (f64, f64, f64) {
    let mut v = feed.min(cfg.path_v);
    let mut a = cfg.path_a;
    if cfg.profile == ProfileKind::Trapezoid {
        for axis in 0..cfg.n_axes.min(MAX_AXES) {
            let u = dq[axis].abs() / length;
            if u > 0.0 {
                v = v.min(limits.v[axis] / u);
                a = a.min(limits.a[axis] / u);
            }
        }
        return (v, a, f64::INFINITY);
    }
    let mut j = cfg.path_j;
    for axis in 0..cfg.n_axes.min(MAX_AXES) {
        let u = dq[axis].abs() / length;
        if u > 0.0 {
            v = v.min(limits.v[axis] / u);
            a = a.min(limits.a[axis] / u);
            j = j.min(limits.j[axis] / u);
        }
    }
    (v, a, j)
}

/// Length a lead-in (or lead-out) needs so that a move of speed limit `v`, acceleration `a` and
/// jerk `j` reaches `v` at its end (or slows from `v` to whatever follows) whatever its other
/// end speed `w` in `[0, w_max]` turns out to be: `max_w ramp_distance(w → v)`.
///
/// From rest this is [`speed_change_distance`]`(0, v, a, j)`, the distance PROCESS.md §4 moves
/// the transition point by. It is not always the maximum: a jerk-limited ramp that starts
/// moving covers more ground than one from rest (see `profile::entry_limit`), so when the
/// lead-in may be entered at speed the worst entry speed is searched. Each piece of
/// `w ↦ ramp_distance(w, v − w)` is concave (with constant-acceleration phase:
/// `(v + w)/2 · ((v − w)/a + a/J)`, stationary at `w = a²/2J`; without: `(v + w)·√((v − w)/J)`,
/// stationary at `w = v/3`), so the maximum lies at one of those points, at the border
/// `w = v − a²/J` between the pieces, or at an end of `[0, w_max]`. NaN for bad inputs.
pub fn lead_distance(v: f64, w_max: f64, a: f64, j: f64) -> f64 {
    if !(v >= 0.0 && w_max >= 0.0 && a > 0.0 && j > 0.0) {
        return f64::NAN;
    }
    let hi = w_max.min(v);
    let f = |w: f64| profile::ramp_distance(w, v - w, a, j);
    let border = if j == f64::INFINITY { v } else { v - a * a / j };
    [0.0, hi, v / 3.0, 0.5 * a * a / j, border]
        .into_iter()
        .filter(|w| w.is_finite())
        .map(|w| f(w.clamp(0.0, hi)))
        .fold(0.0, f64::max)
}

/// Room a lead (or a scan row's run-up) entered or left at speed keeps for the corner blends
/// at its two ends (`Corners::Blend`): each may round up to `BLEND_REACH_MAX · delta` of it,
/// which then cannot count toward its straight ramp. 0 for an infinite corner tolerance
/// (blends then reach half a move: lead-ins are not sized for that).
pub fn lead_blend_room(delta: f64) -> f64 {
    let room = 2.0 * BLEND_REACH_MAX * delta;
    if room.is_finite() { room } else { 0.0 }
}

/// Relative slack on "a move lies wholly on its corners' rounding circles": the chords of one
/// arc have equal lengths up to rounding.
const CURVED_TOL: f64 = 1e-9;

/// Relative slack on "the move's length is its Euclidean length in axis space" (`junction`:
/// which corner rule applies). Cartesian lowering gives equal numbers; a part-space chord of an
/// oriented machine differs by orders of magnitude.
const EUCLIDEAN_TOL: f64 = 1e-9;

/// Plans `moves` from `start` (at rest) to the last target (at rest).
///
/// Validates everything first and fails without a partial plan. Allocates the output (segments
/// and their start points; the look-ahead works in the segments themselves) and nothing else
/// per move, but for the corner blends' byte of flags a move (`blend::MoveInfos`) while
/// `Corners::Blend` judges the corners.
pub fn plan(
    start: impl Into<Axes>,
    moves: &[Move],
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> Result<Plan, PlanError> {
    plan_along(start, moves, &[], limits, cfg)
}

/// What the planner may know of a move beyond its axes (`plan_along`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Along {
    /// The spot's unit direction in part space; zero where the move is not a straight
    /// part-space move (a rapid of an oriented machine) or it is not known. Where a move's
    /// length is not its axis-space length (oriented machines) a blend's reach is bounded by
    /// the spot's turn between two known directions, else by the largest turn there is.
    pub part_dir: [f64; 3],
    /// The beam is on along the move. A corner between two lit moves is not a lead-in's: its
    /// blend may reach up to half of each move (`blend`), so the chords of a lit curve are
    /// rounded along their whole length instead of at their ends only.
    pub lit: bool,
    /// A corner between two such moves keeps the junction-deviation model (an axis velocity
    /// step) under `Corners::Blend`. lase sets it on the lit moves of an oriented machine only
    /// when the plan with every lit corner blended could not hold the lit speed (the arm's
    /// sections at 10 mm/s, whose runs of chords break where the chords are halved; issue 13,
    /// item 3: what is left).
    pub step_corners: bool,
}

/// [`plan`], told more about each move: `along[i]` belongs to `moves[i]` (a shorter slice
/// leaves the rest at `Along::default()`).
pub fn plan_along(
    start: impl Into<Axes>,
    moves: &[Move],
    along: &[Along],
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> Result<Plan, PlanError> {
    if u32::try_from(moves.len()).is_err() {
        return Err(PlanError::TooManyMoves { count: moves.len() });
    }
    let along = moves
        .iter()
        .enumerate()
        .map(|(i, m)| (*m, along.get(i).copied().unwrap_or_default()));
    plan_along_iter(start, along, moves.len(), limits, cfg)
}

/// [`plan_along_iter`] of moves with nothing known beyond their axes.
pub fn plan_iter(
    start: impl Into<Axes>,
    moves: impl IntoIterator<Item = Move>,
    expected: usize,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> Result<Plan, PlanError> {
    let moves = moves.into_iter().map(|m| (m, Along::default()));
    plan_along_iter(start, moves, expected, limits, cfg)
}

/// [`plan`] of moves made as the planner reads them, so the caller never holds them all:
/// `motion` lowers a program of a million short moves straight into the plan's compact
/// segments (the 80-byte [`Move`]s were the largest table a job held). `expected` is how many
/// moves to make room for (the tables grow past it if there are more); a move's index in
/// errors and in [`Segment::move_index`] is its position in `moves`. Each move comes with
/// what the planner may know of it beyond its axes ([`Along`]).
pub fn plan_along_iter(
    start: impl Into<Axes>,
    moves: impl IntoIterator<Item = (Move, Along)>,
    expected: usize,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> Result<Plan, PlanError> {
    let start = start.into();
    validate(start, limits, cfg)?;
    let Prepared {
        mut segments,
        points,
        end,
        blends,
    } = prepare(start, moves.into_iter(), expected, limits, cfg)?;
    // The passes read each move's limits from its segment and time it in place.
    let mut timeline = Timeline { t: 0.0, s: 0.0 };
    let table: &mut [Segment] = &mut segments;
    match cfg.lookahead {
        Some(window) if window.saturating_add(1) < table.len() => {
            lookahead::streaming(table, window, |segs, k, m, v_in, v_out| {
                timeline.commit(&mut segs[k], m, v_in, v_out)
            })
        }
        _ => lookahead::offline(table, |segs, k, m, v_in, v_out| {
            timeline.commit(&mut segs[k], m, v_in, v_out)
        }),
    }
    let duration = timeline.t;
    let halves = plan::half_ranks(&segments);
    Ok(Plan {
        segments,
        points,
        start,
        end,
        duration,
        n_axes: cfg.n_axes,
        blends,
        blend_base: 0,
        halves,
    })
}

/// Fills in the segments' timing in order, as the look-ahead commits each move's end speeds.
struct Timeline {
    /// Start time of the next segment.
    t: f64,
    /// Path distance at the start of the next segment.
    s: f64,
}

impl Timeline {
    /// Times `seg` (its move `m`, read before: this overwrites the `Kin` the segment held).
    #[inline]
    fn commit(&mut self, seg: &mut Segment, m: &Kin, v_in: f64, v_out: f64) {
        let sh = profile::shape(m.len, v_in, v_out, m.v, m.a, m.j);
        seg.t_start = self.t;
        seg.s_start = self.s;
        seg.v_entry = sh.v0;
        seg.v_peak = sh.vp;
        seg.v_exit = sh.v1;
        seg.t_j1 = sh.t_j1;
        seg.t_a1 = sh.t_a1;
        seg.t_cruise = sh.t_c;
        seg.t_j2 = sh.t_j2;
        seg.t_a2 = sh.t_a2;
        self.t += seg.duration();
        self.s += seg.length;
    }
}

// `!(x > 0.0)` rather than `x <= 0.0`: NaN must fail every check.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn validate(start: Axes, limits: &AxisLimits, cfg: &PlannerConfig) -> Result<(), PlanError> {
    let bad = |field, value, why| Err(PlanError::BadConfig { field, value, why });
    if cfg.n_axes == 0 || cfg.n_axes > MAX_AXES {
        return bad("n_axes", cfg.n_axes as f64, "must be between 1 and 6");
    }
    if !(cfg.junction_deviation >= 0.0) {
        return bad("junction_deviation", cfg.junction_deviation, "must be >= 0");
    }
    for (field, value) in [
        ("path_v", cfg.path_v),
        ("path_a", cfg.path_a),
        ("path_j", cfg.path_j),
    ] {
        if !(value > 0.0) {
            return bad(field, value, "must be > 0 (f64::INFINITY for no limit)");
        }
    }
    for axis in 0..cfg.n_axes {
        for (kind, value) in [
            ("speed", limits.v[axis]),
            ("acceleration", limits.a[axis]),
            ("jerk", limits.j[axis]),
        ] {
            if !(value > 0.0) {
                return Err(PlanError::BadLimit { axis, kind, value });
            }
        }
    }
    for (axis, &value) in start.iter().enumerate() {
        if !value.is_finite() {
            return Err(PlanError::BadStart { axis, value });
        }
    }
    Ok(())
}

/// Validates the moves, merges zero-length ones, and derives each move's limits and junction
/// cap. Returns the segment skeletons (timing still empty), their start points (`n_axes` values
/// each), the look-ahead data and the end position.
///
/// A stop needs no flag of its own: the move after it gets entry cap 0, which is all the
/// look-ahead passes need to stop there (the program's end is a stop by position).
fn prepare(
    start: Axes,
    moves: impl Iterator<Item = (Move, Along)>,
    expected: usize,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
) -> Result<Prepared, PlanError> {
    let n_axes = cfg.n_axes;
    let mut raw = Raw {
        segments: Vec::with_capacity(expected),
        points: Vec::with_capacity(expected * n_axes),
        info: blend::MoveInfos::with_capacity(if cfg.corners == Corners::Blend {
            expected
        } else {
            0
        }),
    };
    let mut prep = Preparer::new(start, limits, cfg);
    for (index, (mv, here)) in moves.enumerate() {
        prep.push(index, &mv, here, &mut raw)?;
    }
    let Raw {
        segments,
        points,
        info,
    } = raw;
    let prepared = Prepared {
        segments,
        points,
        end: prep.q,
        blends: Blends::new(n_axes, start),
    };
    Ok(if prep.blending {
        blend::split(
            prepared,
            &info,
            start,
            cfg.junction_deviation,
            limits,
            n_axes,
        )
    } else {
        prepared
    })
}

/// The moves `Preparer` made and not yet handed on: segment skeletons (each holding its move's
/// look-ahead data, `Segment::kin`), their start points and the corner blends' flags.
pub(super) struct Raw {
    pub(super) segments: Vec<Segment>,
    pub(super) points: Vec<f64>,
    pub(super) info: blend::MoveInfos,
}

/// `prepare`, one move at a time: what it remembers of the move before. The last segment it
/// made is not final until the next move comes (a stop or a dwell that follows it, a chord's
/// curve limits), so whoever takes segments out of [`Raw`] leaves the last one in it.
pub(super) struct Preparer<'a> {
    limits: &'a AxisLimits,
    cfg: &'a PlannerConfig,
    n_axes: usize,
    scurve: bool,
    pub(super) blending: bool,
    corners: junction::CornerModel,
    /// Where the last move ended (the plan's end once every move is in).
    pub(super) q: Axes,
    /// The previous move ends at a stop point (or there is none yet).
    prev_stop: bool,
    prev_dir: Axes,
    prev_euclidean: bool,
    prev_along: Along,
    /// Centripetal cap (v²) and rounding-circle reach of the previous move's entry corner.
    prev_corner: junction::Corner,
    prev_d_in: f64,
}

impl<'a> Preparer<'a> {
    pub(super) fn new(start: Axes, limits: &'a AxisLimits, cfg: &'a PlannerConfig) -> Self {
        let n_axes = cfg.n_axes;
        let mut inv_a = [0.0; MAX_AXES];
        for (inv, a) in inv_a.iter_mut().zip(&limits.a).take(n_axes) {
            *inv = 1.0 / a;
        }
        Preparer {
            limits,
            cfg,
            n_axes,
            scurve: cfg.profile == ProfileKind::SCurve,
            blending: cfg.corners == Corners::Blend,
            corners: junction::CornerModel {
                delta: cfg.junction_deviation,
                inv_a,
                path_a: cfg.path_a,
                n_axes,
            },
            q: start,
            prev_stop: true,
            prev_dir: Axes::ZERO,
            prev_euclidean: true,
            prev_along: Along::default(),
            prev_corner: junction::Corner::AT_REST,
            prev_d_in: 0.0,
        }
    }

    /// Move number `index` of the input into `raw` (or into its last segment).
    // `!(x > 0.0)` so NaN fails; axis loops index several parallel arrays.
    #[allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]
    pub(super) fn push(
        &mut self,
        index: usize,
        mv: &Move,
        here: Along,
        raw: &mut Raw,
    ) -> Result<(), PlanError> {
        let Raw {
            segments,
            points,
            info,
        } = raw;
        if u32::try_from(index).is_err() {
            return Err(PlanError::TooManyMoves { count: index + 1 });
        }
        let (n_axes, scurve, blending) = (self.n_axes, self.scurve, self.blending);
        let (limits, cfg) = (self.limits, self.cfg);
        let bad = |field, value, why| PlanError::BadMove {
            index,
            field,
            value,
            why,
        };
        if let Some(&value) = mv.target.iter().find(|x| !x.is_finite()) {
            return Err(bad("target", value, "axis positions must be finite"));
        }
        if !(mv.length >= 0.0 && mv.length.is_finite()) {
            return Err(bad("length", mv.length, "must be finite and >= 0"));
        }
        if !(mv.feed > 0.0) {
            return Err(bad(
                "feed",
                mv.feed,
                "must be > 0 (f64::INFINITY for a rapid)",
            ));
        }
        if !(mv.dwell_after >= 0.0 && mv.dwell_after.is_finite()) {
            return Err(bad(
                "dwell_after",
                mv.dwell_after,
                "must be finite and >= 0",
            ));
        }
        let mut dq = Axes::ZERO;
        let mut norm2 = 0.0;
        for axis in 0..MAX_AXES {
            dq[axis] = mv.target[axis] - self.q[axis];
            if dq[axis] != 0.0 && axis >= n_axes {
                return Err(PlanError::UnusedAxis {
                    index,
                    axis,
                    n_axes,
                });
            }
            norm2 += dq[axis] * dq[axis];
        }
        let stop = mv.stop_after || mv.dwell_after > 0.0;
        if mv.length == 0.0 {
            if let Some(axis) = dq.iter().position(|&d| d != 0.0) {
                return Err(PlanError::ZeroLengthWithMotion {
                    index,
                    axis,
                    delta: dq[axis],
                });
            }
            // No motion: its stop and dwell belong to the previous move's end. Before any
            // motion the program is at rest already, so only a dwell needs a segment.
            if let Some(seg) = segments.last_mut() {
                seg.dwell += mv.dwell_after;
                self.prev_stop |= stop;
            } else if mv.dwell_after > 0.0 {
                segments.push(skeleton(0.0, mv, index));
                points.extend_from_slice(&self.q[..n_axes]);
                if blending {
                    info.push(blend::MoveInfo::REST);
                }
                self.prev_stop = true;
            }
            return Ok(());
        }
        if norm2 == 0.0 {
            return Err(PlanError::LengthWithoutMotion {
                index,
                length: mv.length,
            });
        }
        let (v, a, j) = move_limits(&dq, mv.length, mv.feed, limits, cfg);
        if !scurve {
            if a == f64::INFINITY {
                return Err(PlanError::Unbounded {
                    index,
                    what: "acceleration",
                });
            }
        } else if a == f64::INFINITY && j == f64::INFINITY {
            return Err(PlanError::Unbounded {
                index,
                what: "acceleration and jerk",
            });
        }
        if !(v > 0.0 && a > 0.0 && j > 0.0) {
            // Limits so small against the move's axis motion that they underflow to zero.
            return Err(bad(
                "length",
                mv.length,
                "the axis limits allow no motion along this move",
            ));
        }
        let norm = norm2.sqrt();
        // The length is the axis-space arc length (every Cartesian move): `dir` is the unit
        // direction and the Euclidean corner rule holds. Otherwise (a multi-axis chord measured
        // in part space) `dir` is `Δq / length` and corners are judged per axis (`junction`).
        let euclidean = (norm - mv.length).abs() <= EUCLIDEAN_TOL * mv.length;
        let scale = if euclidean { norm } else { mv.length };
        // Only the axes in use move (checked above): the others stay 0.
        let mut dir = Axes::ZERO;
        for axis in 0..n_axes {
            dir[axis] = dq[axis] / scale;
        }
        // Both moves keep the velocity-step model at their corner (`Along::step_corners`).
        let stepped = here.step_corners && self.prev_along.step_corners;
        // The previous move's look-ahead data, kept in its segment until it is timed.
        let mut prev_kin = segments.last().map(Segment::kin);
        let (entry_cap, corner, d_in) = match prev_kin.as_mut() {
            // Blended corners are judged once every move is known (`blend::split`).
            Some(prev) if blending && !self.prev_stop && !stepped => {
                (v.min(prev.v), junction::Corner::AT_REST, 0.0)
            }
            Some(prev) if !self.prev_stop => {
                let c = if euclidean && self.prev_euclidean {
                    self.corners
                        .corner(&self.prev_dir, &dir, prev.a, a, prev.len, mv.length)
                } else {
                    // A unit direction is `Δq / length` to within the tolerance: either kind
                    // of move enters the per-axis rule as it is.
                    self.corners.corner_per_axis(
                        &self.prev_dir,
                        &dir,
                        prev.a,
                        a,
                        prev.len,
                        mv.length,
                    )
                };
                let d = if c.centripetal_v2 == f64::INFINITY {
                    0.0
                } else if c.per_axis {
                    // The blend reaches `v²·W/2` into each move at the speed `v` it is taken
                    // at, `½·min(L)` only at the curve cap (`junction`): a corner that barely
                    // turns, or one taken far below its curve cap, does not make a short move
                    // next to it a chord of a curve.
                    let cap2 = c.v2.min(v * v).min(prev.v * prev.v);
                    0.5 * prev.len.min(mv.length) * (cap2 / c.centripetal_v2).min(1.0)
                } else {
                    0.5 * prev.len.min(mv.length)
                };
                if self.prev_d_in > 0.0
                    && d > 0.0
                    && self.prev_d_in + d >= prev.len * (1.0 - CURVED_TOL)
                {
                    curve_limits(prev, &self.prev_corner, &c);
                    if let Some(seg) = segments.last_mut() {
                        seg.set_kin(prev);
                    }
                }
                (c.v2.sqrt().min(v).min(prev.v), c, d)
            }
            _ => (0.0, junction::Corner::AT_REST, 0.0),
        };
        self.prev_corner = corner;
        self.prev_d_in = d_in;
        if blending {
            info.push(blend::MoveInfo {
                euclidean,
                stop_before: self.prev_stop,
                part_dir: here.part_dir,
                stepped_before: stepped && !self.prev_stop,
                lit_before: here.lit && self.prev_along.lit && !self.prev_stop,
            });
        }
        let mut seg = skeleton(mv.length, mv, index);
        seg.set_kin(&Kin {
            len: mv.length,
            v,
            a,
            j,
            cap: entry_cap,
        });
        segments.push(seg);
        points.extend_from_slice(&self.q[..n_axes]);
        self.prev_stop = stop;
        self.prev_along = here;
        self.prev_dir = dir;
        self.prev_euclidean = euclidean;
        self.q = mv.target;
        Ok(())
    }
}

/// What `prepare` hands to the look-ahead.
struct Prepared {
    /// Segment skeletons, not yet timed: each holds its move's look-ahead data
    /// (`Segment::kin`).
    segments: Vec<Segment>,
    /// Their start points, `n_axes` values each.
    points: Vec<f64>,
    /// The last target.
    end: Axes,
    /// The corner blends the segments refer to (`Corners::Blend`).
    blends: Blends,
}

/// Share of the acceleration limit a chord of a curve gives to the centripetal acceleration;
/// the rest, `√(1 − share²)` (per axis `1 − share`), is left for speed changes along it.
///
/// It is what keeps `scripts/toppra_compare.py`'s case B (24 corners rounded with R = 5 mm,
/// lase's own chords) above TOPP-RA's time-optimal bound by more than 1 % (issue 13): the
/// arcs run at `√share` of the circle's own speed. B's ratio to the converged bound, by share
/// (trapezoid, `bench_plan --path`): 0.95 → 1.0108, 0.97 → 1.0059, 0.975 → 1.0051, 0.98 →
/// 1.0045, 0.985 → 1.0044, 0.99 → 1.0051, 0.995 → 1.0075 (less is left for the speed changes
/// between arcs as it nears 1); without the tangential cut at all, 0.95 → 1.0099. It was
/// held at 0.95 while lit corners kept the junction-deviation velocity step, since a higher
/// cap raised the speed into them (`tests/trace_axis_limits.rs`' `WORST`: at 0.98
/// material_test X a/a_max 4.90 → 5.07, nested_parts 2.45 → 2.58, serial_number Y 5.46 →
/// 5.62). With lit corners blended every example stays within its axis limits at 0.98 (only
/// the arm's pins remain, unchanged) and no example's plan moves; B goes to 1.0045.
pub const CURVE_SHARE: f64 = 0.98;

/// Limits of a move that lies wholly on the rounding circles of its two corners `c_in` and
/// `c_out` (a chord of a curve, `junction`): all of it turns, not only its ends. Its speed obeys
/// both circles' centripetal caps, scaled by [`CURVE_SHARE`] (`v² ≤ share · a_n · r`), and its
/// tangential acceleration is cut to what is left of the limit at the highest speed the move
/// can reach, `a_t = a · √(1 − (v_max² / (a_n r))²)`, so that tangential and centripetal
/// acceleration together (`√(a_t² + (v²/r)²)`) stay within it. Without this a chord could speed
/// up between two capped corners, or change speed at full rate while turning at full rate.
/// When a corner was judged per axis (`junction`) the same holds with the per-axis curve cap
/// for `a_n r`, but the two accelerations of one axis are not perpendicular: axis k's is
/// `u_k·s̈ + q_k''·v²`, at most `|u_k|·a_t + share·a_k`, so the tangential budget is the
/// remainder `a_t = a · (1 − v_max² / (a_n r))`.
///
/// `v_max` is the move's speed limit, or less when its corners are slow: entered at most at
/// its entry cap `e_in`, left at most at the exit corner's cap `e_out`, it peaks at most at
/// `v_max² = (e_in² + e_out²)/2 + a·L` (the trapezoid peak; a jerk limit or a smaller `a` only
/// lowers it).
#[inline]
fn curve_limits(k: &mut Kin, c_in: &junction::Corner, c_out: &junction::Corner) {
    // Each half of the chord lies on one circle: the tighter one sets the cap.
    let centripetal_v2 = c_in.centripetal_v2.min(c_out.centripetal_v2);
    let cap = (CURVE_SHARE * centripetal_v2).sqrt();
    if cap < k.v {
        k.v = cap;
        k.cap = k.cap.min(cap);
    }
    let v_max2 = (0.5 * (k.cap * k.cap + c_out.v2) + k.a * k.len).min(k.v * k.v);
    let share = v_max2 / centripetal_v2;
    if share > 0.0 && share < 1.0 {
        k.a *= if c_in.per_axis || c_out.per_axis {
            // Per axis the two add up, |u_k|·a + share·a_k ≤ a_k (`junction`, per-axis rule).
            1.0 - share
        } else {
            (1.0 - share * share).sqrt()
        };
    }
}

fn skeleton(length: f64, mv: &Move, index: usize) -> Segment {
    Segment {
        t_start: 0.0,
        s_start: 0.0,
        length,
        v_entry: 0.0,
        v_peak: 0.0,
        v_exit: 0.0,
        t_j1: 0.0,
        t_a1: 0.0,
        t_cruise: 0.0,
        t_j2: 0.0,
        t_a2: 0.0,
        dwell: mv.dwell_after,
        feed: mv.feed,
        tag: mv.tag,
        move_index: index as u32,
        blend: plan::NO_BLEND,
    }
}
