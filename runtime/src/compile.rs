//! The pipeline from a recipe file to a planned job, in one place: load (the recipe and its
//! imports) → `use` (extension modules and presets) → check → evaluate → validate (the
//! laser's limits) → plan. The `lase` binary, its REPL and every test go through it; each
//! stage is callable alone too (the REPL runs them line by line, `lase check` stops before
//! emitting).
//!
//! Files come through one trait, [`Files`]: [`FsFiles`] reads the file system (regular files
//! only, at most [`MAX_FILE_BYTES`]), [`MemFiles`] serves a map of names for tests. Both serve
//! the language's `Loader` (imports) and the evaluator's `Host` (machine files, data files,
//! extensions). Stock machines, modules and presets (`machine xy_table`, `use stdlib::cams`)
//! never reach them.
//!
//! A phase that fails ends the pipeline with its diagnostics, boxed into a [`Failure`], next to
//! the source map they point into.

use crate::eval::{EvalError, Evaluator, Host};
use crate::ext::Extensions;
use crate::motion::{Job, plan_program};
use crate::program::ProcessProgram;
use lase_lang::ast::{Module, Stmt};
use lase_lang::{FileId, Loader, Program, SourceMap, Span};
use miette::Diagnostic;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

// ------------------------------------------------------------------ files

/// Where a recipe's files come from.
pub trait Files {
    /// Reads `path` as written in the file named `importer` (relative to it, unless absolute;
    /// `importer` is empty for the main recipe). Returns the resolved name (what diagnostics
    /// show) and the text, or why it cannot.
    fn read(&mut self, importer: &str, path: &str) -> Result<(String, String), String>;
    /// Reads `path` as bytes (an image to engrave, a font), resolved as [`Files::read`] does.
    fn read_bytes(&mut self, importer: &str, path: &str) -> Result<(String, Vec<u8>), String>;
}

/// Every file the evaluator asks for (machine, data, extension) is read the same way.
impl<F: Files> Host for F {
    fn machine_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        self.read(importer, path)
    }

    fn data_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        self.read(importer, path)
    }

    fn extension_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        self.read(importer, path)
    }

    fn binary_file(&mut self, importer: &str, path: &str) -> Result<(String, Vec<u8>), String> {
        self.read_bytes(importer, path)
    }
}

/// [`Files`] as the language's `Loader` (the orphan rule keeps a blanket impl out).
struct Imports<'a, F>(&'a mut F);

impl<F: Files> Loader for Imports<'_, F> {
    fn load(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        self.0.read(importer, path)
    }
}

/// The largest file lase reads: far above any recipe, machine file or drawing, far below what
/// would exhaust memory (`import "/dev/zero"` is refused, not read until the kernel kills us).
pub const MAX_FILE_BYTES: u64 = 64 * 1024 * 1024;

/// The file system: paths relative to the file that names them.
#[derive(Debug, Default, Clone, Copy)]
pub struct FsFiles;

impl Files for FsFiles {
    fn read(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let full = resolve(importer, path);
        let shown = full.to_string_lossy().into_owned();
        let text = read_regular(Path::new(&full)).map_err(|e| format!("{shown}: {e}"))?;
        Ok((shown, text))
    }

    fn read_bytes(&mut self, importer: &str, path: &str) -> Result<(String, Vec<u8>), String> {
        let full = resolve(importer, path);
        let shown = full.to_string_lossy().into_owned();
        let bytes = read_regular_bytes(Path::new(&full)).map_err(|e| format!("{shown}: {e}"))?;
        Ok((shown, bytes))
    }
}

/// `path` next to `importer` (its directory), as written when absolute or when `importer`
/// has no directory.
fn resolve(importer: &str, path: &str) -> std::path::PathBuf {
    let p = Path::new(path);
    if p.is_absolute() {
        return p.to_path_buf();
    }
    Path::new(importer)
        .parent()
        .map(|d| d.join(p))
        .unwrap_or_else(|| p.to_path_buf())
}

/// The IO limits of every file lase reads: a regular file (not a device, a FIFO or a
/// directory, which could be endless or block), at most [`MAX_FILE_BYTES`] (checked while
/// reading too, in case it grows), UTF-8 (the first bad byte located).
fn read_regular(path: &Path) -> Result<String, String> {
    let bytes = read_regular_bytes(path)?;
    String::from_utf8(bytes).map_err(|e| {
        let good = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = good.iter().filter(|&&b| b == b'\n').count() + 1;
        let col = good.len() - good.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1) + 1;
        format!("not UTF-8 text (line {line}, byte {col} of the line)")
    })
}

/// [`read_regular`]'s limits but the UTF-8 check: the bytes of a binary file.
fn read_regular_bytes(path: &Path) -> Result<Vec<u8>, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let meta = file.metadata().map_err(|e| e.to_string())?;
    if !meta.is_file() {
        return Err("not a regular file".into());
    }
    let too_big = || {
        format!(
            "larger than the {} MiB lase reads from one file",
            MAX_FILE_BYTES / (1024 * 1024)
        )
    };
    if meta.len() > MAX_FILE_BYTES {
        return Err(too_big());
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(MAX_FILE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_FILE_BYTES {
        return Err(too_big());
    }
    Ok(bytes)
}

/// Files from a map of names to texts, for tests: names resolve as on the file system
/// (relative to the importing file's directory), so a recipe and its imports run unchanged.
#[derive(Debug, Default, Clone)]
pub struct MemFiles {
    files: HashMap<String, String>,
    blobs: HashMap<String, Vec<u8>>,
}

impl MemFiles {
    pub fn new<N: Into<String>, T: Into<String>>(files: impl IntoIterator<Item = (N, T)>) -> Self {
        MemFiles {
            files: files
                .into_iter()
                .map(|(n, t)| (n.into(), t.into()))
                .collect(),
            blobs: HashMap::new(),
        }
    }

    /// Adds (or replaces) a file.
    pub fn insert(&mut self, name: impl Into<String>, text: impl Into<String>) {
        self.files.insert(name.into(), text.into());
    }

    /// Adds (or replaces) a binary file (an image).
    pub fn insert_bytes(&mut self, name: impl Into<String>, bytes: impl Into<Vec<u8>>) {
        self.blobs.insert(name.into(), bytes.into());
    }
}

impl Files for MemFiles {
    fn read(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let name = resolve(importer, path).to_string_lossy().into_owned();
        match self.files.get(&name) {
            Some(text) => Ok((name, text.clone())),
            None => Err(format!("no file {name}")),
        }
    }

    /// A file's bytes: blobs and texts from the map; a name not in the map given by an absolute
    /// path (a system font in a test) is read from the disk under the usual limits.
    fn read_bytes(&mut self, importer: &str, path: &str) -> Result<(String, Vec<u8>), String> {
        let name = resolve(importer, path).to_string_lossy().into_owned();
        match (self.blobs.get(&name), self.files.get(&name)) {
            (Some(b), _) => Ok((name, b.clone())),
            (None, Some(t)) => Ok((name, t.clone().into_bytes())),
            (None, None) if Path::new(path).is_absolute() => FsFiles.read_bytes(importer, path),
            (None, None) => Err(format!("no file {name}")),
        }
    }
}

// ------------------------------------------------------------------ failures

/// Everything wrong with a recipe: the diagnostics of the phase that failed, in order. Render
/// them against the recipe's [`SourceMap`].
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

    /// The diagnostics of type `E` (a test's look at what failed).
    pub fn of<E: Diagnostic + 'static>(&self) -> Vec<&E> {
        self.diagnostics
            .iter()
            .filter_map(|d| (&**d as &(dyn std::error::Error + 'static)).downcast_ref::<E>())
            .collect()
    }

    /// Each diagnostic's code, in order.
    pub fn codes(&self) -> Vec<String> {
        self.diagnostics
            .iter()
            .map(|d| d.code().map(|c| c.to_string()).unwrap_or_default())
            .collect()
    }
}

/// One line per diagnostic, `code: message` (no source text: see the binary's renderer).
impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for d in &self.diagnostics {
            match d.code() {
                Some(c) => writeln!(f, "{c}: {d}")?,
                None => writeln!(f, "{d}")?,
            }
        }
        Ok(())
    }
}

/// A failure to read or write a file.
#[derive(Debug, thiserror::Error, Diagnostic)]
#[error("{message}")]
#[diagnostic(code(lase::io))]
pub struct IoError {
    pub message: String,
}

// ------------------------------------------------------------------ stages

/// A loaded recipe: its sources and parsed modules.
#[derive(Debug)]
pub struct Recipe {
    pub map: SourceMap,
    pub main: FileId,
    pub program: Program,
    /// The Rhai extension modules and presets its `use`s load (before checking, so the
    /// checker knows their signatures); handed to the evaluator.
    pub ext: Extensions,
}

impl Recipe {
    /// The recipe's file name, without its directory.
    pub fn name(&self) -> String {
        file_name(self.map.name(self.main))
    }

    /// `file:line` of a span, for NC comments.
    pub fn locate(&self, span: Span) -> String {
        locate_in(&self.map, span)
    }

    /// The empty span at the end of the main file (where a missing `machine` is reported).
    fn end(&self) -> Span {
        let end = self.map.base(self.main) + self.map.text(self.main).len();
        Span::new(end, end)
    }
}

/// [`Recipe::locate`] from the source map alone, which (unlike the recipe, whose extensions
/// hold Rhai's single-threaded values) can be shared with the emitter's thread while
/// `lase run` streams.
pub fn locate_in(map: &SourceMap, span: Span) -> String {
    match map.locate(span) {
        Some((f, lc)) => format!("{}:{}", file_name(map.name(f)), lc.line),
        None => String::new(),
    }
}

fn file_name(name: &str) -> String {
    Path::new(name)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Reads the recipe at `path` and parses it with its imports, then loads what its `use`s
/// name. Stops after the first of the three that fails.
pub fn load(files: &mut impl Files, path: &str) -> Result<Recipe, (SourceMap, Failure)> {
    let mut map = SourceMap::new();
    let text = match files.read("", path) {
        Ok((_, text)) => text,
        Err(reason) => {
            let message = format!("cannot read {reason}");
            return Err((map, Failure::one(IoError { message })));
        }
    };
    // The name as given (not as resolved), so diagnostics show what the user typed.
    let main = map.add(path, text);
    let (mut program, errors) = lase_lang::load(&mut map, main, &mut Imports(&mut *files));
    if !errors.is_empty() {
        return Err((map, Failure::many(errors)));
    }
    let mut ext = Extensions::new();
    let errors = ext.load_uses(&mut program, &mut map, files);
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

/// Loads what one more input (`stmts`, parsed from `file`: a REPL line) imports into
/// `program`, then what its `use`s name into `ext` (recording their declarations in
/// `program.uses` for the checker).
pub fn load_input(
    program: &mut Program,
    map: &mut SourceMap,
    file: FileId,
    stmts: &[Stmt],
    ext: &mut Extensions,
    files: &mut impl Files,
) -> Result<(), Failure> {
    let mut errors = Vec::new();
    lase_lang::resolve_imports(
        program,
        map,
        file,
        stmts,
        &mut Imports(&mut *files),
        &mut errors,
        &mut vec![file],
    );
    if !errors.is_empty() {
        return Err(Failure::many(errors));
    }
    let mut with_input = program.clone();
    with_input.modules.push(Module {
        file,
        stmts: stmts.to_vec(),
    });
    let errors = ext.load_uses(&mut with_input, map, files);
    if !errors.is_empty() {
        return Err(Failure::many(errors));
    }
    program.uses = with_input.uses;
    Ok(())
}

/// Checks a loaded recipe: names, units, types (every error found).
pub fn check(recipe: &Recipe) -> Result<(), Failure> {
    let errors = lase_lang::check_program(&recipe.program);
    if errors.is_empty() {
        Ok(())
    } else {
        Err(Failure::many(errors))
    }
}

/// Runs a checked recipe's statements; the evaluator holds the session it leaves (its
/// bindings, machine and ops).
pub fn run(recipe: &mut Recipe, files: &mut impl Files) -> Result<Evaluator, EvalError> {
    let mut ev = Evaluator::new();
    ev.set_extensions(std::mem::take(&mut recipe.ext));
    let stmts = recipe.program.modules[0].stmts.clone();
    ev.run(&stmts, &recipe.program, &mut recipe.map, files)?;
    Ok(ev)
}

/// Evaluates a checked recipe into its process program and holds it to the machine's laser
/// ([`validate`]).
pub fn evaluate(recipe: &mut Recipe, files: &mut impl Files) -> Result<ProcessProgram, Failure> {
    let program = run(recipe, files)
        .and_then(|ev| ev.into_program(&recipe.name(), recipe.end()))
        .map_err(Failure::one)?;
    validate(&program)?;
    Ok(program)
}

/// [`ProcessProgram::validate`]: laser power and pulse rates within the machine's laser. Run
/// again after anything changes the ops (the REPL's overrides).
pub fn validate(program: &ProcessProgram) -> Result<(), Failure> {
    program.validate().map_err(Failure::many)
}

/// Plans a process program through the machine's kinematics.
pub fn plan(program: ProcessProgram) -> Result<Job, Failure> {
    plan_program(program).map_err(Failure::one)
}

/// [`plan`] in windows (`motion::plan_program_windows`): each window of the plan goes to `each`
/// with the program as planned, and the job returned holds no segments.
pub fn plan_in_windows(
    program: ProcessProgram,
    each: impl FnMut(&ProcessProgram, crate::planner::Plan),
) -> Result<(Job, crate::planner::Planned), Failure> {
    crate::motion::plan_program_windows(program, each).map_err(Failure::one)
}

/// load → `use` → check → evaluate → validate → plan, stopping at the first phase that fails.
pub fn compile(files: &mut impl Files, path: &str) -> Result<(Recipe, Job), (SourceMap, Failure)> {
    let mut recipe = load(files, path)?;
    if let Err(f) = check(&recipe) {
        return Err((recipe.map, f));
    }
    let program = match evaluate(&mut recipe, files) {
        Ok(p) => p,
        Err(f) => return Err((recipe.map, f)),
    };
    match plan(program) {
        Ok(job) => Ok((recipe, job)),
        Err(f) => Err((recipe.map, f)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mem_files_resolve_like_the_file_system() {
        let mut f = MemFiles::new([("lib/a.lase", "x"), ("b.lase", "y")]);
        assert_eq!(f.read("", "lib/a.lase").unwrap().0, "lib/a.lase");
        assert_eq!(f.read("main.lase", "b.lase").unwrap().1, "y");
        assert_eq!(
            f.read("lib/a.lase", "c.lase").unwrap_err(),
            "no file lib/c.lase"
        );
    }

    #[test]
    fn the_file_system_reads_regular_files_only() {
        let dir = tempfile::tempdir().unwrap();
        let e = FsFiles.read("", &dir.path().to_string_lossy()).unwrap_err();
        assert!(e.ends_with("not a regular file"), "{e}");
        let bad = dir.path().join("bad.lase");
        std::fs::write(&bad, b"machine xy_table\nlet \xff = 1\n").unwrap();
        let e = FsFiles.read("", &bad.to_string_lossy()).unwrap_err();
        assert!(
            e.ends_with("not UTF-8 text (line 2, byte 5 of the line)"),
            "{e}"
        );
        #[cfg(unix)]
        {
            let e = FsFiles.read("", "/dev/zero").unwrap_err();
            assert!(e.ends_with("not a regular file"), "{e}");
        }
    }

    #[test]
    fn a_recipe_compiles_from_memory_with_its_imports() {
        let mut files = MemFiles::new([
            (
                "main.lase",
                "import \"lib/ring.lase\"\nmachine xy_table\nlaser { power 5 W }\nring(3 mm)\n",
            ),
            (
                "lib/ring.lase",
                "fn ring(r: length) {\n  follow profile circle(center: (0, 0), radius: r) at 5 mm/s\n}\n",
            ),
        ]);
        let (recipe, job) = compile(&mut files, "main.lase").unwrap();
        assert_eq!(recipe.name(), "main.lase");
        assert!(!job.program.ops.is_empty());
        let Err((_, f)) = compile(&mut files, "missing.lase") else {
            panic!()
        };
        assert_eq!(f.codes(), ["lase::io"]);
    }

    #[test]
    fn validate_holds_time_pulses_to_the_laser() {
        // 1 µs between pulses is 1 MHz; the xy_table's laser gives 100 kHz.
        let mut files = MemFiles::new([(
            "t.lase",
            "machine xy_table\nlaser { power 5 W }\npulse interval 1 us\nfollow profile line((0, 0), (5 mm, 0)) at 5 mm/s\n",
        )]);
        let Err((map, f)) = compile(&mut files, "t.lase") else {
            panic!("a 1 MHz pulse rate was accepted")
        };
        assert_eq!(f.codes(), ["lase::eval::pulse_rate"]);
        let e = f.of::<crate::program::LaserLimit>()[0];
        assert!(map.snippet(e.span()).starts_with("follow"), "{e}");
    }
}
