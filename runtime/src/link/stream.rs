//! Streaming a job over any [`Link`]: keeps the controller's input buffer full, journals every
//! line before it is sent and when it is acknowledged, polls status for progress, takes
//! hold/resume/abort, and stops safely on a rejected line, an alarm or a protocol error.
//!
//! Stopping safely: feed hold (`!`), wait until motion has stopped, then a soft reset, which
//! empties the controller's buffers (with character counting, lines after a rejected one are
//! already there and a GRBL controller would go on executing them) and switches the laser
//! off (M5 is the state after reset). A reset at rest keeps the machine position.
//!
//! A dropped link is not stopped: there is nobody to talk to. The journal is synced and the
//! job can be continued with [`super::resume`].

use super::journal::Journal;
use super::settle::{SettlePoint, Settled};
use super::{Continue, Event, Link, LinkError, MachineState, ModalState, Realtime, Status};
use std::time::{Duration, Instant};

/// What an operator (or a test) can do while a job streams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    Hold,
    Resume,
    Abort,
}

#[derive(Debug, Clone)]
pub struct StreamOptions {
    /// How often to ask for a status report.
    pub status_interval: Duration,
    /// No word from the controller for this long means the link is dead.
    pub stall_timeout: Duration,
}

impl Default for StreamOptions {
    fn default() -> Self {
        StreamOptions {
            status_interval: Duration::from_millis(200),
            stall_timeout: Duration::from_secs(5),
        }
    }
}

/// Where a job stands, for progress displays.
#[derive(Debug, Clone)]
pub struct Progress {
    /// Lines acknowledged (indices below this are done, from the job's first line).
    pub acked: usize,
    pub sent: usize,
    pub total: usize,
    pub status: Option<Status>,
    pub held: bool,
    /// Row starts settled so far, of how many (`scan … { settle }`).
    pub settled: (usize, usize),
}

/// How streaming ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Every line acknowledged and the controller idle.
    Done,
    /// The controller refused line `index` (0-based in the job).
    Rejected {
        index: usize,
        code: u32,
        message: String,
    },
    /// The controller raised an alarm; `index` is the oldest unanswered line, when any.
    Alarm {
        index: Option<usize>,
        code: u32,
        message: String,
    },
    /// The operator aborted.
    Aborted,
    /// The link dropped (or went silent): the job can be resumed from its journal.
    Lost(LinkError),
    /// The controller said something that cannot be trusted; the job was stopped.
    Failed(LinkError),
}

/// What happened, with the numbers.
#[derive(Debug, Clone)]
pub struct Report {
    pub outcome: Outcome,
    pub acked: usize,
    pub sent: usize,
    /// Program bytes written (newlines included), real-time bytes excluded.
    pub program_bytes: u64,
    pub elapsed: Duration,
    /// What the stop sequence did, when it ran.
    pub stop_note: Option<String>,
    /// How each row start settled, in order.
    pub settled: Vec<Settled>,
}

/// Lines made on demand, in order: a program that is never held in memory as a whole (a
/// generated benchmark, an emitter run again), so that a job of any length streams in
/// bounded memory.
pub trait Source: std::fmt::Debug {
    /// How many lines the job has.
    fn len(&self) -> usize;

    /// Line `index`. Streaming asks for indices that never decrease, and may ask for the same
    /// one again (when the controller's buffer was full the first time).
    fn line(&self, index: usize) -> String;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A job's lines: all in memory, or made on demand.
#[derive(Debug, Clone, Copy)]
pub enum Lines<'a> {
    All(&'a [String]),
    Made(&'a dyn Source),
}

impl<'a> Lines<'a> {
    pub fn len(&self) -> usize {
        match self {
            Lines::All(l) => l.len(),
            Lines::Made(s) => s.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Line `index` (see [`Source::line`]); borrowed when it is in memory.
    pub fn get(&self, index: usize) -> std::borrow::Cow<'a, str> {
        match self {
            Lines::All(l) => l[index].as_str().into(),
            Lines::Made(s) => s.line(index).into(),
        }
    }
}

/// What to stream.
#[derive(Debug, Clone)]
pub struct StreamJob<'a> {
    /// The job's lines; the journal counts in their indices.
    pub lines: Lines<'a>,
    /// The first line to send.
    pub from: usize,
    /// Lines sent just before `lines[from]`, in the same burst: the end of a re-approach that
    /// re-arms the laser, so the beam is on at rest no longer than in the program itself.
    /// Not journaled as job lines.
    pub lead: &'a [String],
    /// The modal state a re-approach restores, when resuming: the link may have to send a
    /// modal continuation line differently ([`Link::continue_line`]).
    pub restored: Option<ModalState>,
    /// From [`super::resume::send_guards`], or empty: lines held back until earlier ones are
    /// acknowledged, so that a dropped link can always be resumed.
    pub guards: &'a [Option<usize>],
    /// The machine's axis letters, which a stop's report shows (`Idle | X12 Z0 B0` on the
    /// notcher, never a `Y` it does not have); empty: every axis the controller reports.
    pub letters: &'a [char],
    /// Row starts to settle before the line after each is sent ([`super::settle`]).
    pub settles: &'a [SettlePoint],
}

impl<'a> StreamJob<'a> {
    /// Lines made by `source`, from the start.
    pub fn made(source: &'a dyn Source) -> StreamJob<'a> {
        StreamJob {
            lines: Lines::Made(source),
            ..StreamJob::new(&[])
        }
    }

    /// All of `lines`, from the start.
    pub fn new(lines: &'a [String]) -> StreamJob<'a> {
        StreamJob {
            lines: Lines::All(lines),
            from: 0,
            lead: &[],
            restored: None,
            guards: &[],
            letters: &[],
            settles: &[],
        }
    }
}

/// Streams a job. `observer` sees progress after every event and may return a [`Control`].
pub fn stream(
    link: &mut dyn Link,
    job: &StreamJob<'_>,
    mut journal: Option<&mut Journal>,
    options: &StreamOptions,
    observer: &mut dyn FnMut(&Progress, Option<&Event>) -> Option<Control>,
) -> Report {
    let start = Instant::now();
    let lines = job.lines;
    let guards = job.guards;
    let total = lines.len();
    let mut next = job.from.min(total);
    let mut acked = next;
    // Lead lines sent and acknowledged.
    let (mut lead_sent, mut lead_acked) = (0usize, 0usize);
    let mut continuation = job.restored.clone();
    let mut held = false;
    let mut last_query: Option<Instant> = None;
    let mut last_heard = Instant::now();
    let mut status: Option<Status> = None;
    // Status reports asked for after the last line was acknowledged: only those can say the
    // job has finished.
    let mut queried_after_done = false;
    let mut program_bytes = 0u64;
    // Settle points whose line is before the first one sent are behind a resume already.
    let mut settle_next = job.settles.partition_point(|p| p.after < next);
    let mut settled: Vec<Settled> = Vec::new();
    let mut last_wco: Option<Vec<f64>> = None;

    let finish = |journal: &mut Option<&mut Journal>, how: &str| {
        if let Some(j) = journal.as_deref_mut() {
            let _ = j.finish(how);
        }
    };
    macro_rules! end {
        ($outcome:expr, $note:expr) => {{
            return Report {
                outcome: $outcome,
                acked,
                sent: next,
                program_bytes,
                elapsed: start.elapsed(),
                stop_note: $note,
                settled,
            };
        }};
    }

    loop {
        // The lead goes first, in the same burst as the job lines after it.
        while lead_sent < job.lead.len() && !held && link.can_send(&job.lead[lead_sent]) {
            if let Err(e) = link.send_line(&job.lead[lead_sent]) {
                end!(Outcome::Lost(e), None);
            }
            program_bytes += job.lead[lead_sent].len() as u64 + 1;
            lead_sent += 1;
        }
        // Fill the controller's buffer.
        while next < total && !held && lead_sent == job.lead.len() {
            // A row start to settle: once everything before it is acknowledged, the table
            // stops there and the corrective steps go out before the row's first line.
            if let Some(p) = job.settles.get(settle_next).filter(|p| p.after < next) {
                if acked < next || link.in_flight() > 0 {
                    break;
                }
                match super::settle::settle(link, p, &mut last_wco) {
                    Ok(s) => {
                        settled.push(s);
                        settle_next += 1;
                        let progress = Progress {
                            acked,
                            sent: next,
                            total,
                            status: link.last_status().cloned(),
                            held,
                            settled: (settled.len(), job.settles.len()),
                        };
                        if observer(&progress, None) == Some(Control::Abort) {
                            let note = stop_safely(link, job.letters);
                            finish(&mut journal, "abort");
                            end!(Outcome::Aborted, Some(note));
                        }
                    }
                    Err(e @ LinkError::Lost { .. }) => {
                        if let Some(j) = journal.as_deref_mut() {
                            let _ = j.sync();
                        }
                        end!(Outcome::Lost(e), None);
                    }
                    Err(e) => {
                        let note = stop_safely(link, job.letters);
                        finish(&mut journal, "error settle");
                        end!(Outcome::Failed(e), Some(note));
                    }
                }
                last_heard = Instant::now();
            }
            let line = lines.get(next);
            let how = match &continuation {
                Some(state) => link.continue_line(state, &line),
                None => Continue::Settled,
            };
            let text: &str = match &how {
                Continue::Replace(s) => s.as_str(),
                _ => &line,
            };
            if !link.can_send(text) {
                break;
            }
            if let Some(Some(c)) = guards.get(next).filter(|g| g.is_some_and(|c| c < next)) {
                if acked <= *c {
                    break;
                }
                // The acknowledgement that releases this line must survive a crash too.
                if let Some(j) = journal.as_deref_mut()
                    && let Err(e) = j.sync()
                {
                    let note = stop_safely(link, job.letters);
                    end!(Outcome::Failed(e), Some(note));
                }
            }
            if let Some(j) = journal.as_deref_mut()
                && !j.covers(next)
            {
                // Reservations stop at the next guarded line (looked for only when a new
                // reservation is made: a window is thousands of lines on a fast link).
                let limit = (next + 1..(next + j.window()).min(total))
                    .find(|&k| guards.get(k).is_some_and(Option::is_some))
                    .unwrap_or(usize::MAX);
                if let Err(e) = j.will_send(next, limit) {
                    let note = stop_safely(link, job.letters);
                    end!(Outcome::Failed(e), Some(note));
                }
            }
            if let Err(e) = link.send_line(text) {
                if let Some(j) = journal.as_deref_mut() {
                    // Part of this line may have gone out: count it as sent.
                    let _ = j.settle(next + 1);
                }
                end!(Outcome::Lost(e), None);
            }
            program_bytes += text.len() as u64 + 1;
            if how != Continue::Pending {
                continuation = None;
            }
            if let Some(j) = journal.as_deref_mut() {
                j.sent(next);
            }
            next += 1;
        }

        let now = Instant::now();
        if last_query.is_none_or(|t| now.duration_since(t) >= options.status_interval) {
            if let Err(e) = link.realtime(Realtime::StatusQuery) {
                end!(Outcome::Lost(e), None);
            }
            last_query = Some(now);
            if acked == total && lead_acked == job.lead.len() && link.in_flight() == 0 {
                queried_after_done = true;
            }
        }
        let wait = options
            .status_interval
            .saturating_sub(now.duration_since(last_query.unwrap_or(now)))
            .min(Duration::from_millis(50));
        let event = match link.poll(wait) {
            Ok(e) => e,
            Err(e @ LinkError::Lost { .. }) => {
                if let Some(j) = journal.as_deref_mut() {
                    let _ = j.settle(next);
                }
                end!(Outcome::Lost(e), None);
            }
            Err(e) => {
                let note = stop_safely(link, job.letters);
                finish(&mut journal, "error link");
                end!(Outcome::Failed(e), Some(note));
            }
        };
        match &event {
            None => {
                if last_heard.elapsed() > options.stall_timeout {
                    if let Some(j) = journal.as_deref_mut() {
                        let _ = j.settle(next);
                    }
                    end!(
                        Outcome::Lost(LinkError::Timeout {
                            waiting_for: "streaming".into(),
                            seconds: options.stall_timeout.as_secs_f64(),
                        }),
                        None
                    );
                }
            }
            Some(e) => {
                last_heard = Instant::now();
                match e {
                    Event::Ack if lead_acked < lead_sent => lead_acked += 1,
                    Event::Rejected { code, message } if lead_acked < lead_sent => {
                        let line = job.lead[lead_acked].clone();
                        let note = stop_safely(link, job.letters);
                        finish(&mut journal, &format!("error lead {code}"));
                        end!(
                            Outcome::Failed(LinkError::NotReady {
                                reason: format!(
                                    "the re-approach line `{line}` was refused: error {code}, {message}"
                                ),
                                help:
                                    "check the controller's state and settings, then resume again"
                                        .into(),
                            }),
                            Some(note)
                        );
                    }
                    Event::Ack => {
                        if let Some(j) = journal.as_deref_mut() {
                            j.acked(acked);
                        }
                        acked += 1;
                        if acked == total {
                            // Ask at once whether the machine has finished.
                            last_query = None;
                        }
                    }
                    Event::Rejected { code, message } => {
                        let index = acked;
                        let note = stop_safely(link, job.letters);
                        finish(&mut journal, &format!("error {index} {code}"));
                        end!(
                            Outcome::Rejected {
                                index,
                                code: *code,
                                message: message.clone(),
                            },
                            Some(note)
                        );
                    }
                    Event::Alarm { code, message } => {
                        let index = (acked < next).then_some(acked);
                        let note = stop_after_alarm(link, job.letters);
                        finish(&mut journal, &format!("alarm {code}"));
                        end!(
                            Outcome::Alarm {
                                index,
                                code: *code,
                                message: message.clone(),
                            },
                            Some(note)
                        );
                    }
                    Event::Reset { banner } => {
                        // Someone reset the controller: what was in its buffers is gone and
                        // where it stopped is unknown.
                        finish(&mut journal, "reset");
                        end!(
                            Outcome::Failed(LinkError::NotReady {
                                reason: format!("the controller restarted during the job (`{banner}`)"),
                                help: "the lines in its buffers were lost; check the part before running the rest by hand".into(),
                            }),
                            None
                        );
                    }
                    Event::Status(s) => {
                        status = Some(s.clone());
                        // Idle after the last answer: the planner has run dry.
                        let finished = queried_after_done
                            && matches!(s.state, MachineState::Idle | MachineState::Check);
                        if acked == total && link.in_flight() == 0 && finished {
                            finish(&mut journal, "done");
                            let progress = Progress {
                                acked,
                                sent: next,
                                total,
                                status: status.clone(),
                                held,
                                settled: (settled.len(), job.settles.len()),
                            };
                            observer(&progress, event.as_ref());
                            end!(Outcome::Done, None);
                        }
                    }
                    Event::Message(_) => {}
                }
            }
        }
        let progress = Progress {
            acked,
            sent: next,
            total,
            status: status.clone(),
            held,
            settled: (settled.len(), job.settles.len()),
        };
        match observer(&progress, event.as_ref()) {
            Some(Control::Hold) if !held => {
                held = true;
                if let Err(e) = link.realtime(Realtime::FeedHold) {
                    end!(Outcome::Lost(e), None);
                }
            }
            Some(Control::Resume) if held => {
                held = false;
                if let Err(e) = link.realtime(Realtime::CycleStart) {
                    end!(Outcome::Lost(e), None);
                }
            }
            Some(Control::Abort) => {
                let note = stop_safely(link, job.letters);
                finish(&mut journal, "abort");
                end!(Outcome::Aborted, Some(note));
            }
            _ => {}
        }
    }
}

/// After an alarm the controller has stopped by itself (and ignores status queries until
/// reset): soft reset at once.
fn stop_after_alarm(link: &mut dyn Link, letters: &[char]) -> String {
    let _ = link.realtime(Realtime::FeedHold);
    reset(
        link,
        vec!["the controller halted itself (alarm)".into()],
        letters,
    )
}

/// Feed hold, wait for the machine to stop, soft reset (buffers emptied, laser off). Returns
/// what happened, for the report, with the position on the machine's own axes (`letters`;
/// empty: every axis reported).
pub fn stop_safely(link: &mut dyn Link, letters: &[char]) -> String {
    let mut note = Vec::new();
    if link.realtime(Realtime::FeedHold).is_err() {
        return "the link is gone: the controller could not be told to stop".into();
    }
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut last = None;
    while Instant::now() < deadline {
        match link.query_status(Duration::from_millis(500)) {
            Ok(s) => {
                let stopped = !matches!(
                    s.state,
                    MachineState::Run | MachineState::Jog | MachineState::Hold { complete: false }
                );
                last = Some(s);
                if stopped {
                    break;
                }
            }
            Err(_) => break,
        }
    }
    match &last {
        Some(s) => note.push(format!("feed hold: {}", s.state.name())),
        None => note.push("feed hold sent, no status came back".into()),
    }
    reset(link, note, letters)
}

fn reset(link: &mut dyn Link, mut note: Vec<String>, letters: &[char]) -> String {
    if link.realtime(Realtime::SoftReset).is_ok() {
        let deadline = Instant::now() + Duration::from_secs(3);
        let mut reset = false;
        while Instant::now() < deadline {
            match link.poll(Duration::from_millis(50)) {
                Ok(Some(Event::Reset { .. })) => {
                    reset = true;
                    break;
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        note.push(if reset {
            "soft reset: buffers emptied, laser off".into()
        } else {
            "soft reset sent, no banner came back".into()
        });
    }
    if let Ok(s) = link.query_status(Duration::from_millis(500)) {
        note.push(format!("controller now {}", s.summary_for(None, letters)));
    }
    note.join("; ")
}
