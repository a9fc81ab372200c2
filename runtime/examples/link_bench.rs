//! End-to-end streaming benchmark: a generated raster job streamed by the GRBL client to the
//! simulated controller over TCP loopback, as `lase run --link tcp://…` streams it.
//!
//! ```text
//! cargo run --release -p lase-runtime --example link_bench -- [--lines N] [--baud B] [--journal]
//! ```
//!
//! Without `--baud`: lines per second through the protocol (character counting, one `ok`
//! per line, loopback TCP). With `--baud 115200`: the simulator's serial line carries
//! baud/10 bytes per second each way, and the link utilization is the program bytes sent
//! over the capacity of the line during the job: bytes / (baud/10 × time). The simulated
//! machine executes as fast as possible, so the link is the only bottleneck.
//!
//! Memory: the program is made line by line as it streams (nothing per line is kept, as a
//! job of tens of millions of lines needs) and the simulator keeps a bounded recording, as
//! `lase run` does; the peak of live heap allocation (a counting global allocator, not RSS)
//! is printed in all and per line, and stays flat as `--lines` grows.

use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::journal::{Header, Journal};
use lase_runtime::link::sim::{self, SimOptions, TimeScale};
use lase_runtime::link::stream::{self, Outcome, Progress, Source, StreamJob, StreamOptions};
use lase_runtime::link::transport::TcpTransport;
use lase_runtime::link::{ConnectOptions, Event};
use std::time::Instant;

#[global_allocator]
static ALLOC: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

#[path = "../tests/support/zigzag.rs"]
mod zigzag;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .and_then(|v| v.parse::<u64>().ok())
    };
    let n = arg("--lines").unwrap_or(100_000) as usize;
    let baud = arg("--baud").map(|b| b as u32);
    let use_journal = args.iter().any(|a| a == "--journal");
    let machine = lase_runtime::machine::parse_machine(
        lase_stdlib::machine("xy_table").expect("stock machine"),
        0,
    )
    .expect("machine parses");
    let lines = zigzag::Zigzag {
        n: n.max(6),
        feed_mm_min: 6000,
    };
    let h = sim::serve(
        &machine,
        "127.0.0.1:0".parse().expect("address"),
        SimOptions {
            time_scale: TimeScale::Max,
            baud,
            keep: Some(sim::KEEP_LIVE),
            ..SimOptions::default()
        },
    )
    .expect("simulator listens");
    let a = h.addr().expect("tcp");
    let t = TcpTransport::connect(&a.ip().to_string(), a.port()).expect("connects");
    let mut link = GrblLink::connect(
        Box::new(t),
        format!("tcp://{a}"),
        &ConnectOptions::default(),
    )
    .expect("greets");
    let dir = tempfile::tempdir().expect("temp dir");
    let mut journal = use_journal.then(|| {
        Journal::create(
            &dir.path().join("bench.journal"),
            &Header {
                recipe: "bench".into(),
                link: format!("tcp://{a}"),
                dialect: "grbl".into(),
                lines: lines.len(),
                // Never resumed: the benchmark measures the journal's writing, not its use.
                hash: 0,
                start: [0.0; lase_runtime::link::MAX_AXES],
            },
        )
        .expect("journal")
    });
    let before = ALLOC.allocated();
    let t0 = Instant::now();
    let report = stream::stream(
        &mut link,
        &StreamJob::made(&lines),
        journal.as_mut(),
        &StreamOptions::default(),
        &mut |_: &Progress, _: Option<&Event>| None,
    );
    let secs = t0.elapsed().as_secs_f64();
    assert_eq!(report.outcome, Outcome::Done, "the job streams");
    drop(link);
    let peak = ALLOC.max_allocated().saturating_sub(before);
    let rec = h.stop();
    assert_eq!(
        rec.gcode_lines as usize,
        lines.len(),
        "every line arrives once"
    );
    assert_eq!(rec.rx_overflows, 0, "the RX buffer never overflows");
    let bytes = report.program_bytes as f64;
    println!(
        "{} lines, {:.0} bytes ({:.1} bytes/line){} in {secs:.3} s: {:.0} lines/s, {:.0} bytes/s",
        lines.len(),
        bytes,
        bytes / lines.len() as f64,
        if use_journal { ", journaled" } else { "" },
        lines.len() as f64 / secs,
        bytes / secs
    );
    println!(
        "peak heap while streaming {:.2} MB: {:.1} bytes per line (counting allocator)",
        peak as f64 / 1e6,
        peak as f64 / lines.len() as f64
    );
    if let Some(b) = baud {
        let capacity = f64::from(b) / 10.0;
        println!(
            "link {b} baud ({capacity:.0} bytes/s): utilization {:.2} % (bytes / (baud/10 × time)), max RX fill {} of 127 bytes",
            100.0 * bytes / (capacity * secs),
            rec.max_rx_fill
        );
    }
}
