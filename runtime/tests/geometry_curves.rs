//! Geometry: B-spline interpolation (PROCESS.md §2 step 1), exact queries, resampling, offsets
//! and the seed-2 fold-over rule, each checked against numbers computed independently here.

use lase_runtime::geometry::{GeomError, OffsetOptions, Profile, Seg, Spline, V2};
use std::f64::consts::{PI, TAU};

/// Points of the polar curve r(θ) = a + b cos(kθ), counter-clockwise.
fn polar(n: usize, a: f64, b: f64, k: f64) -> Vec<V2> {
    (0..n)
        .map(|i| {
            let t = TAU * i as f64 / n as f64;
            V2::new(t.cos(), t.sin()) * (a + b * (k * t).cos())
        })
        .collect()
}

fn measured() -> Vec<V2> {
    // An uneven, open "measured section".
    [
        (0.0, 0.0),
        (4.0, 1.5),
        (9.0, 2.2),
        (13.5, 1.0),
        (18.0, -1.2),
        (24.0, -0.5),
        (29.0, 2.5),
        (33.0, 6.0),
    ]
    .iter()
    .map(|&(x, y)| V2::new(x, y))
    .collect()
}

#[test]
fn open_and_closed_splines_pass_through_every_point() {
    let q = measured();
    let open = Spline::interpolate(&q, false).unwrap();
    assert_eq!(open.span_count(), q.len() - 1);
    for (j, p) in q.iter().enumerate() {
        assert!((open.derivs(j as f64).0 - p).norm() < 1e-9, "open Q{j}");
    }
    // Natural end conditions: no second derivative at either end.
    assert!(open.derivs(0.0).2.norm() < 1e-9);
    assert!(open.derivs(open.span_count() as f64).2.norm() < 1e-9);
    // The seed's control-point equation holds on every interior row.
    let p = open.control_points();
    for j in 1..q.len() - 1 {
        let lhs = p[j] + p[j + 1] * 4.0 + p[j + 2];
        assert!((lhs - q[j] * 6.0).norm() < 1e-9);
    }

    let q = polar(23, 20.0, 4.0, 3.0);
    let closed = Spline::interpolate(&q, true).unwrap();
    assert_eq!(closed.span_count(), q.len());
    for (j, p) in q.iter().enumerate() {
        assert!((closed.derivs(j as f64).0 - p).norm() < 1e-9, "closed Q{j}");
    }
    let p = closed.control_points();
    let n = p.len();
    for j in 0..n {
        let lhs = p[(j + n - 1) % n] + p[j] * 4.0 + p[(j + 1) % n];
        assert!((lhs - q[j] * 6.0).norm() < 1e-9, "cyclic row {j}");
    }
}

#[test]
fn closed_spline_is_c2_at_the_seam_and_at_every_knot() {
    let q = polar(17, 30.0, 6.0, 2.0);
    let s = Spline::interpolate(&q, true).unwrap();
    let n = s.span_count();
    for j in 0..n {
        // Left limit: end of span j − 1 (the seam for j = 0); right limit: start of span j.
        let (pl, d1l, d2l) = s.span_derivs((j + n - 1) % n, 1.0);
        let (pr, d1r, d2r) = s.span_derivs(j, 0.0);
        assert!((pl - pr).norm() < 1e-9, "C0 at knot {j}");
        assert!((d1l - d1r).norm() < 1e-9, "C1 at knot {j}");
        assert!((d2l - d2r).norm() < 1e-9, "C2 at knot {j}");
    }
}

#[test]
fn arc_length_matches_the_circle_and_richardson_extrapolation() {
    // A closed spline through 72 points of a circle of radius 10.
    let r = 10.0;
    let q = polar(72, r, 0.0, 0.0);
    let p = Profile::interpolate(&q, true).unwrap();
    let sp = p.as_spline().unwrap();
    // Close to the circle (interpolation error), and exact for its own curve:
    assert!(
        (p.length() - TAU * r).abs() < 1e-5,
        "{}",
        p.length() - TAU * r
    );
    // Reference length from inscribed polygons, Richardson-extrapolated (error O(h⁴)).
    let poly = |m: usize| -> f64 {
        let n = sp.span_count() as f64;
        (0..m)
            .map(|i| {
                let a = sp.derivs(n * i as f64 / m as f64).0;
                let b = sp.derivs(n * (i + 1) as f64 / m as f64).0;
                (b - a).norm()
            })
            .sum()
    };
    let (l1, l2) = (poly(40_000), poly(80_000));
    let reference = (4.0 * l2 - l1) / 3.0;
    assert!(
        (p.length() - reference).abs() < 1e-9,
        "{}",
        p.length() - reference
    );
    // Inversion: length_at_param(param_at(s)) = s, and the point at s sits at angle s / r.
    for k in 0..=50 {
        let s = p.length() * k as f64 / 50.0;
        let u = p.param_at(s);
        assert!((p.length_at_param(u) - s).abs() < 1e-9);
        let f = p.frame_at(s);
        let ang = s / p.length() * TAU;
        assert!((f.point - V2::new(ang.cos(), ang.sin()) * r).norm() < 1e-4);
        // Counter-clockwise circle: curvature 1/r, concave normal toward the center, left
        // normal too.
        // Curvature of the interpolant itself varies by O(h²) between knots.
        assert!((f.curvature - 1.0 / r).abs() < 2e-4, "{}", f.curvature);
        assert!((f.normal + f.point / r).norm() < 1e-4);
        assert!((f.left - f.normal).norm() < 1e-12);
        assert!((f.tangent.norm() - 1.0).abs() < 1e-12);
    }
    // The clockwise circle turns right: negative curvature, concave normal still inward.
    let cw = p.reversed();
    let f = cw.frame_at(3.0);
    assert!(f.curvature < 0.0);
    assert!((f.normal + f.point / r).norm() < 1e-4);
    assert!((f.left + f.normal).norm() < 1e-12);
    assert!((cw.length() - p.length()).abs() < 1e-9);
    assert!((cw.start() - p.start()).norm() < 1e-9);
}

#[test]
fn line_and_arc_frames_are_exact() {
    let a = Profile::arc(V2::new(1.0, 2.0), 4.0, 0.0, PI, false).unwrap(); // clockwise half
    let f = a.frame_at(a.length() / 2.0);
    assert!((f.point - V2::new(1.0, -2.0)).norm() < 1e-12);
    assert!((f.curvature + 0.25).abs() < 1e-15);
    assert!((f.normal - V2::new(0.0, 1.0)).norm() < 1e-12);
    assert!((f.left - V2::new(0.0, -1.0)).norm() < 1e-12);
    let u = a.param_at(a.length() / 4.0);
    assert!((u - 0.25).abs() < 1e-12);
    assert!((a.frame_at_param(0.25).point - a.point_at(a.length() / 4.0)).norm() < 1e-12);
    let sq = Profile::polyline(
        &[V2::new(0.0, 0.0), V2::new(3.0, 0.0), V2::new(3.0, 4.0)],
        false,
    )
    .unwrap();
    let f = sq.frame_at(5.0);
    assert_eq!(f.curvature, 0.0);
    assert!((f.point - V2::new(3.0, 2.0)).norm() < 1e-12);
    assert!((f.left - V2::new(-1.0, 0.0)).norm() < 1e-12);
}

#[test]
fn spline_rendition_stays_within_its_tolerance() {
    let p = Profile::interpolate(&polar(40, 25.0, 5.0, 3.0), true).unwrap();
    for tol in [1e-2, 1e-3, 1e-4] {
        let la = p.to_line_arc(tol).unwrap();
        assert!(la.spline.is_none() && la.closed);
        let mut worst: f64 = 0.0;
        for k in 0..4000 {
            let q = p.point_at(p.length() * k as f64 / 4000.0);
            let d = la
                .segs
                .iter()
                .map(|s| s.distance_to(q))
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
        assert!(worst <= tol, "tol {tol}: {worst}");
        // Tangent continuity of the biarcs.
        for w in la.segs.windows(2) {
            let t0 = w[0].tangent_at(w[0].length());
            let t1 = w[1].tangent_at(0.0);
            assert!((t0 - t1).norm() < 1e-6);
        }
    }
    assert!((p.signed_area() - p.to_line_arc(1e-5).unwrap().signed_area()).abs() < 1e-3);
}

#[test]
fn resampling_steps_are_exact_and_chords_bounded() {
    let p = Profile::interpolate(&polar(50, 30.0, 8.0, 2.0), true).unwrap();
    let step = 0.37;
    let r = p.resample(step, None).unwrap();
    assert_eq!(r.step, step);
    let n = r.samples.len();
    for w in r.samples[..n - 1].windows(2) {
        assert!((w[1].s - w[0].s - step).abs() < 1e-12);
    }
    let last = r.samples[n - 1].s - r.samples[n - 2].s;
    assert!(last > 0.0 && last <= step + 1e-12);
    assert!((r.samples[n - 1].s - p.length()).abs() < 1e-12);
    for smp in r.samples.iter().step_by(37) {
        // The sample is where the curve is at arc length s (length of the exact curve).
        let u = p.param_at(smp.s);
        assert!((p.length_at_param(u) - smp.s).abs() < 1e-9);
        let f = p.frame_at(smp.s);
        assert!((f.point - smp.point).norm() < 1e-9);
        assert!((f.tangent - smp.tangent).norm() < 1e-9);
        assert!((f.curvature - smp.curvature).abs() < 1e-9);
        assert!((smp.left - V2::new(-smp.tangent.y, smp.tangent.x)).norm() < 1e-15);
    }

    // With a chord tolerance the step shrinks so every chord is within it.
    let tol = 1e-3;
    let r = p.resample(2.0, Some(tol)).unwrap();
    assert!(r.step < 2.0);
    assert!(r.max_chord_error <= tol, "{}", r.max_chord_error);
    assert!(r.max_chord_error > 0.3 * tol, "{}", r.max_chord_error);
    // Independent check: distance from quarter and mid points of each step to the chord.
    for w in r.samples.windows(2) {
        for f in [0.25, 0.5, 0.75] {
            let q = p.point_at(w[0].s + f * (w[1].s - w[0].s));
            let chord = Seg::Line {
                a: w[0].point,
                b: w[1].point,
            };
            assert!(chord.distance_to(q) <= tol * 1.0001);
        }
    }

    // Exact circle: the measured error is the sagitta r(1 − cos(h / 2r)).
    let c = Profile::circle(V2::zeros(), 12.0, 0.0, true).unwrap();
    let r = c.resample_even(1.0, Some(1e-3)).unwrap();
    let sag = 12.0 * (1.0 - (r.step / 24.0).cos());
    assert!((r.max_chord_error - sag).abs() < 1e-12);
    assert!(sag <= 1e-3);
    let steps: Vec<f64> = r.samples.windows(2).map(|w| w[1].s - w[0].s).collect();
    assert!(steps.iter().all(|h| (h - r.step).abs() < 1e-9));

    // Corners of a polyline are reported, not counted as smooth chords.
    let sq = Profile::polyline(
        &[
            V2::new(0.0, 0.0),
            V2::new(10.0, 0.0),
            V2::new(10.0, 10.0),
            V2::new(0.0, 10.0),
        ],
        true,
    )
    .unwrap();
    let r = sq.resample(3.0, Some(1e-3)).unwrap();
    assert_eq!(r.corners, vec![0.0, 10.0, 20.0, 30.0]);
    assert_eq!(r.max_chord_error, 0.0);
    assert!(r.corner_chord_error > 0.0);
}

/// Distance from `o` to the spline, by dense search then Newton on (C(u) − o)·C'(u) = 0.
fn distance_to_spline(sp: &Spline, o: V2) -> f64 {
    let n = sp.span_count();
    let m = n * 4;
    let mut best = (0.0, f64::INFINITY);
    for i in 0..=m {
        let u = n as f64 * i as f64 / m as f64;
        let d = (sp.derivs(u).0 - o).norm();
        if d < best.1 {
            best = (u, d);
        }
    }
    let mut u = best.0;
    for _ in 0..30 {
        let (p, d1, d2) = sp.derivs(u);
        let g = (p - o).dot(&d1);
        let dg = d1.dot(&d1) + (p - o).dot(&d2);
        if dg.abs() < 1e-300 {
            break;
        }
        let next = u - g / dg;
        u = if sp.is_closed() {
            next.rem_euclid(n as f64)
        } else {
            next.clamp(0.0, n as f64)
        };
    }
    (sp.derivs(u).0 - o).norm().min(best.1)
}

#[test]
fn spline_offsets_keep_the_distance_within_the_bound() {
    let src = Profile::interpolate(&polar(60, 30.0, 4.0, 3.0), true).unwrap();
    let sp = src.as_spline().unwrap();
    for (d, tol) in [(12.0, 1e-3), (-6.0, 1e-3), (12.0, 1e-5)] {
        let o = src
            .offset_with(
                d,
                &OffsetOptions {
                    trim: false,
                    tol_mm: tol,
                },
            )
            .unwrap();
        assert!(o.as_spline().is_some() && o.closed);
        let r = o.resample(o.length() / 500.0, None).unwrap();
        let mut worst: f64 = 0.0;
        for smp in &r.samples {
            worst = worst.max((distance_to_spline(sp, smp.point) - d.abs()).abs());
        }
        assert!(worst <= tol, "d {d} tol {tol}: {worst}");
        // Outward grows, inward shrinks; the offset starts beside the source start.
        assert_eq!(o.signed_area() > src.signed_area(), d > 0.0);
        assert!(((o.start() - src.start()).norm() - d.abs()).abs() < tol);
    }
    // Open spline: positive d moves it to the left of travel.
    let open = Profile::interpolate(&measured(), false).unwrap();
    let o = open.offset(1.0).unwrap();
    let f = open.frame_at(0.0);
    assert!((o.start() - (f.point + f.left)).norm() < 1e-3);
    let osp = open.as_spline().unwrap();
    let r = o.resample(0.1, None).unwrap();
    for smp in &r.samples {
        assert!((distance_to_spline(osp, smp.point) - 1.0).abs() <= 1e-3);
    }
}

#[test]
fn fold_over_on_a_concave_spline_reports_the_region_and_radius() {
    // Peanut r(θ) = 20 + 8 cos 2θ: concave around θ = ±90°, where the exact polar curve has
    // radius of curvature (r² + r'²)^{3/2} / |r² + 2r'² − r r''| = 1728 / 240 = 7.2 mm.
    let src = Profile::interpolate(&polar(720, 20.0, 8.0, 2.0), true).unwrap();
    let d = 8.0; // outward: the concave side
    let regions = src.fold_over_regions(d);
    assert_eq!(regions.len(), 2, "{regions:?}");
    let left = src.left_offset(d);
    assert_eq!(left, -8.0); // counter-clockwise: outward is to the right
    for reg in &regions {
        assert!((reg.min_radius - 7.2).abs() < 1e-3, "{}", reg.min_radius);
        // The ends are exactly where κ ℓ = 1, and inside κ ℓ > 1.
        for s in [reg.s_start, reg.s_end] {
            let k = src.curvature_at(s);
            assert!((k * left - 1.0).abs() < 1e-6, "κℓ at {s}: {}", k * left);
        }
        let mid = 0.5 * (reg.s_start + reg.s_end);
        assert!(src.curvature_at(mid) * left > 1.0);
        // The smallest radius sits at θ = ±90° (at s = L/4 or 3L/4 by symmetry).
        let quarter = src.length() / 4.0;
        let near = [quarter, 3.0 * quarter]
            .iter()
            .map(|q| (reg.s_min - q).abs())
            .fold(f64::INFINITY, f64::min);
        assert!(near < 1e-3, "s_min {}", reg.s_min);
        assert!((1.0 / src.curvature_at(reg.s_min).abs() - reg.min_radius).abs() < 1e-6);
    }
    // A dense independent scan finds no fold outside the regions.
    for k in 0..20_000 {
        let s = src.length() * k as f64 / 20_000.0;
        let inside = regions
            .iter()
            .any(|r| s >= r.s_start - 1e-9 && s <= r.s_end + 1e-9);
        assert_eq!(src.curvature_at(s) * left >= 1.0, inside, "s = {s}");
    }
    match src.offset(d) {
        Err(GeomError::FoldOver {
            radius,
            distance,
            s_start,
            s_end,
            spline,
            ..
        }) => {
            assert!(spline);
            assert_eq!(distance, d);
            assert_eq!((s_start, s_end), (regions[0].s_start, regions[0].s_end));
            assert_eq!(radius, regions[0].min_radius);
        }
        other => panic!("expected a fold-over, got {other:?}"),
    }
    let msg = src.offset(d).unwrap_err().to_string();
    assert!(msg.contains("7.199") && msg.contains("along it"), "{msg}");
    // Below the smallest radius the offset exists; inward is convex-side here only partly.
    assert!(src.offset(7.0).is_ok());
    // The trimmed offset is asked for explicitly: clean, every point at least d away.
    let t = src
        .offset_with(
            d,
            &OffsetOptions {
                trim: true,
                tol_mm: 1e-3,
            },
        )
        .unwrap();
    let sp = src.as_spline().unwrap();
    let r = t.resample(t.length() / 400.0, None).unwrap();
    for smp in &r.samples {
        assert!(distance_to_spline(sp, smp.point) >= d - 1e-3);
    }
}

#[test]
fn line_arc_fold_over_keeps_its_segment_and_adds_the_range() {
    let c = Profile::circle(V2::new(5.0, 0.0), 3.0, 0.0, true).unwrap();
    match c.offset(-3.5).unwrap_err() {
        GeomError::FoldOver {
            segment,
            radius,
            s_start,
            s_end,
            spline,
            ..
        } => {
            assert_eq!((segment, radius, spline), (0, 3.0, false));
            assert_eq!(s_start, 0.0);
            assert!((s_end - TAU * 3.0).abs() < 1e-12);
        }
        e => panic!("{e:?}"),
    }
    // Trimmed: an inward offset past the radius vanishes instead.
    let t = c.offset_with(
        -3.5,
        &OffsetOptions {
            trim: true,
            tol_mm: 1e-3,
        },
    );
    assert!(matches!(t, Err(GeomError::Split { loops: 0 })));
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let nan = V2::new(f64::NAN, 0.0);
    assert!(Spline::interpolate(&[V2::zeros(), nan, V2::new(1.0, 1.0)], false).is_err());
    assert!(Spline::interpolate(&[], false).is_err());
    assert!(Spline::interpolate(&[V2::zeros()], false).is_err());
    assert!(Spline::interpolate(&[V2::zeros(), V2::new(1.0, 0.0)], true).is_err());
    let dup = [
        V2::zeros(),
        V2::new(1.0, 0.0),
        V2::new(1.0, 0.0),
        V2::new(2.0, 1.0),
    ];
    assert!(matches!(
        Spline::interpolate(&dup, false),
        Err(GeomError::Degenerate(_))
    ));
    assert!(Profile::polyline(&[V2::zeros(), nan], false).is_err());
    assert!(Profile::arc(V2::zeros(), f64::NAN, 0.0, 1.0, true).is_err());
    let p = Profile::interpolate(&measured(), false).unwrap();
    assert!(p.resample(0.0, None).is_err());
    assert!(p.resample(f64::NAN, None).is_err());
    assert!(p.resample(1.0, Some(-1.0)).is_err());
    assert!(p.offset(f64::NAN).is_err());
    assert!(p.to_line_arc(0.0).is_err());
    // Queries clamp NaN and out-of-range arc lengths instead of panicking.
    let _ = p.frame_at(f64::NAN);
    let _ = p.frame_at(-5.0);
    let _ = p.frame_at(1e9);
    let _ = p.frame_at_param(f64::INFINITY);
    // Two points make a straight open spline.
    let two = Profile::interpolate(&[V2::zeros(), V2::new(3.0, 4.0)], false).unwrap();
    assert!((two.length() - 5.0).abs() < 1e-12);
    assert_eq!(two.curvature_at(2.0), 0.0);
}

#[test]
fn rigid_motions_and_reversal_keep_the_spline_exact() {
    let p = Profile::interpolate(&polar(30, 25.0, 3.0, 4.0), true).unwrap();
    let m = p.transformed(0.7, V2::new(3.0, -2.0));
    assert!((m.length() - p.length()).abs() < 1e-9);
    assert!((m.signed_area() - p.signed_area()).abs() < 1e-9);
    let rot = nalgebra::Rotation2::new(0.7);
    for k in 0..10 {
        let s = p.length() * k as f64 / 10.0;
        assert!((m.point_at(s) - (rot * p.point_at(s) + V2::new(3.0, -2.0))).norm() < 1e-9);
        assert!((m.curvature_at(s) - p.curvature_at(s)).abs() < 1e-9);
    }
    let r = p.reversed();
    assert!((r.signed_area() + p.signed_area()).abs() < 1e-9);
    for k in 0..10 {
        let s = p.length() * k as f64 / 10.0;
        assert!((r.point_at(p.length() - s) - p.point_at(s)).norm() < 1e-9);
        assert!((r.curvature_at(p.length() - s) + p.curvature_at(s)).abs() < 1e-9);
    }
}

/// A bow-tie crosses itself at its waist: `crossing` finds the point, and offsetting refuses
/// it there instead of tracing one lobe. A rectangle, a circle and a rounded offset of the
/// rectangle (neighbouring segments meet at every joint) do not cross.
#[test]
fn a_crossing_closed_profile_is_found_and_not_offset() {
    let pts = |v: &[(f64, f64)]| v.iter().map(|&(x, y)| V2::new(x, y)).collect::<Vec<_>>();
    let tie = Profile::polyline(
        &pts(&[(0.0, 0.0), (10.0, 10.0), (10.0, 0.0), (0.0, 10.0)]),
        true,
    )
    .unwrap();
    let near = tie.crossing().expect("a bow-tie crosses itself");
    assert!((near - V2::new(5.0, 5.0)).norm() < 1e-9, "{near:?}");
    match tie.offset(1.0) {
        Err(GeomError::Crosses { near }) => assert!((near - V2::new(5.0, 5.0)).norm() < 1e-9),
        other => panic!("expected a crossing, got {other:?}"),
    }
    let rect = Profile::polyline(
        &pts(&[(0.0, 0.0), (10.0, 0.0), (10.0, 5.0), (0.0, 5.0)]),
        true,
    )
    .unwrap();
    assert_eq!(rect.crossing(), None);
    assert_eq!(rect.offset(1.0).unwrap().crossing(), None);
    let circle = Profile::circle(V2::new(0.0, 0.0), 3.0, 0.0, true).unwrap();
    assert_eq!(circle.crossing(), None);
}
