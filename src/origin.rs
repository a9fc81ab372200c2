//! Where a job's zero is on the machine (issue 20, job origin): `absolute` (the recipe's
//! coordinates are the controller's, as always) or `current` (the recipe's zero is where the
//! spot stands when the job starts). For `current`, `lase run` reads the controller's
//! position before anything is planned, moves the program there, and plans it against the
//! machine's travel, so a job that would leave the travel from here is refused before a line
//! is sent, with the position it was placed at. `lase emit --origin current` cannot know that
//! position: it writes the recipe's coordinates in a work frame whose zero its header sets
//! where the operator has jogged the spot (`G10 L20 P1`, then `G54`), and refuses a job
//! larger than the travel (placed at the travel's middle, it would still leave it).
//!
//! A named work offset (`g54` … `g59`) is the operator's own, set on the controller: the
//! program selects it (`G55` after the header's units) and never writes it. The travel check
//! is at machine positions (machine = work + offset): `lase run` reads the offset from the
//! controller (`$#`), `lase emit` takes it from `--work-offset` or the machine file's
//! `[work_offsets]`. Without either, emit can only check that the job fits the travel
//! somewhere, and says so with a warning; `--set-origin` writes `G10 L20 P2` (for G55) to
//! set the offset where the spot stands, as `current` does for G54.

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
    /// The controller's work offset G54 (machine = work + offset).
    G54,
    /// Work offset G55.
    G55,
    /// Work offset G56.
    G56,
    /// Work offset G57.
    G57,
    /// Work offset G58.
    G58,
    /// Work offset G59.
    G59,
}

const WORK: [JobOrigin; 6] = [
    JobOrigin::G54,
    JobOrigin::G55,
    JobOrigin::G56,
    JobOrigin::G57,
    JobOrigin::G58,
    JobOrigin::G59,
];

impl JobOrigin {
    /// The G number of a named work offset.
    pub fn work(self) -> Option<u8> {
        WORK.iter().position(|w| *w == self).map(|i| 54 + i as u8)
    }
}

impl From<lase_runtime::program::JobOrigin> for JobOrigin {
    fn from(o: lase_runtime::program::JobOrigin) -> Self {
        match o {
            lase_runtime::program::JobOrigin::Absolute => JobOrigin::Absolute,
            lase_runtime::program::JobOrigin::Current => JobOrigin::Current,
            lase_runtime::program::JobOrigin::Work(g) => WORK
                .get(usize::from(g.saturating_sub(54)))
                .copied()
                .unwrap_or(JobOrigin::G54),
        }
    }
}

impl From<JobOrigin> for lase_runtime::program::JobOrigin {
    fn from(o: JobOrigin) -> Self {
        match (o, o.work()) {
            (_, Some(g)) => lase_runtime::program::JobOrigin::Work(g),
            (JobOrigin::Current, _) => lase_runtime::program::JobOrigin::Current,
            _ => lase_runtime::program::JobOrigin::Absolute,
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
    #[error("with the work offset G{g} ({at}) the job leaves the travel")]
    #[diagnostic(
        code(lase::origin::offset),
        help(
            "machine = work + offset: set G{g} where the whole job fits inside the travel, or choose another origin"
        )
    )]
    Offset {
        g: u8,
        at: String,
        #[label("placed by G{g}")]
        span: Span,
    },
    #[error("the controller did not report its work offset G{0}")]
    #[diagnostic(
        code(lase::origin::unknown_offset),
        help(
            "lase checks the travel at machine positions, which needs the offset: give it in the machine file's `[work_offsets]`"
        )
    )]
    UnknownOffset(u8),
    #[error("--origin {0} writes no work offset; --set-origin sets one where the spot stands")]
    #[diagnostic(
        code(lase::origin::set_origin),
        help("use --set-origin with --origin g54 … g59")
    )]
    SetOrigin(String),
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
    work_frame_in(program, dialect, 54)
}

/// [`work_frame`] for the work offset G`g`: `G10 L20 P{g − 53}` sets it where the spot
/// stands, then `G{g}` selects it (the program's own `G{g}`, for a named origin, follows).
fn work_frame_in(
    program: ProcessProgram,
    dialect: Dialect,
    g: u8,
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
    let words: Vec<String> = linear_part_axes(&program)
        .iter()
        .map(|(_, _, n)| format!("{n}0"))
        .collect();
    let job = fit_anywhere(program)?;
    let mut setup = vec![
        "(origin: current position. Jog to the job's zero first)".to_string(),
        format!("G10 L20 P{} {}", g - 53, words.join(" ")),
    ];
    if g == 54 {
        setup.push("G54".to_string());
    }
    Ok((job, setup))
}

/// The job planned in its own coordinates with each linear axis free to move a travel's
/// length either way (its zero may be anywhere in the travel), after the same program
/// centred in the travel was planned with the travel as it is: a job larger than the travel
/// is refused.
fn fit_anywhere(program: ProcessProgram) -> Result<Job, Failure> {
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
    lase_runtime::compile::plan(free)
}

/// A work offset from the command line, `X100 Y50` (mm, deg for rotary axes), one value per
/// machine axis in internal units (an axis not named is 0).
pub fn parse_offset(
    text: &str,
    machine: &lase_runtime::machine::Machine,
) -> Result<Vec<f64>, String> {
    let mut v = vec![0.0; machine.axes.len()];
    for w in text.split([' ', ',']).filter(|w| !w.is_empty()) {
        let (letter, num) = w.split_at(w.chars().next().map_or(0, char::len_utf8));
        let i = machine
            .axis_index(letter)
            .ok_or_else(|| format!("`{w}`: machine `{}` has no axis {letter}", machine.name))?;
        let x: f64 = num
            .parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| format!("`{w}`: write an axis letter and a number, e.g. X100"))?;
        v[i] = lase_runtime::axes::from_external(machine.axes[i].kind, x);
    }
    Ok(v)
}

/// The program with each axis's travel moved by the work offset (machine = work + offset:
/// the work coordinates the recipe writes may span [min − o, max − o]), and the offset
/// for messages, `X100 Y50`.
fn with_offset(mut program: ProcessProgram, offset: &[f64]) -> (ProcessProgram, String) {
    let mut at = Vec::new();
    for (a, o) in program.machine.axes.iter_mut().zip(offset) {
        a.min -= o;
        a.max -= o;
        let ext = lase_runtime::axes::to_external(a.kind, *o);
        at.push(format!("{}{}", a.name, fmt_mm(ext)));
    }
    (program, at.join(" "))
}

/// `lase run --origin g55`: the link opened, the work offset read from the controller and
/// the program planned at it ([`at_offset`]): a job that would leave the travel is refused
/// before a line is sent, with the offset named. A resumed job continues where its journal
/// recorded (the controller's offset has not moved under a job it was running).
pub fn run_at_offset<T>(
    recipe: crate::driver::Recipe,
    program: ProcessProgram,
    named: JobOrigin,
    url: &link::LinkUrl,
    options: &link::ConnectOptions,
    resumed: &Option<T>,
) -> Result<crate::live::Placed, (lase_lang::SourceMap, Failure)> {
    let map = recipe.map.clone();
    let g = named.work().expect("a named origin");
    if resumed.is_some() {
        return match lase_runtime::compile::plan(program) {
            Ok(job) => Ok((recipe, job, None)),
            Err(f) => Err((map, f)),
        };
    }
    let fail = |e: link::LinkError| (map.clone(), Failure::one(link::job::not_started(e)));
    let mut link = link::connect(url, &program.machine, options).map_err(fail)?;
    let reported = link.work_offset(g).map_err(fail)?;
    match at_offset(program, g, reported) {
        Ok((job, at)) => {
            eprintln!(
                "{}: the job's zero is the work offset G{g} {at}",
                recipe.name()
            );
            Ok((recipe, job, Some(link)))
        }
        Err(f) => Err((map, f)),
    }
}

/// `lase run --origin g55`: the program planned with the travel moved by the offset the
/// controller reported (`Link::work_offset`: controller slots X Y Z A B C in mm and deg), else
/// the machine file's `[work_offsets]`; refused when neither says, or when the job would
/// leave the travel there. Returns the job and the offset, for the message.
pub fn at_offset(
    mut program: ProcessProgram,
    g: u8,
    reported: Option<Vec<f64>>,
) -> Result<(Job, String), Failure> {
    if lase_runtime::kinematics::for_machine(&program.machine).oriented() {
        return Err(Failure::one(OriginError::Oriented(
            program.machine.name.clone(),
        )));
    }
    program.planner.origin = lase_runtime::program::JobOrigin::Work(g);
    let offset = match reported {
        Some(slots) => program
            .machine
            .axes
            .iter()
            .map(|a| {
                let slot = a.name.chars().next().and_then(link::axis_index);
                let v = slot.and_then(|s| slots.get(s)).copied().unwrap_or(0.0);
                lase_runtime::axes::from_external(a.kind, v)
            })
            .collect::<Vec<f64>>(),
        None => match program.machine.work_offsets.get(&g) {
            Some(o) => o.clone(),
            None => return Err(Failure::one(OriginError::UnknownOffset(g))),
        },
    };
    plan_offset(program, g, &offset)
}

/// The program planned with each axis's travel moved by work offset G`g`; a job that leaves
/// it is refused with the travel diagnostic and one naming the offset.
fn plan_offset(program: ProcessProgram, g: u8, offset: &[f64]) -> Result<(Job, String), Failure> {
    let first = program.ops.first().map(|o| o.span).unwrap_or_default();
    let (moved, at) = with_offset(program, offset);
    match lase_runtime::compile::plan(moved) {
        Ok(job) => Ok((job, at)),
        Err(mut f) => {
            f.diagnostics
                .push(Box::new(OriginError::Offset { g, at, span: first }));
            Err(f)
        }
    }
}

/// `lase emit --origin g55`: the program selects the offset (`G55`, written by the emitter)
/// and is planned with the travel moved by it, when it is known (`--work-offset`, else the
/// machine file's `[work_offsets]`); a job that would leave the travel is refused with the
/// offset named. When it is not known, the job is only checked to fit the travel somewhere
/// (as for `current`) and the third value is the warning to print. `set_here`: the header
/// sets the offset where the spot stands first (`G10 L20 P2`).
pub fn named(
    mut program: ProcessProgram,
    dialect: Dialect,
    g: u8,
    given: Option<Vec<f64>>,
    set_here: bool,
) -> Result<(Job, Vec<String>, Option<String>), Failure> {
    if lase_runtime::kinematics::for_machine(&program.machine).oriented() {
        return Err(Failure::one(OriginError::Oriented(
            program.machine.name.clone(),
        )));
    }
    program.planner.origin = lase_runtime::program::JobOrigin::Work(g);
    if set_here {
        let (job, setup) = work_frame_in(program, dialect, g)?;
        return Ok((job, setup, None));
    }
    let offset = given.or_else(|| program.machine.work_offsets.get(&g).cloned());
    let Some(offset) = offset else {
        let warning = format!(
            "the work offset G{g} is not known here: the travel was checked only for the job's \
             size, not at machine positions; give it with --work-offset or `[work_offsets] g{g}` \
             in the machine file (`lase run` reads it from the controller)"
        );
        return Ok((fit_anywhere(program)?, Vec::new(), Some(warning)));
    };
    let (job, at) = plan_offset(program, g, &offset)?;
    Ok((job, vec![format!("(origin: work offset G{g} {at})")], None))
}

fn fmt_mm(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
