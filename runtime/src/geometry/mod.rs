//! Geometry: exact planar profiles — lines, circular arcs and interpolating cubic B-splines
//! (PROCESS.md §2, step 1) — and their exact queries (point, unit tangent, normals, signed
//! curvature at a parameter or an arc length), resampling, offsets, cam profiles and import.
//!
//! A `Profile` is a chain of `Seg`s (lines and arcs). A profile built from a spline also keeps
//! the exact `Spline`: every query and offset then uses the spline, and `segs` hold its biarc
//! rendition within `SPLINE_RENDER_TOL_MM`, so code that only knows lines and arcs (NC output)
//! keeps working. `to_line_arc(tol)` renders a spline at another tolerance.
//!
//! Submodules: `spline` (interpolation, arc length), `biarc` (line/arc approximation of smooth
//! curves), `resample` (constant arc-length steps with a chord bound), `offset` (C0 = C ± d·n
//! and the seed-2 fold-over rule), `cam` (lift tables and motion laws), `import` (DXF, SVG),
//! `toolpath` (oriented toolpaths: beam normals, exact or by chords, and the fold-over rule).

pub mod biarc;
pub mod cam;
pub mod import;
pub mod offset;
pub mod resample;
pub mod spline;
pub mod svg_file;
pub mod toolpath;

pub use cam::{CamLaw, CamSegment, CamSegmentKind};
pub use import::{ImportError, ImportOptions};
pub use offset::{FoldRegion, OffsetOptions};
pub use resample::{Resampled, Sample};
pub use spline::Spline;

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

    /// Signed curvature (positive when turning counter-clockwise).
    pub fn curvature(&self) -> f64 {
        match self {
            Seg::Line { .. } => 0.0,
            Seg::Arc { r, sweep, .. } => {
                if *sweep >= 0.0 {
                    1.0 / r
                } else {
                    -1.0 / r
                }
            }
        }
    }

    /// Distance from `p` to the segment.
    pub fn distance_to(&self, p: V2) -> f64 {
        biarc::seg_distance(self, p)
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

/// How far a spline profile's line/arc rendition (`Profile::segs`) may stray from the exact
/// spline, in mm.
pub const SPLINE_RENDER_TOL_MM: f64 = 1e-3;

/// A planar profile: connected segments, optionally closed (the last ends where the first
/// starts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// Lines and arcs; for a spline profile, the spline's biarc rendition.
    pub segs: Vec<Seg>,
    pub closed: bool,
    /// The exact curve when the profile is a spline: queries and offsets use it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spline: Option<Box<Spline>>,
}

/// The local frame of a profile at one place (PROCESS.md §1: the beam runs along the normal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Arc length from the profile start, mm.
    pub s: f64,
    pub point: V2,
    /// Unit tangent in the direction of travel.
    pub tangent: V2,
    /// Unit normal to the left of travel (the tangent turned +90°).
    pub left: V2,
    /// Unit principal normal, pointing to the concave side (seed 1's n(t)); equal to `left`
    /// where the profile is straight.
    pub normal: V2,
    /// Signed curvature, 1/mm: positive where the profile turns left (counter-clockwise).
    pub curvature: f64,
}

impl Frame {
    fn new(s: f64, point: V2, tangent: V2, curvature: f64) -> Frame {
        let left = V2::new(-tangent.y, tangent.x);
        Frame {
            s,
            point,
            tangent,
            left,
            normal: if curvature < 0.0 { -left } else { left },
            curvature,
        }
    }

    /// Radius of curvature, mm (infinite where straight).
    pub fn radius(&self) -> f64 {
        1.0 / self.curvature.abs()
    }
}

/// Why a profile could not be built, queried or offset.
#[derive(Debug, Clone, PartialEq)]
pub enum GeomError {
    TooFewPoints(usize),
    Degenerate(String),
    /// A concave region whose radius of curvature is not larger than the offset distance
    /// (seed 2's rule). `segment` is the segment (line/arc profiles) or spline span holding the
    /// smallest radius; `s_start..s_end` is the region's arc-length range on the source profile.
    FoldOver {
        segment: usize,
        radius: f64,
        distance: f64,
        s_start: f64,
        s_end: f64,
        /// The source is a spline (the message then names the arc-length range).
        spline: bool,
    },
    /// The offset splits into several loops or vanishes.
    Split {
        loops: usize,
    },
    /// The offset crosses itself away from any fold-over (the profile is narrower than twice
    /// the distance somewhere); `near` is a crossing point.
    SelfIntersects {
        near: V2,
    },
    /// A closed profile that crosses itself (a bow-tie): it has no one inside, so it cannot be
    /// offset or filled; `near` is a crossing point.
    Crosses {
        near: V2,
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
                radius,
                distance,
                s_start,
                s_end,
                spline: true,
                ..
            } => write!(
                f,
                "the offset folds over itself: the profile is concave with radius down to {} mm between {} mm and {} mm along it, smaller than the offset distance {} mm",
                n(*radius),
                n(*s_start),
                n(*s_end),
                n(*distance)
            ),
            GeomError::FoldOver {
                segment,
                radius,
                distance,
                ..
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
            GeomError::SelfIntersects { near } => write!(
                f,
                "the offset crosses itself near ({}, {}) mm: the profile is narrower than twice the distance there",
                n(near.x),
                n(near.y)
            ),
            GeomError::Crosses { near } => write!(
                f,
                "the closed profile crosses itself at ({}, {}) mm: it has no one inside to offset \
                 or fill",
                n(near.x),
                n(near.y)
            ),
        }
    }
}

impl std::error::Error for GeomError {}

impl Profile {
    /// Straight segments through `pts`; repeated points are dropped.
    pub fn polyline(pts: &[V2], closed: bool) -> Result<Profile, GeomError> {
        if pts.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(GeomError::Degenerate(
                "a polyline point is not a finite number".into(),
            ));
        }
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
        Ok(Profile::from_segs(segs, closed))
    }

    /// A line/arc profile from its segments (no spline).
    pub fn from_segs(segs: Vec<Seg>, closed: bool) -> Profile {
        Profile {
            segs,
            closed,
            spline: None,
        }
    }

    pub fn arc(center: V2, r: f64, a0: f64, a1: f64, ccw: bool) -> Result<Profile, GeomError> {
        if !(r > 0.0 && r.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "an arc needs a positive radius, got {r} mm"
            )));
        }
        if !(center.x.is_finite() && center.y.is_finite() && a0.is_finite() && a1.is_finite()) {
            return Err(GeomError::Degenerate(
                "an arc's center and angles must be finite numbers".into(),
            ));
        }
        let mut sweep = a1 - a0;
        if ccw {
            sweep = sweep.rem_euclid(TAU);
            if sweep <= 0.0 {
                sweep = TAU;
            }
        } else {
            sweep = -(-sweep).rem_euclid(TAU);
            if sweep >= 0.0 {
                sweep = -TAU;
            }
        }
        Ok(Profile::from_segs(
            vec![Seg::Arc {
                center,
                r,
                a0,
                sweep,
            }],
            false,
        ))
    }

    pub fn circle(center: V2, r: f64, a0: f64, ccw: bool) -> Result<Profile, GeomError> {
        if !(r > 0.0 && r.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "a circle needs a positive radius, got {r} mm"
            )));
        }
        if !(center.x.is_finite() && center.y.is_finite() && a0.is_finite()) {
            return Err(GeomError::Degenerate(
                "a circle's center and start angle must be finite numbers".into(),
            ));
        }
        let s = if ccw { PI } else { -PI };
        // Two half circles: every NC dialect and every offset library takes those unambiguously.
        Ok(Profile::from_segs(
            vec![
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
            true,
        ))
    }

    /// A cubic B-spline through measured points (PROCESS.md §2 step 1); see `Spline`.
    pub fn interpolate(points: &[V2], closed: bool) -> Result<Profile, GeomError> {
        Ok(Profile::from_spline(Spline::interpolate(points, closed)?))
    }

    /// A profile following `spline` exactly, with its biarc rendition in `segs`.
    pub fn from_spline(spline: Spline) -> Profile {
        let segs = spline_biarcs(&spline, SPLINE_RENDER_TOL_MM);
        Profile {
            segs,
            closed: spline.is_closed(),
            spline: Some(Box::new(spline)),
        }
    }

    /// The exact spline, when the profile is one.
    pub fn as_spline(&self) -> Option<&Spline> {
        self.spline.as_deref()
    }

    /// The profile as lines and arcs only: spline profiles become biarcs within `tol` mm
    /// (tangent-continuous); line/arc profiles are returned unchanged.
    pub fn to_line_arc(&self, tol: f64) -> Result<Profile, GeomError> {
        match &self.spline {
            None => Ok(self.clone()),
            Some(sp) => {
                if !(tol > 0.0 && tol.is_finite()) {
                    return Err(GeomError::Degenerate(format!(
                        "a rendering tolerance must be positive, got {tol} mm"
                    )));
                }
                Ok(Profile::from_segs(spline_biarcs(sp, tol), self.closed))
            }
        }
    }

    pub fn start(&self) -> V2 {
        match &self.spline {
            Some(sp) => sp.derivs(0.0).0,
            None => self.segs[0].start(),
        }
    }

    pub fn end(&self) -> V2 {
        match &self.spline {
            Some(sp) => sp.derivs(sp.span_count() as f64).0,
            None => self.segs[self.segs.len() - 1].end(),
        }
    }

    pub fn length(&self) -> f64 {
        match &self.spline {
            Some(sp) => sp.length(),
            None => self.segs.iter().map(Seg::length).sum(),
        }
    }

    /// The segment holding arc length `s` and the arc length within it.
    fn locate(&self, s: f64) -> (usize, f64) {
        let mut rest = if s.is_nan() { 0.0 } else { s.max(0.0) };
        for (i, seg) in self.segs.iter().enumerate() {
            let l = seg.length();
            if rest <= l {
                return (i, rest);
            }
            rest -= l;
        }
        let last = self.segs.len() - 1;
        (last, self.segs[last].length())
    }

    pub fn point_at(&self, s: f64) -> V2 {
        match &self.spline {
            Some(_) => self.frame_at(s).point,
            None => {
                let (i, t) = self.locate(s);
                self.segs[i].point_at(t)
            }
        }
    }

    pub fn tangent_at(&self, s: f64) -> V2 {
        match &self.spline {
            Some(_) => self.frame_at(s).tangent,
            None => {
                let (i, t) = self.locate(s);
                self.segs[i].tangent_at(t)
            }
        }
    }

    /// Unit normal at arc length `s`, pointing to the concave side (seed 1's n(t)).
    pub fn normal_at(&self, s: f64) -> V2 {
        self.frame_at(s).normal
    }

    /// Unit normal to the left of travel at arc length `s`.
    pub fn left_normal_at(&self, s: f64) -> V2 {
        self.frame_at(s).left
    }

    /// Signed curvature at arc length `s` (positive turning counter-clockwise), 1/mm.
    pub fn curvature_at(&self, s: f64) -> f64 {
        self.frame_at(s).curvature
    }

    /// Upper end of the parameter range. The parameter `u = i + f` means piece `i` at fraction
    /// `f` of its own parameter: for lines and arcs the fraction of the segment's length, for a
    /// spline the B-spline parameter of span `i` (the curve passes Q_i at `u = i`).
    pub fn param_end(&self) -> f64 {
        match &self.spline {
            Some(sp) => sp.span_count() as f64,
            None => self.segs.len() as f64,
        }
    }

    /// The parameter at arc length `s` (clamped to the profile).
    pub fn param_at(&self, s: f64) -> f64 {
        match &self.spline {
            Some(sp) => sp.param_at_length(s),
            None => {
                let (i, t) = self.locate(s);
                let l = self.segs[i].length();
                i as f64 + if l > 0.0 { t / l } else { 0.0 }
            }
        }
    }

    /// Arc length from the start to parameter `u`.
    pub fn length_at_param(&self, u: f64) -> f64 {
        match &self.spline {
            Some(sp) => sp.length_at_param(u),
            None => {
                let n = self.segs.len();
                let u = if u.is_nan() {
                    0.0
                } else {
                    u.clamp(0.0, n as f64)
                };
                let i = (u.floor() as usize).min(n - 1);
                let before: f64 = self.segs[..i].iter().map(Seg::length).sum();
                before + self.segs[i].length() * (u - i as f64)
            }
        }
    }

    /// Exact frame at arc length `s`.
    pub fn frame_at(&self, s: f64) -> Frame {
        match &self.spline {
            Some(sp) => {
                let u = sp.param_at_length(s);
                spline_frame(sp, u, s.clamp(0.0, sp.length()))
            }
            None => {
                let (i, t) = self.locate(s);
                let seg = &self.segs[i];
                let s_here = self.segs[..i].iter().map(Seg::length).sum::<f64>() + t;
                Frame::new(s_here, seg.point_at(t), seg.tangent_at(t), seg.curvature())
            }
        }
    }

    /// Exact frame at parameter `u` (see `param_end`).
    pub fn frame_at_param(&self, u: f64) -> Frame {
        match &self.spline {
            Some(sp) => spline_frame(sp, u, sp.length_at_param(u)),
            None => self.frame_at(self.length_at_param(u)),
        }
    }

    pub fn reversed(&self) -> Profile {
        Profile {
            segs: self.segs.iter().rev().map(Seg::reversed).collect(),
            closed: self.closed,
            spline: self.spline.as_ref().map(|s| Box::new(s.reversed())),
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
            spline: self
                .spline
                .as_ref()
                .map(|s| Box::new(s.transformed(angle, shift))),
        }
    }

    /// Signed area (positive when counter-clockwise); 0 for open profiles.
    pub fn signed_area(&self) -> f64 {
        if !self.closed {
            return 0.0;
        }
        match &self.spline {
            Some(sp) => sp.signed_area(),
            None => self.to_pline().area(),
        }
    }

    pub(crate) fn to_pline(&self) -> Polyline<f64> {
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
            let e = self.segs[self.segs.len() - 1].end();
            pl.add(e.x, e.y, 0.0);
        }
        pl
    }

    pub(crate) fn from_pline(pl: &Polyline<f64>) -> Profile {
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
        Profile::from_segs(segs, pl.is_closed())
    }

    /// A closed profile restarted at the vertex nearest `p` (an offset starts beside its
    /// source, not wherever the library put vertex 0).
    pub(crate) fn rotated_to_start_near(mut self, p: V2) -> Profile {
        if !self.closed || self.segs.is_empty() || self.spline.is_some() {
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

/// Frame of a spline at parameter `u` and arc length `s`: tangent C'/|C'|, curvature
/// (C' × C'')/|C'|³.
fn spline_frame(sp: &Spline, u: f64, s: f64) -> Frame {
    let (p, d1, d2) = sp.derivs(u);
    let speed = d1.norm();
    if speed > 0.0 {
        let k = (d1.x * d2.y - d1.y * d2.x) / (speed * speed * speed);
        Frame::new(s, p, d1 / speed, k)
    } else {
        // A cusp (the control polygon doubles back): the second derivative gives the direction.
        let t = d2.try_normalize(0.0).unwrap_or(V2::x());
        Frame::new(s, p, t, 0.0)
    }
}

/// Biarcs of every span of `sp` within `tol`.
pub(crate) fn spline_biarcs(sp: &Spline, tol: f64) -> Vec<Seg> {
    let mut out = Vec::with_capacity(2 * sp.span_count());
    for j in 0..sp.span_count() {
        let f = |t: f64| {
            let (p, d, _) = sp.span_derivs(j, t);
            (p, d)
        };
        biarc::fit_biarcs(&f, 0.0, 1.0, tol, &mut out);
    }
    out
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
