//! A job planned in windows, planned again (`emit`'s held lit blocks, issue 18): the first
//! pass ([`plan_program_windows`](super::plan_program_windows)) checks the whole program and
//! keeps only what the checks read; the writer then reads each lit op's sub-blocks from this
//! second pass as it writes, so no table of them a move is held.
//!
//! The job holds the program as staged (leads added, arcs as chords where the machine needs
//! them), its kinematics and its start, and everything else the planner read is derived from
//! those again: the limits and configuration (`planner_inputs`), the beam switches that stop
//! the machine (`beam::switch_stops`: `every_switch` reads the posts only, `before_op` the ops
//! with their leads, as staging computed it). So the moves, and with them the plan, are those
//! of the first pass bit for bit (the windowed plan is the whole one: `tests/plan_windows.rs`).

use super::{Inputs, Job, MotionError, beam, lower_and_plan, planner_inputs};
use crate::planner::{self, Plan};
use crate::program::ProcessProgram;
use std::cell::Cell;

/// Plans `job` (from [`plan_program_windows`](super::plan_program_windows), on a machine that
/// does not orient the beam) again in windows and hands them to `each`, in order, until `each`
/// returns `false`: then no more moves are lowered, the planner ends the plan there (a stop
/// after the last move read) and the windows after it are not handed on. An error is the
/// first pass's, which the job passed, so none comes here in practice.
///
/// An oriented machine's plan is made whole and may be made twice (`plan_whole`'s stepped lit
/// corners), which a job does not record: its callers keep what they need of the first pass.
pub fn replan_windows(
    job: &Job,
    mut each: impl FnMut(&ProcessProgram, Plan) -> bool,
) -> Result<(), MotionError> {
    debug_assert!(!job.kin.oriented(), "an oriented machine plans whole");
    let program = &job.program;
    let n_axes = job.kin.axis_count();
    let (limits, cfg) = planner_inputs(program, n_axes);
    let switch_stops = beam::switch_stops(&program.ops, &program.machine.post);
    let inputs = Inputs {
        program,
        kin: &*job.kin,
        start: job.start,
        start_span: program.ops.first().map(|o| o.span).unwrap_or_default(),
        laser_switch_stops: switch_stops.every_switch,
        arm_stops: &switch_stops.before_op,
        record_axes: false,
    };
    let go_on = Cell::new(true);
    let planned = lower_and_plan(&inputs, false, |low| {
        let moves = low.take_while(|_| go_on.get());
        planner::plan_along_windows(inputs.start, moves, &limits, &cfg, |w| {
            if go_on.get() {
                go_on.set(each(program, w));
            }
        })
    });
    match planned {
        Ok(_) => Ok(()),
        // Cut short on purpose: whatever the planner made of the shortened program is not read.
        Err(_) if !go_on.get() => Ok(()),
        Err(e) => Err(e),
    }
}
