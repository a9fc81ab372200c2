//! Biarc approximation: turns any smooth parametric curve (B-spline spans, Bézier pieces,
//! NURBS, ellipse arcs) into tangent-continuous line/arc segments within a stated distance
//! tolerance, so that every NC dialect and the exact line/arc offset (PROCESS.md §1, eq. 2) can
//! take it.
//!
//! Each piece gets the equal-tangent-length biarc between its end points and end tangents; the
//! deviation is measured at interior samples of the curve (distance to the nearer of the two
//! arcs) and the piece is halved until it is within tolerance.

use super::{Seg, V2};
use std::f64::consts::TAU;

fn cross(a: V2, b: V2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Distance from `p` to the straight segment from `a` to `b` (to `a` when they coincide).
pub(crate) fn line_distance(a: V2, b: V2, p: V2) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let f = if l2 > 0.0 {
        ((p - a).dot(&ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * f - p).norm()
}

/// Distance from `p` to a segment.
pub(crate) fn seg_distance(seg: &Seg, p: V2) -> f64 {
    match seg {
        Seg::Line { a, b } => line_distance(*a, *b, p),
        Seg::Arc {
            center,
            r,
            a0,
            sweep,
        } => {
            let v = p - center;
            let ang = v.y.atan2(v.x);
            // Angle travelled from a0 in the sweep's direction, in [0, 2π).
            let rel = if *sweep >= 0.0 {
                (ang - a0).rem_euclid(TAU)
            } else {
                (a0 - ang).rem_euclid(TAU)
            };
            if rel <= sweep.abs() {
                (v.norm() - r).abs()
            } else {
                (seg.start() - p).norm().min((seg.end() - p).norm())
            }
        }
    }
}

/// The arc (or line) leaving `p0` along unit tangent `t0` and ending at `p1`.
pub(crate) fn arc_from_tangent(p0: V2, t0: V2, p1: V2) -> Seg {
    let c = p1 - p0;
    let chord = c.norm();
    let cr = cross(t0, c);
    // Sagitta of the arc: below 1e-12 of the chord the arc is a line for every purpose, and a
    // huge radius would only spoil the NC output.
    let half_angle = cr.atan2(t0.dot(&c));
    if chord == 0.0 || (chord * (half_angle / 2.0).tan()).abs() < 1e-12 * chord.max(1.0) {
        return Seg::Line { a: p0, b: p1 };
    }
    let r_signed = c.norm_squared() / (2.0 * cr);
    let left = V2::new(-t0.y, t0.x);
    let center = p0 + left * r_signed;
    let a0 = (p0.y - center.y).atan2(p0.x - center.x);
    Seg::Arc {
        center,
        r: r_signed.abs(),
        a0,
        sweep: 2.0 * half_angle,
    }
}

/// The equal-tangent-length biarc from (p0, t0) to (p1, t1), unit tangents.
pub(crate) fn biarc(p0: V2, t0: V2, p1: V2, t1: V2) -> Vec<Seg> {
    let v = p1 - p0;
    if v.norm() == 0.0 {
        return Vec::new();
    }
    let t = t0 + t1;
    let vt = v.dot(&t);
    let one_minus = 1.0 - t0.dot(&t1);
    let disc = vt * vt + 2.0 * one_minus * v.norm_squared();
    let denom = vt + disc.max(0.0).sqrt();
    if !(denom > 1e-300) {
        // Tangents opposed to the chord: no sensible biarc; the caller splits further.
        return vec![Seg::Line { a: p0, b: p1 }];
    }
    // Positive root of d²(t·t − 4) − 2d(v·t) + v·v = 0, in the cancellation-free form.
    let d = v.norm_squared() / denom;
    let q0 = p0 + t0 * d;
    let q1 = p1 - t1 * d;
    let joint = (q0 + q1) * 0.5;
    let tj = (q1 - q0).try_normalize(0.0).unwrap_or(v / v.norm());
    vec![
        arc_from_tangent(p0, t0, joint),
        arc_from_tangent(joint, tj, p1),
    ]
}

/// Appends to `out` biarcs approximating `curve` on [t0, t1] within `tol`. `curve(t)` returns
/// the point and the derivative. Returns the largest deviation measured.
pub(crate) fn fit_biarcs(
    curve: &impl Fn(f64) -> (V2, V2),
    t0: f64,
    t1: f64,
    tol: f64,
    out: &mut Vec<Seg>,
) -> f64 {
    fit_rec(curve, t0, t1, tol, out, 24)
}

fn unit_or(d: V2, fallback: V2) -> V2 {
    d.try_normalize(1e-300)
        .or_else(|| fallback.try_normalize(0.0))
        .unwrap_or(V2::x())
}

fn fit_rec(
    curve: &impl Fn(f64) -> (V2, V2),
    t0: f64,
    t1: f64,
    tol: f64,
    out: &mut Vec<Seg>,
    depth: u32,
) -> f64 {
    let (p0, d0) = curve(t0);
    let (p1, d1) = curve(t1);
    let chord = p1 - p0;
    let segs = biarc(p0, unit_or(d0, chord), p1, unit_or(d1, chord));
    let mut err: f64 = 0.0;
    const K: usize = 8;
    for k in 1..K {
        let t = t0 + (t1 - t0) * k as f64 / K as f64;
        let p = curve(t).0;
        let e = segs
            .iter()
            .map(|s| seg_distance(s, p))
            .fold(f64::INFINITY, f64::min);
        err = err.max(if segs.is_empty() { (p - p0).norm() } else { e });
    }
    if err <= tol || depth == 0 {
        out.extend(segs);
        return err;
    }
    let m = 0.5 * (t0 + t1);
    let e1 = fit_rec(curve, t0, m, tol, out, depth - 1);
    let e2 = fit_rec(curve, m, t1, tol, out, depth - 1);
    e1.max(e2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn biarc_of_a_circle_quadrant_is_exact() {
        let f = |t: f64| {
            (
                V2::new(t.cos(), t.sin()) * 5.0,
                V2::new(-t.sin(), t.cos()) * 5.0,
            )
        };
        let mut out = Vec::new();
        let e = fit_biarcs(&f, 0.0, 1.5, 1e-9, &mut out);
        assert!(e < 1e-9);
        for s in &out {
            let Seg::Arc { r, .. } = s else { panic!() };
            assert!((r - 5.0).abs() < 1e-9);
        }
    }
}
