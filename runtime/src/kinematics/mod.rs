//! Machine kinematics: tool pose in part coordinates ↔ machine axis positions.
//!
//! One trait for every machine model (one file each), as Klipper gives each kinematics one
//! interface. A tool pose is the spot on the part plus the beam direction. The motion core
//! calls `inverse` for every point it plans and `check` for every axis position before
//! anything is emitted; the planned `motion::Job` carries the model ([`for_machine`], the one
//! constructor) and every op's axis values, so later stages never run the inverse again.
//! Axis values are [`Axes`] (machine order, mm and rad), from the neutral `axes` module.
//! Models: `cartesian`, `cam_xwb` (PROCESS.md §1), `arm_3r` (§2) and `rotary` (a rotary
//! attachment on a flat bed, issue 20).

mod arm_3r;
mod cam_xwb;
mod cartesian;
pub mod chords;
mod rotary;

pub use arm_3r::Arm3r;
pub use cam_xwb::CamXwb;
pub use cartesian::Cartesian;
pub use rotary::RotaryAttachment;

use crate::axes::{Axes, MAX_AXES};
use crate::machine::{KinematicsKind, Machine};
use nalgebra::Vector3;

/// Where the spot is on the part, which way the beam points (unit vector, from the lens
/// toward the surface) and how far the lens stands off the spot along the beam, mm. All in
/// part coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolPose {
    pub spot: Vector3<f64>,
    pub beam: Vector3<f64>,
    pub standoff: f64,
}

impl ToolPose {
    /// A pose with the beam pointing down (−z), as on a flat-bed machine.
    pub fn down(spot: [f64; 3]) -> ToolPose {
        ToolPose {
            spot: Vector3::new(spot[0], spot[1], spot[2]),
            beam: Vector3::new(0.0, 0.0, -1.0),
            standoff: 0.0,
        }
    }

    /// The lens position: `standoff` back from the spot along the beam.
    pub fn lens(&self) -> Vector3<f64> {
        self.spot - self.beam * self.standoff
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

/// A machine model. `Send + Sync` so that a planned job (which carries one) can go to the
/// thread that streams it.
pub trait Kinematics: std::fmt::Debug + Send + Sync {
    /// Number of machine axes (≤ [`MAX_AXES`]).
    fn axis_count(&self) -> usize;
    /// Axis positions that put the spot and beam at `pose`. `prev` is the previous solution
    /// along the path, so branch choices and rotary angles stay continuous.
    fn inverse(&self, pose: &ToolPose, prev: Option<&Axes>) -> Result<Axes, KinError>;
    /// The pose that axis positions produce when the lens stands `standoff` off the surface.
    fn forward_at(&self, q: &Axes, standoff: f64) -> ToolPose;
    /// The pose with the spot at the lens (standoff 0). On a Cartesian machine that is the
    /// spot; on an oriented one, pass the op's standoff to [`Kinematics::forward_at`].
    fn forward(&self, q: &Axes) -> ToolPose {
        self.forward_at(q, 0.0)
    }
    /// ∂spot/∂q at the given standoff: columns are axes, rows part x, y, z. Models without a
    /// closed form use central differences of [`Kinematics::forward_at`].
    fn jacobian(&self, q: &Axes, standoff: f64) -> nalgebra::Matrix3xX<f64> {
        let n = self.axis_count();
        let mut j = nalgebra::Matrix3xX::zeros(n);
        for i in 0..n {
            let h = 1e-6;
            let mut a = *q;
            let mut b = *q;
            a[i] -= h;
            b[i] += h;
            let d = (self.forward_at(&b, standoff).spot - self.forward_at(&a, standoff).spot)
                / (2.0 * h);
            j.set_column(i, &d);
        }
        j
    }
    /// Whether the machine orients the beam (the evaluator then samples paths into poses
    /// with exact normals instead of emitting lines and arcs).
    fn oriented(&self) -> bool {
        false
    }
    /// Whether the controller must be given feed moves in inverse time (G93) to hold the
    /// spot's speed: its F is measured over axis units, which are not the part's millimetres
    /// when a move turns a rotary axis (oriented machines, a rotary attachment).
    fn inverse_time(&self) -> bool {
        self.oriented()
    }
    /// Whether a part-space arc in the xy plane is a circle in the axes, so G2/G3 can write
    /// it. A rotary attachment maps y to an angle: its arcs are written as chords.
    fn circular_arcs(&self) -> bool {
        true
    }
    /// Checks axis positions against travel.
    fn check(&self, q: &Axes) -> Result<(), KinError>;
}

/// The kinematics model a machine declares: the one constructor (motion builds it once per
/// job; the evaluator asks it whether the machine orients the beam).
pub fn for_machine(m: &Machine) -> Box<dyn Kinematics> {
    match m.kinematics {
        KinematicsKind::Cartesian => Box::new(Cartesian::new(m)),
        KinematicsKind::CamXwb => Box::new(CamXwb::new(m)),
        KinematicsKind::Arm3r => Box::new(Arm3r::new(m)),
        KinematicsKind::Rotary => Box::new(RotaryAttachment::new(m)),
    }
}

/// `a` shifted by whole turns to lie within half a turn of `near`: rotary axes move
/// continuously along a path instead of jumping at ±180° (replaces seed 1's quadrant cases).
pub fn unwrap_near(a: f64, near: f64) -> f64 {
    use std::f64::consts::TAU;
    a - ((a - near) / TAU).round() * TAU
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
