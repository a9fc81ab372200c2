//! Planner throughput: a generated 100 000-segment path (circle chords broken by zig-zags,
//! the kind of many-short-segments path a contour cut produces), planned offline with both
//! profiles. Criterion reports `thrpt` in segments (elements) per second.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use lase_runtime::planner::{AxisLimits, Move, PlannerConfig, ProfileKind, Segment, plan};

const N: usize = 100_000;

/// A 3-axis path: 64-chord circles of radius 20 mm, every fourth circle replaced by a
/// zig-zag of 1 mm teeth, with a slow z ramp, a stop every 1000 moves and a rapid every 5000.
fn path() -> Vec<Move> {
    let mut moves = Vec::with_capacity(N);
    let mut q = [0.0; 6];
    for k in 0..N {
        let turn = k / 64;
        let i = k % 64;
        let mut target = if turn % 4 == 3 {
            let x = q[0] + 0.5;
            let y = if i % 2 == 0 { 1.0 } else { 0.0 };
            [x, y, q[2], 0.0, 0.0, 0.0]
        } else {
            let phi = (i + 1) as f64 / 64.0 * std::f64::consts::TAU;
            [
                20.0 * phi.sin(),
                20.0 * (1.0 - phi.cos()),
                q[2],
                0.0,
                0.0,
                0.0,
            ]
        };
        target[2] = (k as f64) * 1e-4;
        let mut m = Move::linear(
            q,
            target,
            if k % 5000 == 4999 {
                f64::INFINITY
            } else {
                80.0
            },
        );
        m.stop_after = k % 1000 == 999;
        m.tag = k as u32;
        moves.push(m);
        q = target;
    }
    moves
}

fn bench(c: &mut Criterion) {
    let moves = path();
    let limits = AxisLimits {
        v: [300.0, 300.0, 50.0, 1.0, 1.0, 1.0],
        a: [3000.0, 3000.0, 1000.0, 1.0, 1.0, 1.0],
        j: [50_000.0, 50_000.0, 20_000.0, 1.0, 1.0, 1.0],
    };
    println!(
        "size_of::<Segment>() = {} bytes",
        std::mem::size_of::<Segment>()
    );
    let mut group = c.benchmark_group("plan_100k");
    group.throughput(Throughput::Elements(N as u64));
    group.sample_size(10);
    for (name, profile) in [
        ("trapezoid", ProfileKind::Trapezoid),
        ("s_curve", ProfileKind::SCurve),
    ] {
        let cfg = PlannerConfig {
            profile,
            junction_deviation: 0.02,
            n_axes: 3,
            ..PlannerConfig::default()
        };
        // One timed run up front so the figure shows up even in `--test` mode.
        let t0 = Instant::now();
        let p = plan([0.0; 6], &moves, &limits, &cfg).expect("bench path plans");
        let dt = t0.elapsed().as_secs_f64();
        println!(
            "{name}: {} segments, {:.3} s of motion, planned at {:.2} M segments/s (single run)",
            p.segments().len(),
            p.duration(),
            N as f64 / dt / 1e6
        );
        group.bench_function(name, |b| {
            b.iter(|| plan([0.0; 6], black_box(&moves), &limits, &cfg).expect("plans"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
