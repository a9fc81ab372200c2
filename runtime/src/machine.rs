//! Machine definitions: axes, limits, laser and the post settings each NC dialect needs.
//!
//! Machines are TOML files (the standard library embeds the stock ones). Quantities are written
//! with units, exactly as in recipes (`v_max = "200 mm/s"`), and converted to internal units
//! here; every error points at the offending TOML span.

use lase_lang::Span;
use lase_lang::units::{self, Dim, QuantityError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::Range;

mod rotary;
pub use rotary::{Drive, Rotary};

/// What is wrong with a machine file. Spans are global offsets (the file is part of the
/// recipe's source map).
#[derive(Debug, Clone, thiserror::Error, miette::Diagnostic, PartialEq)]
pub enum MachineError {
    #[error("machine file: {message}")]
    #[diagnostic(code(lase::machine::invalid))]
    Invalid {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },
}

impl MachineError {
    pub fn span(&self) -> Span {
        match self {
            MachineError::Invalid { span, .. } => *span,
        }
    }
}

pub use crate::axes::AxisKind;

/// Velocity profile shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Ramp {
    Trapezoid,
    Scurve,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KinematicsKind {
    /// Axes move the spot along part x, y, z directly.
    Cartesian,
    /// PROCESS.md §1: table X, rotary table ω turning the part about the origin, head swivel
    /// B turning the beam in the horizontal plane. Axes in that order.
    CamXwb,
    /// PROCESS.md §2: a slide along the joint axes, then the planar arm's joints A, B, C.
    /// Axes in that order.
    Arm3r,
    /// A rotary attachment on a flat bed (issue 20): the recipe's y is the surface around the
    /// object, which the turning axis of `[rotary]` moves; the other axes move x and z.
    Rotary,
}

/// Link lengths and offsets of oriented machines, mm (internal units).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Geometry {
    /// cam_xwb: where the lens sits on the machine's x line when X = 0.
    pub head_x: f64,
    /// arm_3r: the base joint A in part x, y.
    pub base: [f64; 2],
    /// arm_3r: A→B and B→C link lengths.
    pub link1: f64,
    pub link2: f64,
    /// arm_3r: C joint to lens along the beam.
    pub head: f64,
    /// arm_3r: elbow branch, +1 (elbow left of the line base→wrist) or −1.
    pub elbow: f64,
}

/// One machine axis, in internal units (mm or rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// The NC address letter (X, Y, Z, A, B, C).
    pub name: String,
    pub kind: AxisKind,
    /// Which part coordinate a Cartesian axis moves (x, y or z).
    pub part_axis: Option<String>,
    pub min: f64,
    pub max: f64,
    pub v_max: f64,
    pub a_max: f64,
    pub j_max: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LaserSpec {
    pub max_power_w: f64,
    pub max_pulse_rate_hz: f64,
    /// The power the machine allows for pointing (a visible spot that marks nothing):
    /// `lase frame --pointer` traces the frame at it. `None`: framing is dark only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pointer_w: Option<f64>,
}

/// How one dialect switches the laser and frames the program. Templates may use `{power}`
/// (W), `{s}` (the S word: power scaled to `s_max`) and `{pct}` (percent of max power).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DialectPost {
    pub laser_on: Vec<String>,
    pub laser_off: Vec<String>,
    /// Lines that change power while the laser stays on.
    pub power: Vec<String>,
    /// The S value that means full power.
    pub s_max: f64,
    /// Whether switching the laser on or off needs the machine at rest (seed 4: M27 does).
    pub laser_switch_stops: bool,
    /// Pulses by distance, one per trigger edge: lines that raise the trigger at the start of
    /// the next motion block, and lines that lower it (LinuxCNC `M62 P1` / `M63 P1`). Empty:
    /// the beam's own on/off lines gate each pulse (GRBL: the S word of each block).
    #[serde(default)]
    pub pulse_on: Vec<String>,
    #[serde(default)]
    pub pulse_off: Vec<String>,
    /// Position-synchronized output configured once (Aerotech PSO, grblHAL pulses per
    /// distance): lines written when a lit section with pulses by distance starts, with
    /// `{pitch}` (mm) and `{ppi}` (pulses per inch); the controller then fires while the beam
    /// is on, and no per-pulse lines are written.
    #[serde(default)]
    pub pso: Vec<String>,
    /// The pulse budget of this controller (issue 15): the fastest pulse rate it can trigger
    /// as this post writes pulses (`max_pulse_rate`; LinuxCNC: a synchronized output switches
    /// once per servo period), and the most pulses one job may fire (`max_pulses`). `None`:
    /// no limit lase knows of. Checked before a program is written (`emit::validate`).
    #[serde(default)]
    pub budget: PulseBudget,
    /// The controller's servo period, s (`servo_period`; LinuxCNC's `[EMCMOT] SERVO_PERIOD`,
    /// which the generated INI writes): a motion-synchronized output leads the joints by a
    /// fixed number of these periods (`emit::lead`), so the writer places each beam switch
    /// that much further along the path. `None`: [`DEFAULT_SERVO_PERIOD_S`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub servo_period_s: Option<f64>,
    /// Where each template line is written in the machine file, so a diagnostic about one
    /// line points at it (empty for a post not read from a file).
    #[serde(skip)]
    pub spans: PostSpans,
}

/// A controller's pulse limits (`max_pulse_rate`, `max_pulses` of `[post.<dialect>]`), with
/// where the machine file states them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PulseBudget {
    pub max_rate_hz: Option<f64>,
    pub max_pulses: Option<u64>,
    #[serde(skip)]
    pub spans: [Option<Span>; 2],
}

/// The machine-file spans of a post's template lines, one per line in the order written.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PostSpans {
    pub laser_on: Vec<Span>,
    pub laser_off: Vec<Span>,
    pub power: Vec<Span>,
    pub pulse_on: Vec<Span>,
    pub pulse_off: Vec<Span>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventPost {
    /// NC lines per dialect ("linuxcnc", "grbl", "iso"); a dialect not listed cannot run the
    /// event.
    pub codes: BTreeMap<String, Vec<String>>,
    /// Time the machine needs after the event (e.g. a head swing), s.
    pub dwell_s: f64,
    pub doc: String,
}

/// One dialect's lines for a switched output (`[outputs.NAME] DIALECT = { on, off, stops }`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputLines {
    pub on: Vec<String>,
    pub off: Vec<String>,
    /// Whether the controller stops the table for these lines: GRBL's `M7`/`M8`/`M9` empty
    /// the planner first (coolant_control.c), LinuxCNC's `M62`/`M63` take effect with the next
    /// move without stopping. Defaults to `true`, the safe assumption.
    pub stops: bool,
}

/// A switched output of the machine (air assist, exhaust, a pointer): `output NAME on|off`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputPost {
    /// Lines per dialect ("linuxcnc", "grbl", "grblhal", "iso"); a dialect not listed cannot
    /// switch the output.
    pub posts: BTreeMap<String, OutputLines>,
    pub doc: String,
}

impl OutputPost {
    /// Whether switching stops the table on any dialect the output has lines for: one plan
    /// serves every dialect (as for beam switches), so it stops where the strictest one does.
    pub fn stops(&self) -> bool {
        self.posts.values().any(|p| p.stops)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    pub name: String,
    pub description: String,
    pub kinematics: KinematicsKind,
    pub geometry: Geometry,
    pub axes: Vec<Axis>,
    pub laser: LaserSpec,
    pub ramp: Ramp,
    pub junction_deviation_mm: f64,
    pub arc_tolerance_mm: f64,
    pub post: BTreeMap<String, DialectPost>,
    pub events: BTreeMap<String, EventPost>,
    #[serde(default)]
    pub outputs: BTreeMap<String, OutputPost>,
    /// The rotary attachment (`kinematics = "rotary"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotary: Option<Rotary>,
    /// Work offsets the operator has set on the controller, `[work_offsets] g55 = { X = "100
    /// mm", ... }`: by G number (54–59), one value per machine axis in internal units (an
    /// axis not given is 0). `lase emit --origin g55` checks the travel at machine positions
    /// with it; without it the check cannot be done there (issue 20).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub work_offsets: BTreeMap<u8, Vec<f64>>,
    /// How an NC program settles a row start on this machine (`[settle]`).
    #[serde(default)]
    pub settle: SettlePost,
    /// The dialect of the controller that runs this machine (`dialect = "grbl"`): `lase
    /// emit`'s default `--dialect` and the controller whose cycle time `lase plan` reports
    /// first (issue 13). `None`: LinuxCNC, emit's own default. A command given another
    /// controller (`--dialect`, a link) plans for that one instead (`Machine::run_on`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dialect: Option<String>,
}

/// Row-start settling written into an NC program (`scan … { settle }`, issue 15): where a
/// control reads the table's scales, or which of its own macros settles. A live link needs
/// none of this (it reads the status report); a dialect without an entry refuses `settle`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SettlePost {
    /// LinuxCNC: the HAL analog inputs (`motion.analog-in-NN`, read with `M66 E<n> L0`) that
    /// carry the X and Y scales' readings in mm, work coordinates.
    pub linuxcnc_inputs: Option<[u32; 2]>,
    /// ISO: the block that calls the control's settling macro, a template with `{x}` `{y}`
    /// (target, mm), `{ux}` `{uy}` (row direction), `{low}` `{high}` (window along, mm),
    /// `{across}` `{step}` (mm) and `{steps}` (most steps).
    pub iso_call: Option<String>,
}

/// LinuxCNC's usual servo period, s (1 ms: its sample configurations' `SERVO_PERIOD`).
pub const DEFAULT_SERVO_PERIOD_S: f64 = 0.001;

impl Machine {
    /// Plans for the controller that runs this job, `dialect` (`--dialect`, or the one a link
    /// speaks), in place of the machine file's `dialect`: the plan depends on it where a
    /// controller's own planner does (LinuxCNC's parabolic blends between G93 blocks,
    /// `motion::parabolic`), so a program written for one controller is not planned, checked
    /// or refused by another's rules.
    pub fn run_on(&mut self, dialect: &str) {
        self.dialect = Some(dialect.to_string());
    }

    /// The LinuxCNC servo period of this machine (`[post.linuxcnc] servo_period`), s.
    pub fn servo_period_s(&self) -> f64 {
        self.post
            .get("linuxcnc")
            .and_then(|p| p.servo_period_s)
            .unwrap_or(DEFAULT_SERVO_PERIOD_S)
    }

    pub fn axis_index(&self, name: &str) -> Option<usize> {
        self.axes
            .iter()
            .position(|a| a.name.eq_ignore_ascii_case(name))
    }
}

// ------------------------------------------------------------------ file format

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMachine {
    name: String,
    #[serde(default)]
    description: String,
    kinematics: toml::Spanned<String>,
    #[serde(default)]
    geometry: FileGeometry,
    axes: Vec<FileAxis>,
    laser: FileLaser,
    #[serde(default)]
    planner: FilePlanner,
    post: BTreeMap<String, FilePost>,
    #[serde(default)]
    events: BTreeMap<String, FileEvent>,
    #[serde(default)]
    outputs: BTreeMap<String, FileOutput>,
    rotary: Option<rotary::FileRotary>,
    #[serde(default)]
    work_offsets: BTreeMap<String, BTreeMap<String, toml::Spanned<String>>>,
    #[serde(default)]
    settle: FileSettle,
    dialect: Option<toml::Spanned<String>>,
}

/// `[settle]`: `linuxcnc = { x_input = 0, y_input = 1 }`, `iso = { call = "G65 P9100 …" }`.
#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileSettle {
    linuxcnc: Option<FileSettleLinuxCnc>,
    iso: Option<FileSettleIso>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSettleLinuxCnc {
    x_input: u32,
    y_input: u32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileSettleIso {
    call: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileAxis {
    name: toml::Spanned<String>,
    kind: AxisKind,
    part_axis: Option<toml::Spanned<String>>,
    travel: [toml::Spanned<String>; 2],
    v_max: toml::Spanned<String>,
    a_max: toml::Spanned<String>,
    j_max: toml::Spanned<String>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FileGeometry {
    head_x: Option<toml::Spanned<String>>,
    base: Option<[toml::Spanned<String>; 2]>,
    link1: Option<toml::Spanned<String>>,
    link2: Option<toml::Spanned<String>>,
    head: Option<toml::Spanned<String>>,
    elbow: Option<toml::Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileLaser {
    max_power: toml::Spanned<String>,
    max_pulse_rate: toml::Spanned<String>,
    pointer: Option<toml::Spanned<String>>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct FilePlanner {
    ramp: Option<Ramp>,
    junction_deviation: Option<toml::Spanned<String>>,
    arc_tolerance: Option<toml::Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FilePost {
    laser_on: Vec<toml::Spanned<String>>,
    laser_off: Vec<toml::Spanned<String>>,
    #[serde(default)]
    power: Vec<toml::Spanned<String>>,
    #[serde(default = "default_s_max")]
    s_max: f64,
    #[serde(default)]
    laser_switch_stops: bool,
    #[serde(default)]
    pulse_on: Vec<toml::Spanned<String>>,
    #[serde(default)]
    pulse_off: Vec<toml::Spanned<String>>,
    #[serde(default)]
    pso: Vec<String>,
    #[serde(default)]
    max_pulse_rate: Option<toml::Spanned<String>>,
    #[serde(default)]
    max_pulses: Option<toml::Spanned<u64>>,
    #[serde(default)]
    servo_period: Option<toml::Spanned<String>>,
}

fn texts(lines: &[toml::Spanned<String>]) -> Vec<String> {
    lines.iter().map(|l| l.get_ref().clone()).collect()
}

fn default_s_max() -> f64 {
    1000.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileEvent {
    #[serde(default)]
    doc: String,
    #[serde(default)]
    dwell: Option<toml::Spanned<String>>,
    codes: BTreeMap<String, Vec<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileOutput {
    #[serde(default)]
    doc: String,
    linuxcnc: Option<FileOutputLines>,
    grbl: Option<FileOutputLines>,
    grblhal: Option<FileOutputLines>,
    iso: Option<FileOutputLines>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileOutputLines {
    on: Vec<String>,
    off: Vec<String>,
    stops: Option<toml::Spanned<bool>>,
}

/// Whether `line` has the M-word `code` (`M8`, `m08`).
fn has_m(line: &str, code: u32) -> bool {
    line.split_whitespace().any(|w| {
        (w.starts_with('M') || w.starts_with('m')) && w[1..].parse::<u32>().ok() == Some(code)
    })
}

/// An output's lines for one dialect, refusing `stops = false` where lase knows the controller
/// stops (or switches at the wrong time): a plan that flew through such a switch would not be
/// the motion the machine makes.
fn output_lines(
    name: &str,
    dialect: &str,
    l: FileOutputLines,
    at: &dyn Fn(Range<usize>) -> Span,
) -> Result<OutputLines, MachineError> {
    let stops = l.stops.as_ref().is_none_or(|s| *s.get_ref());
    if let (false, Some(s)) = (stops, &l.stops) {
        let lines = || l.on.iter().chain(&l.off);
        let why = if matches!(dialect, "grbl" | "grblhal") {
            Some(
                "GRBL empties its planner before a spindle or coolant change (coolant_control.c \
                 `coolant_sync` calls `protocol_buffer_synchronize`) and runs no other \
                 output, so the table stops"
                    .to_string(),
            )
        } else if lines().any(|x| (7..=9).any(|c| has_m(x, c))) {
            Some("`M7`/`M8`/`M9` stop the table before they switch".to_string())
        } else if dialect == "linuxcnc"
            && lines().any(|x| [64, 65, 68].iter().any(|&c| has_m(x, c)))
        {
            Some(
                "`M64`/`M65`/`M68` switch at once, before the moves queued ahead of them; \
                 use the motion-synchronized `M62`/`M63`/`M67`"
                    .to_string(),
            )
        } else {
            None
        };
        if let Some(why) = why {
            return Err(MachineError::Invalid {
                message: format!("output `{name}` cannot fly on {dialect}"),
                span: at(s.span()),
                label: "`stops = false` here".into(),
                help: Some(format!("{why}; write `stops = true` (or leave it out)")),
            });
        }
    }
    Ok(OutputLines {
        on: l.on,
        off: l.off,
        stops,
    })
}

/// Parses a machine file whose text starts at global offset `base`.
pub fn parse_machine(text: &str, base: usize) -> Result<Machine, MachineError> {
    let at = |r: Range<usize>| Span::new(base + r.start, base + r.end);
    let file: FileMachine = toml::from_str(text).map_err(|e| {
        let span = e.span().map(at).unwrap_or(Span::new(base, base));
        MachineError::Invalid {
            message: e.message().to_string(),
            span,
            label: "here".into(),
            help: Some("see stdlib/machines/README.md for every field of a machine file".into()),
        }
    })?;
    let qty = |s: &toml::Spanned<String>, want: &[Dim], what: &str| -> Result<f64, MachineError> {
        let span = at(s.span());
        let bad = |label: String, help: String| MachineError::Invalid {
            message: format!("`{}` is not a valid {what}", s.get_ref()),
            span,
            label,
            help: Some(help),
        };
        let q = units::parse_quantity(s.get_ref()).map_err(|e| match e {
            QuantityError::NotANumber(_) => bad(
                "expected a number with a unit".into(),
                format!("write it like \"200 mm/s\"; {what} is {}", want[0]),
            ),
            QuantityError::UnknownUnit(e) => bad(
                format!("unknown unit `{}`", e.atom),
                e.suggestion
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| {
                        "units are written as in recipes: mm, deg, mm/s, m/s^2".into()
                    }),
            ),
            QuantityError::NotFinite(_) => bad("not finite".into(), "use a finite value".into()),
        })?;
        if q.bare && !want.contains(&Dim::NONE) {
            return Err(bad(
                "no unit".into(),
                format!(
                    "{what} is {}; give a unit, e.g. \"{} {}\"",
                    want[0],
                    q.value,
                    want[0].base_unit()
                ),
            ));
        }
        if !want.contains(&q.dim) {
            return Err(bad(
                format!("this is {}", q.dim),
                format!(
                    "{what} must be {}",
                    want.iter()
                        .map(|d| d.name())
                        .collect::<Vec<_>>()
                        .join(" or ")
                ),
            ));
        }
        Ok(q.value)
    };
    let positive = |v: f64, s: &toml::Spanned<String>, what: &str| -> Result<f64, MachineError> {
        if v > 0.0 {
            Ok(v)
        } else {
            Err(MachineError::Invalid {
                message: format!("{what} must be greater than zero"),
                span: at(s.span()),
                label: "not positive".into(),
                help: None,
            })
        }
    };
    let kinematics = match file.kinematics.get_ref().as_str() {
        "cartesian" => KinematicsKind::Cartesian,
        "cam_xwb" => KinematicsKind::CamXwb,
        "arm_3r" => KinematicsKind::Arm3r,
        "rotary" => KinematicsKind::Rotary,
        other => {
            return Err(MachineError::Invalid {
                message: format!("unknown kinematics `{other}`"),
                span: at(file.kinematics.span()),
                label: "not a kinematics model".into(),
                help: Some("available: cartesian, cam_xwb, arm_3r, rotary".into()),
            });
        }
    };
    let mut axes = Vec::new();
    for a in &file.axes {
        let (lin, ang) = match a.kind {
            AxisKind::Linear => (true, false),
            AxisKind::Rotary => (false, true),
        };
        let d = |l: Dim, r: Dim| if lin { [l] } else { [r] };
        let _ = ang;
        let min = qty(&a.travel[0], &d(Dim::LENGTH, Dim::ANGLE), "travel")?;
        let max = qty(&a.travel[1], &d(Dim::LENGTH, Dim::ANGLE), "travel")?;
        if min >= max {
            return Err(MachineError::Invalid {
                message: "travel must be [min, max] with min < max".into(),
                span: at(a.travel[0].span().start..a.travel[1].span().end),
                label: "empty travel".into(),
                help: None,
            });
        }
        let v_max = positive(
            qty(&a.v_max, &d(Dim::SPEED, Dim::ANGULAR_SPEED), "v_max")?,
            &a.v_max,
            "v_max",
        )?;
        let a_max = positive(
            qty(&a.a_max, &d(Dim::ACCEL, Dim::ANGULAR_ACCEL), "a_max")?,
            &a.a_max,
            "a_max",
        )?;
        let j_max = positive(
            qty(&a.j_max, &d(Dim::JERK, Dim::ANGULAR_JERK), "j_max")?,
            &a.j_max,
            "j_max",
        )?;
        let name = a.name.get_ref().to_ascii_uppercase();
        if !matches!(
            name.as_str(),
            "X" | "Y" | "Z" | "A" | "B" | "C" | "U" | "V" | "W"
        ) {
            return Err(MachineError::Invalid {
                message: format!("axis name `{}` is not an NC axis letter", a.name.get_ref()),
                span: at(a.name.span()),
                label: "not an axis letter".into(),
                help: Some("use X, Y, Z, A, B, C, U, V or W".into()),
            });
        }
        if axes.iter().any(|x: &Axis| x.name == name) {
            return Err(MachineError::Invalid {
                message: format!("axis `{name}` is defined twice"),
                span: at(a.name.span()),
                label: "duplicate".into(),
                help: None,
            });
        }
        let part_axis = match &a.part_axis {
            Some(p) if matches!(p.get_ref().as_str(), "x" | "y" | "z") => Some(p.get_ref().clone()),
            Some(p) => {
                return Err(MachineError::Invalid {
                    message: format!("part_axis `{}` must be x, y or z", p.get_ref()),
                    span: at(p.span()),
                    label: "not a part axis".into(),
                    help: None,
                });
            }
            None => None,
        };
        axes.push(Axis {
            name,
            kind: a.kind,
            part_axis,
            min,
            max,
            v_max,
            a_max,
            j_max,
        });
    }
    if axes.is_empty() || axes.len() > crate::axes::MAX_AXES {
        return Err(MachineError::Invalid {
            message: format!(
                "a machine has 1 to {} axes, this one has {}",
                crate::axes::MAX_AXES,
                axes.len()
            ),
            span: Span::new(base, base),
            label: "here".into(),
            help: None,
        });
    }
    let kinematics_span = at(file.kinematics.span());
    let need = |v: &Option<toml::Spanned<String>>, what: &str| -> Result<f64, MachineError> {
        match v {
            Some(s) => qty(s, &[Dim::LENGTH], what),
            None => Err(MachineError::Invalid {
                message: format!("this kinematics needs `geometry.{what}`"),
                span: kinematics_span,
                label: "here".into(),
                help: Some(format!("add `{what} = \"... mm\"` under [geometry]")),
            }),
        }
    };
    let roles = |kinds: &[AxisKind], names: &str| -> Result<(), MachineError> {
        let ok = axes.len() == kinds.len() && axes.iter().zip(kinds).all(|(a, k)| a.kind == *k);
        if ok {
            Ok(())
        } else {
            Err(MachineError::Invalid {
                message: format!("this kinematics needs exactly the axes {names}, in that order"),
                span: kinematics_span,
                label: "here".into(),
                help: None,
            })
        }
    };
    let mut geometry = Geometry::default();
    let mut rotary = None;
    match kinematics {
        KinematicsKind::Cartesian => {}
        KinematicsKind::Rotary => {
            let length = |s: &toml::Spanned<String>, what: &str| qty(s, &[Dim::LENGTH], what);
            rotary = Some(rotary::parse(
                file.rotary.as_ref(),
                &axes,
                kinematics_span,
                &at,
                &length,
            )?);
        }
        KinematicsKind::CamXwb => {
            roles(
                &[AxisKind::Linear, AxisKind::Rotary, AxisKind::Rotary],
                "table (linear), rotary table (rotary), head swivel (rotary)",
            )?;
            geometry.head_x = need(&file.geometry.head_x, "head_x")?;
        }
        KinematicsKind::Arm3r => {
            roles(
                &[
                    AxisKind::Linear,
                    AxisKind::Rotary,
                    AxisKind::Rotary,
                    AxisKind::Rotary,
                ],
                "slide (linear), A, B, C (rotary)",
            )?;
            geometry.link1 = positive(
                need(&file.geometry.link1, "link1")?,
                file.geometry.link1.as_ref().expect("checked"),
                "link1",
            )?;
            geometry.link2 = positive(
                need(&file.geometry.link2, "link2")?,
                file.geometry.link2.as_ref().expect("checked"),
                "link2",
            )?;
            geometry.head = need(&file.geometry.head, "head")?;
            if let Some([bx, by]) = &file.geometry.base {
                geometry.base = [
                    qty(bx, &[Dim::LENGTH], "base")?,
                    qty(by, &[Dim::LENGTH], "base")?,
                ];
            }
            geometry.elbow = match file.geometry.elbow.as_ref().map(|e| e.get_ref().as_str()) {
                None | Some("up") => 1.0,
                Some("down") => -1.0,
                Some(other) => {
                    return Err(MachineError::Invalid {
                        message: format!("elbow `{other}` must be \"up\" or \"down\""),
                        span: at(file.geometry.elbow.as_ref().expect("present").span()),
                        label: "here".into(),
                        help: None,
                    });
                }
            };
        }
    }
    if kinematics == KinematicsKind::Cartesian {
        for (i, a) in file.axes.iter().enumerate() {
            if axes[i].kind != AxisKind::Linear || axes[i].part_axis.is_none() {
                return Err(MachineError::Invalid {
                    message: "a cartesian machine's axes are linear and each names its part_axis"
                        .into(),
                    span: at(a.name.span()),
                    label: "this axis".into(),
                    help: Some("add `part_axis = \"x\"` (or y, z) and `kind = \"linear\"`".into()),
                });
            }
        }
    }
    let mut laser = LaserSpec {
        max_power_w: positive(
            qty(&file.laser.max_power, &[Dim::POWER], "max_power")?,
            &file.laser.max_power,
            "max_power",
        )?,
        max_pulse_rate_hz: positive(
            qty(
                &file.laser.max_pulse_rate,
                &[Dim::FREQUENCY],
                "max_pulse_rate",
            )?,
            &file.laser.max_pulse_rate,
            "max_pulse_rate",
        )?,
        pointer_w: None,
    };
    if let Some(p) = &file.laser.pointer {
        let w = positive(qty(p, &[Dim::POWER], "pointer")?, p, "pointer")?;
        if w > laser.max_power_w {
            return Err(MachineError::Invalid {
                message: format!("the pointer power `{}` is above max_power", p.get_ref()),
                span: at(p.span()),
                label: "above the laser's full power".into(),
                help: Some("the pointer marks where the job will be at a power that marks nothing; give a power at most max_power".into()),
            });
        }
        laser.pointer_w = Some(w);
    }
    let junction_deviation_mm = match &file.planner.junction_deviation {
        Some(s) => positive(
            qty(s, &[Dim::LENGTH], "junction_deviation")?,
            s,
            "junction_deviation",
        )?,
        None => 0.01,
    };
    let arc_tolerance_mm = match &file.planner.arc_tolerance {
        Some(s) => positive(qty(s, &[Dim::LENGTH], "arc_tolerance")?, s, "arc_tolerance")?,
        None => 0.002,
    };
    let mut post = BTreeMap::new();
    for (k, p) in file.post {
        let max_rate_hz = match &p.max_pulse_rate {
            Some(r) => Some(positive(
                qty(r, &[Dim::FREQUENCY], "max_pulse_rate")?,
                r,
                "max_pulse_rate",
            )?),
            None => None,
        };
        let budget = PulseBudget {
            max_rate_hz,
            max_pulses: p.max_pulses.as_ref().map(|n| *n.get_ref()),
            spans: [
                p.max_pulse_rate.as_ref().map(|r| at(r.span())),
                p.max_pulses.as_ref().map(|n| at(n.span())),
            ],
        };
        let servo_period_s = match &p.servo_period {
            Some(t) => Some(positive(
                qty(t, &[Dim::TIME], "servo_period")?,
                t,
                "servo_period",
            )?),
            None => None,
        };
        post.insert(
            k,
            DialectPost {
                servo_period_s,
                laser_on: texts(&p.laser_on),
                laser_off: texts(&p.laser_off),
                power: texts(&p.power),
                s_max: p.s_max,
                laser_switch_stops: p.laser_switch_stops,
                pulse_on: texts(&p.pulse_on),
                pulse_off: texts(&p.pulse_off),
                pso: p.pso,
                budget,
                spans: PostSpans {
                    laser_on: p.laser_on.iter().map(|l| at(l.span())).collect(),
                    laser_off: p.laser_off.iter().map(|l| at(l.span())).collect(),
                    power: p.power.iter().map(|l| at(l.span())).collect(),
                    pulse_on: p.pulse_on.iter().map(|l| at(l.span())).collect(),
                    pulse_off: p.pulse_off.iter().map(|l| at(l.span())).collect(),
                },
            },
        );
    }
    let mut events = BTreeMap::new();
    for (k, e) in file.events {
        let dwell_s = match &e.dwell {
            Some(s) => qty(s, &[Dim::TIME], "dwell")?,
            None => 0.0,
        };
        events.insert(
            k,
            EventPost {
                codes: e.codes,
                dwell_s,
                doc: e.doc,
            },
        );
    }
    let mut outputs = BTreeMap::new();
    for (k, o) in file.outputs {
        let mut posts = BTreeMap::new();
        for (dialect, lines) in [
            ("linuxcnc", o.linuxcnc),
            ("grbl", o.grbl),
            ("grblhal", o.grblhal),
            ("iso", o.iso),
        ] {
            if let Some(l) = lines {
                posts.insert(dialect.to_string(), output_lines(&k, dialect, l, &at)?);
            }
        }
        outputs.insert(k, OutputPost { posts, doc: o.doc });
    }
    if let (Some(r), false) = (&file.rotary, kinematics == KinematicsKind::Rotary) {
        return Err(MachineError::Invalid {
            message: "`[rotary]` belongs to the rotary kinematics".into(),
            span: at(r.span()),
            label: "not used".into(),
            help: Some("write `kinematics = \"rotary\"`, or remove `[rotary]`".into()),
        });
    }
    // The controller's dialect must be one lase writes and one this file has a post for
    // (grblHAL runs GRBL's lines), or `lase emit` without `--dialect` would fail later.
    if let Some(d) = &file.dialect {
        let name = d.get_ref().as_str();
        let keys: &[&str] = match name {
            "linuxcnc" | "grbl" | "iso" => &[name],
            "grblhal" => &["grblhal", "grbl"],
            _ => {
                return Err(MachineError::Invalid {
                    message: format!("unknown dialect `{name}`"),
                    span: at(d.span()),
                    label: "not a dialect".into(),
                    help: Some("the dialects are linuxcnc, grbl, grblhal and iso".into()),
                });
            }
        };
        if !keys.iter().any(|k| post.contains_key(*k)) {
            return Err(MachineError::Invalid {
                message: format!("the machine's dialect `{name}` has no `[post.{name}]`"),
                span: at(d.span()),
                label: "no post for it".into(),
                help: Some(format!(
                    "add `[post.{name}]` with the lines that switch the laser, or name a dialect the file has a post for"
                )),
            });
        }
    }
    let mut work_offsets = BTreeMap::new();
    for (key, values) in &file.work_offsets {
        let n = key
            .to_ascii_lowercase()
            .strip_prefix('g')
            .and_then(|n| n.parse::<u8>().ok())
            .filter(|n| (54..=59).contains(n));
        let Some(n) = n else {
            return Err(MachineError::Invalid {
                message: format!("`{key}` is not a work offset"),
                span: values
                    .values()
                    .next()
                    .map(|v| at(v.span()))
                    .unwrap_or(kinematics_span),
                label: "not g54 … g59".into(),
                help: Some("name the offset by its G number: g54, g55, … g59".into()),
            });
        };
        let mut v = vec![0.0; axes.len()];
        for (letter, value) in values {
            let Some(i) = axes
                .iter()
                .position(|a| a.name.eq_ignore_ascii_case(letter))
            else {
                return Err(MachineError::Invalid {
                    message: format!("work offset g{n}: the machine has no axis `{letter}`"),
                    span: at(value.span()),
                    label: "no such axis".into(),
                    help: Some("give values for the machine's own axis letters".into()),
                });
            };
            v[i] = match axes[i].kind {
                AxisKind::Linear => qty(value, &[Dim::LENGTH], "work offset")?,
                AxisKind::Rotary => qty(value, &[Dim::ANGLE], "work offset")?,
            };
        }
        work_offsets.insert(n, v);
    }
    Ok(Machine {
        name: file.name,
        description: file.description,
        kinematics,
        geometry,
        axes,
        laser,
        ramp: file.planner.ramp.unwrap_or(Ramp::Scurve),
        junction_deviation_mm,
        arc_tolerance_mm,
        post,
        events,
        outputs,
        rotary,
        work_offsets,
        settle: SettlePost {
            linuxcnc_inputs: file.settle.linuxcnc.map(|l| [l.x_input, l.y_input]),
            iso_call: file.settle.iso.map(|i| i.call),
        },
        dialect: file.dialect.map(|d| d.into_inner()),
    })
}
