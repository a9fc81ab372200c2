//! Oriented toolpaths (PROCESS.md §1 and §2): a profile sampled into stations, each a spot on
//! the surface and the beam that reaches it from the head's side, for machines that orient
//! the beam.
//!
//! Two ways to take the normal, both here so they cannot drift apart:
//! * exact ([`Normals::Exact`]): the profile is resampled at a constant arc-length step with
//!   exact frames, and the beam runs back along the exact normal;
//! * chord ([`Normals::Chord`]): seed 1's discrete method, where the scan point is a chord's
//!   midpoint M and the normal the chord's perpendicular bisector ([`chord_stations`], which
//!   `CamXwb::seed1_steps` uses too).
//!
//! Before either, the fold-over rule: where the surface is concave seen from the head with a
//! radius of curvature at or below the standoff, the normals cross before they reach the lens,
//! so the lens path folds over (seed 2's offset rule, for the offset the head travels on) and
//! the head would have to jump. Plain geometry: no recipe, no spans, no units but mm.

use super::{GeomError, Profile, V2};

/// Where the head stands relative to a followed profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadSide {
    /// Outside a closed profile.
    Outside,
    /// Inside a closed profile.
    Inside,
    /// Left of the direction of travel.
    Left,
    /// Right of the direction of travel.
    Right,
}

impl HeadSide {
    /// Whether the head is on the left of travel along `profile`: a counter-clockwise closed
    /// profile has its outside on the right.
    pub fn on_left(self, profile: &Profile) -> bool {
        let ccw = profile.signed_area() > 0.0;
        match self {
            HeadSide::Left => true,
            HeadSide::Right => false,
            HeadSide::Outside => !ccw,
            HeadSide::Inside => ccw,
        }
    }
}

/// How the beam's direction is taken from the profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Normals {
    /// Along the exact surface normal at each sample.
    Exact,
    /// Along the perpendicular bisector of each chord between samples (seed 1).
    Chord,
}

/// One point of an oriented toolpath.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Station {
    /// Arc length along the path sampled (the profile, or the chord polyline), mm.
    pub s: f64,
    /// The spot on the surface, mm.
    pub point: V2,
    /// Unit beam direction, from the lens toward the spot (the head-side normal reversed).
    pub beam: V2,
}

/// Why an oriented toolpath cannot be built.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolpathError {
    /// The profile could not be resampled.
    Geometry(GeomError),
    /// The lens path folds over: the surface is concave toward the head with radii down to
    /// `r_min` (not above the standoff) between arc lengths `s_start` and `s_end`.
    FoldOver {
        r_min: f64,
        s_start: f64,
        s_end: f64,
    },
}

/// The stations of `profile` seen from the head on the left (`head_on_left`) or right of
/// travel at `standoff`: samples at equal arc-length steps no longer than `max_step`, within
/// the chord tolerance `chord_tol`, checked against the fold-over rule, with beams by
/// `normals`. A closed profile's path ends where it started.
pub fn oriented_stations(
    profile: &Profile,
    max_step: f64,
    chord_tol: f64,
    standoff: f64,
    head_on_left: bool,
    normals: Normals,
) -> Result<Vec<Station>, ToolpathError> {
    let rs = profile
        .resample_even(max_step, Some(chord_tol))
        .map_err(ToolpathError::Geometry)?;
    // The normals cross at the centre of curvature: concave toward the head (curvature signed
    // toward the head) with radius ≤ standoff, i.e. κ·standoff ≥ 1.
    let toward_head = if head_on_left { 1.0 } else { -1.0 };
    // Where the curve was built from exact data (a cam from its law) its knots carry the exact
    // curvature on both sides, the jumps included: the rule reads those, so the radius it
    // reports is the law's, not a sample's. Elsewhere the samples' curvature is the curve's.
    let probes: Vec<(f64, f64)> = match profile.as_spline().and_then(|sp| sp.exact_knots()) {
        Some(knots) => knots.flat_map(|(s, [a, b])| [(s, a), (s, b)]).collect(),
        None => rs
            .samples
            .iter()
            .map(|smp| (smp.s, smp.curvature))
            .collect(),
    };
    let mut folds = probes
        .iter()
        .filter(|(_, k)| k * toward_head * standoff >= 1.0 - 1e-9);
    if let Some(&(s_start, k0)) = folds.next() {
        let (mut r_min, mut s_end) = (1.0 / k0.abs(), s_start);
        for &(s, k) in folds {
            r_min = r_min.min(1.0 / k.abs());
            s_end = s;
        }
        return Err(ToolpathError::FoldOver {
            r_min,
            s_start,
            s_end,
        });
    }
    match normals {
        Normals::Exact => Ok(rs
            .samples
            .iter()
            .map(|smp| Station {
                s: smp.s,
                point: smp.point,
                beam: beam_from_left(smp.left, head_on_left),
            })
            .collect()),
        Normals::Chord => {
            let points: Vec<V2> = rs.samples.iter().map(|smp| smp.point).collect();
            let mut stations = chord_stations(&points, head_on_left);
            // On a closed profile the path returns to its first scan point; on an open one the
            // ends stay where the chords put them.
            if profile.closed
                && let Some(first) = stations.first().copied()
            {
                stations.push(first);
            }
            Ok(stations)
        }
    }
}

/// Seed 1's discrete method (PROCESS.md §1) on the polyline `points`: one station per chord
/// P_k P_{k+1}, at its midpoint M, with the normal along the chord's perpendicular bisector
/// on the head's side. Chords of zero length have no direction and are skipped. `s` is the
/// arc length along the polyline at M.
pub fn chord_stations(points: &[V2], head_on_left: bool) -> Vec<Station> {
    let mut out = Vec::with_capacity(points.len().saturating_sub(1));
    let mut s = 0.0;
    for w in points.windows(2) {
        let chord = w[1] - w[0];
        let len = chord.norm();
        if len < 1e-12 {
            continue;
        }
        let t = chord / len;
        out.push(Station {
            s: s + 0.5 * len,
            point: 0.5 * (w[0] + w[1]),
            beam: beam_from_left(V2::new(-t.y, t.x), head_on_left),
        });
        s += len;
    }
    out
}

/// The beam toward the surface from the head's side: the head-side normal (± the left
/// normal) reversed.
fn beam_from_left(left: V2, head_on_left: bool) -> V2 {
    let n = if head_on_left { left } else { -left };
    -n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a circle seen from outside, exact beams point at the centre and both methods give
    /// a closed path.
    #[test]
    fn exact_and_chord_beams_on_a_circle() {
        let c = Profile::circle(V2::new(0.0, 0.0), 10.0, 0.0, true).unwrap();
        let left = HeadSide::Outside.on_left(&c);
        assert!(!left, "a ccw circle has its outside on the right");
        for normals in [Normals::Exact, Normals::Chord] {
            let st = oriented_stations(&c, 0.5, 1e-3, 5.0, left, normals).unwrap();
            assert!(st.len() > 100);
            for x in &st {
                let to_centre = -x.point / x.point.norm();
                assert!((x.beam - to_centre).norm() < 1e-2, "{normals:?}: {x:?}");
            }
            let (a, b) = (st.first().unwrap(), st.last().unwrap());
            assert!((a.point - b.point).norm() < 1e-9, "{normals:?} closes");
        }
    }

    /// Inside a circle of radius 10 a standoff of 12 folds the lens path over everywhere.
    #[test]
    fn fold_over_inside_a_tight_circle() {
        let c = Profile::circle(V2::new(0.0, 0.0), 10.0, 0.0, true).unwrap();
        let left = HeadSide::Inside.on_left(&c);
        let e = oriented_stations(&c, 0.5, 1e-3, 12.0, left, Normals::Exact).unwrap_err();
        let ToolpathError::FoldOver { r_min, s_start, .. } = e else {
            panic!("{e:?}");
        };
        assert!((r_min - 10.0).abs() < 1e-6);
        assert_eq!(s_start, 0.0);
        assert!(oriented_stations(&c, 0.5, 1e-3, 8.0, left, Normals::Exact).is_ok());
    }

    /// Chords: midpoints, bisector normals, zero-length chords skipped.
    #[test]
    fn chord_stations_of_a_square() {
        let p = |x, y| V2::new(x, y);
        let pts = [p(0.0, 0.0), p(2.0, 0.0), p(2.0, 0.0), p(2.0, 2.0)];
        let st = chord_stations(&pts, true);
        assert_eq!(st.len(), 2);
        assert_eq!(st[0].point, p(1.0, 0.0));
        assert_eq!(st[0].beam, p(0.0, -1.0));
        assert_eq!(st[0].s, 1.0);
        assert_eq!(st[1].point, p(2.0, 1.0));
        assert_eq!(st[1].beam, p(1.0, 0.0));
        assert_eq!(st[1].s, 3.0);
    }
}
