//! Diagnostics of the language phases: one enum per phase, each variant with a stable code,
//! a label on the source span and a `help` that says how to fix it.
//!
//! Spans are global offsets into the recipe's [`crate::SourceMap`]; the binary attaches the
//! map as the source of every report, in one place.

use crate::span::Span;
use miette::Diagnostic;
use thiserror::Error;

/// Syntax and import errors. pest stops at the first syntax error of a file, so a file yields
/// at most one [`ParseError::Syntax`].
#[derive(Debug, Clone, Error, Diagnostic, PartialEq)]
pub enum ParseError {
    #[error("syntax error: {message}")]
    #[diagnostic(code(lase::parse::syntax))]
    Syntax {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: Option<String>,
    },

    #[error("cannot import \"{path}\": {reason}")]
    #[diagnostic(
        code(lase::parse::import),
        help("paths are relative to the file that imports them")
    )]
    Import {
        path: String,
        reason: String,
        #[label("imported here")]
        span: Span,
    },

    #[error("\"{path}\" imports itself (through {chain})")]
    #[diagnostic(
        code(lase::parse::import_cycle),
        help("move what both files need into a third file and import that from each")
    )]
    ImportCycle {
        path: String,
        chain: String,
        #[label("this import closes the cycle")]
        span: Span,
    },

    #[error("expression nests more than {limit} operators deep")]
    #[diagnostic(
        code(lase::parse::too_deep),
        help(
            "split the expression: name partial results with `let`, or build a list and sum it in a `for` loop"
        )
    )]
    TooDeep {
        limit: usize,
        #[label("this operator is one level too many")]
        span: Span,
    },
}

/// Name, unit and type errors found by the checker before anything is evaluated.
#[derive(Debug, Clone, Error, Diagnostic, PartialEq)]
pub enum CheckError {
    #[error("unknown name `{name}`")]
    #[diagnostic(code(lase::check::unknown_name))]
    UnknownName {
        name: String,
        #[label("not defined here")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("unknown unit `{unit}`")]
    #[diagnostic(code(lase::check::unknown_unit))]
    UnknownUnit {
        unit: String,
        #[label("not a unit")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("cannot {verb} {left} and {right}")]
    #[diagnostic(
        code(lase::check::unit_mismatch),
        help("both sides of `{op}` must have the same dimension; check the units")
    )]
    UnitMismatch {
        verb: &'static str,
        op: &'static str,
        left: String,
        right: String,
        #[label("this is {left}")]
        lhs: Span,
        #[label("this is {right}")]
        rhs: Span,
    },

    #[error("expected {expected} for {context}, found {found}")]
    #[diagnostic(code(lase::check::wrong_dimension))]
    WrongDimension {
        expected: String,
        found: String,
        context: String,
        #[label("this is {found}")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("expected {expected} for {context}, found {found}")]
    #[diagnostic(code(lase::check::type_mismatch))]
    TypeMismatch {
        expected: String,
        found: String,
        context: String,
        #[label("this is {found}")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{name}` takes {expected} argument(s), {found} given")]
    #[diagnostic(code(lase::check::arg_count))]
    ArgCount {
        name: String,
        expected: String,
        found: usize,
        #[label("in this call")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{name}` has no parameter `{arg}`")]
    #[diagnostic(code(lase::check::unknown_arg))]
    UnknownArg {
        name: String,
        arg: String,
        #[label("no such parameter")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{name}` is missing its argument `{arg}`")]
    #[diagnostic(code(lase::check::missing_arg))]
    MissingArg {
        name: String,
        arg: String,
        #[label("in this call")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{key}` is not a setting of `{stmt}`")]
    #[diagnostic(code(lase::check::unknown_setting))]
    UnknownSetting {
        stmt: String,
        key: String,
        #[label("unknown setting")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{first}` and `{second}` contradict each other")]
    #[diagnostic(
        code(lase::check::conflicting_flags),
        help("a profile runs one way: give `cw` or `ccw`, not both")
    )]
    ConflictingFlags {
        first: String,
        second: String,
        #[label("`{first}` given here")]
        first_span: Span,
        #[label("and `{second}` here")]
        second_span: Span,
    },

    #[error("`{key}` needs a value")]
    #[diagnostic(code(lase::check::missing_value))]
    MissingValue {
        key: String,
        #[label("no value")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{what}` is not allowed {place}")]
    #[diagnostic(code(lase::check::misplaced))]
    Misplaced {
        what: String,
        place: String,
        #[label("here")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("{what} is not supported yet")]
    #[diagnostic(code(lase::check::unsupported))]
    Unsupported {
        what: String,
        #[label("not supported yet")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("unknown type `{name}`")]
    #[diagnostic(code(lase::check::unknown_type))]
    UnknownType {
        name: String,
        #[label("not a type")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("`{name}` is defined twice")]
    #[diagnostic(
        code(lase::check::duplicate),
        help("rename one of them; functions cannot be redefined")
    )]
    Duplicate {
        name: String,
        #[label("second definition")]
        span: Span,
        #[label("first definition")]
        first: Span,
    },
}

impl CheckError {
    /// The primary span of the error, for sorting and for inline test expectations.
    pub fn span(&self) -> Span {
        match self {
            CheckError::UnknownName { span, .. }
            | CheckError::UnknownUnit { span, .. }
            | CheckError::WrongDimension { span, .. }
            | CheckError::TypeMismatch { span, .. }
            | CheckError::ArgCount { span, .. }
            | CheckError::UnknownArg { span, .. }
            | CheckError::MissingArg { span, .. }
            | CheckError::UnknownSetting { span, .. }
            | CheckError::MissingValue { span, .. }
            | CheckError::Misplaced { span, .. }
            | CheckError::Unsupported { span, .. }
            | CheckError::UnknownType { span, .. }
            | CheckError::Duplicate { span, .. } => *span,
            CheckError::UnitMismatch { lhs, rhs, .. } => lhs.to(*rhs),
            CheckError::ConflictingFlags { second_span, .. } => *second_span,
        }
    }
}

impl ParseError {
    pub fn span(&self) -> Span {
        match self {
            ParseError::Syntax { span, .. }
            | ParseError::Import { span, .. }
            | ParseError::ImportCycle { span, .. }
            | ParseError::TooDeep { span, .. } => *span,
        }
    }
}

/// "did you mean `x`?" for the closest candidate, if one is close.
pub fn did_you_mean<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<String> {
    crate::units::suggest(name, candidates).map(|c| format!("did you mean `{c}`?"))
}
