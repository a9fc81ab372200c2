//! The ranges a recipe's quantities must lie in, and the work a recipe may ask for.
//!
//! A finite value can still be absurd: a feed of 1e-300 mm/s writes `F0`, a pulse every
//! 1e-12 mm asks for 1e13 pulses, a tolerance of 1e-300 mm cuts an arc into more chords than
//! memory holds. Each quantity here gets the range a machine can carry out, taken from what the
//! controller and the NC text resolve, and each piece of work a budget counted *before* it is
//! generated, so `lase check` refuses the recipe with the number that is out of range, instead
//! of `emit` running for hours or writing a program that means something else.
//!
//! | quantity                                    | range                      | why |
//! |---------------------------------------------|----------------------------|-----|
//! | feed (`at`, `speed`), `limits` `v`          | 1 mm/min … 100 m/s         | grbl's `MINIMUM_FEED_RATE` (1 mm/min) |
//! | `tolerance`, `corner`                       | 0.1 µm … 10 mm             | the NC text's 4 decimals of a mm |
//! | `step`, `spot`, `pitch`, pulse `interval`   | 0.1 µm … 10 m              | the NC text's 4 decimals of a mm |
//! | `dwell`                                     | 0, or 0.1 ms … 1 h         | the NC text's 4 decimals of a second |
//! | pulse `interval` (time), `width`            | 1 fs … 1 h                 | |
//! | pulse `energy`                              | up to 1 kJ                 | |
//! | `limits` `a`, `j`                           | at least 1 mm/s², 1 mm/s³  | |
//! | pulses in the program                       | [`crate::program::MAX_PULSES`] (10 000 000), in `ProcessProgram::validate` | |
//! | moves and machine events                    | [`MAX_OPS`](super::MAX_OPS) | an image row is one move |
//! | pixel runs of image rows                    | [`MAX_RUNS`](super::MAX_RUNS) (20 000 000) | 8 B a run |
//! | a point's coordinates                       | within ±1 km of the origin | beyond any machine's travel; the geometry's tolerances are relative to 0.1 µm |

use super::{EvalError, Evaluator, Kind, R, bad};
use crate::program::{Pulse, PulseMode};
use lase_lang::Span;
use lase_lang::ast::Setting;
use lase_lang::units::{Dim, format_quantity};

/// The slowest feed: grbl's planner raises anything below `MINIMUM_FEED_RATE` (1 mm/min,
/// config.h) to it, so a slower feed would not run as written.
pub(crate) const MIN_FEED_MM_S: f64 = 1.0 / 60.0;
/// The fastest feed: 100 m/s, above any machine's axes (the planner holds a feed to the axes'
/// limits), so only a typo reaches it.
pub(crate) const MAX_FEED_MM_S: f64 = 100_000.0;
/// The finest length the NC programs resolve: they write 4 decimals of a millimetre.
pub(crate) const RESOLUTION_MM: f64 = 1e-4;
/// The finest time the NC programs resolve: they write dwells in 4 decimals of a second.
pub(crate) const RESOLUTION_S: f64 = 1e-4;

/// A range for one kind of quantity, with the reason it ends where it does (the help).
pub(super) struct Range {
    pub lo: f64,
    pub hi: f64,
    /// The bounds as the message shows them, in the units a recipe would write.
    pub lo_text: &'static str,
    pub hi_text: &'static str,
    pub dim: Dim,
    pub why: &'static str,
}

const NC_MM: &str = "the NC programs write lengths to 0.1 µm (4 decimals of a millimetre)";

pub(super) const FEED: Range = Range {
    lo_text: "1 mm/min",
    hi_text: "100 m/s",
    lo: MIN_FEED_MM_S,
    hi: MAX_FEED_MM_S,
    dim: Dim::SPEED,
    why: "a feed runs from 1 mm/min (grbl raises anything slower to it, so it would not run \
          as written) to 100 m/s (beyond any machine's axes)",
};
pub(super) const TOLERANCE: Range = Range {
    lo_text: "0.1 µm",
    hi_text: "10 mm",
    lo: RESOLUTION_MM,
    hi: 10.0,
    dim: Dim::LENGTH,
    why: "a tolerance runs from 0.1 µm (the NC programs write lengths to 0.1 µm) to 10 mm",
};
pub(super) const FINE_LENGTH: Range = Range {
    lo_text: "0.1 µm",
    hi_text: "10 m",
    lo: RESOLUTION_MM,
    hi: 10_000.0,
    dim: Dim::LENGTH,
    why: NC_MM,
};
pub(super) const DWELL: Range = Range {
    lo_text: "0.1 ms",
    hi_text: "1 h",
    lo: RESOLUTION_S,
    hi: 3600.0,
    dim: Dim::TIME,
    why: "a dwell is 0, or from 0.1 ms (the NC programs write dwells to 0.1 ms) to an hour",
};
pub(super) const PULSE_TIME: Range = Range {
    lo_text: "1 fs",
    hi_text: "1 h",
    lo: 1e-15,
    hi: 3600.0,
    dim: Dim::TIME,
    why: "pulse times run from 1 fs to an hour",
};
pub(super) const PULSE_ENERGY: Range = Range {
    lo_text: "0 J",
    hi_text: "1 kJ",
    lo: 0.0,
    hi: 1000.0,
    dim: Dim::ENERGY,
    why: "a pulse's energy is at most 1 kJ",
};
pub(super) const ACCEL: Range = Range {
    lo_text: "1 mm/s^2",
    hi_text: "no bound",
    lo: 1.0,
    hi: f64::INFINITY,
    dim: Dim::ACCEL,
    why: "an axis accelerates at 1 mm/s² at least; slower, a move takes hours to reach speed",
};
pub(super) const JERK: Range = Range {
    lo_text: "1 mm/s^3",
    hi_text: "no bound",
    lo: 1.0,
    hi: f64::INFINITY,
    dim: Dim::JERK,
    why: "an axis's jerk is 1 mm/s³ at least; lower, a move takes hours to reach speed",
};

/// The farthest a point may lie from the origin on any axis: 1 km, beyond any machine's travel.
/// Curve fitting and offsetting work to absolute tolerances of 0.1 µm, which an f64 can no
/// longer tell apart beyond about 10⁹ mm: a spline through (1e300 mm, 0) never converged.
pub(crate) const MAX_COORD_MM: f64 = 1e6;

/// A point value (a literal or the result of point arithmetic) whose coordinates lie within
/// [`MAX_COORD_MM`]; anything else passes through.
pub(super) fn point_in_range(v: super::Value, span: Span) -> R<super::Value> {
    if let super::Value::Point(p, _) = &v
        && let Some(c) = p.iter().find(|c| c.abs() > MAX_COORD_MM)
    {
        let value = if c.abs() < 1e12 {
            format_quantity(*c, Dim::LENGTH)
        } else {
            format!("{c:e} mm")
        };
        return Err(bad(
            Kind::OutOfRange,
            span,
            &format!("the point's coordinate {value} is beyond 1 km from the origin"),
            "too far",
            Some(
                "a point's coordinates lie within ±1 km (1e6 mm) of the origin: beyond any \
                 machine's travel, and beyond what the geometry's 0.1 µm tolerances can resolve",
            ),
        ));
    }
    Ok(v)
}

impl Evaluator {
    /// `x` (of `what`, at `span`), or a diagnostic naming the range and why it ends there.
    pub(super) fn in_range(&self, x: f64, r: &Range, what: &str, span: Span) -> R<f64> {
        if x >= r.lo && x <= r.hi {
            return Ok(x);
        }
        let (bound, label) = if x < r.lo {
            (format!("below {}", r.lo_text), "too small")
        } else {
            (format!("above {}", r.hi_text), "too large")
        };
        // A value far below the display's decimals would read as 0: show its exponent.
        let mut value = format_quantity(x, r.dim);
        if x != 0.0 && value.trim_start_matches('-').starts_with("0 ") {
            value = format!("{x:e} {}", r.dim.base_unit());
        }
        Err(bad(
            Kind::OutOfRange,
            span,
            &format!("{what} {value} is {bound}"),
            label,
            Some(r.why),
        ))
    }

    /// A `pulse` statement's interval, width and energy within their ranges, each diagnosed at
    /// the setting that gave it (an interval set earlier is checked where it was set).
    pub(super) fn pulse_in_range(&self, pulse: &Pulse, set: &[Setting]) -> R<()> {
        let at = |key: &str| {
            set.iter()
                .rev()
                .find(|s| s.key.name == key)
                .map(|s| s.value.as_ref().map_or(s.span, |e| e.span))
        };
        if let Some(sp) = at("interval") {
            match pulse.mode {
                PulseMode::Distance { pitch_mm } => {
                    self.in_range(pitch_mm, &FINE_LENGTH, "the pulse interval", sp)?
                }
                PulseMode::Time { period_s } => {
                    self.in_range(period_s, &PULSE_TIME, "the pulse interval", sp)?
                }
            };
        }
        if let (Some(sp), Some(w)) = (at("width"), pulse.width_s) {
            self.in_range(w, &PULSE_TIME, "the pulse width", sp)?;
        }
        if let (Some(sp), Some(e)) = (at("energy"), pulse.energy_j) {
            self.in_range(e, &PULSE_ENERGY, "the pulse energy", sp)?;
        }
        Ok(())
    }

    /// Refuses work of `n` more ops (a path's segments or stations) that would take the
    /// program past [`super::MAX_OPS`], before any of it is generated.
    /// Refuses image rows whose pixel runs would take the program past [`super::MAX_RUNS`]
    /// (a run is 8 B inside its row's op, so this budget is far larger than the op budget).
    pub(super) fn room_for_runs(&self, n: f64, what: &str, help: &str, span: Span) -> R<()> {
        let total = self.runs as f64 + n;
        if total > super::MAX_RUNS as f64 {
            return Err(EvalError::TooLarge {
                message: format!(
                    "{what} would take the program to {} pixel runs, above the {} lase handles",
                    lase_lang::units::format_number(total.round()),
                    lase_lang::units::format_number(super::MAX_RUNS as f64)
                ),
                span,
                label: "too many pixel runs".into(),
                help: Some(format!("{help}, or split the job into several recipes")),
            });
        }
        Ok(())
    }

    pub(super) fn room_for_ops(&self, n: f64, what: &str, help: &str, span: Span) -> R<()> {
        let total = self.ops.len() as f64 + n;
        if total > super::MAX_OPS as f64 {
            return Err(EvalError::TooLarge {
                message: format!(
                    "{what} would take the program to {} moves, above the {} lase handles",
                    lase_lang::units::format_number(total.round()),
                    lase_lang::units::format_number(super::MAX_OPS as f64)
                ),
                span,
                label: "too many moves".into(),
                help: Some(format!("{help}, or split the job into several recipes")),
            });
        }
        Ok(())
    }
}
