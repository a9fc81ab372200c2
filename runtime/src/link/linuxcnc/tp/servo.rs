//! LinuxCNC 2.9's planner servo period by servo period (`tpRunCycle`), for a chain of lines
//! joined by parabolic blends (rotary motion, where tp.c makes neither tangent nor arc
//! blends: `tpSetupTangent` gives up on ABC motion, so every junction of a cam or rotary
//! section is one), and, among them, by tangent joins (lines without rotary motion in line,
//! such as a rotary attachment's X-only strokes between blocks that turn A).
//!
//! Why not the continuous trapezoids the rest of the model uses: a parabolic blend starts in
//! the servo period in which the finishing segment begins its final deceleration
//! (`tcIsBlending`: `on_final_decel` and below its blend speed), and in that same period the
//! next segment takes its first full acceleration step (`tpUpdateBlend` → `tpUpdateCycle`),
//! while the finishing one decelerates only for the part of the period after its ramp's
//! turning point (`tpCalculateTrapezoidalAccel` solves for the speed that stops it exactly at
//! its end). The next segment thus starts up to one period early, on average about half a
//! period, and a finishing segment's last partial period is skipped (`tpHandleSplitCycle`
//! moves it to its end and gives the next one a whole period). With blocks of 20–40 ms, as
//! the chord-true pose steps write on a cam, that is ~1.5 % of the time, which continuous
//! trapezoids cannot see (rhai_cam ran 1.2 % faster than they predicted). So this replays
//! tp.c's arithmetic for those chains: `tpCalculateTrapezoidalAccel`,
//! `tcUpdateDistFromAccel`, `tpCheckEndCondition` (split cycles), `tpComputeBlendVelocity`
//! (with its `G64 P` cap), `tcGetTangentialMaxAccel` (half the acceleration on both sides of
//! a parabolic blend, and on the queue's last segment), and `tpDoParabolicBlending`'s rule
//! for when the next segment's synced outputs switch (when it is the faster of the two).

pub(super) use crate::motion::parabolic::chain::{ChainSeg, run_chain};

/// A queue segment as the chain replay reads it, under `G64 P` `tolerance`, joined to the
/// next tangentially with the kink's share `tangent` of acceleration, else parabolically.
pub(super) fn chain_seg(s: &super::Seg, tolerance: f64, tangent: Option<f64>) -> ChainSeg {
    ChainSeg {
        len: s.len,
        v: s.req.min(s.vmax),
        acc: s.acc,
        u: if s.u0 == [0.0; 3] {
            [1.0, 0.0, 0.0]
        } else {
            s.u0
        },
        tolerance,
        tangent,
    }
}

/// The kink's share of acceleration where a segment joins the next tangentially within
/// `ARC_BLEND_KINK_RATIO` (`None` elsewhere, and at a kink tp slows for, which the replay does
/// not model).
pub(super) fn tangent_share(joint: Option<super::Joint>, kind: Option<super::Kind>) -> Option<f64> {
    use crate::motion::parabolic::chain::KINK_RATIO;
    match (joint, kind) {
        (None, Some(super::Kind::Tangent { keep, .. })) if keep > 1.0 - KINK_RATIO => {
            Some(1.0 - keep)
        }
        _ => None,
    }
}

/// Whether a chain may hold `s`: a line with somewhere to go at some speed (one that could
/// not move would never end).
pub(super) fn replayable(s: &super::Seg) -> bool {
    !s.arc && s.req.min(s.vmax) > 0.0 && s.acc > 0.0
}

/// Where the model runs chains here instead of its trapezoids: every maximal run of lines
/// from a stop to a stop whose first junction is a parabolic blend and the others parabolic
/// blends or tangent joins (a run of tangent joins alone is left to the trapezoids, which the
/// flat-bed programs were measured against; `TpStream` opens a chain at its first junction).
/// Returns, per piece of the
/// model's queue (`piece_of_seg[i]` is segment `i`'s), the time from its outputs' switch to
/// the next piece's (the chain's last: to the end of its motion).
pub(super) fn chain_times(
    segs: &[super::Seg],
    kinds: &[Option<super::Kind>],
    joints: &[Option<super::Joint>],
    tolerances: &[f64],
    piece_of_seg: &[usize],
    n_pieces: usize,
    period: f64,
) -> Vec<Option<f64>> {
    use super::{Joint, Kind};
    let n = segs.len();
    let mut out = vec![None; n_pieces];
    // What follows segment i: a stop (term STOP or a drain), or a blend.
    let stops_after = |i: usize| {
        i + 1 == n
            || matches!(joints[i], Some(Joint::Stop { .. }))
            || matches!(kinds[i], Some(Kind::Stop))
    };
    let parabolic =
        |i: usize| joints[i].is_none() && matches!(kinds[i], Some(Kind::Parabolic { .. }));
    let tangent = |i: usize| tangent_share(joints[i], kinds[i]);
    let mut i = 0;
    while i < n {
        let starts_at_rest = i == 0 || stops_after(i - 1);
        let mut j = i;
        while j + 1 < n && (parabolic(j) || tangent(j).is_some()) {
            j += 1;
        }
        let simulate = starts_at_rest
            && j > i
            && stops_after(j)
            && parabolic(i)
            && segs[i..=j].iter().all(replayable);
        if simulate {
            let chain: Vec<ChainSeg> = (i..=j)
                .map(|k| chain_seg(&segs[k], tolerances[k], tangent(k)))
                .collect();
            // The queue's last segment keeps its default PARABOLIC term condition; one the
            // planner must stop after (a rapid next, G61) is STOP.
            let parabolic_end =
                j + 1 == n || matches!(joints[j], Some(Joint::Stop { drain: true, .. }));
            let run = run_chain(&chain, parabolic_end, period);
            for k in 0..chain.len() {
                let end = run.switch_s.get(k + 1).copied().unwrap_or(run.total_s);
                out[piece_of_seg[i + k]] = Some((end - run.switch_s[k]).max(0.0));
            }
        }
        i = j + 1;
    }
    out
}
