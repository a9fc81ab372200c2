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
//! the variation inside it. Sub-blocks shorter than [`MIN_BLOCK_MM`] (ten steps of the NC
//! programs' 0.1 µm resolution) are merged into the next one, which happens only near
//! standstill, where a jerk-limited ramp moves very little; the merged block's true error is
//! reported in [`PowerBlock::max_error_w`].

use super::Job;
use crate::planner::Segment;
use crate::program::{Coupling, Laser};

/// Largest speed change inside one sub-block, as a fraction of the programmed feed.
pub const POWER_STEP: f64 = 0.01;

/// Shortest sub-block written, mm.
pub const MIN_BLOCK_MM: f64 = 0.001;

/// One sub-block of a coupled lit op.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PowerBlock {
    /// Path distance from the op's start to the end of the sub-block, mm.
    pub s_end: f64,
    /// The sub-block's power: the time mean of `P_set · v / F` over it, W.
    pub power_w: f64,
    /// Largest difference between `power_w` and the planned power inside the sub-block, W.
    pub max_error_w: f64,
}

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
        if b.1 - b.0 < MIN_BLOCK_MM || cruising_on {
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
            }
        })
        .collect()
}
