//! A machine file's `[rotary]` table (issue 20): a rotary attachment on a flat bed, the
//! `rotary` kinematics. The recipe works on the unrolled surface (x along the object's axis,
//! y around it, mm); the attachment turns the object under the fixed beam.
//!
//! What turns, and so which diameter converts surface millimetres into axis motion, is the
//! attachment's drive, as LightBurn's and LaserGRBL's rotary setups ask it:
//! - `chuck`: the object is clamped on the axis and turns with it. One turn is one object
//!   circumference: angle = surface / r_object, so the object's diameter matters (the
//!   recipe's `rotary { diameter }`, else the file's `diameter`).
//! - `roller`: the object lies on driven rollers and turns by friction. The surface moves as
//!   far as the roller's: angle = surface / r_roller, whatever the object's diameter.
//!
//! The axis that turns is a rotary axis (grblHAL's or LinuxCNC's A, in degrees), or a
//! linear axis the controller still believes is Y (the cheap wiring: the rotary plugged into
//! the Y driver). Then the controller counts `mm_per_rev` of "Y" per turn of the drive
//! (its steps per mm times that are the motor's steps per turn), and Y = surface ·
//! mm_per_rev / (π · d_drive).

use super::{Axis, AxisKind, MachineError};
use lase_lang::Span;
use serde::{Deserialize, Serialize};
use std::ops::Range;

/// How the attachment turns the object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Drive {
    /// The object is clamped and turns with the axis.
    Chuck,
    /// The object rides on driven rollers.
    Roller,
}

/// A rotary attachment, in internal units (mm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rotary {
    pub drive: Drive,
    /// Index of the axis that turns the object.
    pub axis: usize,
    /// The object's diameter, mm (the recipe's `rotary { diameter }` replaces it).
    pub diameter_mm: f64,
    /// The roller's diameter, mm (roller drive only).
    pub roller_diameter_mm: Option<f64>,
    /// A linear turning axis (Y substituted): its mm per turn of the drive.
    pub mm_per_rev: Option<f64>,
}

impl Rotary {
    /// The diameter whose circumference one turn of the axis rolls: the object's on a chuck,
    /// the roller's on rollers.
    pub fn drive_diameter_mm(&self) -> f64 {
        match self.drive {
            Drive::Chuck => self.diameter_mm,
            Drive::Roller => self.roller_diameter_mm.unwrap_or(self.diameter_mm),
        }
    }

    /// Turning-axis units (rad, or mm of a substituted linear axis) per mm of surface.
    pub fn axis_per_surface_mm(&self) -> f64 {
        let d = self.drive_diameter_mm();
        match self.mm_per_rev {
            Some(per_rev) => per_rev / (std::f64::consts::PI * d),
            None => 2.0 / d,
        }
    }
}

/// `[rotary]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileRotary {
    drive: toml::Spanned<String>,
    axis: toml::Spanned<String>,
    diameter: toml::Spanned<String>,
    roller_diameter: Option<toml::Spanned<String>>,
    mm_per_rev: Option<toml::Spanned<String>>,
}

impl FileRotary {
    /// Where the table is written (its `drive`), for a diagnostic about the whole table.
    pub(super) fn span(&self) -> Range<usize> {
        self.drive.span()
    }
}

/// Reads a length from the machine file (the parser's own quantity rule, with its spans).
pub(super) type LengthOf<'a> =
    &'a dyn Fn(&toml::Spanned<String>, &str) -> Result<f64, MachineError>;

/// Reads `[rotary]` against the machine's axes: the turning axis exists, the other axes are
/// linear and move part x or z (part y is the surface around the object, the turning axis's).
pub(super) fn parse(
    file: Option<&FileRotary>,
    axes: &[Axis],
    kinematics_span: Span,
    at: &dyn Fn(Range<usize>) -> Span,
    length: LengthOf<'_>,
) -> Result<Rotary, MachineError> {
    let invalid = |message: String, span: Span, label: &str, help: &str| MachineError::Invalid {
        message,
        span,
        label: label.into(),
        help: Some(help.into()),
    };
    let Some(f) = file else {
        return Err(invalid(
            "the rotary kinematics needs a `[rotary]` table".into(),
            kinematics_span,
            "here",
            "add `[rotary]` with `drive = \"chuck\"` (or \"roller\"), `axis = \"A\"` and \
             `diameter = \"60 mm\"` (stdlib/machines/README.md)",
        ));
    };
    let drive = match f.drive.get_ref().as_str() {
        "chuck" => Drive::Chuck,
        "roller" => Drive::Roller,
        other => {
            return Err(invalid(
                format!("unknown rotary drive `{other}`"),
                at(f.drive.span()),
                "not a drive",
                "`chuck` (the object turns with the axis) or `roller` (it rides on rollers)",
            ));
        }
    };
    let name = f.axis.get_ref().to_ascii_uppercase();
    let Some(axis) = axes.iter().position(|a| a.name == name) else {
        return Err(invalid(
            format!(
                "the rotary axis `{}` is not one of the machine's axes",
                f.axis.get_ref()
            ),
            at(f.axis.span()),
            "no such axis",
            "name one of the `[[axes]]`, e.g. \"A\"",
        ));
    };
    let positive = |s: &toml::Spanned<String>, what: &str| -> Result<f64, MachineError> {
        let v = length(s, what)?;
        if v > 0.0 {
            Ok(v)
        } else {
            Err(invalid(
                format!("{what} must be greater than zero"),
                at(s.span()),
                "not positive",
                "give the diameter in mm",
            ))
        }
    };
    let diameter_mm = positive(&f.diameter, "diameter")?;
    let roller_diameter_mm = match (&f.roller_diameter, drive) {
        (Some(r), Drive::Roller) => Some(positive(r, "roller_diameter")?),
        (None, Drive::Roller) => {
            return Err(invalid(
                "a roller drive needs `roller_diameter`".into(),
                at(f.drive.span()),
                "roller",
                "add `roller_diameter = \"... mm\"`: the surface moves as far as the roller's",
            ));
        }
        (Some(r), Drive::Chuck) => {
            return Err(invalid(
                "a chuck has no roller".into(),
                at(r.span()),
                "not used by a chuck",
                "remove `roller_diameter`, or write `drive = \"roller\"`",
            ));
        }
        (None, Drive::Chuck) => None,
    };
    let mm_per_rev = match (&f.mm_per_rev, axes[axis].kind) {
        (Some(m), AxisKind::Linear) => Some(positive(m, "mm_per_rev")?),
        (None, AxisKind::Linear) => {
            return Err(invalid(
                format!("the linear axis {name} turns the object: give its `mm_per_rev`"),
                at(f.axis.span()),
                "a linear axis substituting Y",
                "add `mm_per_rev = \"... mm\"`: how far the controller counts this axis for one \
                 turn of the drive; or make the axis `kind = \"rotary\"` (degrees)",
            ));
        }
        (Some(m), AxisKind::Rotary) => {
            return Err(invalid(
                format!("the rotary axis {name} counts degrees, not mm per turn"),
                at(m.span()),
                "not used by a rotary axis",
                "remove `mm_per_rev`",
            ));
        }
        (None, AxisKind::Rotary) => None,
    };
    for (i, a) in axes.iter().enumerate() {
        let ok = i == axis
            || (a.kind == AxisKind::Linear && matches!(a.part_axis.as_deref(), Some("x" | "z")));
        if !ok {
            return Err(invalid(
                format!(
                    "axis {}: on a rotary attachment every other axis is linear and moves part x \
                     or z",
                    a.name
                ),
                kinematics_span,
                "rotary kinematics",
                "part y is the surface around the object, which the rotary axis moves; leave \
                 the bed's Y out of this machine file",
            ));
        }
    }
    Ok(Rotary {
        drive,
        axis,
        diameter_mm,
        roller_diameter_mm,
        mm_per_rev,
    })
}
