//! From a recipe file on disk to a planned job: the file system side of the pipeline
//! (imports, machine files) and the one place where diagnostics meet their source text.

use lase_lang::{CheckError, FileId, Loader, Program, SourceMap, Span};
use lase_runtime::eval::{EvalError, Evaluator, Host};
use lase_runtime::motion::{Job, MotionError};
use lase_runtime::program::ProcessProgram;
use miette::{Diagnostic, GraphicalReportHandler, GraphicalTheme};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Reads imports and machine files relative to the file that names them.
#[derive(Debug, Default)]
pub struct FsLoader;

fn resolve(importer: &str, path: &str) -> PathBuf {
    let p = Path::new(path);
    if p.is_absolute() {
        return p.to_path_buf();
    }
    Path::new(importer)
        .parent()
        .map(|d| d.join(p))
        .unwrap_or_else(|| p.to_path_buf())
}

fn read(importer: &str, path: &str) -> Result<(String, String), String> {
    let full = resolve(importer, path);
    let text = std::fs::read_to_string(&full).map_err(|e| format!("{}: {e}", full.display()))?;
    Ok((full.to_string_lossy().into_owned(), text))
}

impl Loader for FsLoader {
    fn load(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        read(importer, path)
    }
}

impl Host for FsLoader {
    fn machine_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        read(importer, path)
    }

    fn data_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        read(importer, path)
    }

    fn extension_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        read(importer, path)
    }
}

/// Everything wrong with a recipe, rendered or not.
#[derive(Debug, Default)]
pub struct Failure {
    pub diagnostics: Vec<Box<dyn Diagnostic + Send + Sync>>,
}

impl Failure {
    pub fn one(d: impl Diagnostic + Send + Sync + 'static) -> Failure {
        Failure {
            diagnostics: vec![Box::new(d)],
        }
    }

    /// Several diagnostics of one kind, in order.
    pub fn many<E: Diagnostic + Send + Sync + 'static>(v: Vec<E>) -> Failure {
        Failure {
            diagnostics: v
                .into_iter()
                .map(|e| Box::new(e) as Box<dyn Diagnostic + Send + Sync>)
                .collect(),
        }
    }
}

/// A loaded recipe: its sources and parsed modules.
#[derive(Debug)]
pub struct Recipe {
    pub map: SourceMap,
    pub main: FileId,
    pub program: Program,
    /// The Rhai extension modules and presets its `use`s load (before checking, so the
    /// checker knows their signatures); handed to the evaluator.
    pub ext: lase_runtime::ext::Extensions,
}

impl Recipe {
    /// The recipe's file name as given on the command line.
    pub fn name(&self) -> String {
        Path::new(self.map.name(self.main))
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// `file:line` of a span, for NC comments.
    pub fn locate(&self, span: Span) -> String {
        match self.map.locate(span) {
            Some((f, lc)) => {
                let name = Path::new(self.map.name(f))
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                format!("{name}:{}", lc.line)
            }
            None => String::new(),
        }
    }
}

/// Reads a recipe and parses it with its imports.
pub fn load(path: &Path) -> Result<Recipe, (SourceMap, Failure)> {
    let mut map = SourceMap::new();
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) => {
            return Err((
                map,
                Failure::one(IoError {
                    message: format!("cannot read {}: {e}", path.display()),
                }),
            ));
        }
    };
    let main = map.add(path.to_string_lossy(), text);
    let (program, errors) = lase_lang::load(&mut map, main, &mut FsLoader);
    if !errors.is_empty() {
        return Err((map, Failure::many(errors)));
    }
    let mut program = program;
    let mut ext = lase_runtime::ext::Extensions::new();
    let errors = ext.load_uses(&mut program, &mut map, &mut FsLoader);
    if !errors.is_empty() {
        return Err((map, Failure::many(errors)));
    }
    Ok(Recipe {
        map,
        main,
        program,
        ext,
    })
}

/// Checks a loaded recipe.
pub fn check(recipe: &Recipe) -> Result<(), Failure> {
    let errors: Vec<CheckError> = lase_lang::check_program(&recipe.program);
    if errors.is_empty() {
        Ok(())
    } else {
        Err(Failure::many(errors))
    }
}

/// Evaluates a checked recipe into its process program.
pub fn evaluate(recipe: &mut Recipe) -> Result<ProcessProgram, Failure> {
    let mut ev = Evaluator::new();
    ev.set_extensions(std::mem::take(&mut recipe.ext));
    let stmts = recipe.program.modules[0].stmts.clone();
    let end = Span::new(
        recipe.map.base(recipe.main) + recipe.map.text(recipe.main).len(),
        recipe.map.base(recipe.main) + recipe.map.text(recipe.main).len(),
    );
    let r: Result<ProcessProgram, EvalError> = ev
        .run(&stmts, &recipe.program, &mut recipe.map, &mut FsLoader)
        .and_then(|_| ev.program(&recipe.name(), end));
    r.map_err(Failure::one)
}

/// Plans a process program.
pub fn plan(program: ProcessProgram) -> Result<Job, Failure> {
    lase_runtime::motion::plan_program(program).map_err(|e: MotionError| Failure::one(e))
}

/// What `lase check` (and the REPL's `:check FILE`) says of a recipe that compiled.
pub fn ok_line(recipe: &Recipe, job: &Job) -> String {
    format!(
        "{}: ok — {} ops on `{}`, cycle time {:.3} s",
        recipe.name(),
        job.program.ops.len(),
        job.program.machine.name,
        lase_runtime::report::summarize(job).cycle_time_s
    )
}

/// load → check → evaluate → plan, stopping at the first phase that fails.
pub fn compile(path: &Path) -> Result<(Recipe, Job), (SourceMap, Failure)> {
    let mut recipe = load(path)?;
    if let Err(f) = check(&recipe) {
        return Err((recipe.map, f));
    }
    let program = match evaluate(&mut recipe) {
        Ok(p) => p,
        Err(f) => return Err((recipe.map, f)),
    };
    match plan(program) {
        Ok(job) => Ok((recipe, job)),
        Err(f) => Err((recipe.map, f)),
    }
}

/// A failure to read or write a file.
#[derive(Debug, thiserror::Error, Diagnostic)]
#[error("{message}")]
#[diagnostic(code(lase::io))]
pub struct IoError {
    pub message: String,
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
    for d in &failure.diagnostics {
        let with_src = WithSource { inner: &**d, map };
        if handler.render_report(&mut out, &with_src).is_err() {
            let _ = writeln!(out, "error: {d}");
        }
    }
    if n > 1 {
        let _ = writeln!(out, "{n} errors");
    }
    out
}

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
