//! Planning holds bounded memory per move (issue 18): a recipe of many short moves from a
//! `for` loop is compiled (check, evaluate, leads, plan: what `lase check` and `lase plan` do)
//! and emitted (what `lase emit` adds), under a fixed cap on the peak of live heap per move,
//! counted by this binary's global allocator.
//!
//! Before issue 18's second round a job held every planner move beside its plan (80 B a move),
//! the evaluator's ops were copied into the program, the lead-in pass copied them again and kept
//! tables of every op (about 120 B an op), and each op's axes took 48 B: 477 B a move at the
//! peak (`examples/bench_moves.rs`, 500 000 moves). Now it is about 356 B (a 168-byte op, the
//! plan's 128 B and the look-ahead's 40 B of scratch, 16 B of op axes), and a per-move table
//! that comes back fails this test.

use cap::Cap;
use lase_runtime::compile::{self, MemFiles};
use lase_runtime::emit::{self, Dialect, EmitOptions, NcLine};
use std::alloc::System;

#[global_allocator]
static ALLOC: Cap<System> = Cap::new(System, usize::MAX);

#[path = "support/short_moves.rs"]
mod short_moves;

/// Peak live heap per move while compiling and emitting, above what was live before, bytes.
/// Corner blends (issue 13, `planner::blend`) cost about 60 B a move on top of the 356 B
/// above: the planner keeps what each move tells the blends (`blend::MoveInfo`: its
/// part-space direction and stop flags, 32 B) until every corner is judged, a segment carries
/// its blend index, and the entry caps are recomputed in one pass (414 B measured; as first
/// merged, with a table of junctions and a copy of the plan, 829 B). Since the lit corners of
/// a flat bed are blended too (issue 13 item 3), every corner of this lit zigzag is: each
/// 0.05 mm move becomes the two halves of the blends at its ends (2.5 segments a move, the
/// plan's 176 B each with its point and look-ahead scratch), each corner keeps its 160-byte
/// `Blend`, and `blend::split` builds the expanded plan beside the one it expands: 1 094 B
/// measured. Compacting that layout is issue 18's (branch `mem150`); this cap still fails a
/// per-move table that comes back.
const CAP_PER_MOVE: f64 = 1100.0;

#[test]
fn short_moves_from_a_loop_compile_and_emit_within_a_fixed_budget_per_move() {
    let n = 100_000;
    let mut files = MemFiles::new([("moves.lase", short_moves::recipe(n))]);
    let before = ALLOC.allocated();
    let (_recipe, job) = compile::compile(&mut files, "moves.lase")
        .unwrap_or_else(|(_, f)| panic!("the recipe compiles: {f}"));
    // Moves, not segments: a blended move is two or three segments (`planner::blend`).
    let moves = job
        .plan
        .segments()
        .last()
        .map_or(0, |s| s.move_index as usize + 1);
    // Every move of the loop was planned (plus the lead-in and lead-out lase adds).
    assert!((n..n + 8).contains(&moves), "{moves} moves planned");
    let mut lines = 0usize;
    emit::emit(
        &job,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut |_: &NcLine| {
            lines += 1;
            Ok(())
        },
    )
    .expect("the job emits");
    assert!(lines >= n, "{lines} lines");
    let peak = ALLOC.max_allocated().saturating_sub(before);
    let per_move = peak as f64 / moves as f64;
    eprintln!("{moves} moves: peak {peak} B, {per_move:.1} B per move");
    assert!(
        per_move < CAP_PER_MOVE,
        "compiling and emitting {moves} moves held {peak} bytes at the peak ({per_move:.1} B per \
         move), over the cap of {CAP_PER_MOVE} B per move"
    );
}
