//! Offset curves `C0 = C ± d·n` (PROCESS.md §1, eq. 2) and the seed-2 fold-over rule
//! (PROCESS.md §2: a concave region whose radius of curvature is smaller than the offset
//! distance folds the offset over itself).
//!
//! Sign convention (kept from the first geometry version): for a closed profile a positive `d`
//! grows it outward; for an open one it moves it to the left of travel. Internally everything
//! is expressed as the signed left offset `ℓ`: the offset point is `C + ℓ·left`, its speed is
//! `(1 − κ ℓ)·|C'|`, and the offset folds exactly where `κ ℓ ≥ 1`.
//!
//! Line/arc profiles are offset exactly by cavalier_contours. Spline profiles are offset by
//! sampling the exact offset `C(u) + ℓ·left(u)`, interpolating a B-spline through the samples
//! (seed 2's own fitting step), and checking the fitted curve against the exact offset at
//! parameters between the samples, refining until the deviation is within the tolerance.

use super::{GeomError, Profile, Seg, Spline, V2};
use cavalier_contours::polyline::{PlineSource, internal::pline_intersects};

/// How to offset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffsetOptions {
    /// Give the clean (trimmed) offset instead of reporting a fold-over: self-intersecting
    /// loops are cut away. The result is then made of lines and arcs.
    pub trim: bool,
    /// Largest distance, mm, between a spline offset and the exact offset curve.
    pub tol_mm: f64,
}

impl Default for OffsetOptions {
    fn default() -> Self {
        OffsetOptions {
            trim: false,
            tol_mm: 1e-3,
        }
    }
}

/// A region of a profile where an offset folds over (seed 2's rule).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FoldRegion {
    /// Arc-length range on the source profile, mm.
    pub s_start: f64,
    pub s_end: f64,
    /// Smallest radius of curvature in the region, mm, and where it is.
    pub min_radius: f64,
    pub s_min: f64,
    /// Segment (line/arc profiles) or spline span holding the smallest radius.
    pub segment: usize,
}

impl Profile {
    /// The offset curve C0 = C ± d·n (PROCESS.md §1, eq. 2), with the default options: a
    /// fold-over is an error, spline offsets are within 1 µm.
    pub fn offset(&self, d: f64) -> Result<Profile, GeomError> {
        self.offset_with(d, &OffsetOptions::default())
    }

    /// The signed offset to the left of travel that `d` means (see the module header).
    pub fn left_offset(&self, d: f64) -> f64 {
        if self.closed {
            if self.signed_area() > 0.0 { -d } else { d }
        } else {
            d
        }
    }

    /// The offset curve with explicit options.
    pub fn offset_with(&self, d: f64, opts: &OffsetOptions) -> Result<Profile, GeomError> {
        if !d.is_finite() {
            return Err(GeomError::Degenerate(format!(
                "an offset distance must be a finite number, got {d}"
            )));
        }
        if !(opts.tol_mm > 0.0 && opts.tol_mm.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "an offset tolerance must be positive, got {} mm",
                opts.tol_mm
            )));
        }
        if d == 0.0 {
            return Ok(self.clone());
        }
        // A crossing closed profile has no one outside: the offset would trace one lobe and
        // drop the rest without a word.
        if self.closed
            && let Some(near) = self.crossing()
        {
            return Err(GeomError::Crosses { near });
        }
        let left = self.left_offset(d);
        if !opts.trim
            && let Some(r) = self.fold_over_regions(d).first()
        {
            return Err(GeomError::FoldOver {
                segment: r.segment,
                radius: r.min_radius,
                distance: d.abs(),
                s_start: r.s_start,
                s_end: r.s_end,
                spline: self.spline.is_some(),
            });
        }
        match (&self.spline, opts.trim) {
            (Some(sp), false) => spline_offset(sp, left, opts.tol_mm),
            (Some(_), true) => line_arc_offset(&self.to_line_arc(0.5 * opts.tol_mm)?, left),
            (None, _) => line_arc_offset(self, left),
        }
    }

    /// A point where the profile crosses or touches itself away from the joints of
    /// neighbouring segments (a bow-tie's waist), if there is one. Near-linear: crossings are
    /// found through an AABB index of the segments.
    pub fn crossing(&self) -> Option<V2> {
        first_crossing(self)
    }

    /// Every region where offsetting by `d` folds over: `κ ℓ ≥ 1`, i.e. the center of
    /// curvature lies on the offset side at a radius not larger than |d| (seed 2's rule).
    /// Ordered along the profile.
    pub fn fold_over_regions(&self, d: f64) -> Vec<FoldRegion> {
        if !d.is_finite() || d == 0.0 {
            return Vec::new();
        }
        let left = self.left_offset(d);
        match &self.spline {
            Some(sp) => spline_fold_regions(sp, left),
            None => {
                let mut out: Vec<FoldRegion> = Vec::new();
                let mut s = 0.0;
                for (i, seg) in self.segs.iter().enumerate() {
                    let l = seg.length();
                    if let Seg::Arc { r, .. } = seg
                        && seg.curvature() * left >= 1.0 - 1e-12
                    {
                        match out.last_mut() {
                            Some(prev) if (prev.s_end - s).abs() <= 1e-9 => {
                                prev.s_end = s + l;
                                if *r < prev.min_radius {
                                    prev.min_radius = *r;
                                    prev.s_min = s + 0.5 * l;
                                    prev.segment = i;
                                }
                            }
                            _ => out.push(FoldRegion {
                                s_start: s,
                                s_end: s + l,
                                min_radius: *r,
                                s_min: s + 0.5 * l,
                                segment: i,
                            }),
                        }
                    }
                    s += l;
                }
                out
            }
        }
    }
}

/// Exact offset of a line/arc profile by `left` (cavalier_contours offsets to the left of
/// travel for positive values and trims self-intersections).
fn line_arc_offset(p: &Profile, left: f64) -> Result<Profile, GeomError> {
    let pl = p.to_pline();
    let result = std::panic::catch_unwind(|| pl.parallel_offset(left)).map_err(|_| {
        GeomError::Degenerate("the offset could not be computed for this profile".into())
    })?;
    if result.len() != 1 {
        return Err(GeomError::Split {
            loops: result.len(),
        });
    }
    if p.closed {
        // An inward offset that collapses to a sliver (zero area) or turns inside out has
        // vanished, whatever the library returned.
        let a0 = pl.area();
        let a1 = result[0].area();
        if a1.abs() < 1e-9 || a1.signum() != a0.signum() {
            return Err(GeomError::Split { loops: 0 });
        }
    }
    let mut o = Profile::from_pline(&result[0]);
    if o.segs.is_empty() {
        return Err(GeomError::Split { loops: 0 });
    }
    if p.closed {
        o = o.rotated_to_start_near(p.start());
    }
    Ok(o)
}

/// The exact offset point and the spline parameter it belongs to.
fn exact_offset_point(sp: &Spline, u: f64, left: f64) -> V2 {
    let (p, d1, _) = sp.derivs(u);
    let t = d1.try_normalize(0.0).unwrap_or(V2::x());
    p + V2::new(-t.y, t.x) * left
}

/// Offset of a spline within `tol`: fit a B-spline through `k` exact offset samples per span,
/// check it against the exact offset midway between samples, double `k` until within `tol`.
fn spline_offset(sp: &Spline, left: f64, tol: f64) -> Result<Profile, GeomError> {
    let n = sp.span_count();
    let closed = sp.is_closed();
    let mut worst = f64::INFINITY;
    for k in [1usize, 2, 4, 8, 16, 32, 64] {
        let count = n * k + usize::from(!closed);
        let pts: Vec<V2> = (0..count)
            .map(|i| exact_offset_point(sp, i as f64 / k as f64, left))
            .collect();
        let fit = Spline::interpolate(&pts, closed)?;
        worst = 0.0;
        for m in 0..fit.span_count() {
            for tau in [0.25, 0.5, 0.75] {
                let uf = m as f64 + tau;
                let e = (fit.derivs(uf).0 - exact_offset_point(sp, uf / k as f64, left)).norm();
                worst = worst.max(e);
            }
        }
        if worst <= tol {
            let o = Profile::from_spline(fit);
            check_self_intersection(&o)?;
            return Ok(o);
        }
    }
    Err(GeomError::Degenerate(format!(
        "the spline offset could not be fitted within {tol} mm (best {worst} mm); use a larger tolerance"
    )))
}

/// An offset that crosses itself away from a fold-over (a neck narrower than 2|d|) is as
/// unusable as a folded one.
fn check_self_intersection(o: &Profile) -> Result<(), GeomError> {
    match first_crossing(o) {
        Some(near) => Err(GeomError::SelfIntersects { near }),
        None => Ok(()),
    }
}

/// The first crossing of `o` with itself that is not the joint of neighbouring segments.
fn first_crossing(o: &Profile) -> Option<V2> {
    if o.segs.len() < 3 {
        return None;
    }
    let pl = o.to_pline();
    let index = pl.create_approx_aabb_index();
    let hits = pline_intersects::all_self_intersects_as_basic(&pl, &index, false, 1e-9);
    // Consecutive segments (and biarc pieces) touch at their joints; only other meetings count.
    let nseg = o.segs.len();
    hits.into_iter()
        .find(|h| {
            let (i, j) = (h.start_index1, h.start_index2);
            !(i.abs_diff(j) <= 1 || (o.closed && i.abs_diff(j) == nseg - 1))
        })
        .map(|h| V2::new(h.point.x, h.point.y))
}

/// Fold regions of a spline: samples of `κ ℓ − 1` per span, local maxima refined by golden
/// section (so a short sharp region between samples is not missed), region ends by bisection.
fn spline_fold_regions(sp: &Spline, left: f64) -> Vec<FoldRegion> {
    let n = sp.span_count();
    let h = |u: f64| -> f64 {
        let (_, d1, d2) = sp.derivs(u);
        let sp3 = d1.norm().powi(3);
        if sp3 > 0.0 {
            (d1.x * d2.y - d1.y * d2.x) / sp3 * left - 1.0
        } else {
            -1.0
        }
    };
    const M: usize = 16;
    let mut us: Vec<f64> = Vec::with_capacity(n * M + 1);
    for j in 0..n {
        for i in 0..M {
            us.push(j as f64 + i as f64 / M as f64);
        }
    }
    us.push(n as f64);
    let mut hs: Vec<f64> = us.iter().map(|&u| h(u)).collect();
    // Refine interior local maxima that stay below zero but might cross it between samples.
    let mut extra: Vec<(f64, f64)> = Vec::new();
    for k in 1..us.len() - 1 {
        if hs[k] >= hs[k - 1] && hs[k] >= hs[k + 1] && hs[k] > -0.5 {
            let (mut a, mut b) = (us[k - 1], us[k + 1]);
            let g = 0.618_033_988_749_894_9;
            for _ in 0..60 {
                let x1 = b - g * (b - a);
                let x2 = a + g * (b - a);
                if h(x1) >= h(x2) {
                    b = x2;
                } else {
                    a = x1;
                }
            }
            let u = 0.5 * (a + b);
            extra.push((u, h(u)));
        }
    }
    if !extra.is_empty() {
        let mut all: Vec<(f64, f64)> = us.iter().copied().zip(hs.iter().copied()).collect();
        all.extend(extra);
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        us = all.iter().map(|p| p.0).collect();
        hs = all.iter().map(|p| p.1).collect();
    }
    let bisect = |mut a: f64, mut b: f64| -> f64 {
        // h(a) < 0 ≤ h(b) or the reverse; returns the crossing.
        let sa = h(a) >= 0.0;
        for _ in 0..60 {
            let m = 0.5 * (a + b);
            if (h(m) >= 0.0) == sa {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    };
    let mut out = Vec::new();
    let mut k = 0;
    while k < us.len() {
        if hs[k] < 0.0 {
            k += 1;
            continue;
        }
        let u0 = if k == 0 {
            us[0]
        } else {
            bisect(us[k - 1], us[k])
        };
        let mut best = (us[k], hs[k]);
        while k < us.len() && hs[k] >= 0.0 {
            if hs[k] > best.1 {
                best = (us[k], hs[k]);
            }
            k += 1;
        }
        let u1 = if k == us.len() {
            us[us.len() - 1]
        } else {
            bisect(us[k - 1], us[k])
        };
        // κ ℓ = h + 1, so the smallest radius is |ℓ| / (h + 1).
        let min_radius = left.abs() / (best.1 + 1.0);
        out.push(FoldRegion {
            s_start: sp.length_at_param(u0),
            s_end: sp.length_at_param(u1),
            min_radius,
            s_min: sp.length_at_param(best.0),
            segment: (best.0.floor() as usize).min(n - 1),
        });
    }
    out
}
