//! Row-start settling over a live link (issue 15, PROCESS.md §3): before a row of
//! `scan … { settle }` fires, the table stops at the row's start, its position is read from
//! the controller's status report, and corrective jog steps are sent until the reading is
//! within the recipe's window — counted from the programmed position, so errors never
//! accumulate from row to row.
//!
//! The position is the status report's `MPos` (less the work offset): on a controller whose
//! position comes from the motors (GRBL, grblHAL without encoders) that is where the steps
//! say the table is, and settling converges at once; only a controller that reports feedback
//! (a linear scale) makes the loop close on the real table, which is what the simulator's
//! `--position-error` models.
//!
//! The corrections are jogs (`Link::jog_line`, GRBL's `$J=G91 …`): a jog does not touch the
//! parser's modal state (G90/G91, feed, motion mode) that the rest of the program relies on.
//! Waiting for the stop: every streamed line acknowledged and the status report Idle — GRBL
//! answers a motion line when it is buffered, so only Idle says the approach has ended.

use super::{Link, LinkError, MachineState, Status};
use crate::motion::Job;
use crate::program::Settle;
use std::time::{Duration, Instant};

/// Jog feed of a corrective step, mm/min: slow, since a step is a fraction of a micrometre.
pub const STEP_FEED_MM_MIN: f64 = 60.0;

/// How far a settle backs off against the row's direction and comes forward again, so the
/// play (backlash up to this much) is taken up the way the row will run, mm.
pub const PRELOAD_MM: f64 = 0.005;

/// The resolution of a reported position, mm: GRBL and grblHAL report millimetres to three
/// decimals (`$13=0`, which the preflight requires), so a 1 µm scale's count.
pub const REPORT_RESOLUTION_MM: f64 = 0.001;

/// The pause before each status report while settling.
const POLL: Duration = Duration::from_millis(10);

/// How long one status report may take while settling.
const STATUS_WAIT: Duration = Duration::from_secs(2);

/// A row start to settle in a job's line stream.
#[derive(Debug, Clone, PartialEq)]
pub struct SettlePoint {
    /// Settle once this line (0-based in the job) is done, before the next one is sent.
    pub after: usize,
    /// Where the table should be, controller X and Y in work coordinates, mm.
    pub target: [f64; 2],
    pub settle: Settle,
}

/// How one row start settled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settled {
    pub pass: u32,
    pub row: u32,
    /// The error before the first step and the final one, (along, across), mm.
    pub first: (f64, f64),
    pub last: (f64, f64),
    pub steps: u32,
    /// From the first status report at rest (the preload included) to within the window.
    pub seconds: f64,
}

/// The settle points of a job streamed as `nc`: each settle's op ends on the last line that
/// came from an op up to it. Only a table whose controller X and Y are the part's x and y
/// can be settled along and across its rows.
/// `runs` are the job's lines' ops, run-length (`JobLines::runs`: the first line of each run and
/// its op), `len` the number of lines.
pub fn settle_points(
    job: &Job,
    runs: &[(usize, Option<u32>)],
    len: usize,
) -> Result<Vec<SettlePoint>, LinkError> {
    let settles = &job.program.settles;
    if settles.is_empty() {
        return Ok(Vec::new());
    }
    let axes = super::ControllerAxes::of(&job.program.machine);
    let letters = axes.letters();
    if job.kin.oriented() || !letters.contains(&'X') || !letters.contains(&'Y') {
        return Err(LinkError::Unsettled {
            message: format!(
                "row-start settling needs a table whose X and Y are the part's x and y; `{}` is not one",
                job.program.machine.name
            ),
            span: settles[0].span,
            help: "leave `settle` out on this machine".into(),
        });
    }
    let mut out = Vec::with_capacity(settles.len());
    let mut line = 0usize;
    let mut run = 0usize;
    for s in settles {
        // The first line of a later op; the settle goes before it.
        while run < runs.len() && runs[run].1.is_none_or(|o| (o as usize) <= s.op) {
            run += 1;
        }
        line = line.max(runs.get(run).map_or(len, |r| r.0));
        let p = axes.to_controller(&job.op_axes.get(s.op));
        out.push(SettlePoint {
            after: line.saturating_sub(1),
            target: [p[0], p[1]],
            settle: s.clone(),
        });
    }
    Ok(out)
}

/// Settles one row start: waits for the table to stop, then reads, steps and reads again
/// until the reading is within the window. Every streamed line must be acknowledged before.
/// `last_wco` is the work offset last reported (GRBL sends `WCO:` only now and then).
pub fn settle(
    link: &mut dyn Link,
    p: &SettlePoint,
    last_wco: &mut Option<Vec<f64>>,
) -> Result<Settled, LinkError> {
    let s = &p.settle;
    let read_window = read_window(s);
    let start = Instant::now();
    let timeout = Duration::from_secs_f64(s.timeout_s);
    let fail = |message: String, help: &str| LinkError::Unsettled {
        message,
        span: s.span,
        help: help.into(),
    };
    let mut steps = 0u32;
    let mut first = None;
    let mut at_rest: Option<Instant> = None;
    loop {
        if start.elapsed() > timeout {
            return Err(fail(
                format!(
                    "row {} of pass {} did not settle within {} s ({steps} steps)",
                    s.row + 1,
                    s.pass + 1,
                    s.timeout_s
                ),
                "the table did not stop, or the steps do not move it: check the axis, or give a longer `settle_timeout`",
            ));
        }
        // A pause before each report: a jog just sent may not have started yet (the
        // simulator at `time-scale=max` runs what is buffered once the client is quiet), and
        // a controller asked without pause is only kept busy answering.
        std::thread::sleep(POLL);
        let st = link.query_status(STATUS_WAIT)?;
        if st.wco.is_some() {
            *last_wco = st.wco.clone();
        }
        match st.state {
            MachineState::Idle => {}
            MachineState::Run | MachineState::Jog => continue,
            other => {
                return Err(fail(
                    format!(
                        "the controller went {} while settling row {} of pass {}",
                        other.name(),
                        s.row + 1,
                        s.pass + 1
                    ),
                    "clear the controller's state, then resume the job",
                ));
            }
        }
        if at_rest.is_none() {
            // Take up the play in the row's direction before the first reading: the row runs
            // up that way, and a table that still had to take it up would lose it there.
            at_rest = Some(Instant::now());
            jog(link, s, -PRELOAD_MM, 0.0)?;
            jog(link, s, PRELOAD_MM, 0.0)?;
            continue;
        }
        let at = at_rest.unwrap_or_else(Instant::now);
        let (along, across) = error_of(&st, p, last_wco.as_deref())?;
        let first = *first.get_or_insert((along, across));
        if read_window.correction(along, across).is_none() {
            return Ok(Settled {
                pass: s.pass,
                row: s.row,
                first,
                last: (along, across),
                steps,
                seconds: at.elapsed().as_secs_f64(),
            });
        };
        if steps >= s.max_steps {
            return Err(fail(
                format!(
                    "row {} of pass {} is still {:+.1} µm along and {:+.1} µm across its start after {steps} steps",
                    s.row + 1,
                    s.pass + 1,
                    along * 1e3,
                    across * 1e3
                ),
                "the table does not follow the steps (backlash larger than the steps allow?): allow more `settle_steps`, or check the axis",
            ));
        }
        // One step toward the window; a step back along the row overshoots by the preload
        // and comes forward again, so the play stays taken up in the row's direction.
        let c = if across < -s.across_mm {
            s.step_mm
        } else if across > s.across_mm {
            -s.step_mm
        } else {
            0.0
        };
        if along > read_window.window_mm.1 {
            jog(link, s, -(s.step_mm + PRELOAD_MM), c)?;
            jog(link, s, PRELOAD_MM, 0.0)?;
        } else {
            let a = if along < read_window.window_mm.0 {
                s.step_mm
            } else {
                0.0
            };
            jog(link, s, a, c)?;
        }
        steps += 1;
    }
}

/// The window along the row the reported position must be in: the recipe's, narrowed by half
/// the report's resolution at each end. A reading of a 1 µm scale stands for every position within
/// ±0.5 µm of it, and a row start off the scale's grid (a lead-in start at −535.535 µm) would
/// otherwise be accepted at a reading whose table may be up to 0.5 µm past the window —
/// where its first pulse then fires. Where that leaves less than a step, the recipe's own
/// window (the steps could not find the narrower one). Across, the recipe's window is the
/// reading's: the seed states none, and a row's error across does not move its spots along.
fn read_window(s: &Settle) -> Settle {
    let h = 0.5 * REPORT_RESOLUTION_MM;
    let narrowed = Settle {
        window_mm: (s.window_mm.0 + h, s.window_mm.1 - h),
        ..s.clone()
    };
    if narrowed.window_mm.1 - narrowed.window_mm.0 + 1e-12 >= s.step_mm {
        narrowed
    } else {
        s.clone()
    }
}

/// Jogs `along` and `across` the row, mm.
fn jog(link: &mut dyn Link, s: &Settle, along: f64, across: f64) -> Result<(), LinkError> {
    let [ux, uy] = s.dir;
    let (dx, dy) = (along * ux - across * uy, along * uy + across * ux);
    let line = link
        .jog_line(dx, dy, STEP_FEED_MM_MIN)
        .ok_or_else(|| LinkError::Unsettled {
            message: format!(
                "{} cannot jog: row-start settling needs a jog command",
                link.describe()
            ),
            span: s.span,
            help: "leave `settle` out for this controller".into(),
        })?;
    super::reply_error(&line, link.send(&line)?)
}

/// The error (along, across) of the reported position from the target, mm.
fn error_of(st: &Status, p: &SettlePoint, wco: Option<&[f64]>) -> Result<(f64, f64), LinkError> {
    let pos = st
        .work_position(wco)
        .filter(|v| v.len() >= 2)
        .ok_or_else(|| LinkError::Unsettled {
            message: "the controller's status report has no position to settle on".into(),
            span: p.settle.span,
            help: "the status report must carry MPos or WPos ($10)".into(),
        })?;
    Ok(p.settle.error(pos[0] - p.target[0], pos[1] - p.target[1]))
}

/// Per-row statistics of a job's settling, for the end-of-job summary.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettleSummary {
    pub rows: usize,
    pub steps: u64,
    /// The largest |final error| along and across, and the mean |final error| along, mm.
    pub worst_along: f64,
    pub worst_across: f64,
    pub mean_along: f64,
    /// The largest |error| along before settling, mm.
    pub worst_first_along: f64,
    pub mean_seconds: f64,
}

impl SettleSummary {
    pub fn of(rows: &[Settled]) -> Option<SettleSummary> {
        if rows.is_empty() {
            return None;
        }
        let n = rows.len() as f64;
        let max = |f: &dyn Fn(&Settled) -> f64| rows.iter().map(f).fold(0.0, f64::max);
        Some(SettleSummary {
            rows: rows.len(),
            steps: rows.iter().map(|r| u64::from(r.steps)).sum(),
            worst_along: max(&|r| r.last.0.abs()),
            worst_across: max(&|r| r.last.1.abs()),
            mean_along: rows.iter().map(|r| r.last.0.abs()).sum::<f64>() / n,
            worst_first_along: max(&|r| r.first.0.abs()),
            mean_seconds: rows.iter().map(|r| r.seconds).sum::<f64>() / n,
        })
    }
}

impl std::fmt::Display for SettleSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} row starts settled with {} steps: final error along worst {:.1} µm, mean {:.2} µm; across worst {:.1} µm (before settling: worst {:.1} µm along); {:.3} s per row",
            self.rows,
            self.steps,
            self.worst_along * 1e3,
            self.mean_along * 1e3,
            self.worst_across * 1e3,
            self.worst_first_along * 1e3,
            self.mean_seconds
        )
    }
}
