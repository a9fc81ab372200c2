//! Where a job's zero is on the machine (issue 20, job origin): `absolute` (the recipe's
//! coordinates are the controller's, as always) or `current` (the recipe's zero is where the
//! spot stands when the job starts). For `current`, `lase run` reads the controller's
//! position before anything is planned, moves the program there, and plans it against the
//! machine's travel, so a job that would leave the travel from here is refused before a line
//! is sent, with the position it was placed at.

use lase_lang::Span;
use lase_runtime::link::{self, Status};
use lase_runtime::machine::AxisKind;
use lase_runtime::program::ProcessProgram;

/// `--origin`: where the recipe's zero is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum JobOrigin {
    /// The recipe's coordinates are the controller's.
    #[default]
    Absolute,
    /// The recipe's zero is the spot's position when the job starts.
    Current,
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

fn fmt_mm(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
