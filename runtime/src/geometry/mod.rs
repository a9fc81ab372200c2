//! Geometry: exact planar profiles made of lines and circular arcs, their queries (length,
//! point and tangent at an arc length) and offsets.
//!
//! Offsets of line/arc profiles are exact (cavalier_contours computes them on bulge
//! polylines). The seed-2 rule — a concave region whose radius is smaller than the offset
//! distance folds the offset over itself — is checked before offsetting and reported rather
//! than silently trimmed.

use cavalier_contours::polyline::{PlineSource, PlineSourceMut, Polyline};
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

pub type V2 = Vector2<f64>;

/// One piece of a profile.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Seg {
    Line {
        a: V2,
        b: V2,
    },
    /// From angle `a0` about `center`, turning by `sweep` (positive = counter-clockwise).
    Arc {
        center: V2,
        r: f64,
        a0: f64,
        sweep: f64,
    },
}

impl Seg {
    pub fn start(&self) -> V2 {
        match self {
            Seg::Line { a, .. } => *a,
            Seg::Arc { center, r, a0, .. } => center + V2::new(a0.cos(), a0.sin()) * *r,
        }
    }

    pub fn end(&self) -> V2 {
        match self {
            Seg::Line { b, .. } => *b,
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => {
                let a = a0 + sweep;
                center + V2::new(a.cos(), a.sin()) * *r
            }
        }
    }

    pub fn length(&self) -> f64 {
        match self {
            Seg::Line { a, b } => (b - a).norm(),
            Seg::Arc { r, sweep, .. } => r * sweep.abs(),
        }
    }

    /// Point at arc length `s` from the segment start (clamped to the segment).
    pub fn point_at(&self, s: f64) -> V2 {
        let len = self.length();
        let f = if len > 0.0 {
            (s / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        match self {
            Seg::Line { a, b } => a + (b - a) * f,
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => {
                let a = a0 + sweep * f;
                center + V2::new(a.cos(), a.sin()) * *r
            }
        }
    }

    /// Unit tangent at arc length `s`.
    pub fn tangent_at(&self, s: f64) -> V2 {
        match self {
            Seg::Line { a, b } => (b - a).try_normalize(0.0).unwrap_or(V2::x()),
            Seg::Arc { a0, sweep, .. } => {
                let len = self.length();
                let f = if len > 0.0 {
                    (s / len).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let a = a0 + sweep * f;
                let t = V2::new(-a.sin(), a.cos());
                if *sweep >= 0.0 { t } else { -t }
            }
        }
    }

    pub fn reversed(&self) -> Seg {
        match self {
            Seg::Line { a, b } => Seg::Line { a: *b, b: *a },
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => Seg::Arc {
                center: *center,
                r: *r,
                a0: a0 + sweep,
                sweep: -sweep,
            },
        }
    }

    /// The segment under a rigid motion: rotation by `angle` about the origin, then a shift.
    pub fn transformed(&self, angle: f64, shift: V2) -> Seg {
        let rot = nalgebra::Rotation2::new(angle);
        match self {
            Seg::Line { a, b } => Seg::Line {
                a: rot * a + shift,
                b: rot * b + shift,
            },
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => Seg::Arc {
                center: rot * center + shift,
                r: *r,
                a0: a0 + angle,
                sweep: *sweep,
            },
        }
    }
}

/// A planar profile: connected segments, optionally closed (the last ends where the first
/// starts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    pub segs: Vec<Seg>,
    pub closed: bool,
}

/// Why a profile could not be built or offset.
#[derive(Debug, Clone, PartialEq)]
pub enum GeomError {
    TooFewPoints(usize),
    Degenerate(String),
    /// A concave arc whose radius is not larger than the offset distance (seed 2's rule).
    FoldOver {
        segment: usize,
        radius: f64,
        distance: f64,
    },
    /// The offset splits into several loops or vanishes.
    Split {
        loops: usize,
    },
}

impl std::fmt::Display for GeomError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use lase_lang::units::format_number as n;
        match self {
            GeomError::TooFewPoints(k) => {
                write!(f, "a polyline needs at least 2 distinct points, got {k}")
            }
            GeomError::Degenerate(why) => write!(f, "{why}"),
            GeomError::FoldOver {
                segment,
                radius,
                distance,
            } => write!(
                f,
                "the offset folds over itself: segment {} is concave with radius {} mm, smaller than the offset distance {} mm",
                segment + 1,
                n(*radius),
                n(*distance)
            ),
            GeomError::Split { loops: 0 } => write!(
                f,
                "the offset vanishes: the profile is narrower than twice the distance"
            ),
            GeomError::Split { loops } => {
                write!(f, "the offset splits into {loops} separate loops")
            }
        }
    }
}

impl Profile {
    /// Straight segments through `pts`; repeated points are dropped.
    pub fn polyline(pts: &[V2], closed: bool) -> Result<Profile, GeomError> {
        let mut p: Vec<V2> = Vec::with_capacity(pts.len());
        for q in pts {
            if p.last().is_none_or(|l: &V2| (l - q).norm() > 1e-9) {
                p.push(*q);
            }
        }
        if closed && p.len() > 2 && (p[0] - p[p.len() - 1]).norm() <= 1e-9 {
            p.pop();
        }
        if p.len() < 2 || (closed && p.len() < 3) {
            return Err(GeomError::TooFewPoints(p.len()));
        }
        let mut segs: Vec<Seg> = p
            .windows(2)
            .map(|w| Seg::Line { a: w[0], b: w[1] })
            .collect();
        if closed {
            segs.push(Seg::Line {
                a: p[p.len() - 1],
                b: p[0],
            });
        }
        Ok(Profile { segs, closed })
    }

    pub fn arc(center: V2, r: f64, a0: f64, a1: f64, ccw: bool) -> Result<Profile, GeomError> {
        if !(r > 0.0) {
            return Err(GeomError::Degenerate(format!(
                "an arc needs a positive radius, got {r} mm"
            )));
        }
        let mut sweep = a1 - a0;
        if ccw {
            while sweep <= 0.0 {
                sweep += TAU;
            }
            while sweep > TAU {
                sweep -= TAU;
            }
        } else {
            while sweep >= 0.0 {
                sweep -= TAU;
            }
            while sweep < -TAU {
                sweep += TAU;
            }
        }
        Ok(Profile {
            segs: vec![Seg::Arc {
                center,
                r,
                a0,
                sweep,
            }],
            closed: false,
        })
    }

    pub fn circle(center: V2, r: f64, a0: f64, ccw: bool) -> Result<Profile, GeomError> {
        if !(r > 0.0) {
            return Err(GeomError::Degenerate(format!(
                "a circle needs a positive radius, got {r} mm"
            )));
        }
        let s = if ccw { PI } else { -PI };
        // Two half circles: every NC dialect and every offset library takes those unambiguously.
        Ok(Profile {
            segs: vec![
                Seg::Arc {
                    center,
                    r,
                    a0,
                    sweep: s,
                },
                Seg::Arc {
                    center,
                    r,
                    a0: a0 + s,
                    sweep: s,
                },
            ],
            closed: true,
        })
    }

    pub fn start(&self) -> V2 {
        self.segs[0].start()
    }

    pub fn end(&self) -> V2 {
        self.segs[self.segs.len() - 1].end()
    }

    pub fn length(&self) -> f64 {
        self.segs.iter().map(Seg::length).sum()
    }

    /// The segment holding arc length `s` and the arc length within it.
    fn locate(&self, s: f64) -> (&Seg, f64) {
        let mut rest = s.max(0.0);
        for seg in &self.segs {
            let l = seg.length();
            if rest <= l {
                return (seg, rest);
            }
            rest -= l;
        }
        let last = &self.segs[self.segs.len() - 1];
        (last, last.length())
    }

    pub fn point_at(&self, s: f64) -> V2 {
        let (seg, t) = self.locate(s);
        seg.point_at(t)
    }

    pub fn tangent_at(&self, s: f64) -> V2 {
        let (seg, t) = self.locate(s);
        seg.tangent_at(t)
    }

    pub fn reversed(&self) -> Profile {
        Profile {
            segs: self.segs.iter().rev().map(Seg::reversed).collect(),
            closed: self.closed,
        }
    }

    pub fn transformed(&self, angle: f64, shift: V2) -> Profile {
        Profile {
            segs: self
                .segs
                .iter()
                .map(|s| s.transformed(angle, shift))
                .collect(),
            closed: self.closed,
        }
    }

    /// Signed area (positive when counter-clockwise); 0 for open profiles.
    pub fn signed_area(&self) -> f64 {
        if !self.closed {
            return 0.0;
        }
        self.to_pline().area()
    }

    fn to_pline(&self) -> Polyline<f64> {
        let mut pl = if self.closed {
            Polyline::new_closed()
        } else {
            Polyline::new()
        };
        for seg in &self.segs {
            let p = seg.start();
            let bulge = match seg {
                Seg::Line { .. } => 0.0,
                Seg::Arc { sweep, .. } => (sweep / 4.0).tan(),
            };
            pl.add(p.x, p.y, bulge);
        }
        if !self.closed {
            let e = self.end();
            pl.add(e.x, e.y, 0.0);
        }
        pl
    }

    fn from_pline(pl: &Polyline<f64>) -> Profile {
        let n = pl.vertex_count();
        let count = if pl.is_closed() {
            n
        } else {
            n.saturating_sub(1)
        };
        let mut segs = Vec::with_capacity(count);
        for i in 0..count {
            let v = pl.at(i);
            let w = pl.at((i + 1) % n);
            let a = V2::new(v.x, v.y);
            let b = V2::new(w.x, w.y);
            if v.bulge.abs() < 1e-12 {
                segs.push(Seg::Line { a, b });
            } else {
                let sweep = 4.0 * v.bulge.atan();
                let chord = b - a;
                let c = chord.norm();
                let r = c / (2.0 * (sweep / 2.0).sin().abs());
                // The center lies on the chord's perpendicular bisector, to the left for a
                // counter-clockwise arc.
                let mid = (a + b) / 2.0;
                let left = V2::new(-chord.y, chord.x) / c;
                let h = (r * r - c * c / 4.0).max(0.0).sqrt();
                let side = if (sweep.abs() < PI) == (sweep > 0.0) {
                    1.0
                } else {
                    -1.0
                };
                let center = mid + left * h * side;
                let a0 = (a.y - center.y).atan2(a.x - center.x);
                segs.push(Seg::Arc {
                    center,
                    r,
                    a0,
                    sweep,
                });
            }
        }
        Profile {
            segs,
            closed: pl.is_closed(),
        }
    }

    /// The offset curve C0 = C ± d·n (PROCESS.md §1, eq. 2). For a closed profile a positive
    /// `d` grows it outward; for an open one it moves it to the left of travel.
    pub fn offset(&self, d: f64) -> Result<Profile, GeomError> {
        if d == 0.0 {
            return Ok(self.clone());
        }
        // cavalier_contours offsets to the left of travel for positive values.
        let left = if self.closed {
            let ccw = self.signed_area() > 0.0;
            if ccw { -d } else { d }
        } else {
            d
        };
        // Seed 2: a concave arc (turning toward the offset side) with r ≤ |d| collapses.
        for (i, seg) in self.segs.iter().enumerate() {
            if let Seg::Arc { r, sweep, .. } = seg {
                let center_on_left = *sweep > 0.0;
                if center_on_left == (left > 0.0) && *r <= left.abs() + 1e-12 {
                    return Err(GeomError::FoldOver {
                        segment: i,
                        radius: *r,
                        distance: d.abs(),
                    });
                }
            }
        }
        let pl = self.to_pline();
        let result = std::panic::catch_unwind(|| pl.parallel_offset(left)).map_err(|_| {
            GeomError::Degenerate("the offset could not be computed for this profile".into())
        })?;
        if result.len() != 1 {
            return Err(GeomError::Split {
                loops: result.len(),
            });
        }
        if self.closed {
            // An inward offset that collapses to a sliver (zero area) or turns inside out has
            // vanished, whatever the library returned.
            let a0 = pl.area();
            let a1 = result[0].area();
            if a1.abs() < 1e-9 || a1.signum() != a0.signum() {
                return Err(GeomError::Split { loops: 0 });
            }
        }
        let mut p = Profile::from_pline(&result[0]);
        if self.closed {
            p = p.rotated_to_start_near(self.start());
        }
        Ok(p)
    }

    /// A closed profile restarted at the vertex nearest `p` (an offset starts beside its
    /// source, not wherever the library put vertex 0).
    fn rotated_to_start_near(mut self, p: V2) -> Profile {
        if !self.closed || self.segs.is_empty() {
            return self;
        }
        let k = (0..self.segs.len())
            .min_by(|&i, &j| {
                let di = (self.segs[i].start() - p).norm();
                let dj = (self.segs[j].start() - p).norm();
                di.total_cmp(&dj)
            })
            .unwrap_or(0);
        self.segs.rotate_left(k);
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect() -> Profile {
        Profile::polyline(
            &[
                V2::new(0.0, 0.0),
                V2::new(40.0, 0.0),
                V2::new(40.0, 20.0),
                V2::new(0.0, 20.0),
            ],
            true,
        )
        .unwrap()
    }

    #[test]
    fn outward_offset_of_a_rectangle_is_a_rounded_rectangle() {
        let o = rect().offset(1.5).unwrap();
        // 4 sides kept, 4 quarter arcs of radius 1.5 added at the corners.
        let expected = 2.0 * (40.0 + 20.0) + TAU * 1.5;
        assert!((o.length() - expected).abs() < 1e-9, "{}", o.length());
        let arcs: Vec<_> = o
            .segs
            .iter()
            .filter(|s| matches!(s, Seg::Arc { .. }))
            .collect();
        assert_eq!(arcs.len(), 4);
        for a in arcs {
            let Seg::Arc { r, .. } = a else {
                unreachable!()
            };
            assert!((r - 1.5).abs() < 1e-12);
        }
        // Every point of the offset lies at exactly 1.5 mm from the rectangle.
        for k in 0..200 {
            let p = o.point_at(o.length() * k as f64 / 200.0);
            let dx = (p.x.clamp(0.0, 40.0) - p.x).abs();
            let dy = (p.y.clamp(0.0, 20.0) - p.y).abs();
            assert!(((dx * dx + dy * dy).sqrt() - 1.5).abs() < 1e-9, "{p:?}");
        }
        assert!(
            (o.start() - V2::new(0.0, -1.5)).norm() < 1e-9
                || (o.start() - V2::new(-1.5, 0.0)).norm() < 1e-9
        );
    }

    #[test]
    fn inward_offset_shrinks() {
        let o = rect().offset(-2.0).unwrap();
        assert!((o.length() - 2.0 * (36.0 + 16.0)).abs() < 1e-9);
        assert!(matches!(
            rect().offset(-10.0),
            Err(GeomError::Split { loops: 0 })
        ));
        assert!(matches!(
            rect().offset(-11.0),
            Err(GeomError::Split { loops: 0 })
        ));
    }

    #[test]
    fn circle_offsets_and_fold_over() {
        let c = Profile::circle(V2::new(5.0, 0.0), 3.0, 0.0, true).unwrap();
        assert!((c.length() - TAU * 3.0).abs() < 1e-12);
        let o = c.offset(2.0).unwrap();
        assert!((o.length() - TAU * 5.0).abs() < 1e-9);
        let err = c.offset(-3.5).unwrap_err();
        assert!(matches!(err, GeomError::FoldOver { radius, .. } if radius == 3.0));
    }

    #[test]
    fn arc_queries_are_exact() {
        let a = Profile::arc(V2::new(0.0, 0.0), 10.0, 0.0, PI / 2.0, true).unwrap();
        assert!((a.length() - 5.0 * PI).abs() < 1e-12);
        let m = a.point_at(2.5 * PI);
        assert!((m - V2::new(10.0 * (PI / 4.0).cos(), 10.0 * (PI / 4.0).sin())).norm() < 1e-12);
        let t = a.tangent_at(0.0);
        assert!((t - V2::new(0.0, 1.0)).norm() < 1e-12);
        let r = a.reversed();
        assert!((r.start() - V2::new(0.0, 10.0)).norm() < 1e-12);
        assert!((r.tangent_at(0.0) - V2::new(1.0, 0.0)).norm() < 1e-12);
    }
}
