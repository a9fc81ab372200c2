//! LinuxCNC 2.9's trajectory planner as a time model: how long a LinuxCNC machine takes to run
//! the program lase writes for it, and how long its beam is on. `lase plan` prints it next to
//! lase's own plan, because the controller that runs the file plans its own motion: trapezoids
//! without a jerk limit, its own corner rules and its own look-ahead.
//!
//! It reads the NC text (the `linuxcnc` dialect emit writes: `G0`–`G3` in `G17`, `G93`/`G94`,
//! `F`, `G4`, `G61`/`G64 P Q`, `M62`–`M68`, `M2`) and the machine's limits exactly as
//! [`super::config`] writes them into the INI, then follows what LinuxCNC 2.9 does with them
//! (`src/emc/task/emccanon.cc`, `src/emc/tp/tp.c`, `tc.c`, `blendmath.c`):
//! - **Segment limits** (canon's `getStraightVelocity`/`getStraightAcceleration`): a line's
//!   length is its X Y Z length, or its rotary length when X Y Z do not move; its speed and
//!   acceleration are the largest that keep every axis within its INI `MAX_VELOCITY` and
//!   `MAX_ACCELERATION` along it; `G0` runs at that speed, a feed at `F` (`G93`: the block's
//!   length over `60/F` s, at least 0.1 per minute: `inverse_time_rate_straight`), both capped by `[TRAJ] MAX_LINEAR_VELOCITY` when X Y Z move and by
//!   the length over one servo period (`tcClampVelocityByLength`). An arc runs at the smaller
//!   of its plane's axis limits, at most `sqrt(0.866·a·r)` (`pmCircleActualMaxVel`), and ramps
//!   with half the acceleration (`BLEND_ACC_RATIO_TANGENTIAL`). In blending mode an arc whose
//!   chord strays less than the naive CAM tolerance (`G64 Q`, else `P`) from it runs as that
//!   chord: canon's `ARC_FEED` sends it as two lines through its middle
//!   (`chord_deviation < naivecamTolerance`), which the naive CAM detector joins into one
//!   (dial_marks' 0.25 mm arcs turn at their chord ends). The same detector joins straight
//!   feeds (`see_segment`/`linkable`/`flush_segments`, [`naive::joins`]): in G64 with Q (else P)
//!   above 0, consecutive G94 lines that move no rotary axis run as one line from the
//!   chain's start while every chained point stays within Q of it (at most 100 points); a
//!   new F, any output word (synchronized ones flush the chain before they queue), a rapid,
//!   an arc or a dwell ends the chain. Measured: serial_number's strokes, short lines
//!   continuing their lead-ins, run at the feed as one segment (cycle 0.913 → 0.951 of the
//!   model with it).
//! - **Term conditions** (`tpAddLine`/`tpAddCircle` → `tpCheckCanonType`, `tpHandleBlendArc`),
//!   parabolic by default under `G64`:
//!   - *stop* between a rapid and a feed (`tpCheckCanonType`), at a reversal sharper than 178°
//!     (`tpSetupTangent`'s `SHARP_CORNER_DEG`) and under `G61`;
//!   - *tangent* when the direction change needs less than `ARC_BLEND_KINK_RATIO` (0.1) of an
//!     axis's acceleration at full speed over one servo period plus the next segment's own
//!     acceleration (`a_inst = v_max / cycleTime + tc->maxaccel`; circles count double): the
//!     speed carries through and both segments lose that share of their acceleration
//!     (`tpAdjustAccelForTangent`);
//!   - otherwise, without rotary motion, a *blend arc* (`blendComputeParameters`) that takes
//!     from each side at most half the segment's programmed length (all of the previous one
//!     when it can be consumed: a line without synced outputs, `tcCanConsume`) and what the
//!     `G64 P` tolerance allows (at most a quarter of either segment: `tcFindBlendTolerance`),
//!     at `sqrt(0.866·a·R)` but at most the faster feed, or the kink speed when that is faster
//!     (`tpCheckTangentPerformance`). The arc is only as large as that speed needs
//!     (`blendComputeParameters`' `R_plan`: the larger of v²/a_n and the equivalent parabolic
//!     blend's radius), so a slow corner (a held lit stroke's) runs nearly into its corner. What a segment keeps between two blend arcs runs at most
//!     its length per servo period: two blend arcs that meet in the middle of a segment
//!     carrying `M62/M63` nearly stop the machine there. That is dial_marks' 17 slowdowns.
//!     A line without synced outputs whose remainder would take fewer than
//!     `ARC_BLEND_GAP_CYCLES` (4) servo periods at the next blend arc's speed is swallowed by
//!     that arc instead (`blendCheckConsume`): the short chords of a lit arc's speed-held
//!     sub-blocks (`motion::power::lit_blocks`) run at the blend's speed, not crawl;
//!   - with rotary motion on either side neither can be made (`tpSetupTangent` gives up on
//!     ABC motion): the *parabolic* blend (`tpComputeBlendVelocity`): the next segment starts
//!     when the previous one, on its final deceleration, has slowed below its blend speed, and
//!     their speeds add up through the overlap. A chain of them from rest to rest runs servo
//!     period by servo period ([`servo`]): that is where a cam's 20–40 ms G93 blocks gain
//!     ~0.4 ms each on continuous trapezoids. Elsewhere the path runs as if at the blend
//!     speed there.
//!   - A parabolic term condition halves the acceleration of the segment it ends
//!     (`tcGetOverallMaxAccel`). Of the segment after it, only where that one's own term
//!     condition is PARABOLIC too: the real LinuxCNC 2.9 ran a lead-out ending in a stop
//!     after a parabolic blend (rotary_engrave's rings) and an X-only block joined
//!     tangentially to the next (its "S") at their full acceleration from the blend's first
//!     period on, where tc.c's `blend_prev` would halve it; with that, the model's NC line
//!     starts of the whole program land on the real ones' servo periods. `G64` makes
//!     PARABOLIC every segment's default (`tcSetupState`), and only a successor changes it,
//!     so the segment the queue ends on keeps it and ramps at half the acceleration too:
//!     where the task waits for motion to end before a dwell, an immediate output
//!     (`M64`/`M65`/`M68`), another M-code or the program's end (conrod_notch's first move). Each such drain rests the machine for about `DRAIN_CYCLES` servo periods.
//! - **Ramps** (`tpActivateSegment`, `tpCalculateRampAccel`): a feed with term condition
//!   TANGENT that would take under `1 / ARC_BLEND_RAMP_FREQ` (10 ms) runs at one constant
//!   acceleration from its entry to its final speed, not a trapezoid ([`piece_time`]).
//! - **Servo periods** outside parabolic chains: each run from rest to rest ends on a servo
//!   period (`tpCheckEndCondition` removes a stopping segment in the period it lands on its
//!   end; the next starts in the following one), half a period more on average ([`quantised`]).
//! - **Look-ahead** (`tpRunOptimization`): end speeds are planned backward over at most
//!   `ARC_BLEND_OPTIMIZATION_DEPTH` (50) pieces; further on the machine is assumed to stop.
//! - **Synced outputs** (`M62`/`M63`/`M67`, `tpSetupSyncedIO`): they switch when the next
//!   segment starts, and they neither stop nor unblend anything; they only keep a blend arc
//!   from swallowing the segment that carries them.
//!
//! Measured against the real controller (`tests/linuxcnc.rs`), every example it runs is within
//! 1 % of the model in cycle and beam-on time, but for the disagreements `tests/linuxcnc.rs`
//! pins and names. Not modelled: feed override, spindle sync, the naive CAM detector joining
//! a flattened arc with its neighbours, split periods within a run (the servo period is kept
//! only where a run ends), the ramp decision on the optimizer's uncapped final speed, and
//! blend arcs in 3D or next to arcs beyond their chord. Of its constants, only `DRAIN_CYCLES` is measured rather than read
//! from LinuxCNC's source: it is task's latency, not the planner's.

use crate::axes::to_external;
use crate::machine::{AxisKind, Machine};

/// The model's name, as `lase plan` prints it.
pub const MODEL: &str = "LinuxCNC 2.9 trajectory planner model";

use crate::motion::parabolic::chain::{
    KINK_RATIO, MIN_ARC_ANGLE, OPTIMIZATION_DEPTH, RAMP_FREQ, kink_scale,
};
/// Servo periods the machine rests where the queue drains (the task waits for motion to end,
/// then runs an immediate output, a dwell or an M-code and queues the next move): measured
/// (milltask's polling and NML round trip, not tp.c's arithmetic),
/// 2 and 3 ms on conrod_notch.
const DRAIN_CYCLES: f64 = 2.5;
/// `BLEND_ACC_RATIO_TANGENTIAL`: the share of acceleration an arc may use along its path.
const ACC_RATIO_TANGENTIAL: f64 = 0.5;
/// `BLEND_ACC_RATIO_NORMAL`: sqrt(1 − 0.5²), the share left for the turn.
const ACC_RATIO_NORMAL: f64 = 0.866_025_403_784_438_6;
/// `BLEND_DIST_FRACTION`: how much of a segment a blend may take.
const BLEND_DIST_FRACTION: f64 = 0.5;
/// `[TRAJ] ARC_BLEND_GAP_CYCLES`' default (`arcBlendGapCycles`): what is left of a line
/// between two blend arcs is swallowed by the second (`blendCheckConsume`) when it would take
/// fewer servo periods than this at the blend's speed.
const GAP_CYCLES: f64 = 4.0;
/// `TP_MIN_ARC_LENGTH`: a shorter blend arc is given up (`blendComputeParameters`).
const MIN_ARC_LENGTH: f64 = 1e-6;
/// `tolerance_ratio` in `tcFindBlendTolerance`: a blend strays at most this share of either
/// segment's programmed length from the corner.
const BLEND_TOL_FRACTION: f64 = 0.25;
/// `SHARP_CORNER_DEG` in `tpSetupTangent`: a turn this close to a reversal stops.
const SHARP_CORNER_DEG: f64 = 2.0;
/// Lengths below this are no motion (`TP_POS_EPSILON`, `CART_FUZZ`).
const POS_EPSILON: f64 = 1e-9;

/// One axis as the INI states it (external units: mm, degrees).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisLimit {
    /// The NC letter.
    pub letter: char,
    pub rotary: bool,
    /// `MAX_VELOCITY`, per second.
    pub v: f64,
    /// `MAX_ACCELERATION`, per second².
    pub a: f64,
}

/// What the planner knows of the machine: the generated INI's numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct TpLimits {
    pub axes: Vec<AxisLimit>,
    /// `[TRAJ] MAX_LINEAR_VELOCITY`, mm/s.
    pub max_linear_v: f64,
    /// `[EMCMOT] SERVO_PERIOD`, s.
    pub cycle_s: f64,
    /// The digital output that gates the beam (`M62/M64 Pn` in the post's `laser_on`).
    pub beam_output: Option<u32>,
}

impl TpLimits {
    /// The limits [`super::config::generate`] writes for `machine`, at its servo period.
    pub fn for_machine(machine: &Machine, cycle_s: f64) -> TpLimits {
        let axes = machine
            .axes
            .iter()
            .map(|a| AxisLimit {
                letter: a.name.chars().next().unwrap_or('X').to_ascii_uppercase(),
                rotary: a.kind == AxisKind::Rotary,
                v: to_external(a.kind, a.v_max),
                a: to_external(a.kind, a.a_max),
            })
            .collect();
        let max_linear_v = super::config::max_linear_velocity(machine);
        let beam_output = machine.post.get("linuxcnc").and_then(|p| {
            p.laser_on.iter().find_map(|l| {
                let w = read::words(l).ok()?;
                w.iter()
                    .find(|(c, v)| *c == 'M' && (*v == 62.0 || *v == 64.0))?;
                w.iter().find(|(c, _)| *c == 'P').map(|(_, p)| *p as u32)
            })
        });
        TpLimits {
            axes,
            max_linear_v,
            cycle_s,
            beam_output,
        }
    }
}

/// What the model predicts for one program.
#[derive(Debug, Clone, PartialEq)]
pub struct TpTime {
    /// From the first motion to the end of the last, s (dwells and stops between included).
    pub total_s: f64,
    /// How long the beam's output is on within that, s.
    pub beam_on_s: f64,
    /// Motion segments the planner queued.
    pub segments: usize,
    /// Places where the machine comes to rest between segments.
    pub stops: usize,
    /// Each queued segment's NC line (1-based, as `motion.program-line` reports it) and the
    /// time its motion starts, s from the first motion: where the model and a real run part.
    pub starts: Vec<(usize, f64)>,
}

/// The LinuxCNC time of a job: `None` when the machine has no LinuxCNC post, `Err` with the
/// reason when the program cannot be written or read.
pub fn controller_time(job: &crate::motion::Job) -> Option<Result<TpTime, String>> {
    controller_time_from(job, None)
}

/// [`controller_time`] of a job planned whole (`facts` `None`) or in windows (`facts` from
/// them): the program streamed line by line through [`TpStream`], never held (issue 18);
/// [`TpTime::starts`] is left empty.
pub fn controller_time_from(
    job: &crate::motion::Job,
    facts: Option<&crate::emit::PlanFacts>,
) -> Option<Result<TpTime, String>> {
    let machine = &job.program.machine;
    machine.post.get("linuxcnc")?;
    let limits = TpLimits::for_machine(machine, machine.servo_period_s());
    let mut model = TpStream::new(&limits, &[], false);
    Some(
        crate::emit::emit_nc_lines(job, facts, crate::emit::Dialect::LinuxCnc, &mut |l| {
            model.line(l)
        })
        .map(|()| model.finish()),
    )
}

/// A segment the planner queues, in its own length unit (see the module doc).
#[derive(Debug, Clone)]
struct Seg {
    len: f64,
    /// The requested speed (F, or the traverse rate), per second.
    req: f64,
    /// The segment's own limit (`maxvel`).
    vmax: f64,
    /// Acceleration along it before blends scale it.
    acc: f64,
    rapid: bool,
    arc: bool,
    rotary: bool,
    /// Unit X Y Z directions at its start and end (zero without X Y Z motion).
    u0: [f64; 3],
    u1: [f64; 3],
    /// Carries synced outputs, applied when it starts: (output, on).
    dio: Vec<(u32, bool)>,
    /// Per-axis X Y Z acceleration bounds, for the kink rule.
    acc_bound: [f64; 3],
    /// Its NC line, 1-based.
    line: usize,
}

/// What comes between two segments.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Joint {
    /// Motion ends; then `dwell` s at rest. `drain`: the queue runs empty because the task
    /// waits for motion to end before its next command.
    Stop { dwell: f64, drain: bool },
    /// Through at most `cap` (the previous segment's unit), the next entering at `ratio` times
    /// the previous one's exit speed.
    Through { cap: f64, ratio: f64 },
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// How LinuxCNC joins two segments.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    /// Its term condition becomes STOP.
    Stop,
    /// Tangent (or a kink it accepts): through at `cap`; both keep `keep` of their
    /// acceleration.
    Tangent { cap: f64, keep: f64 },
    /// A blend arc of radius `r` and deflection `phi` replacing `d` of each side, at most `v`.
    Arc { v: f64, d: f64, r: f64, phi: f64 },
    /// Parabolic: through at `va` (the first's unit), the second entering at `vb`.
    Parabolic { va: f64, vb: f64 },
}

/// The junction LinuxCNC makes from `a` into `b` with blend tolerance `tol`.
fn junction(a: &Seg, b: &Seg, tol: f64, cycle: f64) -> Kind {
    if a.rapid != b.rapid {
        return Kind::Stop; // tpCheckCanonType
    }
    if a.rotary || b.rotary {
        return parabolic(a, b, tol);
    }
    let c = dot(a.u1, b.u0);
    let sharp = (std::f64::consts::PI * (1.0 - SHARP_CORNER_DEG / 180.0)).cos();
    if c < sharp {
        return Kind::Stop;
    }
    // tpSetupTangent: the acceleration to turn at full speed within one servo period, plus the
    // next segment's own (`v_max / cycleTime + tc->maxaccel`: "acceleration past final
    // velocity during a split cycle"). That term is what an earlier reading missed and
    // measured as a factor of 1.081 on dial_marks' 25 mm/s chords (2000 mm/s² along an axis:
    // 1 + 2000 / 25000 = 1.08).
    let v_max = a.vmax.min(a.req).min(b.vmax.min(b.req));
    let mut scale = kink_scale((a.u1, b.u0), v_max, b.acc, a.acc_bound, cycle);
    if a.arc || b.arc {
        scale /= ACC_RATIO_TANGENTIAL;
    }
    if scale < KINK_RATIO {
        return Kind::Tangent {
            cap: v_max,
            keep: 1.0 - scale,
        };
    }
    let kink_vel = v_max * KINK_RATIO / scale;
    let kink = Kind::Tangent {
        cap: kink_vel,
        keep: 1.0 - KINK_RATIO,
    };
    // blendComputeParameters: half the interior angle, and the blend radius it allows.
    let theta = (-c).clamp(-1.0, 1.0).acos() / 2.0;
    let phi = std::f64::consts::PI - 2.0 * theta;
    if theta < MIN_ARC_ANGLE || phi < MIN_ARC_ANGLE || tol <= 0.0 {
        return kink;
    }
    // tcCanConsume: a line without synced outputs may be swallowed whole.
    let consumable = !a.arc && a.dio.is_empty();
    let l1 = if consumable {
        a.len
    } else {
        a.len * BLEND_DIST_FRACTION
    };
    let l2 = b.len * BLEND_DIST_FRACTION;
    // tcFindBlendTolerance: at most a quarter of either segment's programmed length.
    let tol = tol
        .min(BLEND_TOL_FRACTION * a.len)
        .min(BLEND_TOL_FRACTION * b.len);
    let d_tol = theta.cos() * tol / (1.0 - theta.sin());
    let d_geom = l1.min(l2).min(d_tol);
    let r_geom = theta.tan() * d_geom;
    let a_max = a
        .acc_bound
        .iter()
        .copied()
        .filter(|x| *x > 0.0)
        .fold(f64::INFINITY, f64::min);
    let a_n = a_max * ACC_RATIO_NORMAL;
    // blendParamKinematics' goal (feed override at most 1: the INI sets no
    // MAX_FEED_OVERRIDE), then blendComputeParameters.
    let v_goal = a.req.min(a.vmax).max(b.req.min(b.vmax));
    let v = (a_n * r_geom).sqrt().min(v_goal);
    // The arc is only as large as its speed needs: the radius that turns at `v` within
    // the normal acceleration, or the equivalent parabolic blend's, whichever is larger,
    // never beyond the geometric one. A slow corner gets a tiny arc and runs nearly to the
    // corner, instead of cutting it at the tolerance.
    let a_parabolic = 0.5 * a_max;
    let v_triangle = (2.0 * a_parabolic * d_geom).sqrt();
    let s_blend = v_triangle.min(v) / a_parabolic * v;
    let r_blend = (s_blend / phi).min(r_geom);
    let r = (v * v / a_n).max(r_blend);
    let d = r / theta.tan();
    if r < POS_EPSILON || r * phi < MIN_ARC_LENGTH {
        return kink; // blendComputeParameters gives the arc up
    }
    if v < kink_vel {
        kink // tpCheckTangentPerformance: the kink is faster than the arc
    } else {
        Kind::Arc { v, d, r, phi }
    }
}

/// tpComputeBlendVelocity: the parabolic blend between `a` and `b` (both at half acceleration).
fn parabolic(a: &Seg, b: &Seg, tol: f64) -> Kind {
    let side = |s: &Seg| {
        let acc = s.acc * 0.5 * if s.arc { ACC_RATIO_TANGENTIAL } else { 1.0 };
        let reach = (acc * s.len).sqrt().min(s.req);
        (acc, reach)
    };
    let ((acc_a, reach_a), (acc_b, reach_b)) = (side(a), side(b));
    let t_max = (a.len / reach_a).min(b.len / reach_b);
    let t_blend = t_max.min((reach_a / acc_a).max(reach_b / acc_b));
    let mut va = reach_a.min(t_blend * acc_a);
    let mut vb = reach_b.min(t_blend * acc_b);
    if tol > 0.0 {
        // pmCartLineInit: a line without X Y Z motion points along +X.
        let unit = |u: [f64; 3]| if u == [0.0; 3] { [1.0, 0.0, 0.0] } else { u };
        let theta = (-dot(unit(a.u1), unit(b.u0))).clamp(-1.0, 1.0).acos() / 2.0;
        if theta.cos() > (std::f64::consts::FRAC_PI_2 - MIN_ARC_ANGLE).cos() {
            let v_tol = |acc: f64| 2.0 * (acc * tol / theta.cos()).sqrt();
            va = va.min(v_tol(acc_a));
            vb = vb.min(v_tol(acc_b));
        }
    }
    if va <= 0.0 || vb <= 0.0 {
        return Kind::Stop;
    }
    Kind::Parabolic { va, vb }
}

/// Time to run `len` from `v0` to `v1` under `vmax` at `acc` (a trapezoid, or a triangle).
fn trapezoid(len: f64, v0: f64, v1: f64, vmax: f64, acc: f64) -> f64 {
    let peak = ((2.0 * acc * len + v0 * v0 + v1 * v1) / 2.0)
        .sqrt()
        .min(vmax);
    let peak = peak.max(v0).max(v1);
    if peak <= 0.0 {
        return 0.0;
    }
    let ramps = (2.0 * peak * peak - v0 * v0 - v1 * v1) / (2.0 * acc);
    let cruise = (len - ramps).max(0.0);
    (peak - v0) / acc + (peak - v1) / acc + cruise / peak
}

/// How long piece `p` takes from `v0` to `v1`. A feed piece with term condition TANGENT
/// whose time at the mean of its end speeds is under `1 / ARC_BLEND_RAMP_FREQ` runs at one
/// constant acceleration from its entry to its final speed (`tpActivateSegment` sets
/// `TC_ACCEL_RAMP`, `tpCalculateRampAccel`), not up to its feed and back down: a lit stroke's
/// held sub-blocks (short G1s whose F steps along lase's speed profile) run at the mean of
/// their end speeds, slower than trapezoids would. tp.c decides it with the optimizer's final
/// speed, before the feeds cap it; the model uses the capped one (a block it ramps from and
/// to its feed runs the same either way).
fn piece_time(p: &Piece, v0: f64, v1: f64) -> f64 {
    if p.ramp && v1 > 1e-9 {
        let t = 2.0 * p.len / (v0 + v1);
        if t < 1.0 / RAMP_FREQ && (v1 * v1 - v0 * v0).abs() <= 2.0 * p.acc * p.len {
            return t;
        }
    }
    trapezoid(p.len, v0, v1, p.v_top, p.acc)
}

/// The time a rest-to-rest run of `run` s takes in whole servo periods: a segment ending in
/// a stop lands on its end in the period its trapezoid reaches it (`tpCheckEndCondition`
/// flags it for removal only once it is there, `tcUpdateDistFromAccel` clips the last step
/// onto the end), and the next one starts in the following period, so each run from rest to
/// rest takes a whole number of periods: on average half a period more than the continuous
/// ramps.
fn quantised(run: f64, cycle: f64) -> f64 {
    (run / cycle - 1e-6).ceil().max(0.0) * cycle
}

/// One piece of motion as the planner runs it: a queued segment (trimmed by blend arcs), or
/// a blend arc.
#[derive(Debug, Clone)]
struct Piece {
    len: f64,
    v_top: f64,
    acc: f64,
    /// Outputs that switch when it starts.
    dio: Vec<(u32, bool)>,
    /// What follows it.
    joint: Joint,
    /// A feed whose term condition is TANGENT (a line into a tangent or a blend arc, or a
    /// blend arc): short ones run at one constant acceleration ([`piece_time`]).
    ramp: bool,
    /// The queued segment it is (or whose blend arc it is).
    seg: usize,
}

/// The pieces segment `i` runs as (itself trimmed by the blend arcs at its ends, then the
/// blend arc into the next, if any), at acceleration `a`, with `trim_start` taken by the
/// blend arc before it; returns what its own blend arc takes from the next segment.
///
/// Blend arcs take their share of each side; what is left of a segment runs at most its
/// length per servo period (tcClampVelocityByLength), which is how two blend arcs that meet
/// in the middle of a segment they may not swallow nearly stop the machine there.
fn seg_pieces(
    i: usize,
    s: &Seg,
    (kind, queued): (Option<Kind>, Option<Joint>),
    a: f64,
    trim_start: f64,
    cycle: f64,
    pieces: &mut impl Extend<Piece>,
) -> f64 {
    let trim_end = match kind {
        Some(Kind::Arc { d, .. }) => d,
        _ => 0.0,
    };
    let len = (s.len - trim_start - trim_end).max(0.0);
    // blendCheckConsume: a line without synced outputs (`tcCanConsume`) whose remainder would
    // take fewer than GAP_CYCLES servo periods at the next blend arc's speed becomes part of
    // that arc (its `line_length`) and runs at the arc's speed, not at its own length per servo
    // period (a lit arc's short sub-blocks, each a chord).
    let consumed = match kind {
        Some(Kind::Arc { v, .. }) => {
            (!s.arc && s.dio.is_empty() && len < GAP_CYCLES * cycle * v).then_some(v)
        }
        _ => None,
    };
    let v_top = match consumed {
        Some(v) => s.req.min(s.vmax).min(v),
        None => s.req.min(s.vmax).min(len.max(1e-6 * s.len) / cycle),
    };
    let joint = match (kind, queued) {
        (_, Some(j)) => j,
        (None, None) | (Some(Kind::Stop), _) => Joint::Stop {
            dwell: 0.0,
            drain: false,
        },
        (Some(Kind::Tangent { cap, .. }), _) => Joint::Through { cap, ratio: 1.0 },
        (Some(Kind::Arc { v, .. }), _) => Joint::Through { cap: v, ratio: 1.0 },
        (Some(Kind::Parabolic { va, vb }), _) => Joint::Through {
            cap: va,
            ratio: vb / va,
        },
    };
    let ramp = !s.rapid
        && matches!(joint, Joint::Through { .. })
        && matches!(kind, Some(Kind::Tangent { .. } | Kind::Arc { .. }));
    pieces.extend([Piece {
        len: len.max(1e-12),
        v_top,
        acc: a,
        dio: s.dio.clone(),
        joint,
        ramp,
        seg: i,
    }]);
    let Some(Kind::Arc { v, d, r, phi }) = kind else {
        return 0.0;
    };
    // The blend arc (TC_SPHERICAL: half the acceleration along it), tangent to both.
    let blend_acc = s
        .acc_bound
        .iter()
        .copied()
        .filter(|x| *x > 0.0)
        .fold(f64::INFINITY, f64::min)
        * ACC_RATIO_TANGENTIAL;
    let len = r * phi;
    pieces.extend([Piece {
        len: len.max(1e-12),
        v_top: v.min(len / cycle),
        acc: blend_acc,
        dio: Vec::new(),
        joint: Joint::Through { cap: v, ratio: 1.0 },
        ramp: !s.rapid,
        seg: i,
    }]);
    d
}

/// Runs LinuxCNC's planner model over an NC program, the machine starting at axis zero.
pub fn run_program(nc: &str, limits: &TpLimits) -> Result<TpTime, String> {
    run_program_from(nc, limits, &[])
}

/// [`run_program`] with the machine starting at `start` (machine axis order, external
/// units; missing axes at zero): a program's first move is as long as the controller finds it.
pub fn run_program_from(nc: &str, limits: &TpLimits, start: &[f64]) -> Result<TpTime, String> {
    let q = read::read(nc, limits, start)?;
    let segs = Vec::from(q.segs);
    let joints = Vec::from(q.joints);
    let tolerances = Vec::from(q.tolerances);
    let n = segs.len();
    if n == 0 {
        return Ok(TpTime {
            total_s: 0.0,
            beam_on_s: 0.0,
            segments: 0,
            stops: 0,
            starts: Vec::new(),
        });
    }
    let segs = &segs;
    let cycle = limits.cycle_s;
    // Each junction, and each segment's acceleration as tpGetScaledAccel scales it.
    let kinds: Vec<Option<Kind>> = (0..n)
        .map(|i| match joints[i] {
            None if i + 1 < n => Some(junction(&segs[i], &segs[i + 1], tolerances[i + 1], cycle)),
            _ => None,
        })
        .collect();
    let mut acc: Vec<f64> = segs
        .iter()
        .map(|s| s.acc * if s.arc { ACC_RATIO_TANGENTIAL } else { 1.0 })
        .collect();
    let mut half = vec![false; n];
    for i in 0..n {
        match kinds[i] {
            Some(Kind::Tangent { keep, .. }) => {
                acc[i] *= keep;
                acc[i + 1] *= keep;
            }
            Some(Kind::Parabolic { .. }) => {
                // The next one only where its own term condition is parabolic (module doc).
                half[i] = true;
            }
            // A segment the queue ends on (the task waits for motion before a dwell, an
            // immediate output or any M-code, or the program ends) keeps its default,
            // parabolic, term condition.
            None => {
                half[i] |= i + 1 == n || matches!(joints[i], Some(Joint::Stop { drain: true, .. }))
            }
            _ => {}
        }
    }
    // Blend arcs take their share of each side (`seg_pieces`).
    let mut pieces: Vec<Piece> = Vec::with_capacity(n);
    let mut piece_of_seg = Vec::with_capacity(n);
    let mut trim_start = 0.0;
    for i in 0..n {
        piece_of_seg.push(pieces.len());
        let a = if half[i] { acc[i] * 0.5 } else { acc[i] };
        trim_start = seg_pieces(
            i,
            &segs[i],
            (kinds[i], joints[i]),
            a,
            trim_start,
            cycle,
            &mut pieces,
        );
    }
    let m = pieces.len();
    // Chains of parabolic blends run servo period by servo period (`servo`).
    let chain_time =
        servo::chain_times(segs, &kinds, &joints, &tolerances, &piece_of_seg, m, cycle);
    // Backward (tpRunOptimization): each piece's highest exit speed, planning to a stop at
    // most OPTIMIZATION_DEPTH pieces ahead.
    let entry_of = |k: usize, exit: f64| {
        (exit * exit + 2.0 * pieces[k].acc * pieces[k].len)
            .sqrt()
            .min(pieces[k].v_top)
    };
    let exit_of = |k: usize, next_entry: f64| match pieces[k].joint {
        Joint::Stop { .. } => 0.0,
        Joint::Through { cap, ratio } => (next_entry / ratio).min(cap).min(pieces[k].v_top),
    };
    let mut exit = vec![0.0; m];
    for (i, e) in exit.iter_mut().enumerate() {
        let last = (i + OPTIMIZATION_DEPTH).min(m - 1);
        let mut v = 0.0; // the exit of `last`: the horizon's stop
        for k in (i + 1..=last).rev() {
            v = exit_of(k - 1, entry_of(k, v));
        }
        *e = v;
    }
    // Forward: each piece from its entry to its exit, the outputs as they switch.
    let mut total = 0.0;
    let mut beam_on = 0.0;
    let mut outputs = std::collections::BTreeMap::<u32, bool>::new();
    let lit = |outputs: &std::collections::BTreeMap<u32, bool>| {
        limits
            .beam_output
            .is_some_and(|b| outputs.get(&b).copied().unwrap_or(false))
    };
    let mut stops = q.stops;
    let mut entry: f64 = 0.0;
    let mut run_start = 0.0;
    let apply_immediate =
        |at: Option<usize>, outputs: &mut std::collections::BTreeMap<u32, bool>| {
            for &(i, o, on) in &q.immediate {
                if i == at {
                    outputs.insert(o, on);
                }
            }
        };
    apply_immediate(None, &mut outputs);
    let mut starts = Vec::with_capacity(n);
    for (k, p) in pieces.iter().enumerate() {
        if starts.last().is_none_or(|&(i, _)| i != p.seg) {
            starts.push((p.seg, total));
        }
        for &(o, on) in &p.dio {
            outputs.insert(o, on);
        }
        let v0 = entry.min(p.v_top);
        let v1 = exit[k]
            .min((v0 * v0 + 2.0 * p.acc * p.len).sqrt())
            .min(p.v_top);
        let t = chain_time[k].unwrap_or_else(|| piece_time(p, v0, v1));
        total += t;
        if lit(&outputs) {
            beam_on += t;
        }
        match p.joint {
            Joint::Stop { dwell, drain } => {
                entry = 0.0;
                let run = total - run_start;
                let pad = quantised(run, cycle) - run;
                total += pad;
                if lit(&outputs) {
                    beam_on += pad;
                }
                let lit_before = lit(&outputs);
                apply_immediate(Some(p.seg), &mut outputs);
                if k + 1 < m {
                    stops += 1;
                    // The task sees motion done, runs what waited for it, then queues on.
                    let latency = if drain { DRAIN_CYCLES * cycle } else { 0.0 };
                    total += latency + dwell;
                    if lit_before || lit(&outputs) {
                        beam_on += latency;
                    }
                    if lit(&outputs) {
                        beam_on += dwell;
                    }
                }
                run_start = total;
            }
            Joint::Through { ratio, .. } => entry = v1 * ratio,
        }
    }
    Ok(TpTime {
        total_s: total,
        beam_on_s: beam_on,
        segments: n,
        stops,
        starts: starts.into_iter().map(|(i, t)| (segs[i].line, t)).collect(),
    })
}

mod naive;
mod read;
mod servo;
mod stream;
pub use stream::TpStream;
#[cfg(test)]
mod tests;
