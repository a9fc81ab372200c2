//! Planning holds bounded memory per move (issue 18): a recipe of many short moves from a
//! `for` loop is checked (check, evaluate, leads, plan: `lase check`), emitted (`lase emit`) and
//! reported (`lase plan`: the summary, the time split and every controller's cycle time) under
//! a fixed cap on the peak of live heap per move, counted by this binary's global allocator;
//! then planned whole, as trace, plot, pulses, run and the REPL still do, under the whole
//! plan's own cap.
//!
//! Before issue 18's second round a job held every planner move beside its plan (80 B a move),
//! the evaluator's ops were copied into the program, the lead-in pass copied them again and kept
//! tables of every op (about 120 B an op), and each op's axes took 48 B: 477 B a move at the
//! peak (`examples/bench_moves.rs`, 500 000 moves). The third round brought it from 414 B to
//! 225 B, which is what a whole plan costs: the job's op (72 B: `Op` with a shared laser and a
//! boxed orientation), the axes the op ends at (16 B, `OpAxes`), its plan segment (120 B,
//! `planner::Segment`) and the segment's start point (16 B).
//!
//! `lase check`, `lase emit` and `lase plan` plan in windows (`planner::plan_along_windows`):
//! the segments are read (`emit::PlanFacts`, `report::PlanTotals`) and dropped a window at a
//! time, and the controller models read the program from the emitter a line at a time, holding
//! only their controller's queue (`linuxcnc::tp::TpStream`, `sim::motion::ModelStream`), so
//! what remains a move is the job's op and op axes (88 B), and a window of a few thousand
//! segments whatever the job's length. `lase plan` held 892 B a move before (the whole plan,
//! the NC text of each controller and the models' tables per line). Below that the ops
//! themselves would have to stream from the evaluator.

use cap::Cap;
use lase_runtime::compile::{self, MemFiles};
use lase_runtime::emit::{self, Dialect, EmitOptions, NcLine, PlanFacts};
use lase_runtime::link::estimate;
use lase_runtime::program::{Op, ProcessProgram};
use lase_runtime::report::PlanTotals;
use std::alloc::System;
use std::mem::{size_of, size_of_val};

#[global_allocator]
static ALLOC: Cap<System> = Cap::new(System, usize::MAX);

#[path = "support/short_moves.rs"]
mod short_moves;

/// Peak live heap per move while checking, emitting and planning (`lase plan`) in windows, above
/// what was live before, bytes. Before lit corners were blended and held (issue 13 item 3):
/// 101.1 B measured at 100 000 moves, the job's ops and op axes (88.1 B) and the planner's
/// buffers and the window being read (a fixed 1.3 MB whatever the job's length). Now every
/// corner of this lit zigzag is blended (2.5 segments a move in the windows: `lase check`
/// peaks at 111.7 B) and the plan holds every move below its feed, so on LinuxCNC and ISO each
/// move is written as about five held sub-blocks (`power::lit_blocks`). Kept in
/// `emit::PlanFacts` from the windows until the NC was written, they took the peak to 518.2 B
/// (check 111.7, emit 314.9, lase plan 518.2 with two dialects' facts). The writer now reads
/// them from a second pass of the same plan as it writes (`emit::PlanFacts`' module doc, 256
/// ops a batch), which keeps no table of the ops' axes: 113.9 B measured (check 111.7, emit
/// 113.8, lase plan 113.9), the job's 88.1 B and about 2.6 MB fixed.
///
/// That emit went through windows only because this test called `emit_planned` itself: the
/// binary planned whole wherever a post had a pulse budget (every stock LinuxCNC and GRBL post;
/// xy_table's 500 Hz and 300 Hz), 793.1 B a move here, as the whole plan below. The budget is
/// now checked on the windows (`emit::PlanFacts`, `report::PulseStream`), and this test walks
/// the binary's path with a pulse every 0.5 mm (19 982 pulses through both budgets): 111.7 B
/// measured (check 111.7, emit 111.7, lase plan 111.7; the job 88.1 B).
const CAP_PER_MOVE: f64 = 120.0;

/// The same for the whole plan (trace, plot, pulses, run, the REPL). With its corners taken at
/// rest or stepped this recipe peaked at 225.2 B (the job's 224 B: ops, op axes, segments and
/// points, and the blends' flags). Since the lit corners of a flat bed are blended (issue 13
/// item 3), every corner of this lit zigzag is: each 0.05 mm move becomes the halves of the
/// blends at its ends (2.5 segments a move, 300 B). That peaked at 793.2 B (996.4 B read here
/// while the `lase emit` stage's facts, shadowed by the next stage's, were never dropped: 203
/// B): points 40 B a move, a 160-byte `Blend` a corner, and `blend::split` building the
/// expanded plan beside the prepared one (137 B) with 20 % spare capacity (68 B). Now the split
/// writes into the prepared table itself, sized by an upper bound of its segments and shrunk
/// to them (`blend/expand.rs`: 589.2 B), a blend is kept in 41 bytes (`planner::Blends`: the
/// axes in use only, its `w` once as the next blend's `u`: 470.2 B), and the halves of blends
/// keep no point (`Plan::segment_start` computes it from the blend: 446.2 B). The job holds
/// 437.8 B of it: ops 72, op axes 16, segments 300.1, points 8.6, blends 41.0; the split's
/// points room adds the rest. What is left is the segments: 120 B each, 2.5 a move.
const CAP_PER_MOVE_WHOLE: f64 = 450.0;

/// Peak of live heap above `base` so far, bytes.
fn peak_above(base: usize) -> usize {
    ALLOC.max_allocated().saturating_sub(base)
}

/// The short-moves recipe, evaluated.
fn program(files: &mut MemFiles) -> ProcessProgram {
    let mut recipe =
        compile::load(files, "moves.lase").unwrap_or_else(|(_, f)| panic!("the recipe loads: {f}"));
    compile::check(&recipe).unwrap_or_else(|f| panic!("the recipe checks: {f}"));
    compile::evaluate(&mut recipe, files).unwrap_or_else(|f| panic!("evaluates: {f}"))
}

#[test]
fn short_moves_from_a_loop_check_plan_and_emit_within_a_fixed_budget_per_move() {
    let n = 100_000;
    // Pulses every 0.5 mm along the lit zigzag (40 Hz at its 20 mm/s): xy_table's posts hold
    // them to their pulse budgets (LinuxCNC 500 Hz, GRBL 300 Hz), which `lase emit` and `lase
    // plan` check on the windows as they pass (`emit::PlanFacts`), as the binary does.
    let recipe =
        short_moves::recipe(n).replace("laser on\n", "pulse { interval 0.5 mm }\nlaser on\n");
    assert!(recipe.contains("pulse {"), "{recipe}");
    let mut files = MemFiles::new([("moves.lase", recipe)]);
    let before = ALLOC.allocated();
    // `lase check`: the plan made in windows and dropped. The counter's peak only grows, so
    // each stage's peak is read before the next starts.
    let program_ = program(&mut files);
    let evaluated = peak_above(before);
    let ops = program_.ops.len();
    let mut last_move = 0usize;
    let (job, _) = compile::plan_in_windows(program_, |_, w| {
        if let Some(s) = w.segments().last() {
            last_move = s.move_index as usize;
        }
    })
    .unwrap_or_else(|f| panic!("the recipe plans: {f}"));
    let checked = peak_above(before);
    let held = ALLOC.allocated().saturating_sub(before);
    // Moves, not segments: a blended move is two or three segments (`planner::blend`).
    let moves = last_move + 1;
    // Every move of the loop was planned (plus the lead-in and lead-out lase adds).
    assert!((n..n + 8).contains(&moves), "{moves} moves planned");
    assert!(job.plan.segments().is_empty(), "the job keeps no plan");
    let n_axes = job.plan.n_axes();
    let tables = [
        ("program ops", ops * size_of::<Op>()),
        ("op axes", job.op_axes.len() * n_axes * 8),
    ];
    drop(job);
    // `lase emit --dialect linuxcnc` (`src/main.rs`): planned in windows again, what the writer
    // reads gathered as they pass, the post's pulse budget checked on them.
    let program_ = program(&mut files);
    for d in [Dialect::LinuxCnc, Dialect::Grbl] {
        let (_, post) = d
            .lookup(&program_.machine.post)
            .expect("xy_table has the post");
        assert!(
            post.budget.max_rate_hz.is_some(),
            "{d}: xy_table's post has a pulse budget"
        );
    }
    let mut facts = PlanFacts::new(&program_, Dialect::LinuxCnc);
    let mut windows = 0usize;
    let mut largest = 0usize;
    let (job, _) = compile::plan_in_windows(program_, |p, w| {
        windows += 1;
        largest = largest.max(w.segments().len());
        facts.window(p, &w)
    })
    .unwrap_or_else(|f| panic!("the recipe plans: {f}"));
    facts.finish(&job.program);
    let mut lines = 0usize;
    emit::emit_planned(
        &job,
        &facts,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut |_: &NcLine| {
            lines += 1;
            Ok(())
        },
    )
    .expect("the job emits");
    assert!(lines >= n, "{lines} lines");
    drop(job);
    // (The next stage's facts shadow these: dropped here, or they would live to the end.)
    drop(facts);
    let emitted = peak_above(before);
    // `lase plan`: planned in windows again, the summary counted and each controller's facts
    // gathered as they pass, then every controller it reports timed by its streamed model.
    let program_ = program(&mut files);
    let first = estimate::default_dialect(&program_.machine);
    let dialects: Vec<Dialect> = std::iter::once(first)
        .chain(estimate::other_dialects(&program_.machine, first))
        .collect();
    let mut totals = PlanTotals::new(&program_);
    let mut facts = PlanFacts::for_dialects(&program_, &dialects);
    let (job, planned) = compile::plan_in_windows(program_, |p, w| {
        totals.window(p, &w);
        facts.window(p, &w);
    })
    .unwrap_or_else(|f| panic!("the recipe plans: {f}"));
    totals.finish(&job.program, planned.length);
    facts.finish(&job.program);
    let summary = totals.summary(&job);
    assert_eq!(summary.blocks, moves, "the summary counts every move");
    // A pulse every 0.5 mm of the 10 m zigzag: these went through both budgets.
    assert!(summary.pulses > 19_000, "{} pulses", summary.pulses);
    let mut timed = Vec::new();
    for d in &dialects {
        let c = estimate::controller_cycle_from(&job, Some(&facts), *d);
        assert!(c.note.is_none(), "{d}: {:?}", c.note);
        // Every controller ran the whole path, at most at its 20 mm/s feed. (Not a share of
        // lase's own time: lase blends every lit corner of this 0.05 mm zigzag and plans
        // 1993 s, where GRBL's velocity steps take 501 s.)
        let at_feed = summary.path_length_mm / 20.0;
        assert!(
            c.cycle_time_s > at_feed,
            "{d}: {c:?}, {at_feed} s at the feed"
        );
        timed.push(format!("{d} {:.3} s", c.cycle_time_s));
    }
    assert!(dialects.len() >= 2, "{dialects:?}");
    drop(job);
    // What `lase plan` gathered for the controllers goes with it.
    drop(facts);
    drop(totals);
    let peak = peak_above(before);
    let per = |b: usize| b as f64 / moves as f64;
    let tables: Vec<String> = tables
        .iter()
        .map(|(what, b)| format!("{what} {:.1}", per(*b)))
        .collect();
    eprintln!(
        "{moves} moves in windows: peak {peak} B, {:.1} B per move (evaluate {:.1}, check {:.1}, \
         emit {:.1}, plan {:.1}; the job holds {:.1}); {windows} windows of at most {largest} \
         segments; B per move: {}; lase plan timed {}; {} pulses",
        per(peak),
        per(evaluated),
        per(checked),
        per(emitted),
        per(peak),
        per(held),
        tables.join(", "),
        timed.join(", "),
        summary.pulses
    );
    let per_move = per(peak);
    assert!(
        per_move < CAP_PER_MOVE,
        "checking, emitting and planning (`lase plan`) {moves} moves in windows held {peak} \
         bytes at the peak ({per_move:.1} B per move), over the cap of {CAP_PER_MOVE} B per move"
    );
    assert!(windows > 5, "{windows} windows: the plan was cut");

    // The whole plan, as trace, plot, pulses, run and the REPL make it.
    let program_ = program(&mut files);
    let job = compile::plan(program_).unwrap_or_else(|f| panic!("the recipe plans: {f}"));
    let held = ALLOC.allocated().saturating_sub(before);
    let planned = peak_above(before);
    emit::emit(
        &job,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut |_: &NcLine| Ok(()),
    )
    .expect("the job emits");
    let peak = peak_above(before);
    let tables = [
        ("plan segments", size_of_val(job.plan.segments())),
        ("plan points", job.plan.point_heap_bytes()),
        ("plan blends", job.plan.blends().heap_bytes()),
    ];
    let tables: Vec<String> = tables
        .iter()
        .map(|(what, b)| format!("{what} {:.1}", per(*b)))
        .collect();
    eprintln!(
        "{moves} moves planned whole: peak {:.1} B per move (planning {:.1}, the job holds {:.1}); \
         B per move: {}",
        per(peak),
        per(planned),
        per(held),
        tables.join(", ")
    );
    assert!(
        per(peak) < CAP_PER_MOVE_WHOLE,
        "planning {moves} moves whole held {:.1} B per move, over the cap of \
         {CAP_PER_MOVE_WHOLE} B",
        per(peak)
    );
}
