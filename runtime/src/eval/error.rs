//! Evaluation diagnostics: what only running the recipe can find (the machine's axes and
//! limits, geometry that cannot be built, values out of range).
//!
//! Every variant has its own stable code, so a test, an editor or a reader of a log can tell
//! one kind of mistake from another without parsing the message (all `lase::eval::*`):
//!
//! - `not_positive`: must be greater than zero (a limit, a speed, a spot, a step, a pulse);
//! - `negative`: cannot be negative (a dwell, a power, a standoff, an overscan, an inset);
//! - `out_of_range`: outside its range (an M-code, an index, a look-ahead, a cam's angles, a
//!   scan speed the axes cannot reach or an overscan too short to reach it, a quantity outside
//!   what a machine can carry out (`bounds.rs`: feeds, tolerances, steps, dwells, pulses), an
//!   arc that sweeps nothing, an arc length beyond a profile's ends);
//! - `not_whole`: a count that is not a whole number;
//! - `too_large`: work beyond what lase handles, refused before it is generated (a scan's rows
//!   and dot-mode stops, a path's moves or stations past the op budget, the program's pulses);
//! - `undefined`: a variable or function with no definition here;
//! - `unknown_name`: a word not allowed there (a unit, a field, a profile or scan kind, a law);
//! - `missing_argument`: a call or a profile without an argument it needs;
//! - `missing_setting`: a statement without a setting it needs that nothing earlier set (a
//!   standoff, a pulse interval or rate, a scan's speed, pitch, rows and columns);
//! - `conflict`: settings that exclude each other, or one that does not apply here;
//! - `dimension`: dimensions an operation cannot combine;
//! - `division_by_zero`: a division or remainder by zero;
//! - `no_orientation`: a `move` on a machine that orients the beam before any path set it;
//! - `not_loaded`: an `import` whose module was not loaded;
//! - `empty`: a scan with nothing to scan;
//! - `format`: a `format` template that does not fit its values (an unmatched brace, a spec
//!   it does not know, too few or too many values);
//! - `marking`: text or a 2D code that cannot be made (a character the font lacks, a font
//!   file that cannot be read, more text than the largest symbol holds).
//!
//! The rest name the machine and the process sheet: `no_machine`, `unknown_machine`,
//! `machine_file`, `machine_changed`, `unknown_axis`, `unknown_event`, `above_machine` (a
//! setting above the machine's capability), `pulse_rate`, `no_power`; and `type_mismatch`,
//! `geometry` (a profile that cannot be built, offset or followed, a closed profile that crosses
//! itself), `image` (an image file that cannot be read or decoded, or has too many pixels),
//! `limit` (the step budget, the op count and the call depth). Machine files, extensions and presets keep their own
//! codes (`lase::machine::*`, `lase::ext::*`).

use lase_lang::Span;
use miette::Diagnostic;
use thiserror::Error;

#[derive(Debug, Clone, Error, Diagnostic, PartialEq)]
pub enum EvalError {
    #[error("no machine selected")]
    #[diagnostic(code(lase::eval::no_machine))]
    NoMachine {
        #[label("this needs a machine")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("unknown machine `{name}`")]
    #[diagnostic(code(lase::eval::unknown_machine))]
    UnknownMachine {
        name: String,
        #[label("not a stock machine")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("cannot load machine file \"{path}\": {reason}")]
    #[diagnostic(
        code(lase::eval::machine_file),
        help("the path is relative to the recipe")
    )]
    MachineFile {
        path: String,
        reason: String,
        #[label("here")]
        span: Span,
    },

    #[error(transparent)]
    #[diagnostic(transparent)]
    Machine(#[from] crate::machine::MachineError),

    /// A Rhai extension failed or was stopped.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Extension(Box<crate::ext::ExtError>),

    #[error("the machine cannot change once the recipe has moved")]
    #[diagnostic(
        code(lase::eval::machine_changed),
        help("select the machine once, before any motion")
    )]
    MachineChanged {
        #[label("second machine")]
        span: Span,
    },

    #[error("machine `{machine}` has no axis `{axis}`")]
    #[diagnostic(code(lase::eval::unknown_axis))]
    UnknownAxis {
        machine: String,
        axis: String,
        #[label("no such axis")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("{what} {value} is above the machine's {limit}")]
    #[diagnostic(code(lase::eval::above_machine))]
    AboveMachine {
        what: String,
        value: String,
        limit: String,
        #[label("too high for this machine")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    /// A value that must be greater than zero is not: a limit, a speed, a spot, a step, a pulse
    /// setting, a width.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::not_positive))]
    NotPositive {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A value that cannot be negative is: a dwell, a power, a standoff, an overscan, an inset, a
    /// square root's argument.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::negative))]
    Negative {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A value outside its range: an M-code, a list index, a look-ahead, a contour index, a cam
    /// that turns more than once, a scan speed the axes cannot reach or an overscan too short to
    /// reach it.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::out_of_range))]
    OutOfRange {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A count (a range bound, an index, an M-code) that is not a whole number.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::not_whole))]
    NotWhole {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A scan that would produce more rows or dot-mode stops than lase handles.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::too_large))]
    TooLarge {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A variable or function name with no definition here.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::undefined))]
    Undefined {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A word the recipe may not use there: a unit, a field, a profile or scan kind, a cam law.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::unknown_name))]
    UnknownName {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A call or a profile without an argument it needs.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::missing_argument))]
    MissingArgument {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A statement without a setting it needs and that nothing earlier set: a standoff, a pulse
    /// interval, a scan's speed, pitch, rows and columns.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::missing_setting))]
    MissingSetting {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// Settings that exclude each other, or one that does not apply to this machine or path.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::conflict))]
    Conflict {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// Dimensions that an operation cannot combine (a square root of odd unit powers, the min of a
    /// length and a time, rounding a quantity with a unit).
    #[error("{message}")]
    #[diagnostic(code(lase::eval::dimension))]
    Dimension {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A division or remainder by zero.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::division_by_zero))]
    DivisionByZero {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A `move` on a machine that orients the beam before any path set the beam's direction.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::no_orientation))]
    NoOrientation {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// An `import` whose module was not loaded before evaluation.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::not_loaded))]
    NotLoaded {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A `format` template that does not fit its values.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::format))]
    Format {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// Text or a 2D code that cannot be made.
    #[error("{message}")]
    #[diagnostic(code(lase::eval::marking))]
    Marking {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// A scan with nothing to scan (no spot in the list or the region).
    #[error("{message}")]
    #[diagnostic(code(lase::eval::empty))]
    Empty {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    #[error("expected {expected} for {context}, found {found}")]
    #[diagnostic(code(lase::eval::type_mismatch))]
    Type {
        expected: String,
        found: String,
        context: String,
        #[label("this is {found}")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("{message}")]
    #[diagnostic(code(lase::eval::image))]
    Image {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    #[error("{message}")]
    #[diagnostic(code(lase::eval::geometry))]
    Geometry {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    /// The laser's limits (power, pulse rate, pulse budget): one rule with one diagnostic,
    /// `crate::program::LaserLimit`, which `ProcessProgram::validate` reports too.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Laser(crate::program::LaserLimit),

    #[error("machine `{machine}` has no event `{name}`")]
    #[diagnostic(code(lase::eval::unknown_event))]
    UnknownEvent {
        machine: String,
        name: String,
        #[label("unknown event")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("the laser has no power set")]
    #[diagnostic(
        code(lase::eval::no_power),
        help("set it before the first lit move: `laser {{ power 40 W }}`")
    )]
    NoPower {
        #[label("the laser would turn on here")]
        span: Span,
    },

    #[error("{message}")]
    #[diagnostic(code(lase::eval::limit))]
    Budget {
        message: String,
        #[label("here")]
        span: Span,
        #[help]
        help: Option<String>,
    },
}

impl EvalError {
    pub fn span(&self) -> Span {
        match self {
            EvalError::NoMachine { span, .. }
            | EvalError::UnknownMachine { span, .. }
            | EvalError::MachineFile { span, .. }
            | EvalError::MachineChanged { span }
            | EvalError::UnknownAxis { span, .. }
            | EvalError::AboveMachine { span, .. }
            | EvalError::NotPositive { span, .. }
            | EvalError::Negative { span, .. }
            | EvalError::OutOfRange { span, .. }
            | EvalError::NotWhole { span, .. }
            | EvalError::TooLarge { span, .. }
            | EvalError::Undefined { span, .. }
            | EvalError::UnknownName { span, .. }
            | EvalError::MissingArgument { span, .. }
            | EvalError::MissingSetting { span, .. }
            | EvalError::Conflict { span, .. }
            | EvalError::Dimension { span, .. }
            | EvalError::DivisionByZero { span, .. }
            | EvalError::NoOrientation { span, .. }
            | EvalError::NotLoaded { span, .. }
            | EvalError::Empty { span, .. }
            | EvalError::Format { span, .. }
            | EvalError::Marking { span, .. }
            | EvalError::Type { span, .. }
            | EvalError::Geometry { span, .. }
            | EvalError::Image { span, .. }
            | EvalError::UnknownEvent { span, .. }
            | EvalError::NoPower { span }
            | EvalError::Budget { span, .. } => *span,
            EvalError::Machine(m) => m.span(),
            EvalError::Laser(l) => l.span(),
            EvalError::Extension(e) => e.span(),
        }
    }
}

/// The kinds of mistake that share one shape (a message, a label on the span, an optional
/// help), each raised as its own variant so it keeps its own stable code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    NotPositive,
    Negative,
    OutOfRange,
    NotWhole,
    TooLarge,
    Undefined,
    UnknownName,
    MissingArgument,
    MissingSetting,
    Conflict,
    Dimension,
    DivisionByZero,
    NoOrientation,
    NotLoaded,
    Empty,
    Format,
    Marking,
    /// Geometry that cannot be built (`lase::eval::geometry`).
    Geometry,
}

impl EvalError {
    /// The diagnostic of kind `kind`.
    pub(crate) fn of_kind(
        kind: Kind,
        span: Span,
        message: String,
        label: String,
        help: Option<String>,
    ) -> EvalError {
        match kind {
            Kind::NotPositive => EvalError::NotPositive {
                message,
                span,
                label,
                help,
            },
            Kind::Negative => EvalError::Negative {
                message,
                span,
                label,
                help,
            },
            Kind::OutOfRange => EvalError::OutOfRange {
                message,
                span,
                label,
                help,
            },
            Kind::NotWhole => EvalError::NotWhole {
                message,
                span,
                label,
                help,
            },
            Kind::TooLarge => EvalError::TooLarge {
                message,
                span,
                label,
                help,
            },
            Kind::Undefined => EvalError::Undefined {
                message,
                span,
                label,
                help,
            },
            Kind::UnknownName => EvalError::UnknownName {
                message,
                span,
                label,
                help,
            },
            Kind::MissingArgument => EvalError::MissingArgument {
                message,
                span,
                label,
                help,
            },
            Kind::MissingSetting => EvalError::MissingSetting {
                message,
                span,
                label,
                help,
            },
            Kind::Conflict => EvalError::Conflict {
                message,
                span,
                label,
                help,
            },
            Kind::Dimension => EvalError::Dimension {
                message,
                span,
                label,
                help,
            },
            Kind::DivisionByZero => EvalError::DivisionByZero {
                message,
                span,
                label,
                help,
            },
            Kind::NoOrientation => EvalError::NoOrientation {
                message,
                span,
                label,
                help,
            },
            Kind::NotLoaded => EvalError::NotLoaded {
                message,
                span,
                label,
                help,
            },
            Kind::Empty => EvalError::Empty {
                message,
                span,
                label,
                help,
            },
            Kind::Geometry => EvalError::Geometry {
                message,
                span,
                label,
                help,
            },
            Kind::Format => EvalError::Format {
                message,
                span,
                label,
                help,
            },
            Kind::Marking => EvalError::Marking {
                message,
                span,
                label,
                help,
            },
        }
    }
}

impl From<crate::ext::ExtError> for EvalError {
    fn from(e: crate::ext::ExtError) -> EvalError {
        EvalError::Extension(Box::new(e))
    }
}

/// The laser's limits are one rule (`crate::program::check_power`, `check_pulse_rate`), which
/// `ProcessProgram::validate` applies too; the evaluator reports the same diagnostic.
impl From<crate::program::LaserLimit> for EvalError {
    fn from(e: crate::program::LaserLimit) -> EvalError {
        EvalError::Laser(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kind raises its own variant, with the code `error.rs` documents for it: the codes
    /// are part of the product, and two kinds must never share one.
    #[test]
    fn every_kind_has_its_own_documented_code() {
        let kinds = [
            (Kind::NotPositive, "not_positive"),
            (Kind::Negative, "negative"),
            (Kind::OutOfRange, "out_of_range"),
            (Kind::NotWhole, "not_whole"),
            (Kind::TooLarge, "too_large"),
            (Kind::Undefined, "undefined"),
            (Kind::UnknownName, "unknown_name"),
            (Kind::MissingArgument, "missing_argument"),
            (Kind::MissingSetting, "missing_setting"),
            (Kind::Conflict, "conflict"),
            (Kind::Dimension, "dimension"),
            (Kind::DivisionByZero, "division_by_zero"),
            (Kind::NoOrientation, "no_orientation"),
            (Kind::NotLoaded, "not_loaded"),
            (Kind::Empty, "empty"),
            (Kind::Geometry, "geometry"),
            (Kind::Format, "format"),
            (Kind::Marking, "marking"),
        ];
        let doc = include_str!("error.rs");
        for (kind, name) in kinds {
            let span = Span::new(3, 5);
            let e = EvalError::of_kind(kind, span, "m".into(), "l".into(), Some("h".into()));
            let code = e.code().map(|c| c.to_string());
            assert_eq!(
                code.as_deref(),
                Some(&*format!("lase::eval::{name}")),
                "{kind:?}"
            );
            assert_eq!(e.span(), span);
            assert_eq!(e.to_string(), "m");
            assert_eq!(e.help().map(|h| h.to_string()).as_deref(), Some("h"));
            assert!(
                doc.contains(&format!("`{name}`")),
                "{name} is not documented"
            );
        }
    }
}
