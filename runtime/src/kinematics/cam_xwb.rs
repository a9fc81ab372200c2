//! The cam-hardening machine of PROCESS.md §1: table X carries the rotary table ω, which turns
//! the part about the part origin O; the laser head sits on the machine's x line at `head_x`
//! and swivels by B in the horizontal plane.
//!
//! The paper steps the axes from three consecutive contour points (midpoints, perpendicular
//! bisectors, `B = D − C`, with a quadrant special case). Here the inverse is exact for any
//! pose: the lens point in part coordinates, Q = spot − standoff·beam, must be brought onto
//! the head, so the table turns Q onto the +x ray (ω = −∠Q), moves it to the head
//! (X = head_x − |Q|), and the head swivels to the beam's direction seen from the machine
//! (B = ∠(R(ω)·beam) − π, so B = 0 aims at the rotary centre). Angles are unwrapped against
//! the previous solution, never special-cased by quadrant.

use super::{KinError, Kinematics, ToolPose, check_travel, unwrap_near};
use crate::axes::Axes;
use crate::geometry::toolpath::chord_stations;
use crate::machine::Machine;
use nalgebra::{Rotation2, Vector2, Vector3};
use std::f64::consts::PI;

#[derive(Debug, Clone)]
pub struct CamXwb {
    head_x: f64,
    travel: Vec<(f64, f64)>,
}

impl CamXwb {
    pub fn new(m: &Machine) -> CamXwb {
        CamXwb {
            head_x: m.geometry.head_x,
            travel: m.axes.iter().map(|a| (a.min, a.max)).collect(),
        }
    }
}

impl Kinematics for CamXwb {
    fn axis_count(&self) -> usize {
        3
    }

    fn oriented(&self) -> bool {
        true
    }

    fn inverse(&self, pose: &ToolPose, prev: Option<&Axes>) -> Result<Axes, KinError> {
        if pose.beam.z.abs() > 1e-9 || pose.spot.z.abs() > 1e-9 {
            return Err(KinError::Unreachable(
                "the X-ω-B machine works in the part's xy plane: the beam must be horizontal and z = 0".into(),
            ));
        }
        let beam = Vector2::new(pose.beam.x, pose.beam.y);
        let q = Vector2::new(pose.spot.x, pose.spot.y) - beam * pose.standoff;
        let r = q.norm();
        if r < 1e-9 {
            return Err(KinError::Unreachable(
                "the lens would sit on the rotary axis; the rotary table cannot orient the part there".into(),
            ));
        }
        let mut omega = -q.y.atan2(q.x);
        let beam_w = Rotation2::new(omega) * beam;
        let mut b = beam_w.y.atan2(beam_w.x) - PI;
        if let Some(p) = prev {
            omega = unwrap_near(omega, p[1]);
            b = unwrap_near(b, p[2]);
        } else {
            b = unwrap_near(b, 0.0);
        }
        let mut out = Axes::ZERO;
        out[0] = self.head_x - r;
        out[1] = omega;
        out[2] = b;
        Ok(out)
    }

    fn forward_at(&self, q: &Axes, standoff: f64) -> ToolPose {
        let (x, omega, b) = (q[0], q[1], q[2]);
        let back = Rotation2::new(-omega);
        let lens = back * Vector2::new(self.head_x - x, 0.0);
        let beam = back * Vector2::new((b + PI).cos(), (b + PI).sin());
        let spot = lens + beam * standoff;
        ToolPose {
            spot: Vector3::new(spot.x, spot.y, 0.0),
            beam: Vector3::new(beam.x, beam.y, 0.0),
            standoff,
        }
    }

    fn check(&self, q: &Axes) -> Result<(), KinError> {
        check_travel(&self.travel, q)
    }
}

/// One step of the paper's discrete method (PROCESS.md §1), for comparison with the exact
/// inverse: the scan point M (midpoint of a contour chord), the surface normal stood in for by
/// the chord's perpendicular bisector, and the axis positions that follow from them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seed1Step {
    /// Midpoint of the chord P_k P_{k+1}.
    pub m: Vector2<f64>,
    /// Unit normal of the chord (its perpendicular bisector's direction), pointing outward.
    pub normal: Vector2<f64>,
    /// Axis positions X, ω, B for that scan point and normal.
    pub axes: [f64; 3],
}

impl CamXwb {
    /// The paper's method on a closed, counter-clockwise contour polyline: scan points at the
    /// chords' midpoints, normals from their perpendicular bisectors (the same
    /// [`chord_stations`] that `follow ... { normals chord }` uses), axes through the same
    /// exact machine transform (so the comparison isolates the normal and point error).
    pub fn seed1_steps(&self, contour: &[Vector2<f64>], standoff: f64) -> Vec<Seed1Step> {
        // Every chord of the closed contour, the closing one included.
        let closed: Vec<Vector2<f64>> = contour.iter().chain(contour.first()).copied().collect();
        // Counter-clockwise contour: outward, where the head stands, is to the right of travel.
        let stations = chord_stations(&closed, false);
        let mut out: Vec<Seed1Step> = Vec::with_capacity(stations.len());
        let mut prev: Option<Axes> = None;
        for st in stations {
            let pose = ToolPose {
                spot: Vector3::new(st.point.x, st.point.y, 0.0),
                beam: Vector3::new(st.beam.x, st.beam.y, 0.0),
                standoff,
            };
            if let Ok(q) = self.inverse(&pose, prev.as_ref()) {
                out.push(Seed1Step {
                    m: st.point,
                    normal: -st.beam,
                    axes: [q[0], q[1], q[2]],
                });
                prev = Some(q);
            }
        }
        out
    }
}
