//! Extension diagnostics, and the one place where Rhai's positions (line, column in a `.rhai`
//! file) become [`Span`]s of the recipe's source map.
//!
//! A diagnostic about a running extension carries two spans: where in the `.rhai` file it
//! went wrong, and the recipe call that ran it.

use lase_lang::Span;
use miette::Diagnostic;
use rhai::{EvalAltResult, Position};
use thiserror::Error;

#[derive(Debug, Clone, Error, Diagnostic, PartialEq)]
pub enum ExtError {
    #[error("cannot use \"{path}\": {reason}")]
    #[diagnostic(code(lase::ext::load))]
    Load {
        path: String,
        reason: String,
        #[label("here")]
        span: Span,
        #[help]
        help: Option<String>,
    },

    #[error("syntax error in {file}: {message}")]
    #[diagnostic(code(lase::ext::syntax))]
    Syntax {
        file: String,
        message: String,
        #[label("{message}")]
        span: Span,
        #[label("used here")]
        used: Span,
    },

    #[error("bad extension signature for `{function}` in {file}: {message}")]
    #[diagnostic(
        code(lase::ext::signature),
        help(
            "declare what the recipe passes and gets back in a doc comment line right above \
             the function: `/// lase: (theta: angle, lift: length) -> length`"
        )
    )]
    Signature {
        function: String,
        file: String,
        message: String,
        #[label("this function")]
        span: Span,
    },

    #[error("extension `{function}` was stopped: {what}")]
    #[diagnostic(code(lase::ext::runaway))]
    Runaway {
        function: String,
        what: String,
        #[label("stopped here")]
        span: Option<Span>,
        #[label("called here")]
        call: Span,
        #[help]
        help: Option<String>,
    },

    #[error("extension `{function}` failed: {message}")]
    #[diagnostic(code(lase::ext::script))]
    Script {
        function: String,
        message: String,
        #[label("{message}")]
        span: Option<Span>,
        #[label("called here")]
        call: Span,
        #[help]
        help: Option<String>,
    },

    #[error("extension `{function}` returned {found}; its signature declares {expected}")]
    #[diagnostic(code(lase::ext::result))]
    Result {
        function: String,
        expected: String,
        found: String,
        #[label("returned {found}")]
        call: Span,
        #[help]
        help: Option<String>,
    },

    #[error("expected {expected} for `{param}` of `{function}`, found {found}")]
    #[diagnostic(code(lase::ext::argument))]
    Argument {
        function: String,
        param: String,
        expected: String,
        found: String,
        #[label("this is {found}")]
        span: Span,
    },

    #[error("bad preset {file}: {message}")]
    #[diagnostic(code(lase::ext::preset))]
    Preset {
        file: String,
        message: String,
        #[label("{message}")]
        span: Span,
        #[label("used here")]
        used: Span,
    },
}

impl ExtError {
    /// The span that places the error in the recipe (the call or the `use`).
    pub fn span(&self) -> Span {
        match self {
            ExtError::Load { span, .. }
            | ExtError::Signature { span, .. }
            | ExtError::Argument { span, .. } => *span,
            ExtError::Syntax { used, .. } | ExtError::Preset { used, .. } => *used,
            ExtError::Runaway { call, .. }
            | ExtError::Script { call, .. }
            | ExtError::Result { call, .. } => *call,
        }
    }
}

/// A `.rhai` file's text and where it starts in the source map.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FileText<'a> {
    pub text: &'a str,
    pub base: usize,
}

impl FileText<'_> {
    /// The span of the token at a Rhai position (1-based line and column in characters).
    pub fn span_at(&self, pos: Position) -> Option<Span> {
        let line = pos.line()?;
        let col = pos.position().unwrap_or(1).max(1);
        let mut offset = 0;
        for (i, l) in self.text.split_inclusive('\n').enumerate() {
            if i + 1 == line {
                let start = l
                    .char_indices()
                    .nth(col - 1)
                    .map_or(l.trim_end().len(), |(b, _)| b);
                let rest = &l[start..];
                let len = rest
                    .char_indices()
                    .find(|(_, c)| !(c.is_alphanumeric() || *c == '_'))
                    .map_or(rest.trim_end().len(), |(b, _)| b)
                    .max(1)
                    .min(rest.len().max(1));
                let s = self.base + offset + start;
                return Some(Span::new(s, (s + len).min(self.base + self.text.len())));
            }
            offset += l.len();
        }
        None
    }

    /// The span of `fn NAME(` in the file, for errors about a whole function.
    pub fn fn_span(&self, name: &str) -> Span {
        let pat = format!("fn {name}(");
        match self.text.find(&pat) {
            Some(i) => Span::new(self.base + i + 3, self.base + i + 3 + name.len()),
            None => Span::new(self.base, self.base),
        }
    }
}

/// The limits an extension runs under, quoted in diagnostics.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LimitText {
    pub operations: u64,
    pub call_levels: usize,
}

/// Turns a Rhai run-time error into a diagnostic: the innermost position inside the `.rhai`
/// file, the chain of Rhai functions it passed through, and the recipe call site.
pub(crate) fn from_rhai(
    err: EvalAltResult,
    file: FileText,
    function: &str,
    call: Span,
    limits: LimitText,
) -> ExtError {
    let mut err = err;
    let mut chain: Vec<String> = Vec::new();
    let mut outer_pos = Position::NONE;
    loop {
        match err {
            EvalAltResult::ErrorInFunctionCall(name, _, inner, pos) => {
                if outer_pos.is_none() {
                    outer_pos = pos;
                }
                chain.push(if name.starts_with("anon$") {
                    "a closure".into()
                } else {
                    format!("`{name}`")
                });
                err = *inner;
            }
            other => {
                err = other;
                break;
            }
        }
    }
    let pos = err.position();
    let span = file
        .span_at(pos)
        .or_else(|| file.span_at(outer_pos))
        .or_else(|| Some(file.fn_span(function)));
    let via = if chain.len() > 1 {
        Some(format!("in {}", chain.join(" → ")))
    } else {
        None
    };
    let runaway = |what: String, help: &str| ExtError::Runaway {
        function: function.to_string(),
        what,
        span,
        call,
        help: Some(match &via {
            Some(v) => format!("{help} ({v})"),
            None => help.to_string(),
        }),
    };
    match err {
        EvalAltResult::ErrorTooManyOperations(_) => runaway(
            format!(
                "it ran more than {} operations (an endless loop?)",
                limits.operations
            ),
            "extensions run under an operation budget so that a recipe never hangs; check the \
             loop's end condition",
        ),
        EvalAltResult::ErrorStackOverflow(_) => runaway(
            format!(
                "its calls nest more than {} levels deep (endless recursion?)",
                limits.call_levels
            ),
            "a recursive function never reaches its base case",
        ),
        EvalAltResult::ErrorDataTooLarge(what, _) => runaway(
            format!("{} grew beyond the sandbox's limit", what.to_lowercase()),
            "extensions may build arrays of at most 100 000 items, maps of 10 000 and \
             strings of 16 KiB",
        ),
        EvalAltResult::ErrorFunctionNotFound(sig, _) => ExtError::Script {
            function: function.to_string(),
            message: format!("no function `{sig}`"),
            span,
            call,
            help: Some(
                "extensions run in a sandbox: math, arrays, maps, strings and lase's geometry \
                 functions, no files, processes or `eval` (`lase doc extensions` lists them)"
                    .into(),
            ),
        },
        other => {
            let message = match &other {
                EvalAltResult::ErrorRuntime(d, _) => d.to_string(),
                e => {
                    let s = e.to_string();
                    // Rhai appends " (line L, position C)"; the label shows where.
                    match s.rfind(" (line ") {
                        Some(i) => s[..i].to_string(),
                        None => s,
                    }
                }
            };
            ExtError::Script {
                function: function.to_string(),
                message,
                span,
                call,
                help: via,
            }
        }
    }
}
