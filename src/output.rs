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
    help("the job was stopped before this line; fix the recipe statement it came from")
)]
pub struct ControllerRejected {
    pub line_no: usize,
    pub line: String,
    pub code: u32,
    pub message: String,
    #[label("this statement produced the rejected line")]
    pub span: Span,
}
