//! What emitting reads of a plan, gathered while the plan is made in windows (issue 18), so
//! that `lase emit` of a job of millions of moves never holds the plan itself: the windows
//! (`motion::plan_program_windows`) pass through [`PlanFacts::window`] and are dropped.
//!
//! The writer and validation read a plan in two places only: the planned speeds where each op
//! starts and ends, where a LinuxCNC post line could stop the machine (`validate`'s flying
//! switches: gathered only when the post has an immediate output word), the sub-blocks of each
//! lit op (`motion::power::lit_blocks`: the coupled power's and the plan's held speed, only on
//! the dialects that write them), and, on those dialects, the planned speed where each unlit op
//! ends below its feed (the writer holds a lead-in to it where the beam comes on next:
//! `writer::lead_cap`). All come from each op's own segments, which arrive in op order, so an
//! op is complete when a segment of a later op arrives. The pulse budget reads every pulse's time
//! from the whole plan: a post with one plans whole ([`plans_in_windows`]).

use super::{Dialect, validate};
use crate::motion::power::{self, PowerBlock};
use crate::planner::{Plan, Segment};
use crate::program::ProcessProgram;

/// Whether `lase emit` may plan `program` in windows for `dialect` ([`PlanFacts`]): not when
/// the post has a pulse budget, whose check reads the whole plan.
pub fn plans_in_windows(program: &ProcessProgram, dialect: Dialect) -> bool {
    dialect
        .lookup(&program.machine.post)
        .is_none_or(|(_, post)| {
            post.budget.max_rate_hz.is_none() && post.budget.max_pulses.is_none()
        })
}

/// What `emit` reads of a plan made in windows (module doc).
#[derive(Debug, Default)]
pub struct PlanFacts {
    /// `(op, speed where it starts, speed where it ends)` of every op with motion, when the
    /// post has an immediate output word.
    speeds: Option<Vec<(u32, [f64; 2])>>,
    /// The sub-blocks of every lit op that has them, when the dialect writes them.
    lit: Option<Vec<(u32, Vec<PowerBlock>)>>,
    /// `(op, speed where it ends)` of every unlit op that ends moving below its feed, when
    /// `lit` is gathered.
    exits: Vec<(u32, f64)>,
    /// `(op, [speed where the beam comes on, where it goes off])` of every lit op at a beam
    /// edge passed moving, on LinuxCNC (`writer::lead`: the switch is carried by its speed).
    edges: Option<Vec<(u32, [f64; 2])>>,
    /// The op whose segments are arriving, its entry and exit speed so far, and its segments
    /// (kept only for a lit op when `lit` is gathered).
    op: Option<u32>,
    speed: [f64; 2],
    /// The feed of the op's last segment.
    feed: f64,
    segs: Vec<Segment>,
}

impl PlanFacts {
    /// Ready to gather what emitting `program` in `dialect` needs.
    pub fn new(program: &ProcessProgram, dialect: Dialect) -> PlanFacts {
        let post = dialect.lookup(&program.machine.post).map(|(_, p)| p);
        let speeds =
            dialect == Dialect::LinuxCnc && post.is_some_and(validate::has_immediate_words);
        PlanFacts {
            speeds: speeds.then(Vec::new),
            lit: (!dialect.is_grbl_family()).then(Vec::new),
            edges: (dialect == Dialect::LinuxCnc).then(Vec::new),
            ..PlanFacts::default()
        }
    }

    /// Reads a window of the plan of `program` (its segments in order, after the last window's).
    pub fn window(&mut self, program: &ProcessProgram, plan: &Plan) {
        for seg in plan.segments() {
            if self.op != Some(seg.tag) {
                self.close(program);
                self.op = Some(seg.tag);
                self.speed[0] = seg.v_entry;
            }
            self.speed[1] = seg.v_exit;
            self.feed = seg.feed;
            if self.lit.is_some() && lit(program, seg.tag) {
                self.segs.push(*seg);
            }
        }
    }

    /// After the last window.
    pub fn finish(&mut self, program: &ProcessProgram) {
        self.close(program);
    }

    fn close(&mut self, program: &ProcessProgram) {
        let Some(op) = self.op.take() else { return };
        if let Some(speeds) = &mut self.speeds {
            speeds.push((op, self.speed));
        }
        if let Some(edges) = &mut self.edges
            && lit(program, op)
        {
            // Only at edges (the neighbouring motion unlit), so a lit job of a million moves
            // keeps a few of these, not one a move.
            let lit_near = |o: Option<&crate::program::Op>| o.is_some_and(|o| o.laser().is_some());
            let ops = &program.ops;
            let moving = |o: &&crate::program::Op| o.target().is_some();
            let before = ops[..op as usize].iter().rev().find(moving);
            let after = ops[op as usize + 1..].iter().find(moving);
            let v = [
                if lit_near(before) { 0.0 } else { self.speed[0] },
                if lit_near(after) { 0.0 } else { self.speed[1] },
            ];
            if v[0] > 0.0 || v[1] > 0.0 {
                edges.push((op, v));
            }
        }
        if let Some(blocks) = &mut self.lit {
            if lit(program, op) {
                let b = power::lit_blocks_of(program, op as usize, &self.segs);
                if !b.is_empty() {
                    blocks.push((op, b));
                }
            } else if self.speed[1] > 0.0 && self.speed[1] < self.feed {
                self.exits.push((op, self.speed[1]));
            }
        }
        self.segs.clear();
    }

    /// `validate::op_speeds` of the plan the windows made (empty when not gathered).
    pub(super) fn op_speeds(&self) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
        self.speeds
            .iter()
            .flatten()
            .map(|&(op, [v0, v1])| (op as usize, v0, v1))
    }

    /// The planned speed where unlit op `op` ends, where it is moving and below its feed
    /// (`writer::lead_cap`).
    pub(super) fn exit_below_feed(&self, op: usize) -> Option<f64> {
        let k = self
            .exits
            .binary_search_by_key(&op, |&(i, _)| i as usize)
            .ok()?;
        Some(self.exits[k].1)
    }

    /// The planned speeds where lit op `op` starts and ends at a beam edge (0 elsewhere).
    pub(super) fn edge_speeds(&self, op: usize) -> [f64; 2] {
        let Some(all) = &self.edges else {
            return [0.0, 0.0];
        };
        all.binary_search_by_key(&op, |&(i, _)| i as usize)
            .map_or([0.0, 0.0], |k| all[k].1)
    }

    /// `power::lit_blocks` of op `op`.
    pub(super) fn lit_blocks(&self, op: usize) -> Vec<PowerBlock> {
        let Some(all) = &self.lit else {
            return Vec::new();
        };
        all.binary_search_by_key(&op, |&(i, _)| i as usize)
            .map(|k| all[k].1.clone())
            .unwrap_or_default()
    }
}

/// Op `op` is lit.
fn lit(program: &ProcessProgram, op: u32) -> bool {
    program.ops[op as usize].laser().is_some()
}
