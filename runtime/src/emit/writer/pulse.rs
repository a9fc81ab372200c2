//! Pulses in NC text: pulses by distance on the fly, a PSO header, and dot-mode fire windows.
//!
//! One model for every dialect: a pulse is a rising edge of the trigger (`pulse_on` lines of
//! the post; the Q-switch card fires once per edge, as the paper's scale-fed card does).
//!
//! * On the fly, by distance (no `pso` in the post): a lit move is cut at every pulse position
//!   (counted from the start of its lit section, as `report::pulse_events` counts them) into a
//!   trigger-high block of half a pitch (at most the rest of the move) and a trigger-low block
//!   to the next pulse. LinuxCNC's `M62`/`M63` are motion-synchronized: written on the block
//!   they belong to, they switch exactly where that block starts, without stopping. GRBL (and
//!   grblHAL, as lase writes it) has no synchronized output: in laser mode the S word changes
//!   without a stop, so the high block is written at the section's power and the low block at
//!   `S0`, and the high block is kept to half the spot diameter (a dot, not a dash). A post
//!   without `pulse_on` lines gates each pulse with the beam's own on/off lines. No block
//!   carries two switches of the trigger: LinuxCNC keeps only the last one per output and
//!   segment, so where a train ends high and the next one rises on its first block (touching
//!   dots in runs of different pitch), the trigger falls earlier, on a block of its own
//!   ([`lower_before_the_next_train`]).
//! * With `pso` lines in the post the controller fires by distance itself: the lines are
//!   written (with the pitch) when a section with a new pitch starts, and the lit moves are
//!   written as plain blocks with the beam on.
//! * Dot mode (`OpKind::Fire`): at rest, the beam on with the post's lines (LinuxCNC: the
//!   immediate `M64`/`M68` instead of the synchronized `M62`/`M67`, which would wait for a
//!   motion that never comes), then per pulse the trigger high for half the period and low for
//!   the other half (`G4` dwells), then the beam off.
//!
//! A pulse that falls exactly on the end of a section's last lit move has no block left to
//! start on; its edge is written a gate length earlier (scan rows end half a pitch past their
//! last spot, so they never meet this case).

use super::super::format::{self, LaserWords};
use super::{Modal, Out, immediate, motion_line, part_way};
use crate::emit::Dialect;
use crate::machine::{DialectPost, Machine};
use crate::program::{Op, OpKind, Pulse, PulseMode};
use std::io;

/// The pulse train in progress, carried across the lit moves of one section.
#[derive(Debug, Default)]
pub(super) struct Train {
    pulse: Option<Pulse>,
    /// Index of the last op written with this train.
    last_op: usize,
    /// Distance from the current position to the next pulse, mm.
    next_mm: f64,
    /// The pitch the PSO lines last configured.
    pso_pitch: Option<f64>,
    /// The trigger is high (written high and not lowered yet).
    trigger: bool,
}

fn distance_pitch(op: &Op) -> Option<(f64, &Pulse)> {
    let pulse = op.laser()?.pulse.as_ref()?;
    match pulse.mode {
        PulseMode::Distance { pitch_mm } => Some((pitch_mm, pulse)),
        PulseMode::Time { .. } => None,
    }
}

impl Train {
    /// The pitch when op `i` is to be written with a pulse per trigger edge; starts or
    /// continues the train.
    pub(super) fn gated(&mut self, ops: &[Op], i: usize, post: &DialectPost) -> Option<f64> {
        if !post.pso.is_empty() {
            return None;
        }
        let (pitch, pulse) = distance_pitch(&ops[i])?;
        let continues = self.pulse.as_ref() == Some(pulse)
            && self.last_op < i
            && ops[self.last_op + 1..i]
                .iter()
                .all(|o| o.target().is_none());
        if !continues {
            self.pulse = Some(pulse.clone());
            self.next_mm = 0.0;
            self.trigger = false;
        }
        self.last_op = i;
        Some(pitch)
    }

    /// Writes the PSO lines before a lit section whose pitch differs from the one configured.
    pub(super) fn pso(
        &mut self,
        op: &Op,
        beam_on: bool,
        out: &mut Out<'_>,
        post: &DialectPost,
        tag: Option<u32>,
    ) -> io::Result<()> {
        if post.pso.is_empty() || beam_on {
            return Ok(());
        }
        let Some((pitch, _)) = distance_pitch(op) else {
            return Ok(());
        };
        if self.pso_pitch == Some(pitch) {
            return Ok(());
        }
        for t in &post.pso {
            out.put(&format::fill_pitch(t, pitch), tag)?;
        }
        self.pso_pitch = Some(pitch);
        Ok(())
    }
}

/// What `write_gated` needs to know about the machine and the dialect.
pub(super) struct Gate<'a> {
    pub dialect: Dialect,
    pub post: &'a DialectPost,
    pub machine: &'a Machine,
    /// The planned axes each op ends at (`Job::op_axes`).
    pub op_axes: &'a crate::motion::OpAxes,
    pub arc_axes: Option<(usize, usize, Option<usize>)>,
    pub words: &'a dyn Fn(f64) -> LaserWords,
}

/// Whether the lit section goes on after op `i` with the same pulses (the next op that moves
/// is lit with the same pulse setting).
fn continues(ops: &[Op], i: usize) -> bool {
    let pulse = ops[i].laser().and_then(|l| l.pulse.as_ref());
    ops[i + 1..]
        .iter()
        .find(|o| o.target().is_some())
        .is_some_and(|o| o.laser().is_some() && o.laser().and_then(|l| l.pulse.as_ref()) == pulse)
}

/// Whether the next op that moves starts a train of its own, with a rising trigger edge on
/// its first block: lit, pulsed by distance without PSO, and not `ops[i]`'s train going on.
fn next_train_starts(ops: &[Op], i: usize, post: &DialectPost) -> bool {
    post.pso.is_empty()
        && !continues(ops, i)
        && ops[i + 1..]
            .iter()
            .find(|o| o.target().is_some())
            .and_then(distance_pitch)
            .is_some()
}

/// A section that ends with the trigger high, where the next one raises it on its first block
/// (two dots that touch, in runs of different pitch: codes' Data Matrix), would lower and
/// raise it before the same block. LinuxCNC keeps one synchronized switch per output and
/// segment, the last one queued (tp.c `tpSetDout`: `syncdio.dios[index]` is a single slot
/// that `tpAddLine` hands to the next segment), so the trigger would stay high and the second
/// pulse never fire. The last high piece is halved instead: the trigger falls on a block of
/// its own, half the gate before the section's end, and the next pulse still rises where it
/// belongs. The gate is half a pitch and the piece at least its half, so the split always
/// fits; the pulses' places do not move.
fn lower_before_the_next_train(cuts: &mut Vec<(f64, bool)>, len: f64, eps: f64) {
    let Some(&(end, true)) = cuts.last() else {
        return;
    };
    let start = cuts.len().checked_sub(2).map_or(0.0, |k| cuts[k].0);
    if end < len - eps {
        return;
    }
    let mid = 0.5 * (start + end);
    if mid > start + eps {
        let n = cuts.len();
        cuts[n - 1] = (mid, true);
        cuts.push((end, false));
    }
}

/// Writes lit op `ops[i]` cut at its pulse positions (see the module header).
#[allow(clippy::too_many_arguments)]
pub(super) fn write_gated(
    ops: &[Op],
    i: usize,
    pitch: f64,
    lead: f64,
    train: &mut Train,
    out: &mut Out<'_>,
    m: &mut Modal,
    g: &Gate<'_>,
    tag: Option<u32>,
) -> io::Result<()> {
    let op = &ops[i];
    let (from, from_q) = (m.pos, m.q);
    let len = op.length_from(from);
    let laser = op.laser();
    let power = laser.map_or(0.0, |l| l.power_w);
    let gate = if g.dialect.is_grbl_family() {
        (0.5 * pitch).min(0.5 * laser.map_or(pitch, |l| l.spot_mm))
    } else {
        0.5 * pitch
    };
    let goes_on = continues(ops, i);
    let eps = 1e-9;
    // Pieces as (distance along the op at their end, trigger high); pulse k of this op at
    // `first + k·pitch`, from the section's count, never accumulated.
    let first = train.next_mm;
    let mut cuts: Vec<(f64, bool)> = Vec::new();
    let mut pos = 0.0;
    let mut k = 0u64;
    let at = |k: u64| first + k as f64 * pitch;
    while at(k) < len - eps {
        let s = at(k);
        if s > pos + eps {
            cuts.push((s, false));
        }
        let hi_end = (s + gate).min(len);
        cuts.push((hi_end, true));
        pos = hi_end;
        k += 1;
    }
    if at(k) <= len + eps && !goes_on {
        // A pulse on the very end of the section (see the module header).
        let start = (len - gate).max(pos);
        if start > pos + eps {
            cuts.push((start, false));
        }
        if len > start + eps {
            cuts.push((len, true));
            pos = len;
        }
        k += 1;
    }
    if pos < len - eps {
        cuts.push((len, false));
    }
    if !goes_on && !g.dialect.is_grbl_family() && next_train_starts(ops, i, g.post) {
        lower_before_the_next_train(&mut cuts, len, eps);
    }
    train.next_mm = (at(k) - len).max(0.0);
    let mut trigger = train.trigger;
    // A beam switch carried here (`lead`): where `lead::cut_at` puts it in this block, else
    // before it.
    let incoming = out.pending.take();
    let servo_s = g.machine.servo_period_s();
    let feed = match &op.kind {
        OpKind::Line { feed_mm_s, .. } | OpKind::Arc { feed_mm_s, .. } => *feed_mm_s,
        _ => 0.0,
    };
    let min_block = super::lead::MIN_PART_PERIODS * servo_s * feed;
    // Where the first carried edge can go: `lead` where the block continues the one before
    // in line, else past tp's blend arc over the junction (`lead::cut_at`, as a beam switch).
    let first_at = (lead > 0.0)
        .then(|| {
            let p = super::lead::Pending {
                lines: Vec::new(),
                left: lead,
                off: false,
                servo_s,
                v: feed,
                tag,
            };
            let sub = super::lead::retarget(op, op.target().unwrap_or(from));
            super::lead::cut_at(&sub, m, len, &p, None, g.machine)
        })
        .flatten();
    let carried = first_at
        .filter(|_| !g.post.pulse_on.is_empty() && !g.post.pulse_off.is_empty())
        .and_then(|first| carry_edges(&cuts, trigger, (first, lead), len, !goes_on, min_block));
    let (mut cuts, beyond) = match carried {
        Some(c) => c,
        None => (cuts, None),
    };
    let switch_at = incoming.as_ref().and_then(|p| {
        let sub = super::lead::retarget(op, op.target().unwrap_or(from));
        super::lead::cut_at(&sub, m, len, p, None, g.machine)
    });
    let switch_at = switch_at.map(|a| split_at(&mut cuts, a, min_block));
    let mut incoming = incoming;
    if switch_at.is_none() {
        out.pending = incoming.take();
        out.flush_pending()?;
    }
    let mut start = 0.0;
    for (s, high) in cuts {
        if switch_at.is_some_and(|a| (a - start).abs() < 1e-9) {
            // Written by the next line, before its block.
            out.pending = incoming.take();
        }
        start = s;
        let f = if len > 0.0 { s / len } else { 1.0 };
        let (to, q) = part_way(op, (from, &from_q), &g.op_axes.get(i), f, g.arc_axes);
        let block = |line: &mut String, m: &mut Modal| {
            motion_line(line, op, to, q, None, m, g.machine, g.arc_axes)
        };
        if high != trigger {
            write_edge(out, g, high, power, m, block, tag)?;
            if g.dialect.is_grbl_family() {
                // The S word it wrote is in force now.
                m.s = Some(grbl_s(g, if high { power } else { 0.0 }));
            }
            trigger = high;
        } else {
            out.put_with(|line| block(line, m), tag)?;
        }
        out.stats.motion_blocks += 1;
    }
    if let Some(p) = incoming.take() {
        out.pending = Some(p);
        out.flush_pending()?;
    }
    if let Some((left, high)) = beyond {
        // The edge carried past the block's end: written `left` mm into the next block, as a
        // beam switch is (the beam-off, carried as far, joins it).
        let w = (g.words)(if high { power } else { 0.0 });
        let lines = if high {
            &g.post.pulse_on
        } else {
            &g.post.pulse_off
        };
        out.pending = Some(super::lead::Pending {
            lines: lines.iter().map(|t| format::fill(t, w)).collect(),
            left,
            off: false,
            servo_s,
            v: feed,
            tag,
        });
        trigger = high;
    } else if trigger && !goes_on {
        // Lowered with the next motion, the section's end (GRBL: the beam-off line does it).
        if !g.dialect.is_grbl_family() {
            let w = (g.words)(0.0);
            for t in &g.post.pulse_off {
                out.put(&format::fill(t, w), tag)?;
            }
        }
        trigger = false;
    }
    train.trigger = trigger;
    Ok(())
}

/// A piece of a pulsed block: where it ends along the block (mm) and whether the trigger is
/// high along it; for an edge carried past the block's end, how far into the next block.
type Piece = (f64, bool);

/// The pieces `cuts` (each's end along the op and the trigger along it; `before`: the
/// trigger coming in) with every trigger edge carried `lead` mm further along a block `len`
/// mm long, as the writer carries a beam switch (`lead`: LinuxCNC switches a synchronized
/// output, `M62`/`M63` as tp.c `tpSetDout` queues them, as tp takes up the block, 1.5 servo
/// periods before the joints get there). The pieces keep their lengths; the first, the
/// trigger as it came in, is `first` long (`lead`, or past tp's blend arc where the block
/// does not continue the one before in line: an edge on the block's start comes there) and
/// the last shorter. An
/// edge carried past the end is returned (how far into the next block, the trigger then) for
/// the next block; with `low_at_end` (the section ends here) the trigger falls `lead` past
/// the end if it is high there. `None` (nothing carried) where a piece would be left shorter
/// than tp runs at speed (`min_block`, unless the pieces were already as short) or two edges
/// would fall past the end.
fn carry_edges(
    cuts: &[(f64, bool)],
    before: bool,
    (first, lead): (f64, f64),
    len: f64,
    low_at_end: bool,
    min_block: f64,
) -> Option<(Vec<Piece>, Option<Piece>)> {
    let eps = 1e-9;
    let shortest = cuts
        .iter()
        .scan(0.0, |s0, &(s, _)| {
            let l = s - *s0;
            *s0 = s;
            Some(l)
        })
        .fold(f64::INFINITY, f64::min);
    let mut out: Vec<(f64, bool)> = Vec::with_capacity(cuts.len() + 1);
    let mut beyond: Option<(f64, bool)> = None;
    let (mut start, mut state) = (0.0, before);
    for (e, h) in std::iter::once((first, before)).chain(cuts.iter().map(|&(s, h)| (s + lead, h))) {
        if start >= len - eps {
            if h != state {
                if beyond.is_some() {
                    return None;
                }
                beyond = Some((start - len, h));
            }
        } else if let Some(last) = out.last_mut().filter(|l| l.1 == h) {
            // The same trigger on: one block.
            last.0 = last.0.max(e.min(len));
        } else {
            out.push((e.min(len), h));
        }
        start = e;
        state = h;
    }
    if low_at_end && state {
        if beyond.is_some() {
            return None;
        }
        beyond = Some((start - len, false));
    }
    let mut s0 = 0.0;
    for &(s, _) in &out {
        if s - s0 < min_block.min(shortest) - eps {
            return None;
        }
        s0 = s;
    }
    Some((out, beyond))
}

/// Where the pieces `cuts` are split for a carried beam switch `at` mm along: at a piece's
/// end within 0.1 µm of it, else the piece `at` falls in is cut there where both parts last
/// `min_block` (else the switch goes where that piece starts). Returns where the switch is
/// written.
fn split_at(cuts: &mut Vec<(f64, bool)>, at: f64, min_block: f64) -> f64 {
    let mut s0 = 0.0;
    for k in 0..cuts.len() {
        let (s, h) = cuts[k];
        if (at - s0).abs() < 1e-4 {
            return s0;
        }
        if at < s {
            if (s - at).abs() < 1e-4 {
                return s;
            }
            if at - s0 >= min_block && s - at >= min_block {
                cuts.insert(k, (at, h));
                return at;
            }
            return s0;
        }
        s0 = s;
    }
    s0
}

/// The S word of `power_w` on a GRBL-family gate block.
fn grbl_s(g: &Gate<'_>, power_w: f64) -> String {
    let w = (g.words)(power_w);
    format!("S{}", format::number(w.power_w / w.max_power_w * w.s_max))
}

/// A motion block (`block` writes its words) with the trigger switched at its start.
fn write_edge(
    out: &mut Out<'_>,
    g: &Gate<'_>,
    high: bool,
    power_w: f64,
    m: &mut Modal,
    block: impl FnOnce(&mut String, &mut Modal),
    tag: Option<u32>,
) -> io::Result<()> {
    if g.dialect.is_grbl_family() {
        let s = grbl_s(g, if high { power_w } else { 0.0 });
        return out.put_with(
            |line| {
                block(line, m);
                line.push(' ');
                line.push_str(&s);
            },
            tag,
        );
    }
    let (lines, fallback) = if high {
        (&g.post.pulse_on, &g.post.laser_on)
    } else {
        (&g.post.pulse_off, &g.post.laser_off)
    };
    let w = (g.words)(power_w);
    match (lines.len(), lines.is_empty()) {
        (1, _) => out.put_with(
            |line| {
                format::fill_into(line, &lines[0], w);
                line.push(' ');
                block(line, m);
            },
            tag,
        ),
        (_, false) => {
            for t in lines {
                out.put(&format::fill(t, w), tag)?;
            }
            out.put_with(|line| block(line, m), tag)
        }
        (_, true) => {
            for t in fallback {
                out.put(&format::fill(t, w), tag)?;
            }
            out.put_with(|line| block(line, m), tag)
        }
    }
}

/// Writes a dot-mode fire window at rest.
pub(super) fn write_fire(
    op: &Op,
    out: &mut Out<'_>,
    g: &Gate<'_>,
    tag: Option<u32>,
) -> io::Result<()> {
    let OpKind::Fire {
        count,
        period_s,
        laser,
        ..
    } = &op.kind
    else {
        return Ok(());
    };
    let w = (g.words)(laser.power_w);
    let at_rest = |line: String| {
        if g.dialect == Dialect::LinuxCnc {
            immediate(&line).replace("M67", "M68").replace("m67", "m68")
        } else {
            line
        }
    };
    let half = super::dwell(g.dialect, 0.5 * period_s);
    let triggered = !g.post.pulse_on.is_empty() && !g.dialect.is_grbl_family();
    if triggered {
        for t in &g.post.laser_on {
            out.put(&at_rest(format::fill(t, w)), tag)?;
        }
    }
    for _ in 0..*count {
        let (on, off) = if triggered {
            (&g.post.pulse_on, &g.post.pulse_off)
        } else {
            (&g.post.laser_on, &g.post.laser_off)
        };
        for t in on {
            out.put(&at_rest(format::fill(t, w)), tag)?;
        }
        out.put(&half, tag)?;
        for t in off {
            out.put(&at_rest(format::fill(t, (g.words)(0.0))), tag)?;
        }
        out.put(&half, tag)?;
    }
    if triggered {
        for t in &g.post.laser_off {
            out.put(&at_rest(format::fill(t, (g.words)(0.0))), tag)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trigger_edges_are_carried_by_the_lead_and_a_last_fall_past_the_end() {
        // Pulses at 0 and 0.2 mm of a 0.4 mm block, gates of 0.1 mm, carried 0.03 mm: the
        // trigger comes in low up to 0.03, then every edge 0.03 later; the last piece shorter.
        let cuts = [(0.1, true), (0.2, false), (0.3, true), (0.4, false)];
        let (out, beyond) = carry_edges(&cuts, false, (0.03, 0.03), 0.4, true, 0.025).unwrap();
        let want = [
            (0.03, false),
            (0.13, true),
            (0.23, false),
            (0.33, true),
            (0.4, false),
        ];
        assert_eq!(out.len(), want.len());
        for (a, b) in out.iter().zip(&want) {
            assert!((a.0 - b.0).abs() < 1e-12 && a.1 == b.1, "{out:?}");
        }
        assert_eq!(beyond, None);
        // A section ending high: its fall lands 0.03 mm into the next block.
        let cuts = [(0.1, true), (0.2, false), (0.3, true)];
        let (out, beyond) = carry_edges(&cuts, false, (0.03, 0.03), 0.3, true, 0.025).unwrap();
        assert_eq!(out.last().map(|p| p.1), Some(true));
        let (left, high) = beyond.unwrap();
        assert!((left - 0.03).abs() < 1e-12 && !high);
        // Carried past a gate (0.15 mm against 0.1 mm gates), a rise and a fall would both land
        // past the end, on one block to LinuxCNC: nothing is carried.
        assert_eq!(
            carry_edges(&cuts, false, (0.15, 0.15), 0.3, true, 0.025),
            None
        );
    }
}
