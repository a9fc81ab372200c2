//! Uniform cubic B-splines interpolating measured points (PROCESS.md §2, step 1): the
//! "inverse calculation" of control points P_j from the points Q_j through
//! `P_{j−1} + 4 P_j + P_{j+1} = 6 Q_j`, their exact evaluation (point and derivatives per
//! span), and arc length by adaptive Gauss–Legendre quadrature with Newton inversion.
//!
//! Parameterization follows the seed: one unit of parameter per span, the curve passing Q_j at
//! parameter j. Open splines use natural end conditions (zero second derivative at both
//! ends: `P_{−1} − 2 P_0 + P_1 = 0`, which with the interpolation row gives `P_0 = Q_0`); closed
//! splines wrap the indices (`P_n = P_0`), giving a cyclic tridiagonal system solved with the
//! Thomas algorithm plus a Sherman–Morrison correction for the two corner entries.

use super::{GeomError, V2};
use serde::{Deserialize, Serialize};

/// Nodes and weights of the 10-point Gauss–Legendre rule on [−1, 1] (symmetric half).
const GL_X: [f64; 5] = [
    0.148_874_338_981_631_2,
    0.433_395_394_129_247_2,
    0.679_409_568_299_024_4,
    0.865_063_366_688_984_5,
    0.973_906_528_517_171_7,
];
const GL_W: [f64; 5] = [
    0.295_524_224_714_752_9,
    0.269_266_719_309_996_4,
    0.219_086_362_515_982,
    0.149_451_349_150_580_6,
    0.066_671_344_308_688_1,
];

/// Integral of `f` over [a, b] with the 10-point Gauss–Legendre rule.
pub(crate) fn gauss10(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let h = 0.5 * (b - a);
    let m = 0.5 * (a + b);
    let mut sum = 0.0;
    for k in 0..5 {
        let dx = h * GL_X[k];
        sum += GL_W[k] * (f(m - dx) + f(m + dx));
    }
    sum * h
}

/// Adaptive Gauss–Legendre: split until the whole-interval rule agrees with the two halves.
pub(crate) fn gauss_adaptive(f: &impl Fn(f64) -> f64, a: f64, b: f64, tol: f64) -> f64 {
    fn rec(f: &impl Fn(f64) -> f64, a: f64, b: f64, whole: f64, tol: f64, depth: u32) -> f64 {
        let m = 0.5 * (a + b);
        let l = gauss10(f, a, m);
        let r = gauss10(f, m, b);
        if depth == 0 || (l + r - whole).abs() <= tol {
            l + r
        } else {
            rec(f, a, m, l, 0.5 * tol, depth - 1) + rec(f, m, b, r, 0.5 * tol, depth - 1)
        }
    }
    rec(f, a, b, gauss10(f, a, b), tol, 30)
}

/// A cubic B-spline with uniform knots through a list of points, open or closed.
///
/// Each span is kept in power form `a + b t + c t² + d t³`, `t ∈ [0, 1]`, which is exact (it is
/// the same polynomial as the B-spline basis form) and cheap to evaluate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Spline {
    closed: bool,
    /// The interpolated points Q_j (for a closed spline without the repeated first point).
    through: Vec<V2>,
    /// Control points: open `[P_{−1}, P_0, …, P_n, P_{n+1}]`; closed `[P_0, …, P_{n−1}]`.
    ctrl: Vec<V2>,
    spans: Vec<[V2; 4]>,
    /// Arc length at the start of each span, plus the total at the end.
    cum: Vec<f64>,
    /// For a curve built from exact data ([`Spline::hermite`], a cam from its motion law): the
    /// exact signed curvature just before and just after each point in `through` (they differ
    /// where the law's acceleration jumps). Empty for an interpolating B-spline, whose spans
    /// are the curve itself.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    knot_curvature: Vec<[f64; 2]>,
}

/// Solves the (1, 4, 1) tridiagonal system `x_{j−1} + 4 x_j + x_{j+1} = rhs_j` (Thomas).
fn thomas_141(rhs: &[V2]) -> Vec<V2> {
    let n = rhs.len();
    let mut c = vec![0.0; n];
    let mut d = vec![V2::zeros(); n];
    let mut beta = 4.0;
    d[0] = rhs[0] / beta;
    for j in 1..n {
        c[j - 1] = 1.0 / beta;
        beta = 4.0 - c[j - 1];
        d[j] = (rhs[j] - d[j - 1]) / beta;
    }
    for j in (0..n.saturating_sub(1)).rev() {
        let next = d[j + 1];
        d[j] -= next * c[j];
    }
    d
}

/// Solves the cyclic (1, 4, 1) system of a closed spline (PROCESS.md §2: `P_n = P_0`, the
/// corner entries) with Sherman–Morrison: A = B + u vᵀ, B tridiagonal, u = (γ, 0…0, 1),
/// v = (1, 0…0, 1/γ).
fn cyclic_141(rhs: &[V2]) -> Vec<V2> {
    let n = rhs.len();
    let gamma = -4.0;
    // B: diagonal 4 except b0 = 4 − γ and b_{n−1} = 4 − 1/γ.
    let solve = |r: &[V2]| -> Vec<V2> {
        let mut diag = vec![4.0; n];
        diag[0] = 4.0 - gamma;
        diag[n - 1] = 4.0 - 1.0 / gamma;
        let mut c = vec![0.0; n];
        let mut d = vec![V2::zeros(); n];
        let mut beta = diag[0];
        d[0] = r[0] / beta;
        for j in 1..n {
            c[j - 1] = 1.0 / beta;
            beta = diag[j] - c[j - 1];
            d[j] = (r[j] - d[j - 1]) / beta;
        }
        for j in (0..n - 1).rev() {
            let next = d[j + 1];
            d[j] -= next * c[j];
        }
        d
    };
    let x = solve(rhs);
    let mut u = vec![V2::zeros(); n];
    u[0] = V2::new(gamma, gamma);
    u[n - 1] = V2::new(1.0, 1.0);
    let z = solve(&u);
    // Both coordinates share the matrix, so z's two columns are equal; use x's component.
    let mut out = x.clone();
    for k in 0..2 {
        let fact = (x[0][k] + x[n - 1][k] / gamma) / (1.0 + z[0][k] + z[n - 1][k] / gamma);
        for j in 0..n {
            out[j][k] = x[j][k] - fact * z[j][k];
        }
    }
    out
}

/// Power-form coefficients of the uniform cubic B-spline span with control points p0..p3.
fn span_coeffs(p0: V2, p1: V2, p2: V2, p3: V2) -> [V2; 4] {
    [
        (p0 + p1 * 4.0 + p2) / 6.0,
        (p2 - p0) / 2.0,
        (p0 - p1 * 2.0 + p2) / 2.0,
        (p3 - p0 + (p1 - p2) * 3.0) / 6.0,
    ]
}

/// Checks points for NaN and coincident neighbours; drops a closing duplicate.
fn clean_points(points: &[V2], closed: bool) -> Result<Vec<V2>, GeomError> {
    if let Some(i) = points
        .iter()
        .position(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(GeomError::Degenerate(format!(
            "point {} of the spline is not a finite number",
            i + 1
        )));
    }
    let mut q = points.to_vec();
    if closed && q.len() > 1 && (q[0] - q[q.len() - 1]).norm() <= 1e-9 {
        q.pop();
    }
    let need = if closed { 3 } else { 2 };
    if q.len() < need {
        return Err(GeomError::TooFewPoints(q.len()));
    }
    let m = if closed { q.len() } else { q.len() - 1 };
    for j in 0..m {
        let k = (j + 1) % q.len();
        if (q[k] - q[j]).norm() <= 1e-9 {
            return Err(GeomError::Degenerate(format!(
                "spline points {} and {} coincide; a uniform B-spline needs distinct neighbours",
                j + 1,
                k + 1
            )));
        }
    }
    Ok(q)
}

impl Spline {
    /// Interpolates `points` (PROCESS.md §2 step 1). Open: natural ends, `n` points give
    /// `n − 1` spans. Closed: the cyclic system, `n` points give `n` spans and the curve is C²
    /// everywhere including the seam.
    pub fn interpolate(points: &[V2], closed: bool) -> Result<Spline, GeomError> {
        let q = clean_points(points, closed)?;
        let n = q.len();
        let (ctrl, spans) = if closed {
            let rhs: Vec<V2> = q.iter().map(|p| p * 6.0).collect();
            let p = cyclic_141(&rhs);
            let spans = (0..n)
                .map(|j| span_coeffs(p[(j + n - 1) % n], p[j], p[(j + 1) % n], p[(j + 2) % n]))
                .collect();
            (p, spans)
        } else {
            // Unknowns P_1..P_{m−1} with P_0 = Q_0 and P_m = Q_m (natural ends), m = n − 1.
            let m = n - 1;
            let mut p = vec![V2::zeros(); m + 3];
            p[1] = q[0];
            p[m + 1] = q[m];
            if m >= 2 {
                let mut rhs: Vec<V2> = (1..m).map(|j| q[j] * 6.0).collect();
                rhs[0] -= q[0];
                rhs[m - 2] -= q[m];
                let inner = thomas_141(&rhs);
                for (k, v) in inner.into_iter().enumerate() {
                    p[k + 2] = v;
                }
            }
            p[0] = p[1] * 2.0 - p[2];
            p[m + 2] = p[m + 1] * 2.0 - p[m];
            let spans = (0..m)
                .map(|j| span_coeffs(p[j], p[j + 1], p[j + 2], p[j + 3]))
                .collect();
            (p, spans)
        };
        let mut s = Spline {
            closed,
            through: q,
            ctrl,
            spans,
            cum: Vec::new(),
            knot_curvature: Vec::new(),
        };
        s.rebuild_lengths()?;
        Ok(s)
    }

    /// A C¹ curve from exact data (issue 13 item 5): `points[j]` at parameter `knots[j]`
    /// (increasing), with the derivative `slopes[j]` = dP/dknot there and the exact one-sided
    /// signed curvature `curvature[j]` = [before, after]; one cubic Hermite span between
    /// neighbours. Each span depends on its own two ends only, so nothing is smoothed across a
    /// knot where the curvature jumps: put a knot at every such place. Closed: the last point
    /// repeats the first (one span per point).
    pub fn hermite(
        knots: &[f64],
        points: &[V2],
        slopes: &[V2],
        curvature: &[[f64; 2]],
        closed: bool,
    ) -> Result<Spline, GeomError> {
        let n = points.len();
        if n < 2 || knots.len() != n || slopes.len() != n || curvature.len() != n {
            return Err(GeomError::TooFewPoints(n));
        }
        let finite = |v: &V2| v.x.is_finite() && v.y.is_finite();
        if !(points.iter().all(finite) && slopes.iter().all(finite))
            || knots.windows(2).any(|w| !(w[1] > w[0]))
        {
            return Err(GeomError::Degenerate(
                "a Hermite curve needs finite points and increasing knots".into(),
            ));
        }
        let spans = (0..n - 1)
            .map(|j| {
                let h = knots[j + 1] - knots[j];
                let (p0, p1) = (points[j], points[j + 1]);
                let (d0, d1) = (slopes[j] * h, slopes[j + 1] * h);
                [
                    p0,
                    d0,
                    (p1 - p0) * 3.0 - d0 * 2.0 - d1,
                    (p0 - p1) * 2.0 + d0 + d1,
                ]
            })
            .collect();
        let keep = if closed { n - 1 } else { n };
        let mut kc = curvature[..keep].to_vec();
        if closed {
            // The seam: arriving at the last point is arriving at the first.
            kc[0][0] = curvature[n - 1][0];
        }
        let mut s = Spline {
            closed,
            through: points[..keep].to_vec(),
            ctrl: Vec::new(),
            spans,
            cum: Vec::new(),
            knot_curvature: kc,
        };
        s.rebuild_lengths()?;
        Ok(s)
    }

    /// The exact curvature at the knots, when the curve was built from exact data: for each
    /// point in `through_points`, its arc length and signed curvature [before, after].
    pub fn exact_knots(&self) -> Option<impl Iterator<Item = (f64, [f64; 2])> + '_> {
        if self.knot_curvature.is_empty() {
            return None;
        }
        Some(
            self.knot_curvature
                .iter()
                .enumerate()
                .map(|(j, k)| (self.cum[j], *k)),
        )
    }

    fn rebuild_lengths(&mut self) -> Result<(), GeomError> {
        let mut cum = Vec::with_capacity(self.spans.len() + 1);
        cum.push(0.0);
        let mut total = 0.0;
        for j in 0..self.spans.len() {
            let l = self.span_length(j, 0.0, 1.0);
            if !l.is_finite() {
                return Err(GeomError::Degenerate(
                    "the spline's length is not a finite number".into(),
                ));
            }
            total += l;
            cum.push(total);
        }
        self.cum = cum;
        Ok(())
    }

    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The points the spline interpolates.
    pub fn through_points(&self) -> &[V2] {
        &self.through
    }

    /// The control points (open: including the two phantom end points P_{−1}, P_{n+1}).
    pub fn control_points(&self) -> &[V2] {
        &self.ctrl
    }

    pub fn span_count(&self) -> usize {
        self.spans.len()
    }

    pub fn length(&self) -> f64 {
        self.cum[self.cum.len() - 1]
    }

    /// Arc length at the start of each span, and the total length last.
    pub fn span_starts(&self) -> &[f64] {
        &self.cum
    }

    /// Splits a global parameter `u ∈ [0, spans]` into (span, local t).
    fn split(&self, u: f64) -> (usize, f64) {
        let n = self.spans.len();
        let u = if u.is_nan() {
            0.0
        } else {
            u.clamp(0.0, n as f64)
        };
        let j = (u.floor() as usize).min(n - 1);
        (j, u - j as f64)
    }

    /// Point and first two derivatives with respect to the parameter at `u ∈ [0, spans]`.
    pub fn derivs(&self, u: f64) -> (V2, V2, V2) {
        let (j, t) = self.split(u);
        self.span_derivs(j, t)
    }

    /// Point and first two derivatives in span `j` at local parameter `t ∈ [0, 1]`.
    pub fn span_derivs(&self, j: usize, t: f64) -> (V2, V2, V2) {
        let [a, b, c, d] = self.spans[j];
        let p = a + (b + (c + d * t) * t) * t;
        let d1 = b + (c * 2.0 + d * (3.0 * t)) * t;
        let d2 = c * 2.0 + d * (6.0 * t);
        (p, d1, d2)
    }

    fn speed(&self, j: usize, t: f64) -> f64 {
        let [_, b, c, d] = self.spans[j];
        (b + (c * 2.0 + d * (3.0 * t)) * t).norm()
    }

    /// Arc length of span `j` between local parameters t0 and t1.
    fn span_length(&self, j: usize, t0: f64, t1: f64) -> f64 {
        let f = |t: f64| self.speed(j, t);
        let scale = (self.spans[j][1].norm() + self.spans[j][2].norm() + self.spans[j][3].norm())
            .max(1e-300);
        gauss_adaptive(&f, t0, t1, 1e-14 * scale)
    }

    /// Arc length from the start to parameter `u`.
    pub fn length_at_param(&self, u: f64) -> f64 {
        let (j, t) = self.split(u);
        self.cum[j] + self.span_length(j, 0.0, t)
    }

    /// The parameter at arc length `s` (clamped to the curve), by Newton's method on
    /// `L(t) − s` safeguarded by bisection; accurate to about 1e-12 mm.
    pub fn param_at_length(&self, s: f64) -> f64 {
        let total = self.length();
        let s = if s.is_nan() { 0.0 } else { s.clamp(0.0, total) };
        // Span holding s: the last span whose start is ≤ s.
        let j = match self.cum.binary_search_by(|c| c.total_cmp(&s)) {
            Ok(k) => k.min(self.spans.len() - 1),
            Err(k) => k.saturating_sub(1).min(self.spans.len() - 1),
        };
        j as f64 + self.invert_in_span(j, s - self.cum[j])
    }

    /// Local parameter in span `j` where the arc length from the span start is `target`.
    pub(crate) fn invert_in_span(&self, j: usize, target: f64) -> f64 {
        let len = self.cum[j + 1] - self.cum[j];
        if !(len > 0.0) {
            return 0.0;
        }
        if target <= 0.0 {
            return 0.0;
        }
        if target >= len {
            return 1.0;
        }
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        let mut t = target / len;
        let mut lt = self.span_length(j, 0.0, t);
        for _ in 0..60 {
            let f = lt - target;
            if f.abs() <= 1e-13 * len.max(1.0) {
                break;
            }
            if f > 0.0 {
                hi = t;
            } else {
                lo = t;
            }
            let sp = self.speed(j, t);
            let mut next = if sp > 0.0 { t - f / sp } else { f64::NAN };
            if !(next > lo && next < hi) {
                next = 0.5 * (lo + hi);
            }
            // The step is short after the first iterations, so one Gauss rule is exact enough.
            let step = if (next - t).abs() < 0.05 {
                gauss10(&|x| self.speed(j, x), t, next)
            } else {
                self.span_length(j, t.min(next), t.max(next)) * (next - t).signum()
            };
            lt += step;
            t = next;
            if hi - lo < 1e-15 {
                break;
            }
        }
        t
    }

    /// The same curve traversed backwards (closed: starting at the same point).
    pub fn reversed(&self) -> Spline {
        if !self.knot_curvature.is_empty() {
            return self.reversed_spans();
        }
        if self.closed {
            let mut through: Vec<V2> = self.through.iter().rev().copied().collect();
            through.rotate_right(1);
            // Reversing a uniform B-spline reverses its control polygon; the span ending at
            // Q_0 must come first, which the rotation above and below arranges.
            let mut ctrl: Vec<V2> = self.ctrl.iter().rev().copied().collect();
            ctrl.rotate_right(1);
            Spline::from_ctrl(true, through, ctrl)
        } else {
            Spline::from_ctrl(
                false,
                self.through.iter().rev().copied().collect(),
                self.ctrl.iter().rev().copied().collect(),
            )
        }
    }

    /// A Hermite curve backwards: each span's polynomial in 1 − t, in reverse order (closed:
    /// the span that ends at the first point comes first); curvatures change sign and side.
    fn reversed_spans(&self) -> Spline {
        let spans = self
            .spans
            .iter()
            .rev()
            .map(|&[a, b, c, d]| [a + b + c + d, -(b + c * 2.0 + d * 3.0), c + d * 3.0, -d])
            .collect();
        let flip = |k: &[f64; 2]| [-k[1], -k[0]];
        let (mut through, mut kc): (Vec<V2>, Vec<[f64; 2]>) = (
            self.through.iter().rev().copied().collect(),
            self.knot_curvature.iter().rev().map(flip).collect(),
        );
        if self.closed {
            through.rotate_right(1);
            kc.rotate_right(1);
        }
        let mut s = Spline {
            closed: self.closed,
            through,
            ctrl: Vec::new(),
            spans,
            cum: Vec::new(),
            knot_curvature: kc,
        };
        // The source was finite, and a reversal keeps it so.
        let _ = s.rebuild_lengths();
        s
    }

    /// The spline under a rigid motion (rotation by `angle` about the origin, then `shift`).
    pub fn transformed(&self, angle: f64, shift: V2) -> Spline {
        let rot = nalgebra::Rotation2::new(angle);
        if !self.knot_curvature.is_empty() {
            let mut s = Spline {
                closed: self.closed,
                through: self.through.iter().map(|p| rot * p + shift).collect(),
                ctrl: Vec::new(),
                spans: self
                    .spans
                    .iter()
                    .map(|&[a, b, c, d]| [rot * a + shift, rot * b, rot * c, rot * d])
                    .collect(),
                cum: Vec::new(),
                knot_curvature: self.knot_curvature.clone(),
            };
            // A rigid motion keeps lengths and curvatures.
            let _ = s.rebuild_lengths();
            return s;
        }
        Spline::from_ctrl(
            self.closed,
            self.through.iter().map(|p| rot * p + shift).collect(),
            self.ctrl.iter().map(|p| rot * p + shift).collect(),
        )
    }

    fn from_ctrl(closed: bool, through: Vec<V2>, ctrl: Vec<V2>) -> Spline {
        let spans: Vec<[V2; 4]> = if closed {
            let n = ctrl.len();
            (0..n)
                .map(|j| {
                    span_coeffs(
                        ctrl[(j + n - 1) % n],
                        ctrl[j],
                        ctrl[(j + 1) % n],
                        ctrl[(j + 2) % n],
                    )
                })
                .collect()
        } else {
            (0..ctrl.len() - 3)
                .map(|j| span_coeffs(ctrl[j], ctrl[j + 1], ctrl[j + 2], ctrl[j + 3]))
                .collect()
        };
        let mut s = Spline {
            closed,
            through,
            ctrl,
            spans,
            cum: Vec::new(),
            knot_curvature: Vec::new(),
        };
        // The source was finite, and a rigid motion or reversal keeps it so.
        let _ = s.rebuild_lengths();
        s
    }

    /// Signed area enclosed (closed splines; Green's theorem, exact for the polynomial spans).
    pub fn signed_area(&self) -> f64 {
        if !self.closed {
            return 0.0;
        }
        let mut a = 0.0;
        for j in 0..self.spans.len() {
            let f = |t: f64| {
                let (p, d, _) = self.span_derivs(j, t);
                p.x * d.y - p.y * d.x
            };
            // Degree-5 integrand: the 10-point rule is exact.
            a += gauss10(&f, 0.0, 1.0);
        }
        0.5 * a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cyclic_solver_matches_dense() {
        let rhs: Vec<V2> = (0..7).map(|i| V2::new(i as f64, (i * i) as f64)).collect();
        let x = cyclic_141(&rhs);
        let n = rhs.len();
        for j in 0..n {
            let lhs = x[(j + n - 1) % n] + x[j] * 4.0 + x[(j + 1) % n];
            assert!((lhs - rhs[j]).norm() < 1e-12);
        }
    }

    #[test]
    fn open_spline_passes_through_points() {
        let q: Vec<V2> = (0..6)
            .map(|i| V2::new(i as f64, (i as f64 * 0.7).sin()))
            .collect();
        let s = Spline::interpolate(&q, false).unwrap();
        for (j, p) in q.iter().enumerate() {
            assert!((s.derivs(j as f64).0 - p).norm() < 1e-12);
        }
        // Natural ends.
        assert!(s.derivs(0.0).2.norm() < 1e-12);
        assert!(s.derivs(5.0).2.norm() < 1e-12);
    }
}
