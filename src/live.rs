//! `lase run` and `lase sim`: a job streamed live to a controller link, and the simulated
//! controller as a server. The terminal side lives here: the progress bar (indicatif, only
//! when stderr is a terminal), the hold/resume/abort keys (crossterm, only when stdin is a
//! terminal) and the mapping of a controller's answer back to the recipe line.

use crate::driver::{self, Failure, IoError};
use crate::origin::{self, JobOrigin, OriginError};
use crate::output::{self, outln};
use lase_lang::{SourceMap, Span};
use lase_runtime::emit::Dialect;
use lase_runtime::link::job::{self, JobLines, NewJournal, Origin, Refused, Started};
use lase_runtime::link::journal;
use lase_runtime::link::sim::TimeScale;
use lase_runtime::link::stream::{Control, Outcome, Progress, Report};
use lase_runtime::link::{self, ConnectOptions, Event, Link, LinkError, LinkUrl};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

mod linuxcnc;
mod sim;

pub use sim::{SimArgs, cmd_sim};

type CmdResult = Result<(), (SourceMap, Failure)>;

fn io_fail(message: String) -> (SourceMap, Failure) {
    (SourceMap::new(), Failure::one(IoError { message }))
}

/// `lase run` options.
#[derive(Debug, Clone, clap::Args)]
pub struct RunArgs {
    /// The recipe (optional with --resume: the journal names it).
    pub file: Option<PathBuf>,
    /// Controller link URL: sim, tcp://HOST:PORT, serial://DEVICE?baud=N, or
    /// linuxcnc://HOST:PORT[?dir=LOCAL&remote-dir=ON-CONTROLLER&timeout=SECONDS] (LinuxCNC:
    /// the program is written to DIR, opened as REMOTE-DIR/NAME.ngc; TIMEOUT bounds each wait).
    #[arg(long)]
    pub link: Option<String>,
    /// NC dialect sent over the link: grbl (GRBL 1.1, X Y Z) or grblhal (up to six axes,
    /// G93); default: grbl, or grblhal when the machine has axes beyond X, Y, Z.
    #[arg(long)]
    pub dialect: Option<String>,
    /// Job journal file (default for tcp and serial links: the recipe's own in
    /// `$XDG_STATE_HOME/lase/journals/`, else `~/.local/state/lase/journals/`).
    #[arg(long)]
    pub journal: Option<PathBuf>,
    /// Continue the job recorded in this journal after a dropped link; without a value,
    /// the recipe's own journal in the state directory (`lase run FILE --resume`).
    #[arg(long, value_name = "JOURNAL", num_args = 0..=1)]
    pub resume: Option<Option<PathBuf>>,
    /// With --resume: the number of lines that ran, when the controller's state cannot tell.
    #[arg(long, value_name = "N", requires = "resume")]
    pub resume_at: Option<usize>,
    /// GRBL check mode (`$C`): the controller parses every line, nothing moves.
    #[arg(long)]
    pub check: bool,
    /// Where the recipe's zero is: absolute (the controller's coordinates) or current (the
    /// spot's position when the job starts, read from the controller's status; the job is
    /// refused if it would leave the travel from there); default: the recipe's
    /// `planner { origin ... }`, else absolute. g54 … g59: the controller's work offset,
    /// read with `$#` and the travel checked at machine positions before anything is sent.
    #[arg(long, value_enum)]
    pub origin: Option<JobOrigin>,
    /// Send-response flow control (one line in flight) instead of character counting.
    #[arg(long)]
    pub send_response: bool,
    /// The controller's serial RX buffer, bytes (default: what the controller reports in
    /// `$I`, else 128).
    #[arg(long)]
    pub rx_buffer: Option<usize>,
    /// The built-in simulator's clock: `real` (the default: moves take the firmware's time,
    /// status `Run`, the progress bar and the hold keys as at a machine), `max` (moves take no
    /// time, a job ends as fast as lase can stream it; what tests use), or a speed-up factor
    /// such as `10`. Same as `--link 'sim://?time-scale=max'`.
    #[arg(long, value_name = "real|max|FACTOR")]
    pub time_scale: Option<String>,
}

/// The journal of a new job: `--journal`, else the recipe's own in the user's state
/// directory (`link::job::journal_dir`, named by `journal_name`), else in the temporary
/// directory when there is no state directory or it cannot be created. The in-process
/// simulator keeps none unless asked: its machine ends with the process, so there is
/// nothing to resume.
fn journal_path(args: &RunArgs, recipe: &Path, url: &LinkUrl) -> Option<PathBuf> {
    if let Some(j) = &args.journal {
        return Some(j.clone());
    }
    if matches!(url, LinkUrl::Sim(_)) {
        return None;
    }
    let name = job::journal_name(&canonical(recipe));
    let dir = state_journal_dir().filter(|d| std::fs::create_dir_all(d).is_ok());
    Some(dir.unwrap_or_else(std::env::temp_dir).join(name))
}

/// The state directory's journal folder for this user (not created).
fn state_journal_dir() -> Option<PathBuf> {
    job::journal_dir(
        std::env::var_os("XDG_STATE_HOME").as_deref(),
        std::env::var_os("HOME").as_deref(),
    )
}

/// The recipe's full path: what its journal is named by and what the journal records.
fn canonical(recipe: &Path) -> PathBuf {
    std::fs::canonicalize(recipe).unwrap_or_else(|_| recipe.to_path_buf())
}

/// The journal `--resume` means: the one given, or with `--resume` alone the recipe's own
/// (where a run without `--journal` kept it).
fn resume_path(args: &RunArgs) -> Result<Option<PathBuf>, (SourceMap, Failure)> {
    match &args.resume {
        None => Ok(None),
        Some(Some(p)) => Ok(Some(p.clone())),
        Some(None) => {
            let Some(file) = &args.file else {
                return Err(io_fail(
                    "--resume without a journal needs the recipe: `lase run FILE --resume`, or `lase run --resume JOURNAL`".into(),
                ));
            };
            let name = job::journal_name(&canonical(file));
            let found = [state_journal_dir(), Some(std::env::temp_dir())]
                .into_iter()
                .flatten()
                .map(|d| d.join(&name))
                .find(|p| p.exists());
            found.map(Some).ok_or_else(|| {
                io_fail(format!(
                    "no journal of {} to resume (looked for {name} in {}); give it with --resume JOURNAL",
                    file.display(),
                    state_journal_dir()
                        .map(|d| d.display().to_string())
                        .unwrap_or_else(|| "the state directory (HOME is not set)".into())
                ))
            })
        }
    }
}

/// `lase run`: the recipe compiled, the link opened, then `link::job`'s sequence (preflight →
/// start → stream). What is left here is the command line's: which recipe, link, dialect and
/// journal, and what the operator sees.
pub fn cmd_run(args: RunArgs) -> CmdResult {
    // A resumed job names its recipe, link and dialect in the journal.
    let resume = resume_path(&args)?;
    let resumed = read_resumed(resume.as_deref())?;
    let file: PathBuf = match (&args.file, &resumed) {
        (Some(f), _) => f.clone(),
        (None, Some(st)) => PathBuf::from(&st.header.recipe),
        (None, None) => return Err(io_fail("give a recipe file, or --resume JOURNAL".into())),
    };
    let url_text = args
        .link
        .clone()
        .or_else(|| resumed.as_ref().map(|s| s.header.link.clone()))
        .unwrap_or_else(|| "sim".into());
    let mut url = LinkUrl::parse(&url_text).map_err(|e| (SourceMap::new(), Failure::one(e)))?;
    if linuxcnc::is_linuxcnc(&url) {
        return linuxcnc::run(&args, &file, &url, resume.zip(resumed));
    }
    if let Some(ts) = &args.time_scale {
        let LinkUrl::Sim(o) = &mut url else {
            return Err(io_fail(format!(
                "--time-scale sets the built-in simulator's clock; the link {url} is a real controller's"
            )));
        };
        o.time_scale = Some(
            ts.parse()
                .map_err(|e: String| io_fail(format!("--time-scale: {e}")))?,
        );
    }
    // A run on the simulator takes the job's own time unless asked otherwise (issue 14): what
    // the operator sees (`Run`, the progress bar, hold and resume) is then what a machine
    // shows. Tests ask for `max`.
    if let LinkUrl::Sim(o) = &mut url {
        o.time_scale.get_or_insert(TimeScale::Real);
    }
    let options = ConnectOptions {
        rx_buffer: args.rx_buffer,
        send_response: args.send_response,
        ..ConnectOptions::default()
    };
    // A sign of life until the progress bar takes over: a texturing job takes seconds to
    // compile and to write once before it streams.
    let busy = crate::output::Busy::start(&format!("compiling {}", file.display()));
    let (recipe, mut program) = driver::program(&file)?;
    // Planned for the controller at the link's end, not the machine file's (`run_on`).
    let dialect = run_dialect(&args, resumed.as_ref(), &program.machine, &url)?;
    program.machine.run_on(dialect.name());
    let chosen = origin::chosen(args.origin, &program);
    program.planner.origin = chosen.into();
    let (recipe, job, placed_link) = match chosen {
        JobOrigin::Absolute => match lase_runtime::compile::plan(program) {
            Ok(job) => (recipe, job, None),
            Err(f) => return Err((recipe.map, f)),
        },
        JobOrigin::Current if resumed.is_some() => {
            return Err(io_fail(
                "--origin current places a fresh job at the controller's position; a resumed \
                 job continues in the place its journal recorded: leave --origin out"
                    .into(),
            ));
        }
        JobOrigin::Current => placed_at_current(recipe, program, &url, &options)?,
        named => origin::run_at_offset(recipe, program, named, &url, &options, &resumed)?,
    };
    let map = recipe.map.clone();
    let fail = |e: LinkError| (map.clone(), Failure::one(e));
    busy.say(format!("writing the {dialect} program"));
    // The lines are made again as they stream, never held whole (`JobLines::emitted`).
    // Located from the source map alone: the emitter runs on a helper thread while streaming.
    let source_map = &recipe.map;
    let locate = |s: Span| lase_runtime::compile::locate_in(source_map, s);
    let lines = JobLines::emitted(&job, dialect, &locate)
        .map_err(|e| (recipe.map.clone(), Failure::one(e)))?;
    busy.say(format!("connecting to {url}"));
    let origin = match (resumed, &resume) {
        (Some(st), Some(path)) => Origin::resume(
            &lines,
            path.clone(),
            st,
            args.resume_at,
            &file.display().to_string(),
        )
        .map_err(fail)?,
        _ => Origin::Fresh(new_journal(&args, &file, &url)),
    };
    // Until the journal exists nothing of the job has been sent: a lost link is a job that
    // never started, not one to resume.
    let fresh = matches!(origin, Origin::Fresh(_));
    let mut link = match placed_link {
        Some(link) => link,
        None => link::connect(&url, &job.program.machine, &options)
            .map_err(|e| fail(if fresh { job::not_started(e) } else { e }))?,
    };
    let ready = job::preflight(&mut *link, &lines, origin).map_err(|r| refused(r, &lines, &map))?;
    if args.check {
        return run_check(&recipe.name(), &mut *link, &lines, &map);
    }
    if let Some(plan) = ready.resume_plan() {
        eprintln!(
            "{}: {} of {} lines had run (the controller's state fits {}); re-approach: {}",
            recipe.name(),
            plan.executed,
            lines.len(),
            plan.candidates
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(", "),
            plan.reapproach.all().join(" | ")
        );
    }
    let mut started = ready.start(&mut *link, &lines).map_err(fail)?;
    drop(busy);
    stream_run(&recipe.name(), &mut *link, &lines, &mut started)
        .map_err(|failure| (map.clone(), failure))
}

/// A recipe, its job and, when `--origin current` read the controller's position, the link
/// it read it over (the job goes out on the same connection).
pub(crate) type Placed = (
    driver::Recipe,
    lase_runtime::motion::Job,
    Option<Box<dyn Link>>,
);

/// `lase run` with the origin `current`: the recipe evaluated, the link opened and its position read
/// (nothing sent but the status request), the program moved there and planned against the
/// travel. A job that would leave the travel from here is refused with the travel diagnostic
/// at the move and a second one naming the position it was placed at.
fn placed_at_current(
    recipe: driver::Recipe,
    program: lase_runtime::program::ProcessProgram,
    url: &LinkUrl,
    options: &ConnectOptions,
) -> Result<Placed, (SourceMap, Failure)> {
    let map = recipe.map.clone();
    let fail = |e: LinkError| (map.clone(), Failure::one(job::not_started(e)));
    let oriented = lase_runtime::kinematics::for_machine(&program.machine).oriented();
    let mut link = link::connect(url, &program.machine, options).map_err(fail)?;
    let status = link.query_status(Duration::from_secs(2)).map_err(fail)?;
    let (program, at) = origin::at_current(program, &status, oriented)
        .map_err(|e| (map.clone(), Failure::one(e)))?;
    let first = program.ops.first().map(|o| o.span).unwrap_or_default();
    match lase_runtime::compile::plan(program) {
        Ok(job) => {
            eprintln!(
                "{}: the job's zero is the controller's position {at}",
                recipe.name()
            );
            Ok((recipe, job, Some(link)))
        }
        Err(mut f) => {
            f.diagnostics
                .push(Box::new(OriginError::Placed { at, span: first }));
            Err((map, f))
        }
    }
}

/// `lase frame`: what a job's frame needs to know.
#[derive(Debug, Clone, clap::Args)]
pub struct FrameArgs {
    /// The recipe whose lit work is framed.
    pub file: PathBuf,
    /// Controller link URL (default: the built-in simulator).
    #[arg(long)]
    pub link: Option<String>,
    /// Speed of the trace, with a unit.
    #[arg(long, default_value = "50 mm/s")]
    pub speed: String,
    /// Trace at the pointer power the machine file allows (`[laser] pointer`), not dark.
    #[arg(long)]
    pub pointer: bool,
}

/// Traces the bounding box of a recipe's lit work with the beam off over the live link and
/// returns to where the job starts (`ProcessProgram::frame`), through the same job start as
/// `lase run` (`link::job`: every line checked, the controller's settings against the plan,
/// the controller idle), so the operator can check the sheet's place before anything burns.
pub fn cmd_frame(args: FrameArgs) -> CmdResult {
    let url = LinkUrl::parse(args.link.as_deref().unwrap_or("sim"))
        .map_err(|e| (SourceMap::new(), Failure::one(e)))?;
    let speed = lase_lang::units::parse_quantity(&args.speed)
        .ok()
        .filter(|q| q.dim == lase_lang::units::Dim::SPEED && q.value > 0.0 && q.value.is_finite())
        .ok_or_else(|| {
            io_fail(format!(
                "--speed {}: give a speed above zero with its unit, e.g. 50 mm/s",
                args.speed
            ))
        })?;
    // Planned for the GRBL-family controller the frame streams to.
    let (recipe, job) = driver::compile_for(&args.file, None)?;
    if job.kin.oriented() {
        return Err(io_fail(format!(
            "{}: machine `{}` orients the beam; a frame traces the work on a flat bed",
            recipe.name(),
            job.program.machine.name
        )));
    }
    let pointer = match (args.pointer, job.program.machine.laser.pointer_w) {
        (false, _) => None,
        (true, Some(w)) => Some(w),
        (true, None) => {
            return Err(io_fail(format!(
                "{}: machine `{}` allows no pointer power; add `pointer = \"0.5 W\"` to its \
                 [laser], or frame dark without --pointer",
                recipe.name(),
                job.program.machine.name
            )));
        }
    };
    let Some(frame) = job.program.frame(speed.value, pointer) else {
        return Err(io_fail(format!(
            "{}: nothing is lit, so there is no work to frame",
            recipe.name()
        )));
    };
    let job = lase_runtime::compile::plan(frame).map_err(|f| (recipe.map.clone(), f))?;
    let dialect = link::live_dialect(&job.program.machine);
    let map = recipe.map.clone();
    let fail = |e: LinkError| (map.clone(), Failure::one(e));
    // A frame is a dozen lines, made as they stream like any job's.
    let source_map = &recipe.map;
    let locate = |s: Span| lase_runtime::compile::locate_in(source_map, s);
    let lines = JobLines::emitted(&job, dialect, &locate)
        .map_err(|e| (recipe.map.clone(), Failure::one(e)))?;
    let mut link = link::connect(&url, &job.program.machine, &ConnectOptions::default())
        .map_err(|e| fail(job::not_started(e)))?;
    let ready = job::preflight(&mut *link, &lines, Origin::Fresh(None))
        .map_err(|r| refused(r, &lines, &map))?;
    let mut started = ready.start(&mut *link, &lines).map_err(fail)?;
    stream_run(
        &format!("{} (frame)", recipe.name()),
        &mut *link,
        &lines,
        &mut started,
    )
    .map_err(|failure| (map.clone(), failure))
}

/// The journal `--resume` names, read; a job that ended has nothing to resume.
fn read_resumed(path: Option<&Path>) -> Result<Option<journal::State>, (SourceMap, Failure)> {
    let Some(path) = path else {
        return Ok(None);
    };
    let st = journal::read(path).map_err(|e| (SourceMap::new(), Failure::one(e)))?;
    if let Some(how) = &st.end {
        return Err(io_fail(format!(
            "the job in {} ended ({how}): there is nothing to resume",
            path.display()
        )));
    }
    Ok(Some(st))
}

/// The dialect a run streams in: `--dialect`, else the resumed journal's, else the machine's.
fn run_dialect(
    args: &RunArgs,
    resumed: Option<&journal::State>,
    machine: &lase_runtime::machine::Machine,
    url: &LinkUrl,
) -> Result<Dialect, (SourceMap, Failure)> {
    // Every link lase has speaks the GRBL 1.1 protocol: to GRBL (X, Y, Z) or, for machines
    // with more axes, grblHAL (up to six, inverse-time feed). The machine says which.
    let machine_dialect = link::live_dialect(machine);
    let dialect_name = args
        .dialect
        .clone()
        .or_else(|| resumed.map(|s| s.header.dialect.clone()))
        .unwrap_or_else(|| machine_dialect.to_string());
    let dialect = dialect_name.parse::<Dialect>().map_err(|_| {
        io_fail(format!(
            "unknown dialect `{dialect_name}`: choose grbl or grblhal (linuxcnc and iso are written with `lase emit`)"
        ))
    })?;
    if !dialect.is_grbl_family() {
        return Err(io_fail(format!(
            "the link to {url} speaks the GRBL 1.1 protocol and takes the grbl or grblhal dialect, not {dialect}; write a {dialect} program with `lase emit --dialect {dialect}`"
        )));
    }
    Ok(dialect)
}

/// The journal of a new job (none for the in-process simulator unless asked), its header
/// naming the recipe by its full path so that `--resume` finds it from anywhere.
fn new_journal(args: &RunArgs, file: &Path, url: &LinkUrl) -> Option<NewJournal> {
    let path = journal_path(args, file, url)?;
    let recipe = canonical(file);
    Some(NewJournal {
        path,
        recipe: recipe.display().to_string(),
        link: url.to_string(),
    })
}

/// The diagnostic of a job that did not pass its preflight.
fn refused(r: Refused, lines: &JobLines<'_>, map: &SourceMap) -> (SourceMap, Failure) {
    let failure = match r {
        Refused::Link(e) => Failure::one(e),
        Refused::Settings(m) => Failure::many(m),
        Refused::NotIdle(status) => Failure::one(job::not_idle(&status, &lines.letters())),
    };
    (map.clone(), failure)
}

/// Streams a started job with the progress bar and the keys, and words how it ended.
fn stream_run(
    name: &str,
    link: &mut dyn Link,
    lines: &JobLines<'_>,
    started: &mut Started,
) -> Result<(), Failure> {
    let total = lines.len();
    let summary = lase_runtime::report::summarize(lines.job());
    let (cycle_s, cycle) = output::controller_cycle(lines.job(), lines.dialect());
    let journal_name = started.journal_path().map(|j| j.display().to_string());
    eprintln!(
        "{name}: {} lines to {} — {cycle}{}",
        total - started.from(),
        link.describe(),
        journal_name
            .as_ref()
            .map(|p| format!(", journal {p}"))
            .unwrap_or_default()
    );
    let eta = lase_runtime::link::eta::Eta::from_runs(lines.job(), lines.runs(), total)
        .counted_in(cycle_s);
    // Ctrl-C is a feed hold from here until the job has ended, as in the REPL: the machine
    // stops on the path with the laser off, and a second Ctrl-C (or `a`) aborts.
    let sig = SigGuard::new();
    let keys = Keys::for_terminal();
    let mut display = Display::new(total, started.from(), eta);
    let mut asked = false;
    let report = started.stream(link, lines, &mut |p: &Progress, e: Option<&Event>| {
        display.update(p, e);
        let mut key = keys.as_ref().and_then(Keys::try_key);
        if sig.take() {
            key = Some(Key::Interrupt);
        }
        if asked
            && let Some(s) = p.status.as_ref()
            && s.state == (link::MachineState::Hold { complete: true })
            && keys.is_none()
        {
            // Nobody at a terminal to resume: a job held by a signal is stopped safely.
            return Some(Control::Abort);
        }
        match key? {
            Key::Interrupt if !p.held => {
                asked = true;
                display.println(
                    "^C feed hold: stopping on the path, laser off — r or Enter = resume, a or Ctrl-C = abort",
                );
                Some(Control::Hold)
            }
            Key::Interrupt | Key::Abort => Some(Control::Abort),
            Key::Hold => Some(Control::Hold),
            Key::Resume => {
                asked = false;
                Some(Control::Resume)
            }
        }
    });
    drop(keys);
    display.finish();
    drop(sig);
    if report.outcome != Outcome::Done {
        if let Outcome::Failed(_) = &report.outcome
            && let Some(note) = report.stop_note.as_deref().filter(|n| !n.is_empty())
        {
            eprintln!("stopped: {note}");
        }
        let resume = match journal_name {
            Some(j) => format!("the controller goes on with what it had received; reconnect it and continue with `lase run --resume {j}`"),
            None => "this run kept no journal and cannot be resumed: check the part; stream to a controller with a journal (tcp:// or serial://, or --journal FILE) to be able to resume".into(),
        };
        return Err(job_failure(report, lines, resume));
    }
    let elapsed = report.elapsed.as_secs_f64();
    let rate = report.program_bytes as f64 / elapsed.max(1e-9);
    outln!(
        "{name}: done — {} lines acknowledged in {elapsed:.3} s ({:.0} bytes/s), controller {}",
        report.acked,
        rate,
        link.status(&lines.letters())
    );
    outln!(
        "  {cycle}, laser on {:.3} mm / {:.3} s, {} pulses",
        summary.laser_on_length_mm,
        summary.laser_on_time_s,
        summary.pulses
    );
    if let Some(s) = lase_runtime::link::settle::SettleSummary::of(&report.settled) {
        outln!("  {s}");
    }
    Ok(())
}

/// The diagnostic of a job that did not finish (any outcome but `Done`), for `lase run` and
/// the REPL's jobs alike; `resume` says how a job stopped by a lost link continues.
pub(crate) fn job_failure(report: Report, lines: &JobLines<'_>, resume: String) -> Failure {
    let total = lines.len();
    let stop = report.stop_note.unwrap_or_default();
    match report.outcome {
        Outcome::Aborted => Failure::one(output::JobAborted {
            acked: report.acked,
            total,
            stop,
        }),
        Outcome::Lost(e) => Failure::one(output::LinkLost {
            // The reason alone: `LinkError::Lost`'s own text starts with "the link to the
            // controller was lost", which `LinkLost` already says.
            reason: match e {
                lase_runtime::link::LinkError::Lost { reason } => reason,
                other => other.to_string(),
            },
            acked: report.acked,
            total,
            resume,
        }),
        Outcome::Failed(e) => Failure::one(e),
        outcome => controller_stop(outcome, lines, stop),
    }
}

/// The diagnostic of a job the controller refused a line of or stopped with an alarm: the
/// line, the recipe statement it came from, and what stopping the machine did.
fn controller_stop(outcome: Outcome, lines: &JobLines<'_>, stop: String) -> Failure {
    match outcome {
        Outcome::Rejected {
            index,
            code,
            message,
        } => Failure::one(output::ControllerRejected {
            line_no: index + 1,
            line: lines.line(index),
            code,
            message,
            span: lines.span_of(index),
            stop,
        }),
        Outcome::Alarm {
            index,
            code,
            message,
        } => Failure::one(output::ControllerAlarm {
            line: index
                .map(|i| format!(" at line {} `{}`", i + 1, lines.line(i)))
                .unwrap_or_default(),
            code,
            message,
            span: index.map(|i| lines.span_of(i)),
            stop,
        }),
        _ => Failure::one(IoError {
            message: format!("the controller ended the job: {outcome:?}"),
        }),
    }
}

/// `--check`: GRBL check mode parses every line and moves nothing.
fn run_check(name: &str, link: &mut dyn Link, lines: &JobLines<'_>, map: &SourceMap) -> CmdResult {
    let fail = |e: LinkError| (map.clone(), Failure::one(e));
    let report = job::check_mode(link, lines).map_err(fail)?;
    match report.outcome {
        Outcome::Done => {
            outln!(
                "{name}: check mode — the controller accepted all {} lines",
                lines.len()
            );
            Ok(())
        }
        outcome @ (Outcome::Rejected { .. } | Outcome::Alarm { .. }) => Err((
            map.clone(),
            controller_stop(outcome, lines, "check mode: nothing moved".into()),
        )),
        Outcome::Aborted => Err(io_fail("check aborted".into())),
        Outcome::Lost(e) | Outcome::Failed(e) => Err(fail(e)),
    }
}

/// The progress bar, by planned time: the share of the plan's cycle time done (from the
/// acknowledged lines and the controller's position, `Eta::done`), the ETA from the plan, and
/// the lines acknowledged. Lines would mislead: a 50 mm move is one line of many. The REPL's
/// `:run` shows the same one.
pub(crate) struct Display {
    bar: Option<indicatif::ProgressBar>,
    eta: lase_runtime::link::eta::Eta,
    total_lines: usize,
    last_msg: Instant,
}

/// Steps of the bar: tenths of a percent of the planned time.
const BAR_STEPS: u64 = 1000;

/// The keys the bar's hint names; `lase run` and the REPL's `:run` read them alike.
pub(crate) const KEY_HINT: &str = "keys: Ctrl-C, h or space = feed hold (laser off); r or Enter = resume; a, q or a second Ctrl-C = abort";

impl Display {
    pub(crate) fn new(total: usize, from: usize, eta: lase_runtime::link::eta::Eta) -> Display {
        let bar = std::io::stderr().is_terminal().then(|| {
            let b = indicatif::ProgressBar::new(BAR_STEPS);
            let style = indicatif::ProgressStyle::with_template(
                "{spinner} {elapsed_precise} [{wide_bar}] {percent}% {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("=> ");
            b.set_style(style);
            b.set_position(time_steps(eta.done(from, None), eta.total()));
            if std::io::stdin().is_terminal() {
                b.println(KEY_HINT);
            }
            b
        });
        Display {
            bar,
            eta,
            total_lines: total,
            last_msg: Instant::now() - Duration::from_secs(1),
        }
    }

    /// A message above the bar (on stderr), or plain on stderr without one.
    pub(crate) fn println(&self, msg: &str) {
        match &self.bar {
            Some(b) => b.println(msg),
            None => eprintln!("{msg}"),
        }
    }

    pub(crate) fn update(&mut self, p: &Progress, e: Option<&Event>) {
        let Some(bar) = &self.bar else {
            return;
        };
        if let Some(Event::Message(m)) = e {
            bar.println(format!("controller: {m}"));
        }
        if self.last_msg.elapsed() < Duration::from_millis(100) {
            return;
        }
        self.last_msg = Instant::now();
        let pos = p
            .status
            .as_ref()
            .and_then(|s| s.work_position(s.wco.as_deref()));
        let done = self.eta.done(p.acked, pos.as_deref());
        bar.set_position(time_steps(done, self.eta.total()));
        let left = (self.eta.total() - done).max(0.0);
        let state = p
            .status
            .as_ref()
            .map(|s| s.summary_for(s.wco.as_deref(), self.eta.letters()))
            .unwrap_or_default();
        let pulses = match self.eta.pulses() {
            0 => String::new(),
            n => format!(" | ≈{} of {n} pulses", self.eta.pulses_done(done)),
        };
        let settled = match p.settled {
            (_, 0) => String::new(),
            (k, n) => format!(" | {k}/{n} rows settled"),
        };
        bar.set_message(format!(
            "ETA {left:.1} s of {:.1} s planned{}{pulses}{settled} | {}/{} lines | {state}",
            self.eta.total(),
            if p.held { " (held)" } else { "" },
            p.acked,
            self.total_lines,
        ));
    }

    pub(crate) fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}

/// Ctrl-C, caught as a signal while the controller moves (in `lase run` and the REPL's jobs) (and the terminal is not in raw
/// mode); outside that window SIGINT keeps its default action. The handlers are installed once
/// per process: removing a signal action would leave SIGINT ignored, not restored.
pub(crate) struct SigGuard {
    caught: Arc<AtomicBool>,
    idle: Arc<AtomicBool>,
}

fn sigint_flags() -> &'static (Arc<AtomicBool>, Arc<AtomicBool>) {
    static FLAGS: std::sync::OnceLock<(Arc<AtomicBool>, Arc<AtomicBool>)> =
        std::sync::OnceLock::new();
    FLAGS.get_or_init(|| {
        let caught = Arc::new(AtomicBool::new(false));
        let idle = Arc::new(AtomicBool::new(true));
        let sig = signal_hook::consts::SIGINT;
        // Without the handlers Ctrl-C would still stop the process: nothing to do about a
        // failure here but run without them.
        // 130: how a shell reports a process ended by SIGINT.
        let _ = signal_hook::flag::register_conditional_shutdown(sig, 130, idle.clone());
        let _ = signal_hook::flag::register(sig, caught.clone());
        (caught, idle)
    })
}

impl SigGuard {
    pub(crate) fn new() -> SigGuard {
        let (caught, idle) = sigint_flags();
        caught.store(false, Ordering::SeqCst);
        idle.store(false, Ordering::SeqCst);
        SigGuard {
            caught: caught.clone(),
            idle: idle.clone(),
        }
    }

    /// Whether Ctrl-C came since the last call.
    pub(crate) fn take(&self) -> bool {
        self.caught.swap(false, Ordering::SeqCst)
    }
}

impl Drop for SigGuard {
    fn drop(&mut self) {
        self.idle.store(true, Ordering::SeqCst);
        self.caught.store(false, Ordering::SeqCst);
    }
}

/// The bar's position for `done` of `total` planned seconds.
fn time_steps(done: f64, total: f64) -> u64 {
    if total > 0.0 {
        ((done / total).clamp(0.0, 1.0) * BAR_STEPS as f64).round() as u64
    } else {
        0
    }
}

/// A key pressed during a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Key {
    /// Ctrl-C typed in a raw-mode window (between windows it arrives as a signal).
    Interrupt,
    Hold,
    Resume,
    Abort,
}

/// Hold/resume/abort keys, read in raw mode in short windows so that output in between
/// stays normal. Shared by `lase run` and the REPL's `:run`.
pub(crate) struct Keys {
    rx: Receiver<Key>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Keys {
    /// Starts the reader when stdin and stderr are terminals.
    fn for_terminal() -> Option<Keys> {
        (std::io::stdin().is_terminal() && std::io::stderr().is_terminal()).then(Keys::start)
    }

    pub(crate) fn start() -> Keys {
        use crossterm::event::{self, Event as CtEvent, KeyCode, KeyEventKind, KeyModifiers};
        let (tx, rx) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || {
            while !flag.load(Ordering::SeqCst) {
                if crossterm::terminal::enable_raw_mode().is_err() {
                    return;
                }
                let ev = match event::poll(Duration::from_millis(100)) {
                    Ok(true) => event::read().ok(),
                    _ => None,
                };
                let _ = crossterm::terminal::disable_raw_mode();
                let Some(CtEvent::Key(k)) = ev else {
                    std::thread::sleep(Duration::from_millis(5));
                    continue;
                };
                if k.kind != KeyEventKind::Press {
                    continue;
                }
                let key = match k.code {
                    KeyCode::Char('c') if k.modifiers.contains(KeyModifiers::CONTROL) => {
                        Some(Key::Interrupt)
                    }
                    KeyCode::Char('h') | KeyCode::Char(' ') | KeyCode::Char('!') => Some(Key::Hold),
                    KeyCode::Char('r') | KeyCode::Char('~') | KeyCode::Enter => Some(Key::Resume),
                    KeyCode::Char('a') | KeyCode::Char('q') | KeyCode::Esc => Some(Key::Abort),
                    _ => None,
                };
                if let Some(key) = key
                    && tx.send(key).is_err()
                {
                    return;
                }
            }
        });
        Keys {
            rx,
            stop,
            thread: Some(thread),
        }
    }

    /// The next key pressed, if any.
    pub(crate) fn try_key(&self) -> Option<Key> {
        self.rx.try_recv().ok()
    }
}

impl Drop for Keys {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = crossterm::terminal::disable_raw_mode();
    }
}
