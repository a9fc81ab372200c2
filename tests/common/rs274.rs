//! LinuxCNC's own interpreter as a checker, shared by the binary's tests (`tests/common`) and
//! the runtime's (`runtime/tests/emit_nc.rs` includes this file by path).

use std::path::Path;
use std::process::Command;

/// Runs LinuxCNC's `rs274 -g FILE`. The interpreter always prints its start-up canonical
/// calls (`USE_LENGTH_UNITS`, …) on stdout before it reads the program, even when it then
/// rejects the first line; a failure with nothing on stdout is the process dying, not a verdict
/// on the program, and so is one killed by a signal (several `rs274` started at once, as the
/// per-case trials do, sometimes die of SIGBUS right after printing `executing`). Either is
/// asked again, up to four times.
pub fn rs274_g(file: &Path) -> std::io::Result<std::process::Output> {
    let run = || {
        Command::new("rs274")
            .arg("-g")
            .arg(file)
            .stdin(std::process::Stdio::null())
            .output()
    };
    let mut out = run()?;
    for _ in 0..4 {
        let died = out.status.code().is_none();
        if !died && (out.status.success() || !out.stdout.is_empty()) {
            break;
        }
        out = run()?;
    }
    Ok(out)
}
