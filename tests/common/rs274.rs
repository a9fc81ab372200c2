//! LinuxCNC's own interpreter as a checker, shared by the binary's tests (`tests/common`) and
//! the runtime's (`runtime/tests/emit_nc.rs` includes this file by path).

use std::path::Path;
use std::process::Command;

/// Runs LinuxCNC's `rs274 -g FILE`. The interpreter always prints its start-up canonical
/// calls (`USE_LENGTH_UNITS`, …) on stdout before it reads the program, even when it then
/// rejects the first line; a failure with nothing on stdout is the process dying (seen on a
/// loaded machine, with only its `executing` on stderr), not a verdict on the program: it is
/// asked again, up to twice.
pub fn rs274_g(file: &Path) -> std::io::Result<std::process::Output> {
    let run = || {
        Command::new("rs274")
            .arg("-g")
            .arg(file)
            .stdin(std::process::Stdio::null())
            .output()
    };
    let mut out = run()?;
    for _ in 0..2 {
        if out.status.success() || !out.stdout.is_empty() {
            break;
        }
        out = run()?;
    }
    Ok(out)
}
