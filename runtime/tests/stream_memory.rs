//! Streaming holds bounded memory, whatever the job's length (issue 18): a million-line
//! program, made line by line on demand, streamed by the GRBL client through the simulated
//! controller (its recording bounded as `lase run` bounds it), under a fixed cap on the peak
//! of live heap allocation, counted by this binary's global allocator.
//!
//! Before issue 18 the simulator kept a record of every line and block (about 730 B per
//! line): a million lines held some 700 MB. The cap here is a few MB, so any per-line state
//! that comes back fails this test long before a real job runs out of memory.

use cap::Cap;
use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::sim::{self, SimOptions, TimeScale};
use lase_runtime::link::stream::{self, Outcome, Progress, StreamJob, StreamOptions};
use lase_runtime::link::{ConnectOptions, Event};
use lase_runtime::machine::parse_machine;
use std::alloc::System;

#[global_allocator]
static ALLOC: Cap<System> = Cap::new(System, usize::MAX);

#[path = "support/zigzag.rs"]
mod zigzag;

/// Peak live heap while streaming, above what was live before, bytes.
const CAP_BYTES: usize = 8 << 20;

#[test]
fn a_million_line_stream_through_the_simulator_holds_bounded_memory() {
    let n = 1_000_000;
    let machine = parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    let (h, transport) = sim::spawn_in_process(
        &machine,
        SimOptions {
            time_scale: TimeScale::Max,
            keep: Some(sim::KEEP_LIVE),
            ..SimOptions::default()
        },
    )
    .unwrap();
    let mut link = GrblLink::connect(transport, "sim".into(), &ConnectOptions::default()).unwrap();
    let before = ALLOC.allocated();
    let source = zigzag::Zigzag {
        n,
        feed_mm_min: 60_000,
    };
    let report = stream::stream(
        &mut link,
        &StreamJob::made(&source),
        None,
        &StreamOptions::default(),
        &mut |_: &Progress, _: Option<&Event>| None,
    );
    assert_eq!(report.outcome, Outcome::Done);
    assert_eq!(report.acked, n);
    let peak = ALLOC.max_allocated().saturating_sub(before);
    drop(link);
    let rec = h.stop();
    // Every line arrived once and ran; the recording kept only the latest ones.
    assert_eq!(rec.gcode_lines, n as u64);
    assert_eq!(rec.rx_overflows, 0);
    assert!(
        rec.blocks_executed as usize >= n - 8,
        "{}",
        rec.blocks_executed
    );
    assert!(rec.lines.len() <= 2 * sim::KEEP_LIVE);
    assert!(
        peak < CAP_BYTES,
        "streaming {n} lines held {peak} bytes at its peak ({:.1} B per line), over the {CAP_BYTES}-byte cap",
        peak as f64 / n as f64
    );
}
