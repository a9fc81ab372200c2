//! The inverse-time blocks a LinuxCNC program has queued since tp last stopped, as the writer
//! wrote them, so that a beam switch further on can be timed by tp.c's own arithmetic
//! (`motion::parabolic::chain::run_chain`) from the rest the chain started at.
//!
//! tp.c runs a chain of G93 blocks that turn a rotary axis as parabolic blends, servo period
//! by servo period from the rest it started at (a rapid meeting a feed is a stop,
//! `tpCheckCanonType`). Where in its period each block's deceleration turns, and so how fast
//! the summed speeds of a blend run when a synchronized output switches, follows from that
//! clock. [`Chain`] keeps the blocks since the last rapid; any other line but a comment,
//! `G93` or a synchronized output (`M62`/`M63`/`M67`, which tp queues with the next block
//! without a stop) forgets them, as does an arc, a block in units per minute or a chain too
//! long to replay ([`MAX_LINKS`]). `timing::off_edge_timing` times a lit block and the
//! lead-out after it with it ([`Chain::replay_off`]).

use crate::axes::Axes;
use crate::machine::{AxisKind, Machine};
use crate::motion::parabolic::{Block, chain as tp};
use crate::program::{OpKind, P3};

/// Longest chain kept: a lit run longer than this is left to the mean gain
/// (`lead::split_at`), and the chain's memory stays bounded on any job.
const MAX_LINKS: usize = 4096;

/// Servo periods of motion a replay may run: 5 minutes at 1 ms.
pub(super) const MAX_REPLAY_PERIODS: f64 = 3.0e5;

/// One block of the chain.
#[derive(Debug, Clone)]
pub(super) struct Link {
    seg: tp::ChainSeg,
    /// Its length is X Y Z's (else the rotary axes', where X Y Z stay): two blocks' speeds
    /// add only where both measure alike.
    xyz: bool,
    /// It turns a rotary axis: tp.c joins it to its neighbours by parabolic blends.
    turns: bool,
}

impl Link {
    /// The segment tp queues for it.
    pub(super) fn seg(&self) -> &tp::ChainSeg {
        &self.seg
    }

    /// Its length is X Y Z's (else the rotary axes').
    pub(super) fn xyz(&self) -> bool {
        self.xyz
    }

    /// The G93 block from axes `from` to `to` that lasts `time_s`, under `G64 P` `tolerance`;
    /// `None` where it does not move.
    pub(super) fn of(
        machine: &Machine,
        (from, to): (&Axes, &Axes),
        time_s: f64,
        tolerance: f64,
    ) -> Option<Link> {
        let b = Block::of(machine, from, to, time_s)?;
        let xyz = machine
            .axes
            .iter()
            .enumerate()
            .any(|(k, x)| x.kind != AxisKind::Rotary && (to[k] - from[k]).abs() > 1e-9);
        Some(Link {
            seg: tp::ChainSeg {
                len: b.len,
                v: b.req,
                acc: b.acc,
                u: unit_xyz(machine, from, to),
                tolerance,
                tangent: None,
            },
            xyz,
            turns: super::lead::turns(machine, from, to),
        })
    }
}

/// The G93 blocks since tp last stopped (`None`: not known to start at rest, or not a chain
/// of parabolic blends the replay models).
/// Where and how fast tp.c switches a block's synchronized outputs, in tp's length unit
/// (`Block::len`): `motion::parabolic::chain::ChainRun`'s `switch_speed`, `switch_past` and
/// `switch_window` for that block.
#[derive(Debug, Clone, Copy)]
pub(super) struct Switch {
    pub speed: f64,
    pub past: f64,
    pub window: [f64; tp::SWITCH_WINDOW],
}

#[derive(Debug, Default)]
pub(super) struct Chain(Option<Vec<Link>>);

impl Chain {
    /// A line other than a motion block was written.
    pub(super) fn after_line(&mut self, text: &str) {
        if self.0.is_some() && !keeps_moving(text) {
            self.0 = None;
        }
    }

    /// A motion block was written that is not tracked.
    pub(super) fn forget(&mut self) {
        self.0 = None;
    }

    /// A motion block `kind` was written from axes `from` to `to`; `time_s` its time where
    /// it is a G93 feed (`Modal::block_s`).
    pub(super) fn after_block(
        &mut self,
        machine: &Machine,
        kind: &OpKind,
        (from, to): (&Axes, &Axes),
        time_s: Option<f64>,
        tolerance: f64,
    ) {
        self.0 = match (kind, time_s) {
            // The next feed starts at rest.
            (OpKind::Rapid { .. }, _) => Some(Vec::new()),
            (OpKind::Line { .. }, Some(t)) => self.0.take().and_then(|mut links| {
                let link = Link::of(machine, (from, to), t, tolerance)?;
                if let Some(last) = links.last_mut() {
                    last.seg.tangent = join(machine, last, &link)?;
                }
                (links.len() < MAX_LINKS).then(|| {
                    links.push(link);
                    links
                })
            }),
            _ => None,
        };
    }

    /// The time the chain runs at its requested speeds, s.
    pub(super) fn seconds(&self) -> f64 {
        self.0.as_ref().map_or(0.0, |links| {
            links.iter().map(|l| l.seg.len / l.seg.v).sum::<f64>()
        })
    }

    /// The chain replayed up to where tp first looks past it, block `lit` to follow it
    /// (`replay_off` runs each ending on from there).
    pub(super) fn prefix(&self, machine: &Machine, lit: &Link) -> Option<tp::Replay> {
        let links = self.0.as_ref()?;
        let mut segs: Vec<tp::ChainSeg> = links.iter().map(|l| l.seg.clone()).collect();
        if let (Some(last), Some(l)) = (segs.last_mut(), links.last()) {
            last.tangent = join(machine, l, lit)?;
        }
        Some(tp::Replay::prefix(&segs, machine.servo_period_s()))
    }

    /// Whether the chain, followed by block `lit`, is one the replay models: known from rest,
    /// every junction a parabolic blend (one of its two blocks turns a rotary axis) or a
    /// tangent join ([`join`]; the chain's own were judged as it grew, `after_block`), the
    /// first parabolic, short enough to replay.
    pub(super) fn replayable(&self, machine: &Machine, lit: &Link) -> bool {
        let Some(links) = self.0.as_ref() else {
            return false;
        };
        let all = || links.iter().chain(std::iter::once(lit));
        let period = machine.servo_period_s();
        let periods: f64 = all().map(|l| l.seg.len / l.seg.v / period).sum();
        let first_parabolic = links
            .first()
            .is_none_or(|a| a.turns || links.get(1).unwrap_or(lit).turns);
        links
            .last()
            .is_none_or(|last| join(machine, last, lit).is_some())
            && first_parabolic
            && period > 0.0
            && periods <= MAX_REPLAY_PERIODS
    }

    /// tp.c's speeds and point as it switches the synchronized outputs written before the
    /// lead-out `out` (its one or two blocks, the last ending in a stop), in the chain
    /// followed by `lit` and `out` ([`Switch`]); `None` where `lit` and the lead-out measure
    /// unalike or a junction is not a parabolic blend.
    ///
    /// Through the blend of a lit block into its lead-out the summed speed is the lit speed
    /// less `A·(T − φ)`, `φ` where in its servo period the lit block's final deceleration
    /// turns, or, where the lead-out's first block is short enough to hold the blend speed
    /// below the lit one (`tpComputeBlendVelocity`), a period later, `A·φ` above it. The real
    /// LinuxCNC ran rotary_engrave's ring with its lit block 0, ¼, ½, ¾ and 1 ms longer at
    /// 0.727, 2.078, 1.629, 1.177 and 0.727 °/s below the lit speed through the blend, which
    /// this replay gives to 0.001 °/s (`motion::parabolic::chain`'s test).
    pub(super) fn replay_off(
        &self,
        machine: &Machine,
        prefix: &tp::Replay,
        (lit, out): (&Link, &[Link]),
    ) -> Option<Switch> {
        let links = self.0.as_ref()?;
        let a = out.first()?;
        if a.xyz != lit.xyz {
            return None;
        }
        let blocks: Vec<&Link> = std::iter::once(lit).chain(out).collect();
        let mut tail: Vec<tp::ChainSeg> = blocks.iter().map(|l| l.seg.clone()).collect();
        for (k, w) in blocks.windows(2).enumerate() {
            tail[k].tangent = join(machine, w[0], w[1])?;
        }
        let run = prefix.then(&tail);
        let n = links.len() + 1;
        Some(Switch {
            speed: run.switch_speed[n],
            past: run.switch_past[n],
            window: run.switch_window[n],
        })
    }
}

/// How tp.c joins block `a` to block `b`: `Some(None)` by a parabolic blend (one of them
/// turns a rotary axis), `Some(Some(r))` tangentially, the kink taking the share `r` of both
/// blocks' acceleration (`motion::parabolic::chain::tangent_join`: lines in X Y Z whose
/// directions agree, as a rotary attachment's X-only stroke), `None` where it makes what the
/// replay does not model (a blend arc, a kink it slows for, a stop at a reversal).
fn join(machine: &Machine, a: &Link, b: &Link) -> Option<Option<f64>> {
    if a.turns || b.turns {
        return Some(None);
    }
    let mut bound = [0.0; 3];
    for x in machine.axes.iter().filter(|x| x.kind != AxisKind::Rotary) {
        if let Some(slot) = xyz_slot(&x.name) {
            bound[slot] = x.a_max;
        }
    }
    let v_max = a.seg.v.min(b.seg.v);
    let r = tp::tangent_join(
        (a.seg.u, b.seg.u),
        v_max,
        b.seg.acc,
        bound,
        machine.servo_period_s(),
    )?;
    Some(Some(r))
}

/// The slot of an axis named X, Y or Z in an X Y Z vector.
fn xyz_slot(name: &str) -> Option<usize> {
    match name.chars().next() {
        Some('X') => Some(0),
        Some('Y') => Some(1),
        Some('Z') => Some(2),
        _ => None,
    }
}

/// Whether tp runs on through `text`, a line that is not a motion block: a comment, `G93`,
/// or a synchronized output with its words (`M62`/`M63 P…`, `M67 E… Q…`).
fn keeps_moving(text: &str) -> bool {
    let mut bare = String::with_capacity(text.len());
    let mut depth = 0usize;
    for c in text.chars() {
        match c {
            '(' => depth += 1,
            ')' => depth = depth.saturating_sub(1),
            _ if depth == 0 => bare.push(c),
            _ => {}
        }
    }
    bare.split_whitespace().all(|w| {
        let w = w.to_ascii_uppercase();
        matches!(w.as_str(), "M62" | "M63" | "M67" | "G93")
            || (w.len() > 1
                && matches!(w.as_bytes()[0], b'P' | b'E' | b'Q')
                && w[1..].parse::<f64>().is_ok())
    })
}

/// The time of a G93 feed block at `feed` mm/s from spot `from` (axes `from_q`) to `to`
/// (axes `q`), s: its length over the feed, or where the spot stays (the beam turns in
/// place) as fast as the slowest axis allows. `motion_line` writes F as its inverse.
pub(super) fn g93_seconds(
    machine: &Machine,
    (from, from_q): (P3, &Axes),
    (to, q): (P3, &Axes),
    feed: f64,
) -> f64 {
    let len = crate::program::dist(from, to);
    if len > 1e-9 {
        len / feed
    } else {
        machine
            .axes
            .iter()
            .enumerate()
            .map(|(k, a)| (q[k] - from_q[k]).abs() / a.v_max)
            .fold(60.0 * 1e-9, f64::max)
    }
}

/// The X Y Z unit direction of the block `a → b` as canon gives it (`uVec`; (1, 0, 0) where X
/// Y Z stay).
fn unit_xyz(machine: &Machine, a: &Axes, b: &Axes) -> [f64; 3] {
    let mut u = [0.0; 3];
    for (k, x) in machine.axes.iter().enumerate() {
        if x.kind == AxisKind::Rotary {
            continue;
        }
        let Some(slot) = xyz_slot(&x.name) else {
            continue;
        };
        u[slot] = b[k] - a[k];
    }
    let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    if n > 1e-12 {
        [u[0] / n, u[1] / n, u[2] / n]
    } else {
        [1.0, 0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::keeps_moving;

    #[test]
    fn only_comments_g93_and_synchronized_outputs_keep_the_chain() {
        for l in ["(lit)", "G93", "M62 P0", "m63 p0 (off)", "M67 E0 Q42.5", ""] {
            assert!(keeps_moving(l), "{l}");
        }
        for l in [
            "M64 P0",
            "M68 E0 Q1",
            "G4 P0.5",
            "M5",
            "G94",
            "M62 P0 G4 P1",
            "G0 X1",
        ] {
            assert!(!keeps_moving(l), "{l}");
        }
    }
}
