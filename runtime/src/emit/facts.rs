//! What emitting reads of a plan, gathered while the plan is made in windows (issue 18), so
//! that `lase emit` of a job of millions of moves never holds the plan itself: the windows
//! (`motion::plan_program_windows`) pass through [`PlanFacts::window`] and are dropped.
//!
//! The writer and validation read a plan in two places only: the planned speeds where each op
//! starts and ends, where a LinuxCNC post line could stop the machine (`validate`'s flying
//! switches: gathered only when the post has an immediate output word), and the power
//! sub-blocks of each lit op coupled to speed (`motion::power`: only on the dialects that
//! write them). Both come from each op's own segments, which arrive in op order, so an op is
//! complete when a segment of a later op arrives. The pulse budget reads every pulse's time
//! from the whole plan: a post with one plans whole ([`plans_in_windows`]).

use super::{Dialect, validate};
use crate::motion::power::{self, PowerBlock};
use crate::planner::{Plan, Segment};
use crate::program::{Coupling, ProcessProgram};

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
    /// The power sub-blocks of every coupled lit op, when the dialect writes them.
    coupled: Option<Vec<(u32, Vec<PowerBlock>)>>,
    /// The op whose segments are arriving, its entry and exit speed so far, and its segments
    /// (kept only for a coupled op when `coupled` is gathered).
    op: Option<u32>,
    speed: [f64; 2],
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
            coupled: (!dialect.is_grbl_family()).then(Vec::new),
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
            if self.coupled.is_some() && coupled(program, seg.tag) {
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
        if let Some(blocks) = &mut self.coupled
            && let Some(laser) = program.ops[op as usize].laser()
            && laser.couple == Coupling::Speed
        {
            blocks.push((op, power::coupled_blocks_of(laser, &self.segs)));
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

    /// `power::coupled_blocks` of op `op`.
    pub(super) fn coupled_blocks(&self, op: usize) -> Vec<PowerBlock> {
        let Some(all) = &self.coupled else {
            return Vec::new();
        };
        all.binary_search_by_key(&op, |&(i, _)| i as usize)
            .map(|k| all[k].1.clone())
            .unwrap_or_default()
    }
}

/// Op `op` is lit and its power follows the speed.
fn coupled(program: &ProcessProgram, op: u32) -> bool {
    program.ops[op as usize]
        .laser()
        .is_some_and(|l| l.couple == Coupling::Speed)
}
