//! Resampling a profile at a constant arc-length step with a chord-error bound (PROCESS.md §1:
//! "discretize the cam contour into a polyline at a step Δt chosen for the chord tolerance";
//! equal steps in equal times give constant surface speed).
//!
//! Each sample carries the exact frame (point, unit tangent, left normal, signed curvature), so
//! the kinematics never has to estimate normals from neighbouring points. The chord deviation
//! is measured, not only predicted: the distance from the curve's arc-length midpoint between
//! two samples to their chord (exact for arcs, the maximum to within higher-order terms for a
//! smooth spline span).

use super::biarc::line_distance;
use super::{Frame, GeomError, Profile, Seg, Spline, V2};

/// One resampled point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Arc length from the profile start, mm.
    pub s: f64,
    pub point: V2,
    /// Unit tangent in the direction of travel.
    pub tangent: V2,
    /// Unit normal to the left of travel.
    pub left: V2,
    /// Signed curvature, 1/mm (positive turning counter-clockwise).
    pub curvature: f64,
}

impl From<Frame> for Sample {
    fn from(f: Frame) -> Sample {
        Sample {
            s: f.s,
            point: f.point,
            tangent: f.tangent,
            left: f.left,
            curvature: f.curvature,
        }
    }
}

/// The result of a resampling.
#[derive(Debug, Clone, PartialEq)]
pub struct Resampled {
    /// From s = 0 to s = length, both included (a closed profile's last sample repeats the
    /// first point).
    pub samples: Vec<Sample>,
    /// The step used, mm: every step has this length except possibly the last.
    pub step: f64,
    /// Largest measured distance between the profile and a chord, over chords that do not
    /// straddle a corner, mm.
    pub max_chord_error: f64,
    /// Arc lengths of tangent discontinuities (corners of line/arc profiles). A constant-step
    /// path cuts them; the chords across them are reported in `corner_chord_error`.
    pub corners: Vec<f64>,
    pub corner_chord_error: f64,
}

/// Evaluates frames at increasing arc lengths in one pass (O(1) amortized per sample).
struct Walker<'a> {
    profile: &'a Profile,
    cum: Vec<f64>,
    k: usize,
}

impl<'a> Walker<'a> {
    fn new(profile: &'a Profile) -> Walker<'a> {
        let cum = match profile.as_spline() {
            Some(sp) => sp.span_starts().to_vec(),
            None => {
                let mut c = Vec::with_capacity(profile.segs.len() + 1);
                let mut t = 0.0;
                c.push(0.0);
                for s in &profile.segs {
                    t += s.length();
                    c.push(t);
                }
                c
            }
        };
        Walker { profile, cum, k: 0 }
    }

    fn frame(&mut self, s: f64) -> Frame {
        let pieces = self.cum.len() - 1;
        while self.k > 0 && s < self.cum[self.k] {
            self.k -= 1;
        }
        while self.k + 1 < pieces && self.cum[self.k + 1] < s {
            self.k += 1;
        }
        let local = (s - self.cum[self.k]).max(0.0);
        match self.profile.as_spline() {
            Some(sp) => spline_frame_in_span(sp, self.k, local, s),
            None => {
                let seg: &Seg = &self.profile.segs[self.k];
                Frame::new(
                    s,
                    seg.point_at(local),
                    seg.tangent_at(local),
                    seg.curvature(),
                )
            }
        }
    }
}

fn spline_frame_in_span(sp: &Spline, j: usize, local: f64, s: f64) -> Frame {
    let t = sp.invert_in_span(j, local);
    let (p, d1, d2) = sp.span_derivs(j, t);
    let speed = d1.norm();
    if speed > 0.0 {
        let k = (d1.x * d2.y - d1.y * d2.x) / (speed * speed * speed);
        Frame::new(s, p, d1 / speed, k)
    } else {
        Frame::new(s, p, d2.try_normalize(0.0).unwrap_or(V2::x()), 0.0)
    }
}

/// Largest |curvature| of the profile (spline: sampled 8 times per span, with 10% margin).
fn max_curvature(p: &Profile) -> f64 {
    match p.as_spline() {
        Some(sp) => {
            let mut k: f64 = 0.0;
            for j in 0..sp.span_count() {
                for i in 0..=8 {
                    let (_, d1, d2) = sp.span_derivs(j, i as f64 / 8.0);
                    let v3 = d1.norm().powi(3);
                    if v3 > 0.0 {
                        k = k.max(((d1.x * d2.y - d1.y * d2.x) / v3).abs());
                    }
                }
            }
            1.1 * k
        }
        None => p
            .segs
            .iter()
            .map(|s| s.curvature().abs())
            .fold(0.0, f64::max),
    }
}

/// Arc lengths where the tangent jumps by more than 1e-7 rad.
fn corners(p: &Profile) -> Vec<f64> {
    if p.as_spline().is_some() {
        return Vec::new();
    }
    let mut out = Vec::new();
    let n = p.segs.len();
    let mut s = 0.0;
    for i in 0..n {
        s += p.segs[i].length();
        let next = if i + 1 < n {
            Some(&p.segs[i + 1])
        } else if p.closed {
            Some(&p.segs[0])
        } else {
            None
        };
        if let Some(nx) = next {
            let t0 = p.segs[i].tangent_at(p.segs[i].length());
            let t1 = nx.tangent_at(0.0);
            if (t0.x * t1.y - t0.y * t1.x).atan2(t0.dot(&t1)).abs() > 1e-7 {
                out.push(if i + 1 < n { s } else { 0.0 });
            }
        }
    }
    out.sort_by(f64::total_cmp);
    out
}

/// Upper bound on the number of samples one call may produce.
const MAX_SAMPLES: f64 = 5e7;

impl Profile {
    /// Samples at s = 0, p, 2p, … and at the end (the last step may be shorter). With a chord
    /// tolerance the step is reduced below `p` until every measured chord deviation is within
    /// it (first predicted from the largest curvature: a chord of length h on radius R deviates
    /// by R(1 − cos(h / 2R))).
    pub fn resample(&self, step: f64, chord_tol: Option<f64>) -> Result<Resampled, GeomError> {
        self.resample_impl(step, chord_tol, false)
    }

    /// Like `resample`, with the step shortened so that all steps are equal and the last
    /// sample lands on the end (what a closed path at constant speed wants).
    pub fn resample_even(
        &self,
        max_step: f64,
        chord_tol: Option<f64>,
    ) -> Result<Resampled, GeomError> {
        self.resample_impl(max_step, chord_tol, true)
    }

    fn resample_impl(
        &self,
        step: f64,
        chord_tol: Option<f64>,
        even: bool,
    ) -> Result<Resampled, GeomError> {
        if !(step > 0.0 && step.is_finite()) {
            return Err(GeomError::Degenerate(format!(
                "a resampling step must be positive, got {step} mm"
            )));
        }
        if let Some(t) = chord_tol
            && !(t > 0.0 && t.is_finite())
        {
            return Err(GeomError::Degenerate(format!(
                "a chord tolerance must be positive, got {t} mm"
            )));
        }
        if self.segs.is_empty() {
            return Err(GeomError::TooFewPoints(0));
        }
        let total = self.length();
        if !(total > 0.0 && total.is_finite()) {
            return Err(GeomError::Degenerate(
                "the profile has no length to resample".into(),
            ));
        }
        let mut h = step;
        if let Some(tol) = chord_tol {
            let k = max_curvature(self);
            if k > 0.0 {
                let r = 1.0 / k;
                let c = (1.0 - tol / r).clamp(-1.0, 1.0);
                h = h.min(2.0 * r * c.acos());
            }
        }
        let corner_s = corners(self);
        for _attempt in 0..12 {
            if even {
                h = total / (total / h).ceil().max(1.0);
            }
            if total / h > MAX_SAMPLES {
                return Err(GeomError::Degenerate(format!(
                    "resampling {total} mm at a {h} mm step needs more than {MAX_SAMPLES} points"
                )));
            }
            let count = (total / h).ceil() as usize;
            let mut positions: Vec<f64> = (0..count).map(|i| i as f64 * h).collect();
            // A final step shorter than a billionth of the step is rounding, not a step.
            if let Some(&last) = positions.last()
                && total - last <= 1e-9 * h
            {
                positions.pop();
            }
            positions.push(total);
            let mut w = Walker::new(self);
            let mut samples = Vec::with_capacity(positions.len());
            let mut max_err: f64 = 0.0;
            let mut corner_err: f64 = 0.0;
            let mut ci = 0;
            for (i, &s) in positions.iter().enumerate() {
                if i > 0 {
                    let s0 = positions[i - 1];
                    let mid = w.frame(0.5 * (s0 + s)).point;
                    let a: &Sample = &samples[i - 1];
                    let a = a.point;
                    let f = w.frame(s);
                    let mut e = line_distance(a, f.point, mid);
                    while ci < corner_s.len() && corner_s[ci] <= s0 {
                        ci += 1;
                    }
                    let straddles = ci < corner_s.len() && corner_s[ci] < s;
                    if straddles {
                        let c = w.frame(corner_s[ci]).point;
                        e = e.max(line_distance(a, f.point, c));
                        corner_err = corner_err.max(e);
                        w.frame(s);
                    } else {
                        max_err = max_err.max(e);
                    }
                    samples.push(Sample::from(f));
                } else {
                    samples.push(Sample::from(w.frame(s)));
                }
            }
            match chord_tol {
                Some(tol) if max_err > tol => {
                    h *= 0.95 * (tol / max_err).sqrt();
                }
                _ => {
                    return Ok(Resampled {
                        samples,
                        step: h,
                        max_chord_error: max_err,
                        corners: corner_s,
                        corner_chord_error: corner_err,
                    });
                }
            }
        }
        Err(GeomError::Degenerate(format!(
            "no step met the chord tolerance of {} mm",
            chord_tol.unwrap_or(0.0)
        )))
    }
}
