//! The checker: names, units and types, before anything is evaluated.
//!
//! It walks the whole recipe once and collects every error it can (it never stops at the
//! first), recovering with [`Ty::Unknown`] so one mistake does not cascade into many. Units
//! are checked by dimensional analysis over [`Dim`]; a literal `0` fits any dimension, any
//! other bare number is a plain count. Function parameters without an annotation are
//! `Unknown` and checked again, at run time, by the evaluator.

use crate::ast::*;
use crate::diag::{CheckError, did_you_mean};
use crate::schema::{self, PTy, ParamSpec, Ret, SettingSpec};
use crate::span::Span;
use crate::units::{self, Dim};
use crate::{Program, Resolved};
use std::collections::HashMap;
use std::rc::Rc;

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

    fn block(&mut self, stmts: &[Stmt], place: Place, new_scope: bool) {
        if new_scope {
            self.scopes.push(HashMap::new());
        }
        // Functions are visible in their whole block, so they may be called before (and from
        // within) their definition.
        for s in stmts {
            if let StmtKind::Fn(f) = &s.kind {
                self.declare_fn(f);
            }
        }
        for s in stmts {
            self.stmt(s, place);
        }
        if new_scope {
            self.scopes.pop();
        }
    }

    fn annotation(&mut self, ty: &Ident) -> Ty {
        Ty::from_name(&ty.name).unwrap_or_else(|| {
            self.err(CheckError::UnknownType {
                name: ty.name.clone(),
                span: ty.span,
                help: did_you_mean(&ty.name, schema::TYPE_NAMES.iter().copied())
                    .or_else(|| Some(format!("types are: {}", schema::TYPE_NAMES.join(", ")))),
            });
            Ty::Unknown
        })
    }

    fn declare_fn(&mut self, f: &FnDef) {
        if let Some(prev) = self.fns.get(&f.name.name)
            && prev.span != f.name.span
        {
            let first = prev.span;
            self.err(CheckError::Duplicate {
                name: f.name.name.clone(),
                span: f.name.span,
                first,
            });
            return;
        }
        let params = f
            .params
            .iter()
            .map(|p| {
                let ty = p.ty.as_ref().map_or(Ty::Unknown, |t| self.annotation(t));
                (p.name.name.clone(), ty)
            })
            .collect();
        let ret = f.ret.as_ref().map_or(Ty::Unknown, |t| self.annotation(t));
        self.fns.insert(
            f.name.name.clone(),
            FnSig {
                params,
                ret,
                span: f.name.span,
            },
        );
    }

    fn misplaced(&mut self, what: &str, place: &str, span: Span, help: &str) {
        self.err(CheckError::Misplaced {
            what: what.into(),
            place: place.into(),
            span,
            help: Some(help.into()),
        });
    }

    fn stmt(&mut self, s: &Stmt, place: Place) {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.stmt_here(s, place)
        })
    }

    fn stmt_here(&mut self, s: &Stmt, place: Place) {
        let in_import = place == Place::Import;
        let process_stmt = !matches!(
            s.kind,
            StmtKind::Let { .. }
                | StmtKind::Fn(_)
                | StmtKind::Import(_)
                | StmtKind::Use(_)
                | StmtKind::Return(_)
        );
        if in_import && process_stmt {
            self.misplaced(
                "a process statement",
                "in an imported file",
                s.span,
                "imported files hold definitions (`let`, `fn`) only; move this into the recipe \
                 or into a function the recipe calls",
            );
            return;
        }
        match &s.kind {
            StmtKind::Machine(_) => {
                if place != Place::Main {
                    self.misplaced(
                        "`machine`",
                        "here",
                        s.span,
                        "select the machine once, at the top level of the recipe",
                    );
                }
            }
            StmtKind::Limits(groups) => {
                for g in groups {
                    self.settings("limits", &g.settings, schema::LIMIT_SETTINGS);
                }
            }
            StmtKind::Let { name, ty, value } => {
                let t = self.expr(value);
                let t = match ty {
                    Some(ann) => {
                        let want = self.annotation(ann);
                        self.expect_ty(&t, &want, value, &format!("`{}`", name.name));
                        want
                    }
                    None => t,
                };
                let t = if t == Ty::Zero { Ty::Unknown } else { t };
                self.bind(&name.name, t);
            }
            StmtKind::Fn(f) => self.fn_body(f),
            StmtKind::Import(path) => self.import(path),
            StmtKind::Use(path) => self.use_module(path, s.span),
            StmtKind::If { cond, then, els } => {
                let t = self.expr(cond);
                self.expect_ty(&t, &Ty::Bool, cond, "the condition of `if`");
                let inner = if place == Place::Main {
                    Place::Nested
                } else {
                    place
                };
                self.block(then, inner, true);
                if let Some(e) = els {
                    self.block(e, inner, true);
                }
            }
            StmtKind::For { var, iter, body } => {
                let var_ty = match iter {
                    ForIter::Range { start, end, .. } => {
                        for e in [start, end] {
                            let t = self.expr(e);
                            self.expect_count(&t, e, "a range bound");
                        }
                        Ty::Num(Dim::NONE)
                    }
                    ForIter::Expr(e) => match self.expr(e) {
                        Ty::List(t) => *t,
                        Ty::Unknown => Ty::Unknown,
                        other => {
                            self.err(CheckError::TypeMismatch {
                                expected: "a list or a range".into(),
                                found: other.describe(),
                                context: "`for`".into(),
                                span: e.span,
                                help: Some("loop over a list `[a, b]` or a range `0..n`".into()),
                            });
                            Ty::Unknown
                        }
                    },
                };
                let inner = if place == Place::Main {
                    Place::Nested
                } else {
                    place
                };
                self.scopes.push(HashMap::new());
                self.bind(&var.name, var_ty);
                self.block(body, inner, false);
                self.scopes.pop();
            }
            StmtKind::Return(e) => {
                let t = e.as_ref().map_or(Ty::Nothing, |e| self.expr(e));
                match self.returns.last_mut() {
                    Some(r) => r.push(t),
                    None => self.misplaced(
                        "`return`",
                        "outside a function",
                        s.span,
                        "`return` ends a function; a recipe simply ends at its last line",
                    ),
                }
            }
            StmtKind::Laser(LaserStmt::Settings(set)) => {
                self.settings("laser", set, schema::LASER_SETTINGS)
            }
            StmtKind::Laser(_) => {}
            StmtKind::Pulse(PulseStmt::Settings(set)) => {
                self.settings("pulse", set, schema::PULSE_SETTINGS)
            }
            StmtKind::Pulse(PulseStmt::Off) => {}
            StmtKind::Planner(set) => self.settings("planner", set, schema::PLANNER_SETTINGS),
            StmtKind::Move { target, speed, .. } => {
                let t = self.expr(target);
                self.expect_ty(&t, &Ty::Point, target, "the target of `move`");
                if let MoveSpeed::At(v) = speed {
                    let t = self.expr(v);
                    self.expect_dim(&t, Dim::SPEED, v, "the speed of `move`");
                }
            }
            StmtKind::Follow {
                path,
                speed,
                settings,
            } => {
                let t = self.expr(path);
                self.expect_ty(&t, &Ty::Profile, path, "the path of `follow`");
                let t = self.expr(speed);
                self.expect_dim(&t, Dim::SPEED, speed, "the speed of `follow`");
                self.settings("follow", settings, schema::FOLLOW_SETTINGS);
            }
            StmtKind::Dwell(e) => {
                let t = self.expr(e);
                self.expect_dim(&t, Dim::TIME, e, "`dwell`");
            }
            StmtKind::MCode { code, .. } => {
                let t = self.expr(code);
                self.expect_count(&t, code, "an M-code number");
            }
            StmtKind::Event(_) => {}
            StmtKind::Scan {
                kind,
                region,
                settings,
            } => {
                let t = self.expr(region);
                let Some(sk) = schema::scan_kind(&kind.name) else {
                    self.err(CheckError::UnknownName {
                        name: kind.name.clone(),
                        span: kind.span,
                        help: did_you_mean(&kind.name, schema::SCAN_KINDS.iter().map(|k| k.name))
                            .or_else(|| Some("scan kinds: `scan dots`, `scan raster`".into())),
                    });
                    return;
                };
                let ok = match &t {
                    Ty::Profile | Ty::Unknown => true,
                    Ty::Point => sk.name == "dots",
                    Ty::List(inner) => match **inner {
                        Ty::Profile | Ty::Unknown => true,
                        Ty::Point => sk.name == "dots",
                        _ => false,
                    },
                    _ => false,
                };
                if !ok {
                    self.err(CheckError::TypeMismatch {
                        expected: sk.region.into(),
                        found: t.describe(),
                        context: format!("the region of `scan {}`", sk.name),
                        span: region.span,
                        help: Some(if sk.name == "dots" {
                            "e.g. `scan dots (0, 0) { rows 20, cols 30, pitch 0.2 mm, speed \
                             20 mm/s }` or `scan dots profile rect((0, 0), 4 mm, 2 mm) { ... }`"
                                .into()
                        } else {
                            "e.g. `scan raster profile rect((0, 0), 10 mm, 5 mm) { pitch \
                             0.1 mm, speed 100 mm/s }`"
                                .into()
                        }),
                    });
                }
                self.settings(&format!("scan {}", sk.name), settings, sk.settings);
            }
            StmtKind::Expr(e) => {
                self.expr(e);
            }
        }
    }

    fn fn_body(&mut self, f: &Rc<FnDef>) {
        let Some(sig) = self.fns.get(&f.name.name).cloned() else {
            return;
        };
        if sig.span != f.name.span {
            return; // a duplicate, already reported
        }
        let mut scope = HashMap::new();
        for (n, t) in &sig.params {
            scope.insert(n.clone(), t.clone());
        }
        self.scopes.push(scope);
        self.returns.push(Vec::new());
        self.block(&f.body, Place::Function, false);
        let rets = self.returns.pop().unwrap_or_default();
        self.scopes.pop();
        if sig.ret == Ty::Unknown {
            // Infer the result from the first return that says something definite.
            let inferred = rets
                .into_iter()
                .find(|t| !matches!(t, Ty::Unknown | Ty::Zero))
                .unwrap_or(Ty::Unknown);
            if let Some(s) = self.fns.get_mut(&f.name.name) {
                s.ret = inferred;
            }
        }
    }

    /// `use`: the declarations the caller resolved (see [`crate::Program::uses`]) come into
    /// scope; extension functions are typed by their declared signatures.
    fn use_module(&mut self, path: &StrLit, span: Span) {
        let Some(ex) = self.program.uses.get(&path.span.start).cloned() else {
            self.err(CheckError::Unsupported {
                what: format!("`use {}` here", path.value),
                span,
                help: Some(
                    "extension modules and presets are loaded by `lase` before checking; \
                     this tool did not load them"
                        .into(),
                ),
            });
            return;
        };
        for f in ex.fns {
            if let Some(prev) = self.fns.get(&f.name)
                && prev.span != path.span
            {
                let first = prev.span;
                self.err(CheckError::Duplicate {
                    name: f.name.clone(),
                    span: path.span,
                    first,
                });
                continue;
            }
            self.fns.insert(
                f.name,
                FnSig {
                    params: f.params,
                    ret: f.ret,
                    span: path.span,
                },
            );
        }
        for (name, ty) in ex.vars {
            self.bind(&name, ty);
        }
    }

    fn import(&mut self, path: &StrLit) {
        let Some(Resolved::Module(idx)) = self.program.imports.get(&path.span.start).cloned()
        else {
            return; // the loader has reported why it could not be loaded
        };
        if !self.checked_modules.contains_key(&idx) {
            let stmts = self.program.modules[idx].stmts.clone();
            let globals = vec![self.scopes[0].clone()];
            let saved_scopes = std::mem::replace(&mut self.scopes, globals);
            let saved_fns = std::mem::take(&mut self.fns);
            self.scopes.push(HashMap::new());
            self.block(&stmts, Place::Import, false);
            let vars = self.scopes.pop().unwrap_or_default();
            let fns = std::mem::replace(&mut self.fns, saved_fns);
            self.scopes = saved_scopes;
            self.checked_modules.insert(idx, (vars, fns));
        }
        let (vars, fns) = self.checked_modules[&idx].clone();
        for (n, t) in vars {
            self.bind(&n, t);
        }
        for (n, sig) in fns {
            self.fns.entry(n).or_insert(sig);
        }
    }

    fn settings(&mut self, stmt: &str, set: &[Setting], specs: &[SettingSpec]) {
        for s in set {
            let Some(spec) = specs.iter().find(|sp| sp.key == s.key.name) else {
                self.err(CheckError::UnknownSetting {
                    stmt: stmt.into(),
                    key: s.key.name.clone(),
                    span: s.key.span,
                    help: did_you_mean(&s.key.name, specs.iter().map(|sp| sp.key)).or_else(|| {
                        Some(format!(
                            "`{stmt}` takes: {}",
                            specs.iter().map(|sp| sp.key).collect::<Vec<_>>().join(", ")
                        ))
                    }),
                });
                if let Some(v) = &s.value {
                    self.expr(v);
                }
                continue;
            };
            self.setting_value(spec.key, spec.ty, s);
        }
    }

    fn setting_value(&mut self, key: &str, ty: PTy, s: &Setting) {
        let Some(v) = &s.value else {
            if ty != PTy::Flag {
                self.err(CheckError::MissingValue {
                    key: key.into(),
                    span: s.span,
                    help: Some(format!("`{key}` takes {}", ty.describe())),
                });
            }
            return;
        };
        if let PTy::Word(words) = ty {
            match &v.kind {
                ExprKind::Var(w) if words.contains(&w.as_str()) => {}
                _ => self.err(CheckError::TypeMismatch {
                    expected: ty.describe(),
                    found: format!("`{}`", self.snippet_of(v)),
                    context: format!("`{key}`"),
                    span: v.span,
                    help: did_you_mean(&self.snippet_of(v), words.iter().copied())
                        .or_else(|| Some(format!("write one of: {}", words.join(", ")))),
                }),
            }
            return;
        }
        let t = self.expr(v);
        self.expect_param(&t, ty, v, &format!("`{key}`"));
    }

    fn snippet_of(&self, e: &Expr) -> String {
        match &e.kind {
            ExprKind::Var(n) => n.clone(),
            _ => "this".into(),
        }
    }

    // ------------------------------------------------------------ expectations

    fn bare_number_help(e: &Expr, want: Dim) -> Option<String> {
        let unit = match want {
            d if d == Dim::LENGTH => "mm",
            d if d == Dim::SPEED => "mm/s",
            d if d == Dim::TIME => "s",
            d if d == Dim::ANGLE => "deg",
            d if d == Dim::POWER => "W",
            d if d == Dim::ACCEL => "mm/s^2",
            d if d == Dim::JERK => "mm/s^3",
            d if d == Dim::FREQUENCY => "kHz",
            d if d == Dim::ENERGY => "mJ",
            _ => return None,
        };
        match &e.kind {
            ExprKind::Number { value, unit: None } => Some(format!(
                "a bare number has no unit; write `{} {unit}`",
                units::format_number(*value)
            )),
            _ => Some(format!("give it a unit, e.g. multiply by `1 {unit}`")),
        }
    }

    fn expect_dim(&mut self, t: &Ty, want: Dim, e: &Expr, context: &str) {
        match t {
            Ty::Num(d) if *d == want => {}
            Ty::Zero | Ty::Unknown => {}
            Ty::Num(d) => self.err(CheckError::WrongDimension {
                expected: Ty::Num(want).describe(),
                found: t.describe(),
                context: context.into(),
                span: e.span,
                help: if d.is_none() {
                    Self::bare_number_help(e, want)
                } else {
                    Some(format!(
                        "{} is measured in {}; this is in {}",
                        Ty::Num(want).describe(),
                        want.base_unit(),
                        d.base_unit()
                    ))
                },
            }),
            other => self.err(CheckError::TypeMismatch {
                expected: Ty::Num(want).describe(),
                found: other.describe(),
                context: context.into(),
                span: e.span,
                help: None,
            }),
        }
    }

    fn expect_count(&mut self, t: &Ty, e: &Expr, context: &str) {
        self.expect_dim(t, Dim::NONE, e, context);
    }

    fn expect_ty(&mut self, t: &Ty, want: &Ty, e: &Expr, context: &str) {
        match (t, want) {
            (_, Ty::Unknown) | (Ty::Unknown, _) => {}
            (_, Ty::Num(d)) => self.expect_dim(t, *d, e, context),
            (Ty::List(_), Ty::List(w)) if **w == Ty::Unknown => {}
            (a, b) if a == b => {}
            (a, b) => {
                let help = match (a, b) {
                    (Ty::Point, Ty::Profile) => Some(
                        "a point is not a path; make one with `profile line(a, b)` or \
                         `profile polyline [...]`"
                            .to_string(),
                    ),
                    (Ty::List(_), Ty::Point) => {
                        Some("a point is written with parentheses: `(x, y)`".to_string())
                    }
                    _ => None,
                };
                self.err(CheckError::TypeMismatch {
                    expected: b.describe(),
                    found: a.describe(),
                    context: context.into(),
                    span: e.span,
                    help,
                })
            }
        }
    }

    fn expect_param(&mut self, t: &Ty, ty: PTy, e: &Expr, context: &str) {
        match ty {
            PTy::Dim(d) => self.expect_dim(t, d, e, context),
            PTy::Either(a, b) => match t {
                Ty::Num(d) if *d == a || *d == b => {}
                Ty::Zero | Ty::Unknown => {}
                _ => self.err(CheckError::WrongDimension {
                    expected: ty.describe(),
                    found: t.describe(),
                    context: context.into(),
                    span: e.span,
                    help: match t {
                        Ty::Num(d) if d.is_none() => Self::bare_number_help(e, a),
                        _ => None,
                    },
                }),
            },
            PTy::AnyNum => {
                if !t.is_numeric() {
                    self.err(CheckError::TypeMismatch {
                        expected: "a number".into(),
                        found: t.describe(),
                        context: context.into(),
                        span: e.span,
                        help: None,
                    })
                }
            }
            PTy::Point => self.expect_ty(t, &Ty::Point, e, context),
            PTy::Profile => self.expect_ty(t, &Ty::Profile, e, context),
            PTy::Points => self.expect_ty(t, &Ty::List(Box::new(Ty::Point)), e, context),
            PTy::List => self.expect_ty(t, &Ty::List(Box::new(Ty::Unknown)), e, context),
            PTy::Bool => self.expect_ty(t, &Ty::Bool, e, context),
            PTy::Str => self.expect_ty(t, &Ty::Str, e, context),
            PTy::Word(_) | PTy::Flag => {}
        }
    }

    // ------------------------------------------------------------ expressions

    fn expr(&mut self, e: &Expr) -> Ty {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.expr_here(e)
        })
    }

    fn expr_here(&mut self, e: &Expr) -> Ty {
        match &e.kind {
            ExprKind::Number { value, unit } => {
                if !value.is_finite() {
                    self.err(CheckError::WrongDimension {
                        expected: "a finite number".into(),
                        found: "a number too large to represent".into(),
                        context: "a literal".into(),
                        span: e.span,
                        help: Some("use a unit instead of a huge exponent".into()),
                    });
                    return Ty::Unknown;
                }
                match unit {
                    None if *value == 0.0 => Ty::Zero,
                    None => Ty::Num(Dim::NONE),
                    Some((u, span)) => match units::parse_unit(u) {
                        Ok(unit) => Ty::Num(unit.dim),
                        Err(bad) => {
                            self.err(CheckError::UnknownUnit {
                                unit: bad.atom.clone(),
                                span: *span,
                                help: bad
                                    .suggestion
                                    .map(|s| format!("did you mean `{s}`?"))
                                    .or_else(|| Some(units_help())),
                            });
                            Ty::Unknown
                        }
                    },
                }
            }
            ExprKind::Bool(_) => Ty::Bool,
            ExprKind::Str(_) => Ty::Str,
            ExprKind::Var(name) => match self.lookup(name) {
                Some(t) => t.clone(),
                None => {
                    let help = if self.fns.contains_key(name) || schema::builtin(name).is_some() {
                        Some(format!("`{name}` is a function; call it: `{name}(...)`"))
                    } else if units::parse_unit(name).is_ok() {
                        Some(format!(
                            "`{name}` is a unit; it goes right after a number on the same line: `1 {name}`"
                        ))
                    } else {
                        did_you_mean(name, self.all_names().into_iter())
                    };
                    self.err(CheckError::UnknownName {
                        name: name.clone(),
                        span: e.span,
                        help,
                    });
                    Ty::Unknown
                }
            },
            ExprKind::Point(items) => {
                if !(2..=3).contains(&items.len()) {
                    self.err(CheckError::TypeMismatch {
                        expected: "a point with 2 or 3 coordinates".into(),
                        found: format!("{} coordinates", items.len()),
                        context: "a point".into(),
                        span: e.span,
                        help: None,
                    });
                }
                for it in items {
                    let t = self.expr(it);
                    self.expect_dim(&t, Dim::LENGTH, it, "a point coordinate");
                }
                Ty::Point
            }
            ExprKind::List(items) => {
                let mut elem = Ty::Unknown;
                for it in items {
                    let t = self.expr(it);
                    match (&elem, &t) {
                        (Ty::Unknown, _) => elem = t,
                        (a, b) if same_kind(a, b) => {
                            if *a == Ty::Zero {
                                elem = t
                            }
                        }
                        (_, Ty::Unknown) => {}
                        (a, b) => self.err(CheckError::TypeMismatch {
                            expected: a.describe(),
                            found: b.describe(),
                            context: "a list item".into(),
                            span: it.span,
                            help: Some("all items of a list have one type".into()),
                        }),
                    }
                }
                if elem == Ty::Zero {
                    elem = Ty::Unknown;
                }
                Ty::List(Box::new(elem))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let l = self.expr(lhs);
                let r = self.expr(rhs);
                self.binary(*op, l, r, lhs, rhs)
            }
            ExprKind::Unary { op, expr } => {
                let t = self.expr(expr);
                match (op, &t) {
                    (UnOp::Neg, Ty::Num(_) | Ty::Zero | Ty::Point | Ty::Unknown) => t,
                    (UnOp::Not, Ty::Bool | Ty::Unknown) => Ty::Bool,
                    (UnOp::Neg, _) => {
                        self.type_err("a number or a point", &t, expr, "`-`");
                        Ty::Unknown
                    }
                    (UnOp::Not, _) => {
                        self.type_err("a bool", &t, expr, "`not`");
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Field { expr, field } => {
                let t = self.expr(expr);
                match (&t, field.name.as_str()) {
                    (Ty::Point | Ty::Unknown, "x" | "y" | "z") => Ty::Num(Dim::LENGTH),
                    (Ty::Profile, "length") => Ty::Num(Dim::LENGTH),
                    (Ty::Profile, "start" | "end") => Ty::Point,
                    (Ty::Unknown, _) => Ty::Unknown,
                    _ => {
                        let fields: &[&str] = match t {
                            Ty::Point => &["x", "y", "z"],
                            Ty::Profile => &["length", "start", "end"],
                            _ => &[],
                        };
                        self.err(CheckError::UnknownName {
                            name: format!(".{}", field.name),
                            span: field.span,
                            help: if fields.is_empty() {
                                Some(format!("{} has no fields", t.describe()))
                            } else {
                                did_you_mean(&field.name, fields.iter().copied()).or_else(|| {
                                    Some(format!("{} has: {}", t.describe(), fields.join(", ")))
                                })
                            },
                        });
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Index { expr, index } => {
                let t = self.expr(expr);
                let i = self.expr(index);
                self.expect_count(&i, index, "an index");
                match t {
                    Ty::List(elem) => *elem,
                    Ty::Unknown => Ty::Unknown,
                    other => {
                        self.type_err("a list", &other, expr, "indexing");
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Call { callee, args } => self.call(callee, args, e.span),
            ExprKind::Profile { kind, args, flags } => {
                let Some(pk) = schema::profile_kind(&kind.name) else {
                    self.err(CheckError::UnknownName {
                        name: kind.name.clone(),
                        span: kind.span,
                        help: did_you_mean(
                            &kind.name,
                            schema::PROFILE_KINDS.iter().map(|k| k.name),
                        )
                        .or_else(|| {
                            Some(format!(
                                "profiles are: {}",
                                schema::PROFILE_KINDS
                                    .iter()
                                    .filter(|k| !k.unsupported)
                                    .map(|k| k.name)
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            ))
                        }),
                    });
                    for a in args {
                        self.expr(&a.value);
                    }
                    return Ty::Profile;
                };
                if pk.unsupported {
                    self.err(CheckError::Unsupported {
                        what: format!("`profile {}`", pk.name),
                        span: kind.span,
                        help: Some(format!(
                            "{} — not available in this version; use polyline, line, arc, \
                             circle or rect",
                            pk.doc
                        )),
                    });
                    return Ty::Profile;
                }
                let name = format!("profile {}", pk.name);
                self.bind_args(&name, pk.params, args, e.span);
                for f in flags {
                    if !pk.flags.contains(&f.name.as_str()) {
                        self.err(CheckError::UnknownSetting {
                            stmt: name.clone(),
                            key: f.name.clone(),
                            span: f.span,
                            help: Some(if pk.flags.is_empty() {
                                format!("`{name}` takes no flags")
                            } else {
                                format!("`{name}` takes: {}", pk.flags.join(", "))
                            }),
                        });
                    }
                }
                if flags.iter().any(|f| f.name == "cw") && flags.iter().any(|f| f.name == "ccw") {
                    self.err(CheckError::UnknownSetting {
                        stmt: name,
                        key: "cw".into(),
                        span: e.span,
                        help: Some("give `cw` or `ccw`, not both".into()),
                    });
                }
                Ty::Profile
            }
        }
    }

    fn type_err(&mut self, expected: &str, found: &Ty, e: &Expr, context: &str) {
        self.err(CheckError::TypeMismatch {
            expected: expected.into(),
            found: found.describe(),
            context: context.into(),
            span: e.span,
            help: None,
        });
    }

    fn binary(&mut self, op: BinOp, l: Ty, r: Ty, lhs: &Expr, rhs: &Expr) -> Ty {
        use Ty::*;
        if l == Unknown || r == Unknown {
            return match op {
                BinOp::Eq
                | BinOp::Ne
                | BinOp::Lt
                | BinOp::Le
                | BinOp::Gt
                | BinOp::Ge
                | BinOp::And
                | BinOp::Or => Bool,
                _ => match (&l, &r) {
                    (Point, _) | (_, Point) if matches!(op, BinOp::Add | BinOp::Sub) => Point,
                    _ => Unknown,
                },
            };
        }
        let mismatch = |s: &mut Self, verb: &'static str| {
            s.err(CheckError::UnitMismatch {
                verb,
                op: op.symbol(),
                left: l.describe(),
                right: r.describe(),
                lhs: lhs.span,
                rhs: rhs.span,
            });
            Unknown
        };
        match op {
            BinOp::Add | BinOp::Sub | BinOp::Rem => {
                let verb = match op {
                    BinOp::Add => "add",
                    BinOp::Sub => "subtract",
                    _ => "take the remainder of",
                };
                match (&l, &r) {
                    (Num(a), Num(b)) if a == b => l.clone(),
                    (Zero, Num(_)) => r.clone(),
                    (Num(_), Zero) | (Zero, Zero) => l.clone(),
                    (Point, Point) if op != BinOp::Rem => Point,
                    (Str, Str) if op == BinOp::Add => Str,
                    _ => mismatch(self, verb),
                }
            }
            BinOp::Mul => match (&l, &r) {
                (Num(a), Num(b)) => Num(*a * *b),
                (Zero, Num(_)) => r.clone(),
                (Num(_), Zero) | (Zero, Zero) => l.clone(),
                (Point, Num(d)) | (Num(d), Point) if d.is_none() => Point,
                (Point, Zero) | (Zero, Point) => Point,
                _ => mismatch(self, "multiply"),
            },
            BinOp::Div => match (&l, &r) {
                (Num(a), Num(b)) => Num(*a / *b),
                (Zero, Num(b)) => Num(Dim::NONE / *b),
                (_, Zero) => {
                    self.err(CheckError::WrongDimension {
                        expected: "a non-zero divisor".into(),
                        found: "zero".into(),
                        context: "`/`".into(),
                        span: rhs.span,
                        help: Some("division by zero".into()),
                    });
                    Unknown
                }
                (Point, Num(d)) if d.is_none() => Point,
                _ => mismatch(self, "divide"),
            },
            BinOp::Eq | BinOp::Ne => {
                if !same_kind(&l, &r) {
                    mismatch(self, "compare");
                }
                Bool
            }
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                match (&l, &r) {
                    (Num(a), Num(b)) if a == b => {}
                    (Zero, Num(_)) | (Num(_), Zero) | (Zero, Zero) => {}
                    _ => {
                        mismatch(self, "compare");
                    }
                }
                Bool
            }
            BinOp::And | BinOp::Or => {
                if l != Bool {
                    self.type_err("a bool", &l, lhs, &format!("`{}`", op.symbol()));
                }
                if r != Bool {
                    self.type_err("a bool", &r, rhs, &format!("`{}`", op.symbol()));
                }
                Bool
            }
        }
    }

    fn call(&mut self, callee: &Ident, args: &[Arg], span: Span) -> Ty {
        if let Some(sig) = self.fns.get(&callee.name).cloned() {
            // User functions: bind by position or name, check annotated parameters.
            let mut bound: Vec<Option<Ty>> = vec![None; sig.params.len()];
            let mut positional = 0;
            for a in args {
                let t = self.expr(&a.value);
                let idx = match &a.name {
                    Some(n) => match sig.params.iter().position(|(p, _)| *p == n.name) {
                        Some(i) => i,
                        None => {
                            self.err(CheckError::UnknownArg {
                                name: callee.name.clone(),
                                arg: n.name.clone(),
                                span: n.span,
                                help: did_you_mean(
                                    &n.name,
                                    sig.params.iter().map(|(p, _)| p.as_str()),
                                ),
                            });
                            continue;
                        }
                    },
                    None => {
                        positional += 1;
                        positional - 1
                    }
                };
                if idx >= sig.params.len() {
                    continue;
                }
                let want = sig.params[idx].1.clone();
                self.expect_ty(
                    &t,
                    &want,
                    &a.value,
                    &format!("parameter `{}` of `{}`", sig.params[idx].0, callee.name),
                );
                bound[idx] = Some(t);
            }
            let missing: Vec<&str> = sig
                .params
                .iter()
                .zip(&bound)
                .filter(|(_, b)| b.is_none())
                .map(|((n, _), _)| n.as_str())
                .collect();
            if args.len() > sig.params.len() || !missing.is_empty() {
                self.err(CheckError::ArgCount {
                    name: callee.name.clone(),
                    expected: sig.params.len().to_string(),
                    found: args.len(),
                    span,
                    help: Some(format!(
                        "`{}({})`",
                        callee.name,
                        sig.params
                            .iter()
                            .map(|(n, _)| n.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )),
                });
            }
            return sig.ret.clone();
        }
        let Some(b) = schema::builtin(&callee.name) else {
            self.err(CheckError::UnknownName {
                name: callee.name.clone(),
                span: callee.span,
                help: did_you_mean(&callee.name, self.all_names().into_iter()),
            });
            for a in args {
                self.expr(&a.value);
            }
            return Ty::Unknown;
        };
        let tys = self.bind_args(b.name, b.params, args, span);
        let first = tys.first().cloned().flatten().unwrap_or(Ty::Unknown);
        // Two-operand numeric builtins need operands of one dimension.
        if matches!(b.name, "min" | "max" | "atan2")
            && let (Some(Some(x)), Some(Some(y))) = (tys.first(), tys.get(1))
            && !same_kind(x, y)
        {
            self.err(CheckError::UnitMismatch {
                verb: "compare",
                op: ",",
                left: x.describe(),
                right: y.describe(),
                lhs: args[0].value.span,
                rhs: args[1].value.span,
            });
        }
        match b.ret {
            Ret::Dim(d) => Ty::Num(d),
            Ret::Point => Ty::Point,
            Ret::Profile => Ty::Profile,
            Ret::Points => Ty::List(Box::new(Ty::Point)),
            Ret::SameAsFirst => match (first, tys.get(1).cloned().flatten()) {
                (Ty::Zero, Some(t)) => t,
                (t, _) => t,
            },
            Ret::SqrtOfFirst => match first {
                Ty::Num(d) => {
                    let even = d.length % 2 == 0
                        && d.time % 2 == 0
                        && d.angle % 2 == 0
                        && d.power % 2 == 0;
                    if even {
                        Ty::Num(Dim::new(d.length / 2, d.time / 2, d.angle / 2, d.power / 2))
                    } else {
                        self.err(CheckError::WrongDimension {
                            expected: "a quantity with even unit powers".into(),
                            found: Ty::Num(d).describe(),
                            context: "`sqrt`".into(),
                            span: args[0].value.span,
                            help: Some("sqrt of mm^2 is mm; sqrt of mm has no unit".into()),
                        });
                        Ty::Unknown
                    }
                }
                t => t,
            },
        }
    }

    /// Binds call arguments to a builtin's parameters by position or name, checks each, and
    /// returns the bound argument types in parameter order.
    fn bind_args(
        &mut self,
        name: &str,
        params: &[ParamSpec],
        args: &[Arg],
        span: Span,
    ) -> Vec<Option<Ty>> {
        let mut bound: Vec<Option<Ty>> = vec![None; params.len()];
        let mut positional = 0;
        let mut too_many = false;
        for a in args {
            let t = self.expr(&a.value);
            let idx = match &a.name {
                Some(n) => match params.iter().position(|p| p.name == n.name) {
                    Some(i) => i,
                    None => {
                        self.err(CheckError::UnknownArg {
                            name: name.into(),
                            arg: n.name.clone(),
                            span: n.span,
                            help: did_you_mean(&n.name, params.iter().map(|p| p.name)).or_else(
                                || {
                                    Some(format!(
                                        "`{name}` takes: {}",
                                        params
                                            .iter()
                                            .map(|p| p.name)
                                            .collect::<Vec<_>>()
                                            .join(", ")
                                    ))
                                },
                            ),
                        });
                        continue;
                    }
                },
                None => {
                    positional += 1;
                    positional - 1
                }
            };
            if idx >= params.len() {
                too_many = true;
                continue;
            }
            let p = params[idx];
            self.expect_param(&t, p.ty, &a.value, &format!("`{}` of `{name}`", p.name));
            bound[idx] = Some(t);
        }
        let signature = || {
            format!(
                "`{name}({})`",
                params
                    .iter()
                    .map(|p| if p.required {
                        format!("{}: {}", p.name, p.ty.describe())
                    } else {
                        format!("{}: {} (optional)", p.name, p.ty.describe())
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        if too_many {
            let req = params.iter().filter(|p| p.required).count();
            self.err(CheckError::ArgCount {
                name: name.into(),
                expected: if req == params.len() {
                    req.to_string()
                } else {
                    format!("{req} to {}", params.len())
                },
                found: args.len(),
                span,
                help: Some(signature()),
            });
        } else {
            for (p, b) in params.iter().zip(&bound) {
                if p.required && b.is_none() {
                    self.err(CheckError::MissingArg {
                        name: name.into(),
                        arg: p.name.into(),
                        span,
                        help: Some(signature()),
                    });
                }
            }
        }
        bound
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

fn units_help() -> String {
    "units: mm um cm m in · s ms us ns min · deg rad rev · W kW · Hz kHz MHz · J mJ uJ, \
     combined with / and ^ (mm/s, m/s^2)"
        .into()
}
