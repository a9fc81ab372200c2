//! A recipe of many short lit moves written with a `for` loop (issue 18's "10⁶ short moves"
//! row): 0.05 mm moves zigzagging over a 100 × 100 mm field, two per loop turn. Shared by the
//! bounded-memory test (`tests/plan_memory.rs`) and the benchmark (`examples/bench_moves.rs`).

/// The recipe of `n` moves (`n` even; a `for` loop writes at most the evaluator's op budget,
/// 2 000 000).
pub fn recipe(n: usize) -> String {
    format!(
        "machine xy_table\n\
         laser {{ power 20 W, spot 40 um }}\n\
         laser on\n\
         for i in 0..{turns} {{\n\
         \x20   move to (-50 mm + (i % 1000) * 0.1 mm, -50 mm + (i / 1000) * 0.01 mm) at 20 mm/s\n\
         \x20   move to (-49.95 mm + (i % 1000) * 0.1 mm, -49.995 mm + (i / 1000) * 0.01 mm) at 20 mm/s\n\
         }}\n",
        turns = n / 2
    )
}
