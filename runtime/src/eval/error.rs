//! Evaluation diagnostics: what only running the recipe can find (the machine's axes and
//! limits, geometry that cannot be built, values out of range).

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

    #[error("{message}")]
    #[diagnostic(code(lase::eval::bad_value))]
    BadValue {
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
    #[diagnostic(code(lase::eval::geometry))]
    Geometry {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    #[error("pulse rate {rate} is above the laser's maximum {max}")]
    #[diagnostic(code(lase::eval::pulse_rate))]
    PulseRate {
        rate: String,
        max: String,
        #[label("at this speed")]
        span: Span,
        #[help]
        help: Option<String>,
    },

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
            | EvalError::BadValue { span, .. }
            | EvalError::Type { span, .. }
            | EvalError::Geometry { span, .. }
            | EvalError::PulseRate { span, .. }
            | EvalError::UnknownEvent { span, .. }
            | EvalError::NoPower { span }
            | EvalError::Budget { span, .. } => *span,
            EvalError::Machine(m) => m.span(),
            EvalError::Extension(e) => e.span(),
        }
    }
}

impl From<crate::ext::ExtError> for EvalError {
    fn from(e: crate::ext::ExtError) -> EvalError {
        EvalError::Extension(Box::new(e))
    }
}

/// The laser's limits are one rule (`crate::program::check_power`, `check_pulse_rate`), which
/// `ProcessProgram::validate` applies too; while running, the evaluator reports it as its own.
impl From<crate::program::LaserLimit> for EvalError {
    fn from(e: crate::program::LaserLimit) -> EvalError {
        use crate::program::LaserLimit;
        match e {
            LaserLimit::Power {
                value,
                limit,
                span,
                help,
            } => EvalError::AboveMachine {
                what: "laser power".into(),
                value,
                limit,
                span,
                help,
            },
            LaserLimit::PulseRate {
                rate,
                max,
                span,
                help,
                ..
            } => EvalError::PulseRate {
                rate,
                max,
                span,
                help,
            },
        }
    }
}
