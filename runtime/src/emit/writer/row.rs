//! The blocks of one motion op as the writer lays them out: the op itself, or, for an image
//! row (`Line` with a [`PixelRow`]), one lit `Line` per pixel run, made here at write time so
//! the runs never exist as ops (a million-run photo stays a thousand ops through planning).
//!
//! A run's block ends where a `Line` per run would have ended (the row's column times the
//! pixel size, through the image frame), its axes come from the same inverse kinematics as the
//! planned ops' (motion's), and on dialects whose power follows the speed block by block
//! (`power::coupled_blocks`) the row's planned blocks are cut at the run ends, each scaled
//! from the row's power to the run's: the plan's speed is the row's, the power the run's.

use crate::axes::Axes;
use crate::motion::power::PowerBlock;
use crate::motion::{Job, tool_pose};
use crate::program::{Laser, Op, OpKind, P3, dist};
use std::borrow::Cow;

/// How far a row's power steps are carried along it on LinuxCNC (`lead`): each run's end
/// moves `lead` mm on, so its power line (`M67`, a synchronized output that leads the joints
/// as the beam switch does) reaches the spot where the run ends; with `past_end` the last run
/// runs on `lead` mm into the lead-out too (which the beam-off then needs no cut of).
#[derive(Debug, Clone, Copy)]
pub(super) struct Carry {
    pub lead: f64,
    pub past_end: bool,
    /// The shortest block tp runs at the row's speed (`lead::MIN_PART_PERIODS`), mm.
    pub min_block: f64,
}

/// One motion block (or a coupled op's sub-blocks) to write.
pub(super) struct Piece<'a> {
    pub op: Cow<'a, Op>,
    /// The axes the piece ends at.
    pub q: Axes,
    /// Its power sub-blocks when the power follows the speed on this dialect; else empty.
    pub blocks: Vec<PowerBlock>,
}

/// The pieces of motion op `i` starting at `from` (axes `from_q`); `blocks`: its lit
/// sub-blocks where the dialect writes them (`power::lit_blocks`: the coupled power's, and the
/// planned speed's; `emit::facts::LitBlocks`), else none.
pub(super) fn pieces<'j>(
    job: &'j Job,
    blocks: Vec<PowerBlock>,
    i: usize,
    from: P3,
    from_q: Axes,
    carry: Option<Carry>,
) -> Vec<Piece<'j>> {
    let op = &job.program.ops[i];
    let OpKind::Line {
        to,
        feed_mm_s,
        laser: Some(laser),
        orient,
        row: Some(row),
    } = &op.kind
    else {
        return vec![Piece {
            op: Cow::Borrowed(op),
            q: job.op_axes.get(i),
            blocks,
        }];
    };
    let total = dist(from, *to);
    let shifts = carry
        .filter(|_| blocks.len() <= 1 && total > 0.0)
        .map(|c| shifts(row, from, total, c))
        .unwrap_or_default();
    let mut out = Vec::with_capacity(row.runs.len());
    let (mut s0, mut q_prev, mut b) = (0.0, from_q, 0);
    for (k, &(c, shade)) in row.runs.iter().enumerate() {
        let last = k + 1 == row.runs.len();
        let sh = shifts.get(k).copied().unwrap_or(0.0);
        let p = if last {
            *to
        } else {
            let [x, y] = row.end_of(c);
            [x, y, to[2]]
        };
        // Carried `sh` mm further along the row (`Carry`).
        let p: P3 = std::array::from_fn(|j| p[j] + sh * (to[j] - from[j]) / total);
        let s1 = if last && sh == 0.0 {
            total
        } else {
            dist(from, p)
        };
        let q = if last && sh == 0.0 {
            job.op_axes.get(i)
        } else {
            run_axes(
                job,
                p,
                orient.as_deref().copied(),
                &q_prev,
                &from_q,
                &job.op_axes.get(i),
                s1 / total,
            )
        };
        let power_w = row.power_w(shade);
        let mut sub = Vec::new();
        // The row's planned blocks over [s0, s1], at this run's power.
        while b < blocks.len() {
            // A last run carried past the row's end runs on to its own end.
            let end = if last && b + 1 == blocks.len() {
                s1
            } else {
                blocks[b].s_end.min(s1)
            };
            let scale = scale(laser, power_w);
            sub.push(PowerBlock {
                s_end: end - s0,
                power_w: blocks[b].power_w * scale,
                max_error_w: blocks[b].max_error_w * scale,
                v_cap: blocks[b].v_cap,
            });
            if blocks[b].s_end > s1 + 1e-12 && !last {
                break;
            }
            b += 1;
        }
        out.push(Piece {
            op: Cow::Owned(Op {
                kind: OpKind::Line {
                    to: p,
                    feed_mm_s: *feed_mm_s,
                    laser: Some(std::sync::Arc::new(Laser {
                        power_w,
                        ..(**laser).clone()
                    })),
                    orient: orient.clone(),
                    row: None,
                },
                span: op.span,
            }),
            q,
            blocks: sub,
        });
        s0 = s1;
        q_prev = q;
    }
    out
}

/// How far each run's end is carried (`Carry`; the last entry, the row's end, only
/// `past_end`): `lead`, but where a run's block would be left shorter than tp runs at the
/// row's speed (a one-pixel run at the end of a row that cannot run on into its lead-out),
/// the ends before it stay where they are, from the row's end back.
fn shifts(row: &crate::program::PixelRow, from: P3, total: f64, c: Carry) -> Vec<f64> {
    let n = row.runs.len();
    let ends: Vec<f64> = row
        .runs
        .iter()
        .enumerate()
        .map(|(k, &(col, _))| {
            if k + 1 == n {
                total
            } else {
                let [x, y] = row.end_of(col);
                ((x - from[0]).powi(2) + (y - from[1]).powi(2)).sqrt()
            }
        })
        .collect();
    let mut sh = vec![0.0; n];
    sh[n - 1] = if c.past_end { c.lead } else { 0.0 };
    for k in (0..n - 1).rev() {
        // Run k + 1's block, from run k's carried end to its own.
        let len = ends[k + 1] + sh[k + 1] - (ends[k] + c.lead);
        sh[k] = if len >= c.min_block { c.lead } else { 0.0 };
    }
    sh
}

/// The factor from the row's power to a run's (0 for a row lit at 0 W throughout).
fn scale(row: &Laser, run_w: f64) -> f64 {
    if row.power_w > 0.0 {
        run_w / row.power_w
    } else {
        0.0
    }
}

/// A run end's axes: the machine's inverse at that point, as motion computes every op's; on an
/// oriented machine (whose beam turns along the op) the planned axes interpolated, as a
/// coupled op's sub-blocks are.
fn run_axes(
    job: &Job,
    p: P3,
    orient: Option<crate::program::Orient>,
    prev: &Axes,
    from_q: &Axes,
    to_q: &Axes,
    f: f64,
) -> Axes {
    if job.kin.oriented() {
        return from_q.lerp(to_q, f);
    }
    job.kin
        .inverse(&tool_pose(p, orient), Some(prev))
        .unwrap_or_else(|_| from_q.lerp(to_q, f))
}
