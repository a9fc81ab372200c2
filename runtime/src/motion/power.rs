//! Power coupled to speed (PROCESS.md §1, eq. 1: `Q ∝ P / (D · v)`): where the planned speed
//! ramps with the beam on (corners, short blocks, a section without lead-in), a lit op whose
//! laser says `couple speed` gets `P(t) = P_set · v(t) / F` (F its programmed feed), so the
//! energy per length stays that of the programmed feed.
//!
//! A controller that cannot scale power by speed itself gets the lit move cut into sub-blocks,
//! each with one power value. This module computes those sub-blocks from the plan; `emit`
//! writes them. Pure math on the job: no NC text.
//!
//! Error bound: each ramp is cut at equal speed steps of at most [`POWER_STEP`] · F, so inside
//! a sub-block the planned power varies by at most `POWER_STEP · P_set` (1 %). Each sub-block
//! gets the *time mean* of the planned power over it, `P_set / F · Δs / Δt`, which makes the
//! energy it deposits exact (`∫P dt = P_set / F · Δs`) and its pointwise power error at most
//! the variation inside it. Consecutive steps are merged until a sub-block is at least
//! [`MIN_BLOCK_MM`] long and lasts at least [`MIN_BLOCK_S`]: a controller runs a block no
//! faster than its length per servo period (LinuxCNC's `tcClampVelocityByLength`), so the 1 %
//! steps of a steep ramp (0.1 ms each at 2 m/s² and 20 mm/s) would make it crawl. Where that
//! merges steps, the power inside a block varies by at most 1 % of `P_set` plus `P_set / F`
//! times the speed change over 2 ms (`a · MIN_BLOCK_S`), and the block's true error is
//! reported in [`PowerBlock::max_error_w`].
//!
//! **The controller holds the planned speed** ([`PowerBlock::v_cap`]). The power of a
//! sub-block assumes the plan's speed there, but a controller without a jerk limit (LinuxCNC
//! 2.9: trapezoids, accel-only blends) would run a lit corner or a lit arc's chords at the
//! programmed feed where lase's S-curve plan is slower, and deliver less energy per mm than
//! the plan (and its coupled power) assume: frame_marking's 1.5 mm corner arcs at 20 mm/s
//! where the plan says 9.9. So each sub-block also carries the plan's mean speed over it,
//! `Δs / Δt`, which `emit` writes as the block's feed where it is below the programmed one.
//! The controller cannot exceed it (tp.c also ends each block at no more than the next one's
//! feed: `tpGetRealFinalVel`), so it takes at least the plan's time over every such block and
//! the energy per mm it delivers, `P / v`, is at least the time-mean power over the mean
//! speed, `P_set / F` when coupled (the plan's average when not): never below what the plan
//! assumes. Where the controller is slower still (its own corner or look-ahead limits, the
//! ramps between two blocks' feeds), the energy per mm is higher than planned by the ratio of
//! the speeds, never lower. A lit move whose power is not coupled (constant `P_set`) is cut
//! the same way where the plan holds it below its feed, with one power throughout
//! ([`lit_blocks`]); where the plan holds the feed it stays one block.

use super::Job;
use crate::planner::Segment;
use crate::program::{Coupling, Laser, ProcessProgram};

/// Largest speed change inside one sub-block, as a fraction of the programmed feed.
pub const POWER_STEP: f64 = 0.01;

/// Shortest sub-block written, mm.
pub const MIN_BLOCK_MM: f64 = 0.001;

/// Shortest sub-block written, in planned time, s: two of LinuxCNC's 1 ms servo periods, so
/// that its length per servo period (the most tp.c runs a segment at) is twice its speed.
pub const MIN_BLOCK_S: f64 = 0.002;

/// One sub-block of a coupled lit op.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerBlock {
    /// Path distance from the op's start to the end of the sub-block, mm.
    pub s_end: f64,
    /// The sub-block's power: the time mean of `P_set · v / F` over it, W.
    pub power_w: f64,
    /// Largest difference between `power_w` and the planned power inside the sub-block, W.
    pub max_error_w: f64,
    /// The plan's mean path speed over the sub-block (`Δs / Δt`), mm/s: the feed the
    /// controller is held to there where it is below the programmed one.
    pub v_cap: f64,
}

/// The sub-blocks of lit op `op` on a controller that is given its speed block by block:
/// the coupled power's ([`coupled_blocks`]), or, for a lit move at constant power (not
/// pulsed: a pulse train's spacing is the emitter's), the same cuts at that power where the
/// plan holds the move below its feed somewhere; empty where it is written as one block.
pub fn lit_blocks(job: &Job, op: usize) -> Vec<PowerBlock> {
    lit_blocks_of(&job.program, op, &job.plan.segments()[op_segments(job, op)])
}

/// [`lit_blocks`] of op `op` of `program` whose plan segments are `segs` (all of them, in
/// order): what `emit::PlanFacts` computes from a plan made in windows.
pub fn lit_blocks_of(program: &ProcessProgram, op: usize, segs: &[Segment]) -> Vec<PowerBlock> {
    let Some(laser) = program.ops.get(op).and_then(|o| o.laser()) else {
        return Vec::new();
    };
    let mut blocks = match laser.couple {
        Coupling::Speed => coupled_blocks_of(laser, segs),
        Coupling::None if laser.pulse.is_some() => return Vec::new(),
        Coupling::None => coupled_blocks_of(laser, segs)
            .into_iter()
            .map(|b| PowerBlock {
                power_w: laser.power_w,
                max_error_w: 0.0,
                ..b
            })
            .collect(),
    };
    // LinuxCNC stops between a rapid and a feed (tp.c's tpCheckCanonType), where lase's plan
    // may blend them: a lit move next to a rapid starts or ends at rest there.
    let ops = &program.ops;
    let moving = |o: &&crate::program::Op| o.target().is_some();
    let rapid = |o: Option<&crate::program::Op>| {
        o.is_some_and(|o| matches!(o.kind, crate::program::OpKind::Rapid { .. }))
    };
    let after_rapid = rapid(ops[..op].iter().rev().find(moving));
    let before_rapid = rapid(ops[op + 1..].iter().find(moving));
    free_rest_ramps(segs, (after_rapid, before_rapid), &mut blocks);
    let feed = segs.first().map_or(f64::INFINITY, |s| s.feed);
    if laser.couple == Coupling::None {
        // At one power, consecutive blocks written at the feed are one block.
        let at_feed = |b: &PowerBlock| b.v_cap >= feed * FEED_HELD;
        blocks.dedup_by(|next, prev| {
            let same = at_feed(prev) && at_feed(next);
            if same {
                prev.s_end = next.s_end;
                prev.v_cap = f64::INFINITY;
            }
            same
        });
        if blocks.iter().all(at_feed) {
            return Vec::new();
        }
    }
    blocks
}

/// Leaves the blocks of a ramp from or to standstill to the controller (`v_cap` infinite: the
/// programmed feed): a lit section that starts or ends at rest (the notcher's pierce, its
/// beam switched at rest; a lit move next to a rapid, where LinuxCNC stops) ramps at the
/// controller's own acceleration, as it did before
/// blocks were held. There the controller is faster than the jerk-limited plan and the energy
/// per mm below the plan's, as at any start from rest; holding it to the plan's ramp instead
/// cost conrod_notch 1.5 % of its motion time on the real LinuxCNC (its approach, ending at
/// an immediate output, already runs at half acceleration: the segment the queue drains on
/// keeps its parabolic term condition), beyond the 1 % `tests/linuxcnc.rs` allows.
fn free_rest_ramps(
    segs: &[Segment],
    (after_rapid, before_rapid): (bool, bool),
    blocks: &mut [PowerBlock],
) {
    let Some(s0) = segs.first().map(|s| s.s_start) else {
        return;
    };
    // The ramps at rest, as path ranges from the op's start: from a standstill on while the
    // speed only rises (a ramp may run over several segments: blend halves, chords), and
    // likewise back from a standstill while it only falls.
    let mut ramps: Vec<(f64, f64)> = Vec::new();
    let at = |seg: &Segment, t: f64| seg.s_start - s0 + seg.path_state(t).0;
    let t_up = |seg: &Segment| 2.0 * seg.t_j1 + seg.t_a1;
    // Monotone segments: a blend half or a chord at one speed counts as either.
    let rises = |seg: &Segment| seg.v_exit >= seg.v_peak * FEED_HELD;
    let falls = |seg: &Segment| seg.v_entry >= seg.v_peak * FEED_HELD;
    let mut k = 0;
    while k < segs.len() {
        if segs[k].v_entry <= 0.0 || (k == 0 && after_rapid) {
            let a = segs[k].s_start - s0;
            while k + 1 < segs.len() && rises(&segs[k]) {
                k += 1;
            }
            ramps.push((a, at(&segs[k], t_up(&segs[k]))));
        }
        k += 1;
    }
    let mut k = segs.len();
    while k > 0 {
        k -= 1;
        if segs[k].v_exit <= 0.0 || (k + 1 == segs.len() && before_rapid) {
            let b = segs[k].s_start - s0 + segs[k].length;
            while k > 0 && falls(&segs[k]) {
                k -= 1;
            }
            let seg = &segs[k];
            ramps.push((at(seg, t_up(seg) + seg.t_cruise), b));
        }
    }
    let slack = 1e-9 * segs.iter().map(|s| s.length).sum::<f64>().max(1.0);
    let mut sa = 0.0;
    for b in blocks.iter_mut() {
        // A block that starts on a ramp from rest or ends on one to rest is the ramp's (its
        // other end may reach into the cruise, merged to the 2 ms a block lasts at least).
        let on = |x: f64| {
            ramps
                .iter()
                .any(|&(ra, rb)| x >= ra - slack && x <= rb + slack)
        };
        let mid = 0.5 * (sa + b.s_end);
        if on(mid) && (on(sa) || on(b.s_end)) {
            b.v_cap = f64::INFINITY;
        }
        sa = b.s_end;
    }
}

/// A planned speed at or above this share of the feed is the feed (the plan's rounding).
const FEED_HELD: f64 = 1.0 - 1e-9;

/// Plan segments of op `op` (tags are op indices, in order): `first..end`.
pub fn op_segments(job: &Job, op: usize) -> std::ops::Range<usize> {
    let segs = job.plan.segments();
    let first = segs.partition_point(|s| (s.tag as usize) < op);
    let end = segs.partition_point(|s| (s.tag as usize) <= op);
    first..end
}

/// The sub-blocks of lit op `op` whose laser is coupled to speed; empty when the op is not
/// lit, not coupled, or has no motion. The last block ends at the op's full length.
pub fn coupled_blocks(job: &Job, op: usize) -> Vec<PowerBlock> {
    let Some(laser) = job.program.ops.get(op).and_then(|o| o.laser()) else {
        return Vec::new();
    };
    if laser.couple != Coupling::Speed {
        return Vec::new();
    }
    coupled_blocks_of(laser, &job.plan.segments()[op_segments(job, op)])
}

/// [`coupled_blocks`] of a coupled lit op whose plan segments are `segs` (all of them, in
/// order): what `emit::PlanFacts` computes from a plan made in windows.
pub fn coupled_blocks_of(laser: &Laser, segs: &[Segment]) -> Vec<PowerBlock> {
    let Some(s0) = segs.first().map(|s| s.s_start) else {
        return Vec::new();
    };
    // Pieces (s_end, t_len, v_min, v_max) with bounded speed variation, then merged.
    let mut pieces: Vec<(f64, f64, f64, f64)> = Vec::new();
    for seg in segs {
        let feed = seg.feed;
        let step = POWER_STEP * if feed.is_finite() { feed } else { seg.v_peak };
        let base = seg.s_start - s0;
        for (t0, t1) in speed_steps(seg, step) {
            let va = seg.path_state(t0).1;
            let (sb, vb, _, _) = seg.path_state(t1);
            if t1 > t0 {
                pieces.push((base + sb, t1 - t0, va.min(vb), va.max(vb)));
            }
        }
    }
    merge(laser, segs, s0, &pieces)
}

/// Time intervals of a segment's motion inside which the speed changes by at most `step`:
/// the ramps cut at equal speed steps (speed is monotone in each ramp), the cruise whole.
fn speed_steps(seg: &Segment, step: f64) -> Vec<(f64, f64)> {
    let t_up = 2.0 * seg.t_j1 + seg.t_a1;
    let t_down = 2.0 * seg.t_j2 + seg.t_a2;
    let t_c_end = t_up + seg.t_cruise;
    let mut out = Vec::new();
    let ramp = |out: &mut Vec<(f64, f64)>, ta: f64, tb: f64, va: f64, vb: f64| {
        if tb <= ta {
            return;
        }
        let n = if step > 0.0 {
            ((vb - va).abs() / step).ceil().clamp(1.0, 1e6) as usize
        } else {
            1
        };
        let mut t_prev = ta;
        for k in 1..=n {
            let t = if k == n {
                tb
            } else {
                let target = va + (vb - va) * k as f64 / n as f64;
                time_at_speed(seg, ta, tb, va < vb, target)
            };
            out.push((t_prev, t));
            t_prev = t;
        }
    };
    ramp(&mut out, 0.0, t_up, seg.v_entry, seg.v_peak);
    if seg.t_cruise > 0.0 {
        out.push((t_up, t_c_end));
    }
    ramp(&mut out, t_c_end, t_c_end + t_down, seg.v_peak, seg.v_exit);
    out
}

/// The instant in `[ta, tb]` where the (monotone) speed of a ramp reaches `target`.
fn time_at_speed(seg: &Segment, ta: f64, tb: f64, rising: bool, target: f64) -> f64 {
    let (mut lo, mut hi) = (ta, tb);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        let v = seg.path_state(mid).1;
        if (v < target) == rising {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Turns pieces into blocks: consecutive pieces are merged while they are too short or
/// cruise at one speed (a cruise over several chords), and each block gets its time-mean power.
fn merge(
    laser: &Laser,
    segs: &[Segment],
    s0: f64,
    pieces: &[(f64, f64, f64, f64)],
) -> Vec<PowerBlock> {
    let feed = segs.first().map_or(f64::INFINITY, |s| s.feed);
    let scale = if feed.is_finite() && feed > 0.0 {
        laser.power_w / feed
    } else {
        0.0
    };
    let total = segs.last().map_or(0.0, |s| s.s_start + s.length - s0);
    // Blocks as (s_start, s_end, time, v_min, v_max).
    let mut blocks: Vec<(f64, f64, f64, f64, f64)> = Vec::new();
    let mut open: Option<(f64, f64, f64, f64, f64)> = None;
    for (k, &(s_end, dt, lo, hi)) in pieces.iter().enumerate() {
        let s_end = if k + 1 == pieces.len() { total } else { s_end };
        let b = match open {
            Some((sa, _, t, a, b)) => (sa, s_end, t + dt, a.min(lo), b.max(hi)),
            None => (blocks.last().map_or(0.0, |b| b.1), s_end, dt, lo, hi),
        };
        let cruising_on = pieces
            .get(k + 1)
            .is_some_and(|n| n.2 == n.3 && b.3 == b.4 && n.2 == b.3);
        if b.1 - b.0 < MIN_BLOCK_MM || b.2 < MIN_BLOCK_S || cruising_on {
            open = Some(b);
        } else {
            blocks.push(b);
            open = None;
        }
    }
    if let Some(b) = open {
        // A short tail joins the block before it.
        match blocks.last_mut() {
            Some(prev) => *prev = (prev.0, b.1, prev.2 + b.2, prev.3.min(b.3), prev.4.max(b.4)),
            None => blocks.push(b),
        }
    }
    blocks
        .into_iter()
        .map(|(sa, sb, t, lo, hi)| {
            let mean_v = if t > 0.0 { (sb - sa) / t } else { hi };
            PowerBlock {
                s_end: sb,
                power_w: scale * mean_v,
                max_error_w: scale * (hi - mean_v).max(mean_v - lo).max(0.0),
                v_cap: mean_v,
            }
        })
        .collect()
}

/// Merges the first of `blocks` into one that reaches at least `s_min` from the op's start
/// (all of them when the op is shorter): its power the time mean of theirs, its speed their
/// mean speed (`Δs / Δt`, each block's time `Δs / v_cap`), its error the largest of theirs
/// widened by the change of power. For a controller that must see a block's shape (an arc
/// whose first block would otherwise run as its chord: `emit`'s LinuxCNC writer).
pub fn merge_front(blocks: &mut Vec<PowerBlock>, s_min: f64) {
    let n = blocks
        .iter()
        .position(|b| b.s_end >= s_min)
        .map_or(blocks.len(), |k| k + 1);
    merge_range(blocks, 0, n);
}

/// Merges `blocks[first..end]` into one, as [`merge_front`] merges the first ones.
pub fn merge_range(blocks: &mut Vec<PowerBlock>, first: usize, end: usize) {
    let end = end.min(blocks.len());
    if end < first + 2 {
        return;
    }
    let start_s = if first == 0 {
        0.0
    } else {
        blocks[first - 1].s_end
    };
    let (mut s0, mut t, mut energy) = (start_s, 0.0, 0.0);
    let (mut p_lo, mut p_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for b in &blocks[first..end] {
        let dt = if b.v_cap > 0.0 && b.v_cap.is_finite() {
            (b.s_end - s0) / b.v_cap
        } else {
            0.0
        };
        t += dt;
        energy += b.power_w * dt;
        p_lo = p_lo.min(b.power_w - b.max_error_w);
        p_hi = p_hi.max(b.power_w + b.max_error_w);
        s0 = b.s_end;
    }
    let power_w = if t > 0.0 {
        energy / t
    } else {
        blocks[end - 1].power_w
    };
    let merged = PowerBlock {
        s_end: s0,
        power_w,
        max_error_w: (p_hi - power_w).max(power_w - p_lo).max(0.0),
        // A ramp at rest left to the controller (`free_rest_ramps`) stays so.
        v_cap: if blocks[first..end].iter().any(|b| !b.v_cap.is_finite()) {
            f64::INFINITY
        } else if t > 0.0 {
            (s0 - start_s) / t
        } else {
            blocks[end - 1].v_cap
        },
    };
    blocks.splice(first..end, [merged]);
}

/// [`merge_short`] from the back, for a block that ends at a beam edge: its last run is the
/// shortest that lasts `min_time`, so the block that carries the edge holds the plan's speed
/// nearest the edge (`emit`'s LinuxCNC writer in a parabolic chain; `min_time` must not
/// depend on where a run lies, only on its length).
pub fn merge_short_from_back(blocks: &mut Vec<PowerBlock>, min_time: impl Fn(f64) -> f64) {
    // Mirrored: block k spans [s_{k-1}, s_k], mirrored [total - s_k, total - s_{k-1}].
    let mirror = |b: &mut Vec<PowerBlock>| {
        let total = b.last().map_or(0.0, |x| x.s_end);
        let starts: Vec<f64> = std::iter::once(0.0)
            .chain(b.iter().map(|x| x.s_end))
            .collect();
        let n = b.len();
        b.reverse();
        for (j, x) in b.iter_mut().enumerate() {
            x.s_end = total - starts[n - 1 - j];
        }
    };
    mirror(blocks);
    merge_short(blocks, min_time);
    mirror(blocks);
}

/// Merges runs of `blocks` until each lasts at least `min_time(Δs)` (s) for its length `Δs`
/// (mm) at its mean speed, from the front; a short rest joins the run before it. For a
/// controller that cannot carry a block shorter than some time at speed (LinuxCNC's parabolic
/// blends, `parabolic`): the blocks keep as much of the plan's speed as that allows.
pub fn merge_short(blocks: &mut Vec<PowerBlock>, min_time: impl Fn(f64) -> f64) {
    let time = |b: &[PowerBlock], first: usize, end: usize| -> (f64, f64) {
        let mut s0 = if first == 0 { 0.0 } else { b[first - 1].s_end };
        let (start, mut t) = (s0, 0.0);
        for x in &b[first..end] {
            if x.v_cap > 0.0 && x.v_cap.is_finite() {
                t += (x.s_end - s0) / x.v_cap;
            }
            s0 = x.s_end;
        }
        (s0 - start, t)
    };
    let mut first = 0;
    while first < blocks.len() {
        let mut end = first + 1;
        loop {
            let (ds, t) = time(blocks, first, end);
            if t >= min_time(ds) || end == blocks.len() {
                break;
            }
            end += 1;
        }
        let (ds, t) = time(blocks, first, end);
        if end == blocks.len() && t < min_time(ds) && first > 0 {
            // The rest is short: it joins the run before (merged already, at `first - 1`).
            merge_range(blocks, first - 1, end);
            return;
        }
        merge_range(blocks, first, end);
        first += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blocks(v: &[f64]) -> Vec<PowerBlock> {
        v.iter()
            .enumerate()
            .map(|(k, &v)| PowerBlock {
                s_end: (k + 1) as f64,
                power_w: 10.0,
                max_error_w: 0.0,
                v_cap: v,
            })
            .collect()
    }

    /// A ramp 1..=5 mm/s in 1 mm blocks, each run to last 0.6 s: from the front the short
    /// rest joins the last run; from the back the last run is the shortest that lasts, and
    /// the first run takes the rest. Lengths and times are kept either way.
    #[test]
    fn merging_from_the_back_keeps_the_last_run_shortest() {
        let min = |_: f64| 0.6;
        let mut front = blocks(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        merge_short(&mut front, min);
        let mut back = blocks(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        merge_short_from_back(&mut back, min);
        let time = |b: &[PowerBlock]| {
            let mut s0 = 0.0;
            b.iter()
                .map(|x| {
                    let t = (x.s_end - s0) / x.v_cap;
                    s0 = x.s_end;
                    t
                })
                .collect::<Vec<f64>>()
        };
        let ends = |b: &[PowerBlock]| b.iter().map(|x| x.s_end).collect::<Vec<f64>>();
        // Front: [1] 1 s, [2, 3] 0.83 s, [4, 5] 0.45 s short: joins → [2..5].
        assert_eq!(ends(&front), vec![1.0, 5.0]);
        // Back: [5, 4] 0.45 s short, [5, 4, 3] 0.78 s; [2] 0.5 s short, [2, 1] 1.5 s.
        assert_eq!(ends(&back), vec![2.0, 5.0]);
        let total = |b: &[PowerBlock]| time(b).iter().sum::<f64>();
        let want = 1.0 + 0.5 + 1.0 / 3.0 + 0.25 + 0.2;
        assert!((total(&front) - want).abs() < 1e-12);
        assert!((total(&back) - want).abs() < 1e-12);
        assert!(time(&back).iter().all(|&t| t >= 0.6));
        // The last run's speed: 3 mm over 0.783 s.
        assert!((back[1].v_cap - 3.0 / (1.0 / 3.0 + 0.25 + 0.2)).abs() < 1e-12);
    }
}
