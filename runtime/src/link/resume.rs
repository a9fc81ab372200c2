//! Continuing a job whose link dropped: find the last line the controller executed, then a
//! safe re-approach.
//!
//! The journal bounds it: every line below `acked` surely reached the controller, no line at
//! or above `sent_bound` did. A controller keeps executing what it received after the link
//! drops, so once it is idle, the executed count `c` lies in `[acked, sent_bound]` and its
//! state — position and modal state (GRBL `$G`) — is the state predicted after line `c`.
//! Several counts can fit when the lines between them change nothing observable (comments,
//! dwells, repeated modal words). Re-running such lines is harmless, so the smallest count
//! that fits is taken, unless a lit move lies between the fits (a full circle ends where it
//! starts): then it cannot be told whether that cut ran, and lase refuses to guess.
//!
//! The re-approach ([`Link::reapproach`], its lines written by `emit::reapproach`): laser off,
//! millimetres and absolute, a rapid to the resume point, then the modal state after line `c`
//! (units, distance mode, feed mode, plane, coolant, laser power, motion mode with feed).
//! Nothing already executed is sent again.

use super::journal::State;
use super::modal::{self, LineKind, Tracker};
use super::{
    AxisPos, Link, LinkError, MAX_AXES, MachineState, ModalState, MotionMode, Reapproach,
    axis_index,
};
use std::time::{Duration, Instant};

/// How a job continues.
#[derive(Debug, Clone, PartialEq)]
pub struct ResumePlan {
    /// Lines the controller executed: streaming continues with line index `executed`.
    pub executed: usize,
    /// The re-approach: setup lines one at a time, then the lead in a burst with the job.
    pub reapproach: Reapproach,
    /// The modal state the re-approach restores.
    pub restored: ModalState,
    /// Every executed count that fitted the controller's state.
    pub candidates: Vec<usize>,
}

/// Position tolerance when matching: GRBL reports 3 decimals, lase writes 4.
const POS_TOL: f64 = 0.0015;

/// Motion modes as a resume can compare them: a re-approach restores G2/G3 as G1 (a GRBL
/// controller cannot be put in an arc mode without an arc), so the feed modes count as one.
fn same_motion(a: MotionMode, b: MotionMode) -> bool {
    let feed = |m| {
        matches!(
            m,
            MotionMode::Linear | MotionMode::ArcCw | MotionMode::ArcCcw
        )
    };
    a == b || (feed(a) && feed(b))
}

fn fits(pred: &Tracker, pos: &[f64], m: &ModalState) -> bool {
    let s = &pred.state;
    let pos_ok =
        (0..MAX_AXES).all(|i| (pred.pos[i] - pos.get(i).copied().unwrap_or(0.0)).abs() <= POS_TOL);
    // GRBL prints F and S without decimals.
    let feed_ok = s.inverse_time || (s.feed - m.feed).abs() <= 0.5 + 1e-9 * s.feed.abs();
    pos_ok
        && feed_ok
        && (s.s - m.s).abs() <= 0.5 + 1e-9 * s.s.abs()
        && same_motion(s.motion, m.motion)
        && s.plane == m.plane
        && s.inches == m.inches
        && s.incremental == m.incremental
        && s.inverse_time == m.inverse_time
        && s.spindle == m.spindle
        && s.flood == m.flood
        && s.mist == m.mist
}

/// Waits until the controller is idle (it may still be running what it received), then
/// works out where the job stands.
///
/// `letters` are the machine's axis letters (for the re-approach); `resume_at` forces the
/// executed count after an operator has checked the part.
pub fn plan(
    link: &mut dyn Link,
    lines: &[String],
    journal: &State,
    letters: &[char],
    resume_at: Option<usize>,
    wait: Duration,
) -> Result<ResumePlan, LinkError> {
    let deadline = Instant::now() + wait;
    let status = loop {
        let s = link.query_status(Duration::from_secs(2))?;
        match s.state {
            MachineState::Idle => break s,
            MachineState::Run | MachineState::Hold { complete: false } | MachineState::Jog
                if Instant::now() < deadline =>
            {
                std::thread::sleep(Duration::from_millis(100));
            }
            other => {
                return Err(LinkError::NotReady {
                    reason: format!("the controller is in {} rather than idle", other.name()),
                    help: match other {
                        MachineState::Alarm => "an alarm may have lost the position: check the machine, clear the alarm (`$X` or homing) and only resume if the position is right".into(),
                        MachineState::Hold { .. } => "someone holds the job: resume it on the controller (`~`) and let it finish its buffer, then resume".into(),
                        _ => "bring the controller to idle, then resume".into(),
                    },
                });
            }
        }
    };
    let pos = status
        .work_position(status.wco.as_deref())
        .ok_or_else(|| LinkError::Protocol {
            text: status.summary(),
            reason: "no position in the status report".into(),
        })?;
    let observed = link.modal_state()?;
    let start = Tracker::new(journal.header.start);
    let lo = journal.acked.min(lines.len());
    let hi = journal.sent_bound.clamp(lo, lines.len());
    let predicted = modal::predict(&start, &lines[..hi]);
    let mut candidates: Vec<usize> = (lo..=hi)
        .filter(|&c| fits(&predicted[c].0, &pos, &observed))
        .collect();
    // The link dropped during the previous re-approach: its lines changed the modal state,
    // but no job line ran since. The re-approach starts again (it is idempotent, laser off
    // first), if the machine stands where it leads.
    if candidates.is_empty()
        && let Some(&c) = journal.resumes.last()
        && journal.acked == c
        && c <= hi
        && (0..3)
            .all(|i| (predicted[c].0.pos[i] - pos.get(i).copied().unwrap_or(0.0)).abs() <= POS_TOL)
    {
        candidates.push(c);
    }
    let executed = match resume_at {
        Some(c) if c <= lines.len() => c,
        Some(c) => {
            return Err(LinkError::Resume {
                reason: format!("--resume-at {c} is past the job's {} lines", lines.len()),
                help: "give the number of lines that ran".into(),
            });
        }
        None => {
            let (Some(&first), Some(&last)) = (candidates.first(), candidates.last()) else {
                let words: Vec<String> = pos.iter().map(|v| format!("{v:.3}")).collect();
                return Err(LinkError::Resume {
                    reason: format!(
                        "the controller is at ({}) in {}, which fits none of lines {lo} to {hi} the journal says may have run",
                        words.join(", "),
                        observed.describe()
                    ),
                    help: "it was reset, re-homed or moved since the link dropped; check the part and run the rest by hand, or give the number of lines that ran with --resume-at".into(),
                });
            };
            if let Some(k) = (first..last)
                .find(|&k| matches!(predicted[k + 1].1, LineKind::Motion { lit: true }))
            {
                return Err(LinkError::Resume {
                    reason: format!(
                        "the controller's state fits both {first} and {last} executed lines, and line {} between them fires the laser: whether it ran cannot be told",
                        k + 1
                    ),
                    help: "look at the part, then resume with --resume-at N, N the number of lines that ran".into(),
                });
            }
            first
        }
    };
    let after = match predicted.get(executed) {
        Some((t, _)) => t.clone(),
        None => {
            let mut t = start.clone();
            for l in &lines[..executed] {
                let _ = t.apply(l);
            }
            t
        }
    };
    let position: Vec<f64> = letters
        .iter()
        .map(|&l| axis_index(l).map_or(0.0, |i| after.pos[i]))
        .collect();
    let reapproach = if executed < lines.len() {
        link.reapproach(&after.state, letters, &position)
    } else {
        Reapproach::default()
    };
    Ok(ResumePlan {
        executed,
        reapproach,
        restored: after.state,
        candidates,
    })
}

/// Starts carrying out `plan` for the job journaled at `journal`: records the resume point and
/// the re-approach in the journal, then sends the re-approach's setup lines one at a time,
/// each answered (its lead lines go out with the job's next lines, [`super::stream`]).
/// Returns the journal, open for the rest of the job.
pub fn enter(
    link: &mut dyn Link,
    plan: &ResumePlan,
    journal: &std::path::Path,
) -> Result<super::journal::Journal, LinkError> {
    let (mut j, _) = super::journal::Journal::append(journal)?;
    j.resumed(plan.executed, &plan.reapproach.all())?;
    for p in &plan.reapproach.setup {
        let reply = link.send(p)?;
        super::reply_error(p, reply)?;
    }
    Ok(j)
}

/// Lines that must wait for acknowledgements before they are sent, so that a resume can
/// always tell how far a job ran: `guards[k] = Some(c)` means line `k` may only be sent once
/// the first `c + 1` lines are acknowledged.
///
/// Why: when the link drops, the controller has executed some count of lines between the
/// acknowledged ones and the sent ones, and the resume recognizes that count by the state it
/// leaves (position, modal state). A closed lit contour ends in the state it started from,
/// and so does a dwell; with both ends in flight, a cut leaves it unknown whether the loop
/// was cut or the dwell waited. So the line that returns to an earlier state (its end state
/// equals the state after line `c`, with a line that does something in between) waits until
/// line `c` is acknowledged: the two states are then never in flight together. Earlier
/// equal states are excluded by induction (the guard of the line that made them equal has
/// already waited). Then two counts a resume cannot tell apart have between them only lines
/// that change nothing (comments, repeated words: re-sending them does nothing) or a single
/// line that returns to its own start state (a dwell, which is re-run; a lit full circle,
/// which the resume refuses to guess about). It costs one round trip per closed contour.
pub fn send_guards(start: &Tracker, lines: &[String]) -> Vec<Option<usize>> {
    use std::collections::HashMap;
    let predicted = modal::predict(start, lines);
    // Twice the matching tolerance: a guard too many costs a round trip, one too few a
    // resume that cannot decide.
    let tol = 2.0 * POS_TOL;
    let cell = 0.01;
    let key = |t: &Tracker| {
        let s = &t.state;
        let motion = match s.motion {
            MotionMode::ArcCw | MotionMode::ArcCcw => MotionMode::Linear,
            m => m,
        };
        format!(
            "{:?}{:?}{}{}{}{:?}{}{}{:.3}{:.3}",
            motion,
            s.plane,
            s.inches,
            s.incremental,
            s.inverse_time,
            s.spindle,
            s.flood,
            s.mist,
            s.feed,
            s.s
        )
    };
    type Cell = (String, [i64; MAX_AXES]);
    let mut buckets: HashMap<Cell, Vec<(usize, AxisPos)>> = HashMap::new();
    let mut guards = vec![None; lines.len()];
    let mut last_lit: Option<usize> = None;
    // Neighbouring cells are searched along the axes the job moves only: 3^m cells for m
    // moving axes (9 on an XY table, 27 on the cam machine, 81 on the arm).
    let moving: Vec<usize> = (0..MAX_AXES)
        .filter(|&i| predicted.iter().any(|(t, _)| t.pos[i] != start.pos[i]))
        .collect();
    let neighbours = 3usize.pow(moving.len() as u32);
    for (c, (t, kind)) in predicted.iter().enumerate() {
        if c > 0 && *kind != LineKind::Nothing {
            last_lit = Some(c - 1);
        }
        let k = key(t);
        let cellpos = t.pos.map(|v| (v / cell).floor() as i64);
        if c > 0
            && let Some(lit) = last_lit
        {
            let mut best: Option<usize> = None;
            let mut cell_key = (k.clone(), cellpos);
            for n in 0..neighbours {
                let mut digits = n;
                for &i in &moving {
                    cell_key.1[i] = cellpos[i] + (digits % 3) as i64 - 1;
                    digits /= 3;
                }
                if let Some(v) = buckets.get(&cell_key)
                    && let Some(&(c1, _)) = v
                        .iter()
                        .rev()
                        .find(|(_, p)| (0..MAX_AXES).all(|i| (p[i] - t.pos[i]).abs() <= tol))
                {
                    best = best.max(Some(c1));
                }
            }
            // A line that by itself returns to the state before it (a dwell, a full circle)
            // cannot be guarded: it is in flight alone, and only a resume can settle it.
            if let Some(c1) = best
                && lit >= c1
                && c1 + 1 < c
            {
                guards[c - 1] = Some(c1);
            }
        }
        buckets.entry((k, cellpos)).or_default().push((c, t.pos));
    }
    guards
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn the_line_closing_a_lit_contour_waits_for_the_start_to_be_acknowledged() {
        let job = lines(&[
            "G21 G90 G94",
            "G1 X0 Y0 F600",
            "M3 S400",
            "X10",
            "Y10",
            "X0",
            "Y0",
            "M5",
            "G4 P1",
            "G0 X20",
        ]);
        let g = send_guards(&Tracker::new([0.0; MAX_AXES]), &job);
        // `Y0` (index 6) closes the square: the state after it equals the state after
        // `M3 S400` (3 lines), so it waits until 4 lines are acknowledged. The dwell returns
        // to its own start state: not guardable, no guard.
        assert_eq!(g[6], Some(3));
        assert_eq!(g.iter().filter(|c| c.is_some()).count(), 1, "{g:?}");
        assert!(g.iter().enumerate().all(|(k, c)| c.is_none_or(|c| c < k)));
    }
}
