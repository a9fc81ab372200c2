//! Memory per move of a job of many short moves written with a `for` loop (issue 18): the
//! recipe is compiled with its plan made in windows and emitted as LinuxCNC NC to a sink that
//! keeps nothing (what `lase check` and `lase emit` do), planned in windows again with the
//! summary counted and every controller timed by its streamed model (what `lase plan` does),
//! then compiled with the whole plan (what trace, plot, run and the REPL do), in this one
//! process, and the peak of live heap above what was live before is counted by a counting
//! global allocator, not read from RSS.
//!
//! ```text
//! cargo run --release -p lase-runtime --example bench_moves            # 1 000 000 moves
//! cargo run --release -p lase-runtime --example bench_moves -- 100000
//! ```
//!
//! The default is issue 18's million short moves; the evaluator's op budget (`MAX_OPS`,
//! 2 000 000) is the most a `for` loop can write. The recipe is generated (`tests/support/short_moves.rs`): lit moves of
//! 0.05 mm zigzagging over a 100 × 100 mm field, two per loop turn.

use lase_runtime::compile::{self, MemFiles};
use lase_runtime::emit::{self, Dialect, EmitOptions, NcLine, PlanFacts};
use lase_runtime::program::ProcessProgram;
use std::alloc::System;

#[path = "../tests/support/short_moves.rs"]
mod short_moves;

#[global_allocator]
static ALLOC: cap::Cap<System> = cap::Cap::new(System, usize::MAX);

/// CPU time this process has run, every thread's, in s (`/proc/self/stat`'s utime and stime,
/// in ticks of 1/100 s): `lase emit` plans the lit sub-blocks again on a thread of its own
/// (`emit::PlanFacts`), and on a shared machine the wall clock also counts the time other
/// processes hold the core.
fn cpu_time() -> f64 {
    let ticks = || {
        let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
        // After the command's closing parenthesis come fields 3 (state) on: utime is 14,
        // stime 15.
        let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
        let user: u64 = fields.get(11)?.parse().ok()?;
        let system: u64 = fields.get(12)?.parse().ok()?;
        Some(user + system)
    };
    ticks().map_or(f64::NAN, |t| t as f64 / 100.0)
}

/// The recipe loaded, checked and evaluated.
fn program(files: &mut MemFiles) -> ProcessProgram {
    let mut recipe = compile::load(files, "moves.lase").unwrap_or_else(|(_, f)| fail(f));
    compile::check(&recipe).unwrap_or_else(|f| fail(f));
    compile::evaluate(&mut recipe, files).unwrap_or_else(|f| fail(f))
}

fn fail(e: impl std::fmt::Display) -> ! {
    eprintln!("bench_moves: {e}");
    std::process::exit(1)
}

fn main() {
    let n: usize = match std::env::args().nth(1) {
        Some(s) => s.parse().unwrap_or_else(|_| {
            eprintln!("bench_moves: the argument is a number of moves, not `{s}`");
            std::process::exit(2)
        }),
        None => 1_000_000,
    };
    let mut files = MemFiles::new([("moves.lase", short_moves::recipe(n))]);
    let before = ALLOC.allocated();
    let mib = |b: usize| b as f64 / (1 << 20) as f64;
    // `lase check` and `lase emit`: the plan made in windows, read and dropped. The counter's
    // peak only grows: the whole plan comes last.
    let c0 = cpu_time();
    let p = program(&mut files);
    let mut facts = PlanFacts::new(&p, Dialect::LinuxCnc);
    let (job, planned) =
        compile::plan_in_windows(p, |p, w| facts.window(p, &w)).unwrap_or_else(|f| fail(f));
    facts.finish(&job.program);
    let c1 = cpu_time();
    let check_peak = ALLOC.max_allocated().saturating_sub(before);
    let held = ALLOC.allocated().saturating_sub(before);
    let moves = planned.segments;
    let per = |b: usize| b as f64 / moves.max(1) as f64;
    let mut bytes = 0u64;
    let mut sink = |l: &NcLine| {
        bytes += l.text.len() as u64 + 1;
        Ok(())
    };
    let stats = emit::emit_planned(
        &job,
        &facts,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut sink,
    )
    .unwrap_or_else(|e| fail(e));
    let c2 = cpu_time();
    let peak = ALLOC.max_allocated().saturating_sub(before);
    println!(
        "{moves} moves ({} ops) in windows: check peak {:.0} B/move ({:.1} MiB), the job holds \
         {:.0} B/move; with emit peak {:.0} B/move ({:.1} MiB); {} NC lines, {bytes} bytes; CPU \
         {:.2} s compile, {:.2} s emit",
        job.program.ops.len(),
        per(check_peak),
        mib(check_peak),
        per(held),
        per(peak),
        mib(peak),
        stats.lines,
        c1 - c0,
        c2 - c1,
    );
    drop((job, facts));
    // `lase plan`: the summary's running totals and each controller's facts gathered as the
    // windows pass, then every controller it reports timed by its model, line by line.
    let c0 = cpu_time();
    let p = program(&mut files);
    let first = lase_runtime::link::estimate::default_dialect(&p.machine);
    let dialects: Vec<Dialect> = std::iter::once(first)
        .chain(lase_runtime::link::estimate::other_dialects(
            &p.machine, first,
        ))
        .collect();
    let mut totals = lase_runtime::report::PlanTotals::new(&p);
    let mut facts = PlanFacts::for_dialects(&p, &dialects);
    let (job, planned) = compile::plan_in_windows(p, |p, w| {
        totals.window(p, &w);
        facts.window(p, &w);
    })
    .unwrap_or_else(|f| fail(f));
    totals.finish(&job.program, planned.length);
    facts.finish(&job.program);
    let summary = totals.summary(&job);
    let c1 = cpu_time();
    let times: Vec<String> = dialects
        .iter()
        .map(|&d| {
            let c = lase_runtime::link::estimate::controller_cycle_from(&job, Some(&facts), d);
            format!("{d} {:.3} s", c.cycle_time_s)
        })
        .collect();
    let c2 = cpu_time();
    let peak = ALLOC.max_allocated().saturating_sub(before);
    println!(
        "{moves} moves planned in windows (lase plan): peak so far {:.0} B/move ({:.1} MiB); \
         lase's plan {:.3} s, {}; CPU {:.2} s plan, {:.2} s controller models",
        per(peak),
        mib(peak),
        summary.cycle_time_s,
        times.join(", "),
        c1 - c0,
        c2 - c1,
    );
    drop((job, facts));
    // Trace, plot, run, the REPL: the whole plan.
    let c0 = cpu_time();
    let job = compile::plan(program(&mut files)).unwrap_or_else(|f| fail(f));
    let c1 = cpu_time();
    let held = ALLOC.allocated().saturating_sub(before);
    let peak = ALLOC.max_allocated().saturating_sub(before);
    println!(
        "{} moves planned whole: peak {:.0} B/move ({:.1} MiB), the job holds {:.0} B/move; CPU \
         {:.2} s compile",
        job.plan.segments().len(),
        per(peak),
        mib(peak),
        per(held),
        c1 - c0,
    );
}
