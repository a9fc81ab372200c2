//! The lase recipe language: grammar, syntax tree with spans, unit and name checking, and the
//! diagnostics of those phases.
//!
//! Architecture invariant: this crate does no IO and knows nothing of machines. Imported
//! files arrive through the [`Loader`] trait that the caller implements.

pub mod ast;
pub mod check;
pub mod diag;
pub mod parser;
pub mod schema;
pub mod span;
pub mod units;

pub use check::{Checker, Ty, check_program};

/// Recursive walks over the syntax (building it, checking it, evaluating it) continue on a new
/// stack segment of `STACK_SEGMENT` bytes when less than `STACK_RED_ZONE` is left: a recipe
/// nests as deep as its author likes (or a function calls itself up to the evaluator's depth
/// limit) without overflowing a thread's stack, whatever a build's frame sizes.
pub const STACK_RED_ZONE: usize = 256 * 1024;
pub const STACK_SEGMENT: usize = 4 * 1024 * 1024;
pub use diag::{CheckError, ParseError};
pub use span::{FileId, LineCol, SourceMap, Span};

use ast::{Module, Stmt, StmtKind};
use std::collections::HashMap;

/// Supplies the text of imported files. The binary reads the file system; tests use a map.
pub trait Loader {
    /// Resolves `path` as written in `importer` (a file name in the source map) and returns
    /// the resolved file name and its text.
    fn load(&mut self, importer: &str, path: &str) -> Result<(String, String), String>;
}

/// What an `import` resolved to.
#[derive(Debug, Clone, PartialEq)]
pub enum Resolved {
    /// An index into [`Program::modules`].
    Module(usize),
    /// It could not be loaded; the error has been reported.
    Failed,
}

/// A recipe and every file it imports, parsed. `modules[0]` is the main recipe.
#[derive(Debug, Clone, Default)]
pub struct Program {
    pub modules: Vec<Module>,
    /// Each import statement, keyed by the start offset of its path literal.
    pub imports: HashMap<u32, Resolved>,
    /// What each `use` statement brings in, keyed by the start offset of its path. The caller
    /// fills it before checking (this crate reads no files and runs no Rhai): the runtime's
    /// `ext` module loads the extension modules and presets and reports their declarations.
    pub uses: HashMap<u32, UseExports>,
}

/// The declarations a `use` brings into scope: functions of a Rhai extension module (with the
/// signatures their doc comments declare) and named values (a process preset).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UseExports {
    pub fns: Vec<ExtSig>,
    pub vars: Vec<(String, Ty)>,
}

/// The declared signature of an extension function: the checker types its calls like those
/// of a recipe `fn`, and the evaluator converts values at the boundary by it.
#[derive(Debug, Clone, PartialEq)]
pub struct ExtSig {
    pub name: String,
    pub params: Vec<(String, Ty)>,
    pub ret: Ty,
    /// The doc comment, without the signature line.
    pub doc: String,
}

/// Parses the main file and, through `loader`, every file it imports (each once). Returns the
/// program and every parse/import error found (at most one syntax error per file).
pub fn load(
    map: &mut SourceMap,
    main: FileId,
    loader: &mut dyn Loader,
) -> (Program, Vec<ParseError>) {
    let mut program = Program::default();
    let mut errors = Vec::new();
    match parser::parse_recipe(map.text(main), main, map.base(main)) {
        Ok(m) => {
            program.modules.push(m);
            let stmts = program.modules[0].stmts.clone();
            resolve_imports(
                &mut program,
                map,
                main,
                &stmts,
                loader,
                &mut errors,
                &mut vec![main],
            );
        }
        Err(e) => {
            program.modules.push(Module {
                file: main,
                stmts: Vec::new(),
            });
            errors.push(e);
        }
    }
    (program, errors)
}

/// Loads the imports that `stmts` (parsed from `file`) contain, recursively. The REPL calls it
/// for each line it reads.
pub fn resolve_imports(
    program: &mut Program,
    map: &mut SourceMap,
    file: FileId,
    stmts: &[Stmt],
    loader: &mut dyn Loader,
    errors: &mut Vec<ParseError>,
    stack: &mut Vec<FileId>,
) {
    let mut imports = Vec::new();
    collect_imports(stmts, &mut imports);
    for path in imports {
        let importer = map.name(file).to_string();
        let (name, text) = match loader.load(&importer, &path.value) {
            Ok(v) => v,
            Err(reason) => {
                errors.push(ParseError::Import {
                    path: path.value.clone(),
                    reason,
                    span: path.span,
                });
                program.imports.insert(path.span.start, Resolved::Failed);
                continue;
            }
        };
        if let Some(existing) = map.find(&name) {
            if stack.contains(&existing) {
                let chain = stack
                    .iter()
                    .map(|f| map.name(*f).to_string())
                    .collect::<Vec<_>>()
                    .join(" → ");
                errors.push(ParseError::ImportCycle {
                    path: path.value.clone(),
                    chain,
                    span: path.span,
                });
                program.imports.insert(path.span.start, Resolved::Failed);
                continue;
            }
            if let Some(idx) = program.modules.iter().position(|m| m.file == existing) {
                program
                    .imports
                    .insert(path.span.start, Resolved::Module(idx));
                continue;
            }
        }
        let id = map.add(name, text);
        match parser::parse_recipe(map.text(id), id, map.base(id)) {
            Ok(m) => {
                let sub = m.stmts.clone();
                program.modules.push(m);
                let idx = program.modules.len() - 1;
                program
                    .imports
                    .insert(path.span.start, Resolved::Module(idx));
                stack.push(id);
                resolve_imports(program, map, id, &sub, loader, errors, stack);
                stack.pop();
            }
            Err(e) => {
                errors.push(e);
                program.imports.insert(path.span.start, Resolved::Failed);
            }
        }
    }
}

fn collect_imports(stmts: &[Stmt], out: &mut Vec<ast::StrLit>) {
    for s in stmts {
        match &s.kind {
            StmtKind::Import(p) => out.push(p.clone()),
            StmtKind::If { then, els, .. } => {
                collect_imports(then, out);
                if let Some(e) = els {
                    collect_imports(e, out);
                }
            }
            StmtKind::For { body, .. } => collect_imports(body, out),
            StmtKind::Fn(f) => collect_imports(&f.body, out),
            _ => {}
        }
    }
}

/// A loader with no files, for recipes that import nothing.
#[derive(Debug, Default)]
pub struct NoImports;

impl Loader for NoImports {
    fn load(&mut self, _importer: &str, path: &str) -> Result<(String, String), String> {
        Err(format!("imports are not available here (\"{path}\")"))
    }
}

/// Parses and checks a recipe given as text, with no imports: the quick path for tests and
/// tools.
pub fn check_source(
    name: &str,
    text: &str,
) -> (SourceMap, Program, Vec<ParseError>, Vec<CheckError>) {
    let mut map = SourceMap::new();
    let id = map.add(name, text);
    let (program, perr) = load(&mut map, id, &mut NoImports);
    let cerr = if perr.iter().any(|e| matches!(e, ParseError::Syntax { span, .. } if map.file_of(span.start as usize) == Some(id))) {
        Vec::new()
    } else {
        check_program(&program)
    };
    (map, program, perr, cerr)
}
