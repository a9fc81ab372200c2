//! A rotary attachment on a flat bed (issue 20): the part is the unrolled surface of a
//! cylinder, x along its axis and y around it, z the height above the top of the object.
//! The linear axes move x (and z) as on a Cartesian machine; the turning axis turns the
//! object under the fixed, downward beam by `Rotary::axis_per_surface_mm` per mm of y (a
//! chuck by the object's radius, rollers by the roller's; a Y-substituted linear axis by its
//! mm per turn). The map is linear, so a straight line on the surface is a straight line in
//! axis space, but an arc is not a circle there: motion writes arcs as chords on this machine
//! (`Kinematics::circular_arcs`), and emit writes feed moves in inverse time, since the
//! controller measures F over axis units (mm mixed with degrees), not over the surface.

use super::{KinError, Kinematics, ToolPose, check_travel};
use crate::axes::Axes;
use crate::machine::Machine;
use nalgebra::{Matrix3xX, Vector3};

#[derive(Debug, Clone)]
pub struct RotaryAttachment {
    /// For each axis, the part coordinate it moves: 0 x, 2 z, or 1 (the turning axis: the
    /// surface around the object).
    map: Vec<usize>,
    /// Turning-axis units (rad, or mm of a substituted linear axis) per mm of surface.
    per_mm: f64,
    travel: Vec<(f64, f64)>,
}

impl RotaryAttachment {
    /// The attachment a machine file declares (`[rotary]`, validated by the machine parser),
    /// with the object diameter the recipe set.
    pub fn new(m: &Machine) -> RotaryAttachment {
        let rotary = m
            .rotary
            .as_ref()
            .expect("the rotary kinematics has [rotary]");
        let map = m
            .axes
            .iter()
            .enumerate()
            .map(|(i, a)| match a.part_axis.as_deref() {
                _ if i == rotary.axis => 1,
                Some("z") => 2,
                _ => 0,
            })
            .collect();
        RotaryAttachment {
            map,
            per_mm: rotary.axis_per_surface_mm(),
            travel: m.axes.iter().map(|a| (a.min, a.max)).collect(),
        }
    }

    /// Axis units per mm of part coordinate `k`.
    fn scale(&self, k: usize) -> f64 {
        if k == 1 { self.per_mm } else { 1.0 }
    }
}

impl Kinematics for RotaryAttachment {
    fn axis_count(&self) -> usize {
        self.map.len()
    }

    fn inverse(&self, pose: &ToolPose, _prev: Option<&Axes>) -> Result<Axes, KinError> {
        let down = Vector3::new(0.0, 0.0, -1.0);
        if (pose.beam - down).norm() > 1e-9 {
            return Err(KinError::Unreachable(
                "a rotary attachment's beam always points down (−z)".into(),
            ));
        }
        if !self.map.contains(&2) && pose.spot.z.abs() > 1e-9 {
            return Err(KinError::Unreachable(format!(
                "this machine has no axis along part z (asked for {:.4} mm)",
                pose.spot.z
            )));
        }
        // The map is linear and one-to-one: the surface y of a point fixes the angle, so
        // consecutive solutions are continuous without unwrapping (y past one circumference
        // is more than one turn, as the recipe asked).
        let mut q = Axes::ZERO;
        for (i, &k) in self.map.iter().enumerate() {
            q[i] = pose.spot[k] * self.scale(k);
        }
        Ok(q)
    }

    fn forward_at(&self, q: &Axes, standoff: f64) -> ToolPose {
        let mut spot = [0.0; 3];
        for (i, &k) in self.map.iter().enumerate() {
            spot[k] = q[i] / self.scale(k);
        }
        ToolPose {
            standoff,
            ..ToolPose::down(spot)
        }
    }

    fn jacobian(&self, _q: &Axes, _standoff: f64) -> Matrix3xX<f64> {
        let mut j = Matrix3xX::zeros(self.map.len());
        for (i, &k) in self.map.iter().enumerate() {
            j[(k, i)] = 1.0 / self.scale(k);
        }
        j
    }

    fn inverse_time(&self) -> bool {
        true
    }

    fn circular_arcs(&self) -> bool {
        false
    }

    fn check(&self, q: &Axes) -> Result<(), KinError> {
        check_travel(&self.travel, q)
    }
}
