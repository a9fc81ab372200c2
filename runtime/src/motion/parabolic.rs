//! Whether LinuxCNC 2.9 can run a lit section of a machine that orients the beam at the speed
//! lase plans (issue 13 items 4 and 5 on the real controller).
//!
//! An oriented machine's lit path is written as joint-linear G93 blocks, each held whole in
//! its planned time (`power::lit_blocks`), as short as the spot's tolerance under joint-linear
//! interpolation needs (`kinematics::chords`). LinuxCNC joins blocks that move a rotary axis
//! only by *parabolic* blends (`tpSetupTangent` gives up on A B C motion, so neither a tangent
//! join nor a blend arc is made), and a parabolic blend cannot carry a short block at its
//! requested speed (`src/emc/tp/tp.c`, `tpComputeBlendVelocity`, `tcGetTangentialMaxAccel`):
//! - each block ramps at half its acceleration (`tcGetOverallMaxAccel`: `blend_prev` or its
//!   own term condition PARABOLIC), where canon's `getStraightAcceleration` gives the block
//!   the largest acceleration that keeps every axis within its own along it: the block's
//!   length over `t_a = max_i |Δq_i| / a_i`;
//! - its blend speed is capped at its *triangle* speed `sqrt(a/2 · L)`, the speed it would
//!   reach ramping from rest over its whole length; the next block starts as this one slows
//!   below it, and the two speeds add through the overlap. A chain of equal blocks thus runs
//!   at `min(v, sqrt(a/2 · L))`, measured on the arm: 15 ms blocks where lase wrote 5.4 ms.
//!
//! In a block's own terms the held share of its requested speed `v = L / T` is
//! `sqrt(a/2 · L) / v = T / sqrt(2 · t_a)`: it does not depend on the unit LinuxCNC measures
//! the block's length in (X Y Z's, or the rotary axes' when X Y Z stay), and a block holds
//! its speed when its time is at least `sqrt(2 · t_a)`, its *triangle time*. tp.c moves a
//! chain on the servo clock, and a block that short ends on the period after it (14.53 ms ran
//! as 15 on the real LinuxCNC and in `link::linuxcnc::tp`'s replay; a block longer than the
//! period after its triangle time runs as planned or a little faster): so the triangle time
//! rounded up to the servo period (`[post.linuxcnc] servo_period`,
//! `Machine::servo_period_s`) is the shortest block held. At each junction the blend speeds `tpComputeBlendVelocity` gives both sides are judged as well (a short block next to
//! a long one caps the long one's blend too).
//!
//! What LinuxCNC would then do cannot be planned honestly by lase: the power coupled to lase's
//! speed would over-expose those stretches (36 % of the recipe's speed on the arm's bends). So
//! a lit section some block of which LinuxCNC cannot run at its planned speed (within
//! `held::HELD_REL`) is refused after planning, at the `follow`, with the stretch's arc
//! lengths and the highest speed LinuxCNC holds through it with the same blocks (a slower
//! feed lengthens every block's time in proportion and leaves `t_a` as it is). Only where the
//! controller that runs the job is LinuxCNC (`--dialect`, a link's, else the machine file's
//! `dialect`, LinuxCNC when it names none: `Machine::run_on`) and the machine has a LinuxCNC
//! post: `lase emit --dialect grblhal` plans and checks for grblHAL. `G64 P`'s cap on a parabolic blend applies only where
//! X Y Z turn between blocks, which the oriented machines' lit blocks do not (their slide
//! stays), and is not judged here.

pub mod chain;

use super::held::{HELD_REL, floor3};
use super::{Job, LitSection, MotionError};
use crate::axes::Axes;
use crate::machine::{AxisKind, Machine};
use lase_lang::units::{Dim, format_quantity};

/// Whether `machine`'s programs run on LinuxCNC: its `dialect` (LinuxCNC when it names none)
/// with a LinuxCNC post to write them.
pub fn runs_on_linuxcnc(machine: &Machine) -> bool {
    machine.dialect.as_deref().unwrap_or("linuxcnc") == "linuxcnc"
        && machine.post.contains_key("linuxcnc")
}

/// One G93 block as LinuxCNC's planner queues it, in lase's internal units (the ratios this
/// module computes do not depend on them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    /// Its length in LinuxCNC's sense: X Y Z's, else the rotary axes'.
    pub len: f64,
    /// The requested speed: the length over the block's time.
    pub req: f64,
    /// The acceleration along it before the parabolic blend halves it.
    pub acc: f64,
    /// Its triangle time `sqrt(2·t_a)` rounded up to the servo period, s.
    pub shortest_s: f64,
    /// Whether it turns a rotary axis (else LinuxCNC may blend it otherwise).
    pub rotary: bool,
}

impl Block {
    /// The block from axes `from` to `to` run in `time_s` on `machine`; `None` when nothing
    /// moves or it takes no time.
    pub fn of(machine: &Machine, from: &Axes, to: &Axes, time_s: f64) -> Option<Block> {
        let (mut lin2, mut rot2, mut t_a) = (0.0, 0.0, 0.0f64);
        for (k, axis) in machine.axes.iter().enumerate() {
            let d = to[k] - from[k];
            match axis.kind {
                AxisKind::Rotary => rot2 += d * d,
                _ => lin2 += d * d,
            }
            if axis.a_max > 0.0 {
                t_a = t_a.max(d.abs() / axis.a_max);
            }
        }
        let (lin, rot) = (f64::sqrt(lin2), f64::sqrt(rot2));
        let len = if lin > 1e-9 { lin } else { rot };
        if len <= 1e-12 || t_a <= 0.0 || time_s <= 0.0 {
            return None;
        }
        let triangle = (2.0 * t_a).sqrt();
        // A relative hair below a whole period counts as on it (times summed from the plan).
        let period = machine.servo_period_s();
        let periods = (triangle / period * (1.0 - 1e-9)).ceil();
        Some(Block {
            len,
            req: len / time_s,
            acc: len / t_a,
            shortest_s: periods * period,
            rotary: rot > 1e-12,
        })
    }

    /// `tcGetTangentialMaxAccel` on a parabolic chain: half the block's acceleration.
    fn half_acc(&self) -> f64 {
        0.5 * self.acc
    }

    /// The speed the block reaches in a parabolic chain: its triangle speed, at most its own.
    fn reach(&self) -> f64 {
        (self.half_acc() * self.len).sqrt().min(self.req)
    }
}

/// `tpComputeBlendVelocity` (without its `G64 P` cap): the blend speeds of `a` at its end and
/// of `b` at its start.
pub fn blend_velocity(a: &Block, b: &Block) -> (f64, f64) {
    let (acc_a, acc_b) = (a.half_acc(), b.half_acc());
    let (reach_a, reach_b) = (a.reach(), b.reach());
    let t_reachable = (a.len / reach_a).min(b.len / reach_b);
    let t_blend = t_reachable.min((reach_a / acc_a).max(reach_b / acc_b));
    (reach_a.min(t_blend * acc_a), reach_b.min(t_blend * acc_b))
}

/// The share of its requested speed each block of a chain holds on LinuxCNC (1 when all of
/// it): its triangle speed, and the blend speeds at both its ends.
pub fn held_shares(blocks: &[Option<Block>]) -> Vec<f64> {
    let mut share: Vec<f64> = blocks
        .iter()
        .map(|b| match b {
            Some(b) if b.rotary => (b.len / b.req / b.shortest_s).min(1.0),
            _ => 1.0,
        })
        .collect();
    for i in 1..blocks.len() {
        if let (Some(a), Some(b)) = (blocks[i - 1], blocks[i])
            && (a.rotary || b.rotary)
        {
            let (va, vb) = blend_velocity(&a, &b);
            share[i - 1] = share[i - 1].min(va / a.req);
            share[i] = share[i].min(vb / b.req);
        }
    }
    share
}

/// A lit stretch LinuxCNC cannot run at the planned speed.
#[derive(Debug, Clone, PartialEq)]
pub struct Slow {
    /// Arc length from the section's first lit point, mm.
    pub from_mm: f64,
    pub to_mm: f64,
    /// The highest speed LinuxCNC holds over that stretch, and over the whole section, mm/s.
    pub held_mm_s: f64,
    pub section_held_mm_s: f64,
    pub feed_mm_s: f64,
    /// Further stretches of the same section.
    pub more: usize,
}

/// The first lit section of an oriented job run on LinuxCNC whose blocks LinuxCNC cannot run
/// at their planned speed, as a diagnostic at the recipe statement that made it.
pub fn check_linuxcnc_held(job: &Job) -> Result<(), MotionError> {
    if !job.kin.inverse_time() || !runs_on_linuxcnc(&job.program.machine) {
        return Ok(());
    }
    let times = op_times(job);
    for section in &job.sections {
        if let Some(slow) = slow_stretch(job, section, &times) {
            let span = job.program.ops[section.first_op as usize].span;
            let len = |x: f64| format_quantity((x * 100.0).round() / 100.0, Dim::LENGTH);
            let speed = |x: f64| format_quantity(x, Dim::SPEED);
            return Err(MotionError::SpeedNotHeld {
                feed: speed(slow.feed_mm_s),
                stretch: format!(
                    "between {} and {} along this lit path LinuxCNC runs its blocks at {} at \
                     most{}",
                    len(slow.from_mm),
                    len(slow.to_mm),
                    speed(floor3(slow.held_mm_s)),
                    if slow.more == 0 {
                        String::new()
                    } else {
                        format!(" (and {} more stretches further on)", slow.more)
                    }
                ),
                span,
                help: format!(
                    "LinuxCNC joins blocks that turn rotary axes by parabolic blends, which \
                     cannot carry a block shorter than its triangle time at speed; the blocks \
                     here are as short as `planner {{ tolerance }}` needs: follow at {} or \
                     slower, or allow a coarser tolerance (longer blocks)",
                    speed(floor3(slow.section_held_mm_s))
                ),
            });
        }
    }
    Ok(())
}

/// The highest speed LinuxCNC holds over all of `section`, mm/s, where it holds less than
/// the section's feed; `None` elsewhere, and where the machine does not run on LinuxCNC.
/// `held::check_held` offers the lower of the plan's and this, so that the speed a refusal
/// offers is one both hold.
pub fn linuxcnc_section_limit(job: &Job, section: &LitSection) -> Option<f64> {
    if !job.kin.inverse_time() || !runs_on_linuxcnc(&job.program.machine) {
        return None;
    }
    slow_stretch(job, section, &op_times(job)).map(|s| s.section_held_mm_s)
}

/// Each op's planned motion time, s (0 for ops that do not move).
fn op_times(job: &Job) -> Vec<f64> {
    let mut t = vec![0.0; job.program.ops.len()];
    for s in job.plan.segments() {
        if let Some(x) = t.get_mut(s.tag as usize) {
            *x += s.motion_duration();
        }
    }
    t
}

/// The share of its planned speed each lit op of `section` holds on LinuxCNC, with the arc
/// length it ends at from the section's first lit point (mm).
pub fn section_shares(job: &Job, section: &LitSection, times: &[f64]) -> Vec<(f64, f64, f64)> {
    let ops = &job.program.ops;
    let machine = &job.program.machine;
    let (first, last) = (section.first_op as usize, section.last_op as usize);
    let mut blocks = Vec::with_capacity(last + 1 - first);
    let mut ends = Vec::with_capacity(last + 1 - first);
    let mut s = 0.0;
    // Where the spot stands before the section: the last target before it (its lead-in's).
    let mut at = ops[..first].iter().rev().find_map(|o| o.target());
    for i in first..=last {
        let lit_move = ops[i].target().is_some() && ops[i].laser().is_some() && i > 0;
        let block = if lit_move {
            let (from, to) = (job.op_axes.get(i - 1), job.op_axes.get(i));
            Block::of(machine, &from, &to, times[i])
        } else {
            None
        };
        let start = s;
        if let Some(to) = ops[i].target() {
            if let Some(from) = at {
                s += ops[i].length_from(from);
            }
            at = Some(to);
        }
        blocks.push(block);
        ends.push((start, s));
    }
    held_shares(&blocks)
        .into_iter()
        .zip(ends)
        .map(|(share, (a, b))| (a, b, share))
        .collect()
}

/// The stretches of `section` LinuxCNC runs slower than planned (by more than `HELD_REL`).
fn slow_stretch(job: &Job, section: &LitSection, times: &[f64]) -> Option<Slow> {
    let feed = section.start_feed_mm_s;
    let ok = 1.0 - HELD_REL;
    let shares = section_shares(job, section, times);
    let section_min = shares.iter().map(|x| x.2).fold(1.0, f64::min);
    let mut stretches: Vec<(f64, f64, f64)> = Vec::new();
    let mut open: Option<(f64, f64, f64)> = None;
    for &(a, b, share) in &shares {
        if share < ok {
            open = Some(match open {
                Some((from, _, m)) => (from, b, m.min(share)),
                None => (a, b, share),
            });
        } else if let Some(st) = open.take() {
            stretches.push(st);
        }
    }
    stretches.extend(open);
    let (from, to, m) = *stretches.first()?;
    Some(Slow {
        from_mm: from,
        to_mm: to,
        held_mm_s: feed * m,
        section_held_mm_s: feed * section_min,
        feed_mm_s: feed,
        more: stretches.len() - 1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::DEFAULT_SERVO_PERIOD_S as SERVO_PERIOD_S;

    /// A rotary block of `len` at acceleration `acc` along it, run in `time` s.
    fn block(len: f64, time: f64, acc: f64) -> Block {
        let triangle = (2.0 * len / acc).sqrt();
        Block {
            len,
            req: len / time,
            acc,
            shortest_s: (triangle / SERVO_PERIOD_S * (1.0 - 1e-9)).ceil() * SERVO_PERIOD_S,
            rotary: true,
        }
    }

    #[test]
    fn a_block_holds_its_speed_from_its_triangle_time_on_the_servo_clock() {
        // 0.19° in 5.4 ms on a 1800 °/s² axis (the arm's bends): t_a = 1.056e-4 s², the
        // triangle time sqrt(2 t_a) = 14.53 ms, run as 15: 5.4 / 15 = 36 % of the speed.
        let b = block(0.19, 0.0054, 1800.0);
        let share = held_shares(&[Some(b), Some(b), Some(b)]);
        assert!((share[1] - 0.36).abs() < 1e-12, "{share:?}");
        // Just over the triangle time is not enough: the block ends on the next period.
        let over = block(0.19, 0.01460, 1800.0);
        assert!(held_shares(&[Some(over), Some(over)])[0] < 0.98);
        // From that period on, all of it.
        let long = block(0.19, 0.015, 1800.0);
        assert!(
            held_shares(&[Some(long), Some(long)])
                .iter()
                .all(|s| *s == 1.0)
        );
    }

    #[test]
    fn a_short_block_caps_the_blend_of_its_long_neighbour() {
        let long = block(2.0, 0.1, 900.0);
        let short = block(0.05, 0.0025, 900.0);
        let share = held_shares(&[Some(long), Some(short)]);
        let (va, _) = blend_velocity(&long, &short);
        assert!(va < long.req && share[0] == va / long.req, "{share:?} {va}");
        assert!(share[1] < 1.0);
    }

    #[test]
    fn the_share_does_not_depend_on_the_length_unit() {
        // The same block measured in degrees and in radians.
        let k = std::f64::consts::PI / 180.0;
        let (d, r) = (block(0.3, 0.008, 900.0), block(0.3 * k, 0.008, 900.0 * k));
        let (sd, sr) = (
            held_shares(&[Some(d), Some(d)]),
            held_shares(&[Some(r), Some(r)]),
        );
        assert!(
            (sd[0] - sr[0]).abs() < 1e-12 && sd[0] < 1.0,
            "{sd:?} {sr:?}"
        );
    }
}
