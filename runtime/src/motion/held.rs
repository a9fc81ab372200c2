//! Whether the plan holds the programmed surface speed inside every lit section of a machine
//! that orients the beam (issue 13 item 5).
//!
//! On such a machine the surface speed is the process (PROCESS.md §1: the energy per length).
//! Where a joint's rate must change faster than its acceleration allows at that speed — a cam
//! law whose acceleration jumps turns the beam's rate in a step — the planner slows the whole
//! path there, and the beam would harden that stretch at a lower speed than the recipe says.
//! That is refused here, after planning, from the plan itself (whatever rule made the planner
//! slow down): the first stretch of a lit section where the planned speed falls below the
//! programmed one by more than 0.1 % is named by its arc length along the section, with the
//! highest speed the plan holds there.
//!
//! `plan_program` plans an oriented job with every lit corner blended first; where that dips
//! (the chords of a lit curve blended one by one), it plans again with the velocity step
//! between lit chords (`planner::Along::step_corners`) and judges that plan.
//!
//! The ramps at a section's ends are not dips: with lead-ins (the default) the section is
//! entered and left at the programmed speed; with `planner { leadin none }` the recipe has
//! accepted that the beam comes on during the ramp, and only what lies between the first and
//! the last point at the programmed speed is judged.

use super::{Job, LitSection, MotionError};
use lase_lang::Span;
use lase_lang::units::{Dim, format_quantity};

/// How far below the programmed speed a lit stretch may be planned (the surface-speed
/// tolerance of issue 13): 0.1 %.
pub const HELD_REL: f64 = 1e-3;

/// A lit stretch the plan runs too slowly.
#[derive(Debug, Clone, PartialEq)]
pub struct Shortfall {
    /// Arc length from the section's first lit point where the dip starts and ends, mm.
    pub from_mm: f64,
    pub to_mm: f64,
    /// The highest speed the plan holds over that stretch, mm/s.
    pub held_mm_s: f64,
    pub feed_mm_s: f64,
    /// Further stretches of the same section that dip too.
    pub more: usize,
}

/// The first lit section of an oriented job whose planned speed dips, as a diagnostic at the
/// recipe statement that made it.
pub fn check_held(job: &Job) -> Result<(), MotionError> {
    if !job.kin.oriented() {
        // On a flat bed a lit path slows at its corners by design (their blends' limits;
        // coupled power and pulses by distance follow the planned speed).
        return Ok(());
    }
    for section in &job.sections {
        if let Some(short) = shortfall(job, section) {
            let span: Span = job.program.ops[section.first_op as usize].span;
            // Hundredths of a mm place the stretch; the held speed is rounded down, so that a
            // recipe that follows at it is held.
            let len = |x: f64| format_quantity((x * 100.0).round() / 100.0, Dim::LENGTH);
            let speed = |x: f64| format_quantity(x, Dim::SPEED);
            // On LinuxCNC the blocks of the whole section must also be long enough for its
            // parabolic blends (`parabolic`): offer the lower of the two speeds, so that the
            // recipe is not refused again at the one offered.
            let plan_offer = floor3(short.held_mm_s);
            let offer = match super::parabolic::linuxcnc_section_limit(job, section) {
                Some(l) if floor3(l) < plan_offer => floor3(l),
                _ => plan_offer,
            };
            let linuxcnc_binds = offer < plan_offer;
            return Err(MotionError::SpeedNotHeld {
                feed: speed(short.feed_mm_s),
                stretch: format!(
                    "between {} and {} along this lit path it runs at {} at most{}",
                    len(short.from_mm),
                    len(short.to_mm),
                    speed(floor3(short.held_mm_s)),
                    if short.more == 0 {
                        String::new()
                    } else {
                        format!(" (and {} more stretches further on)", short.more)
                    }
                ),
                span,
                help: format!(
                    "follow at {} or slower{}, or make the path smoother there (a cam law whose \
                     acceleration does not jump, such as \"cycloidal\" or \"345\")",
                    speed(offer),
                    if linuxcnc_binds {
                        " (LinuxCNC's parabolic blends hold no more on this path's shortest \
                         blocks)"
                    } else {
                        ""
                    }
                ),
            });
        }
    }
    Ok(())
}

/// `v` rounded down to three significant digits: a speed the message can promise.
pub(super) fn floor3(v: f64) -> f64 {
    if !(v > 0.0 && v.is_finite()) {
        return 0.0;
    }
    let scale = 10f64.powi(2 - v.log10().floor() as i32);
    (v * scale).floor() / scale
}

/// The planned speeds at the junctions of `section`'s lit moves, with the dips found.
pub fn shortfall(job: &Job, section: &LitSection) -> Option<Shortfall> {
    let segs: Vec<_> = job
        .plan
        .segments()
        .iter()
        .filter(|s| (section.first_op..=section.last_op).contains(&s.tag) && s.length > 0.0)
        .collect();
    let first = segs.first()?;
    let feed = first.feed;
    if !feed.is_finite() {
        return None;
    }
    let ok = feed * (1.0 - HELD_REL);
    // The speed at every junction point (and each move's peak between two of them), with the
    // arc length from the section start.
    let s0 = first.s_start;
    let mut points: Vec<(f64, f64)> = Vec::with_capacity(2 * segs.len() + 1);
    points.push((0.0, first.v_entry));
    for s in &segs {
        points.push((s.s_start - s0 + 0.5 * s.length, s.v_peak));
        points.push((s.s_start - s0 + s.length, s.v_exit));
    }
    let reach_first = points.iter().position(|p| p.1 >= ok);
    let Some(a) = reach_first else {
        // Never at speed: the whole section is short of it.
        let held = points.iter().map(|p| p.1).fold(0.0, f64::max);
        let end = points.last().map_or(0.0, |p| p.0);
        return Some(Shortfall {
            from_mm: 0.0,
            to_mm: end,
            held_mm_s: held,
            feed_mm_s: feed,
            more: 0,
        });
    };
    let b = points.iter().rposition(|p| p.1 >= ok).unwrap_or(a);
    let mut dips: Vec<Shortfall> = Vec::new();
    let mut i = a;
    while i < b {
        if points[i + 1].1 >= ok {
            i += 1;
            continue;
        }
        // A dip from the last point at speed (i) to the next one at speed (j).
        let mut j = i + 1;
        let mut held = f64::INFINITY;
        while j < b && points[j].1 < ok {
            held = held.min(points[j].1);
            j += 1;
        }
        dips.push(Shortfall {
            from_mm: points[i].0,
            to_mm: points[j].0,
            held_mm_s: held,
            feed_mm_s: feed,
            more: 0,
        });
        i = j;
    }
    let more = dips.len().saturating_sub(1);
    dips.into_iter().next().map(|d| Shortfall { more, ..d })
}
