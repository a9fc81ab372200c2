//! The checker: names, units and types, before anything is evaluated.
//!
//! It walks the whole recipe once and collects every error it can (it never stops at the
//! first), recovering with [`Ty::Unknown`] so one mistake does not cascade into many. Units
//! are checked by dimensional analysis over [`Dim`]; a literal `0` fits any dimension, any
//! other bare number is a plain count. Function parameters without an annotation are
//! `Unknown` and checked again, at run time, by the evaluator.
//!
//! This file holds the types and the checker's state and scopes; the walk is split by what
//! it checks: `stmt` (statements, functions, imports, settings), `expr` (expressions and
//! operators), `call` (argument binding) and `expect` (type expectations and their help).
//! The checker reads the [`schema`] tables; the schema knows nothing of the checker.

mod call;
mod expect;
mod expr;
mod stmt;

use crate::Program;
use crate::ast::*;
use crate::diag::CheckError;
use crate::schema;
use crate::span::Span;
use crate::units::{self, Dim};
use std::collections::HashMap;

/// A static type.
#[derive(Debug, Clone, PartialEq)]
pub enum Ty {
    Num(Dim),
    /// The literal `0`: a number of any dimension.
    Zero,
    Bool,
    Str,
    Point,
    List(Box<Ty>),
    Profile,
    /// No value (a function without `return`).
    Nothing,
    /// Not known statically; checked at run time.
    Unknown,
}

impl Ty {
    /// "a length", "a list of points", ...
    pub fn describe(&self) -> String {
        match self {
            Ty::Num(d) => d.describe(),
            Ty::Zero => "zero".into(),
            Ty::Bool => "a bool".into(),
            Ty::Str => "a string".into(),
            Ty::Point => "a point".into(),
            Ty::List(t) => match **t {
                Ty::Unknown => "a list".into(),
                Ty::Point => "a list of points".into(),
                ref t => format!("a list of {}", t.describe().trim_start_matches("a ")),
            },
            Ty::Profile => "a profile".into(),
            Ty::Nothing => "nothing".into(),
            Ty::Unknown => "a value".into(),
        }
    }

    /// The type a type annotation names (`length`, `point`, `list`, ...).
    pub fn from_name(name: &str) -> Option<Ty> {
        Some(match name {
            "bool" => Ty::Bool,
            "string" => Ty::Str,
            "point" => Ty::Point,
            "profile" => Ty::Profile,
            "list" => Ty::List(Box::new(Ty::Unknown)),
            n => Ty::Num(units::dim_by_name(n)?),
        })
    }

    fn is_numeric(&self) -> bool {
        matches!(self, Ty::Num(_) | Ty::Zero | Ty::Unknown)
    }
}

#[derive(Debug, Clone)]
struct FnSig {
    params: Vec<(String, Ty)>,
    ret: Ty,
    span: Span,
}

/// What an imported module defines: its variables and functions.
type Exports = (HashMap<String, Ty>, HashMap<String, FnSig>);

/// Where a statement stands, which decides what it may do.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Place {
    /// The main recipe (or a REPL session), at top level.
    Main,
    /// Inside `if`/`for` of the main recipe.
    Nested,
    /// A function body.
    Function,
    /// An imported file: definitions only.
    Import,
}

/// The checker's state. A REPL session keeps one alive across lines.
#[derive(Debug)]
pub struct Checker {
    program: Program,
    errors: Vec<CheckError>,
    scopes: Vec<HashMap<String, Ty>>,
    fns: HashMap<String, FnSig>,
    /// Return types seen in the function being checked.
    returns: Vec<Vec<Ty>>,
    /// Modules already checked, with what they export.
    checked_modules: HashMap<usize, Exports>,
}

/// Checks a whole program; the main module is `program.modules[0]`.
pub fn check_program(program: &Program) -> Vec<CheckError> {
    let mut c = Checker::new(program.clone());
    if let Some(m) = program.modules.first() {
        c.check_stmts(&m.stmts.clone());
    }
    c.take_errors()
}

impl Checker {
    pub fn new(program: Program) -> Checker {
        let mut globals = HashMap::new();
        for (name, _, _) in schema::CONSTANTS {
            globals.insert((*name).to_string(), Ty::Num(Dim::NONE));
        }
        Checker {
            program,
            errors: Vec::new(),
            scopes: vec![globals],
            fns: HashMap::new(),
            returns: Vec::new(),
            checked_modules: HashMap::new(),
        }
    }

    /// Lets a session checker see a newer version of the (growing) program.
    pub fn set_program(&mut self, program: Program) {
        self.program = program;
    }

    /// The errors found so far, in source order; clears them.
    pub fn take_errors(&mut self) -> Vec<CheckError> {
        let mut e = std::mem::take(&mut self.errors);
        e.sort_by_key(|e| (e.span().start, e.span().end));
        e
    }

    /// Names in scope (variables and functions), for completion.
    pub fn names(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .scopes
            .iter()
            .flat_map(|s| s.keys().cloned())
            .chain(self.fns.keys().cloned())
            .collect();
        v.sort();
        v.dedup();
        v
    }

    /// The static type of an expression in the current scope (the REPL checks a bare
    /// expression this way).
    pub fn check_expr_stmt(&mut self, e: &Expr) -> Ty {
        self.expr(e)
    }

    /// Checks top-level statements of the main recipe (or one REPL line).
    pub fn check_stmts(&mut self, stmts: &[Stmt]) {
        self.block(stmts, Place::Main, false);
    }

    fn err(&mut self, e: CheckError) {
        self.errors.push(e);
    }

    fn lookup(&self, name: &str) -> Option<&Ty> {
        self.scopes.iter().rev().find_map(|s| s.get(name))
    }

    fn bind(&mut self, name: &str, ty: Ty) {
        self.scopes
            .last_mut()
            .expect("there is always a scope")
            .insert(name.to_string(), ty);
    }

    fn all_names(&self) -> Vec<&str> {
        self.scopes
            .iter()
            .flat_map(|s| s.keys().map(String::as_str))
            .chain(self.fns.keys().map(String::as_str))
            .chain(schema::BUILTINS.iter().map(|b| b.name))
            .collect()
    }
}

/// Types that may stand in one list or be compared.
fn same_kind(a: &Ty, b: &Ty) -> bool {
    match (a, b) {
        (Ty::Unknown, _) | (_, Ty::Unknown) => true,
        (Ty::Zero, Ty::Num(_)) | (Ty::Num(_), Ty::Zero) => true,
        (Ty::List(x), Ty::List(y)) => same_kind(x, y),
        (x, y) => x == y,
    }
}
