//! Beam switches placed ahead of LinuxCNC's joint pipeline (issue 13: every beam edge at the
//! planned place on the real controller).
//!
//! LinuxCNC 2.9 switches a motion-synchronized output (`M62`/`M63`/`M67`) from its trajectory
//! planner, in the servo period in which tp takes up the block the output is attached to
//! (tp.c `tpToggleDIOs` → `emcmotDioWrite`, which writes the HAL pin at once). The joints do
//! not get tp's position at once: control.c `get_pos_cmds` feeds each tp point into a cubic
//! interpolator per joint (`cubicAddPoint`), and `cubicInterpolate` returns the way point
//! (x0 + 4·x1 + x2) / 6 of the 4-point queue, centred on the point added two trajectory
//! periods before (cubic.c; at `TRAJ_PERIOD` = `SERVO_PERIOD`, what lase's INI leaves it,
//! two servo periods). The output therefore switches while the joints are still two periods
//! short of the block's start, less the part of a period tp ran past that start before the
//! period ended (0 to 1 period, ½ on average): on the real machine the beam went on and off
//! 1–3 periods before its planned place (0.057 mm at 20 mm/s, 0.28 mm at 100 mm/s with the
//! test's own 1 ms rounding).
//!
//! So on LinuxCNC the writer attaches each beam switch [`LEAD_PERIODS`] servo periods of the
//! planned edge speed further along the path: the block is cut there and the switch lines
//! written between its two parts. The edge then falls within ±½ servo period of travel of its
//! planned place, the spread tp's switching once per period leaves. At an edge the plan
//! passes at rest the lead is 0: a switch is never carried past a stop.
//!
//! The other synchronized outputs lead alike (tp.c `tpSetAout` and `tpSetDout` fill the same
//! slot, which `tpToggleDIOs` writes as tp takes up the block): an image row's power steps
//! (`M67`, `row::Carry`) and the pulse triggers (`M62`/`M63 P1`, `pulse::carry_edges`) are
//! carried as far where the plan runs the op at its feed. On the real machine (branch
//! pulselead): image_engrave's edges 0.149 → 0.049 mm (every row start carried), the
//! texture rows' 0.036 → 0.005, dial_marks' 0.128 → 0.033 with arcs cut.
//!
//! Programs in units per minute are cut, and a rotary attachment's inverse-time (G93) ones
//! (each part's F is its own length over the feed, `motion_line`) where neither block turns
//! A. Where one does, tp.c joins them by a parabolic blend and switches in its middle: the
//! junction moves instead ([`shift`]), and a lead-out before a stop is written in two
//! ([`split`]). An oriented machine's G93 blocks all turn a rotary joint: where its lead runs
//! on the lit chord's line in the axes (a cam's C and B together) the junction moves alike;
//! its edges on the real LinuxCNC went from 1.7 periods early to within ±0.25.

use crate::axes::Axes;
use crate::machine::AxisKind;
use crate::motion::{Job, power};
use crate::program::{Op, OpKind, P3};

/// Servo periods a synchronized output leads the joints by (module doc): the cubic
/// interpolator's two, less tp's mean half period past the block start.
pub(super) const LEAD_PERIODS: f64 = 1.5;

/// Switch lines waiting to be written `left` mm further along the path.
#[derive(Debug)]
pub(super) struct Pending {
    pub lines: Vec<String>,
    pub left: f64,
    /// They are the laser-off lines (the footer need not repeat them).
    pub off: bool,
    /// The servo period, s.
    pub servo_s: f64,
    /// The planned speed at the edge, mm/s.
    pub v: f64,
    /// The op whose switch it is: the lines keep its tag wherever they land, as a journal of
    /// a live run reads them.
    pub tag: Option<u32>,
}

/// Servo periods each part of a cut block must last at its feed: tp.c caps a segment's speed
/// at its length over `TP_MIN_SEGMENT_CYCLES` (1.02) periods, so a shorter part would slow
/// the machine at the beam's edge.
pub(super) const MIN_PART_PERIODS: f64 = 1.25;

/// Servo periods at the edge speed what a blend arc leaves of a cut block's first part lasts
/// (the blend takes up to half of it: `BLEND_DIST_FRACTION`), just above tp.c's 1.02.
const BEHIND_BLEND_PERIODS: f64 = 1.1;

/// Where block `sub` (`len` mm from where the spot is, F `cap` or its own) is cut to carry a
/// switch `left` mm along it, if at all. A straight block or an arc (a short arc piece ran
/// as its chord under canon's naive CAM and kinked against the move before it; the header's
/// `G64 … Q0` keeps it an arc: cut, frame_marking's on-edges on arcs went from +1.53 to +0.59
/// periods and dial_marks' circle start from +3.21 to +0.21 on the real LinuxCNC), and only
/// where the part after the cut lasts [`MIN_PART_PERIODS`] at the block's feed (tp.c
/// caps a shorter segment's speed). Where LinuxCNC joins the block tangentially to the one
/// before (tp.c's rule, [`tangent`]) the cut is at `left` (the part before lasts 1.5 periods
/// of the edge speed, which never exceeds the feed). Elsewhere tp lays a blend arc over the
/// junction that takes up to half of the first part, and what is left of it runs at most its
/// length per servo period (on the real machine dial_marks' circle went dark at 31 of
/// 40 mm/s after a cut 0.06 mm into its lead-out): the first part then lasts at least twice
/// [`BEHIND_BLEND_PERIODS`] at the edge speed, and the switch, which tp makes where that part
/// ends, after the blend, is late by what that adds (without the cut it came after the whole
/// blend arc: 0.35 mm on dial_marks). `None` (also where a rapid meets a feed, where tp stops): the switch goes
/// to the nearer end of the block.
pub(super) fn cut_at(
    sub: &Op,
    m: &super::Modal,
    len: f64,
    p: &Pending,
    cap: Option<f64>,
    machine: &crate::machine::Machine,
) -> Option<f64> {
    let (left, servo_s) = (p.left, p.servo_s);
    let feed = match &sub.kind {
        OpKind::Line { feed_mm_s, .. } | OpKind::Arc { feed_mm_s, .. } => {
            cap.map_or(*feed_mm_s, |c| c.min(*feed_mm_s))
        }
        OpKind::Rapid { .. } => machine.axes.iter().map(|a| a.v_max).fold(0.0, f64::max),
        _ => return None,
    };
    // An arc held below the edge's speed (a lit corner arc's first sub-block, its F the plan's
    // mean over it): tp slows to that F on the arc, so a switch cut into it came at 1.37 of
    // 2.66 mm/s on nested_parts (before it, 0.5 off); it stays where the arc starts. (At
    // frame_marking's 9.49 of 9.92 mm/s the cut measured right: +1.53 → +0.59 periods.)
    if matches!(sub.kind, OpKind::Arc { .. }) && feed < 0.9 * p.v {
        return None;
    }
    // A rapid meeting a feed is a stop to tp.c (`tpCheckCanonType`): the edge is at rest there.
    if (m.motion == Some("G0")) != matches!(sub.kind, OpKind::Rapid { .. }) {
        return None;
    }
    let (before, start) = (m.dir?, direction(sub, m.pos, sub_end(sub), false)?);
    let at = if tangent(before, start, feed, servo_s, machine) {
        left
    } else {
        // The first part runs at about the edge's speed (air_assist's lit end is passed at
        // 2.2 mm/s: at its block's 12 mm/s the minimum let tp reach 8.8 there), and what the
        // blend leaves of it caps tp's speed at its length over 1.02 periods: 1.1 periods keep
        // that cap 8 % above the edge speed (at 1.25, 23 %: 2.77 for 2.19 mm/s, 0.58 off).
        left.max(2.0 * BEHIND_BLEND_PERIODS * servo_s * p.v)
    };
    (left > 0.0 && at < len && len - at >= MIN_PART_PERIODS * servo_s * feed).then_some(at)
}

/// Whether a block from axes `a` to `b` turns a rotary axis: tp.c then joins it to its
/// neighbours only by parabolic blends (`tpSetupTangent`, `tpCheckBlendArcType`: no tangent
/// join and no blend arc with A B C motion).
pub(super) fn turns(machine: &crate::machine::Machine, a: &Axes, b: &Axes) -> bool {
    machine
        .axes
        .iter()
        .enumerate()
        .any(|(k, x)| x.kind == AxisKind::Rotary && (b[k] - a[k]).abs() > 1e-12)
}

/// The shortest time a part `f` (0..1) of the block from axes `a` to `b` may last to run
/// at its speed in a chain of parabolic blends (`motion::parabolic`): its triangle time
/// `sqrt(2 · t_a)`, `t_a = max_i |Δq_i| / a_i`, rounded up to the servo period, and a period
/// more for tp's clock (the leads keep two: `motion::leadin::ParabolicLeads`).
pub(super) fn triangle_s(machine: &crate::machine::Machine, a: &Axes, b: &Axes, f: f64) -> f64 {
    let t_a = machine
        .axes
        .iter()
        .enumerate()
        .filter(|(_, x)| x.a_max > 0.0)
        .map(|(k, x)| (b[k] - a[k]).abs() * f / x.a_max)
        .fold(0.0, f64::max);
    let period = machine.servo_period_s();
    ((2.0 * t_a).sqrt() / period).ceil() * period + period
}

/// Where lit or unlit Line op `i` (from spot `from` at axes `from_q`) ends instead, on a
/// LinuxCNC program in inverse time, when a flying beam switch sits at its end on a junction
/// tp.c blends parabolically (either block turns a rotary axis, [`turns`]); `None` elsewhere.
///
/// In a parabolic blend tp.c switches the next block's synchronized outputs in the first
/// servo period in which that block runs faster than the finishing one
/// (`tpDoParabolicBlending` → `tpToggleDIOs`), not as it starts. Both sides ramp at half
/// their acceleration (`tcGetTangentialMaxAccel`), so where their accelerations match (a
/// straight junction in the axes, and the leads `motion::leadin` makes long enough for the
/// blend to run at the edge speed, `ParabolicLeads`) that moment is when each has half the
/// speed, and the path point tp has then is the junction itself: the finishing block is
/// `(v/2)²/a` short of its end, the next one as far into its start. The joints follow tp's
/// point 2 periods late less the part of a period tp ran past it (control.c's cubic
/// interpolator: `LEAD_PERIODS`, as for a block start). A block cannot be cut there (the cut
/// would leave a block far shorter than its triangle time, which the blend could not carry
/// at speed), so the junction itself moves: op `i` runs on `carry` mm (the edge's
/// `LEAD_PERIODS` of travel, `carry((op, end))` of the lit op whose edge it is) along the
/// next op, which it must continue in a straight line, and the next op starts there. Both
/// keep their speeds: in G93 each block's F is its own length over its feed.
///
/// Where the blend is too short to carry the edge speed through it (an arm's, [`carries`]),
/// `short` asks for that place instead: `timing::off_edge_timing` times such an off-edge
/// about it, by tp.c's replay.
pub(super) fn shift(
    job: &Job,
    i: usize,
    (from, from_q): (P3, &Axes),
    carry: impl Fn((usize, usize)) -> f64,
    short: bool,
) -> Option<(P3, Axes)> {
    let ops = &job.program.ops;
    let op = &ops[i];
    let OpKind::Line { to, .. } = op.kind else {
        return None;
    };
    let mut j = i + 1;
    while !ops.get(j)?.moves_from(to) {
        if !matches!(ops[j].kind, OpKind::Line { .. } | OpKind::Rapid { .. }) {
            // An M code, event, output or dwell between: tp's queue is not one blend there.
            return None;
        }
        j += 1;
    }
    let next = &ops[j];
    let OpKind::Line { to: end, .. } = next.kind else {
        return None;
    };
    let lit = op.laser().is_some();
    if lit == next.laser().is_some() {
        return None;
    }
    let d = if lit { carry((i, 1)) } else { carry((j, 0)) };
    let (u, w) = (
        direction(op, from, to, true)?,
        direction(next, to, end, false)?,
    );
    let len = crate::program::dist(to, end);
    let machine = &job.program.machine;
    let (qa, qb) = (job.op_axes.get(i), job.op_axes.get(j));
    // What tp.c blends is the joints' straight lines: on an oriented machine the two blocks
    // continue each other in the axes (a cam's lead-in turns C and B in the ratio of the
    // first lit chord), whatever the spot does in the part's frame.
    let straight = if job.kin.oriented() {
        in_line(from_q, &qa, &qb)
    } else {
        (0..3).map(|k| u[k] * w[k]).sum::<f64>() > 1.0 - 1e-9
    };
    let parabolic = turns(machine, from_q, &qa) || turns(machine, &qa, &qb);
    // Both blocks must carry the edge speed into the blend, as the leads `motion::leadin`
    // makes do: else tp blends below it and switches elsewhere (an arm's lit chords of a
    // few ms, whose chains `motion::parabolic` judges instead).
    let feed = |o: &Op| match o.kind {
        OpKind::Line { feed_mm_s, .. } => feed_mm_s,
        _ => f64::INFINITY,
    };
    let v = if lit { feed(op) } else { feed(next) };
    let carried = carries(machine, (from_q, &qa), crate::program::dist(from, to), v)
        && carries(machine, (&qa, &qb), len, v);
    (d > 0.0 && straight && parabolic && carried != short && d < 0.5 * len).then(|| {
        let p = std::array::from_fn(|k| to[k] + w[k] * d);
        (p, qa.lerp(&qb, d / len))
    })
}

/// How much faster than the finishing block's speed tp.c runs a parabolic blend into a block
/// of the same direction, on average, mm/s: the block from axes `a` to `b`, `len` mm of the
/// part, at servo period `servo_s`.
///
/// In the blend's first servo period the next block takes a whole step of its (half)
/// acceleration `A` (`tpUpdateBlend` → `tpUpdateCycle`), while the finishing block
/// decelerates only for the part of the period after its ramp's turning point (`tpUpdateCycle`
/// solves for the speed that stops it at its end): the two speeds, which tp adds through the
/// overlap, then run `A·(T − φ)` above the finishing block's, φ where in the period the turn
/// falls, until the finishing block has stopped. The output switches in the middle of that
/// (`tpDoParabolicBlending`: as the next block becomes the faster), so an on-edge behind a
/// lead-in at the lit speed was crossed 1-4 % fast (rotary_engrave's rings at 115.8 of 114.6
/// °/s, the "S" at 47.76 of 45.73). Where the turn falls within the period depends on the
/// servo clock since the chain left rest: where the lead-in starts at rest `timing::lead_in_speed`
/// follows it; elsewhere its mean, `A·T/2`, is what the lead-in gives up (and what a lead-out
/// [`split_at`] gives up). `A` is half the path acceleration canon gives a
/// straight block (`getStraightAcceleration`: each axis within its own), the same for the
/// lead-in and the lit block it runs into in line.
pub(super) fn blend_gain(
    machine: &crate::machine::Machine,
    a: &Axes,
    b: &Axes,
    len: f64,
    servo_s: f64,
) -> f64 {
    let a_path = machine
        .axes
        .iter()
        .enumerate()
        .filter(|(k, x)| x.a_max > 0.0 && (b[*k] - a[*k]).abs() > 1e-12)
        .map(|(k, x)| x.a_max * len / (b[k] - a[k]).abs())
        .fold(f64::INFINITY, f64::min);
    if a_path.is_finite() {
        0.5 * a_path * servo_s / 2.0
    } else {
        0.0
    }
}

/// Where a lead-out [`split`] in two ends its first block: the fraction of its `len` mm
/// (axes `a` to `b`, at `v` mm/s the lit block's speed, servo period `servo_s`) as long as a
/// block whose triangle speed is `v` less the blend's mean gain ([`blend_gain`]), at most half.
///
/// tp.c caps the speed at which the lit block starts blending into the lead-out by the
/// lead-out's first block (`tpComputeBlendVelocity`: its triangle speed `sqrt(A·L)` and the
/// time to reach it): so the blend starts as the lit block has slowed by that gain, and its
/// speed and the lead-out's, which tp adds, cross the off-edge at the plan's speed where a
/// block long enough to carry the full speed crossed it up to `A·T` fast (rotary_engrave's
/// ring went dark at 115.67 of 114.59 °/s, cam_hardening's at 15.88 of 15.28).
pub(super) fn split_at(
    machine: &crate::machine::Machine,
    (a, b): (&Axes, &Axes),
    len: f64,
    v: f64,
    servo_s: f64,
) -> f64 {
    let gain = blend_gain(machine, a, b, len, servo_s);
    split_for(gain, len, v - gain, servo_s)
}

/// The fractions of a lead-out's `len` mm (axes `a` to `b`) at which its first block's
/// triangle speed is `v` less 0 to 3 blend gains ([`blend_gain`]), in `steps` steps: where
/// the chain before it is known from rest, `timing::off_edge_timing` picks among them
/// by tp.c's arithmetic.
pub(super) fn split_candidates(
    machine: &crate::machine::Machine,
    (a, b): (&Axes, &Axes),
    len: f64,
    v: f64,
    servo_s: f64,
    steps: usize,
) -> Vec<f64> {
    let gain = blend_gain(machine, a, b, len, servo_s);
    (0..=steps)
        .map(|k| {
            let u = v - 3.0 * gain * k as f64 / steps.max(1) as f64;
            split_for(gain, len, u, servo_s)
        })
        .collect()
}

/// The fraction of `len` mm a block must span for its triangle speed `sqrt(A·L)` to be `u`,
/// at most half; `gain` its blend gain `A·T/2` ([`blend_gain`], `A` half its path
/// acceleration).
fn split_for(gain: f64, len: f64, u: f64, servo_s: f64) -> f64 {
    let half_acc = 2.0 * gain / servo_s;
    if !(gain > 0.0 && len > 0.0 && u > 0.0) {
        return 0.5;
    }
    (u.powi(2) / half_acc / len).min(0.5)
}

/// Whether the block from axes `a` to `b`, `len` mm, reaches `v` mm/s in a chain of parabolic
/// blends: its triangle speed `sqrt(A·len)`, `A` half its path acceleration
/// ([`blend_gain`]), is at least `v`; and whether a blend at `v` lasts [`MIN_BLEND_PERIODS`]
/// servo periods or more, as the mean gain and the switch in its middle assume (an arm's
/// joints ramp 3.5 mm/s of spot speed in 2 ms, where tp switches in the blend's first period
/// or second and the gain would be a quarter of the speed: not measured, left as it was).
fn carries(machine: &crate::machine::Machine, (a, b): (&Axes, &Axes), len: f64, v: f64) -> bool {
    // blend_gain(…, T) = A·T/2.
    let half_acc = 2.0 * blend_gain(machine, a, b, len, 1.0);
    half_acc > 0.0
        && (half_acc * len).sqrt() >= v * (1.0 - 1e-9)
        && v / half_acc >= MIN_BLEND_PERIODS * machine.servo_period_s()
}

/// Servo periods a parabolic blend at the edge speed must last for the writer to move its
/// junction and trim its lead ([`carries`]).
const MIN_BLEND_PERIODS: f64 = 5.0;

/// Whether the joint-space lines `a → b` and `b → c` run on in the same direction (to 1e-9 of
/// the cosine, axes in their own units).
pub(super) fn in_line(a: &Axes, b: &Axes, c: &Axes) -> bool {
    let (mut uu, mut ww, mut uw) = (0.0, 0.0, 0.0);
    for k in 0..crate::axes::MAX_AXES {
        let (u, w) = (b[k] - a[k], c[k] - b[k]);
        uu += u * u;
        ww += w * w;
        uw += u * w;
    }
    uu > 0.0 && ww > 0.0 && uw / (uu * ww).sqrt() > 1.0 - 1e-9
}

/// Whether unlit Line op `i`, which follows a lit move, is written as two blocks: where it
/// meets that lit move in a parabolic blend (`turned`: the lit block turned a rotary axis, or
/// this one does from `from_q`) and a stop follows it (a rapid next, or nothing: tp.c's
/// `tcSetTermCond` … STOP). A block that ends in STOP ramps at its full acceleration against
/// the lit one's half (`tcGetTangentialMaxAccel` halves only where the term condition is
/// PARABOLIC or `blend_prev` is set, and the real machine showed the full one), so the speeds
/// add past the edge and the two become equal, where tp switches, before the junction (the
/// ring's end went dark 0.53° early at 106.7 of 114.6 °/s; with a lead-out long enough to
/// carry the speed, 1.07° early at 151.7). The first of the two blocks blends on into the
/// second (PARABOLIC: half), as the lit block does, and `motion::leadin` makes such a lead
/// out long enough for both.
pub(super) fn split(job: &Job, i: usize, (from, from_q): (P3, &Axes), turned: bool) -> bool {
    let ops = &job.program.ops;
    let OpKind::Line { to, feed_mm_s, .. } = ops[i].kind else {
        return false;
    };
    let q = job.op_axes.get(i);
    // Each of the two blocks must carry the lit speed (`motion::leadin` makes the leads so
    // long where they meet the lit path in line; an arm's short lead-out is left whole).
    let mid = from_q.lerp(&q, 0.5);
    let long = carries(
        &job.program.machine,
        (from_q, &mid),
        0.5 * crate::program::dist(from, to),
        feed_mm_s,
    );
    long && stops_after(job, i, (from, from_q), turned)
}

/// Whether unlit Line op `i` (from `from` at axes `from_q`) meets the lit move before it in
/// a parabolic blend (`turned`: the lit block turned a rotary axis, or this one does) and
/// tp stops at its end (a rapid next, or nothing: tp.c's `tcSetTermCond` … STOP).
pub(super) fn stops_after(job: &Job, i: usize, (_, from_q): (P3, &Axes), turned: bool) -> bool {
    let ops = &job.program.ops;
    let OpKind::Line { to, .. } = ops[i].kind else {
        return false;
    };
    let parabolic = turned || turns(&job.program.machine, from_q, &job.op_axes.get(i));
    let stop_next = ops[i + 1..]
        .iter()
        .find(|o| o.moves_from(to) || !matches!(o.kind, OpKind::Line { .. }))
        .is_none_or(|o| !matches!(o.kind, OpKind::Line { .. } | OpKind::Arc { .. }));
    parabolic && stop_next
}

/// The end a motion op's block runs to.
fn sub_end(op: &Op) -> P3 {
    op.target().unwrap_or_default()
}

/// tp.c `tpSetupTangent`'s rule, on the safe side: LinuxCNC passes a junction without a blend
/// arc where turning at speed `v` within one servo period, plus the next segment's own
/// acceleration, needs under 10 % (`ARC_BLEND_KINK_RATIO`) of the axes' acceleration
/// (`link::linuxcnc::tp` models it in full; here the least linear axis acceleration bounds
/// every component).
fn tangent(a: P3, b: P3, v: f64, servo_s: f64, machine: &crate::machine::Machine) -> bool {
    let acc = machine
        .axes
        .iter()
        .filter(|x| x.kind == crate::machine::AxisKind::Linear)
        .map(|x| x.a_max)
        .fold(f64::INFINITY, f64::min);
    if !(acc.is_finite() && acc > 0.0 && servo_s > 0.0) {
        return false;
    }
    let turn = (0..3).map(|k| (b[k] - a[k]).abs()).fold(0.0, f64::max);
    (v / servo_s + acc) * turn / acc < 0.1
}

/// The unit direction of travel of block `op` from `from` to `to`, where it starts (`end`
/// false) or ends; `None` for a block that does not move.
pub(super) fn direction(op: &Op, from: P3, to: P3, end: bool) -> Option<P3> {
    let d = match &op.kind {
        OpKind::Arc { center, ccw, .. } => {
            let p = if end { to } else { from };
            let (rx, ry) = (p[0] - center[0], p[1] - center[1]);
            if *ccw { [-ry, rx, 0.0] } else { [ry, -rx, 0.0] }
        }
        _ => [to[0] - from[0], to[1] - from[1], to[2] - from[2]],
    };
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    (n > 1e-12).then(|| [d[0] / n, d[1] / n, d[2] / n])
}

/// How far the beam switch at an edge passed at `v` mm/s is carried on a machine with servo
/// period `servo_s` (s).
pub(super) fn distance(v: f64, servo_s: f64) -> f64 {
    let d = LEAD_PERIODS * servo_s * v;
    if d >= MIN_LEAD_MM { d } else { 0.0 }
}

/// Whether the plan's speed `v` is the feed `feed` (to 1e-3 of it): where an op runs whole at
/// its feed, its pulse triggers and image-row power steps are carried ([`gated`], [`row`];
/// `emit::PlanFacts` keeps those ops' speeds by the same rule).
pub(in crate::emit) fn at_cruise(v: f64, feed: f64) -> bool {
    (v - feed).abs() <= 1e-3 * feed
}

/// The least lead written, mm: below it (an edge passed at under 0.7 mm/s at 1 ms) the cut
/// would move the switch by less than the program's 0.1 µm words resolve and 1 µm a beam
/// edge could show.
const MIN_LEAD_MM: f64 = 1e-3;

/// `op` with its end moved to `to` (a block cut from it ends there; arcs keep their centre).
pub(super) fn retarget(op: &Op, to: P3) -> Op {
    let mut sub = op.clone();
    match &mut sub.kind {
        OpKind::Rapid { to: t, .. } | OpKind::Line { to: t, .. } | OpKind::Arc { to: t, .. } => {
            *t = to;
        }
        _ => {}
    }
    sub
}

/// The feed an unlit feed move that leads into a lit one is held to: the plan's speed where
/// the beam comes on, where that is below the move's feed (a lit section that starts on a
/// slow lit arc or corner). LinuxCNC runs the blend arc between two blocks at the higher of
/// their feeds (`blendParamKinematics`' `v_goal`) and switches a synced output as the next
/// block starts, after that blend: a lead-in written at its full feed carried 14.8 mm/s over
/// frame_marking's beam edge, where the plan (and the held lit block) say 9.9. `None` at a
/// stop (the controller stops there anyway) and where the plan keeps the feed.
pub(super) fn lead_cap(
    job: &Job,
    facts: Option<&crate::emit::PlanFacts>,
    i: usize,
    rest: &[Op],
    to: P3,
) -> Option<f64> {
    if !super::next_move_lit(rest, to) {
        return None;
    }
    // A plan made in windows left it in `facts` (`emit::PlanFacts`).
    if let Some(f) = facts {
        return f.exit_below_feed(i);
    }
    let seg = job.plan.segments()[power::op_segments(job, i)].last()?;
    (seg.v_exit > 0.0 && seg.v_exit < seg.feed).then_some(seg.v_exit)
}

/// The plan's speeds where lit op `i` starts and ends, mm/s, from the whole plan or (planned
/// in windows) `facts`; 0 where not known.
pub(super) fn edge_speeds(job: &Job, facts: Option<&crate::emit::PlanFacts>, i: usize) -> [f64; 2] {
    if let Some(f) = facts {
        return f.edge_speeds(i);
    }
    let r = power::op_segments(job, i);
    let segs = job.plan.segments();
    match (
        segs.get(r.start),
        r.end.checked_sub(1).and_then(|e| segs.get(e)),
    ) {
        (Some(a), Some(b)) if !r.is_empty() => [a.v_entry, b.v_exit],
        _ => [0.0, 0.0],
    }
}

/// How far pulsed op `op`'s trigger edges are carried along it on LinuxCNC at servo period
/// `servo_s` (`pulse::write_gated`; `[v0, v1]` the plan's speeds where it starts and ends):
/// the beam switch's lead where the plan runs the whole op (a line or an arc) at its feed,
/// else 0.
pub(super) fn gated(op: &Op, [v0, v1]: [f64; 2], servo_s: f64) -> f64 {
    let (OpKind::Line {
        feed_mm_s: feed, ..
    }
    | OpKind::Arc {
        feed_mm_s: feed, ..
    }) = &op.kind
    else {
        return 0.0;
    };
    let cruise = |v: f64| at_cruise(v, *feed);
    if cruise(v0) && cruise(v1) {
        distance(*feed, servo_s)
    } else {
        0.0
    }
}

/// How image row `i` of `job` (from `from`; `[v0, v1]` the plan's speeds where it starts and
/// ends) carries its power steps on LinuxCNC at servo period
/// `servo_s` (`row::Carry`): where the plan runs the whole row at its feed, each run's end
/// by the beam switch's lead (tp.c `tpSetAout` queues an `M67` in the same synchronized slot
/// as `tpSetDout` an `M62`/`M63`, and `tpToggleDIOs` writes both as tp takes up the block:
/// they lead the joints alike). The last run runs on into the lead-out where that continues
/// the row in line at its feed, long enough for what is left of it.
pub(super) fn row(
    job: &crate::motion::Job,
    i: usize,
    from: P3,
    servo_s: f64,
    [v0, v1]: [f64; 2],
) -> Option<super::row::Carry> {
    let ops = &job.program.ops;
    let OpKind::Line {
        to,
        feed_mm_s: feed,
        row: Some(_),
        ..
    } = &ops[i].kind
    else {
        return None;
    };
    if job.kin.oriented() {
        return None;
    }
    let cruise = |v: f64| at_cruise(v, *feed);
    let lead = distance(*feed, servo_s);
    if !(cruise(v0) && cruise(v1) && lead > 0.0) {
        return None;
    }
    let min_block = MIN_PART_PERIODS * servo_s * feed;
    let dir = direction(&ops[i], from, *to, true)?;
    let past_end = ops[i + 1..]
        .iter()
        .find(|o| o.moves_from(*to))
        .is_some_and(|o| match &o.kind {
            OpKind::Line {
                to: end,
                feed_mm_s,
                laser: None,
                ..
            } => {
                let len = crate::program::dist(*to, *end);
                direction(o, *to, *end, false)
                    .is_some_and(|d| (0..3).map(|k| d[k] * dir[k]).sum::<f64>() > 1.0 - 1e-9)
                    && (feed_mm_s - feed).abs() <= 1e-9 * feed
                    && len - lead >= min_block
            }
            _ => false,
        });
    Some(super::row::Carry {
        lead,
        past_end,
        min_block,
    })
}

/// LinuxCNC runs an arc whose sagitta is below the naive CAM tolerance (`G64 Q`, else `P`) as
/// its chord (canon's `ARC_FEED`). Emit now writes `G64 P<corner> Q0`, under which canon keeps
/// every arc an arc; the merge below is kept (measured with it on the real LinuxCNC, and an
/// NC with a non-zero Q still needs it), at the corner tolerance `P`. A lit arc's first
/// speed-held sub-block is short, and as a chord it meets the move before it (a lead-in along
/// lase's first chord, a few degrees off the arc's tangent) at a kink, which tp.c passes at
/// its kink speed (`tpSetupTangent`: 3 mm/s on the real machine where frame_marking's plan
/// says 9.9 at the beam's edge). So the first sub-blocks are merged until the first one is an
/// arc to LinuxCNC too (sagitta at least the tolerance), which it blends with the line before
/// it (`power::merge_front`: their mean speed and time-mean power).
pub(super) fn arc_first_block(op: &Op, from: P3, blocks: &mut Vec<power::PowerBlock>, tol: f64) {
    let Some((r, _, sweep)) = op.arc_from(from) else {
        return;
    };
    let total = blocks.last().map_or(0.0, |b| b.s_end);
    let arc_len = r * sweep.abs();
    if !(tol > 0.0 && r > 0.0 && arc_len > 0.0 && total > 0.0) {
        return;
    }
    // Sagitta r·(1 − cos(φ/2)) ≥ tol: φ ≥ 2·acos(1 − tol/r) (the whole arc when r < tol/2).
    let phi = 2.0 * (1.0 - tol / r).max(-1.0).acos();
    let s_min = total * (r * phi * (1.0 + 1e-6) / arc_len);
    power::merge_front(blocks, s_min);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lead_is_one_and_a_half_servo_periods_of_the_edge_speed() {
        // 20 mm/s at 1 ms: 0.03 mm; 100 mm/s: 0.15 mm; at rest nothing is carried.
        assert!((distance(20.0, 0.001) - 0.03).abs() < 1e-12);
        assert!((distance(100.0, 0.001) - 0.15).abs() < 1e-12);
        assert_eq!(distance(0.0, 0.001), 0.0);
        assert_eq!(distance(0.5, 0.001), 0.0);
    }
}
