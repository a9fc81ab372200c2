//! Disc cam profiles for seed 1 (PROCESS.md §1, cam hardening): from a lift table (follower
//! lift against cam angle, CSV) or from standard motion laws over rise / dwell / return
//! segments, for a radial translating knife-edge follower: `r(θ) = r_base + lift(θ)`.
//!
//! Convention: the profile point at polar angle θ (counter-clockwise from +X, about the cam
//! center at the origin) has radius `r_base + lift(θ)`, θ being the cam angle of the table or
//! the motion program; the profile runs counter-clockwise. A cam from a motion program is
//! built from the law itself: cubic Hermite spans between dense knots placed also at every
//! segment boundary, each span exact in point and slope at its ends, and the exact one-sided
//! curvature kept at every knot — a law whose acceleration jumps (harmonic) keeps its
//! curvature jump where it is instead of having it smoothed over neighbouring samples, and
//! the fold-over rule reads the law's own radius (`cam_curvature`). A cam from a lift table
//! has no law: it is the closed cubic B-spline (PROCESS.md §2 step 1, cyclic system) through
//! the table's rows.
//!
//! Motion laws are given dimensionless on u ∈ [0, 1]: s(0) = 0, s(1) = 1, with velocity s'(u)
//! and acceleration s''(u) in closed form.

use super::import::ImportError;
use super::{GeomError, Profile, Spline, V2};
use std::f64::consts::{PI, TAU};

/// A standard cam motion law.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CamLaw {
    /// Simple harmonic: s = (1 − cos πu)/2; peak velocity π/2, acceleration jumps at the ends.
    Harmonic,
    /// Cycloidal: s = u − sin(2πu)/(2π); peak velocity 2, peak acceleration 2π.
    Cycloidal,
    /// 3-4-5 polynomial: s = 10u³ − 15u⁴ + 6u⁵; peak velocity 1.875, acceleration 10/√3.
    Poly345,
    /// Modified trapezoid (sine ramps of width 1/8 around constant acceleration); peak
    /// acceleration 8π/(2 + π) ≈ 4.888, peak velocity 2.
    ModifiedTrapezoid,
}

/// Peak acceleration of the modified trapezoid: fixed by s(1) = 1.
const MT_A: f64 = 8.0 * PI / (2.0 + PI);

impl CamLaw {
    /// (s, s', s'') at u ∈ [0, 1] (clamped).
    pub fn eval(self, u: f64) -> (f64, f64, f64) {
        let u = if u.is_nan() { 0.0 } else { u.clamp(0.0, 1.0) };
        match self {
            CamLaw::Harmonic => (
                0.5 * (1.0 - (PI * u).cos()),
                0.5 * PI * (PI * u).sin(),
                0.5 * PI * PI * (PI * u).cos(),
            ),
            CamLaw::Cycloidal => (
                u - (TAU * u).sin() / TAU,
                1.0 - (TAU * u).cos(),
                TAU * (TAU * u).sin(),
            ),
            CamLaw::Poly345 => {
                let u2 = u * u;
                let u3 = u2 * u;
                (
                    u3 * (10.0 - 15.0 * u + 6.0 * u2),
                    30.0 * u2 * (1.0 - 2.0 * u + u2),
                    60.0 * u - 180.0 * u2 + 120.0 * u3,
                )
            }
            CamLaw::ModifiedTrapezoid => {
                // The law is antisymmetric about u = 1/2: s(1 − u) = 1 − s(u).
                if u <= 0.5 {
                    mt_half(u)
                } else {
                    let (s, v, a) = mt_half(1.0 - u);
                    (1.0 - s, v, -a)
                }
            }
        }
    }

    pub fn s(self, u: f64) -> f64 {
        self.eval(u).0
    }

    pub fn v(self, u: f64) -> f64 {
        self.eval(u).1
    }

    pub fn a(self, u: f64) -> f64 {
        self.eval(u).2
    }
}

/// Modified trapezoid on [0, 1/2]: a = A sin 4πu up to 1/8, A up to 3/8, A cos 4π(u − 3/8)
/// to 1/2; velocity and lift are its integrals.
fn mt_half(u: f64) -> (f64, f64, f64) {
    let a = MT_A;
    let w4 = 4.0 * PI;
    if u <= 0.125 {
        (
            a / w4 * (u - (w4 * u).sin() / w4),
            a * (1.0 - (w4 * u).cos()) / w4,
            a * (w4 * u).sin(),
        )
    } else if u <= 0.375 {
        let w = u - 0.125;
        let s1 = a / w4 * (0.125 - 1.0 / w4);
        (s1 + a * w / w4 + 0.5 * a * w * w, a / w4 + a * w, a)
    } else {
        let w = u - 0.375;
        let s1 = a / w4 * (0.125 - 1.0 / w4);
        let s3 = s1 + a * 0.25 / w4 + a / 32.0;
        let v3 = a / w4 + 0.25 * a;
        (
            s3 + v3 * w + a * (1.0 - (w4 * w).cos()) / (w4 * w4),
            v3 + a * (w4 * w).sin() / w4,
            a * (w4 * w).cos(),
        )
    }
}

/// What a program segment does to the follower.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CamSegmentKind {
    Rise,
    Dwell,
    Return,
}

/// One segment of a cam motion program.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CamSegment {
    pub kind: CamSegmentKind,
    /// Ignored for dwells.
    pub law: CamLaw,
    pub duration_deg: f64,
    /// How far a rise lifts or a return lowers the follower, mm (ignored for dwells).
    pub lift_mm: f64,
}

/// Checks a motion program: positive finite durations summing to 360°, positive lifts, the
/// follower back at zero lift after the last segment and never below it.
pub fn check_program(segments: &[CamSegment]) -> Result<(), GeomError> {
    if segments.is_empty() {
        return Err(GeomError::Degenerate(
            "a cam program needs at least one segment".into(),
        ));
    }
    let mut total = 0.0;
    let mut lift = 0.0;
    for (i, seg) in segments.iter().enumerate() {
        if !(seg.duration_deg > 0.0 && seg.duration_deg.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "cam segment {} lasts {}°; durations must be positive",
                i + 1,
                seg.duration_deg
            )));
        }
        total += seg.duration_deg;
        match seg.kind {
            CamSegmentKind::Dwell => {}
            CamSegmentKind::Rise | CamSegmentKind::Return => {
                if !(seg.lift_mm > 0.0 && seg.lift_mm.is_finite()) {
                    return Err(GeomError::Degenerate(format!(
                        "cam segment {} has lift {} mm; a rise or return needs a positive lift",
                        i + 1,
                        seg.lift_mm
                    )));
                }
                lift += if seg.kind == CamSegmentKind::Rise {
                    seg.lift_mm
                } else {
                    -seg.lift_mm
                };
                if lift < -1e-9 {
                    return Err(GeomError::Degenerate(format!(
                        "cam segment {} returns the follower below the base circle",
                        i + 1
                    )));
                }
            }
        }
    }
    if (total - 360.0).abs() > 1e-6 {
        return Err(GeomError::Degenerate(format!(
            "the cam segments last {total}° in all; they must make one turn (360°)"
        )));
    }
    if lift.abs() > 1e-9 {
        return Err(GeomError::Degenerate(format!(
            "the cam program ends at lift {lift} mm; returns must undo the rises"
        )));
    }
    Ok(())
}

/// Follower lift (mm) and its first two derivatives with respect to the cam angle (per rad)
/// at `theta_deg`, for a checked program.
pub fn program_lift(segments: &[CamSegment], theta_deg: f64) -> (f64, f64, f64) {
    let th = if theta_deg.is_finite() {
        theta_deg.rem_euclid(360.0)
    } else {
        0.0
    };
    let mut start = 0.0;
    let mut base = 0.0;
    for seg in segments {
        let end = start + seg.duration_deg;
        let sign = match seg.kind {
            CamSegmentKind::Rise => 1.0,
            CamSegmentKind::Return => -1.0,
            CamSegmentKind::Dwell => 0.0,
        };
        if th < end || std::ptr::eq(seg, &segments[segments.len() - 1]) {
            let beta = seg.duration_deg.to_radians();
            let (s, v, a) = seg.law.eval((th - start) / seg.duration_deg);
            let h = sign * seg.lift_mm;
            return (base + h * s, h * v / beta, h * a / (beta * beta));
        }
        base += sign * seg.lift_mm;
        start = end;
    }
    (0.0, 0.0, 0.0)
}

/// [`program_lift`] on one side of `theta_deg`: at a segment boundary, `before` takes the
/// segment that ends there (its u = 1), otherwise the one that starts there; elsewhere both
/// sides agree. The lift and its slope are continuous for every law; the second derivative
/// jumps where the law's acceleration does (the harmonic law at both ends of a rise).
pub fn program_lift_sided(
    segments: &[CamSegment],
    theta_deg: f64,
    before: bool,
) -> (f64, f64, f64) {
    if before {
        let th = theta_deg.rem_euclid(360.0);
        let th = if th == 0.0 { 360.0 } else { th };
        let mut start = 0.0;
        let mut base = 0.0;
        for seg in segments {
            let end = start + seg.duration_deg;
            let sign = match seg.kind {
                CamSegmentKind::Rise => 1.0,
                CamSegmentKind::Return => -1.0,
                CamSegmentKind::Dwell => 0.0,
            };
            if th <= end {
                let beta = seg.duration_deg.to_radians();
                let (s, v, a) = seg.law.eval((th - start) / seg.duration_deg);
                let h = sign * seg.lift_mm;
                return (base + h * s, h * v / beta, h * a / (beta * beta));
            }
            base += sign * seg.lift_mm;
            start = end;
        }
    }
    program_lift(segments, theta_deg)
}

/// The exact signed curvature (1/mm, positive where the counter-clockwise contour turns left)
/// of the cam `r(θ) = base + lift(θ)` at `theta_deg`, on the side `before` says (see
/// [`program_lift_sided`]): κ = (r² + 2r′² − r·r″) / (r² + r′²)^{3/2}, the polar curve's
/// curvature with r′, r″ per radian. Negative κ is a concave stretch; 1/|κ| its radius.
pub fn cam_curvature(base: f64, segments: &[CamSegment], theta_deg: f64, before: bool) -> f64 {
    let (lift, d1, d2) = program_lift_sided(segments, theta_deg, before);
    let r = base + lift;
    (r * r + 2.0 * d1 * d1 - r * d2) / (r * r + d1 * d1).powf(1.5)
}

/// Closed spline through `(r(θ) cos θ, r(θ) sin θ)` for the given (θ rad, r mm) pairs.
fn polar_profile(points: &[(f64, f64)]) -> Result<Profile, GeomError> {
    if let Some((th, r)) = points.iter().find(|(_, r)| !(*r > 0.0 && r.is_finite())) {
        return Err(GeomError::Degenerate(format!(
            "the cam radius at {}° is {r} mm; it must be positive",
            th.to_degrees()
        )));
    }
    let pts: Vec<V2> = points
        .iter()
        .map(|&(th, r)| V2::new(th.cos(), th.sin()) * r)
        .collect();
    Ok(Profile::from_spline(Spline::interpolate(&pts, true)?))
}

impl Profile {
    /// A disc cam from a motion program: r(θ) = r_base + lift(θ) through knots every
    /// 360°/`samples` and at every segment boundary, exact there in point, slope and (one-sided)
    /// curvature, joined by cubic Hermite spans.
    pub fn cam(
        base_radius: f64,
        segments: &[CamSegment],
        samples: usize,
    ) -> Result<Profile, GeomError> {
        if !(base_radius > 0.0 && base_radius.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "a cam needs a positive base radius, got {base_radius} mm"
            )));
        }
        if !(8..=10_000_000).contains(&samples) {
            return Err(GeomError::Degenerate(format!(
                "a cam needs between 8 and 10 000 000 samples, got {samples}"
            )));
        }
        check_program(segments)?;
        // Knots every 360°/samples and at every segment boundary, where the law's acceleration
        // may jump (issue 13 item 5): each Hermite span takes exact points, slopes and
        // curvatures at its two ends only, so nothing is smoothed across a jump, and the span
        // between two knots a quarter degree apart follows the law to well under a nanometre.
        let mut knots: Vec<f64> = (0..samples)
            .map(|i| 360.0 * i as f64 / samples as f64)
            .collect();
        let mut at = 0.0;
        for seg in segments {
            knots.push(at);
            at += seg.duration_deg;
        }
        knots.sort_by(f64::total_cmp);
        knots.dedup_by(|b, a| (*b - *a).abs() < 1e-9);
        knots.push(360.0);
        let mut points = Vec::with_capacity(knots.len());
        let mut slopes = Vec::with_capacity(knots.len());
        let mut kappa = Vec::with_capacity(knots.len());
        for &deg in &knots {
            let (lift, d1, _) = program_lift(segments, deg);
            let th = deg.to_radians();
            let r = base_radius + lift;
            if !(r > 0.0 && r.is_finite()) {
                return Err(GeomError::Degenerate(format!(
                    "the cam radius at {deg}° is {r} mm; it must be positive"
                )));
            }
            let (radial, across) = (V2::new(th.cos(), th.sin()), V2::new(-th.sin(), th.cos()));
            points.push(radial * r);
            slopes.push(radial * d1 + across * r);
            kappa.push([
                cam_curvature(base_radius, segments, deg, true),
                cam_curvature(base_radius, segments, deg, false),
            ]);
        }
        // The closing knot is the first one: the same point, exactly.
        let last = points.len() - 1;
        points[last] = points[0];
        slopes[last] = slopes[0];
        let rad: Vec<f64> = knots.iter().map(|d| d.to_radians()).collect();
        Ok(Profile::from_spline(Spline::hermite(
            &rad, &points, &slopes, &kappa, true,
        )?))
    }

    /// A disc cam through a lift table: (cam angle °, lift mm) pairs, angles increasing within
    /// one turn; a closing row at 360° equal to the 0° row is dropped.
    pub fn cam_from_lifts(base_radius: f64, table: &[(f64, f64)]) -> Result<Profile, GeomError> {
        if !(base_radius > 0.0 && base_radius.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "a cam needs a positive base radius, got {base_radius} mm"
            )));
        }
        let mut rows = table.to_vec();
        if rows.len() > 1 {
            let (a0, l0) = rows[0];
            let (an, ln) = rows[rows.len() - 1];
            if (an - a0 - 360.0).abs() < 1e-9 && (ln - l0).abs() < 1e-9 {
                rows.pop();
            }
        }
        if rows.len() < 3 {
            return Err(GeomError::TooFewPoints(rows.len()));
        }
        for (i, w) in rows.windows(2).enumerate() {
            if !(w[1].0 > w[0].0) {
                return Err(GeomError::Degenerate(format!(
                    "lift table rows {} and {}: angles must increase",
                    i + 1,
                    i + 2
                )));
            }
        }
        if !(rows[rows.len() - 1].0 - rows[0].0 < 360.0) {
            return Err(GeomError::Degenerate(
                "the lift table spans more than one turn".into(),
            ));
        }
        let pts: Vec<(f64, f64)> = rows
            .iter()
            .map(|&(deg, lift)| (deg.to_radians(), base_radius + lift))
            .collect();
        polar_profile(&pts)
    }

    /// A disc cam from lift-table CSV text (`angle_deg,lift_mm`; see `parse_lift_table`).
    pub fn cam_from_lift_csv(base_radius: f64, csv: &str) -> Result<Profile, ImportError> {
        let rows = parse_lift_table(csv)?;
        Profile::cam_from_lifts(base_radius, &rows).map_err(|e| ImportError::new(e.to_string()))
    }
}

/// Parses a lift table: one `angle_deg,lift_mm` row a line (comma, semicolon, tab or spaces
/// between), an optional header line, blank lines and `#` comments ignored.
pub fn parse_lift_table(text: &str) -> Result<Vec<(f64, f64)>, ImportError> {
    let mut rows = Vec::new();
    let mut offset = 0;
    let mut seen_data = false;
    for (i, raw) in text.split_inclusive('\n').enumerate() {
        let line_start = offset;
        offset += raw.len();
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line
            .split([',', ';', '\t', ' '])
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .collect();
        let nums: Vec<Option<f64>> = fields.iter().map(|f| f.parse::<f64>().ok()).collect();
        let numeric = nums.len() >= 2 && nums[0].is_some() && nums[1].is_some();
        if !numeric {
            if !seen_data && nums.iter().all(Option::is_none) {
                // A header such as `angle_deg,lift_mm`.
                seen_data = true;
                continue;
            }
            return Err(ImportError::at(
                format!(
                    "lift table line {}: expected `angle_deg,lift_mm`, found `{line}`",
                    i + 1
                ),
                i + 1,
                line_start,
            ));
        }
        seen_data = true;
        let (a, l) = (nums[0].unwrap_or(0.0), nums[1].unwrap_or(0.0));
        if !(a.is_finite() && l.is_finite()) {
            return Err(ImportError::at(
                format!("lift table line {}: numbers must be finite", i + 1),
                i + 1,
                line_start,
            ));
        }
        rows.push((a, l));
    }
    if rows.is_empty() {
        return Err(ImportError::new("the lift table has no rows".into()));
    }
    Ok(rows)
}
