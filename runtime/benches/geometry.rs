//! Geometry throughput: offset + resample of 100 000-point closed profiles (a cam-like closed
//! B-spline through 100 000 measured points, and a 100 000-vertex polyline), reported as
//! source points per second; and the whole seed-1 chain, offset + resample + inverse
//! kinematics of the X-ω-B machine at every sample.

use criterion::{Criterion, criterion_group, criterion_main};
use lase_runtime::geometry::{Profile, V2};
use lase_runtime::kinematics::{self, Kinematics, ToolPose};
use lase_runtime::machine::parse_machine;
use lase_runtime::planner::Axes;
use nalgebra::Vector3;
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

/// Seed 1 end to end: the lens path (12 mm offset), resampled, and every sample through the
/// cam machine's inverse kinematics (beam along the normal, continuous angles).
fn offset_resample_inverse(p: &Profile, kin: &dyn Kinematics) -> usize {
    let step = p.length() / N as f64;
    let rs = p.resample(step, Some(1e-3)).expect("resample");
    let o = p.offset(12.0).expect("offset");
    black_box(o.length());
    let mut prev: Option<Axes> = None;
    let mut n = 0;
    for s in &rs.samples {
        // The beam points into the part, against the outward normal of a counter-clockwise
        // contour (right of travel): along `left`.
        let pose = ToolPose {
            spot: Vector3::new(s.point.x, s.point.y, 0.0),
            beam: Vector3::new(s.left.x, s.left.y, 0.0),
            standoff: 12.0,
        };
        let q = kin.inverse(&pose, prev.as_ref()).expect("reachable");
        prev = Some(q);
        n += 1;
    }
    n
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
    let machine = parse_machine(lase_stdlib::machine("cam_xwb").expect("stock"), 0).expect("ok");
    let kin = kinematics::for_machine(&machine);
    report("spline offset + resample + cam_xwb inverse", || {
        offset_resample_inverse(&spline, &*kin)
    });
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
    g.bench_function("spline_offset_resample_inverse", |b| {
        b.iter(|| offset_resample_inverse(black_box(&spline), &*kin))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
