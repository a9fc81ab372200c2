//! A job on LinuxCNC: the program written where the controller reads it, opened and run in
//! AUTO mode, then followed by polling until the controller is idle again, journaled as a
//! GRBL job is ([`crate::link::journal`]: `a N` once line N has run), so that a dropped link
//! can be continued.
//!
//! linuxcncrsh cannot upload a file: `set open` takes a path *on the controller*. lase writes
//! the program into a folder it can write ([`Placement::local`]) and names it to the
//! controller by the path the controller sees it under ([`Placement::remote`]): the same path
//! when LinuxCNC runs on this computer, or a folder both share (NFS, SMB, sshfs) with
//! `linuxcnc://HOST:PORT?dir=LOCAL&remote-dir=ON-CONTROLLER`.
//!
//! A dropped link does not stop LinuxCNC: the program goes on. Resuming therefore first asks
//! the controller: still running or paused → lase follows it again where it is; idle before
//! the program's last move (aborted, E-stop) → outputs off at once, a rapid to where the first
//! unfinished line starts, the beam's synchronized outputs re-armed when that line is lit, and
//! `set run N` (LinuxCNC's run-from-line rebuilds the modal state by reading lines 1…N).

use super::{ProgramStatus, Rsh, RunStatus};
use crate::emit::reapproach::{Reapproach, linuxcnc_outputs_off, linuxcnc_reapproach};
use crate::link::journal::{self, Journal};
use crate::link::modal::{self, LineKind, Tracker};
use crate::link::stream::{Control, Outcome, Progress, Report};
use crate::link::{AxisPos, LinkError, MachineState, Status, axis_index};
use crate::machine::DialectPost;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Where the program file goes: written at `local`, opened by the controller as `remote`.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    pub local: PathBuf,
    pub remote: String,
}

impl Placement {
    /// `file_name` in `dir` (default: `lase-linuxcnc` in the temporary directory), named to
    /// the controller in `remote_dir` (default: the same folder).
    pub fn new(dir: Option<&Path>, remote_dir: Option<&str>, file_name: &str) -> Placement {
        let dir = dir
            .map(Path::to_path_buf)
            .unwrap_or_else(|| std::env::temp_dir().join("lase-linuxcnc"));
        let local = dir.join(file_name);
        let remote = match remote_dir {
            Some(r) => format!("{}/{file_name}", r.trim_end_matches('/')),
            None => local.display().to_string(),
        };
        Placement { local, remote }
    }

    /// Writes the program (one line per NC line, so LinuxCNC's line N is the job's line
    /// N − 1), readable by the controller's user.
    pub fn write(&self, lines: &[String]) -> Result<(), LinkError> {
        let fail = |e: std::io::Error| {
            LinkError::NotReady {
            reason: format!("cannot write the program to {}: {e}", self.local.display()),
            help: "give a folder lase can write and LinuxCNC can read: linuxcnc://HOST:PORT?dir=LOCAL&remote-dir=ON-CONTROLLER".into(),
        }
        };
        if let Some(d) = self.local.parent() {
            std::fs::create_dir_all(d).map_err(fail)?;
        }
        let mut text = lines.join("\n");
        text.push('\n');
        std::fs::write(&self.local, text).map_err(fail)?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&self.local, std::fs::Permissions::from_mode(0o644));
        }
        Ok(())
    }
}

/// What a LinuxCNC job needs besides the link.
#[derive(Debug, Clone)]
pub struct LinuxCncJob<'a> {
    /// The NC lines (the LinuxCNC dialect), journaled by index.
    pub lines: &'a [String],
    pub placement: Placement,
    /// The machine's axis letters, in its order.
    pub letters: Vec<char>,
    /// The machine's LinuxCNC post (which outputs switch the beam).
    pub post: DialectPost,
    /// How often to poll.
    pub poll: Duration,
}

/// How a resumed job goes on.
#[derive(Debug, Clone, PartialEq)]
pub enum Resumed {
    /// LinuxCNC was still running (or paused in) the program: lase follows it again.
    Reattached { line: u32 },
    /// LinuxCNC had stopped before the end: re-approach, then `set run` from this file line.
    Restarted { line: u32, reapproach: Vec<String> },
    /// The program had ended while the link was down.
    Finished,
}

/// The index of the last line that moves: the program has ended once LinuxCNC reports it (or
/// a later one) at rest.
fn last_motion_line(lines: &[String]) -> usize {
    let kinds = modal::predict(&Tracker::new([0.0; 6]), lines);
    kinds
        .iter()
        .rposition(|(_, k)| matches!(k, LineKind::Motion { .. }))
        .map_or(0, |c| c.saturating_sub(1))
}

/// Where the program leaves the machine (the axes it moves, absolute X…C), against where
/// LinuxCNC reports it: `None` when they agree within 1 µm (linuxcncrsh prints 6 decimals),
/// else both, for the operator.
fn away_from_end(lines: &[String], at: &[f64; 6]) -> Option<String> {
    let kinds = modal::predict(&Tracker::new([0.0; 6]), lines);
    let end = kinds.last()?.0.pos;
    let moved: Vec<usize> = (0..6)
        .filter(|&k| kinds.iter().any(|(t, _)| t.pos[k] != 0.0))
        .collect();
    let off = moved.iter().any(|&k| (at[k] - end[k]).abs() > 1e-3);
    off.then(|| {
        let show = |p: &[f64]| {
            moved
                .iter()
                .map(|&k| format!("{}{:.4}", crate::link::AXIS_LETTERS[k], p[k]))
                .collect::<Vec<_>>()
                .join(" ")
        };
        format!(
            "the machine stands at {}, the program ends at {}",
            show(at),
            show(&end)
        )
    })
}

/// The progress of a job at a poll, in the shared stream's terms.
fn progress(st: &RunStatus, total: usize, done: usize, held: bool) -> Progress {
    let state = match st.program {
        ProgramStatus::Idle => MachineState::Idle,
        ProgramStatus::Running => MachineState::Run,
        ProgramStatus::Paused => MachineState::Hold { complete: true },
    };
    Progress {
        acked: done,
        sent: total,
        total,
        // LinuxCNC runs the program as a file; lase settles no row starts there.
        settled: (0, 0),
        status: Some(Status {
            state,
            mpos: Some(st.abs_pos.to_vec()),
            wpos: Some(st.abs_pos.to_vec()),
            line: Some(st.line),
            ..Status::default()
        }),
        held,
    }
}

/// A new job's journal header, from the controller's position at the start.
pub fn header(recipe: &str, link: &str, lines: &[String], start: AxisPos) -> journal::Header {
    journal::Header {
        recipe: recipe.to_string(),
        link: link.to_string(),
        dialect: "linuxcnc".into(),
        lines: lines.len(),
        hash: journal::program_hash(lines.iter().map(String::as_str)),
        start,
    }
}

/// Writes the program, puts LinuxCNC in AUTO, opens the file and runs it from its first line
/// (or from `from_line`, 1-based, when resuming).
pub fn start(
    rsh: &mut Rsh,
    job: &LinuxCncJob<'_>,
    from_line: Option<u32>,
) -> Result<(), LinkError> {
    job.placement.write(job.lines)?;
    rsh.start_auto()?;
    // Errors left from before are not this job's.
    rsh.errors()?;
    rsh.set(&format!("open {}", job.placement.remote))?;
    if let Some(e) = rsh.errors()?.into_iter().next() {
        return Err(refused_program(job, e));
    }
    match from_line {
        Some(l) => rsh.set(&format!("run {l}")),
        None => rsh.set("run"),
    }
}

fn refused_program(job: &LinuxCncJob<'_>, message: String) -> LinkError {
    LinkError::NotReady {
        reason: format!("LinuxCNC could not run {}: {message}", job.placement.remote),
        help: "the program must be a file LinuxCNC can read at that path: on another computer, share the folder and give linuxcnc://HOST:PORT?dir=LOCAL&remote-dir=ON-CONTROLLER".into(),
    }
}

/// Follows a started job until LinuxCNC is idle again: journals each line it has passed,
/// hands every poll to `observer` (which may hold, resume or abort), and says how it ended.
///
/// Every wait ends: each reply within the session's reply timeout ([`Rsh::reply_timeout`]),
/// else the job ends `Lost` with what was waited for. A LinuxCNC whose task (milltask) has
/// died keeps answering `get` from its last status, a program RUNNING forever: when a running
/// program's status has not changed for the reply timeout (a long `G4` or an `M66` wait can
/// do that too), lase asks whether the task still takes commands ([`Rsh::probe_task`]); one
/// that does not ends the job `Lost` as well, where it would otherwise be followed forever.
pub fn follow(
    rsh: &mut Rsh,
    job: &LinuxCncJob<'_>,
    mut journal: Option<&mut Journal>,
    observer: &mut dyn FnMut(&Progress) -> Option<Control>,
) -> Report {
    let t0 = Instant::now();
    let total = job.lines.len();
    let mut done = 0usize;
    let mut held = false;
    let mut seen_running = false;
    let mut last_sync = Instant::now();
    // The last status that changed, and since when it has stood still.
    let mut last_seen: Option<RunStatus> = None;
    let mut still_since = Instant::now();
    let report = |outcome, done, note: Option<String>| Report {
        outcome,
        acked: done,
        sent: total,
        program_bytes: job.lines.iter().map(|l| l.len() as u64 + 1).sum(),
        elapsed: t0.elapsed(),
        stop_note: note,
        settled: Vec::new(),
    };
    let lost = |e: LinkError| match e {
        LinkError::Lost { .. } | LinkError::Timeout { .. } => Outcome::Lost(e),
        e => Outcome::Failed(e),
    };
    loop {
        let st = match rsh.status() {
            Ok(s) => s,
            Err(e) => return report(lost(e), done, None),
        };
        match rsh.errors() {
            Ok(errs) if !errs.is_empty() => {
                let e = refused_program(job, errs.join("; "));
                if let Some(j) = journal.as_deref_mut() {
                    let _ = j.finish("error linuxcnc");
                }
                return report(Outcome::Failed(e), done, None);
            }
            Ok(_) => {}
            Err(e) => return report(lost(e), done, None),
        }
        seen_running |= st.program != ProgramStatus::Idle;
        if last_seen.as_ref() != Some(&st) {
            last_seen = Some(st.clone());
            still_since = Instant::now();
        } else if st.program == ProgramStatus::Running
            && still_since.elapsed() >= rsh.reply_timeout()
        {
            let still = still_since.elapsed().as_secs_f64();
            if let Err(e) = rsh.probe_task() {
                let e = match e {
                    LinkError::Timeout { seconds, .. } => LinkError::Timeout {
                        waiting_for: format!(
                            "LinuxCNC reported its program RUNNING at line {} with nothing moving for {still:.1} s, and lase waited for its task to take `{}` (its task, milltask, has likely stopped)",
                            st.line,
                            rsh.last_sent()
                        ),
                        seconds,
                    },
                    e => e,
                };
                if let Some(j) = journal.as_deref_mut() {
                    let _ = j.sync();
                }
                return report(lost(e), done, None);
            }
            still_since = Instant::now();
        }
        if st.program == ProgramStatus::Idle
            && (seen_running || t0.elapsed() > Duration::from_secs(2))
        {
            // Idle after running: the end, unless E-stop, a machine off or an abort stopped
            // it. An idle LinuxCNC reports the line its interpreter read last, not the last
            // that moved, and a program its task aborted without a message (a motion command
            // not acknowledged within `[EMCMOT]COMM_TIMEOUT`) ends idle too, with every line
            // read: only where the machine stands tells that the program ran to its end.
            let stopped = matches!(rsh.get("estop").as_deref(), Ok("ON"))
                || matches!(rsh.get("machine").as_deref(), Ok("OFF"));
            let short = (st.line as usize) < last_motion_line(job.lines) + 1;
            let away = away_from_end(job.lines, &st.abs_pos);
            if stopped || short || away.is_some() {
                let e = LinkError::NotReady {
                    reason: match away {
                        Some(where_) if !stopped && !short => format!(
                            "LinuxCNC ended the program without reaching its end: {where_}"
                        ),
                        _ => format!("LinuxCNC stopped the program at line {}", st.line),
                    },
                    help: "E-stop, machine off, an abort from another client, or LinuxCNC's task aborting silently (its motion did not answer within [EMCMOT]COMM_TIMEOUT); check the part, then resume with `lase run --resume`".into(),
                };
                if let Some(j) = journal.as_deref_mut() {
                    let _ = j.sync();
                }
                return report(Outcome::Failed(e), done, None);
            }
            if let Some(j) = journal.as_deref_mut() {
                for i in done..total {
                    j.acked(i);
                }
                let _ = j.finish("done");
            }
            return report(Outcome::Done, total, None);
        }
        // Line L (1-based) is running: the lines before it have run.
        let passed = (st.line as usize).saturating_sub(1).min(total);
        if passed > done {
            if let Some(j) = journal.as_deref_mut() {
                for i in done..passed {
                    j.acked(i);
                }
                if last_sync.elapsed() > Duration::from_millis(500) {
                    let _ = j.sync();
                    last_sync = Instant::now();
                }
            }
            done = passed;
        }
        let p = progress(&st, total, done, held);
        let control = observer(&p);
        let result = match control {
            Some(Control::Hold) if !held => rsh.set("pause").map(|_| held = true),
            Some(Control::Resume) if held => rsh.set("resume").map(|_| held = false),
            Some(Control::Abort) => {
                let note = abort(rsh, job);
                if let Some(j) = journal.as_deref_mut() {
                    let _ = j.finish("abort");
                }
                return report(Outcome::Aborted, done, Some(note));
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            return report(lost(e), done, None);
        }
        std::thread::sleep(job.poll);
    }
}

/// `set abort`, then the beam's outputs off at once (an abort stops motion; synchronized
/// outputs would wait for a move that never comes). Returns what it did, for the operator.
fn abort(rsh: &mut Rsh, job: &LinuxCncJob<'_>) -> String {
    let mut note = vec!["set abort".to_string()];
    if let Err(e) = rsh.set("abort") {
        return format!("set abort failed: {e}");
    }
    let _ = rsh.wait_idle(Duration::from_secs(10));
    let off = linuxcnc_outputs_off(&job.post);
    if rsh.set("mode mdi").is_ok() {
        for l in &off {
            match rsh.mdi(l) {
                Ok(()) => note.push(l.clone()),
                Err(e) => note.push(format!("{l} failed: {e}")),
            }
        }
        let _ = rsh.set("mode auto");
    }
    note.join(", ")
}

/// After a lost link: asks LinuxCNC where the job stands and goes on (see the module's
/// comment). `state` is the journal read back; `journal` appends to it.
pub fn resume(
    rsh: &mut Rsh,
    job: &LinuxCncJob<'_>,
    state: &journal::State,
    journal: Option<&mut Journal>,
) -> Result<Resumed, LinkError> {
    if state.header.hash != journal::program_hash(job.lines.iter().map(String::as_str)) {
        return Err(LinkError::Resume {
            reason: "the recipe's program is not the one the journal recorded".into(),
            help: "resume with the recipe and machine file the job started with".into(),
        });
    }
    let st = rsh.status()?;
    if st.program != ProgramStatus::Idle {
        return Ok(Resumed::Reattached { line: st.line });
    }
    let last = last_motion_line(job.lines);
    // The journal knows what surely ran. An idle LinuxCNC's line is the one its interpreter
    // read last, which runs ahead of motion: it says the program ended only when the machine
    // also stands where the program ends.
    let ended = (st.line as usize) > last && away_from_end(job.lines, &st.abs_pos).is_none();
    let from = if ended { last + 1 } else { state.acked };
    if from > last {
        if let Some(j) = journal {
            j.finish("done")?;
        }
        return Ok(Resumed::Finished);
    }
    let ra = reapproach(job, state.header.start, from);
    rsh.start_auto()?;
    rsh.set("mode mdi")?;
    for l in &ra.setup {
        rsh.mdi(l)?;
    }
    // The beam's synchronized outputs, queued to switch with the first move of the run.
    for l in &ra.lead {
        rsh.set(&format!("mdi {l}"))?;
    }
    if let Some(j) = journal {
        j.resumed(from, &ra.all())?;
    }
    let line = from as u32 + 1;
    start(rsh, job, Some(line))?;
    Ok(Resumed::Restarted {
        line,
        reapproach: ra.all(),
    })
}

/// The re-approach to where line `from` starts, with the beam's outputs of that point: the
/// program's own last `M62`/`M63 Pn` and `M67 En` lines before it, when they leave an output
/// on.
fn reapproach(job: &LinuxCncJob<'_>, start: AxisPos, from: usize) -> Reapproach {
    let predicted = modal::predict(&Tracker::new(start), &job.lines[..from]);
    let pos = predicted.last().map(|(t, _)| t.pos).unwrap_or(start);
    let position: Vec<f64> = job
        .letters
        .iter()
        .map(|&l| axis_index(l).map_or(0.0, |i| pos[i]))
        .collect();
    let mut outputs: Vec<(String, String)> = Vec::new();
    for line in &job.lines[..from] {
        let words: Vec<&str> = line.split_whitespace().collect();
        for (k, w) in words.iter().enumerate() {
            let arg = words.get(k + 1).copied().unwrap_or("");
            let on = match *w {
                "M62" | "M64" => true,
                "M63" | "M65" => false,
                "M67" | "M68" => words
                    .get(k + 2)
                    .and_then(|q| q.strip_prefix('Q'))
                    .and_then(|q| q.parse::<f64>().ok())
                    .is_some_and(|q| q > 0.0),
                _ => continue,
            };
            outputs.retain(|(o, _)| o != arg);
            if on {
                outputs.push((arg.to_string(), line.clone()));
            }
        }
    }
    let lead = outputs.into_iter().map(|(_, l)| l).collect();
    linuxcnc_reapproach(&job.post, &job.letters, &position, lead)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn post() -> DialectPost {
        let m =
            crate::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
        m.post["linuxcnc"].clone()
    }

    #[test]
    fn a_reapproach_mid_section_rearms_the_beam_with_the_programs_own_lines() {
        let lines: Vec<String> = [
            "G21 G90 G17 G94",
            "G0 X-1 Y0",
            "G1 X0 Y0 F1200",
            "M67 E0 Q40",
            "M62 P0",
            "G1 X10",
            "G1 Y10",
            "M63 P0",
            "G0 X0 Y0",
            "M2",
        ]
        .map(String::from)
        .to_vec();
        let job = LinuxCncJob {
            lines: &lines,
            placement: Placement::new(Some(Path::new("/tmp")), None, "t.ngc"),
            letters: vec!['X', 'Y'],
            post: post(),
            poll: Duration::from_millis(10),
        };
        // Line index 6 (`G1 Y10`) starts at X10 Y0 with the beam on at 40 %.
        let ra = reapproach(&job, [0.0; 6], 6);
        assert_eq!(
            ra.setup,
            ["M65 P0", "M65 P1", "M68 E0 Q0", "G21 G90 G94", "G0 X10 Y0"]
        );
        assert_eq!(ra.lead, ["M67 E0 Q40", "M62 P0"]);
        // After the section the gate stays off; the power output keeps the program's level.
        assert_eq!(reapproach(&job, [0.0; 6], 8).lead, ["M67 E0 Q40"]);
        assert_eq!(last_motion_line(&lines), 8);
        assert_eq!(
            job.placement.remote, "/tmp/t.ngc",
            "the same folder when none is named for the controller"
        );
        let p = Placement::new(Some(Path::new("/mnt/cnc")), Some("/home/cnc/nc/"), "a.ngc");
        assert_eq!(p.remote, "/home/cnc/nc/a.ngc");
    }

    /// An idle LinuxCNC ended the program only where the program ends: run8 of the
    /// COMM_TIMEOUT hunt reported `PROGRAM_LINE 913` (the last line, read ahead) with the
    /// table at X2.3 of a dot row; that is a stop, not the end.
    #[test]
    fn the_end_is_where_the_program_leaves_the_machine() {
        let lines: Vec<String> = ["G21 G90", "G1 X2.3 F1200", "G1 X10 Y5", "G0 X0 Y0", "M2"]
            .iter()
            .map(|l| l.to_string())
            .collect();
        assert_eq!(away_from_end(&lines, &[0.0; 6]), None);
        assert_eq!(
            away_from_end(&lines, &[0.0004, 0.0, 7.0, 0.0, 0.0, 0.0]),
            None
        );
        let stopped = away_from_end(&lines, &[2.3, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(
            stopped,
            "the machine stands at X2.3000 Y0.0000, the program ends at X0.0000 Y0.0000"
        );
    }
}
