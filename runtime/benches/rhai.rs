//! Rhai extension throughput (issue 8's goal: 100 000 calls of a Rhai profile function in
//! under 0.5 s, release build). Two paths are measured:
//! - `recipe_calls`: 100 000 calls from Rust through `Extensions::call`, as the evaluator makes
//!   them (argument conversion by the declared signature, the sandboxed call, the result
//!   checked and converted back);
//! - `polar_profile`: one generator that samples a Rhai closure 100 000 times inside Rhai and
//!   builds the spline through the points.
//!
//! `cargo bench -p lase-runtime --bench rhai`

use criterion::{Criterion, criterion_group, criterion_main};
use lase_lang::units::Dim;
use lase_lang::{SourceMap, Span};
use lase_runtime::eval::Value;
use lase_runtime::ext::Extensions;
use std::hint::black_box;
use std::time::{Duration, Instant};

const N: usize = 100_000;

const MODULE: &str = r#"
/// A cam radius: base 30 mm, a 10 mm cycloidal rise over 180° and back.
/// lase: (theta: angle) -> length
fn radius(theta) {
    let u = if theta < PI() { theta / PI() } else { 2.0 - theta / PI() };
    30.0 + 10.0 * (u - sin(2.0 * PI() * u) / (2.0 * PI()))
}

/// lase: (n: number) -> profile
fn sampled(n) { polar_profile(|t| radius(t), n.to_int()) }
"#;

fn load() -> Extensions {
    let mut ext = Extensions::new();
    ext.load_module(&mut SourceMap::new(), "bench.rhai", MODULE)
        .expect("the bench module loads");
    ext
}

fn recipe_calls(ext: &mut Extensions) -> f64 {
    let mut sum = 0.0;
    for i in 0..N {
        let theta = std::f64::consts::TAU * i as f64 / N as f64;
        let args = [(Value::Num(theta, Dim::ANGLE), Span::default())];
        match ext.call("radius", &args, Span::default()) {
            Ok(Value::Num(r, _)) => sum += r,
            other => panic!("{other:?}"),
        }
    }
    sum
}

fn bench(c: &mut Criterion) {
    let mut ext = load();
    let t = Instant::now();
    black_box(recipe_calls(&mut ext));
    eprintln!(
        "rhai: {N} calls of a profile function from the evaluator in {:.3} s",
        t.elapsed().as_secs_f64()
    );
    let t = Instant::now();
    let p = ext
        .call(
            "sampled",
            &[(Value::Num(N as f64, Dim::NONE), Span::default())],
            Span::default(),
        )
        .expect("polar_profile");
    eprintln!(
        "rhai: polar_profile sampling a closure {N} times (and the spline) in {:.3} s",
        t.elapsed().as_secs_f64()
    );
    black_box(p);

    let mut g = c.benchmark_group("rhai");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("recipe_calls_100k", |b| {
        b.iter(|| black_box(recipe_calls(&mut ext)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
