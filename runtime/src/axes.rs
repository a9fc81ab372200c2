//! Axis values in the two frames lase speaks, and the one conversion between their units.
//!
//! * [`Axes`]: a machine's axes in the machine's own order (as its file lists them), in the
//!   internal units mm (linear) and rad (rotary). What the kinematics returns, what the
//!   planner plans and what a planned job carries for every op.
//! * [`ControllerPos`]: a GRBL-family controller's slots X Y Z A B C, in the units the
//!   controller and every NC program speak: mm (linear) and degrees (rotary). What a status
//!   report says and what the link's journal and resume logic compare.
//!
//! A rotary axis's value leaves lase — in an NC word, a report, a controller setting, a
//! diagnostic — in degrees, and only through [`to_external`] (its unit named by
//! [`external_unit`]), so that no consumer converts radians on its own.
//!
//! A low-level module on purpose: `kinematics`, `planner`, `motion`, `emit`, `report` and
//! `link` all import from here, and it imports nothing of theirs.

use serde::{Deserialize, Serialize};
use std::ops::{Deref, DerefMut};

/// Whether an axis moves in mm or turns in rad (deg outside lase).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AxisKind {
    Linear,
    Rotary,
}

/// Most machine axes one plan can carry (X Y Z A B C). Unused axes stay at zero.
pub const MAX_AXES: usize = 6;

/// Machine axis values (a position, or a per-axis quantity such as a direction), machine
/// order, internal units: mm for linear axes, rad for rotary ones. Axes beyond the machine's
/// count stay 0.
///
/// A newtype, not a bare array, so that it cannot be mixed up with a [`ControllerPos`] (other
/// order, degrees): crossing between them takes `link::ControllerAxes`. It reads as the array
/// it wraps (`q[k]`, `q.iter()`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Axes(pub [f64; MAX_AXES]);

impl Axes {
    /// Every axis at 0.
    pub const ZERO: Axes = Axes([0.0; MAX_AXES]);

    /// Axis `k`'s value from `f(k)`.
    pub fn from_fn(f: impl FnMut(usize) -> f64) -> Axes {
        Axes(std::array::from_fn(f))
    }

    /// The point fraction `f` of the way from `self` to `to`, per axis (`a + f·(b − a)`, the
    /// straight line a controller runs between two blocks' end points).
    pub fn lerp(&self, to: &Axes, f: f64) -> Axes {
        Axes::from_fn(|k| self[k] + f * (to[k] - self[k]))
    }
}

impl Deref for Axes {
    type Target = [f64; MAX_AXES];

    fn deref(&self) -> &[f64; MAX_AXES] {
        &self.0
    }
}

impl DerefMut for Axes {
    fn deref_mut(&mut self) -> &mut [f64; MAX_AXES] {
        &mut self.0
    }
}

impl IntoIterator for Axes {
    type Item = f64;
    type IntoIter = std::array::IntoIter<f64, MAX_AXES>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl<'a> IntoIterator for &'a Axes {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl From<[f64; MAX_AXES]> for Axes {
    fn from(a: [f64; MAX_AXES]) -> Axes {
        Axes(a)
    }
}

impl PartialEq<[f64; MAX_AXES]> for Axes {
    fn eq(&self, other: &[f64; MAX_AXES]) -> bool {
        self.0 == *other
    }
}

/// A controller position: slots X Y Z A B C (in that order, whatever the machine's order), mm
/// for X, Y, Z and degrees for rotary A, B, C; slots a machine lacks stay 0. Kept an array
/// (the link's protocol code and simulator index and build it as one); being a different type
/// from [`Axes`], it cannot be passed where machine axes are meant.
pub type ControllerPos = [f64; MAX_AXES];

/// External units (mm, deg) per internal unit (mm, rad) of an axis of this kind.
pub fn external_scale(kind: AxisKind) -> f64 {
    match kind {
        // The same factor as `f64::to_degrees`, so values convert bit for bit as before.
        AxisKind::Rotary => 180.0 / std::f64::consts::PI,
        AxisKind::Linear => 1.0,
    }
}

/// An axis value (or rate, acceleration, jerk) in external units: mm stay mm, rad become
/// degrees.
pub fn to_external(kind: AxisKind, v: f64) -> f64 {
    v * external_scale(kind)
}

/// An axis value in external units (mm, deg) back in internal units (mm, rad).
pub fn from_external(kind: AxisKind, v: f64) -> f64 {
    v / external_scale(kind)
}

/// The external unit of an axis of this kind, as diagnostics write it.
pub fn external_unit(kind: AxisKind) -> &'static str {
    match kind {
        AxisKind::Rotary => "deg",
        AxisKind::Linear => "mm",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotary_converts_as_to_degrees_does() {
        for v in [0.0, 1.0, -0.3, std::f64::consts::PI, 12.345_678_9] {
            assert_eq!(to_external(AxisKind::Rotary, v), v.to_degrees());
            assert_eq!(to_external(AxisKind::Linear, v), v);
        }
        let back = from_external(AxisKind::Rotary, to_external(AxisKind::Rotary, 0.5));
        assert!((back - 0.5).abs() < 1e-15);
    }

    #[test]
    fn lerp_is_per_axis() {
        let a = Axes([1.0, 2.0, 0.0, 0.0, 0.0, 0.0]);
        let b = Axes([3.0, -2.0, 0.0, 1.0, 0.0, 0.0]);
        assert_eq!(a.lerp(&b, 0.5), [2.0, 0.0, 0.0, 0.5, 0.0, 0.0]);
        assert_eq!(a.lerp(&b, 1.0), b);
    }
}
