//! Starting a job on a controller: the one safety sequence that `lase run` and the REPL's
//! `:run` and `:resume` go through, so that what is checked before anything moves cannot
//! drift between them.
//!
//! 1. [`preflight`]: every line can go over this link; a resumed job finds where it stands
//!    ([`resume::plan`], which waits for the controller to finish what it had received); the
//!    controller's settings (`$$`) fit the plan's needs; the controller is idle. Nothing of
//!    the job is sent, and a link lost here is a job that never started.
//! 2. [`Ready::start`]: the journal is created (or, resuming, the resume point recorded and
//!    the re-approach's setup lines sent), and the send guards that keep a dropped link
//!    resumable are set.
//! 3. [`Started::stream`]: the lines go out through [`stream::stream`]; the caller's
//!    observer sees progress and returns the operator's hold/resume/abort.
//!
//! Where a journal lives by default is decided here too ([`journal_dir`], [`journal_name`]:
//! the user's state directory, one file per recipe path). The callers keep only what is
//! theirs: which journal a command uses, the progress display, the keys, and the wording of
//! the outcome.

use super::journal::{self, Header, Journal};
use super::modal::Tracker;
use super::resume::{self, ResumePlan};
use super::stream::{self, Control, Lines, Progress, Report, Source, StreamJob, StreamOptions};
use super::{
    AxisPos, ControllerAxes, Event, Link, LinkError, MachineState, ModalState, Requirements,
    SettingMismatch, Status,
};
use crate::emit::{Dialect, EmitError, EmitOptions, NcLine};
use crate::motion::Job;
use lase_lang::Span;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long a status report may take.
const STATUS_WAIT: Duration = Duration::from_secs(2);

/// How long a resumed job waits for the controller to finish the lines it had received.
const RESUME_WAIT: Duration = Duration::from_secs(600);

/// A job's NC lines as they go to a controller, with the planned job they came from (for the
/// settings it needs and the recipe statement behind each line).
///
/// The lines are either kept in memory ([`JobLines::new`], the REPL's jobs) or made again by
/// the emitter each time they are read ([`JobLines::emitted`], `lase run`): a texturing job
/// of tens of millions of lines is then never held as a whole. Checking every line, streaming
/// and the progress display read them in order; a journaled job's send guards and a resume
/// read them all ([`JobLines::all`]), which holds them for as long as that takes.
#[derive(Debug)]
pub struct JobLines<'a> {
    job: &'a Job,
    dialect: Dialect,
    text: Text<'a>,
    /// The op each line came from, run-length: (first line, op) wherever it changes.
    runs: Vec<(usize, Option<u32>)>,
    len: usize,
    hash: u64,
}

/// Where a job's lines come from.
enum Text<'a> {
    Kept(Vec<String>),
    /// Written with comments, each op located by this (`Sync`: the emitter runs on a helper
    /// thread while the job streams).
    Emitted(&'a (dyn Fn(Span) -> String + Sync)),
}

impl std::fmt::Debug for Text<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Text::Kept(l) => write!(f, "Kept({} lines)", l.len()),
            Text::Emitted(_) => f.write_str("Emitted"),
        }
    }
}

/// The options every emitted job is written with: what `lase emit` writes, comments and
/// recipe locations included.
fn options(locate: &(dyn Fn(Span) -> String + Sync)) -> EmitOptions<'_> {
    EmitOptions {
        locate: Some(locate),
        comments: true,
        // The lines go to a controller: `link::settle` settles row starts itself.
        live: true,
    }
}

/// Lines handed from the emitter's thread to the streaming side at a time.
const BATCH: usize = 4096;

/// Run-length ops of lines, pushed one line at a time.
fn push_run(runs: &mut Vec<(usize, Option<u32>)>, line: usize, op: Option<u32>) {
    if runs.last().is_none_or(|r| r.1 != op) {
        runs.push((line, op));
    }
}

impl<'a> JobLines<'a> {
    /// The lines `nc` of `job`, written in `dialect`, kept in memory.
    pub fn new(job: &'a Job, nc: &'a [NcLine], dialect: Dialect) -> JobLines<'a> {
        let mut runs = Vec::new();
        for (i, l) in nc.iter().enumerate() {
            push_run(&mut runs, i, l.op);
        }
        let lines: Vec<String> = nc.iter().map(|l| l.text.clone()).collect();
        JobLines {
            job,
            dialect,
            len: lines.len(),
            hash: journal::program_hash(lines.iter().map(String::as_str)),
            text: Text::Kept(lines),
            runs,
        }
    }

    /// The lines of `job` in `dialect` as `lase emit` writes them (comments located by
    /// `locate`), made by the emitter whenever they are read: this first pass validates the
    /// program, counts and hashes its lines and notes the op of each, and keeps none of them.
    pub fn emitted(
        job: &'a Job,
        dialect: Dialect,
        locate: &'a (dyn Fn(Span) -> String + Sync),
    ) -> Result<JobLines<'a>, EmitError> {
        let mut runs = Vec::new();
        let mut hash = journal::ProgramHash::new();
        let mut len = 0;
        crate::emit::emit(job, dialect, &options(locate), &mut |l: &NcLine| {
            push_run(&mut runs, len, l.op);
            hash.add(&l.text);
            len += 1;
            Ok(())
        })?;
        Ok(JobLines {
            job,
            dialect,
            text: Text::Emitted(locate),
            runs,
            len,
            hash: hash.finish(),
        })
    }

    /// How many lines the job has.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Reads every line in order (`f` gets its index and text) until `f` returns false.
    pub fn scan(&self, f: &mut dyn FnMut(usize, &str) -> bool) {
        match &self.text {
            Text::Kept(lines) => {
                for (i, l) in lines.iter().enumerate() {
                    if !f(i, l) {
                        return;
                    }
                }
            }
            Text::Emitted(locate) => {
                let mut i = 0;
                // Validated by `emitted`: only the stop below ends it early.
                let options = options(*locate);
                let _ = crate::emit::emit(self.job, self.dialect, &options, &mut |l: &NcLine| {
                    let go = f(i, &l.text);
                    i += 1;
                    if go {
                        Ok(())
                    } else {
                        Err(std::io::Error::other("enough lines read"))
                    }
                });
            }
        }
    }

    /// Line `index` (empty past the end). Reading one line of an emitted job writes the
    /// program up to it: for diagnostics, not for loops.
    pub fn line(&self, index: usize) -> String {
        let mut out = String::new();
        self.scan(&mut |i, l| {
            if i == index {
                out = l.to_string();
            }
            i < index
        });
        out
    }

    /// Every line, in memory while the result lives (borrowed when kept anyway).
    pub fn all(&self) -> std::borrow::Cow<'_, [String]> {
        match &self.text {
            Text::Kept(lines) => lines.as_slice().into(),
            Text::Emitted(_) => {
                let mut v = Vec::with_capacity(self.len);
                self.scan(&mut |_, l| {
                    v.push(l.to_string());
                    true
                });
                v.into()
            }
        }
    }

    /// Runs `f` with the lines as streaming reads them: the kept ones, or an emitter running
    /// on a helper thread that hands over [`BATCH`] lines at a time through a channel of a
    /// few batches, so at most a few batches are in memory whatever the job's length. When
    /// `f` returns early (a stop, a lost link) the channel closes and the emitter ends.
    pub fn with_lines<R>(&self, f: impl FnOnce(Lines<'_>) -> R) -> R {
        match &self.text {
            Text::Kept(lines) => f(Lines::All(lines)),
            Text::Emitted(locate) => std::thread::scope(|s| {
                let (tx, rx) = std::sync::mpsc::sync_channel::<Vec<String>>(4);
                let (job, dialect, locate) = (self.job, self.dialect, *locate);
                s.spawn(move || {
                    let mut batch = Vec::with_capacity(BATCH);
                    let options = options(locate);
                    let r = crate::emit::emit(job, dialect, &options, &mut |l: &NcLine| {
                        batch.push(l.text.clone());
                        if batch.len() == BATCH {
                            let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH));
                            tx.send(full)
                                .map_err(|_| std::io::Error::other("streaming ended"))?;
                        }
                        Ok(())
                    });
                    if r.is_ok() && !batch.is_empty() {
                        let _ = tx.send(batch);
                    }
                });
                let feed = Feed {
                    len: self.len,
                    rx,
                    batch: std::cell::RefCell::new((0, Vec::new())),
                };
                f(Lines::Made(&feed))
            }),
        }
    }

    pub fn job(&self) -> &'a Job {
        self.job
    }

    pub fn dialect(&self) -> Dialect {
        self.dialect
    }

    /// The op each line came from, run-length: (first line, op) wherever it changes.
    pub fn runs(&self) -> &[(usize, Option<u32>)] {
        &self.runs
    }

    /// The recipe statement that produced line `index` (empty for header and footer lines).
    pub fn span_of(&self, index: usize) -> Span {
        let k = self.runs.partition_point(|r| r.0 <= index);
        k.checked_sub(1)
            .and_then(|k| self.runs[k].1)
            .and_then(|o| self.job.program.ops.get(o as usize))
            .map(|o| o.span)
            .unwrap_or_default()
    }

    /// The machine's axis letters, as its controller names them.
    pub fn letters(&self) -> Vec<char> {
        ControllerAxes::of(&self.job.program.machine)
            .letters()
            .to_vec()
    }

    fn hash(&self) -> u64 {
        self.hash
    }
}

/// The streaming side of [`JobLines::with_lines`]: the current batch, and the channel the
/// next ones come through.
#[derive(Debug)]
struct Feed {
    len: usize,
    rx: std::sync::mpsc::Receiver<Vec<String>>,
    /// The first line's index and the lines of the current batch.
    batch: std::cell::RefCell<(usize, Vec<String>)>,
}

impl Source for Feed {
    fn len(&self) -> usize {
        self.len
    }

    fn line(&self, index: usize) -> String {
        let mut b = self.batch.borrow_mut();
        // Streaming reads forward: batches before `index` are done with.
        while index >= b.0 + b.1.len() {
            match self.rx.recv() {
                Ok(next) => {
                    b.0 += b.1.len();
                    b.1 = next;
                }
                Err(_) => return String::new(),
            }
        }
        b.1.get(index.wrapping_sub(b.0))
            .cloned()
            .unwrap_or_default()
    }
}

/// The folder `lase run` keeps journals in when no path is given: the user's state directory,
/// `$XDG_STATE_HOME/lase/journals`, else `$HOME/.local/state/lase/journals` (the XDG base
/// directory default; a relative `XDG_STATE_HOME` is ignored, as the spec says). Not the
/// recipe's folder: that is often a source tree, and a journal is the machine's record, not
/// the recipe's. `None` when neither variable says where home is.
pub fn journal_dir(
    state_home: Option<&std::ffi::OsStr>,
    home: Option<&std::ffi::OsStr>,
) -> Option<PathBuf> {
    let state = state_home
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| {
            home.map(PathBuf::from)
                .filter(|p| !p.as_os_str().is_empty())
                .map(|h| h.join(".local").join("state"))
        })?;
    Some(state.join("lase").join("journals"))
}

/// The journal file name of the recipe at `recipe` (its canonical path): the file name, then
/// a hash of the whole path, so that two `frame.lase` in different folders keep two journals
/// and the same recipe always finds its own again (`lase run FILE --resume`).
pub fn journal_name(recipe: &Path) -> String {
    let name = recipe
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "job".into());
    let hash = journal::program_hash([recipe.to_string_lossy().as_ref()]);
    format!("{name}-{hash:016x}.journal")
}

/// The journal of a job that starts from its first line.
#[derive(Debug, Clone)]
pub struct NewJournal {
    pub path: PathBuf,
    /// The recipe and the link, as the journal's header names them for `--resume`.
    pub recipe: String,
    pub link: String,
}

/// Where a job starts.
#[derive(Debug)]
pub enum Origin {
    /// From its first line, journaled (or not: then it cannot be resumed).
    Fresh(Option<NewJournal>),
    /// After a lost link, continuing the job journaled at `path`.
    Resume {
        path: PathBuf,
        state: journal::State,
        /// The executed count an operator gave after checking the part.
        resume_at: Option<usize>,
    },
}

impl Origin {
    /// Continuing the job journaled at `path` (read as `state`), once it is sure that `job`
    /// is the program the journal recorded; `recipe` names it in the refusal.
    pub fn resume(
        job: &JobLines<'_>,
        path: PathBuf,
        state: journal::State,
        resume_at: Option<usize>,
        recipe: &str,
    ) -> Result<Origin, LinkError> {
        if state.header.hash != job.hash() || state.header.lines != job.len() {
            return Err(LinkError::Resume {
                reason: format!(
                    "{recipe} no longer produces the program the journal recorded ({} lines then, {} now)",
                    state.header.lines,
                    job.len()
                ),
                help: "resume with the recipe (and machine file) exactly as they were when the job started".into(),
            });
        }
        Ok(Origin::Resume {
            path,
            state,
            resume_at,
        })
    }
}

/// Why a job did not start: nothing of it was sent.
#[derive(Debug)]
pub enum Refused {
    /// A line that cannot be sent, a resume that cannot be decided, a failed link.
    Link(LinkError),
    /// Controller settings that would make the job run differently from its plan.
    Settings(Vec<SettingMismatch>),
    /// The controller is not idle (an alarm, a hold, still moving): its status. Each caller
    /// words what to do about it (`lase run`: [`not_idle`]; the REPL names its commands).
    NotIdle(Box<Status>),
}

impl From<LinkError> for Refused {
    fn from(e: LinkError) -> Refused {
        Refused::Link(e)
    }
}

/// A link lost before a job's first line was sent: nothing to resume, so not
/// [`LinkError::Lost`] (whose help points at the journal).
pub fn not_started(e: LinkError) -> LinkError {
    match e {
        LinkError::Lost { reason } => LinkError::NotReady {
            reason: format!(
                "the link was lost while connecting, before the job started ({reason}): no program line was sent"
            ),
            help: "check the cable or network and run the job again".into(),
        },
        e => e,
    }
}

/// The diagnostic of [`Refused::NotIdle`] for a command-line run.
pub fn not_idle(status: &Status, letters: &[char]) -> LinkError {
    LinkError::NotReady {
        reason: format!(
            "it reports `{}`, not Idle: no program line was sent",
            status.summary_for(None, letters)
        ),
        help: match status.state {
            MachineState::Alarm => "an alarm may have lost the position: check the machine, clear the alarm (`$H` homing, or `$X`) and run the job again".into(),
            MachineState::Hold { .. } | MachineState::Door(_) => "the controller holds a job: resume it (`~`) or reset it, then run the job again".into(),
            _ => "wait until the controller is idle, then run the job again".into(),
        },
    }
}

/// A job that passed its preflight: ready to start.
#[derive(Debug)]
pub struct Ready {
    from: ReadyFrom,
    /// The controller's work position when the job started: where its journal and send
    /// guards predict from.
    start: AxisPos,
}

/// Where a job that passed its preflight starts.
#[derive(Debug)]
enum ReadyFrom {
    Fresh(Option<NewJournal>),
    Resume { path: PathBuf, plan: ResumePlan },
}

/// Checks everything that can be checked before a job moves (see the module header). On a
/// fresh job a lost link is reported as [`not_started`].
pub fn preflight(
    link: &mut dyn Link,
    job: &JobLines<'_>,
    origin: Origin,
) -> Result<Ready, Refused> {
    let fresh = matches!(origin, Origin::Fresh(_));
    let setup = |e: LinkError| if fresh { not_started(e) } else { e };
    let mut unsendable = None;
    job.scan(&mut |i, l| match link.validate_line(l) {
        Ok(()) => true,
        Err(reason) => {
            unsendable = Some((i, l.to_string(), reason));
            false
        }
    });
    if let Some((i, line, reason)) = unsendable {
        return Err(Refused::Link(LinkError::Unsendable {
            line_no: i + 1,
            line,
            reason,
            span: job.span_of(i),
            help:
                "change the recipe text that ends up in this line (names in comments, for instance)"
                    .into(),
        }));
    }
    // Row-start settling needs X and Y the part's (checked before anything is sent).
    super::settle::settle_points(job.job, job.runs(), job.len())?;
    // A resumed job first waits for the controller to finish what it had received (`$$` is
    // refused while it moves) and finds where the job stands.
    let (from, resumed_start) = match origin {
        Origin::Resume {
            path,
            state,
            resume_at,
        } => {
            let plan = resume::plan(
                link,
                &job.all(),
                &state,
                &job.letters(),
                resume_at,
                RESUME_WAIT,
            )?;
            (ReadyFrom::Resume { path, plan }, Some(state.header.start))
        }
        Origin::Fresh(journal) => (ReadyFrom::Fresh(journal), None),
    };
    let needs = Requirements::of_job(job.job, job.dialect);
    let mismatches = link.check_settings(&needs).map_err(setup)?;
    if !mismatches.is_empty() {
        return Err(Refused::Settings(mismatches));
    }
    let start = match resumed_start {
        // The resume plan found the controller idle, and the journal knows where the job
        // started.
        Some(start) => start,
        None => {
            let status = link.query_status(STATUS_WAIT).map_err(setup)?;
            if status.state != MachineState::Idle {
                return Err(Refused::NotIdle(Box::new(status)));
            }
            status.work_axes()
        }
    };
    Ok(Ready { from, start })
}

impl Ready {
    /// Where a resumed job stands and how it re-approaches; `None` for a fresh job.
    pub fn resume_plan(&self) -> Option<&ResumePlan> {
        match &self.from {
            ReadyFrom::Resume { plan, .. } => Some(plan),
            ReadyFrom::Fresh(_) => None,
        }
    }

    /// Starts the job: the journal and, resuming, the re-approach's setup lines.
    pub fn start(self, link: &mut dyn Link, job: &JobLines<'_>) -> Result<Started, LinkError> {
        let (journal, from, lead, restored) = match self.from {
            ReadyFrom::Resume { path, plan } => {
                let j = resume::enter(link, &plan, &path)?;
                (
                    Some(j),
                    plan.executed,
                    plan.reapproach.lead,
                    Some(plan.restored),
                )
            }
            ReadyFrom::Fresh(Some(nj)) => {
                let header = Header {
                    recipe: nj.recipe,
                    link: nj.link,
                    dialect: job.dialect.to_string(),
                    lines: job.len(),
                    hash: job.hash(),
                    start: self.start,
                };
                (
                    Some(Journal::create(&nj.path, &header)?),
                    0,
                    Vec::new(),
                    None,
                )
            }
            ReadyFrom::Fresh(None) => (None, 0, Vec::new(), None),
        };
        // Closed lit contours wait for acknowledgements, so that a drop can always be
        // resumed; without a journal there is nothing to resume.
        let guards = if journal.is_some() {
            // They hold every line while they are worked out (see `JobLines`).
            resume::send_guards(&Tracker::new(self.start), &job.all())
        } else {
            Vec::new()
        };
        Ok(Started {
            journal,
            from,
            lead,
            restored,
            guards,
        })
    }
}

/// A started job: its journal open, where streaming starts, its send guards.
#[derive(Debug)]
pub struct Started {
    journal: Option<Journal>,
    from: usize,
    lead: Vec<String>,
    restored: Option<ModalState>,
    guards: Vec<Option<usize>>,
}

impl Started {
    /// The first job line to send (0 unless resuming).
    pub fn from(&self) -> usize {
        self.from
    }

    pub fn journal_path(&self) -> Option<&Path> {
        self.journal.as_ref().map(Journal::path)
    }

    /// Streams the job's lines from [`Started::from`]; `observer` sees progress after every
    /// event and returns the operator's [`Control`].
    pub fn stream(
        &mut self,
        link: &mut dyn Link,
        job: &JobLines<'_>,
        observer: &mut dyn FnMut(&Progress, Option<&Event>) -> Option<Control>,
    ) -> Report {
        // Checked by the preflight.
        let settles =
            super::settle::settle_points(job.job, job.runs(), job.len()).unwrap_or_default();
        let letters = job.letters();
        job.with_lines(|lines| {
            stream::stream(
                link,
                &StreamJob {
                    lines,
                    from: self.from,
                    lead: &self.lead,
                    restored: self.restored.clone(),
                    guards: &self.guards,
                    letters: &letters,
                    settles: &settles,
                },
                self.journal.as_mut(),
                &StreamOptions::default(),
                observer,
            )
        })
    }
}

/// Check mode (GRBL `$C`): the controller parses every line of a job that passed its
/// preflight and moves nothing; the controller leaves check mode afterwards.
pub fn check_mode(link: &mut dyn Link, job: &JobLines<'_>) -> Result<Report, LinkError> {
    link.set_check_mode(true)?;
    let report = job.with_lines(|lines| {
        stream::stream(
            link,
            &StreamJob {
                lines,
                ..StreamJob::new(&[])
            },
            None,
            &StreamOptions::default(),
            &mut |_: &Progress, _: Option<&Event>| None,
        )
    });
    let _ = link.set_check_mode(false);
    Ok(report)
}

#[cfg(test)]
mod journal_place_tests {
    use super::*;
    use std::ffi::OsStr;

    #[test]
    fn journals_live_in_the_state_directory_one_per_recipe_path() {
        let d = journal_dir(Some(OsStr::new("/s")), Some(OsStr::new("/h")));
        assert_eq!(d, Some(PathBuf::from("/s/lase/journals")));
        // A relative XDG_STATE_HOME is ignored; then HOME's default.
        let d = journal_dir(Some(OsStr::new("rel")), Some(OsStr::new("/h")));
        assert_eq!(d, Some(PathBuf::from("/h/.local/state/lase/journals")));
        assert_eq!(journal_dir(None, None), None);
        let a = journal_name(Path::new("/a/frame.lase"));
        let b = journal_name(Path::new("/b/frame.lase"));
        assert!(
            a.starts_with("frame.lase-") && a.ends_with(".journal"),
            "{a}"
        );
        assert_ne!(a, b);
        assert_eq!(a, journal_name(Path::new("/a/frame.lase")));
    }
}
