//! Output: files written atomically, and standard output as coreutils treat it.
//!
//! A regular file is written into a temporary file beside it, synced, then renamed over it,
//! so a failed or killed run never leaves a half-written NC program behind and never
//! replaces a good one with a partial one. The temporary file is named after the output and
//! the writing process (`.NAME.lase-PID.tmp`), so one left by a killed run is recognisably
//! lase's, and the next write of the same output removes it.
//!
//! The target is resolved first, because a rename replaces whatever node stands at the
//! path: a symbolic link is followed to the file it names (the link stays a link); a FIFO
//! or a character device (`/dev/null`, a tty) is written in place, never replaced; a
//! directory, a block device or a socket is refused. A new file gets the mode the user's
//! umask gives (`0666 & !umask`); a replaced file keeps its mode (and, where permitted,
//! its owner).

use crate::driver::{Failure, IoError};
use lase_lang::{SourceMap, Span};
use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

type Fail = (SourceMap, Failure);

fn fail(message: String) -> Fail {
    (SourceMap::new(), Failure::one(IoError { message }))
}

/// Symbolic links followed before giving up, as the kernel's own `ELOOP` limit.
const MAX_LINKS: usize = 40;

/// What stands at an output path once symbolic links are followed.
#[derive(Debug)]
enum Target {
    /// Nothing yet: a new regular file at this path.
    New(PathBuf),
    /// A regular file, replaced atomically; its metadata is kept.
    Regular(PathBuf, std::fs::Metadata),
    /// A FIFO or character device, written in place.
    Stream(PathBuf),
}

fn resolve(path: &Path) -> Result<Target, Fail> {
    let mut p = path.to_path_buf();
    for _ in 0..MAX_LINKS {
        let meta = match std::fs::symlink_metadata(&p) {
            Ok(m) => m,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Target::New(p)),
            Err(e) => return Err(fail(format!("cannot write {}: {e}", p.display()))),
        };
        let ft = meta.file_type();
        if ft.is_symlink() {
            let link = std::fs::read_link(&p)
                .map_err(|e| fail(format!("cannot read the link {}: {e}", p.display())))?;
            p = match p.parent() {
                Some(dir) if link.is_relative() => dir.join(link),
                _ => link,
            };
            continue;
        }
        if ft.is_file() {
            return Ok(Target::Regular(p, meta));
        }
        if ft.is_fifo() || ft.is_char_device() {
            return Ok(Target::Stream(p));
        }
        let what = if ft.is_dir() {
            "a directory"
        } else if ft.is_block_device() {
            "a block device"
        } else {
            "a socket"
        };
        return Err(fail(format!(
            "cannot write {}: it is {what}; name a file (lase writes regular files, FIFOs and character devices)",
            path.display()
        )));
    }
    Err(fail(format!(
        "cannot write {}: more than {MAX_LINKS} symbolic links to follow",
        path.display()
    )))
}

/// `.NAME.lase-` : the start of every temporary file lase writes for the output NAME.
fn temp_prefix(target: &Path) -> String {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!(".{name}.lase-")
}

/// Removes temporary files of earlier writes of `target` whose process is gone (killed
/// mid-write). A process that is still running may be writing the same output: its file stays.
fn remove_stale(dir: &Path, prefix: &str) {
    if !Path::new("/proc/self").exists() {
        return; // no way to tell a live writer from a dead one
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(prefix))
            .and_then(|n| n.strip_suffix(".tmp"))
            .and_then(|n| n.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The temporary file of one write; removed unless it was renamed into place.
struct Temp {
    path: PathBuf,
    done: bool,
}

impl Drop for Temp {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Writes `path` through `body`: atomically for a regular file, in place for a FIFO or a
/// character device. On any error nothing at `path` has changed (for a regular file).
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> Result<(), Fail>,
) -> Result<(), Fail> {
    let (target, old) = match resolve(path)? {
        Target::Stream(p) => {
            let f = OpenOptions::new()
                .write(true)
                .open(&p)
                .map_err(|e| fail(format!("cannot write {}: {e}", p.display())))?;
            let mut w = io::BufWriter::with_capacity(1 << 16, f);
            body(&mut w)?;
            return w
                .flush()
                .map_err(|e| fail(format!("cannot write {}: {e}", p.display())));
        }
        Target::New(p) => (p, None),
        Target::Regular(p, meta) => (p, Some(meta)),
    };
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let prefix = temp_prefix(&target);
    remove_stale(&dir, &prefix);
    let mut temp = Temp {
        path: dir.join(format!("{prefix}{}.tmp", std::process::id())),
        done: false,
    };
    // `create_new` with the default mode 0666: the kernel applies the umask, as for any file
    // the user's tools create.
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temp.path)
        .or_else(|e| {
            // Our own leftover (a pid reused after a crash) is stale by definition.
            if e.kind() == io::ErrorKind::AlreadyExists {
                std::fs::remove_file(&temp.path)?;
                OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(&temp.path)
            } else {
                Err(e)
            }
        })
        .map_err(|e| fail(format!("cannot write in {}: {e}", dir.display())))?;
    let mut w = io::BufWriter::with_capacity(1 << 16, file);
    body(&mut w)?;
    let file: File = w
        .into_inner()
        .map_err(|e| fail(format!("cannot write {}: {e}", target.display())))?;
    if let Some(old) = &old {
        // Keep what the user set on the file being replaced: its mode, and its owner where
        // this process may give it (root replacing another user's file).
        file.set_permissions(std::fs::Permissions::from_mode(old.mode() & 0o7777))
            .map_err(|e| fail(format!("cannot write {}: {e}", target.display())))?;
        let _ = std::os::unix::fs::fchown(&file, Some(old.uid()), Some(old.gid()));
    }
    file.sync_all()
        .map_err(|e| fail(format!("cannot write {}: {e}", target.display())))?;
    drop(file);
    std::fs::rename(&temp.path, &target)
        .map_err(|e| fail(format!("cannot write {}: {e}", target.display())))?;
    temp.done = true;
    Ok(())
}

/// Standard output that treats a reader gone away (`lase plan … | head`) as coreutils do:
/// the program ends at once, quietly, with the status a SIGPIPE would give (141), instead of
/// panicking or printing an error. Any other write error ends it with a message and status 1.
#[derive(Debug)]
pub struct Stdout<W: Write>(pub W);

/// Exit status of a program ended by SIGPIPE, as a shell reports it (128 + 13).
pub const BROKEN_PIPE_STATUS: i32 = 141;

impl<W: Write> Stdout<W> {
    fn check<T>(r: io::Result<T>) -> io::Result<T> {
        match r {
            Err(e) if e.kind() == io::ErrorKind::BrokenPipe => {
                std::process::exit(BROKEN_PIPE_STATUS)
            }
            Err(e) => {
                eprintln!("lase: cannot write to standard output: {e}");
                std::process::exit(1)
            }
            ok => ok,
        }
    }
}

impl<W: Write> Write for Stdout<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        Self::check(self.0.write(buf))
    }

    fn flush(&mut self) -> io::Result<()> {
        Self::check(self.0.flush())
    }
}

/// `println!` for the command-line output: a closed pipe ends the program quietly.
macro_rules! outln {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!($crate::output::Stdout(std::io::stdout().lock()), $($arg)*);
    }};
}

/// `print!` for the command-line output: a closed pipe ends the program quietly.
macro_rules! out {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!($crate::output::Stdout(std::io::stdout().lock()), $($arg)*);
    }};
}

pub(crate) use {out, outln};

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

/// `28 ops`, or `28 ops + 6 lead-ins/outs`: the ops the recipe wrote (what `:load` reports),
/// then those the planner added so every lit section starts and ends at speed.
pub(crate) fn ops_count(job: &lase_runtime::motion::Job) -> String {
    let leads = job.leads.len();
    let written = job.program.ops.len().saturating_sub(leads);
    if leads == 0 {
        format!("{written} ops")
    } else {
        format!("{written} ops + {leads} lead-ins/outs")
    }
}

/// The job's cycle time on the controller that runs it in `dialect`, by that controller's
/// model (issue 13: lase's own plan is ideal, the machine runs its controller's planner), and
/// the words for it with lase's plan beside it: `cycle time 19.794 s by the GRBL 1.1 planner
/// model (lase's plan 20.681 s)`. `lase run`, the REPL's `:plan` and `:run` say it so.
pub(crate) fn controller_cycle(
    job: &lase_runtime::motion::Job,
    dialect: lase_runtime::emit::Dialect,
) -> (f64, String) {
    let c = lase_runtime::link::estimate::controller_cycle(job, dialect);
    let words = match &c.note {
        None => format!(
            "cycle time {:.3} s by the {} (lase's plan {:.3} s)",
            c.cycle_time_s,
            c.model,
            job.cycle_time()
        ),
        Some(note) => format!("cycle time {:.3} s by {} ({note})", c.cycle_time_s, c.model),
    };
    (c.cycle_time_s, words)
}

/// A sign of life on the terminal while a command works: a spinner on stderr with what it is
/// doing, drawn within 100 ms of the start (texturing jobs take seconds to compile and
/// write), and nothing at all when stderr is not a terminal, so logs and goldens stay clean.
pub struct Busy {
    bar: Option<indicatif::ProgressBar>,
}

impl Busy {
    /// Starts the spinner with `what` (e.g. "compiling recipe.lase").
    pub fn start(what: &str) -> Busy {
        use std::io::IsTerminal;
        let bar = io::stderr().is_terminal().then(|| {
            let b = indicatif::ProgressBar::new_spinner();
            b.set_style(
                indicatif::ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
            );
            b.set_message(what.to_string());
            b.enable_steady_tick(std::time::Duration::from_millis(100));
            b
        });
        Busy { bar }
    }

    /// No spinner.
    pub fn off() -> Busy {
        Busy { bar: None }
    }

    /// What it is doing now.
    pub fn say(&self, what: impl Into<String>) {
        if let Some(b) = &self.bar {
            b.set_message(what.into());
        }
    }

    /// Whether anybody sees it (callers skip building messages otherwise).
    pub fn shown(&self) -> bool {
        self.bar.is_some()
    }
}

impl Drop for Busy {
    fn drop(&mut self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

impl std::fmt::Debug for Busy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Busy")
            .field("shown", &self.bar.is_some())
            .finish()
    }
}
