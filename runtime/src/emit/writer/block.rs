//! Writing one motion block of an op: the point part way along it where a block is cut
//! (`part_way`), the block itself with a carried beam switch cut into it (`write_block`) and
//! its words (`motion_line`).

use super::{FINE_MIN_MOVE_MM, MIN_CAP_MM_S, Modal, Out, chain, format, lead};
use crate::axes::{self, Axes};
use crate::machine::AxisKind;
use crate::program::{Op, OpKind, P3};
use std::io;

/// Block `op` (from spot `from` at axes `from_q`, to its planned axes `to_q`) cut at fraction
/// `f` of its length: the spot where the shorter block ends (its new target; the rest of the
/// op is unchanged), and the axes where the controller is then.
///
/// The axes are the point of the block as the controller runs it, so a sub-block never leaves
/// the move the planner timed: a line's axes interpolate straight (`from_q → to_q`, what
/// the controller does between two block ends), an arc's plane axes lie on its circle (the
/// part point: arcs are written only on machines whose X and Y move part x and y, validated)
/// and its other axes interpolate. On a Cartesian machine these are exactly the inverse
/// kinematics of the cut point.
pub(super) fn part_way(
    op: &Op,
    (from, from_q): (P3, &Axes),
    to_q: &Axes,
    f: f64,
    arc_axes: Option<(usize, usize, Option<usize>)>,
) -> (P3, Axes) {
    let end = op.target().unwrap_or(from);
    if f >= 1.0 {
        return (end, *to_q);
    }
    let mut q = from_q.lerp(to_q, f);
    match &op.kind {
        OpKind::Rapid { to, .. } | OpKind::Line { to, .. } => {
            (std::array::from_fn(|k| from[k] + f * (to[k] - from[k])), q)
        }
        OpKind::Arc { to, center, .. } => {
            let (r, a0, sweep) = op.arc_from(from).unwrap_or_default();
            let a = a0 + f * sweep;
            let z = from[2] + f * (to[2] - from[2]);
            let p = [center[0] + r * a.cos(), center[1] + r * a.sin(), z];
            if let Some((x, y, _)) = arc_axes {
                q[x] = p[0];
                q[y] = p[1];
            }
            (p, q)
        }
        _ => (end, q),
    }
}

/// Writes the block `(op, to, q, cap)` (see [`motion_line`]) from where the spot is; where a
/// beam switch is carried (`Out::pending`) and `lead::cut_at` finds its place inside the
/// block, the block is cut there and the switch written between its two parts; else the
/// switch goes before the block.
pub(super) fn write_block(
    out: &mut Out<'_>,
    m: &mut Modal,
    (op, to, q, cap): (&Op, P3, Axes, Option<f64>),
    machine: &crate::machine::Machine,
    arc_axes: Option<(usize, usize, Option<usize>)>,
    tag: Option<u32>,
) -> io::Result<()> {
    // A junction LinuxCNC blends parabolically is never cut (the piece would be a block far
    // shorter than its triangle time); `lead::shift` moved it instead.
    let parabolic = m.turned || lead::turns(machine, &m.q, &q);
    let mut cap = cap;
    if let Some(p) = out.pending.take() {
        let sub = lead::retarget(op, to);
        let len = sub.length_from(m.pos);
        // tp.c passes a tangent junction at the lower of its two blocks' feeds
        // (`tpGetRealFinalVel`), so the part from the edge to the carried switch is written at
        // the plan's speed at the edge: with the held lit block's mean there (or a lead-out's
        // full feed) LinuxCNC crossed the edges of serial_number's strokes 1.2 mm/s off it.
        let edge_cap = (p.v > 0.0).then_some(p.v);
        if let Some(at) = lead::cut_at(&sub, m, len, &p, cap, machine).filter(|_| !parabolic) {
            let (cut, cut_q) = part_way(&sub, (m.pos, &m.q), &q, at / len, arc_axes);
            let first = edge_cap.or(cap);
            put_motion(out, m, (op, cut, cut_q, first), machine, arc_axes, tag)?;
        } else if let Some(v) = edge_cap.filter(|_| !parabolic) {
            // Not cut: the switch goes before the block, which starts at the edge. A lead-out
            // no faster than the edge, a lit block no slower.
            cap = if p.off {
                Some(cap.map_or(v, |c| c.min(v)))
            } else {
                cap.map(|c| c.max(v))
            };
        }
        // Where it was cut, or else where the block starts, as without the lead: never past
        // the block (the next block may start with a switch line of its own).
        out.pending = Some(p);
        out.flush_pending()?;
    }
    put_motion(out, m, (op, to, q, cap), machine, arc_axes, tag)
}

/// Writes the motion block `(op, to, q, cap)` ([`motion_line`]) and, on LinuxCNC, keeps the
/// chain of G93 blocks tp runs since it last stopped (`chain`).
fn put_motion(
    out: &mut Out<'_>,
    m: &mut Modal,
    (op, to, q, cap): (&Op, P3, Axes, Option<f64>),
    machine: &crate::machine::Machine,
    arc_axes: Option<(usize, usize, Option<usize>)>,
    tag: Option<u32>,
) -> io::Result<()> {
    // A carried switch goes first, and the chain hears of it.
    out.flush_pending()?;
    let from_q = m.q;
    let mut chain = std::mem::take(&mut out.chain);
    out.put_with(
        |line| motion_line(line, op, to, q, cap, m, machine, arc_axes),
        tag,
    )?;
    out.stats.motion_blocks += 1;
    if out.dialect == crate::emit::Dialect::LinuxCnc {
        chain.after_block(machine, &op.kind, (&from_q, &q), m.block_s, out.tolerance);
        out.chain = chain;
    }
    Ok(())
}

/// The block that moves the spot to `to` at axes `q` (planned: see [`part_way`]) as `op`
/// says (its motion mode, feed and arc centre; `to` is the op's target or a point part way
/// along it), its words appended to `line` (after the ISO block number or a trigger word a
/// caller put there), each separated by one space. `cap` is the plan's mean speed over a
/// lit sub-block (`power::PowerBlock::v_cap`): where it is below the op's feed, the block's
/// feed is that speed (in G93 its planned time), so the controller runs it no faster than
/// lase planned (and coupled the power to).
#[allow(clippy::too_many_arguments)] // the block, where it ends, and the modal state
pub(super) fn motion_line(
    line: &mut String,
    op: &Op,
    to: P3,
    q: Axes,
    cap: Option<f64>,
    m: &mut Modal,
    machine: &crate::machine::Machine,
    arc_axes: Option<(usize, usize, Option<usize>)>,
) {
    let (g, feed) = match &op.kind {
        OpKind::Rapid { .. } => ("G0", None),
        OpKind::Line { feed_mm_s, .. } => ("G1", Some(*feed_mm_s)),
        OpKind::Arc { ccw, feed_mm_s, .. } => (if *ccw { "G3" } else { "G2" }, Some(*feed_mm_s)),
        _ => unreachable!("motion_line is called for motion ops only"),
    };
    let feed = feed.map(|f| match cap {
        Some(c) if c < f => c.max(MIN_CAP_MM_S),
        _ => f,
    });
    // Words go straight into the line handed to the sink: this runs once per NC block, and a
    // million-spot raster writes millions of them.
    let start = line.len();
    let word = |line: &mut String, letter: &str, value: &str| {
        if line.len() > start {
            line.push(' ');
        }
        line.push_str(letter);
        line.push_str(value);
    };
    if m.motion != Some(g) {
        word(line, g, "");
        m.motion = Some(g);
    }
    // An arc always names its plane's axes: a full circle ends where it starts, and G2/G3
    // without axis words is an error.
    let arc_plane = match (&op.kind, arc_axes) {
        (OpKind::Arc { .. }, Some((x, y, _))) => Some((x, y)),
        _ => None,
    };
    let mut v = std::mem::take(&mut m.scratch);
    for (k, axis) in machine.axes.iter().enumerate() {
        let forced = arc_plane.is_some_and(|(x, y)| k == x || k == y);
        if !forced && m.words[k].is_number(q[k]) {
            continue;
        }
        // To 1 nm, but an axis moves only where it moves by the old 0.1 µm resolution: below
        // that, what changes is the kinematics' rounding noise (a few nm), and a block that
        // carried it would turn a rotary-only move into an X Y Z one, which controllers time
        // by its X Y Z length. The axis stays within 0.05 µm of its planned position.
        if m.fine
            && !forced
            && axis.kind == AxisKind::Linear
            && m.words[k].written
            && (q[k] - f64::from_bits(m.words[k].value)).abs() < FINE_MIN_MOVE_MM
        {
            continue;
        }
        v.clear();
        match axis.kind {
            AxisKind::Linear if m.fine => v.push_str(&format::fine_number(q[k])),
            AxisKind::Linear => format::number_into(&mut v, q[k]),
            AxisKind::Rotary => v.push_str(&format::degrees(axes::to_external(axis.kind, q[k]))),
        }
        if forced || !m.words[k].is(&v) {
            word(line, &axis.name, &v);
        }
        m.words[k].set(&v, q[k]);
    }
    if let OpKind::Arc { center, .. } = &op.kind {
        // Center relative to the start, in part x/y (= machine X/Y, validated).
        word(line, "I", &format::number(center[0] - m.pos[0]));
        word(line, "J", &format::number(center[1] - m.pos[1]));
    }
    match feed {
        Some(f) if m.inverse_time => {
            // G93: F is the inverse of the block's time in minutes, written on every block.
            let seconds = chain::g93_seconds(machine, (m.pos, &m.q), (to, &q), f);
            word(line, "F", &format::inverse_time(60.0 / seconds));
            m.feed.unset();
            m.block_s = Some(seconds);
        }
        Some(f) if m.feed.is_number(f) => {}
        Some(f) => {
            v.clear();
            format::number_into(&mut v, f * 60.0);
            if !m.feed.is(&v) {
                word(line, "F", &v);
            }
            m.feed.set(&v, f);
        }
        None => m.feed.unset(),
    }
    if !(m.inverse_time && feed.is_some()) {
        m.block_s = None;
    }
    m.scratch = v;
    m.dir = lead::direction(op, m.pos, to, true);
    m.turned = lead::turns(machine, &m.q, &q);
    m.pos = to;
    m.q = q;
}
