//! Writing one motion block of an op: the point part way along it where a block is cut
//! (`part_way`), and the block itself with a carried beam switch cut into it (`write_block`).

use super::{Modal, Out, lead, motion_line};
use crate::axes::Axes;
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
            out.put_with(
                |line| motion_line(line, op, cut, cut_q, first, m, machine, arc_axes),
                tag,
            )?;
            out.stats.motion_blocks += 1;
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
    out.put_with(
        |line| motion_line(line, op, to, q, cap, m, machine, arc_axes),
        tag,
    )?;
    out.stats.motion_blocks += 1;
    Ok(())
}
