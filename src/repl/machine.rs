//! The REPL's controller: one link kept open across commands (the built-in simulator unless
//! `--link` or `:connect` names another), jogging, homing, status, and jobs streamed with the
//! progress bar.
//!
//! Safety at the machine: a job is streamed only once it is planned and every line is known
//! to be sendable and the controller's settings fit the plan. Ctrl-C during a job or a jog is
//! a feed hold (GRBL's laser mode switches the beam off while held), never a kill of the
//! process: the REPL then asks whether to resume or abort. Signals are caught only while the
//! controller moves; at the prompt rustyline reads Ctrl-C as a key.

use crate::driver::Failure;
use crate::live::{Display, Key, Keys};
use crate::output;
use lase_lang::Span;
use lase_runtime::emit::NcLine;
use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::journal::{self, Header, Journal};
use lase_runtime::link::modal::Tracker;
use lase_runtime::link::sim::{self, SimHandle};
use lase_runtime::link::stream::{self, Control, Outcome, Progress, StreamJob, StreamOptions};
use lase_runtime::link::{
    self, AxisPos, ConnectOptions, Event, Link, LinkError, LinkUrl, MachineState, ModalState,
    Realtime, Requirements, Status, resume,
};
use lase_runtime::machine::Machine;
use lase_runtime::motion::Job;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// An open link.
struct Conn {
    link: Box<dyn Link>,
    /// The in-process simulator behind a `sim` link, and the machine it simulates.
    sim: Option<(SimHandle, String)>,
}

/// The controller side of a session.
pub struct Station {
    url: LinkUrl,
    conn: Option<Conn>,
    interactive: bool,
    /// A job whose link was lost: `:resume` continues it.
    lost: Option<LostJob>,
    /// The session machine's axis letters: what status lines show (every reported axis
    /// until a machine is chosen).
    letters: Vec<char>,
}

/// What continuing a job after a lost link needs: its lines, how to point back at the recipe,
/// and its journal (a temporary file: what was sent and acknowledged).
struct LostJob {
    name: String,
    machine: Machine,
    job: Job,
    nc: Vec<NcLine>,
    journal: tempfile::TempPath,
}

/// Where a job starts streaming: from its first line with a new journal, or after a resume.
struct Start<'a> {
    journal: Journal,
    from: usize,
    lead: &'a [String],
    restored: Option<ModalState>,
    start: AxisPos,
}

impl std::fmt::Debug for Station {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Station({})", self.url)
    }
}

/// Something went wrong on the controller side, already worded for the operator, or a
/// diagnostic to render against the session's sources.
pub enum Trouble {
    Say(String),
    Diag(Failure),
}

impl From<LinkError> for Trouble {
    fn from(e: LinkError) -> Trouble {
        Trouble::Diag(Failure::one(e))
    }
}

type R<T> = Result<T, Trouble>;

/// Ctrl-C, caught as a signal while the controller moves (and the terminal is not in raw
/// mode); outside that window SIGINT keeps its default action. The handlers are installed once
/// per process: removing a signal action would leave SIGINT ignored, not restored.
struct SigGuard {
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
    fn new() -> SigGuard {
        let (caught, idle) = sigint_flags();
        caught.store(false, Ordering::SeqCst);
        idle.store(false, Ordering::SeqCst);
        SigGuard {
            caught: caught.clone(),
            idle: idle.clone(),
        }
    }

    fn take(&self) -> bool {
        self.caught.swap(false, Ordering::SeqCst)
    }
}

impl Drop for SigGuard {
    fn drop(&mut self) {
        self.idle.store(true, Ordering::SeqCst);
        self.caught.store(false, Ordering::SeqCst);
    }
}

/// Everything a job needs to be streamed: its NC lines and how to point back at the recipe.
pub struct Stream<'a> {
    pub job: &'a Job,
    pub nc: &'a [NcLine],
}

impl Stream<'_> {
    fn span_of(&self, index: usize) -> Span {
        self.nc
            .get(index)
            .and_then(|l| l.op)
            .and_then(|o| self.job.program.ops.get(o as usize))
            .map(|o| o.span)
            .unwrap_or_default()
    }
}

/// How a job ended, for the session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ran {
    /// Nothing was sent.
    NotStarted,
    /// Lines went out (the job finished, or stopped).
    Started,
}

fn moving(s: &Status) -> bool {
    matches!(
        s.state,
        MachineState::Run | MachineState::Jog | MachineState::Home
    )
}

impl Station {
    pub fn new(url: LinkUrl, interactive: bool) -> Station {
        Station {
            url,
            conn: None,
            interactive,
            lost: None,
            letters: Vec::new(),
        }
    }

    pub fn url(&self) -> &LinkUrl {
        &self.url
    }

    /// Uses another link from now on (the old one is closed).
    pub fn set_url(&mut self, url: LinkUrl) {
        self.conn = None;
        self.url = url;
    }

    /// The open link, connecting first if needed. A simulator link follows the session's
    /// machine: a new `machine` statement gets a freshly powered-up simulator for it.
    fn link(&mut self, machine: Option<&Machine>) -> R<&mut Box<dyn Link>> {
        if let Some(m) = machine {
            self.letters = machine_letters(m);
        }
        let stale = match (&self.conn, &self.url, machine) {
            (Some(c), LinkUrl::Sim(_), Some(m)) => {
                c.sim.as_ref().is_some_and(|(_, n)| *n != m.name)
            }
            (Some(_), _, _) => false,
            (None, _, _) => true,
        };
        if stale {
            let had = self.conn.take().is_some();
            let conn = self.open(machine)?;
            if had && let Some((_, name)) = &conn.sim {
                eprintln!("simulator: now simulating `{name}`");
            }
            self.conn = Some(conn);
        }
        match self.conn.as_mut() {
            Some(c) => Ok(&mut c.link),
            None => Err(Trouble::Say("not connected".into())),
        }
    }

    fn open(&self, machine: Option<&Machine>) -> R<Conn> {
        let options = ConnectOptions {
            busy_wait: Duration::from_secs(30),
            // As much of the controller's input buffer as its `$I` reports.
            rx_buffer: None,
            ..ConnectOptions::default()
        };
        match &self.url {
            LinkUrl::Sim(o) => {
                let Some(m) = machine else {
                    return Err(Trouble::Say(
                        "the simulator needs a machine: say which first (e.g. `machine xy_table`), or `:connect tcp://HOST:PORT`".into(),
                    ));
                };
                let (handle, t) = sim::spawn_in_process(m, o.to_options()).map_err(|reason| {
                    LinkError::Connect {
                        url: self.url.to_string(),
                        reason,
                        help: None,
                    }
                })?;
                let link = GrblLink::connect(t, self.url.to_string(), &options)?;
                Ok(Conn {
                    link: Box::new(link),
                    sim: Some((handle, m.name.clone())),
                })
            }
            url => {
                let link = lase_runtime::link::connect(
                    url,
                    machine.unwrap_or(&placeholder_machine()?),
                    &options,
                )?;
                Ok(Conn { link, sim: None })
            }
        }
    }

    /// Connects now and says to what.
    pub fn connect(&mut self, machine: Option<&Machine>) -> R<String> {
        self.conn = None;
        let link = self.link(machine)?;
        Ok(link.describe())
    }

    /// The controller's work position, one value per axis letter it reports (X Y Z A B C;
    /// mm and degrees), connecting first if needed.
    pub fn position(&mut self, machine: Option<&Machine>) -> R<Vec<f64>> {
        let link = self.link(machine)?;
        let s = link.query_status(Duration::from_secs(2))?;
        s.work_position(s.wco.as_deref())
            .ok_or_else(|| Trouble::Say("the controller's status report has no position".into()))
    }

    /// `:status`: the controller's live state.
    pub fn status(&mut self, machine: Option<&Machine>) -> R<String> {
        let link = self.link(machine)?;
        let s = link.query_status(Duration::from_secs(2))?;
        let mut out = format!(
            "{} — {}",
            link.describe(),
            s.summary_for(None, &self.letters)
        );
        let laser = match s.spindle {
            Some(v) if v > 0.0 && !matches!(s.state, MachineState::Hold { .. }) => {
                format!("laser S{}", lase_lang::units::format_number(v))
            }
            _ => "laser off".into(),
        };
        out.push_str(&format!(" | {laser}"));
        if let Some(f) = s.feed.filter(|f| *f > 0.0) {
            out.push_str(&format!(" | F{}", lase_lang::units::format_number(f)));
        }
        if let Some([f, r, sp]) = s.overrides
            && [f, r, sp] != [100, 100, 100]
        {
            out.push_str(&format!(" | overrides feed {f}% rapid {r}% laser {sp}%"));
        }
        if s.state == MachineState::Alarm {
            out.push_str(
                "\n  the controller is in alarm: `:home` it (or `$X` on its console) before moving",
            );
        }
        Ok(out)
    }

    /// `:jog AXIS DIST`: a GRBL jog (`$J=`), relative, laser off; waits until it ends.
    /// Ctrl-C cancels it.
    pub fn jog(
        &mut self,
        machine: Option<&Machine>,
        axis: char,
        dist: f64,
        feed_per_min: f64,
    ) -> R<String> {
        let link = self.link(machine)?;
        // Distance and rate in the controller's units: mm, or degrees for a rotary axis.
        let line = format!(
            "$J=G91 G21 {}{} F{}",
            axis.to_ascii_uppercase(),
            fmt3(dist),
            fmt3(feed_per_min)
        );
        let reply = link.send(&line)?;
        if let lase_runtime::link::Reply::Error { code, message } = reply {
            let why = match code {
                15 => " (the jog would leave the machine's travel)".to_string(),
                8 => " (the controller is busy or held)".to_string(),
                _ => String::new(),
            };
            return Err(Trouble::Say(format!(
                "the controller refused `{line}`: error {code}, {message}{why}"
            )));
        }
        self.wait_idle(Realtime::JogCancel, "jog cancelled")
    }

    /// `:home`: the homing cycle (`$H`).
    pub fn home(&mut self, machine: Option<&Machine>) -> R<String> {
        let link = self.link(machine)?;
        let reply = link.send("$H")?;
        if let lase_runtime::link::Reply::Error { code, message } = reply {
            return Err(Trouble::Say(format!(
                "the controller refused homing: error {code}, {message}"
            )));
        }
        self.wait_idle(Realtime::FeedHold, "homing interrupted")
    }

    /// Waits until the controller is at rest; Ctrl-C sends `stop`.
    fn wait_idle(&mut self, stop: Realtime, stopped: &str) -> R<String> {
        let sig = SigGuard::new();
        let Some(conn) = self.conn.as_mut() else {
            return Err(Trouble::Say("not connected".into()));
        };
        let link = &mut conn.link;
        let letters = &self.letters;
        let mut note = String::new();
        loop {
            if sig.take() {
                link.realtime(stop)?;
                note = format!(" ({stopped})");
            }
            let s = link.query_status(Duration::from_secs(2))?;
            if !moving(&s) {
                return Ok(format!("{}{note}", s.summary_for(None, letters)));
            }
            // Status reports pace the loop; nothing else to wait for.
            let _ = link.poll(Duration::from_millis(50));
        }
    }

    /// `:hold`: feed hold now.
    pub fn hold(&mut self, machine: Option<&Machine>) -> R<String> {
        let link = self.link(machine)?;
        link.realtime(Realtime::FeedHold)?;
        let s = settle(link)?;
        Ok(format!(
            "{} (laser off while held; `:resume` continues)",
            s.summary_for(None, &self.letters)
        ))
    }

    /// `:resume`: continues a job whose link was lost, else cycle start after a hold.
    pub fn resume(&mut self, machine: Option<&Machine>) -> R<String> {
        if let Some(lost) = self.lost.take() {
            return self.resume_job(lost);
        }
        let link = self.link(machine)?;
        link.realtime(Realtime::CycleStart)?;
        let s = link.query_status(Duration::from_secs(2))?;
        Ok(s.summary_for(None, &self.letters))
    }

    /// `:abort`: feed hold, wait for rest, soft reset (buffers emptied, laser off); a job
    /// interrupted by a lost link is dropped.
    pub fn abort(&mut self, machine: Option<&Machine>) -> R<String> {
        let dropped = self.lost.take().map(|j| j.name);
        let link = self.link(machine)?;
        let stop = stream::stop_safely(&mut **link);
        Ok(match dropped {
            Some(name) => format!("dropped the interrupted job `{name}` (check the part); {stop}"),
            None => stop,
        })
    }

    /// Before leaving: waits while the controller still moves. `Err` with a reason when it is
    /// held (someone has to decide about the job in it).
    pub fn before_exit(&mut self) -> R<()> {
        let Some(conn) = self.conn.as_mut() else {
            return Ok(());
        };
        let s = match conn.link.query_status(Duration::from_secs(2)) {
            Ok(s) => s,
            // A link that is gone holds nothing back.
            Err(_) => return Ok(()),
        };
        if let MachineState::Hold { .. } | MachineState::Door(_) = s.state {
            return Err(Trouble::Say(format!(
                "the controller is held ({}): `:resume` or `:abort` first",
                s.summary_for(None, &self.letters)
            )));
        }
        if moving(&s) {
            eprintln!(
                "waiting for the controller to come to rest ({}); Ctrl-C = feed hold",
                s.summary_for(None, &self.letters)
            );
            self.wait_idle(Realtime::FeedHold, "held")?;
        }
        Ok(())
    }

    /// Streams a planned job: nothing is sent unless every line can go over the link and the
    /// controller's settings fit the plan, and no job interrupted by a lost link waits.
    pub fn run(&mut self, machine: &Machine, job: &Stream<'_>, name: &str) -> (Ran, R<String>) {
        if let Some(old) = &self.lost {
            return (
                Ran::NotStarted,
                Err(Trouble::Say(format!(
                    "`{}` was interrupted by a lost link: `:resume` continues it, `:abort` drops it",
                    old.name
                ))),
            );
        }
        let link = match self.link(Some(machine)) {
            Ok(l) => l,
            Err(t) => return (Ran::NotStarted, Err(t)),
        };
        let lines: Vec<String> = job.nc.iter().map(|l| l.text.clone()).collect();
        for (i, l) in lines.iter().enumerate() {
            if let Err(reason) = link.validate_line(l) {
                return (
                    Ran::NotStarted,
                    Err(LinkError::Unsendable {
                        line_no: i + 1,
                        line: l.clone(),
                        reason,
                        span: job.span_of(i),
                        help: "change the recipe text that ends up in this line".into(),
                    }
                    .into()),
                );
            }
        }
        let needs = Requirements::of_job(job.job, link::live_dialect(&job.job.program.machine));
        match link.check_settings(&needs) {
            Ok(m) if m.is_empty() => {}
            Ok(m) => {
                return (Ran::NotStarted, Err(Trouble::Diag(Failure::many(m))));
            }
            Err(e) => return (Ran::NotStarted, Err(e.into())),
        }
        match link.query_status(Duration::from_secs(2)) {
            Ok(s) if s.state == MachineState::Idle => {}
            Ok(s) => {
                return (
                    Ran::NotStarted,
                    Err(Trouble::Say(format!(
                        "the controller is not idle ({}): {}",
                        s.summary_for(None, &machine_letters(machine)),
                        match s.state {
                            MachineState::Alarm => "`:home` it first",
                            MachineState::Hold { .. } => "`:resume` or `:abort` first",
                            _ => "wait for it, or `:abort`",
                        }
                    ))),
                );
            }
            Err(e) => return (Ran::NotStarted, Err(e.into())),
        }
        // The journal: what was sent and acknowledged, so that a lost link can be resumed.
        let header_start = match link.query_status(Duration::from_secs(2)) {
            Ok(s) => s.work_axes(),
            Err(e) => return (Ran::NotStarted, Err(e.into())),
        };
        let path = match tempfile::Builder::new()
            .prefix("lase-repl-")
            .suffix(".journal")
            .tempfile()
        {
            Ok(f) => f.into_temp_path(),
            Err(e) => {
                return (
                    Ran::NotStarted,
                    Err(Trouble::Say(format!("cannot create the job journal: {e}"))),
                );
            }
        };
        let header = Header {
            recipe: name.to_string(),
            link: self.url.to_string(),
            dialect: link::live_dialect(machine).to_string(),
            lines: lines.len(),
            hash: journal::program_hash(lines.iter().map(String::as_str)),
            start: header_start,
        };
        let jour = match Journal::create(&path, &header) {
            Ok(j) => j,
            Err(e) => return (Ran::NotStarted, Err(e.into())),
        };
        let lost = LostJob {
            name: name.to_string(),
            machine: machine.clone(),
            job: job.job.clone(),
            nc: job.nc.to_vec(),
            journal: path,
        };
        self.stream_job(
            lost,
            &lines,
            Start {
                journal: jour,
                from: 0,
                lead: &[],
                restored: None,
                start: header_start,
            },
        )
    }

    /// Continues a job after a lost link: reconnects, finds from the controller's state where
    /// the job stands, re-approaches and streams the rest.
    fn resume_job(&mut self, lost: LostJob) -> R<String> {
        let lines: Vec<String> = lost.nc.iter().map(|l| l.text.clone()).collect();
        let letters = machine_letters(&lost.machine);
        let path = lost.journal.to_path_buf();
        let machine = lost.machine.clone();
        // Until it is streamed again, the job stays resumable.
        self.lost = Some(lost);
        let link = self.link(Some(&machine))?;
        let st = journal::read(&path)?;
        let plan = resume::plan(
            &mut **link,
            &lines,
            &st,
            &letters,
            None,
            Duration::from_secs(600),
        )?;
        let jour = resume::enter(&mut **link, &plan, &path)?;
        let note = format!(
            "{} of {} lines had run; re-approach: {}",
            plan.executed,
            lines.len(),
            plan.reapproach.all().join(" | ")
        );
        let Some(lost) = self.lost.take() else {
            return Err(Trouble::Say("no job to resume".into()));
        };
        if self.interactive {
            eprintln!("{}: {note}", lost.name);
        } else {
            println!("{}: {note}", lost.name);
        }
        let (_, r) = self.stream_job(
            lost,
            &lines,
            Start {
                journal: jour,
                from: plan.executed,
                lead: &plan.reapproach.lead,
                restored: Some(plan.restored),
                start: st.header.start,
            },
        );
        r
    }

    /// Streams a checked job's lines from `at`, with the progress bar and Ctrl-C as a feed
    /// hold. A lost link keeps the job for `:resume`.
    fn stream_job(&mut self, lost: LostJob, lines: &[String], at: Start<'_>) -> (Ran, R<String>) {
        let interactive = self.interactive;
        let Some(conn) = self.conn.as_mut() else {
            return (Ran::NotStarted, Err(Trouble::Say("not connected".into())));
        };
        let link = &mut conn.link;
        let job = Stream {
            job: &lost.job,
            nc: &lost.nc,
        };
        let name = lost.name.as_str();
        let Start {
            journal: mut jour,
            from,
            lead,
            restored,
            start,
        } = at;
        let guards = resume::send_guards(&Tracker::new(start), lines);
        let letters = machine_letters(&lost.machine);
        let summary = lase_runtime::report::summarize(job.job);
        let eta = lase_runtime::link::eta::Eta::new(job.job, job.nc);
        // Ctrl-C is ours from here until the job has ended.
        let sig = SigGuard::new();
        let keys = interactive.then(Keys::start);
        let mut display = Display::new(lines.len(), from, eta);
        let header = format!(
            "{name}: {} lines to {}, planned cycle time {:.3} s",
            lines.len() - from,
            link.describe(),
            summary.cycle_time_s
        );
        if interactive {
            display.println(&header);
            display.println("Ctrl-C = feed hold, laser off");
        } else {
            println!("{}: {} lines", name, lines.len() - from);
        }
        let mut asking = false;
        let mut announced = false;
        let report = stream::stream(
            &mut **link,
            &StreamJob {
                lines,
                from,
                lead,
                restored,
                guards: &guards,
            },
            Some(&mut jour),
            &StreamOptions::default(),
            &mut |p: &Progress, e: Option<&Event>| {
                display.update(p, e);
                let mut key = keys.as_ref().and_then(Keys::try_key);
                if sig.take() {
                    key = Some(Key::Interrupt);
                }
                if asking
                    && !announced
                    && p.status
                        .as_ref()
                        .is_some_and(|s| s.state == (MachineState::Hold { complete: true }))
                {
                    announced = true;
                    let at = p
                        .status
                        .as_ref()
                        .map(|s| s.summary_for(None, &letters))
                        .unwrap_or_default();
                    display.println(&format!(
                        "held: {at}, laser off, {} of {} lines done — r = resume, a = abort",
                        p.acked,
                        lines.len()
                    ));
                }
                match key {
                    Some(Key::Interrupt) if !p.held => {
                        asking = true;
                        announced = false;
                        display.println("^C feed hold: stopping on the path, laser off");
                        Some(Control::Hold)
                    }
                    Some(Key::Interrupt) | Some(Key::Abort) => Some(Control::Abort),
                    Some(Key::Hold) => Some(Control::Hold),
                    Some(Key::Resume) if p.held => {
                        asking = false;
                        display.println("resumed");
                        Some(Control::Resume)
                    }
                    // Nobody to ask without a terminal: a held job is stopped.
                    None if asking && announced && !interactive => Some(Control::Abort),
                    _ => None,
                }
            },
        );
        drop(keys);
        display.finish();
        drop(sig);
        let total = lines.len();
        let result = match report.outcome {
            Outcome::Done => {
                let mut msg = format!(
                    "{name}: done — {} lines, controller {}",
                    report.acked,
                    link.status(&letters)
                );
                if interactive {
                    msg.push_str(&format!(" ({:.1} s)", report.elapsed.as_secs_f64()));
                }
                Ok(msg)
            }
            outcome @ (Outcome::Rejected { .. } | Outcome::Alarm { .. }) => {
                Err(Trouble::Diag(crate::live::controller_stop(
                    outcome,
                    lines,
                    &|i| job.span_of(i),
                    report.stop_note.unwrap_or_default(),
                )))
            }
            Outcome::Aborted => Err(Trouble::Diag(Failure::one(output::JobAborted {
                acked: report.acked,
                total,
                stop: report.stop_note.unwrap_or_default(),
            }))),
            Outcome::Lost(e) => {
                self.conn = None;
                let resume = match &self.url {
                    // The in-process simulator ends with its link: there is nothing to resume.
                    LinkUrl::Sim(_) => {
                        "the simulator ended with the link: check the part, `:connect` again"
                            .to_string()
                    }
                    _ => format!(
                        "the controller goes on with what it had received; reconnect it and `:resume`: the job continues where the controller stopped (its journal: {})",
                        lost.journal.display()
                    ),
                };
                if !matches!(self.url, LinkUrl::Sim(_)) {
                    self.lost = Some(lost);
                }
                return (
                    Ran::Started,
                    Err(Trouble::Diag(Failure::one(output::LinkLost {
                        reason: e.to_string(),
                        acked: report.acked,
                        total,
                        resume,
                    }))),
                );
            }
            Outcome::Failed(e) => Err(e.into()),
        };
        let ran = if report.sent > 0 {
            Ran::Started
        } else {
            Ran::NotStarted
        };
        (ran, result)
    }
}

/// A machine's axis letters, as its controller names them.
fn machine_letters(m: &Machine) -> Vec<char> {
    link::ControllerAxes::of(m).letters().to_vec()
}

/// After a feed hold: waits (a little) until motion has stopped.
fn settle(link: &mut Box<dyn Link>) -> R<Status> {
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let s = link.query_status(Duration::from_secs(2))?;
        if s.state != (MachineState::Hold { complete: false }) || Instant::now() > deadline {
            return Ok(s);
        }
    }
}

/// A link to a real controller does not depend on the machine; `connect` takes one for the
/// simulator's sake only.
fn placeholder_machine() -> R<Machine> {
    let text = lase_stdlib::machine("xy_table").unwrap_or_default();
    lase_runtime::machine::parse_machine(text, 0)
        .map_err(|_| Trouble::Say("the stock machine `xy_table` does not load".into()))
}

fn fmt3(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}
