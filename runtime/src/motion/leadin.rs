//! Lead-ins and lead-outs: the transition points of PROCESS.md §4, placed so that the beam is
//! only on at the programmed speed.
//!
//! The paper's look-ahead preprocessing computes, for each M-function point, the distance the
//! machine needs to reach the cutting feed from rest and moves the transition point back by it,
//! "so that the cutting feed is reached exactly at the start of the cut". This module does that
//! for every lit section (a maximal run of lit motion ops; non-motion ops between two lit moves
//! stay inside it, as in `emit`'s laser model), as a pure transformation of the op list before
//! lowering: no IO, no recipe syntax, no NC text.
//!
//! Two machine styles:
//! * (a) the beam switch needs the machine at rest (`laser_switch_stops`, the notcher's M27):
//!   the move before the section is redirected to end `d_in` back along the entry direction,
//!   where the beam is switched on at rest; a *lit* lead-in of length `d_in` at the cutting feed
//!   follows, reaching the feed exactly at the first programmed lit point. Symmetrically a lit
//!   lead-out of `d_out` runs past the last lit point and the beam goes off at rest there. The
//!   beam is on during both ramps, but outside the programmed section (in the paper, above the
//!   notch).
//! * (b) motion-synchronized outputs (xy_table, xyz: M62/M63, M3 in laser mode): the lead-in and
//!   lead-out are *unlit* moves along the entry and exit tangents; the lit section runs at its
//!   feed from its first to its last point and the beam switches at full speed on a
//!   straight-through junction, so there is no speed dip.
//!
//! Lengths come from the profile and the limits the planner will use for that direction
//! ([`planner::move_limits`]: tightest axis along the direction): `d = `[`planner::lead_distance`]
//! `(v, w_max, a, j)`, the worst ramp between the feed `v` and any speed `w ≤ w_max` the lead's
//! other end may have. After a stop (always in style a) `w_max = 0` and `d` is PROCESS.md §4's
//! ramp distance from rest (for an S-curve with `v < a²/J`, `d = v · √(v/J)`). When the lead-in
//! may be entered at speed (the move before ends in a corner) `w_max = v`, because a
//! jerk-limited ramp entered at speed can need more room than one from rest. In style (b) a
//! lead also keeps [`planner::lead_blend_room`] for the corner blends at its two ends (the
//! planner rounds corners taken at speed over up to `4 · corner` of each move), so that its
//! straight ramp still reaches the feed at the lit point.
//!
//! Positioning moves adjacent to a section change: the unlit move before it now ends at the
//! lead-in start (or a rapid there is inserted when no straight move precedes), and the move
//! after it starts at the lead-out end. An unlit arc after a section would lose its start, so a
//! rapid back to the section's end is inserted before it.

use super::{MotionError, arc_points, dist};
use crate::axes::{Axes, MAX_AXES};
use crate::kinematics::Kinematics;
use crate::planner::{self, AxisLimits, PlannerConfig};
use crate::program::{Laser, Op, OpKind, Orient, P3};
use lase_lang::units::format_number;
use std::collections::BTreeMap;
use std::sync::Arc;

use crate::program::PULSE_CRUISE_MARGIN_S;

/// What the lead computation needs to know about the machine and the planner.
#[derive(Clone, Copy, Debug)]
pub struct LeadContext<'a> {
    pub kin: &'a dyn Kinematics,
    pub limits: &'a AxisLimits,
    pub cfg: &'a PlannerConfig,
    /// The machine switches the beam at rest (style a above).
    pub switch_stops: bool,
    /// Chord tolerance of arcs, so that an arc's entry direction is its first chord's, as the
    /// planner sees it.
    pub arc_tolerance_mm: f64,
    /// Add leads at all (`planner { leadin auto }`).
    pub enabled: bool,
    /// Where the program runs on LinuxCNC and its lit junctions with the leads are parabolic
    /// blends (a rotary attachment's G93 blocks, [`ParabolicLeads`]); `None` elsewhere.
    pub parabolic: Option<ParabolicLeads>,
}

/// What LinuxCNC 2.9 needs of a lead that meets the lit path in a *parabolic* blend (tp.c
/// joins blocks that turn a rotary axis only so: `tpSetupTangent` and `tpCheckBlendArcType`
/// give up on A B C motion), so that the beam switches where and at the speed lase plans.
///
/// - The blend runs at the lead's speed only if the lead could reach it ramping from rest
///   over its whole length at half its acceleration (`tcGetTangentialMaxAccel` halves it on
///   both sides of a parabolic blend; `tpComputeBlendVelocity` caps the blend speed at that
///   triangle speed `sqrt(a/2 · L)`): `L ≥ 2·v²/a`, where `a` is the acceleration canon gives
///   the block (`getStraightAcceleration`: the block's length over `max_i |Δq_i| / a_i`), plus
///   two servo periods of travel for tp's clock (`parabolic` rounds the triangle time up to a
///   period too). The rings of rotary_engrave had 5.13° where 7.33° were needed: LinuxCNC
///   crossed the edge at 96.8 of the planned 114.6 °/s.
/// - tp switches the synchronized output in the middle of the blend, when the block that
///   carries it becomes the faster of the two (`tpDoParabolicBlending` → `tpToggleDIOs`):
///   with equal accelerations on both sides that is where the two blocks meet, and the writer
///   moves that junction [`SWITCH_LEAD_PERIODS`] of travel past the edge (`emit`'s
///   flying switches, the cubic interpolator's delay: control.c).
/// - A lead-out before a stop would end in STOP, and ramp at its full acceleration against
///   the lit block's half (the real machine: the ring's end went dark 0.53° early at 106.7
///   of 114.6 °/s): the writer writes it as two blocks, the first of which blends on
///   (PARABOLIC, half), so a lead-out holds two such lengths.
#[derive(Clone, Copy, Debug)]
pub struct ParabolicLeads {
    /// The servo period, s.
    pub servo_s: f64,
    /// Each axis's acceleration as LinuxCNC's INI has it (the machine file's), internal units.
    pub a_max: [f64; MAX_AXES],
    /// Which axes are rotary: a lead that turns none, next to a lit block that turns none,
    /// meets it tangentially and needs no more than the planner's ramp.
    pub rotary: [bool; MAX_AXES],
}

/// Servo periods of the edge speed a flying switch is moved past its edge on LinuxCNC
/// (`emit`'s `lead::LEAD_PERIODS`: the cubic interpolator's two periods less tp's mean half).
pub const SWITCH_LEAD_PERIODS: f64 = 1.5;

/// Servo periods of travel a parabolic lead keeps beyond its triangle length.
const PARABOLIC_MARGIN_PERIODS: f64 = 2.0;

impl ParabolicLeads {
    /// The shortest lead from `from` toward `to` (a straight piece in the axes, `Δq` over
    /// `len` mm) that carries `v` mm/s into a parabolic blend: `parts` triangle lengths with
    /// their margins, and the switch's carry.
    fn length(&self, dq: &[f64; MAX_AXES], len: f64, v: f64, parts: f64) -> f64 {
        let turns = (0..MAX_AXES).any(|i| self.rotary[i] && dq[i].abs() > 1e-12);
        if !(len > 0.0 && v > 0.0 && turns) {
            return 0.0;
        }
        // s²/mm: t_a = max_i |Δq_i| / a_i per mm of the lead.
        let k = (0..MAX_AXES)
            .filter(|&i| self.a_max[i] > 0.0 && self.a_max[i].is_finite())
            .map(|i| dq[i].abs() / len / self.a_max[i])
            .fold(0.0, f64::max);
        let one = 2.0 * v * v * k + PARABOLIC_MARGIN_PERIODS * self.servo_s * v;
        parts * one + SWITCH_LEAD_PERIODS * self.servo_s * v
    }
}

/// Whether an added move leads into or out of a section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeadKind {
    In,
    Out,
}

/// A move lase added in front of or behind a lit section.
#[derive(Debug, Clone, PartialEq)]
pub struct Lead {
    /// Index of the added op in the transformed program.
    pub op: u32,
    pub kind: LeadKind,
    /// Its length, mm.
    pub length_mm: f64,
    /// Whether the beam is on during it (style a).
    pub lit: bool,
}

/// One lit section as the recipe wrote it, located in the transformed program.
#[derive(Debug, Clone, PartialEq)]
pub struct LitSection {
    /// First and last lit motion op of the section (leads excluded).
    pub first_op: u32,
    pub last_op: u32,
    /// The first programmed lit point and the feed of the op that starts there.
    pub start: P3,
    pub start_feed_mm_s: f64,
    /// The last programmed lit point and the feed of the op that ends there.
    pub end: P3,
    pub end_feed_mm_s: f64,
}

/// The program with its leads.
#[derive(Debug, Clone)]
pub struct Leads {
    pub ops: Vec<Op>,
    /// Where each op of the input landed in `ops` (what refers to an op by index, such as a
    /// row start to settle, follows it).
    pub index: Vec<u32>,
    pub sections: Vec<LitSection>,
    pub leads: Vec<Lead>,
}

/// An op to insert, and what lead it is (kind, length, lit) if it is one.
type Insert = (Op, Option<(LeadKind, f64, bool)>);

/// Edits to the op list, collected first and applied in one pass. Keyed by op index, and only
/// where there is an edit: a lit section of a million short moves gets four, not tables of a
/// million entries.
#[derive(Default)]
struct Edits {
    /// New target (and orientation) of op i (an unlit straight move redirected to a lead-in
    /// start).
    redirect: BTreeMap<usize, (P3, Option<Orient>)>,
    /// Ops to insert before op i.
    before: BTreeMap<usize, Vec<Insert>>,
    /// Ops to insert after op i.
    after: BTreeMap<usize, Vec<Insert>>,
    /// Ops to insert before everything.
    front: Vec<Op>,
}

/// Adds lead-ins and lead-outs around every lit section of `ops` (starting at `start`).
///
/// Fails, without a partial result, when a lead does not fit in the machine's travel or the
/// lit feed is above what the axes allow along the cut (then no lead could reach it).
pub fn add_leads(start: P3, ops: Vec<Op>, cx: &LeadContext<'_>) -> Result<Leads, MotionError> {
    let starts = start_points(start, &ops);
    let moving: Vec<bool> = ops
        .iter()
        .zip(&starts)
        .map(|(op, from)| op.moves_from(*from))
        .collect();
    let runs = lit_runs(&ops, &moving);
    if !cx.enabled || runs.is_empty() {
        let sections = runs
            .iter()
            .map(|&(f, l)| section(&ops, &starts, f, l, f as u32, l as u32))
            .collect();
        return Ok(Leads {
            index: (0..ops.len() as u32).collect(),
            ops,
            sections,
            leads: Vec::new(),
        });
    }

    let n = ops.len();
    let mut ed = Edits::default();
    let owned = ops;
    let ops = &owned[..];
    for &(first, last) in &runs {
        let prev_move = (0..first).rev().find(|&i| moving[i]);
        let next_move = (last + 1..n).find(|&i| moving[i]);
        let stop_between = |a: usize, b: usize| ops[a..b].iter().any(is_stop);

        // Lead-in: ends at the first lit point P0 at full speed.
        let op = &ops[first];
        let p0 = starts[first];
        // On a machine that orients the beam, the lead-in keeps the orientation at P0 (set by
        // the move before the section), so the first lit block starts on the normal.
        let o_in = orient_before(ops, first).or(op.orient());
        let (u, chord_end) = entry_chord(op, p0, cx.arc_tolerance_mm);
        let feed = feed_of(op);
        let (v, a, j) = limits_along(cx, (p0, o_in), (chord_end, op.orient()), feed, op)?;
        let w_max = match prev_move {
            _ if cx.switch_stops => 0.0,
            None => 0.0,
            Some(pm) if stop_between(pm + 1, first) => 0.0,
            Some(_) => v,
        };
        let margin = if pulsed_by_distance(op) {
            v * PULSE_CRUISE_MARGIN_S
        } else {
            0.0
        };
        let d_in = (planner::lead_distance(v, w_max, a, j) + margin + blend_room(cx)).max(
            parabolic_length(cx, (p0, o_in), (chord_end, op.orient()), v, 1.0),
        );
        let (p_lead, o_lead, room) =
            match oriented_lead(cx, (p0, o_in), (chord_end, op.orient()), d_in) {
                Some((p, o)) => (p, Some(o), d_in),
                None => (
                    along(p0, u, -d_in),
                    o_in,
                    room_along(cx.kin, p0, o_in, u, -1.0, d_in),
                ),
            };
        if room < d_in {
            return Err(MotionError::NoRoomForLeadIn {
                needed: mm(d_in),
                available: mm(floor_nc(room)),
                span: op.span,
                help: no_room_help("before", "in"),
            });
        }
        let lit_lead = cx.switch_stops.then(|| lead_laser(op.laser()));
        match prev_move {
            Some(pm)
                if matches!(
                    ops[pm].kind,
                    OpKind::Rapid { .. } | OpKind::Line { laser: None, .. }
                ) =>
            {
                ed.redirect.insert(pm, (p_lead, o_lead));
            }
            Some(pm) => ed
                .after
                .entry(pm)
                .or_default()
                .push((rapid(p_lead, op, o_lead), None)),
            None if dist(start, p_lead) > 1e-12 => ed.front.push(rapid(p_lead, op, o_lead)),
            None => {}
        }
        // Positioning ops between that did not move the spot (a `follow`'s rapid to a start
        // the machine is already at, with the beam turned by a rounding) stood where the move
        // before ended; that is now the lead-in start. Left aiming at P0, one of them would
        // carry the machine along the lead-in as a rapid, and the lead-in itself would be
        // empty: the section would start from a rapid, not from the planned ramp.
        for i in prev_move.map_or(0, |pm| pm + 1)..first {
            if !moving[i]
                && matches!(
                    ops[i].kind,
                    OpKind::Rapid { .. } | OpKind::Line { laser: None, .. }
                )
            {
                ed.redirect.insert(i, (p_lead, o_lead));
            }
        }
        ed.before.entry(first).or_default().push((
            Op {
                kind: OpKind::Line {
                    to: p0,
                    feed_mm_s: feed,
                    laser: lit_lead.clone(),
                    orient: o_in.map(Box::new),
                    row: None,
                },
                span: op.span,
            },
            Some((LeadKind::In, d_in, cx.switch_stops)),
        ));

        // Lead-out: leaves the last lit point P1 at full speed.
        let op = &ops[last];
        let p1 = op.target().unwrap_or(starts[last]);
        let (u, chord_start) = exit_chord(op, starts[last], cx.arc_tolerance_mm);
        let feed = feed_of(op);
        let (v, a, j) = limits_along(
            cx,
            (chord_start, orient_before(ops, last).or(op.orient())),
            (p1, op.orient()),
            feed,
            op,
        )?;
        let w_max = match next_move {
            _ if cx.switch_stops => 0.0,
            None => 0.0,
            Some(nm) if stop_between(last + 1, nm) => 0.0,
            Some(_) => v,
        };
        let o_start = orient_before(ops, last).or(op.orient());
        let d_out = (planner::lead_distance(v, w_max, a, j) + blend_room(cx)).max(
            parabolic_length(cx, (chord_start, o_start), (p1, op.orient()), v, 2.0),
        );
        let (p_out, o_out, room) =
            match oriented_lead(cx, (p1, op.orient()), (chord_start, o_start), d_out) {
                Some((p, o)) => (p, Some(o), d_out),
                None => (
                    along(p1, u, d_out),
                    op.orient(),
                    room_along(cx.kin, p1, op.orient(), u, 1.0, d_out),
                ),
            };
        if room < d_out {
            return Err(MotionError::NoRoomForLeadOut {
                needed: mm(d_out),
                available: mm(floor_nc(room)),
                span: op.span,
                help: no_room_help("after", "out"),
            });
        }
        let lit_lead = cx.switch_stops.then(|| lead_laser(op.laser()));
        ed.after.entry(last).or_default().push((
            Op {
                kind: OpKind::Line {
                    to: p_out,
                    feed_mm_s: feed,
                    laser: lit_lead,
                    orient: o_out.map(Box::new),
                    row: None,
                },
                span: op.span,
            },
            Some((LeadKind::Out, d_out, cx.switch_stops)),
        ));
        if let Some(nm) = next_move
            && matches!(ops[nm].kind, OpKind::Arc { .. })
        {
            // An arc is defined from where it starts: go back to it.
            ed.after
                .entry(last)
                .or_default()
                .push((rapid(p1, op, op.orient()), None));
        }
    }
    Ok(apply(owned, &starts, &runs, ed))
}

fn apply(mut ops: Vec<Op>, starts: &[P3], runs: &[(usize, usize)], mut ed: Edits) -> Leads {
    let n = ops.len();
    // The sections as written, before any op moves or is redirected.
    let mut sections: Vec<LitSection> = runs
        .iter()
        .map(|&(f, l)| section(&ops, starts, f, l, 0, 0))
        .collect();
    let len = |v: Option<&Vec<Insert>>| v.map_or(0, Vec::len);
    let mut new_index = vec![0u32; n];
    let mut at = ed.front.len();
    for (i, x) in new_index.iter_mut().enumerate() {
        at += len(ed.before.get(&i));
        *x = at as u32;
        at += 1 + len(ed.after.get(&i));
    }
    for (&i, &(p, o)) in &ed.redirect {
        match &mut ops[i].kind {
            OpKind::Rapid { to, orient } | OpKind::Line { to, orient, .. } => {
                *to = p;
                if o.is_some() {
                    *orient = o.map(Box::new);
                }
            }
            _ => {}
        }
    }
    // The ops move to their places in the one list, from the back (each place is at or after
    // the op's own, and every op behind it has moved already), and the inserts fill the gaps:
    // the program is never held twice (issue 18: a million short moves).
    let gap = || Op {
        kind: OpKind::Dwell { seconds: 0.0 },
        span: Default::default(),
    };
    ops.reserve_exact(at - n);
    ops.resize_with(at, gap);
    for i in (0..n).rev() {
        ops.swap(i, new_index[i] as usize);
    }
    let mut leads = Vec::new();
    let mut put = |ops: &mut Vec<Op>, k: usize, (op, lead): Insert| {
        if let Some((kind, length_mm, lit)) = lead {
            leads.push(Lead {
                op: k as u32,
                kind,
                length_mm,
                lit,
            });
        }
        ops[k] = op;
    };
    for (k, op) in std::mem::take(&mut ed.front).into_iter().enumerate() {
        put(&mut ops, k, (op, None));
    }
    for (i, &k) in new_index.iter().enumerate() {
        let k = k as usize;
        if let Some(b) = ed.before.remove(&i) {
            let first = k - b.len();
            for (j, x) in b.into_iter().enumerate() {
                put(&mut ops, first + j, x);
            }
        }
        if let Some(a) = ed.after.remove(&i) {
            for (j, x) in a.into_iter().enumerate() {
                put(&mut ops, k + 1 + j, x);
            }
        }
    }
    for (s, &(f, l)) in sections.iter_mut().zip(runs) {
        s.first_op = new_index[f];
        s.last_op = new_index[l];
    }
    Leads {
        ops,
        index: new_index,
        sections,
        leads,
    }
}

fn section(
    ops: &[Op],
    starts: &[P3],
    first: usize,
    last: usize,
    first_op: u32,
    last_op: u32,
) -> LitSection {
    LitSection {
        first_op,
        last_op,
        start: starts[first],
        start_feed_mm_s: feed_of(&ops[first]),
        end: ops[last].target().unwrap_or(starts[last]),
        end_feed_mm_s: feed_of(&ops[last]),
    }
}

/// The point each op starts at.
fn start_points(start: P3, ops: &[Op]) -> Vec<P3> {
    let mut pos = start;
    ops.iter()
        .map(|op| {
            let from = pos;
            if let Some(t) = op.target() {
                pos = t;
            }
            from
        })
        .collect()
}

/// Lit sections: (first, last) indices of maximal runs of moving lit ops; non-motion ops and
/// zero-length moves between two lit moves do not break a run.
fn lit_runs(ops: &[Op], moving: &[bool]) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut current: Option<(usize, usize)> = None;
    for (i, op) in ops.iter().enumerate() {
        if !moving[i] {
            continue;
        }
        match (op.laser().is_some(), current) {
            (true, Some((f, _))) => current = Some((f, i)),
            (true, None) => current = Some((i, i)),
            (false, Some(run)) => {
                runs.push(run);
                current = None;
            }
            (false, None) => {}
        }
    }
    runs.extend(current);
    runs
}

/// Ops that bring the machine to rest where they stand.
/// Room a lead keeps for the blends at its ends (`planner::lead_blend_room`): its corners
/// (the one to the lit move, whose axis-space continuation is straight only to rounding, and
/// the far one when it is entered or left at speed) are rounded over part of it, which then
/// cannot count toward its straight ramp. Scan rows run up by the same rule (`eval::scan`). A
/// machine that switches its beam at rest has lit leads: their corner to the lit move keeps
/// the velocity-step model and their far end is a stop, so they need no room.
fn blend_room(cx: &LeadContext<'_>) -> f64 {
    if !cx.switch_stops && cx.cfg.corners == planner::Corners::Blend {
        planner::lead_blend_room(cx.cfg.junction_deviation)
    } else {
        0.0
    }
}

fn is_stop(op: &Op) -> bool {
    matches!(
        op.kind,
        OpKind::Dwell { .. }
            | OpKind::MCode { .. }
            | OpKind::Event { .. }
            | OpKind::Output { stops: true, .. }
    )
}

/// Whether `op` fires pulses by distance (on the fly).
fn pulsed_by_distance(op: &Op) -> bool {
    op.laser()
        .and_then(|l| l.pulse.as_ref())
        .is_some_and(|p| matches!(p.mode, crate::program::PulseMode::Distance { .. }))
}

fn feed_of(op: &Op) -> f64 {
    match &op.kind {
        OpKind::Line { feed_mm_s, .. } | OpKind::Arc { feed_mm_s, .. } => *feed_mm_s,
        _ => f64::INFINITY,
    }
}

/// The laser of a lit lead (style a): the section's, without pulses, so that pulse trains
/// still start at the programmed first lit point.
fn lead_laser(l: Option<&Laser>) -> Arc<Laser> {
    let mut l = l.cloned().unwrap_or(Laser {
        power_w: 0.0,
        spot_mm: 0.0,
        pulse: None,
        couple: Default::default(),
        kerf_mm: 0.0,
    });
    l.pulse = None;
    Arc::new(l)
}

fn rapid(to: P3, like: &Op, orient: Option<Orient>) -> Op {
    Op {
        kind: OpKind::Rapid {
            to,
            orient: orient.map(Box::new),
        },
        span: like.span,
    }
}

/// A lead on a machine that orients the beam. A lead along the part's tangent would be a
/// corner in axis space (the beam stops turning where the lead meets the lit path), and the
/// planner would slow down exactly at the lit point. Instead the lead continues the adjacent
/// lit chord's axis-space direction: its far end is the forward kinematics of the axes at
/// `anchor` moved `d` further, away from `other`, along that chord. The spot then runs `d`
/// (to first order) off the part's path with the beam still turning, and the junction at the
/// lit point is straight. `None` on flat-bed machines, or when the extrapolated axes leave the
/// travel (the straight lead and its room check apply then).
fn oriented_lead(
    cx: &LeadContext<'_>,
    (anchor, o_anchor): (P3, Option<Orient>),
    (other, o_other): (P3, Option<Orient>),
    d: f64,
) -> Option<(P3, Orient)> {
    if !cx.kin.oriented() || !(d > 0.0) {
        return None;
    }
    let o = o_anchor.or(o_other)?;
    let len = dist(anchor, other);
    if len <= 1e-12 {
        return None;
    }
    let qa = axes_at(cx.kin, anchor, o_anchor.or(Some(o)), None)?;
    let qo = axes_at(cx.kin, other, o_other.or(Some(o)), Some(&qa))?;
    let mut q = qa;
    for k in 0..MAX_AXES {
        q[k] = qa[k] + (qa[k] - qo[k]) * d / len;
    }
    cx.kin.check(&q).ok()?;
    let pose = cx.kin.forward_at(&q, o.standoff_mm);
    Some((
        [pose.spot.x, pose.spot.y, pose.spot.z],
        Orient {
            beam: [pose.beam.x, pose.beam.y, pose.beam.z],
            standoff_mm: o.standoff_mm,
        },
    ))
}

/// The orientation in force when op `i` starts: the last one set before it.
fn orient_before(ops: &[Op], i: usize) -> Option<Orient> {
    ops[..i].iter().rev().find_map(|o| o.orient())
}

/// Unit direction and end point of the first straight piece the planner will see for `op`
/// starting at `from`.
fn entry_chord(op: &Op, from: P3, tol: f64) -> (P3, P3) {
    let end = match &op.kind {
        OpKind::Arc {
            to, center, ccw, ..
        } => arc_points(from, *to, *center, *ccw, tol)
            .first()
            .copied()
            .unwrap_or(*to),
        _ => op.target().unwrap_or(from),
    };
    (unit(from, end), end)
}

/// Unit direction and start point of the last straight piece of `op` starting at `from`.
fn exit_chord(op: &Op, from: P3, tol: f64) -> (P3, P3) {
    let to = op.target().unwrap_or(from);
    let begin = match &op.kind {
        OpKind::Arc { center, ccw, .. } => {
            let pts = arc_points(from, to, *center, *ccw, tol);
            if pts.len() >= 2 {
                pts[pts.len() - 2]
            } else {
                from
            }
        }
        _ => from,
    };
    (unit(begin, to), begin)
}

fn unit(a: P3, b: P3) -> P3 {
    let l = dist(a, b);
    if l > 0.0 {
        [(b[0] - a[0]) / l, (b[1] - a[1]) / l, (b[2] - a[2]) / l]
    } else {
        [0.0; 3]
    }
}

fn along(p: P3, u: P3, t: f64) -> P3 {
    [p[0] + t * u[0], p[1] + t * u[1], p[2] + t * u[2]]
}

/// Axis positions of spot `p` with the beam as `orient` says (a lead keeps the orientation of
/// the lit point it leads to), continuous with `prev` when given.
fn axes_at(
    kin: &dyn Kinematics,
    p: P3,
    orient: Option<Orient>,
    prev: Option<&Axes>,
) -> Option<Axes> {
    let q = kin.inverse(&super::tool_pose(p, orient), prev).ok()?;
    kin.check(&q).ok()?;
    Some(q)
}

/// [`ParabolicLeads::length`] along the straight piece `from → to` (0 where the machine
/// needs none or its ends are out of reach).
fn parabolic_length(
    cx: &LeadContext<'_>,
    (from, o_from): (P3, Option<Orient>),
    (to, o_to): (P3, Option<Orient>),
    v: f64,
    parts: f64,
) -> f64 {
    let Some(p) = cx.parabolic else {
        return 0.0;
    };
    let q0 = axes_at(cx.kin, from, o_from, None);
    let q1 = q0.and_then(|q0| axes_at(cx.kin, to, o_to, Some(&q0)));
    let (Some(q0), Some(q1)) = (q0, q1) else {
        return 0.0;
    };
    let dq: [f64; MAX_AXES] = std::array::from_fn(|k| q1[k] - q0[k]);
    p.length(&dq, dist(from, to), v, parts)
}

/// Speed, acceleration and jerk limits of the straight piece `from → to` at `feed`, as the
/// planner derives them. The feed must be reachable along it: a lead cannot help otherwise.
fn limits_along(
    cx: &LeadContext<'_>,
    (from, o_from): (P3, Option<Orient>),
    (to, o_to): (P3, Option<Orient>),
    feed: f64,
    op: &Op,
) -> Result<(f64, f64, f64), MotionError> {
    let length = dist(from, to);
    let q0 = axes_at(cx.kin, from, o_from, None);
    let q1 = q0.and_then(|q0| axes_at(cx.kin, to, o_to, Some(&q0)));
    let (Some(q0), Some(q1)) = (q0, q1) else {
        // Unreachable ends are reported with their own diagnostic by the lowering; the feed
        // is then all a lead can aim for.
        return Ok((feed, f64::INFINITY, f64::INFINITY));
    };
    let mut dq = [0.0; MAX_AXES];
    for k in 0..MAX_AXES {
        dq[k] = q1[k] - q0[k];
    }
    let (v, a, j) = planner::move_limits(&dq, length, feed, cx.limits, cx.cfg);
    if v < feed * (1.0 - 1e-9) {
        return Err(MotionError::FeedUnreachable {
            feed: speed(feed),
            limit: speed(v),
            span: op.span,
            help: format!(
                "lower the feed to at most {}, or turn lead-ins off with `planner {{ leadin none }}` \
                 to let the planner cap it (the beam is then on below the programmed speed)",
                speed(v)
            ),
        });
    }
    Ok((v, a, j))
}

/// How far from `p` along `sign · u` the machine can go, up to `want` (bisection on the
/// kinematics' travel check; travel regions are intervals along a line for the machines lase
/// knows).
fn room_along(
    kin: &dyn Kinematics,
    p: P3,
    orient: Option<Orient>,
    u: P3,
    sign: f64,
    want: f64,
) -> f64 {
    if !(want > 0.0) {
        return want.max(0.0);
    }
    if axes_at(kin, along(p, u, sign * want), orient, None).is_some() {
        return want;
    }
    if axes_at(kin, p, orient, None).is_none() {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, want);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if axes_at(kin, along(p, u, sign * mid), orient, None).is_some() {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Rounded down to the NC programs' 0.1 µm, so the travel check's rounding slack does not
/// show as "0.000001 mm".
fn floor_nc(x: f64) -> f64 {
    (x * 1e4).floor() / 1e4
}

fn mm(x: f64) -> String {
    format!("{} mm", format_number(x))
}

fn speed(v: f64) -> String {
    format!("{} mm/min", format_number(v * 60.0))
}

fn no_room_help(side: &str, lead: &str) -> String {
    format!(
        "the beam may only be on at the programmed speed, so lase needs room {side} this cut to \
         ramp; move the part away from the travel limit, or write `planner {{ leadin none }}` \
         to cut while the speed ramps (lead-{lead})"
    )
}
