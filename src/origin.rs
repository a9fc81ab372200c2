//! Where a job's zero is on the machine (issue 20, job origin): `absolute` (the recipe's
//! coordinates are the controller's, as always) or `current` (the recipe's zero is where the
//! spot stands when the job starts). For `current`, `lase run` reads the controller's
//! position before anything is planned, moves the program there, and plans it against the
//! machine's travel, so a job that would leave the travel from here is refused before a line
//! is sent, with the position it was placed at. `lase emit --origin current` cannot know that
//! position: it writes the recipe's coordinates in a work frame whose zero its header sets
//! where the operator has jogged the spot (`G10 L20 P1`, then `G54`), and refuses a job
//! larger than the travel (placed at the travel's middle, it would still leave it).

use lase_lang::Span;
use lase_runtime::compile::Failure;
use lase_runtime::emit::Dialect;
use lase_runtime::link::{self, Status};
use lase_runtime::machine::AxisKind;
use lase_runtime::motion::Job;
use lase_runtime::program::{P3, ProcessProgram};

/// `--origin`: where the recipe's zero is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum JobOrigin {
    /// The recipe's coordinates are the controller's.
    #[default]
    Absolute,
    /// The recipe's zero is the spot's position when the job starts.
    Current,
}

impl From<lase_runtime::program::JobOrigin> for JobOrigin {
    fn from(o: lase_runtime::program::JobOrigin) -> Self {
        match o {
            lase_runtime::program::JobOrigin::Absolute => JobOrigin::Absolute,
            lase_runtime::program::JobOrigin::Current => JobOrigin::Current,
        }
    }
}

/// `--origin` if given, else the recipe's `planner { origin ... }`.
pub fn chosen(cli: Option<JobOrigin>, program: &ProcessProgram) -> JobOrigin {
    cli.unwrap_or_else(|| program.planner.origin.into())
}

/// Why a job cannot be placed at the controller's position.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum OriginError {
    #[error("--origin current: the controller did not report its position")]
    #[diagnostic(
        code(lase::origin::no_position),
        help(
            "the job's zero is where the spot stands; a controller that reports no MPos or WPos cannot place it: run with --origin absolute"
        )
    )]
    NoPosition,
    #[error("--origin current places the job on a flat bed; machine `{0}` orients the beam")]
    #[diagnostic(
        code(lase::origin::oriented),
        help("an oriented machine starts from its axis zero: run with --origin absolute")
    )]
    Oriented(String),
    #[error("--origin current needs G10 L20 to set the work frame; {0} has none lase writes")]
    #[diagnostic(
        code(lase::origin::dialect),
        help("emit for linuxcnc, grbl or grblhal, or with --origin absolute")
    )]
    Dialect(Dialect),
    #[error("the job is larger than the travel: placed at its middle ({at}), it leaves it")]
    #[diagnostic(
        code(lase::origin::too_large),
        help("with --origin current the job may start anywhere; no start fits a job this large")
    )]
    TooLarge {
        at: String,
        #[label("this job")]
        span: Span,
    },
    #[error("the job's zero is the controller's position {at} (--origin current)")]
    #[diagnostic(
        code(lase::origin::placed),
        help(
            "jog to where the whole job fits inside the travel, or run it with --origin absolute"
        )
    )]
    Placed {
        at: String,
        #[label("placed here")]
        span: Span,
    },
}

/// The program moved so that its zero is the controller's work position (what the streamed
/// `G90` coordinates mean), with each linear axis's travel moved by the work offset the
/// controller reports (`WCO`, machine = work + WCO): the travel check is then against the
/// machine positions the job will reach. Returns the program and the position, for messages.
pub fn at_current(
    mut program: ProcessProgram,
    status: &Status,
    oriented: bool,
) -> Result<(ProcessProgram, String), OriginError> {
    if oriented {
        return Err(OriginError::Oriented(program.machine.name.clone()));
    }
    let wco = status.wco.clone().unwrap_or_default();
    let work = status
        .work_position(status.wco.as_deref())
        .ok_or(OriginError::NoPosition)?;
    let mut by = [0.0; 3];
    let mut at = Vec::new();
    for axis in &mut program.machine.axes {
        let slot = axis.name.chars().next().and_then(link::axis_index);
        let (Some(slot), AxisKind::Linear) = (slot, axis.kind) else {
            continue;
        };
        let part = match axis.part_axis.as_deref() {
            Some("x") => 0,
            Some("y") => 1,
            Some("z") => 2,
            _ => continue,
        };
        let w = work.get(slot).copied().unwrap_or(0.0);
        let o = wco.get(slot).copied().unwrap_or(0.0);
        by[part] = w;
        axis.min -= o;
        axis.max -= o;
        at.push(format!("{}{}", axis.name, fmt_mm(w)));
    }
    Ok((program.translated(by), at.join(" ")))
}

/// The part axes (0 x, 1 y, 2 z) the linear axes of a flat bed move, with their travel.
fn linear_part_axes(program: &ProcessProgram) -> Vec<(usize, usize, String)> {
    program
        .machine
        .axes
        .iter()
        .enumerate()
        .filter(|(_, a)| a.kind == AxisKind::Linear)
        .filter_map(|(i, a)| {
            let part = match a.part_axis.as_deref() {
                Some("x") => 0,
                Some("y") => 1,
                Some("z") => 2,
                _ => return None,
            };
            Some((i, part, a.name.clone()))
        })
        .collect()
}

/// `lase emit --origin current`: the job planned in its own coordinates with each linear
/// axis free to move a travel's length either way (the start may be anywhere in the travel),
/// after the same program centred in the travel was planned with the travel as it is: a job
/// larger than the travel is refused. Returns the job and the setup lines that set the work
/// frame where the spot stands (written after the header's `G21 G90 …`).
pub fn work_frame(
    program: ProcessProgram,
    dialect: Dialect,
) -> Result<(Job, Vec<String>), Failure> {
    if !matches!(
        dialect,
        Dialect::LinuxCnc | Dialect::Grbl | Dialect::GrblHal
    ) {
        return Err(Failure::one(OriginError::Dialect(dialect)));
    }
    if lase_runtime::kinematics::for_machine(&program.machine).oriented() {
        return Err(Failure::one(OriginError::Oriented(
            program.machine.name.clone(),
        )));
    }
    let axes = linear_part_axes(&program);
    let mut lo = program.start;
    let mut hi = program.start;
    for t in program.ops.iter().filter_map(|o| o.target()) {
        for k in 0..3 {
            lo[k] = lo[k].min(t[k]);
            hi[k] = hi[k].max(t[k]);
        }
    }
    let mut by: P3 = [0.0; 3];
    let mut at = Vec::new();
    for (i, part, name) in &axes {
        let a = &program.machine.axes[*i];
        by[*part] = (a.min + a.max) / 2.0 - (lo[*part] + hi[*part]) / 2.0;
        at.push(format!("{name}{}", fmt_mm(by[*part])));
    }
    let first = program.ops.first().map(|o| o.span).unwrap_or_default();
    if let Err(mut f) = lase_runtime::compile::plan(program.clone().translated(by)) {
        f.diagnostics.push(Box::new(OriginError::TooLarge {
            at: format!("zero at {}", at.join(" ")),
            span: first,
        }));
        return Err(f);
    }
    let mut free = program;
    for (i, _, _) in &axes {
        let a = &mut free.machine.axes[*i];
        let span = a.max - a.min;
        (a.min, a.max) = (-span, span);
    }
    let job = lase_runtime::compile::plan(free)?;
    let words: Vec<String> = axes.iter().map(|(_, _, n)| format!("{n}0")).collect();
    let setup = vec![
        "(origin: current position. Jog to the job's zero first)".to_string(),
        format!("G10 L20 P1 {}", words.join(" ")),
        "G54".to_string(),
    ];
    Ok((job, setup))
}

fn fmt_mm(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
