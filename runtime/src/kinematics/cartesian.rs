//! Cartesian machines (`xy_table`, `xyz`, `notcher`): each axis moves the spot along one part
//! coordinate; the beam always points down.

use super::{KinError, Kinematics, ToolPose, check_travel};
use crate::axes::Axes;
use crate::machine::Machine;
use nalgebra::{Matrix3xX, Vector3};

#[derive(Debug, Clone)]
pub struct Cartesian {
    /// For each axis, the part coordinate it moves (0 = x, 1 = y, 2 = z).
    map: Vec<usize>,
    travel: Vec<(f64, f64)>,
}

impl Cartesian {
    pub fn new(m: &Machine) -> Cartesian {
        let map = m
            .axes
            .iter()
            .map(|a| match a.part_axis.as_deref() {
                Some("y") => 1,
                Some("z") => 2,
                _ => 0,
            })
            .collect();
        Cartesian {
            map,
            travel: m.axes.iter().map(|a| (a.min, a.max)).collect(),
        }
    }

    /// Which part coordinates the machine can move (a notcher has no y).
    pub fn moves_part_axis(&self, k: usize) -> bool {
        self.map.contains(&k)
    }
}

impl Kinematics for Cartesian {
    fn axis_count(&self) -> usize {
        self.map.len()
    }

    fn inverse(&self, pose: &ToolPose, _prev: Option<&Axes>) -> Result<Axes, KinError> {
        let down = Vector3::new(0.0, 0.0, -1.0);
        if (pose.beam - down).norm() > 1e-9 {
            return Err(KinError::Unreachable(
                "a cartesian machine's beam always points down (−z)".into(),
            ));
        }
        for k in 0..3 {
            if !self.moves_part_axis(k) && pose.spot[k].abs() > 1e-9 {
                return Err(KinError::Unreachable(format!(
                    "this machine has no axis along part {} (asked for {:.4} mm)",
                    ["x", "y", "z"][k],
                    pose.spot[k]
                )));
            }
        }
        let mut q = Axes::ZERO;
        for (i, &k) in self.map.iter().enumerate() {
            q[i] = pose.spot[k];
        }
        Ok(q)
    }

    fn forward_at(&self, q: &Axes, standoff: f64) -> ToolPose {
        let mut spot = [0.0; 3];
        for (i, &k) in self.map.iter().enumerate() {
            spot[k] = q[i];
        }
        // The head's focus is the machine's calibration: the axes place the spot itself.
        ToolPose {
            standoff,
            ..ToolPose::down(spot)
        }
    }

    fn jacobian(&self, _q: &Axes, _standoff: f64) -> Matrix3xX<f64> {
        let mut j = Matrix3xX::zeros(self.map.len());
        for (i, &k) in self.map.iter().enumerate() {
            j[(k, i)] = 1.0;
        }
        j
    }

    fn check(&self, q: &Axes) -> Result<(), KinError> {
        check_travel(&self.travel, q)
    }
}
