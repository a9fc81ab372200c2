//! The binary's side of the pipeline (`lase_runtime::compile` does the work): recipe files
//! from disk, and the one place where diagnostics meet their source text and are rendered.

use lase_lang::SourceMap;
use lase_runtime::emit::Dialect;
use lase_runtime::motion::Job;
use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme};
use std::fmt::Write as _;
use std::path::Path;

pub use lase_runtime::compile::{Failure, IoError, Recipe};

/// The whole pipeline ([`lase_runtime::compile`]) on a recipe file on disk.
pub fn compile(path: &Path) -> Result<(Recipe, Job), (SourceMap, Failure)> {
    lase_runtime::compile(&mut lase_runtime::FsFiles, &path.to_string_lossy())
}

/// [`compile`] planned for the controller that runs it, whatever the machine file names
/// (`Machine::run_on`): `dialect`, or with `None` the GRBL-family one a link speaks.
pub fn compile_for(
    path: &Path,
    dialect: Option<Dialect>,
) -> Result<(Recipe, Job), (SourceMap, Failure)> {
    let (recipe, mut program) = program(path)?;
    let dialect = dialect.unwrap_or_else(|| lase_runtime::link::live_dialect(&program.machine));
    program.machine.run_on(dialect.name());
    match lase_runtime::compile::plan(program) {
        Ok(job) => Ok((recipe, job)),
        Err(f) => Err((recipe.map, f)),
    }
}

/// [`compile`] with the plan made in windows and dropped (`lase check`, issue 18): the job
/// holds no segments, only its cycle time, so a job of millions of moves is checked in
/// memory that does not grow with its plan. It also runs what `lase emit` checks before its
/// first line for the controller that runs the program (`runs_on` of the recipe's machine:
/// `--dialect`, else the machine file's, else LinuxCNC; the REPL's link), so a recipe `lase
/// check` passes is one `lase emit` writes (`emit::check_planned`); the warnings `lase emit`
/// would print come back with the job.
pub fn check(
    path: &Path,
    runs_on: impl FnOnce(&lase_runtime::machine::Machine) -> Dialect,
) -> Result<(Recipe, Job, Vec<String>), (SourceMap, Failure)> {
    let (recipe, mut program) = program(path)?;
    let dialect = runs_on(&program.machine);
    program.machine.run_on(dialect.name());
    let mut facts = lase_runtime::emit::PlanFacts::new(&program, dialect);
    let job = match lase_runtime::compile::plan_in_windows(program, |p, w| facts.window(p, &w)) {
        Ok((job, _)) => job,
        Err(f) => return Err((recipe.map, f)),
    };
    facts.finish(&job.program);
    match lase_runtime::emit::check_planned(&job, &facts, dialect) {
        Ok(warnings) => {
            let warnings = warnings.iter().map(|w| w.to_string()).collect();
            Ok((recipe, job, warnings))
        }
        Err(e) => Err((recipe.map, Failure::one(e))),
    }
}

/// A recipe file on disk evaluated into its process program, not yet planned (`lase run
/// --origin current` places it at the controller's position first).
pub fn program(
    path: &Path,
) -> Result<(Recipe, lase_runtime::program::ProcessProgram), (SourceMap, Failure)> {
    let files = &mut lase_runtime::FsFiles;
    let mut recipe = lase_runtime::compile::load(files, &path.to_string_lossy())?;
    if let Err(f) = lase_runtime::compile::check(&recipe) {
        return Err((recipe.map, f));
    }
    match lase_runtime::compile::evaluate(&mut recipe, files) {
        Ok(p) => Ok((recipe, p)),
        Err(f) => Err((recipe.map, f)),
    }
}

/// What `lase check` (and the REPL's `:check FILE`) says of a recipe that compiled.
pub fn ok_line(recipe: &Recipe, job: &Job) -> String {
    format!(
        "{}: ok — {} ops on `{}`, cycle time {:.3} s",
        recipe.name(),
        job.program.ops.len(),
        job.program.machine.name,
        lase_runtime::report::round_sig(job.cycle_time())
    )
}

/// Renders diagnostics against the recipe's sources. Colour only for a terminal; a fixed
/// width of 80 otherwise, so the output is stable for golden tests and logs.
pub fn render(map: &SourceMap, failure: &Failure, color: bool) -> String {
    let theme = if color {
        GraphicalTheme::unicode()
    } else {
        GraphicalTheme::unicode_nocolor()
    };
    let handler = GraphicalReportHandler::new_themed(theme).with_width(80);
    let mut out = String::new();
    let n = failure.diagnostics.len();
    for d in failure.diagnostics.iter().take(MAX_SHOWN) {
        let with_src = WithSource { inner: &**d, map };
        if handler.render_report(&mut out, &with_src).is_err() {
            let _ = writeln!(out, "error: {d}");
        }
    }
    if n > MAX_SHOWN {
        let _ = writeln!(
            out,
            "… and {} more errors not shown (only the first {MAX_SHOWN} are)",
            n - MAX_SHOWN
        );
    }
    if n > 1 {
        let _ = writeln!(out, "{n} errors");
    }
    out
}

/// How many diagnostics are rendered. Rendering one locates its line from the start of its
/// file, so rendering all of a generated recipe's thousands would take quadratic time, and
/// nobody reads past the first screenfuls: the rest are counted.
pub const MAX_SHOWN: usize = 50;

/// A diagnostic viewed with the recipe's source map attached.
struct WithSource<'a> {
    inner: &'a (dyn Diagnostic + Send + Sync),
    map: &'a SourceMap,
}

impl std::fmt::Debug for WithSource<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        std::fmt::Debug::fmt(self.inner, f)
    }
}

impl std::fmt::Display for WithSource<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        std::fmt::Display::fmt(self.inner, f)
    }
}

impl std::error::Error for WithSource<'_> {}

impl Diagnostic for WithSource<'_> {
    fn code<'b>(&'b self) -> Option<Box<dyn std::fmt::Display + 'b>> {
        self.inner.code()
    }
    fn severity(&self) -> Option<miette::Severity> {
        self.inner.severity()
    }
    fn help<'b>(&'b self) -> Option<Box<dyn std::fmt::Display + 'b>> {
        self.inner.help()
    }
    fn url<'b>(&'b self) -> Option<Box<dyn std::fmt::Display + 'b>> {
        self.inner.url()
    }
    fn source_code(&self) -> Option<&dyn miette::SourceCode> {
        Some(self.map)
    }
    fn labels(&self) -> Option<Box<dyn Iterator<Item = miette::LabeledSpan> + '_>> {
        self.inner.labels()
    }
    fn related<'b>(&'b self) -> Option<Box<dyn Iterator<Item = &'b dyn Diagnostic> + 'b>> {
        self.inner.related()
    }
    fn diagnostic_source(&self) -> Option<&dyn Diagnostic> {
        self.inner.diagnostic_source()
    }
}
