//! Pose steps that stay true between the poses (issue 13 item 4).
//!
//! A controller moves every axis linearly from one programmed pose to the next. On a machine
//! that orients the beam the spot then does not run along the chord between the two spots: it
//! runs along the image of a straight joint-space segment under the forward kinematics, which
//! bulges off the surface, and its speed along that curve is |J(q(t))·Δq| / T, which changes
//! inside the block even though the block time T (G93's F) is right on average. Both effects
//! grow with the step, and neither is seen at the poses themselves.
//!
//! [`refine`] therefore checks every step the way the controller will run it: at interior
//! points of the joint-space segment, through the forward kinematics, it measures the spot's
//! distance from the surface and the spot's speed against the chord speed the block time
//! gives; a step that exceeds the budget is halved (in arc length, the new pose exact on the
//! surface with the exact normal) until it holds. Steps only ever shrink, so every pose the
//! caller asked for is kept.

use super::{Kinematics, ToolPose};
use crate::axes::Axes;
use crate::geometry::{Frame, Profile};
use nalgebra::Vector3;

/// What joint-linear interpolation inside one block may cost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChordBudget {
    /// Largest distance of the spot from the surface inside a block, mm.
    pub deviation_mm: f64,
    /// Largest relative departure of the spot's speed inside a block from the chord speed
    /// (the chord between the block's spots over the block time).
    pub speed_rel: f64,
}

impl ChordBudget {
    /// The budget for a path held to `tolerance` (mm) and the surface speed to 0.1 %: the
    /// spot within 70 % of the tolerance (the rest is the profile's own error against its
    /// law and the three-point bulge estimate) and the speed within 0.085 % (the rest is the
    /// NC text's rounding of short blocks: 0.1 µm on a linear axis). Every halving doubles the
    /// blocks a controller must stream, so the budget is not tighter than that.
    pub fn for_tolerance(tolerance: f64) -> ChordBudget {
        ChordBudget {
            deviation_mm: 0.7 * tolerance,
            speed_rel: 0.85e-3,
        }
    }
}

/// The surface a `follow` hardens, seen from the head: the profile in the plane z = `z`, the
/// head on the left of travel or not, the lens `standoff` off the spot along the normal.
#[derive(Debug, Clone, Copy)]
pub struct Surface<'a> {
    pub profile: &'a Profile,
    pub z: f64,
    pub standoff: f64,
    pub head_on_left: bool,
}

impl Surface<'_> {
    /// The exact pose at arc length `s`: the spot on the profile, the beam against the
    /// head-side normal.
    pub fn pose(&self, s: f64) -> (ToolPose, Frame) {
        let f = self.profile.frame_at(s);
        let n = if self.head_on_left { f.left } else { -f.left };
        (
            ToolPose {
                spot: Vector3::new(f.point.x, f.point.y, self.z),
                beam: Vector3::new(-n.x, -n.y, 0.0),
                standoff: self.standoff,
            },
            f,
        )
    }
}

/// Halvings of one requested step at most: 2⁻¹⁴ of a 0.5 mm step is 30 nm, below what the NC
/// text resolves, so a step that still fails there is left (near a singularity the budget may
/// not be reachable by stepping at all; the planner then limits the speed).
const MAX_DEPTH: u32 = 14;

/// Interior fractions of a block where the spot's distance from the surface is measured. The
/// bulge of a short block is close to a parabola with its top near the middle; three points
/// find it within a few per cent, which the callers' budget leaves room for.
const DEVIATION_AT: [f64; 3] = [0.25, 0.5, 0.75];

/// Fractions where the speed is measured: it changes almost linearly along a short block, so
/// its extremes are at the ends; the middle catches what curvature there is.
const SPEED_AT: [f64; 3] = [0.0, 0.5, 1.0];

/// The arc lengths of the poses to run: `s` (increasing, the caller's stations), with steps
/// halved where the joint-linear block between two poses leaves `budget`. At most
/// `max_points` are returned (refinement stops there; the caller's op budget then refuses the
/// path). Where a pose has no inverse the step is left as it is: the motion stage reports the
/// unreachable pose with its place on the path.
pub fn refine(
    kin: &dyn Kinematics,
    surface: &Surface,
    s: &[f64],
    budget: ChordBudget,
    max_points: usize,
) -> Vec<f64> {
    let Some(&s0) = s.first() else {
        return Vec::new();
    };
    let mut out = Vec::with_capacity(s.len());
    out.push(s0);
    let mut q0 = kin.inverse(&surface.pose(s0).0, None).ok();
    let mut from = s0;
    let mut r = Refiner {
        kin,
        surface,
        budget,
        max_points,
    };
    for &s1 in &s[1..] {
        q0 = match q0 {
            Some(q) => r.step(from, q, s1, 0, &mut out),
            None => {
                out.push(s1);
                kin.inverse(&surface.pose(s1).0, None).ok()
            }
        };
        from = s1;
    }
    out
}

struct Refiner<'a> {
    kin: &'a dyn Kinematics,
    surface: &'a Surface<'a>,
    budget: ChordBudget,
    max_points: usize,
}

impl Refiner<'_> {
    /// Pushes the poses from `s0` (axes `q0`, already pushed) to `s1`, halving the step while
    /// it fails the budget; returns the axes at `s1`.
    fn step(&mut self, s0: f64, q0: Axes, s1: f64, depth: u32, out: &mut Vec<f64>) -> Option<Axes> {
        let q1 = match self.kin.inverse(&self.surface.pose(s1).0, Some(&q0)) {
            Ok(q) => q,
            Err(_) => {
                out.push(s1);
                return None;
            }
        };
        if depth < MAX_DEPTH && out.len() < self.max_points && !self.holds(s0, &q0, s1, &q1) {
            let mid = 0.5 * (s0 + s1);
            let qm = self.step(s0, q0, mid, depth + 1, out)?;
            return self.step(mid, qm, s1, depth + 1, out);
        }
        out.push(s1);
        Some(q1)
    }

    /// Whether the block from `q0` to `q1` keeps the spot within the budget.
    fn holds(&self, s0: f64, q0: &Axes, s1: f64, q1: &Axes) -> bool {
        let (kin, st) = (self.kin, self.surface.standoff);
        let chord = (kin.forward_at(q1, st).spot - kin.forward_at(q0, st).spot).norm();
        if chord < 1e-9 {
            return true;
        }
        for t in DEVIATION_AT {
            let spot = kin.forward_at(&q0.lerp(q1, t), st).spot;
            if deviation(self.surface, spot, s0 + t * (s1 - s0)) > self.budget.deviation_mm {
                return false;
            }
        }
        let n = kin.axis_count();
        let dq = nalgebra::DVector::from_fn(n, |i, _| q1[i] - q0[i]);
        SPEED_AT.iter().all(|&t| {
            let v = kin.jacobian(&q0.lerp(q1, t), st) * &dq;
            (v.norm() / chord - 1.0).abs() <= self.budget.speed_rel
        })
    }
}

/// The spot's distance from the surface near arc length `s_guess`: the normal offset from the
/// frame there, less the curve's fall-off over the tangential offset (which is second order
/// and small: the spot lags or leads its arc length by the speed ripple times the step).
pub fn deviation(surface: &Surface, spot: Vector3<f64>, s_guess: f64) -> f64 {
    let f = surface.profile.frame_at(s_guess);
    let d = nalgebra::Vector2::new(spot.x - f.point.x, spot.y - f.point.y);
    let along = d.dot(&f.tangent);
    let normal = d.dot(&f.left) - 0.5 * f.curvature * along * along;
    normal.hypot(spot.z - surface.z)
}
