//! Geometry: cam motion laws against their closed forms, cam profiles (PROCESS.md §1) from
//! programs and lift tables, and DXF / SVG import round trips on small inline fixtures.

use lase_runtime::geometry::cam::{parse_lift_table, program_lift};
use lase_runtime::geometry::import::{dxf_profiles, svg_path_profiles};
use lase_runtime::geometry::{CamLaw, CamSegment, CamSegmentKind, ImportOptions, Profile, Seg, V2};
use std::f64::consts::{PI, TAU};

const LAWS: [CamLaw; 4] = [
    CamLaw::Harmonic,
    CamLaw::Cycloidal,
    CamLaw::Poly345,
    CamLaw::ModifiedTrapezoid,
];

fn peak(f: impl Fn(f64) -> f64) -> (f64, f64) {
    (0..=100_000)
        .map(|i| i as f64 / 100_000.0)
        .map(|u| (u, f(u)))
        .fold(
            (0.0, f64::NEG_INFINITY),
            |a, b| if b.1 > a.1 { b } else { a },
        )
}

#[test]
fn motion_laws_match_their_closed_forms() {
    for law in LAWS {
        let (s0, v0, _) = law.eval(0.0);
        let (s1, v1, _) = law.eval(1.0);
        assert!(s0.abs() < 1e-15 && (s1 - 1.0).abs() < 1e-12, "{law:?}");
        assert!(v0.abs() < 1e-12 && v1.abs() < 1e-12, "{law:?}");
        // v = ds/du and a = dv/du (central differences), everywhere inside.
        let h = 1e-6;
        for i in 1..200 {
            let u = i as f64 / 200.0;
            let dv = (law.s(u + h) - law.s(u - h)) / (2.0 * h);
            let da = (law.v(u + h) - law.v(u - h)) / (2.0 * h);
            assert!((dv - law.v(u)).abs() < 1e-7, "{law:?} v at {u}");
            assert!((da - law.a(u)).abs() < 1e-6, "{law:?} a at {u}");
        }
        // Symmetric rise: s(1 − u) = 1 − s(u).
        for i in 0..=20 {
            let u = i as f64 / 20.0;
            assert!((law.s(1.0 - u) - (1.0 - law.s(u))).abs() < 1e-12);
        }
    }
    // Acceleration at the ends: zero except for the harmonic law (π²/2 jump).
    assert!((CamLaw::Harmonic.a(0.0) - PI * PI / 2.0).abs() < 1e-12);
    assert!((CamLaw::Harmonic.a(1.0) + PI * PI / 2.0).abs() < 1e-12);
    for law in [
        CamLaw::Cycloidal,
        CamLaw::Poly345,
        CamLaw::ModifiedTrapezoid,
    ] {
        assert!(
            law.a(0.0).abs() < 1e-12 && law.a(1.0).abs() < 1e-12,
            "{law:?}"
        );
    }
    // Known peaks.
    let (u, v) = peak(|u| CamLaw::Harmonic.v(u));
    assert!((v - PI / 2.0).abs() < 1e-12 && (u - 0.5).abs() < 1e-12);
    let (u, a) = peak(|u| CamLaw::Cycloidal.a(u));
    assert!((a - TAU).abs() < 1e-12 && (u - 0.25).abs() < 1e-12);
    assert!((peak(|u| CamLaw::Cycloidal.v(u)).1 - 2.0).abs() < 1e-12);
    let (u, v) = peak(|u| CamLaw::Poly345.v(u));
    assert!((v - 1.875).abs() < 1e-12 && (u - 0.5).abs() < 1e-12);
    assert!((peak(|u| CamLaw::Poly345.a(u)).1 - 10.0 / 3f64.sqrt()).abs() < 1e-8);
    let (_, a) = peak(|u| CamLaw::ModifiedTrapezoid.a(u));
    assert!((a - 4.888).abs() < 1e-3, "{a}");
    assert!((a - 8.0 * PI / (2.0 + PI)).abs() < 1e-12);
    assert!((peak(|u| CamLaw::ModifiedTrapezoid.v(u)).1 - 2.0).abs() < 1e-12);
    // The modified trapezoid's pieces join continuously.
    for b in [0.125, 0.375, 0.625, 0.875] {
        for f in [CamLaw::s, CamLaw::v, CamLaw::a] {
            let l = f(CamLaw::ModifiedTrapezoid, b - 1e-12);
            let r = f(CamLaw::ModifiedTrapezoid, b + 1e-12);
            assert!((l - r).abs() < 1e-9, "join at {b}");
        }
    }
}

fn program() -> Vec<CamSegment> {
    let seg = |kind, duration_deg, lift_mm| CamSegment {
        kind,
        law: CamLaw::Cycloidal,
        duration_deg,
        lift_mm,
    };
    vec![
        seg(CamSegmentKind::Rise, 120.0, 10.0),
        seg(CamSegmentKind::Dwell, 60.0, 0.0),
        seg(CamSegmentKind::Return, 120.0, 10.0),
        seg(CamSegmentKind::Dwell, 60.0, 0.0),
    ]
}

#[test]
fn cam_from_motion_program_follows_r_base_plus_lift() {
    let prog = program();
    assert_eq!(program_lift(&prog, 0.0).0, 0.0);
    assert!((program_lift(&prog, 60.0).0 - 5.0).abs() < 1e-12);
    assert!((program_lift(&prog, 150.0).0 - 10.0).abs() < 1e-12);
    // Lift velocity per rad at mid-rise: h · s'(1/2) / β = 10 · 2 / (2π/3).
    assert!((program_lift(&prog, 60.0).1 - 20.0 / (TAU / 3.0)).abs() < 1e-9);
    let cam = Profile::cam(30.0, &prog, 720).unwrap();
    assert!(cam.closed && cam.signed_area() > 0.0);
    let sp = cam.as_spline().unwrap();
    // Through the sampled points exactly, and close to r(θ) everywhere between.
    for j in 0..sp.span_count() {
        let th = TAU * j as f64 / 720.0;
        let p = sp.derivs(j as f64).0;
        let r = 30.0 + program_lift(&prog, th.to_degrees()).0;
        assert!((p - V2::new(th.cos(), th.sin()) * r).norm() < 1e-9);
        let mid = sp.derivs(j as f64 + 0.5).0;
        let thm = mid.y.atan2(mid.x);
        let rm = 30.0 + program_lift(&prog, thm.to_degrees()).0;
        assert!((mid.norm() - rm).abs() < 1e-5, "between samples at {thm}");
    }
    // Base circle dwell (300°–360°): curvature 1/30 in its middle.
    let s = cam.length_at_param(330.0 / 360.0 * 720.0);
    assert!((cam.curvature_at(s) - 1.0 / 30.0).abs() < 1e-6);
    // Programs that do not close or make one turn are refused.
    let mut bad = prog.clone();
    bad[2].lift_mm = 9.0;
    assert!(Profile::cam(30.0, &bad, 720).is_err());
    let mut bad = prog.clone();
    bad[3].duration_deg = 50.0;
    assert!(Profile::cam(30.0, &bad, 720).is_err());
    assert!(Profile::cam(f64::NAN, &prog, 720).is_err());
    assert!(Profile::cam(30.0, &[], 720).is_err());
    assert!(Profile::cam(30.0, &prog, 3).is_err());
}

#[test]
fn cam_from_lift_table_csv() {
    let mut csv = String::from("angle_deg,lift_mm\n# measured\n");
    for i in 0..36 {
        let deg = i as f64 * 10.0;
        let lift = program_lift(&program(), deg).0;
        csv.push_str(&format!("{deg}, {lift}\n"));
    }
    csv.push_str("360,0\n");
    let rows = parse_lift_table(&csv).unwrap();
    assert_eq!(rows.len(), 37);
    let cam = Profile::cam_from_lift_csv(30.0, &csv).unwrap();
    let sp = cam.as_spline().unwrap();
    assert_eq!(sp.span_count(), 36);
    for (j, (deg, lift)) in rows.iter().take(36).enumerate() {
        let p = sp.derivs(j as f64).0;
        let th = deg.to_radians();
        assert!((p - V2::new(th.cos(), th.sin()) * (30.0 + lift)).norm() < 1e-9);
    }
    let err = parse_lift_table("angle,lift\n0,0\n10,abc\n").unwrap_err();
    assert_eq!(err.line, Some(3));
    assert_eq!(err.offset, Some(15));
    assert!(parse_lift_table("").is_err());
    assert!(Profile::cam_from_lift_csv(30.0, "0,0\n10,1\n5,1\n").is_err());
    assert!(Profile::cam_from_lift_csv(30.0, "0,0\n10,nan\n20,1\n").is_err());
}

// ---------------------------------------------------------------------------------------------
// DXF

/// Writes a line/arc profile as DXF entities (the test's own writer, for round trips).
fn to_dxf(p: &Profile) -> String {
    let mut s = String::from("0\nSECTION\n2\nENTITIES\n");
    for seg in &p.segs {
        match seg {
            Seg::Line { a, b } => s.push_str(&format!(
                "0\nLINE\n8\n0\n10\n{}\n20\n{}\n30\n0\n11\n{}\n21\n{}\n31\n0\n",
                a.x, a.y, b.x, b.y
            )),
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => {
                // DXF arcs run counter-clockwise.
                let (st, en) = if *sweep > 0.0 {
                    (*a0, a0 + sweep)
                } else {
                    (a0 + sweep, *a0)
                };
                s.push_str(&format!(
                    "0\nARC\n8\n0\n10\n{}\n20\n{}\n30\n0\n40\n{}\n50\n{}\n51\n{}\n",
                    center.x,
                    center.y,
                    r,
                    st.to_degrees(),
                    en.to_degrees()
                ));
            }
        }
    }
    s.push_str("0\nENDSEC\n0\nEOF\n");
    s
}

/// A 20 mm square with its (20, 20) corner rounded to 5 mm, counter-clockwise.
fn rounded_square() -> Profile {
    let mut segs = vec![
        Seg::Line {
            a: V2::new(0.0, 0.0),
            b: V2::new(20.0, 0.0),
        },
        Seg::Line {
            a: V2::new(20.0, 0.0),
            b: V2::new(20.0, 15.0),
        },
    ];
    segs.push(Seg::Arc {
        center: V2::new(15.0, 15.0),
        r: 5.0,
        a0: 0.0,
        sweep: PI / 2.0,
    });
    segs.push(Seg::Line {
        a: V2::new(15.0, 20.0),
        b: V2::new(0.0, 20.0),
    });
    segs.push(Seg::Line {
        a: V2::new(0.0, 20.0),
        b: V2::new(0.0, 0.0),
    });
    Profile::from_segs(segs, true)
}

fn same_shape(a: &Profile, b: &Profile, tol: f64) {
    assert!(
        (a.length() - b.length()).abs() < tol,
        "{} vs {}",
        a.length(),
        b.length()
    );
    assert!(
        (a.signed_area().abs() - b.signed_area().abs()).abs() < tol * a.length(),
        "{} vs {}",
        a.signed_area(),
        b.signed_area()
    );
    for k in 0..200 {
        let p = a.point_at(a.length() * k as f64 / 200.0);
        let d = b
            .segs
            .iter()
            .map(|s| s.distance_to(p))
            .fold(f64::INFINITY, f64::min);
        assert!(d < tol, "{p:?} is {d} away");
    }
}

#[test]
fn dxf_round_trip_of_a_rounded_square_and_a_circle() {
    let sq = rounded_square();
    assert!((sq.length() - (70.0 + PI * 2.5)).abs() < 1e-12);
    let text = to_dxf(&sq);
    let got = dxf_profiles(&text, &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 1);
    assert!(got[0].closed);
    assert_eq!(got[0].segs.len(), 5);
    same_shape(&sq, &got[0], 1e-9);
    assert!((got[0].signed_area() - (400.0 - 25.0 + PI * 25.0 / 4.0)).abs() < 1e-9);

    // Entities shuffled and one reversed still chain into one closed profile.
    let mut shuffled = sq.clone();
    shuffled.segs.swap(0, 3);
    shuffled.segs[1] = shuffled.segs[1].reversed();
    let got = dxf_profiles(&to_dxf(&shuffled), &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 1);
    assert!(got[0].closed);
    same_shape(&sq, &got[0], 1e-9);

    // CIRCLE, and the same rounded square as one LWPOLYLINE with a bulge.
    let b = (PI / 8.0).tan();
    let text = format!(
        "0\nSECTION\n2\nENTITIES\n\
         0\nCIRCLE\n8\n0\n10\n50\n20\n0\n30\n0\n40\n7.5\n\
         0\nLWPOLYLINE\n8\n0\n90\n5\n70\n1\n\
         10\n0\n20\n0\n10\n20\n20\n0\n10\n20\n20\n15\n42\n{b}\n10\n15\n20\n20\n10\n0\n20\n20\n\
         0\nENDSEC\n0\nEOF\n"
    );
    let got = dxf_profiles(&text, &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 2);
    assert!(got[0].closed && (got[0].length() - TAU * 7.5).abs() < 1e-12);
    assert!((got[0].point_at(0.0) - V2::new(57.5, 0.0)).norm() < 1e-12);
    assert!(got[1].closed);
    same_shape(&sq, &got[1], 1e-9);
    // Circle round trip.
    let c = Profile::circle(V2::new(3.0, 4.0), 6.0, 0.0, true).unwrap();
    let got = dxf_profiles(&to_dxf(&c), &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 1);
    assert!(got[0].closed);
    same_shape(&c, &got[0], 1e-9);
}

#[test]
fn dxf_splines_rational_and_fit_points() {
    // A full circle of radius 10 as a rational quadratic NURBS (9 control points).
    let w = std::f64::consts::FRAC_1_SQRT_2;
    let cps = [
        (10.0, 0.0, 1.0),
        (10.0, 10.0, w),
        (0.0, 10.0, 1.0),
        (-10.0, 10.0, w),
        (-10.0, 0.0, 1.0),
        (-10.0, -10.0, w),
        (0.0, -10.0, 1.0),
        (10.0, -10.0, w),
        (10.0, 0.0, 1.0),
    ];
    let knots = [
        0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
    ];
    let mut t =
        String::from("0\nSECTION\n2\nENTITIES\n0\nSPLINE\n8\n0\n70\n5\n71\n2\n72\n12\n73\n9\n");
    for k in knots {
        t.push_str(&format!("40\n{k}\n"));
    }
    for (_, _, wt) in cps {
        t.push_str(&format!("41\n{wt}\n"));
    }
    for (x, y, _) in cps {
        t.push_str(&format!("10\n{x}\n20\n{y}\n30\n0\n"));
    }
    t.push_str("0\nENDSEC\n0\nEOF\n");
    let got = dxf_profiles(&t, &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 1);
    assert!(got[0].closed);
    assert!(
        (got[0].length() - TAU * 10.0).abs() < 1e-2,
        "{}",
        got[0].length()
    );
    for k in 0..500 {
        let p = got[0].point_at(got[0].length() * k as f64 / 500.0);
        assert!((p.norm() - 10.0).abs() <= 1e-3, "{p:?}");
    }
    // Fit points only: the seed-2 interpolation through them.
    let t = "0\nSECTION\n2\nENTITIES\n0\nSPLINE\n8\n0\n70\n8\n71\n3\n74\n4\n\
             11\n0\n21\n0\n31\n0\n11\n10\n21\n5\n31\n0\n11\n20\n21\n0\n31\n0\n11\n30\n21\n5\n31\n0\n\
             0\nENDSEC\n0\nEOF\n";
    let got = dxf_profiles(t, &ImportOptions::default()).unwrap();
    assert_eq!(got.len(), 1);
    assert!(!got[0].closed);
    assert!((got[0].start() - V2::new(0.0, 0.0)).norm() < 1e-9);
    assert!((got[0].end() - V2::new(30.0, 5.0)).norm() < 1e-9);
}

#[test]
fn dxf_errors_point_at_the_bad_entity() {
    let t = "0\nSECTION\n2\nENTITIES\n\
             0\nLINE\n8\n0\n10\n0\n20\n0\n11\n1\n21\n0\n\
             0\nARC\n8\n0\n10\n0\n20\n0\n40\n0\n50\n0\n51\n90\n\
             0\nENDSEC\n0\nEOF\n";
    let e = dxf_profiles(t, &ImportOptions::default()).unwrap_err();
    assert!(e.message.contains("ARC #1"), "{}", e.message);
    assert_eq!(e.line, Some(17));
    assert_eq!(e.offset, Some(t.find("ARC").unwrap() - 2));
    // A number the DXF reader would skip silently is an error at its line.
    let t = "0\nSECTION\n2\nENTITIES\n0\nLINE\n10\nabc\n0\nENDSEC\n0\nEOF\n";
    let e = dxf_profiles(t, &ImportOptions::default()).unwrap_err();
    assert_eq!(
        (e.line, e.offset),
        (Some(8), Some(t.find("abc").unwrap())),
        "{e:?}"
    );
    // Structural errors come from the reader, with its line.
    let t = "0\nSECTION\n2\nENTITIES\n0\nLINE\nxx\n1\n0\nENDSEC\n0\nEOF\n";
    let e = dxf_profiles(t, &ImportOptions::default()).unwrap_err();
    assert_eq!(e.line, Some(8), "{e:?}");
    let e = dxf_profiles("garbage\n", &ImportOptions::default()).unwrap_err();
    assert_eq!(e.line, Some(1));
    assert!(
        dxf_profiles(
            "0\nSECTION\n2\nENTITIES\n0\nLINE\n10\n",
            &ImportOptions::default()
        )
        .is_err()
    );
    assert!(
        dxf_profiles("", &ImportOptions::default())
            .unwrap()
            .is_empty()
    );
}

// ---------------------------------------------------------------------------------------------
// SVG

#[test]
fn svg_round_trip_of_a_rounded_square_and_a_circle() {
    let sq = rounded_square();
    for d in [
        "M 0 0 H 20 V 15 A 5 5 0 0 1 15 20 H 0 Z",
        "m0,0 h20 v15 a5,5 0 0 1 -5,5 h-15 z",
        "M0 0L20 0L20 15A5 5 30 0 1 15 20L0 20z",
    ] {
        let got = svg_path_profiles(d, &ImportOptions::default()).unwrap();
        assert_eq!(got.len(), 1, "{d}");
        assert!(got[0].closed);
        assert_eq!(got[0].segs.len(), 5, "{d}");
        same_shape(&sq, &got[0], 1e-9);
        let arc = got[0]
            .segs
            .iter()
            .find(|s| matches!(s, Seg::Arc { .. }))
            .unwrap();
        assert!((arc.curvature() - 0.2).abs() < 1e-12);
    }
    // Circle from two SVG arcs; and a second subpath.
    let got = svg_path_profiles(
        "M 13 4 A 10 10 0 1 1 -7 4 A 10 10 0 1 1 13 4 Z M 50 50 l 10 0",
        &ImportOptions::default(),
    )
    .unwrap();
    assert_eq!(got.len(), 2);
    let c = Profile::circle(V2::new(3.0, 4.0), 10.0, 0.0, true).unwrap();
    same_shape(&c, &got[0], 1e-9);
    assert!(!got[1].closed && (got[1].length() - 10.0).abs() < 1e-12);
    // flip_y mirrors: the counter-clockwise square becomes clockwise.
    let got = svg_path_profiles(
        "M 0 0 H 20 V 15 A 5 5 0 0 1 15 20 H 0 Z",
        &ImportOptions {
            flip_y: true,
            ..ImportOptions::default()
        },
    )
    .unwrap();
    assert!((got[0].signed_area() + sq.signed_area()).abs() < 1e-9);
}

#[test]
fn svg_curves_become_biarcs_within_tolerance() {
    // Circle of radius 10 from four cubic Béziers (k = 0.5523): within 3e-3 of the circle,
    // and the biarcs within the tolerance of the Béziers themselves.
    let k = 10.0 * 0.552_284_749_8;
    let d = format!("M10,0 C10,{k} {k},10 0,10 S-10,{k} -10,0 S-{k},-10 0,-10 S10,-{k} 10,0 Z");
    for tol in [1e-2, 1e-3, 1e-4] {
        let got = svg_path_profiles(
            &d,
            &ImportOptions {
                tol_mm: tol,
                ..ImportOptions::default()
            },
        )
        .unwrap();
        assert_eq!(got.len(), 1);
        assert!(got[0].closed);
        let bez = |p: [V2; 4], t: f64| {
            let m = 1.0 - t;
            p[0] * m * m * m + p[1] * 3.0 * m * m * t + p[2] * 3.0 * m * t * t + p[3] * t * t * t
        };
        let q1 = [
            V2::new(10.0, 0.0),
            V2::new(10.0, k),
            V2::new(k, 10.0),
            V2::new(0.0, 10.0),
        ];
        for i in 0..=100 {
            let p = bez(q1, i as f64 / 100.0);
            let dist = got[0]
                .segs
                .iter()
                .map(|s| s.distance_to(p))
                .fold(f64::INFINITY, f64::min);
            assert!(dist <= tol, "tol {tol}: {dist}");
        }
        for s in 0..100 {
            let p = got[0].point_at(got[0].length() * s as f64 / 100.0);
            assert!((p.norm() - 10.0).abs() < 3e-3 + tol);
        }
    }
    // Quadratic with T reflection: a parabola-like arch; ends exact.
    let got = svg_path_profiles("M0 0 Q 5 10 10 0 T 20 0", &ImportOptions::default()).unwrap();
    assert!((got[0].end() - V2::new(20.0, 0.0)).norm() < 1e-12);
    let mid = got[0]
        .segs
        .iter()
        .map(|s| s.distance_to(V2::new(5.0, 5.0)))
        .fold(f64::INFINITY, f64::min);
    assert!(mid <= 1e-3);
    // Elliptical arc (rx ≠ ry, rotated): points on the ellipse within tolerance.
    let got = svg_path_profiles("M 10 0 A 10 5 0 0 1 -10 0", &ImportOptions::default()).unwrap();
    for s in 0..100 {
        let p = got[0].point_at(got[0].length() * s as f64 / 100.0);
        let e = (p.x / 10.0).powi(2) + (p.y / 5.0).powi(2) - 1.0;
        assert!(e.abs() < 1e-3, "{p:?}");
        assert!(p.y >= -1e-3);
    }
}

#[test]
fn svg_errors_give_the_offset() {
    let d = "M 0 0 L 10 10 L 5 x";
    let e = svg_path_profiles(d, &ImportOptions::default()).unwrap_err();
    let off = e.offset.expect("an offset");
    assert!(off >= d.find("5 x").unwrap() && off <= d.len(), "{e:?}");
    assert_eq!(e.line, Some(1));
    assert!(
        svg_path_profiles("", &ImportOptions::default())
            .unwrap()
            .is_empty()
    );
    assert!(svg_path_profiles("M 0 0 L 1e400 0", &ImportOptions::default()).is_err());
    assert!(
        svg_path_profiles("M 0 0 Z", &ImportOptions::default())
            .unwrap()
            .is_empty()
    );
}
