//! The curved-surface hardening machine of PROCESS.md §2: a planar arm with rotary joints
//! A, B, C on parallel axes (links `link1` A→B, `link2` B→C, the head `head` from C to the
//! lens along the beam), and a slide along the joint axes that brings each section of the
//! surface into the arm's plane.
//!
//! Part frame: the arm works in the part's xy plane; the slide position is the part z of the
//! section being hardened. Joint angles are absolute-relative as usual for serial arms:
//! link 1 points at A, link 2 at A + B, the beam at A + B + C.

use super::{KinError, Kinematics, ToolPose, check_travel, unwrap_near};
use crate::axes::Axes;
use crate::machine::Machine;
use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

#[derive(Debug, Clone)]
pub struct Arm3r {
    base: Vector2<f64>,
    l1: f64,
    l2: f64,
    head: f64,
    elbow: f64,
    travel: Vec<(f64, f64)>,
}

fn e(a: f64) -> Vector2<f64> {
    Vector2::new(a.cos(), a.sin())
}

/// Below this |sin B| the arm is (nearly) stretched or folded and its Jacobian loses rank.
pub const SINGULAR_SIN: f64 = 1e-3;

impl Arm3r {
    pub fn new(m: &Machine) -> Arm3r {
        Arm3r {
            base: Vector2::new(m.geometry.base[0], m.geometry.base[1]),
            l1: m.geometry.link1,
            l2: m.geometry.link2,
            head: m.geometry.head,
            elbow: m.geometry.elbow,
            travel: m.axes.iter().map(|a| (a.min, a.max)).collect(),
        }
    }

    /// The wrist (joint C) for a pose: back from the lens by the head length.
    fn wrist(&self, pose: &ToolPose) -> Vector2<f64> {
        let b = Vector2::new(pose.beam.x, pose.beam.y);
        Vector2::new(pose.spot.x, pose.spot.y) - b * (pose.standoff + self.head)
    }

    /// The 2×2 Jacobian of the wrist point with respect to A and B.
    pub fn wrist_jacobian(&self, a: f64, b: f64) -> Matrix2<f64> {
        let (s1, c1) = a.sin_cos();
        let (s12, c12) = (a + b).sin_cos();
        Matrix2::new(
            -self.l1 * s1 - self.l2 * s12,
            -self.l2 * s12,
            self.l1 * c1 + self.l2 * c12,
            self.l2 * c12,
        )
    }

    /// The full 3×3 Jacobian of (spot x, spot y, beam angle) with respect to (A, B, C).
    pub fn full_jacobian(&self, q: &Axes, standoff: f64) -> Matrix3<f64> {
        let (a, b, c) = (q[1], q[2], q[3]);
        let r = self.head + standoff;
        let (s1, c1) = a.sin_cos();
        let (s12, c12) = (a + b).sin_cos();
        let (s123, c123) = (a + b + c).sin_cos();
        Matrix3::new(
            -self.l1 * s1 - self.l2 * s12 - r * s123,
            -self.l2 * s12 - r * s123,
            -r * s123,
            self.l1 * c1 + self.l2 * c12 + r * c123,
            self.l2 * c12 + r * c123,
            r * c123,
            1.0,
            1.0,
            1.0,
        )
    }

    /// Joint rates by the seed's method (§2 step 4): C's rate from the beam's turning rate,
    /// then A and B from the 2×2 wrist Jacobian so the wrist follows the offset path.
    /// `spot_vel` is the spot's velocity on the part (mm/s), `beam_rate` the beam's turning
    /// rate (rad/s).
    pub fn joint_rates(
        &self,
        q: &Axes,
        spot_vel: Vector2<f64>,
        beam_rate: f64,
        standoff: f64,
    ) -> Result<[f64; 3], KinError> {
        let (a, b, c) = (q[1], q[2], q[3]);
        let phi = a + b + c;
        // The wrist sits (head + standoff) behind the spot along the beam; it moves with the
        // spot minus the beam's turning: ẇ = ṡ − r·φ̇·e⊥(φ).
        let r = self.head + standoff;
        let wrist_vel = spot_vel - Vector2::new(-phi.sin(), phi.cos()) * (r * beam_rate);
        let j = self.wrist_jacobian(a, b);
        let ab = j.try_inverse().ok_or_else(|| {
            KinError::Unreachable("the arm is stretched or folded (singular Jacobian)".into())
        })? * wrist_vel;
        Ok([ab.x, ab.y, beam_rate - ab.x - ab.y])
    }
}

impl Kinematics for Arm3r {
    fn axis_count(&self) -> usize {
        4
    }

    fn oriented(&self) -> bool {
        true
    }

    fn inverse(&self, pose: &ToolPose, prev: Option<&Axes>) -> Result<Axes, KinError> {
        if pose.beam.z.abs() > 1e-9 {
            return Err(KinError::Unreachable(
                "the arm turns the beam in its plane only: the beam must have no z component"
                    .into(),
            ));
        }
        let w = self.wrist(pose) - self.base;
        let d2 = w.norm_squared();
        let cos_b = (d2 - self.l1 * self.l1 - self.l2 * self.l2) / (2.0 * self.l1 * self.l2);
        if !(-1.0..=1.0).contains(&cos_b) {
            return Err(KinError::Unreachable(format!(
                "the wrist point is {:.3} mm from the base; the arm reaches {:.3} to {:.3} mm",
                d2.sqrt(),
                (self.l1 - self.l2).abs(),
                self.l1 + self.l2
            )));
        }
        let sin_b = self.elbow * (1.0 - cos_b * cos_b).max(0.0).sqrt();
        if sin_b.abs() < SINGULAR_SIN {
            return Err(KinError::Unreachable(
                "the arm would be stretched or folded here (near-singular Jacobian)".into(),
            ));
        }
        let b = sin_b.atan2(cos_b);
        let a = w.y.atan2(w.x) - (self.l2 * sin_b).atan2(self.l1 + self.l2 * cos_b);
        let phi = pose.beam.y.atan2(pose.beam.x);
        let (mut a, mut c) = (a, phi - a - b);
        if let Some(p) = prev {
            a = unwrap_near(a, p[1]);
            c = unwrap_near(c, p[3]);
        } else {
            a = unwrap_near(a, 0.0);
            c = unwrap_near(c, 0.0);
        }
        let mut q = Axes::ZERO;
        q[0] = pose.spot.z;
        q[1] = a;
        q[2] = b;
        q[3] = c;
        Ok(q)
    }

    fn forward_at(&self, q: &Axes, standoff: f64) -> ToolPose {
        let (a, b, c) = (q[1], q[2], q[3]);
        let wrist = self.base + e(a) * self.l1 + e(a + b) * self.l2;
        let beam = e(a + b + c);
        let spot = wrist + beam * (self.head + standoff);
        ToolPose {
            spot: Vector3::new(spot.x, spot.y, q[0]),
            beam: Vector3::new(beam.x, beam.y, 0.0),
            standoff,
        }
    }

    fn jacobian(&self, q: &Axes, standoff: f64) -> nalgebra::Matrix3xX<f64> {
        let f = self.full_jacobian(q, standoff);
        let mut j = nalgebra::Matrix3xX::zeros(4);
        j[(2, 0)] = 1.0;
        for col in 0..3 {
            j[(0, col + 1)] = f[(0, col)];
            j[(1, col + 1)] = f[(1, col)];
        }
        j
    }

    fn check(&self, q: &Axes) -> Result<(), KinError> {
        check_travel(&self.travel, q)
    }
}
