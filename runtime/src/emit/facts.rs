//! What emitting reads of a plan, gathered while the plan is made in windows (issue 18), so
//! that `lase emit` of a job of millions of moves never holds the plan itself: the windows
//! (`motion::plan_program_windows`) pass through [`PlanFacts::window`] and are dropped.
//!
//! The writer and validation read a plan in these places only: the planned speeds where each
//! op starts and ends, where a LinuxCNC post line could stop the machine (`validate`'s flying
//! switches: gathered only when the post has an immediate output word), the sub-blocks of each
//! lit op (`motion::power::lit_blocks`: the coupled power's and the plan's held speed, only on
//! the dialects that write them), and, on those dialects, the planned speed where each unlit op
//! ends below its feed (the writer holds a lead-in to it where the beam comes on next:
//! `writer::lead_cap`). All come from each op's own segments, which arrive in op order, so an
//! op is complete when a segment of a later op arrives.
//!
//! The pulse budget (`max_pulse_rate`, `max_pulses` of a post) is checked here too, on the
//! pulses as the windows pass (`report::PulseStream`, the generator `report::pulse_events` uses
//! on a whole plan): the running count and the last pulse's time per post with a budget, and
//! the first pulse over it (`validate::BudgetCheck`), which `emit` turns into the very
//! diagnostic of the whole plan before the first NC line.
//!
//! The sub-blocks are not kept here: on a lit job of short moves they were about five blocks a
//! move (518 B a move at `lase plan`'s peak with two dialects' facts, against the job's 88 B).
//! The checks read none of them, and the writer reads them op by op in increasing op order, each
//! op once (`writer::write`'s loop over the ops), so [`LitBlocks`] gets them from a second pass
//! of the same plan (`motion::replan_windows`), made on a scoped thread while the writer writes
//! and handed over in batches of a few hundred ops through a channel of two. Every check has
//! run on the first pass before the first NC line. On an oriented machine the plan is made
//! whole anyway (`motion::plan_program_windows`), maybe twice, so its sub-blocks are kept here
//! as before.

use super::validate::{self, BudgetCheck};
use super::{Dialect, EmitError};
use crate::motion::power::{self, PowerBlock};
use crate::motion::{self, Job};
use crate::planner::{Plan, Segment};
use crate::program::ProcessProgram;
use crate::report::{PulseStream, PulseTime};
use std::sync::mpsc;

/// What `emit` reads of a plan made in windows (module doc).
#[derive(Debug, Default)]
pub struct PlanFacts {
    /// `(op, speed where it starts, speed where it ends)` of every op with motion, when the
    /// post has an immediate output word.
    speeds: Option<Vec<(u32, [f64; 2])>>,
    /// The dialect writes lit sub-blocks (so the writer reads `exits`).
    split: bool,
    /// The sub-blocks of every lit op that has them, when the dialect writes them and the
    /// machine orients the beam (module doc).
    lit: Option<Vec<(u32, Vec<PowerBlock>)>>,
    /// `(op, speed where it ends)` of every unlit op that ends moving below its feed, when
    /// `split`.
    exits: Vec<(u32, f64)>,
    /// `(op, [speed where the beam comes on, where it goes off])` of every lit op at a beam
    /// edge passed moving (0 at an end that is not an edge), and of every pulsed op and image
    /// row (both ends), on LinuxCNC (`writer::lead`: the switch is carried by its speed).
    edges: Option<Vec<(u32, [f64; 2])>>,
    /// The op whose segments are arriving, its entry and exit speed so far, and its segments
    /// (kept only for a lit op when `lit` is gathered).
    op: Option<u32>,
    speed: [f64; 2],
    /// The feed of the op's last segment.
    feed: f64,
    segs: Vec<Segment>,
    /// The pulse budget of each dialect asked for whose post has one, and the pulses that
    /// feed them (none when no post has a budget).
    budgets: Vec<(Dialect, BudgetCheck)>,
    pulses: Option<PulseStream>,
}

impl PlanFacts {
    /// Ready to gather what emitting `program` in `dialect` needs.
    pub fn new(program: &ProcessProgram, dialect: Dialect) -> PlanFacts {
        PlanFacts::for_dialects(program, &[dialect])
    }

    /// Ready to gather what emitting `program` in any of `dialects` needs, once for them all
    /// (`lase plan` times several controllers): each fact is the plan's, whichever dialect
    /// reads it, and a dialect reads only its own (the speeds LinuxCNC's checks, the exits and
    /// held blocks the dialects that write sub-blocks).
    pub fn for_dialects(program: &ProcessProgram, dialects: &[Dialect]) -> PlanFacts {
        let speeds = dialects.iter().any(|&d| {
            d == Dialect::LinuxCnc
                && d.lookup(&program.machine.post)
                    .is_some_and(|(_, p)| validate::has_immediate_words(p))
        });
        let split = dialects.iter().any(|d| !d.is_grbl_family());
        let oriented = crate::kinematics::for_machine(&program.machine).oriented();
        let budgets: Vec<_> = dialects
            .iter()
            .filter_map(|&d| {
                let (_, post) = d.lookup(&program.machine.post)?;
                Some((d, BudgetCheck::new(post)?))
            })
            .collect();
        PlanFacts {
            speeds: speeds.then(Vec::new),
            split,
            lit: (split && oriented).then(Vec::new),
            pulses: (!budgets.is_empty()).then(PulseStream::new),
            budgets,
            edges: dialects.contains(&Dialect::LinuxCnc).then(Vec::new),
            ..PlanFacts::default()
        }
    }

    /// Reads a window of the plan of `program` (its segments in order, after the last window's).
    pub fn window(&mut self, program: &ProcessProgram, plan: &Plan) {
        self.check_pulses(|pulses, each| pulses.window(program, plan, each));
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
        self.check_pulses(|pulses, each| pulses.finish(program, each));
    }

    /// Hands the pulses `run` takes from the stream to every budget, while one has seen no
    /// pulse over it (after that, no later pulse changes a diagnostic).
    fn check_pulses(&mut self, run: impl FnOnce(&mut PulseStream, &mut dyn FnMut(PulseTime))) {
        let PlanFacts {
            budgets, pulses, ..
        } = self;
        let Some(pulses) = pulses else { return };
        if budgets.iter().all(|(_, b)| b.over().is_some()) {
            return;
        }
        run(pulses, &mut |p| {
            for (_, b) in budgets.iter_mut() {
                b.pulse(p.t, p.op);
            }
        });
    }

    /// The pulse budget of `dialect`'s post, as `validate::check_pulse_budget` finds it on the
    /// whole plan: the same diagnostic for the same first pulse over it. The facts must have
    /// been gathered for `dialect` (a post without a budget passes).
    pub(super) fn pulse_budget(
        &self,
        program: &ProcessProgram,
        dialect: Dialect,
    ) -> Result<(), EmitError> {
        match self.budgets.iter().find(|(d, _)| *d == dialect) {
            Some((_, b)) => b.result(program, dialect),
            None => Ok(()),
        }
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
            // keeps a few of these, not one a move; both ends of a pulsed op or an image row
            // the plan runs whole at its feed, whose trigger edges and power steps are carried
            // (`writer::lead::gated`, `writer::lead::row`; elsewhere they read 0, as where not
            // at cruise): one per row, none on a zigzag of short pulsed moves.
            let lit_near = |o: Option<&crate::program::Op>| o.is_some_and(|o| o.laser().is_some());
            let ops = &program.ops;
            let this = &ops[op as usize];
            let cruise = |v: f64| super::writer::at_cruise(v, self.feed);
            let whole = (this.laser().is_some_and(|l| l.pulse.is_some())
                || matches!(this.kind, crate::program::OpKind::Line { row: Some(_), .. }))
                && cruise(self.speed[0])
                && cruise(self.speed[1]);
            let moving = |o: &&crate::program::Op| o.target().is_some();
            let before = ops[..op as usize].iter().rev().find(moving);
            let after = ops[op as usize + 1..].iter().find(moving);
            let v = [
                if lit_near(before) && !whole {
                    0.0
                } else {
                    self.speed[0]
                },
                if lit_near(after) && !whole {
                    0.0
                } else {
                    self.speed[1]
                },
            ];
            if v[0] > 0.0 || v[1] > 0.0 {
                edges.push((op, v));
            }
        }
        if self.split {
            if lit(program, op) {
                if let Some(blocks) = &mut self.lit {
                    let b = power::lit_blocks_of(program, op as usize, &self.segs);
                    if !b.is_empty() {
                        blocks.push((op, b));
                    }
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

    /// The planned speeds where lit op `op` starts and ends at a beam edge (0 elsewhere), and
    /// at both ends of a pulsed op or an image row.
    pub(super) fn edge_speeds(&self, op: usize) -> [f64; 2] {
        let Some(all) = &self.edges else {
            return [0.0, 0.0];
        };
        all.binary_search_by_key(&op, |&(i, _)| i as usize)
            .map_or([0.0, 0.0], |k| all[k].1)
    }
}

/// Where the writer reads each lit op's sub-blocks (`power::lit_blocks`), asked op by op in
/// increasing op order, each op at most once (module doc).
pub(super) enum LitBlocks<'a> {
    /// The dialect writes none.
    Unsplit,
    /// From the job's whole plan.
    Whole(&'a Job),
    /// Kept by the facts of an oriented machine's plan.
    Held(&'a PlanFacts),
    /// From the second pass: its batches as they come, and the one being read.
    Replayed {
        batches: mpsc::Receiver<Result<Batch, motion::MotionError>>,
        batch: std::iter::Peekable<std::vec::IntoIter<(u32, Vec<PowerBlock>)>>,
    },
}

/// The `(op, sub-blocks)` of some lit ops that have them, in op order: at most [`BATCH`] ops.
type Batch = Vec<(u32, Vec<PowerBlock>)>;

/// Batches the second pass may send ahead of the writer: it plans while the writer writes.
const AHEAD: usize = 2;

/// Ops a batch holds at most. A window of the plan is a few thousand segments: sent a window at
/// a time, the blocks in the channel took `tests/plan_memory.rs`'s peak from 113.9 to 124.2 B
/// a move (1 MB, fixed, over its 100 000 moves). A batch of 256 lit ops is about 50 kB, and a
/// send per 256 ops costs nothing next to planning them.
const BATCH: usize = 256;

impl<'a> LitBlocks<'a> {
    /// Where the writer of `job` in `dialect` reads the sub-blocks; `facts`: the job was
    /// planned in windows, and then (on a flat bed) the second pass starts on `scope`. It ends
    /// once it has handed on its last window or once this is dropped (its next send fails),
    /// so the scope's end never waits on a writer that stopped early.
    pub(super) fn new<'s>(
        job: &'a Job,
        facts: Option<&'a PlanFacts>,
        dialect: Dialect,
        scope: &'s std::thread::Scope<'s, '_>,
    ) -> LitBlocks<'a>
    where
        'a: 's,
    {
        let Some(facts) = facts else {
            return LitBlocks::Whole(job);
        };
        if dialect.is_grbl_family() {
            return LitBlocks::Unsplit;
        }
        if facts.lit.is_some() {
            return LitBlocks::Held(facts);
        }
        if !job.program.ops.iter().any(|o| o.laser().is_some()) {
            // Nothing to plan again for.
            return LitBlocks::Unsplit;
        }
        let (tx, batches) = mpsc::sync_channel(AHEAD);
        scope.spawn(move || replay(job, &tx));
        LitBlocks::Replayed {
            batches,
            batch: Vec::new().into_iter().peekable(),
        }
    }

    /// The sub-blocks of op `op` (none for an op without).
    pub(super) fn of(&mut self, op: usize) -> Result<Vec<PowerBlock>, EmitError> {
        match self {
            LitBlocks::Unsplit => Ok(Vec::new()),
            LitBlocks::Whole(job) => Ok(power::lit_blocks(job, op)),
            LitBlocks::Held(facts) => {
                let all = facts.lit.as_deref().unwrap_or_default();
                Ok(all
                    .binary_search_by_key(&op, |&(i, _)| i as usize)
                    .map(|k| all[k].1.clone())
                    .unwrap_or_default())
            }
            LitBlocks::Replayed { batches, batch } => loop {
                // Ops before `op` the writer did not ask for (no motion from where it was).
                while batch.next_if(|(i, _)| (*i as usize) < op).is_some() {}
                if let Some((_, blocks)) = batch.next_if(|(i, _)| *i as usize == op) {
                    return Ok(blocks);
                }
                if batch.peek().is_some() {
                    return Ok(Vec::new());
                }
                match batches.recv() {
                    Ok(Ok(b)) => *batch = b.into_iter().peekable(),
                    Ok(Err(e)) => return Err(EmitError::Replan(Box::new(e))),
                    // The pass has handed on every batch: no lit op from here on has blocks.
                    Err(mpsc::RecvError) => return Ok(Vec::new()),
                }
            },
        }
    }
}

/// The second pass (module doc): the lit ops' sub-blocks to `tx` in batches, an op's once a
/// segment of a later op arrives, the last after the last window; a batch at most every
/// [`BATCH`] ops and at the end of each window.
fn replay(job: &Job, tx: &mpsc::SyncSender<Result<Batch, motion::MotionError>>) {
    let program = &job.program;
    let mut op = None;
    let mut segs: Vec<Segment> = Vec::new();
    let close = |op: Option<u32>, segs: &mut Vec<Segment>, out: &mut Batch| {
        if let Some(op) = op.filter(|&o| lit(program, o)) {
            let b = power::lit_blocks_of(program, op as usize, segs);
            if !b.is_empty() {
                out.push((op, b));
            }
        }
        segs.clear();
    };
    let replayed = motion::replan_windows(job, |program, w| {
        let mut out = Batch::new();
        for seg in w.segments() {
            if op != Some(seg.tag) {
                close(op, &mut segs, &mut out);
                op = Some(seg.tag);
                if out.len() >= BATCH && tx.send(Ok(std::mem::take(&mut out))).is_err() {
                    return false;
                }
            }
            if lit(program, seg.tag) {
                segs.push(*seg);
            }
        }
        // Sent even when empty: a send fails once the writer is gone, and then the pass plans
        // no further.
        tx.send(Ok(out)).is_ok()
    });
    let last = match replayed {
        Ok(()) => {
            let mut out = Batch::new();
            close(op, &mut segs, &mut out);
            Ok(out)
        }
        Err(e) => Err(e),
    };
    // Nobody may be listening any more: nothing to do then.
    let _ = tx.send(last);
}

/// Op `op` is lit.
fn lit(program: &ProcessProgram, op: u32) -> bool {
    program.ops[op as usize].laser().is_some()
}
