//! NC program emitters: the only code in lase that knows NC text.
//!
//! A planned [`Job`] becomes an NC program for one [`Dialect`] (LinuxCNC, GRBL 1.1, grblHAL,
//! ISO/Fanuc style), streamed line by line to a sink so that a texturing job of millions of
//! lines never sits in memory. The machine file supplies what differs between machines of one
//! dialect: the laser on/off/power lines (`[post.<dialect>]`) and the codes of named events
//! ([`Dialect::lookup`]: grblHAL falls back to GRBL's).
//!
//! The path of one op: [`validate`] checks the whole program for the dialect first (every
//! M-code, event, axis letter, template and, for the GRBL family, line length), so that
//! emission can only fail on the sink's IO, never halfway through a program ("validate before
//! anything moves", CONVENTIONS.md). Then [`writer`] walks `program.ops` once, keeping the
//! modal state a controller keeps (motion mode, feed, last axis words, laser state) and writes
//! only what changes.
//!
//! Laser model (shared with `report`): the beam is switched at motion ops only. It goes on
//! right before the first lit move after an unlit one and off right after the last lit move of
//! a run; dwells, M-codes and events between two lit moves happen with the beam on (a pierce
//! dwell), and power changes between lit moves are written before the next lit move.

mod facts;
mod format;
pub mod modal;
pub mod reapproach;
mod relative;
mod validate;
mod writer;

use crate::motion::Job;
use lase_lang::Span;
use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

pub use facts::PlanFacts;
pub use format::{degrees, number};

/// An NC dialect lase can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Dialect {
    /// LinuxCNC's rs274ngc interpreter.
    LinuxCnc,
    /// GRBL 1.1 (laser mode `$32=1`): X, Y, Z only, 80-character lines.
    Grbl,
    /// grblHAL, GRBL's 32-bit successor: GRBL's protocol, words and laser mode, with up to six
    /// axes (linear X, Y, Z; A, B, C rotary or linear), so oriented machines run in inverse time
    /// (G93), and 256-character lines.
    GrblHal,
    /// ISO 6983 / Fanuc style: `%`, program number, `N` block numbers, `M30`.
    Iso,
}

impl Dialect {
    pub const ALL: [Dialect; 4] = [
        Dialect::LinuxCnc,
        Dialect::Grbl,
        Dialect::GrblHal,
        Dialect::Iso,
    ];

    /// The name used on the command line and as the key of `[post.<name>]` and event codes in
    /// machine files.
    pub fn name(self) -> &'static str {
        match self {
            Dialect::LinuxCnc => "linuxcnc",
            Dialect::Grbl => "grbl",
            Dialect::GrblHal => "grblhal",
            Dialect::Iso => "iso",
        }
    }

    /// GRBL 1.1 or a controller that reads its programs (grblHAL): laser mode with `M3`/`M4`
    /// and S words, GRBL's M-codes, no synchronized outputs, no path blending mode.
    pub fn is_grbl_family(self) -> bool {
        matches!(self, Dialect::Grbl | Dialect::GrblHal)
    }

    /// The keys this dialect reads in a machine file's per-dialect tables (`[post.<key>]`, an
    /// event's `codes`), most specific first: grblHAL runs GRBL programs, so a machine's GRBL
    /// lines serve it when it has none of its own.
    pub fn post_keys(self) -> &'static [&'static str] {
        match self {
            Dialect::LinuxCnc => &["linuxcnc"],
            Dialect::Grbl => &["grbl"],
            Dialect::GrblHal => &["grblhal", "grbl"],
            Dialect::Iso => &["iso"],
        }
    }

    /// The entry of a per-dialect table of a machine file (`machine.post`, an event's `codes`)
    /// this dialect uses, with the key it was found under (the first of
    /// [`post_keys`](Self::post_keys) present). The one place the fallback is decided.
    pub fn lookup<V>(self, table: &BTreeMap<String, V>) -> Option<(&'static str, &V)> {
        self.post_keys()
            .iter()
            .find_map(|&k| table.get(k).map(|v| (k, v)))
    }
}

impl fmt::Display for Dialect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A dialect name that is not one of `linuxcnc`, `grbl`, `grblhal`, `iso`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error, miette::Diagnostic)]
#[error("unknown NC dialect `{0}`")]
#[diagnostic(
    code(lase::emit::unknown_dialect),
    help("the dialects are linuxcnc, grbl, grblhal and iso")
)]
pub struct UnknownDialect(pub String);

impl FromStr for Dialect {
    type Err = UnknownDialect;

    fn from_str(s: &str) -> Result<Dialect, UnknownDialect> {
        Dialect::ALL
            .into_iter()
            .find(|d| d.name().eq_ignore_ascii_case(s.trim()))
            .ok_or_else(|| UnknownDialect(s.to_string()))
    }
}

/// One line of NC text (without its newline) and the op that produced it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct NcLine {
    pub text: String,
    /// Index of the producing op in `job.program.ops`; `None` for the header and footer.
    pub op: Option<u32>,
}

/// How to emit.
#[derive(Clone, Copy)]
pub struct EmitOptions<'a> {
    /// Names the recipe line of a span, e.g. `recipe.lase:12`. When given (and `comments` is
    /// on), a `(recipe.lase:12)` comment is written whenever the recipe line of the ops
    /// changes. An empty string writes nothing.
    pub locate: Option<&'a dyn Fn(Span) -> String>,
    /// Write traceability comments and the comments of M-code ops. The header comment is
    /// always written.
    pub comments: bool,
    /// The lines go to a live link, which settles row starts itself (`link::settle`): a
    /// program with `settle` is refused only as an NC file.
    pub live: bool,
}

impl Default for EmitOptions<'_> {
    fn default() -> Self {
        EmitOptions {
            locate: None,
            comments: true,
            live: false,
        }
    }
}

impl fmt::Debug for EmitOptions<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EmitOptions")
            .field("locate", &self.locate.map(|_| "Fn(Span) -> String"))
            .field("comments", &self.comments)
            .finish()
    }
}

/// What emission produced.
#[derive(Debug, Clone, Default)]
pub struct EmitStats {
    /// Lines handed to the sink.
    pub lines: u64,
    /// Bytes handed to the sink, counting one newline per line.
    pub bytes: u64,
    /// Motion blocks (G0/G1/G2/G3).
    pub motion_blocks: u64,
    /// The longest line, in characters.
    pub longest_line: usize,
    /// Things that are valid NC but need attention on the machine.
    pub warnings: Vec<EmitWarning>,
}

/// Valid NC that needs attention on the machine.
#[derive(Debug, Clone, PartialEq, thiserror::Error, miette::Diagnostic)]
pub enum EmitWarning {
    #[error(
        "M{code} is a user M-code: LinuxCNC runs the file `M{code}` from its program directory"
    )]
    #[diagnostic(
        code(lase::emit::user_mcode),
        severity(Warning),
        help(
            "make sure the file M{code} exists and is executable in the machine's [DISPLAY]PROGRAM_PREFIX or [RS274NGC]USER_M_PATH"
        )
    )]
    UserMCode {
        code: u32,
        #[label("needs a user M-code file")]
        span: Span,
    },

    #[error("M{code} ends the program here; the ops after it never run")]
    #[diagnostic(
        code(lase::emit::program_end),
        severity(Warning),
        help("lase ends every program itself; remove this `mcode`, or use M0/M1 to pause")
    )]
    ProgramEnd {
        code: u32,
        #[label("program end before the last op")]
        span: Span,
    },
}

/// Why a program cannot be written in a dialect. Nothing is written when one of these is
/// returned, except for [`EmitError::Io`] and [`EmitError::Replan`].
#[derive(Debug, thiserror::Error, miette::Diagnostic)]
pub enum EmitError {
    #[error("M{code} is not an M-code {dialect} accepts")]
    #[diagnostic(code(lase::emit::unsupported_mcode))]
    UnsupportedMCode {
        code: u32,
        dialect: Dialect,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: String,
    },

    #[error("output `{name}` has no {dialect} lines in machine `{machine}`")]
    #[diagnostic(code(lase::emit::unsupported_output))]
    UnsupportedOutput {
        name: String,
        dialect: Dialect,
        machine: String,
        #[label("not available in {dialect}")]
        span: Span,
        #[help]
        help: String,
    },

    #[error("event `{name}` has no {dialect} code in machine `{machine}`")]
    #[diagnostic(code(lase::emit::unsupported_event))]
    UnsupportedEvent {
        name: String,
        dialect: Dialect,
        machine: String,
        #[label("not available in {dialect}")]
        span: Span,
        #[help]
        help: String,
    },

    #[error("{message}")]
    #[diagnostic(code(lase::emit::dialect))]
    Dialect {
        message: String,
        dialect: Dialect,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: String,
    },

    /// The job fires pulses faster, or more of them, than the controller's pulse budget in
    /// the machine file allows (`max_pulse_rate`, `max_pulses` of `[post.<dialect>]`).
    #[error("{message}")]
    #[diagnostic(code(lase::emit::pulse_budget))]
    PulseBudget {
        message: String,
        #[label("{label}")]
        span: Span,
        label: String,
        #[help]
        help: String,
    },

    #[error("machine `{machine}` has no post for {dialect}")]
    #[diagnostic(code(lase::emit::no_post))]
    NoPost {
        machine: String,
        dialect: Dialect,
        #[label("this program needs a [post.{dialect}] section in the machine file")]
        span: Span,
        #[help]
        help: String,
    },

    #[error("post template `{template}` of machine `{machine}`: {message}")]
    #[diagnostic(code(lase::emit::template))]
    Template {
        template: String,
        machine: String,
        message: String,
        #[label("used here")]
        span: Span,
        #[help]
        help: String,
    },

    /// A LinuxCNC post line with an immediate output word (M64/M65/M68) where the plan
    /// switches on the fly: the message names the line, its post key and the planned speed.
    #[error("{message}")]
    #[diagnostic(code(lase::emit::immediate_output))]
    ImmediateOutput {
        message: String,
        code: u32,
        #[label("LinuxCNC drains its motion queue for M{code}: the machine stops here")]
        span: Span,
        #[help]
        help: String,
    },

    #[error("writing the NC program failed: {0}")]
    #[diagnostic(code(lase::emit::io))]
    Io(#[from] std::io::Error),

    /// Planning a job made in windows again, for the lit sub-blocks the writer reads
    /// (`motion::replan_windows`, [`PlanFacts`]), failed where the first pass had not: the plan
    /// is deterministic, so this is a bug, reported as the planner's own diagnostic.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Replan(Box<crate::motion::MotionError>),
}

/// Writes `job` as an NC program in `dialect`, one line at a time to `sink`.
///
/// The whole program is validated for the dialect before the first line is written; after
/// that only the sink can fail.
pub fn emit(
    job: &Job,
    dialect: Dialect,
    options: &EmitOptions<'_>,
    sink: &mut dyn FnMut(&NcLine) -> std::io::Result<()>,
) -> Result<EmitStats, EmitError> {
    emit_with(job, None, dialect, options, sink)
}

/// [`emit`] of a job planned in windows (`motion::plan_program_windows`, whose plan holds no
/// segments): what the writer reads of the plan is in `facts`, gathered from the windows
/// ([`PlanFacts`], gathered for `dialect`).
pub fn emit_planned(
    job: &Job,
    facts: &PlanFacts,
    dialect: Dialect,
    options: &EmitOptions<'_>,
    sink: &mut dyn FnMut(&NcLine) -> std::io::Result<()>,
) -> Result<EmitStats, EmitError> {
    emit_with(job, Some(facts), dialect, options, sink)
}

/// What `lase emit` refuses before the first NC line of a job planned in windows (`facts`
/// gathered for `dialect`): the post's words and settles, flying switches an immediate output
/// would stop, the pulse budget. `lase check` runs it for the machine's controller, so a
/// recipe it passes is one `lase emit` writes.
/// Its warnings are those `lase emit` prints.
pub fn check_planned(
    job: &Job,
    facts: &PlanFacts,
    dialect: Dialect,
) -> Result<Vec<EmitWarning>, EmitError> {
    check_with(job, Some(facts), dialect, false).map(|c| c.warnings)
}

fn check_with<'j>(
    job: &'j Job,
    facts: Option<&PlanFacts>,
    dialect: Dialect,
    live: bool,
) -> Result<validate::Checked<'j>, EmitError> {
    if !live {
        validate::check_settles(&job.program, dialect)?;
    }
    let checked = validate::validate(job, dialect, facts)?;
    match facts {
        None => validate::check_pulse_budget(job, dialect, checked.post)?,
        // Checked on the pulses as the windows passed (`PlanFacts`).
        Some(facts) => facts.pulse_budget(&job.program, dialect)?,
    }
    Ok(checked)
}

fn emit_with(
    job: &Job,
    facts: Option<&PlanFacts>,
    dialect: Dialect,
    options: &EmitOptions<'_>,
    sink: &mut dyn FnMut(&NcLine) -> std::io::Result<()>,
) -> Result<EmitStats, EmitError> {
    let checked = check_with(job, facts, dialect, options.live)?;
    // Settled rows go out relative to their settled start (`relative`), whether a live link
    // or the control settles them.
    let rows = relative::row_ranges(&job.program);
    // A job planned in windows has its lit sub-blocks planned again as they are written
    // (`facts::LitBlocks`), on a thread of this scope.
    let mut stats = std::thread::scope(|scope| {
        let mut lit = facts::LitBlocks::new(job, facts, dialect, scope);
        let lit = &mut lit;
        if rows.is_empty() {
            writer::write(job, facts, lit, dialect, options, &checked, sink)
        } else {
            let mut r = relative::Rows::new(&job.program, rows, sink);
            let mut put = |l: &NcLine| r.put(l);
            let mut stats = writer::write(job, facts, lit, dialect, options, &checked, &mut put)?;
            r.finish(&mut stats);
            Ok(stats)
        }
    })?;
    stats.warnings = checked.warnings;
    Ok(stats)
}

/// The whole program as lines, each with the op it came from (what a link streams), and the
/// emitter's statistics and warnings.
pub fn emit_lines(
    job: &Job,
    dialect: Dialect,
    options: &EmitOptions<'_>,
) -> Result<(Vec<NcLine>, EmitStats), EmitError> {
    let mut lines = Vec::new();
    let stats = emit(job, dialect, options, &mut |l: &NcLine| {
        lines.push(l.clone());
        Ok(())
    })?;
    Ok((lines, stats))
}

/// The whole program as one string, one `\n` after every line. For tests and small jobs.
pub fn emit_to_string(job: &Job, dialect: Dialect) -> Result<String, EmitError> {
    emit_to_string_with(job, dialect, &EmitOptions::default())
}

/// [`emit_to_string`] with options.
pub fn emit_to_string_with(
    job: &Job,
    dialect: Dialect,
    options: &EmitOptions<'_>,
) -> Result<String, EmitError> {
    let mut out = String::new();
    emit(job, dialect, options, &mut |l: &NcLine| {
        out.push_str(&l.text);
        out.push('\n');
        Ok(())
    })?;
    Ok(out)
}

/// [`emit_to_string`]'s lines handed to `each` one at a time instead (the controller models of
/// `lase plan`, which read a program line by line and never hold it, issue 18): exactly the
/// lines `emit_to_string(job, dialect)?.lines()` yields. `facts`: the job was planned in
/// windows ([`emit_planned`]). Stops at the first line `each` refuses, with its reason; an
/// emit error is given as its text.
pub fn emit_nc_lines(
    job: &Job,
    facts: Option<&PlanFacts>,
    dialect: Dialect,
    each: &mut dyn FnMut(&str) -> Result<(), String>,
) -> Result<(), String> {
    let mut refused = None;
    let emitted = emit_with(
        job,
        facts,
        dialect,
        &EmitOptions::default(),
        &mut |l: &NcLine| {
            // `str::lines` of the text with its `\n`: split at each `\n`, a `\r` before it
            // dropped.
            for raw in l.text.split('\n') {
                if let Err(why) = each(raw.strip_suffix('\r').unwrap_or(raw)) {
                    refused = Some(why);
                    return Err(std::io::Error::other("refused"));
                }
            }
            Ok(())
        },
    );
    match (refused, emitted) {
        (Some(why), _) => Err(why),
        (None, Err(e)) => Err(e.to_string()),
        (None, Ok(_)) => Ok(()),
    }
}
