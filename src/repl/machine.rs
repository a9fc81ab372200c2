//! The REPL's controller: one link kept open across commands (the built-in simulator unless
//! `--link` or `:connect` names another), jogging, homing, status, and jobs streamed with the
//! progress bar.
//!
//! Safety at the machine: a job starts through `link::job`, as `lase run`'s do: streamed only
//! once it is planned, every line is known to be sendable, the controller's settings fit the
//! plan and the controller is idle. Ctrl-C during a job or a jog is a feed hold (GRBL's laser
//! mode switches the beam off while held), never a kill of the process: the REPL then asks
//! whether to resume or abort. Signals are caught only while the
//! controller moves; at the prompt rustyline reads Ctrl-C as a key.

use crate::driver::Failure;
use crate::live::{Display, Key, Keys, SigGuard};
use lase_runtime::emit::NcLine;
use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::job::{self, JobLines, NewJournal, Origin, Refused, Started};
use lase_runtime::link::journal;
use lase_runtime::link::sim::{self, SimHandle};
use lase_runtime::link::stream::{self, Control, Outcome, Progress};
use lase_runtime::link::{
    self, ConnectOptions, Event, Link, LinkError, LinkUrl, MachineState, Realtime, Status,
};
use lase_runtime::machine::Machine;
use lase_runtime::motion::Job;
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

impl LostJob {
    /// Its lines as they go to the controller.
    fn lines(&self) -> JobLines<'_> {
        JobLines::new(
            &self.job,
            &self.nc,
            link::live_dialect(&self.job.program.machine),
        )
    }
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

/// Everything a job needs to be streamed: its NC lines and how to point back at the recipe.
pub struct Stream<'a> {
    pub job: &'a Job,
    pub nc: &'a [NcLine],
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
        let line = lase_runtime::emit::reapproach::grbl_jog(axis, dist, feed_per_min);
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
        let letters = self.letters.clone();
        let link = self.link(machine)?;
        let stop = stream::stop_safely(&mut **link, &letters);
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

    /// Streams a planned job: nothing is sent unless it passes the job preflight (every line
    /// sendable, settings fit the plan, controller idle), and no job interrupted by a lost
    /// link waits.
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
        // The journal: what was sent and acknowledged, so that a lost link can be resumed.
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
        let lost = LostJob {
            name: name.to_string(),
            machine: machine.clone(),
            job: job.job.clone(),
            nc: job.nc.to_vec(),
            journal: path,
        };
        let lines = lost.lines();
        let origin = Origin::Fresh(Some(NewJournal {
            path: lost.journal.to_path_buf(),
            recipe: name.to_string(),
            link: self.url.to_string(),
        }));
        let started = match self.start_job(machine, &lines, origin) {
            Ok((started, _)) => started,
            Err(t) => return (Ran::NotStarted, Err(t)),
        };
        let (ran, result, resumable) = self.stream_job(&lost, &lines, started);
        if resumable {
            self.lost = Some(lost);
        }
        (ran, result)
    }

    /// Continues a job after a lost link: reconnects, finds from the controller's state where
    /// the job stands, re-approaches and streams the rest. Until it is streamed again, the job
    /// stays resumable.
    fn resume_job(&mut self, lost: LostJob) -> R<String> {
        let lines = lost.lines();
        let origin = match journal::read(&lost.journal)
            .and_then(|st| Origin::resume(&lines, lost.journal.to_path_buf(), st, None, &lost.name))
        {
            Ok(o) => o,
            Err(e) => {
                self.lost = Some(lost);
                return Err(e.into());
            }
        };
        let started = match self.start_job(&lost.machine, &lines, origin) {
            Ok((started, note)) => {
                let note = note.unwrap_or_default();
                if self.interactive {
                    eprintln!("{}: {note}", lost.name);
                } else {
                    println!("{}: {note}", lost.name);
                }
                started
            }
            Err(t) => {
                self.lost = Some(lost);
                return Err(t);
            }
        };
        let (_, result, resumable) = self.stream_job(&lost, &lines, started);
        if resumable {
            self.lost = Some(lost);
        }
        result
    }

    /// The job preflight and start on the session's link; for a resumed job also what the
    /// resume found, worded for the operator.
    fn start_job(
        &mut self,
        machine: &Machine,
        lines: &JobLines<'_>,
        origin: Origin,
    ) -> R<(Started, Option<String>)> {
        let link = self.link(Some(machine))?;
        let ready = job::preflight(&mut **link, lines, origin).map_err(|r| match r {
            Refused::Link(e) => Trouble::from(e),
            Refused::Settings(m) => Trouble::Diag(Failure::many(m)),
            Refused::NotIdle(s) => Trouble::Say(format!(
                "the controller is not idle ({}): {}",
                s.summary_for(None, &lines.letters()),
                match s.state {
                    MachineState::Alarm => "`:home` it first",
                    MachineState::Hold { .. } => "`:resume` or `:abort` first",
                    _ => "wait for it, or `:abort`",
                }
            )),
        })?;
        let note = ready.resume_plan().map(|plan| {
            format!(
                "{} of {} lines had run; re-approach: {}",
                plan.executed,
                lines.len(),
                plan.reapproach.all().join(" | ")
            )
        });
        let started = ready.start(&mut **link, lines)?;
        Ok((started, note))
    }

    /// Streams a started job with the progress bar and Ctrl-C as a feed hold. The flag says
    /// whether the link was lost and the job is worth keeping for `:resume`.
    fn stream_job(
        &mut self,
        lost: &LostJob,
        lines: &JobLines<'_>,
        mut started: Started,
    ) -> (Ran, R<String>, bool) {
        let interactive = self.interactive;
        let Some(conn) = self.conn.as_mut() else {
            return (
                Ran::NotStarted,
                Err(Trouble::Say("not connected".into())),
                false,
            );
        };
        let link = &mut conn.link;
        let name = lost.name.as_str();
        let from = started.from();
        let total = lines.len();
        let letters = lines.letters();
        let (cycle_s, cycle) = crate::output::controller_cycle(lines.job(), lines.dialect());
        let eta = lase_runtime::link::eta::Eta::from_runs(lines.job(), lines.runs(), total)
            .counted_in(cycle_s);
        // Ctrl-C is ours from here until the job has ended.
        let sig = SigGuard::new();
        let keys = interactive.then(Keys::start);
        let mut display = Display::new(total, from, eta);
        let header = format!(
            "{name}: {} lines to {}, {cycle}",
            total - from,
            link.describe()
        );
        if interactive {
            display.println(&header);
            display.println("Ctrl-C = feed hold, laser off");
        } else {
            println!("{}: {} lines", name, total - from);
        }
        let mut asking = false;
        let mut announced = false;
        let report = started.stream(
            &mut **link,
            lines,
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
                        "held: {at}, laser off, {} of {total} lines done — r = resume, a = abort",
                        p.acked,
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
        let ran = if report.sent > 0 || matches!(report.outcome, Outcome::Lost(_)) {
            Ran::Started
        } else {
            Ran::NotStarted
        };
        if report.outcome == Outcome::Done {
            let mut msg = format!(
                "{name}: done — {} lines, controller {}",
                report.acked,
                link.status(&letters)
            );
            if interactive {
                msg.push_str(&format!(" ({:.1} s)", report.elapsed.as_secs_f64()));
            }
            return (ran, Ok(msg), false);
        }
        let lost_link = matches!(report.outcome, Outcome::Lost(_));
        if lost_link {
            self.conn = None;
        }
        let resume = match &self.url {
            // The in-process simulator ends with its link: there is nothing to resume.
            LinkUrl::Sim(_) => {
                "the simulator ended with the link: check the part, `:connect` again".to_string()
            }
            _ => format!(
                "the controller goes on with what it had received; reconnect it and `:resume`: the job continues where the controller stopped (its journal: {})",
                lost.journal.display()
            ),
        };
        let resumable = lost_link && !matches!(self.url, LinkUrl::Sim(_));
        let failure = crate::live::job_failure(report, lines, resume);
        (ran, Err(Trouble::Diag(failure)), resumable)
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
