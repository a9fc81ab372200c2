//! Machine kinematics: tool pose in part coordinates ↔ machine axis positions.
//!
//! One trait for every machine model (one file each), as Klipper gives each kinematics one
//! interface. A tool pose is the spot on the part plus the beam direction. The motion core
//! calls `inverse` for every point it plans and `check` for every axis position before
//! anything is emitted.

mod cartesian;

pub use cartesian::Cartesian;

use crate::machine::{KinematicsKind, Machine};
use crate::planner::{Axes, MAX_AXES};
use nalgebra::Vector3;

/// Where the spot is on the part and which way the beam points (unit vector, from the head
/// toward the surface).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolPose {
    pub spot: Vector3<f64>,
    pub beam: Vector3<f64>,
}

impl ToolPose {
    /// A pose with the beam pointing down (−z), as on a flat-bed machine.
    pub fn down(spot: [f64; 3]) -> ToolPose {
        ToolPose {
            spot: Vector3::new(spot[0], spot[1], spot[2]),
            beam: Vector3::new(0.0, 0.0, -1.0),
        }
    }
}

/// Why a pose cannot be reached.
#[derive(Debug, Clone, PartialEq)]
pub enum KinError {
    /// An axis would leave its travel: axis index, the position asked for, its travel.
    Travel {
        axis: usize,
        value: f64,
        min: f64,
        max: f64,
    },
    /// The machine cannot produce the pose at all (e.g. a beam direction a flat bed cannot tilt).
    Unreachable(String),
}

pub trait Kinematics: std::fmt::Debug {
    /// Number of machine axes (≤ [`MAX_AXES`]).
    fn axis_count(&self) -> usize;
    /// Axis positions that put the spot and beam at `pose`. `prev` is the previous solution
    /// along the path, so branch choices and rotary angles stay continuous.
    fn inverse(&self, pose: &ToolPose, prev: Option<&Axes>) -> Result<Axes, KinError>;
    /// The pose that axis positions produce.
    fn forward(&self, q: &Axes) -> ToolPose;
    /// ∂spot/∂q: columns are axes, rows part x, y, z.
    fn jacobian(&self, q: &Axes) -> nalgebra::Matrix3xX<f64>;
    /// Checks axis positions against travel.
    fn check(&self, q: &Axes) -> Result<(), KinError>;
}

/// The kinematics model a machine declares.
pub fn for_machine(m: &Machine) -> Box<dyn Kinematics> {
    match m.kinematics {
        KinematicsKind::Cartesian => Box::new(Cartesian::new(m)),
    }
}

/// Travel check shared by all models: every axis inside [min, max] (with a nanometre of slack
/// for values that land on a limit by rounding).
pub(crate) fn check_travel(m_axes: &[(f64, f64)], q: &Axes) -> Result<(), KinError> {
    for (i, (min, max)) in m_axes.iter().enumerate().take(MAX_AXES) {
        let v = q[i];
        if !(v >= min - 1e-6 && v <= max + 1e-6) {
            return Err(KinError::Travel {
                axis: i,
                value: v,
                min: *min,
                max: *max,
            });
        }
    }
    Ok(())
}
