//! Cams from motion laws whose acceleration jumps (issue 13 item 5), measured against the law
//! in closed form: the profile follows the law (point and normal) with the curvature jump kept
//! at the breakpoint, and the fold-over rule reads the law's exact concave radius.
//!
//! The cam: base 20 mm, lift 10 mm, harmonic rise over 60°, top dwell 60°, harmonic return
//! over 60°, base dwell for the rest. At the start of the rise r = 20 mm, r′ = 0 and
//! r″ = 10·π²/(2·(π/3)²) = 45 mm/rad², so κ = (r² − r·r″)/r³ = −1/16: the contour is concave
//! there with a radius of exactly 16 mm, and just before it (the base dwell) convex with 20 mm.

use lase_runtime::geometry::toolpath::{Normals, ToolpathError, oriented_stations};
use lase_runtime::geometry::{CamLaw, CamSegment, CamSegmentKind, Profile, V2};

fn harmonic_cam() -> Profile {
    let seg = |kind, deg| CamSegment {
        kind,
        law: CamLaw::Harmonic,
        duration_deg: deg,
        lift_mm: 10.0,
    };
    Profile::cam(
        20.0,
        &[
            seg(CamSegmentKind::Rise, 60.0),
            seg(CamSegmentKind::Dwell, 60.0),
            seg(CamSegmentKind::Return, 60.0),
            seg(CamSegmentKind::Dwell, 180.0),
        ],
        1440,
    )
    .unwrap()
}

#[path = "support/harmonic_cam.rs"]
mod harmonic_cam;
use harmonic_cam::radius as law;

/// Every 0.01 mm of contour: the profile point lies on r(θ) of the law (radial error), and its
/// tangent is the law's, to well within any tolerance a recipe can set.
#[test]
fn harmonic_cam_follows_its_law_in_point_and_normal() {
    let cam = harmonic_cam();
    let len = cam.length();
    let n = (len / 0.01) as usize;
    let (mut worst_r, mut worst_angle) = (0.0f64, 0.0f64);
    for k in 0..=n {
        let f = cam.frame_at(len * k as f64 / n as f64);
        let theta = f.point.y.atan2(f.point.x);
        let (r, dr) = law(theta);
        worst_r = worst_r.max((f.point.norm() - r).abs());
        let t = V2::new(
            dr * theta.cos() - r * theta.sin(),
            dr * theta.sin() + r * theta.cos(),
        )
        .normalize();
        worst_angle = worst_angle.max((t.x * f.tangent.y - t.y * f.tangent.x).abs());
    }
    eprintln!(
        "harmonic cam against its law: radius {:.2e} mm, tangent {:.2e}°",
        worst_r,
        worst_angle.to_degrees()
    );
    assert!(worst_r < 1e-6, "{worst_r} mm");
    assert!(worst_angle.to_degrees() < 1e-5, "{worst_angle} rad");
}

/// The curvature jump at the start of the rise is kept at the breakpoint, on both sides exactly.
#[test]
fn the_curvature_jump_stays_at_the_breakpoint() {
    let cam = harmonic_cam();
    let knots: Vec<(f64, [f64; 2])> = cam.as_spline().unwrap().exact_knots().unwrap().collect();
    let (s, [before, after]) = knots[0];
    assert_eq!(s, 0.0);
    assert!((before - 1.0 / 20.0).abs() < 1e-12, "{before}");
    assert!((after + 1.0 / 16.0).abs() < 1e-12, "{after}");
    // Reversed, the same place is met from the other side with the sign of travel flipped.
    let rev = cam.reversed();
    let (_, [b, a]) = rev
        .as_spline()
        .unwrap()
        .exact_knots()
        .unwrap()
        .next()
        .unwrap();
    assert!((b - 1.0 / 16.0).abs() < 1e-12 && (a + 1.0 / 20.0).abs() < 1e-12);
}

/// The head outside: a standoff of 16.05 mm exceeds the law's 16.000 mm concave radius and is
/// refused with that exact radius (the B-spline through samples used to report 16.193 mm and
/// accept it); 15.95 mm is accepted.
#[test]
fn fold_over_reads_the_laws_exact_concave_radius() {
    let cam = harmonic_cam();
    let left = false; // counter-clockwise, head outside: on the right of travel
    let e = oriented_stations(&cam, 0.5, 5e-4, 16.05, left, Normals::Exact).unwrap_err();
    let ToolpathError::FoldOver { r_min, s_start, .. } = e else {
        panic!("{e:?}");
    };
    assert!((r_min - 16.0).abs() < 1e-9, "{r_min}");
    assert_eq!(s_start, 0.0);
    assert!(oriented_stations(&cam, 0.5, 5e-4, 15.95, left, Normals::Exact).is_ok());
}
