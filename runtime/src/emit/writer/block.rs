//! Writing one motion block of an op: the point part way along it where a block is cut
//! (`part_way`), the block itself with a carried beam switch cut into it (`write_block`), its
//! words (`motion_line`), and the off-edge's timing on LinuxCNC (`off_edge_timing`).

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

/// Where lit Line op `i`'s last block ends and the feed it is written at, mm/s, where a
/// lead-out written in two before a stop follows it (`lead::split`) on a LinuxCNC program in
/// inverse time and the chain of blocks before it is known from rest: the block runs from
/// spot `from` at axes `from_q` to its moved junction `to` at `q` (`lead::shift`), held to
/// `cap`. The junction moves by up to half a servo period of travel either way, the block's
/// time grows by up to a period and at most [`TRIM_REL`] of it, and the lead-out's first block's length
/// (kept in `out.split_len`) is chosen, so that tp.c's replay (`chain::Chain::replay_off`)
/// crosses the off-edge nearest the lit speed with the beam within half a period of travel
/// of its planned place ([`MAX_PLACE_PERIODS`]). `None` (written as it was, the lead-out split by the mean
/// gain, `lead::split_at`) where the replay does not model the chain or finds nothing better
/// than that.
///
/// The place: the joints follow tp's point two servo periods late (control.c's cubic
/// interpolator, `lead::LEAD_PERIODS`), so the beam goes off where the joints are then:
/// `d + past − 2·v·T` past the planned edge, `d` how far the junction moved, `past` how far
/// past it tp's point is at the switch. On the real LinuxCNC the ring's off-edge with the
/// mean split (past 0.37 periods in the replay) measured −0.12 periods; this gives −0.13.
#[allow(clippy::too_many_arguments)] // the op, its block, and the lead-out's
pub(super) fn off_edge_timing(
    out: &mut Out<'_>,
    job: &crate::motion::Job,
    i: usize,
    ((from, from_q), (to, q)): ((P3, &Axes), (P3, &Axes)),
    cap: f64,
    servo_s: f64,
) -> Option<(P3, Axes, f64)> {
    use super::chain::{Link, g93_seconds};
    let machine = &job.program.machine;
    let ops = &job.program.ops;
    let OpKind::Line { feed_mm_s, .. } = ops[i].kind else {
        return None;
    };
    let feed = feed_mm_s.min(cap).max(super::MIN_CAP_MM_S);
    let end = ops[i].target()?;
    let j = i + 1 + ops[i + 1..].iter().position(|o| o.moves_from(end))?;
    let (
        OpKind::Line {
            to: out_end,
            feed_mm_s: out_feed,
            ..
        },
        None,
    ) = (&ops[j].kind, ops[j].laser())
    else {
        return None;
    };
    let (out_end, out_feed) = (*out_end, *out_feed);
    let (q_end, q_out) = (job.op_axes.get(i), job.op_axes.get(j));
    let out_len = crate::program::dist(end, out_end);
    let w = lead::direction(&ops[j], end, out_end, false)?;
    let d0 = crate::program::dist(end, to);
    let turned = lead::turns(machine, from_q, q);
    let long = out_len > 0.0 && crate::program::dist(from, to) > 1e-9;
    if !(long && lead::split(job, j, (to, q), turned)) {
        return None;
    }
    // The junction `d` mm along the lead-out, as `lead::shift` moves it.
    let at = |d: f64| -> (P3, Axes) {
        let p = std::array::from_fn(|k| end[k] + w[k] * d);
        (p, q_end.lerp(&q_out, d / out_len))
    };
    let tol = out.tolerance;
    let lit_link = |(p, qp): (P3, &Axes), trim: f64| {
        let t = crate::program::dist(from, p) / feed + trim;
        Link::of(machine, (from_q, qp), t, tol)
    };
    let link = |(a, qa): (P3, &Axes), (b, qb): (P3, &Axes)| {
        let t = g93_seconds(machine, (a, qa), (b, qb), out_feed);
        Link::of(machine, (qa, qb), t, tol)
    };
    let parts = |(p, qp): (P3, &Axes), len1: f64| {
        let rest = crate::program::dist(p, out_end);
        let (mid, mid_q) = part_way(&ops[j], (p, qp), &q_out, len1 / rest, None);
        Some((
            link((p, qp), (mid, &mid_q))?,
            link((mid, &mid_q), (out_end, &q_out))?,
        ))
    };
    let base = lit_link((to, q), 0.0)?;
    if !out.chain.replayable(machine, &base) {
        return None;
    }
    let time = crate::program::dist(from, to) / feed;
    let period = servo_s;
    let step = feed * period;
    let max_trim = period.min(TRIM_REL * time);
    let rest0 = crate::program::dist(to, out_end);
    let lens: Vec<f64> = lead::split_candidates(machine, (q, &q_out), rest0, out_feed, period, 5)
        .into_iter()
        .map(|f| f * rest0)
        .collect();
    let mean_len = lead::split_at(machine, (q, &q_out), rest0, out_feed, period) * rest0;
    // The chain once, then each candidate's lit block and lead-out.
    let tail = (time + out_len / out_feed) / period;
    let scans = (1 + D_STEPS) * (1 + TRIM_STEPS) * lens.len();
    let budget = out.chain.seconds() / period + tail * scans as f64;
    if budget > MAX_SCAN_PERIODS {
        return None;
    }
    let prefix = out.chain.prefix(period)?;
    // Each (speed error, place in periods, trim, first block's length) for the junction at
    // `d`: where it is, the lit speed and mm per tp unit depend on `d` only, the lead-out's
    // two blocks on `d` and the length, the lit block on `d` and the trim.
    let scan = |d: f64, trims: &[f64], lens: &[f64]| -> Vec<(f64, f64, f64, f64)> {
        let (p, qp) = at(d);
        let Some(untrimmed) = lit_link((p, &qp), 0.0) else {
            return Vec::new();
        };
        let want = untrimmed.seg().v;
        // tp's units to mm along the path: the lit block's own ratio.
        let mm = crate::program::dist(from, p) / untrimmed.seg().len;
        let endings: Vec<(f64, (Link, Link))> = lens
            .iter()
            .filter_map(|&len1| Some((len1, parts((p, &qp), len1)?)))
            .collect();
        let mut found = Vec::new();
        for &trim in trims {
            let Some(lit) = lit_link((p, &qp), trim) else {
                continue;
            };
            for (len1, (a, b)) in &endings {
                if let Some((v, past)) = out.chain.replay_off(&prefix, (&lit, a, b)) {
                    let place = (d + past * mm - 2.0 * step) / step;
                    found.push(((v / want - 1.0).abs(), place, trim, *len1));
                }
            }
        }
        found
    };
    let &(base_err, base_place, ..) = scan(d0, &[0.0], &[mean_len]).first()?;
    // Only longer: a cap above the feed is not written (`motion_line`).
    let trims: Vec<f64> = (0..=TRIM_STEPS)
        .map(|kt| max_trim * kt as f64 / TRIM_STEPS as f64)
        .collect();
    let mut best: Option<(f64, f64, f64, f64, f64)> = None;
    for kd in 0..=D_STEPS {
        let d = d0 + step * (kd as f64 / D_STEPS as f64 - 0.5);
        if !(d > 0.0 && d < 0.5 * out_len) {
            continue;
        }
        for (err, place, trim, len1) in scan(d, &trims, &lens) {
            if place.abs() > MAX_PLACE_PERIODS.max(base_place.abs()) {
                continue;
            }
            if best.is_none_or(|(e, ..)| err < e - 1e-12) {
                best = Some((err, place, d, trim, len1));
            }
        }
    }
    let (err, _, d, trim, len1) = best?;
    if err >= base_err {
        return None;
    }
    let (p, qp) = at(d);
    out.split_len = Some((j, len1));
    let len = crate::program::dist(from, p);
    Some((p, qp, len / (len / feed + trim)))
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

/// The most a lit block's speed is changed to time its off-edge (`off_edge_timing`): a
/// twentieth of the plan's 0.1 % on the lit surface speed.
const TRIM_REL: f64 = 5e-4;

/// Steps over the period of travel the junction is moved by, and over the lit block's time
/// (`off_edge_timing`).
const D_STEPS: usize = 8;
const TRIM_STEPS: usize = 8;

/// The most servo periods of travel the beam goes off from its planned place where the
/// off-edge is timed (`off_edge_timing`), unless it went off farther before: half a period,
/// the spread tp's switching once a period leaves any edge (`lead::LEAD_PERIODS`).
const MAX_PLACE_PERIODS: f64 = 0.5;

/// The most servo periods an off-edge's scan replays, all replays summed: some 10⁷ steps of
/// tp's arithmetic, a tenth of a second.
const MAX_SCAN_PERIODS: f64 = 1.0e7;
