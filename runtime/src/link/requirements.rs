//! What a job needs from a controller's configuration, from its plan: the laser, each axis's
//! peak rate and acceleration (from [`crate::report::summarize`]) and where in the recipe each
//! peak is reached, so a setting too low for the plan is reported at the statement that needs
//! it. Protocol-neutral: a link maps these to its own settings (GRBL `$32`, `$110`…).

use crate::emit::Dialect;
use crate::motion::Job;
use lase_lang::Span;

/// A controller setting that would make the job run differently from its plan.
#[derive(Debug, Clone, PartialEq, thiserror::Error, miette::Diagnostic)]
#[error("controller setting {setting} is {found}, the job needs {needed}")]
#[diagnostic(code(lase::link::setting))]
pub struct SettingMismatch {
    pub setting: String,
    pub found: String,
    pub needed: String,
    #[label("{label}")]
    pub span: Span,
    pub label: String,
    #[help]
    pub help: String,
}

/// One axis's needs, in the axis's external unit (`axes::external_unit`: mm for a linear
/// axis, deg for a rotary one), per minute and per second² as controller settings take them.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisNeed {
    /// The NC address letter.
    pub letter: char,
    /// A rotary axis: its rate and acceleration are in degrees.
    pub rotary: bool,
    /// Peak speed, units per minute: mm/min, or deg/min for a rotary axis (the unit of
    /// controller rate settings).
    pub v_per_min: f64,
    /// Peak acceleration, units per s²: mm/s², or deg/s² for a rotary axis.
    pub a_per_s2: f64,
    /// Where the peak speed and the peak acceleration are reached.
    pub v_span: Span,
    pub a_span: Span,
}

/// What a job needs from the controller.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Requirements {
    /// The first lit move, when the job fires the laser at all.
    pub laser: Option<Span>,
    pub axes: Vec<AxisNeed>,
    /// The S word the dialect's post writes for full power, and the op that first uses it.
    pub s_max: Option<(f64, Span)>,
}

impl Requirements {
    /// The needs of a planned job sent in `dialect`.
    pub fn of_job(job: &Job, dialect: Dialect) -> Requirements {
        let program = &job.program;
        let summary = crate::report::summarize(job);
        let span_of = |tag: u32| {
            program
                .ops
                .get(tag as usize)
                .map(|o| o.span)
                .unwrap_or_default()
        };
        let laser = program
            .ops
            .iter()
            .find(|o| o.laser().is_some())
            .map(|o| o.span);
        // Where each axis's peaks are reached: the same per-segment quantities `summarize`
        // takes the maximum of (|u_k|·v_peak and |u_k|·a_peak along a straight move).
        let segs = job.plan.segments();
        let controller = super::ControllerAxes::of(&program.machine);
        let mut axes = Vec::new();
        for (k, axis) in program.machine.axes.iter().enumerate() {
            let Some(peaks) = summary.axes.get(&axis.name) else {
                continue;
            };
            let (mut best_v, mut best_a) = ((0.0, Span::default()), (0.0, Span::default()));
            for (i, seg) in segs.iter().enumerate() {
                let u = job.plan.direction(i)[k].abs();
                let v = u * seg.v_peak;
                let a = u * seg.accel_peak().max(seg.decel_peak());
                if v > best_v.0 {
                    best_v = (v, span_of(seg.tag));
                }
                if a > best_a.0 {
                    best_a = (a, span_of(seg.tag));
                }
            }
            axes.push(AxisNeed {
                letter: controller.letters()[k],
                rotary: axis.kind == crate::machine::AxisKind::Rotary,
                // The summary's peaks are in external units already.
                v_per_min: peaks.v_max * 60.0,
                a_per_s2: peaks.a_max,
                v_span: best_v.1,
                a_span: best_a.1,
            });
        }
        let s_max = dialect
            .lookup(&program.machine.post)
            .map(|(_, p)| p)
            .filter(|p| p.laser_on.iter().chain(&p.power).any(|t| t.contains("{s}")))
            .and_then(|p| laser.map(|span| (p.s_max, span)));
        Requirements { laser, axes, s_max }
    }
}
