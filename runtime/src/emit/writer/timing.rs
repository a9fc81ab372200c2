//! Beam edges on LinuxCNC timed by tp.c's own arithmetic, where the servo clock is known:
//! the chain of G93 blocks since tp last stopped (`chain`) replayed servo period by servo
//! period (`motion::parabolic::chain`) with each candidate lead-in or lit block and lead-out,
//! and the one kept whose speed at the switch is nearest the plan's, with the beam within
//! half a servo period of travel of its planned place. Where a blend lasts five servo
//! periods or more (the rotary attachment's, a cam's) that speed is tp's summed speed in the
//! switching period; where it lasts two (an arm's), the joints, two periods behind tp, are
//! still at the finishing block's speed as tp switches and show the blend's after it, so the
//! speeds that count are the joints' at each sample the beam is on about the switch
//! (`ChainRun::switch_window`, which the real machine's samples match to 0.001 °/s).
//!
//! The joints follow tp's point two servo periods late (control.c's cubic interpolator,
//! `lead::LEAD_PERIODS`), so a beam switches where the joints are then: `d + past − 2·v·T`
//! past its planned edge, `d` how far the junction moved, `past` how far past it tp's point
//! is at the switch (`ChainRun::switch_past`).

use super::block::part_way;
use super::{Out, lead};
use crate::axes::Axes;
use crate::motion::Job;
use crate::motion::parabolic::chain::SWITCH_WINDOW;
use crate::program::{OpKind, P3};

/// The speed, mm/s, at which lead-in op `i` (from spot `from` at axes `from_q` to its moved
/// junction `to` at `q_to`, `lead::shift`) makes tp's summed speed cross the on-edge at the lit
/// op's `v`, where the lead-in starts at rest (after a rapid: tp stops where a rapid meets a
/// feed, and starts the next segment on a servo period); `None` elsewhere, where the writer
/// falls back on the blend's mean gain (`lead::blend_gain`).
///
/// From rest, the servo clock the lead-in runs on is known, and with it where in its period
/// the lead-in's deceleration turns and how far its first blend period lifts the sum: tp.c's
/// arithmetic replays the lead-in and the lit block (`motion::parabolic::chain::run_chain`)
/// for lead-in speeds over the gain's range, 0 to 3·A·T/2 below `v`, and the one whose summed
/// speed at the lit block's switch is nearest `v` is kept.
pub(super) fn lead_in_speed(
    job: &Job,
    i: usize,
    (from, from_q): (P3, &Axes),
    (to, q_to): (P3, &Axes),
    v: f64,
    servo_s: f64,
) -> Option<f64> {
    use crate::motion::parabolic::chain;
    let ops = &job.program.ops;
    let machine = &job.program.machine;
    let j = lit_after_rest(ops, i)?;
    let OpKind::Line { to: end, .. } = ops[j].kind else {
        return None;
    };
    let q_end = job.op_axes.get(j);
    let (lead_len, lit_len) = (
        crate::program::dist(from, to),
        crate::program::dist(to, end),
    );
    let gain = lead::blend_gain(machine, from_q, q_to, lead_len, servo_s);
    let link =
        |a: &Axes, b: &Axes, time_s: f64| super::chain::Link::of(machine, (a, b), time_s, 0.0);
    let lit = link(q_to, &q_end, lit_len / v)?;
    // Both lengths in one unit (X Y Z's, or the rotary axes' where X Y Z stay), so the two
    // blocks' speeds add.
    let alike = link(from_q, q_to, lead_len / v).is_some_and(|l| l.xyz() == lit.xyz());
    if !(alike && lead_len > 0.0 && lit_len > 0.0 && gain > 0.0 && v > 3.0 * gain) {
        return None;
    }
    const STEPS: usize = 60;
    let mut best: Option<(f64, f64)> = None;
    for k in 0..=STEPS {
        let speed = v - 3.0 * gain * k as f64 / STEPS as f64;
        let lead = link(from_q, q_to, lead_len / speed)?;
        // The lit block blends on into what follows it: its term condition stays parabolic.
        let run = chain::run_chain(&[lead.seg().clone(), lit.seg().clone()], true, servo_s);
        let err = (run.switch_speed[1] / lit.seg().v - 1.0).abs();
        if best.is_none_or(|(e, _)| err < e) {
            best = Some((err, speed));
        }
    }
    best.map(|(_, speed)| speed)
}

/// Where lead-in op `i` (unlit, from spot `from` at axes `from_q`) ends and the speed it is
/// written at, mm/s, where the lit op after it starts a chain from rest (after a rapid) on a
/// junction tp.c blends parabolically in line in the axes, but the blend is too short for
/// `lead::shift`'s rule (its mean gain and a switch in its middle need 5 servo periods:
/// an arm's joints reach 3.5 mm/s of spot speed in 2, `lead::carries`). `None` elsewhere, and
/// where nothing beats the block as it is.
///
/// From rest the servo clock is known, so tp.c's arithmetic replays the lead-in and the lit
/// block (`motion::parabolic::chain::run_chain`) with the junction moved 0 to
/// [`MAX_ON_SHIFT_PERIODS`] periods of travel into the lit block and the lead-in 0 to 3
/// blend gains slower, and keeps the one whose joints run nearest the lit block's speed at
/// the switch's sample and the four after it ([`lit_error`]) with the beam within
/// [`MAX_PLACE_PERIODS`] of its planned place. Unmoved, the arm's beam came on 1.4-2.2
/// periods early on the real LinuxCNC, at up to 16 % over its joint speed. (Ranked by tp's
/// summed speed at the switch instead, a lead-in ran at 0.83 of the lit speed and the
/// joints, lit, at +21 % in the blend after it.)
pub(super) fn timed_lead_in(
    job: &Job,
    i: usize,
    (from, from_q): (P3, &Axes),
    servo_s: f64,
) -> Option<(P3, Axes, f64)> {
    use crate::motion::parabolic::chain;
    let ops = &job.program.ops;
    let machine = &job.program.machine;
    let (OpKind::Line { to, .. }, None) = (&ops[i].kind, ops[i].laser()) else {
        return None;
    };
    let to = *to;
    let j = lit_after_rest(ops, i)?;
    let OpKind::Line {
        to: end,
        feed_mm_s: v,
        ..
    } = ops[j].kind
    else {
        return None;
    };
    let (q_to, q_end) = (job.op_axes.get(i), job.op_axes.get(j));
    let (lead_len, lit_len) = (
        crate::program::dist(from, to),
        crate::program::dist(to, end),
    );
    let w = lead::direction(&ops[j], to, end, false)?;
    let parabolic = lead::turns(machine, from_q, &q_to) || lead::turns(machine, &q_to, &q_end);
    let gain = lead::blend_gain(machine, from_q, &q_to, lead_len, servo_s);
    if !(parabolic
        && ops[j].moves_from(to)
        && lead::in_line(from_q, &q_to, &q_end)
        && lead_len > 0.0
        && lit_len > 0.0
        && gain > 0.0
        && v > 0.0)
    {
        return None;
    }
    let link =
        |a: &Axes, b: &Axes, time_s: f64| super::chain::Link::of(machine, (a, b), time_s, 0.0);
    let step = v * servo_s;
    // Only the lit block's start takes part before the switch: the replay runs no more of it
    // than reaching its speed at half its acceleration `A` takes four times over, and 20
    // periods (the blend's speeds, `tpComputeBlendVelocity`, are the same for any longer
    // block, `sqrt(A·L)` and `L / v` then never binding), so a long first block costs no more.
    let clip = 4.0 * v * v / (2.0 * gain / servo_s) + 20.0 * step;
    let periods = (lead_len + MAX_ON_SHIFT_PERIODS * step + clip) / v / servo_s;
    let runs = (1 + ON_D_STEPS) * (1 + ON_SPEED_STEPS);
    if periods * runs as f64 > MAX_SCAN_PERIODS {
        return None;
    }
    // (speed error, place in periods, d, lead-in speed) for the junction `d` mm into the lit
    // block and the lead-in at `speed`.
    let try_one = |d: f64, speed: f64| -> Option<(f64, f64, f64, f64)> {
        let qd = q_to.lerp(&q_end, d / lit_len);
        let run_len = (lit_len - d).min(clip);
        let q_run = qd.lerp(&q_end, run_len / (lit_len - d));
        let lit = link(&qd, &q_run, run_len / v)?;
        let lead = link(from_q, &qd, (lead_len + d) / speed)?;
        if lead.xyz() != lit.xyz() {
            return None;
        }
        // The lit block blends on into what follows it: its term condition stays parabolic.
        let run = chain::run_chain(&[lead.seg().clone(), lit.seg().clone()], true, servo_s);
        let mm = run_len / lit.seg().len;
        let place = (d + run.switch_past[1] * mm - 2.0 * step) / step;
        let err = lit_error(&run.switch_window[1], lit.seg().v, true);
        Some((err, place, d, speed))
    };
    let (base_err, base_place, ..) = try_one(0.0, v)?;
    let mut best: Option<(f64, f64, f64, f64)> = None;
    for kd in 0..=ON_D_STEPS {
        let d = step * MAX_ON_SHIFT_PERIODS * kd as f64 / ON_D_STEPS as f64;
        if d >= 0.5 * lit_len {
            break;
        }
        for ks in 0..=ON_SPEED_STEPS {
            let speed = v - 3.0 * gain * ks as f64 / ON_SPEED_STEPS as f64;
            if speed < 0.25 * v {
                break;
            }
            let Some(c) = try_one(d, speed) else {
                continue;
            };
            if c.1.abs() <= MAX_PLACE_PERIODS
                && best.is_none_or(|b| score((c.0, c.1)) < score((b.0, b.1)))
            {
                best = Some(c);
            }
        }
    }
    let (err, _, d, speed) = best?;
    if base_place.abs() <= MAX_PLACE_PERIODS && err >= base_err {
        return None;
    }
    let p = std::array::from_fn(|k| to[k] + w[k] * d);
    Some((p, q_to.lerp(&q_end, d / lit_len), speed))
}

/// The largest relative error of the joints' speeds from the lit speed `v` (tp's units) at the
/// samples of a switch window (`ChainRun::switch_window`) while the beam is on: from the
/// switch's sample on at an on-edge (`on`), up to it at an off-edge.
fn lit_error(window: &[f64; SWITCH_WINDOW], v: f64, on: bool) -> f64 {
    let half = SWITCH_WINDOW / 2;
    let lit = if on {
        &window[half..]
    } else {
        &window[..=half]
    };
    lit.iter().map(|w| (w / v - 1.0).abs()).fold(0.0, f64::max)
}

/// How a short blend's timing is ranked: the speed error (`lit_error`), and where two are
/// alike to a tenth of a per mille, the place nearer the planned one (periods).
fn score((err, place): (f64, f64)) -> f64 {
    err + 2e-4 * place.abs()
}

/// The farthest a lead-in's junction is moved into the lit block (`timed_lead_in`), in servo
/// periods of travel: past the joints' two periods of lag and a period of tp's switching.
const MAX_ON_SHIFT_PERIODS: f64 = 4.0;

/// Steps over the junction's move and the lead-in's speed (`timed_lead_in`).
const ON_D_STEPS: usize = 32;
const ON_SPEED_STEPS: usize = 60;

/// The lit Line op that lead-in op `i` runs into, where the lead-in starts at rest: after a
/// rapid (tp stops where a rapid meets a feed, and starts the next segment on a servo period)
/// or at the program's first move, so the servo clock it runs on is known.
fn lit_after_rest(ops: &[crate::program::Op], i: usize) -> Option<usize> {
    let at_rest = ops[..i]
        .iter()
        .rev()
        .find(|o| o.target().is_some())
        .is_none_or(|o| matches!(o.kind, OpKind::Rapid { .. }));
    let j = (i + 1..ops.len()).find(|&j| ops[j].target().is_some())?;
    let lit_line = matches!(ops[j].kind, OpKind::Line { .. }) && ops[j].laser().is_some();
    (at_rest && lit_line).then_some(j)
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
/// `short`: the junction `to` is where `lead::shift` would move it but for a blend too short
/// for its rule (an arm's): the lead-out stays whole, the junction moves 0 to
/// [`MAX_SHORT_SHIFT_PERIODS`] periods of travel past the edge, and the speeds that count are
/// the joints' at the lit samples up to the switch's ([`lit_error`]), the nearer place
/// breaking ties ([`score`]); `None` leaves the junction unmoved.
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
    short: bool,
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
    // In two where `lead::split` writes it so; an arm's short lead-out whole.
    let split = !short && long && lead::split(job, j, (to, q), turned);
    if !(split || (short && long && lead::stops_after(job, j, (to, q), turned))) {
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
    // The lead-out's blocks, its first `len1` mm long (whole where not split).
    let parts = |(p, qp): (P3, &Axes), len1: f64| {
        if !split {
            return Some(vec![link((p, qp), (out_end, &q_out))?]);
        }
        let rest = crate::program::dist(p, out_end);
        let (mid, mid_q) = part_way(&ops[j], (p, qp), &q_out, len1 / rest, None);
        Some(vec![
            link((p, qp), (mid, &mid_q))?,
            link((mid, &mid_q), (out_end, &q_out))?,
        ])
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
    let lens: Vec<f64> = if split {
        lead::split_candidates(machine, (q, &q_out), rest0, out_feed, period, 5)
            .into_iter()
            .map(|f| f * rest0)
            .collect()
    } else {
        vec![rest0]
    };
    // The junction moves ±½ period about `lead::shift`'s place, or, where its blend is too
    // short for that rule, from the edge to [`MAX_SHORT_SHIFT_PERIODS`] past it.
    let (d_lo, d_span, d_steps) = if short {
        (0.0, MAX_SHORT_SHIFT_PERIODS * step, SHORT_D_STEPS)
    } else {
        (d0 - 0.5 * step, step, D_STEPS)
    };
    // The chain once, then each candidate's lit block and lead-out.
    let tail = (time + out_len / out_feed) / period;
    let scans = (1 + d_steps) * (1 + TRIM_STEPS) * lens.len();
    let budget = out.chain.seconds() / period + tail * scans as f64;
    if budget > MAX_SCAN_PERIODS {
        return None;
    }
    let prefix = out.chain.prefix(machine, &base)?;
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
        let endings: Vec<(f64, Vec<Link>)> = lens
            .iter()
            .filter_map(|&len1| Some((len1, parts((p, &qp), len1)?)))
            .collect();
        let mut found = Vec::new();
        for &trim in trims {
            let Some(lit) = lit_link((p, &qp), trim) else {
                continue;
            };
            for (len1, blocks) in &endings {
                if let Some(s) = out.chain.replay_off(machine, &prefix, (&lit, blocks)) {
                    let place = (d + s.past * mm - 2.0 * step) / step;
                    // A blend of a few periods: the joints' speeds while lit about the switch.
                    let err = if short {
                        lit_error(&s.window, want, false)
                    } else {
                        (s.speed / want - 1.0).abs()
                    };
                    found.push((err, place, trim, *len1));
                }
            }
        }
        found
    };
    // As it would be written: at `lead::shift`'s place split by the mean gain, or unmoved.
    let base = if short {
        scan(0.0, &[0.0], &lens)
    } else {
        let mean_len = lead::split_at(machine, (q, &q_out), rest0, out_feed, period) * rest0;
        scan(d0, &[0.0], &[mean_len])
    };
    let &(base_err, base_place, ..) = base.first()?;
    // Only longer: a cap above the feed is not written (`motion_line`).
    let trims: Vec<f64> = (0..=TRIM_STEPS)
        .map(|kt| max_trim * kt as f64 / TRIM_STEPS as f64)
        .collect();
    let mut best: Option<(f64, f64, f64, f64, f64)> = None;
    for kd in 0..=d_steps {
        let d = d_lo + d_span * kd as f64 / d_steps as f64;
        if !(d > 0.0 && d < 0.5 * out_len) {
            continue;
        }
        for (err, place, trim, len1) in scan(d, &trims, &lens) {
            let bound = if short {
                MAX_PLACE_PERIODS
            } else {
                MAX_PLACE_PERIODS.max(base_place.abs())
            };
            if place.abs() > bound {
                continue;
            }
            // Short: speeds alike to a tenth of a per mille, the nearer place.
            let better = match best {
                None => true,
                Some((e, p, ..)) if short => score((err, place)) < score((e, p)),
                Some((e, ..)) => err < e - 1e-12,
            };
            if better {
                best = Some((err, place, d, trim, len1));
            }
        }
    }
    let (err, _, d, trim, len1) = best?;
    // Where the beam went off out of place, a place within bounds beats any speed.
    let placed = short && base_place.abs() > MAX_PLACE_PERIODS;
    if err >= base_err && !placed {
        return None;
    }
    let (p, qp) = at(d);
    if split {
        out.split_len = Some((j, len1));
    }
    let len = crate::program::dist(from, p);
    Some((p, qp, len / (len / feed + trim)))
}

/// The most a lit block's speed is changed to time its off-edge (`off_edge_timing`): a
/// twentieth of the plan's 0.1 % on the lit surface speed.
const TRIM_REL: f64 = 5e-4;

/// Steps over the period of travel the junction is moved by, and over the lit block's time
/// (`off_edge_timing`).
const D_STEPS: usize = 8;
const TRIM_STEPS: usize = 8;

/// The farthest an off-edge's junction is moved into the lead-out where the blend is too
/// short for `lead::shift`'s rule, in servo periods of travel, and the steps over it.
const MAX_SHORT_SHIFT_PERIODS: f64 = 4.0;
const SHORT_D_STEPS: usize = 32;

/// The most servo periods of travel the beam goes off from its planned place where the
/// off-edge is timed (`off_edge_timing`), unless it went off farther before: half a period,
/// the spread tp's switching once a period leaves any edge (`lead::LEAD_PERIODS`).
const MAX_PLACE_PERIODS: f64 = 0.5;

/// The most servo periods an off-edge's scan replays, all replays summed: some 10⁷ steps of
/// tp's arithmetic, a tenth of a second.
const MAX_SCAN_PERIODS: f64 = 1.0e7;
