//! `lase run --link linuxcnc://HOST:PORT`: the job as a file LinuxCNC opens and runs in AUTO
//! mode (`link::linuxcnc::job`), followed with the same progress bar and keys as a streamed
//! job, journaled so that `lase run --resume` continues it after a dropped link.

use super::{CmdResult, Display, Key, Keys, RunArgs, canonical, io_fail, job_failure};
use crate::driver::{self, Failure};
use lase_runtime::emit::Dialect;
use lase_runtime::link::job::JobLines;
use lase_runtime::link::journal::{self, Journal};
use lase_runtime::link::linuxcnc::job::{self as lcjob, LinuxCncJob, Placement, Resumed};
use lase_runtime::link::linuxcnc::{LIVE_TIMEOUT, Rsh};
use lase_runtime::link::stream::{Control, Outcome, Progress};
use lase_runtime::link::{LinkError, LinkUrl};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Runs (or, with `resumed`, continues) a job on LinuxCNC.
pub(super) fn run(
    args: &RunArgs,
    file: &Path,
    url: &LinkUrl,
    resumed: Option<(PathBuf, journal::State)>,
) -> CmdResult {
    let LinkUrl::LinuxCnc {
        host,
        port,
        dir,
        remote_dir,
        timeout,
    } = url
    else {
        unreachable!("called for linuxcnc links only");
    };
    if let Some(d) = args.dialect.as_deref().filter(|d| *d != "linuxcnc") {
        return Err(io_fail(format!(
            "the link to {url} runs LinuxCNC programs: the dialect is linuxcnc, not {d}"
        )));
    }
    if args.check || args.send_response || args.rx_buffer.is_some() {
        return Err(io_fail(
            "--check, --send-response and --rx-buffer are GRBL options: a LinuxCNC link runs the whole program as a file".into(),
        ));
    }
    let (recipe, job) = driver::compile_for(file, Some(Dialect::LinuxCnc))?;
    let origin = crate::origin::chosen(args.origin, &job.program);
    if origin != crate::origin::JobOrigin::Absolute {
        // The travel check at machine positions needs the controller's position or offset,
        // which this link does not read yet: refused rather than run unchecked.
        let name = format!("{origin:?}").to_lowercase();
        return Err(io_fail(format!(
            "--origin {name} over a LinuxCNC link is not built yet: run with --origin absolute, \
             or write the program with `lase emit --origin ...` and run it on the controller"
        )));
    }
    if let Some(s) = job.program.settles.first() {
        // The program runs from a file on LinuxCNC: lase cannot step between its lines.
        return Err((
            recipe.map.clone(),
            Failure::one(LinkError::Unsettled {
                message: "row-start settling over a LinuxCNC link is not built yet: LinuxCNC runs \
                          the program as a file, so lase cannot settle between its lines"
                    .into(),
                span: s.span,
                help: "stream the job to a GRBL controller (`--link tcp://…` or `serial://…`), \
                       or leave `settle` out"
                    .into(),
            }),
        ));
    }
    let map = recipe.map.clone();
    let fail = |e: LinkError| {
        let e = match e {
            // Before the job runs: linuxcncrsh took the connection but LinuxCNC does not
            // answer (GRBL's cable-and-baud help does not fit).
            LinkError::Timeout {
                waiting_for,
                seconds,
            } => LinkError::NotReady {
                reason: format!("LinuxCNC did not answer within {seconds} s while {waiting_for}"),
                help: "linuxcncrsh took the connection but LinuxCNC did not answer: its task (milltask) may have stopped or the computer may be overloaded; check LinuxCNC's terminal, restart LinuxCNC if needed, or allow longer with linuxcnc://HOST:PORT?timeout=SECONDS".into(),
            },
            e => e,
        };
        (map.clone(), Failure::one(e))
    };
    // LinuxCNC runs the program from a file, so the whole text is made here (the GRBL
    // stream makes its lines as they go).
    let source_map = &recipe.map;
    let locate = |s: lase_lang::Span| lase_runtime::compile::locate_in(source_map, s);
    let lines = JobLines::emitted(&job, Dialect::LinuxCnc, &locate)
        .map_err(|e| (recipe.map.clone(), Failure::one(e)))?;
    let text: Vec<String> = (0..lines.len()).map(|i| lines.line(i)).collect();
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "job".into());
    let machine = &job.program.machine;
    let lc = LinuxCncJob {
        lines: &text,
        placement: Placement::new(
            dir.as_deref().map(Path::new),
            remote_dir.as_deref(),
            &format!("{stem}.ngc"),
        ),
        letters: lines.letters(),
        post: machine.post.get("linuxcnc").cloned().ok_or_else(|| {
            io_fail(format!(
                "machine `{}` has no [post.linuxcnc]: lase cannot switch its beam on LinuxCNC",
                machine.name
            ))
        })?,
        poll: Duration::from_millis(50),
    };
    let timeout = timeout.map_or(LIVE_TIMEOUT, Duration::from_secs_f64);
    let mut rsh = Rsh::connect_with(host, *port, timeout).map_err(fail)?;
    let name = recipe.name();
    let mut journal = match resumed {
        Some((path, state)) => {
            let (mut j, _) = Journal::append(&path).map_err(fail)?;
            match lcjob::resume(&mut rsh, &lc, &state, Some(&mut j)).map_err(fail)? {
                Resumed::Finished => {
                    println!("{name}: LinuxCNC had finished the program while the link was down");
                    return Ok(());
                }
                Resumed::Reattached { line } => eprintln!(
                    "{name}: LinuxCNC is still running the program (line {line}): following it again"
                ),
                Resumed::Restarted { line, reapproach } => eprintln!(
                    "{name}: LinuxCNC had stopped; re-approach: {} — running from line {line}",
                    reapproach.join(" | ")
                ),
            }
            Some(j)
        }
        None => {
            let path = super::journal_path(args, file, url);
            let j = match &path {
                Some(p) => {
                    let start = rsh.status().map_err(fail)?.abs_pos;
                    let header = lcjob::header(
                        &canonical(file).display().to_string(),
                        &url.to_string(),
                        &text,
                        start,
                    );
                    Some(Journal::create(p, &header).map_err(fail)?)
                }
                None => None,
            };
            lcjob::start(&mut rsh, &lc, None).map_err(fail)?;
            j
        }
    };
    let summary = lase_runtime::report::summarize(&job);
    let (cycle_s, cycle) = crate::output::controller_cycle(&job, Dialect::LinuxCnc);
    let journal_name = journal.as_ref().map(|j| j.path().display().to_string());
    eprintln!(
        "{name}: {} running {} — {cycle}{}",
        rsh.describe(),
        lc.placement.remote,
        journal_name
            .as_ref()
            .map(|p| format!(", journal {p}"))
            .unwrap_or_default()
    );
    let eta = lase_runtime::link::eta::Eta::from_runs(&job, lines.runs(), lines.len())
        .counted_in(cycle_s);
    let mut display = Display::new(text.len(), 0, eta);
    let keys = Keys::for_terminal();
    let report = lcjob::follow(&mut rsh, &lc, journal.as_mut(), &mut |p: &Progress| {
        display.update(p, None);
        keys.as_ref().and_then(Keys::try_key).map(|k| match k {
            Key::Interrupt | Key::Abort => Control::Abort,
            Key::Hold => Control::Hold,
            Key::Resume => Control::Resume,
        })
    });
    drop(keys);
    display.finish();
    if report.outcome != Outcome::Done {
        let resume = match &journal_name {
            Some(j) => format!(
                "LinuxCNC goes on with the program by itself while it runs; reconnect and follow (or continue) it with `lase run --resume {j}`. If LinuxCNC itself stopped answering (its task, milltask, gone: a program RUNNING that never moves, commands unanswered), check the machine and restart LinuxCNC first; the resume then re-approaches and runs on from the first unfinished line"
            ),
            None => "this run kept no journal and cannot be resumed".into(),
        };
        let mut report = report;
        if let Outcome::Lost(e) = &report.outcome {
            // What LinuxCNC was last seen doing: the line before the one it reported running.
            let last = match report.acked {
                0 => "no line had run yet".to_string(),
                n => format!("the last line seen done was {n}: `{}`", text[n - 1]),
            };
            let why = match e {
                LinkError::Lost { reason } => reason.clone(),
                e => e.to_string(),
            };
            report.outcome = Outcome::Lost(LinkError::Lost {
                reason: format!("{why}; {last}"),
            });
        }
        return Err((map.clone(), job_failure(report, &lines, resume)));
    }
    println!(
        "{name}: done — LinuxCNC ran {} lines in {:.3} s",
        text.len(),
        report.elapsed.as_secs_f64()
    );
    println!(
        "  {cycle}, laser on {:.3} mm / {:.3} s, {} pulses",
        summary.laser_on_length_mm, summary.laser_on_time_s, summary.pulses
    );
    Ok(())
}

/// Whether a link runs programs on LinuxCNC.
pub(super) fn is_linuxcnc(url: &LinkUrl) -> bool {
    matches!(url, LinkUrl::LinuxCnc { .. })
}
