//! Geometry throughput: offset + resample of 100 000-point closed profiles (a cam-like closed
//! B-spline through 100 000 measured points, and a 100 000-vertex polyline), reported as
//! source points per second.

use criterion::{Criterion, criterion_group, criterion_main};
use lase_runtime::geometry::{Profile, V2};
use std::f64::consts::TAU;
use std::hint::black_box;
use std::time::{Duration, Instant};

const N: usize = 100_000;

fn cam_points() -> Vec<V2> {
    (0..N)
        .map(|i| {
            let t = TAU * i as f64 / N as f64;
            // Base radius 30 mm with a 10 mm smooth lobe: convex, like a disc cam.
            let r = 30.0 + 5.0 * (1.0 - t.cos());
            V2::new(t.cos(), t.sin()) * r
        })
        .collect()
}

/// Offset by 12 mm (seed 1's standoff) and resample at the source's mean spacing.
fn offset_and_resample(p: &Profile) -> usize {
    let o = p.offset(12.0).expect("offset");
    let step = o.length() / N as f64;
    o.resample(step, Some(1e-3))
        .expect("resample")
        .samples
        .len()
}

fn report(name: &str, f: impl Fn() -> usize) {
    let t = Instant::now();
    let n = f();
    let dt = t.elapsed().as_secs_f64();
    println!(
        "{name}: {N} source points, {n} samples in {:.3} s = {:.0} points/s",
        dt,
        N as f64 / dt
    );
}

fn bench(c: &mut Criterion) {
    let spline = Profile::interpolate(&cam_points(), true).expect("spline");
    let poly = Profile::polyline(&cam_points(), true).expect("polyline");
    report("spline build (interpolate + biarc rendition)", || {
        Profile::interpolate(&cam_points(), true)
            .expect("spline")
            .segs
            .len()
    });
    report("spline offset + resample", || offset_and_resample(&spline));
    report("polyline offset + resample", || offset_and_resample(&poly));
    let mut g = c.benchmark_group("geometry_100k");
    g.sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(5));
    g.bench_function("spline_offset_resample", |b| {
        b.iter(|| offset_and_resample(black_box(&spline)))
    });
    g.bench_function("polyline_offset_resample", |b| {
        b.iter(|| offset_and_resample(black_box(&poly)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
