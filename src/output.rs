//! Output files, written atomically: into a temporary file beside the target, then renamed,
//! so a failed run never leaves a half-written NC program behind.

use crate::driver::{Failure, IoError};
use lase_lang::{SourceMap, Span};
use std::io::Write;
use std::path::Path;

pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> Result<(), (SourceMap, Failure)>,
) -> Result<(), (SourceMap, Failure)> {
    let fail = |m: String| (SourceMap::new(), Failure::one(IoError { message: m }));
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let tmp = tempfile::NamedTempFile::new_in(dir)
        .map_err(|e| fail(format!("cannot write in {}: {e}", dir.display())))?;
    let mut w = std::io::BufWriter::new(tmp);
    body(&mut w)?;
    let tmp = w
        .into_inner()
        .map_err(|e| fail(format!("cannot write {}: {e}", path.display())))?;
    tmp.persist(path)
        .map_err(|e| fail(format!("cannot write {}: {e}", path.display())))?;
    Ok(())
}

/// The controller refused a line: points at the recipe line that produced it.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[error("the controller rejected line {line_no} `{line}`: error {code}, {message}")]
#[diagnostic(
    code(lase::link::rejected),
    help(
        "the job was stopped at this line ({stop}); fix the recipe statement it came from and run the job again"
    )
)]
pub struct ControllerRejected {
    pub line_no: usize,
    pub line: String,
    pub code: u32,
    pub message: String,
    #[label("this statement produced the rejected line")]
    pub span: Span,
    /// What the stop sequence did.
    pub stop: String,
}

/// The controller raised an alarm; points at the line it was parsing, when known.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[error("the controller raised ALARM:{code}{line}: {message}")]
#[diagnostic(
    code(lase::link::alarm),
    help(
        "the job was stopped ({stop}); clear the alarm on the controller (`$X`, or home it when the position may be lost) before running again"
    )
)]
pub struct ControllerAlarm {
    pub line: String,
    pub code: u32,
    pub message: String,
    #[label("this statement produced the line the controller was reading")]
    pub span: Option<Span>,
    pub stop: String,
}

/// The link dropped in the middle of a job.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[error("the link to the controller was lost after {acked} of {total} lines: {reason}")]
#[diagnostic(code(lase::link::lost))]
pub struct LinkLost {
    pub reason: String,
    pub acked: usize,
    pub total: usize,
    /// How to go on: the controller goes on with what it had received.
    #[help]
    pub resume: String,
}

/// The operator aborted a streaming job.
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
#[error("aborted after {acked} of {total} lines: {stop}")]
#[diagnostic(
    code(lase::link::aborted),
    help("the controller was stopped at rest and reset; the job cannot be resumed, run it again")
)]
pub struct JobAborted {
    pub acked: usize,
    pub total: usize,
    pub stop: String,
}
