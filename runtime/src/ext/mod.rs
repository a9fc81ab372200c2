//! User extensions in Rhai, and the standard library modules built on them.
//!
//! The recipe language stays small; what it lacks — a cam motion law, a spot pattern, a visit
//! order, a measured-data filter — a user writes as a Rhai function and calls from a recipe:
//!
//! ```text
//! // rhai_cam_law.rhai
//! /// Lift of a cam with my law at cam angle `theta`.
//! /// lase: (theta: angle, rise: length) -> length
//! fn my_lift(theta, rise) { rise * (1.0 - cos(theta)) / 2.0 }
//!
//! // recipe.lase
//! use "rhai_cam_law.rhai"
//! let h = my_lift(30 deg, 6 mm)      // a length
//! ```
//!
//! How it fits the pipeline:
//! 1. Before checking, [`Extensions::load_uses`] resolves every `use` of the program (a
//!    `.rhai` module, a `.toml` preset, `stdlib::cams`, `stdlib::patterns`,
//!    `stdlib::presets::NAME`), adds the file to the [`SourceMap`] (so diagnostics can point
//!    into it), compiles it in the sandbox (`engine.rs`) and records the declared signatures
//!    (`sig.rs`) in [`Program::uses`]. The checker types calls to extension functions like
//!    calls to a recipe `fn`.
//! 2. The evaluator owns the [`Extensions`]; `use` makes the module's functions callable,
//!    and a call converts the arguments by the declared signature ([`Value`] → Rhai), runs
//!    the function under the sandbox's limits, and converts the result back, checking it
//!    against the declared type.
//!
//! Values across the boundary (the convention, not a registered quantity type): a number
//! crosses as a plain float **in lase's internal unit of its declared dimension** — mm, s,
//! rad, W, mm/s — and the declared dimension is checked on the recipe side (statically by
//! the checker, again at run time) and re-attached to the result. So `my_lift(30 deg, 6 mm)`
//! receives `theta = 0.5236` (rad) and `rise = 6.0` (mm), and its float result becomes a
//! length in mm. Points are the registered type `point` (`p.x`, `point(x, y)`, `+ - * /`),
//! lists are arrays, profiles the registered type `profile` with `length()`, `point_at(s)`,
//! `normal_at(s)`, `tangent_at(s)`, `curvature_at(s)`, `offset(d)`, `sample(n)`.
//!
//! Extension points:
//! - profile generators: a function returning a `profile`, typically through
//!   `polar_profile(|theta| radius, samples)` or `parametric_profile(|t| point, t0, t1, n,
//!   closed)` (closed/open interpolating splines, so normals are exact);
//! - spot patterns and visit orders for `scan raster`: a function returning `[point]`. The
//!   recipe value is a plain list of points, so `scan raster` takes it as it takes a literal
//!   list; Rust callers use [`Extensions::call`] and [`spots`];
//! - process-parameter functions (power against position, energy per spot): any function
//!   `(p: point) -> power` called from the recipe where the value is needed.

mod api;
mod engine;
mod error;
mod preset;
mod sig;

pub use api::{ExtPoint, ExtProfile};
pub use engine::{
    MAX_ARRAY, MAX_CALL_LEVELS, MAX_EXPR_DEPTH, MAX_FN_EXPR_DEPTH, MAX_MAP, MAX_OPERATIONS,
    MAX_STRING,
};
pub use error::ExtError;
pub use preset::Preset;
pub use sig::describe;

use crate::host::Host;
use crate::value::Value;
use error::{FileText, LimitText};
use lase_lang::ast::{Stmt, StmtKind, StrLit};
use lase_lang::units::Dim;
use lase_lang::{ExtSig, Program, SourceMap, Span, Ty, UseExports};
use rhai::{AST, Array, CallFnOptions, Dynamic, Engine, Scope};
use std::collections::HashMap;
use std::rc::Rc;

/// One compiled Rhai module.
struct Module {
    /// As shown in messages: `stdlib::cams` or the file name.
    name: String,
    text: Rc<str>,
    base: usize,
    ast: AST,
    fns: Vec<ExtSig>,
}

/// What one `use` refers to.
#[derive(Debug, Clone)]
enum Target {
    Module(usize),
    Preset(Rc<Preset>),
}

/// The loaded extension modules and presets of one recipe (or REPL session), the sandboxed
/// engine that runs them, and the functions `use` has made callable.
#[derive(Default)]
pub struct Extensions {
    engine: Option<Engine>,
    modules: Vec<Module>,
    /// Each `use`, keyed by the start offset of its path.
    targets: HashMap<u32, Target>,
    /// Callable now: function name → (module, signature).
    active: HashMap<String, (usize, ExtSig)>,
}

impl std::fmt::Debug for Extensions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Extensions")
            .field(
                "modules",
                &self.modules.iter().map(|m| &m.name).collect::<Vec<_>>(),
            )
            .field("active", &self.active.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Extensions {
    pub fn new() -> Extensions {
        Extensions::default()
    }

    fn engine(&mut self) -> &mut Engine {
        self.engine.get_or_insert_with(engine::sandbox)
    }

    /// Resolves every `use` of the program not resolved yet (all modules, nested blocks
    /// included), loading files through `host`, and records their declarations in
    /// [`Program::uses`] for the checker. Returns every load, syntax and signature error.
    pub fn load_uses(
        &mut self,
        program: &mut Program,
        map: &mut SourceMap,
        host: &mut dyn Host,
    ) -> Vec<ExtError> {
        let mut uses = Vec::new();
        for m in &program.modules {
            collect_uses(&m.stmts, &mut uses);
        }
        let mut errors = Vec::new();
        for path in uses {
            if program.uses.contains_key(&path.span.start) {
                continue;
            }
            match self.resolve(&path, map, host) {
                Ok(t) => {
                    program.uses.insert(path.span.start, self.exports(&t));
                    self.targets.insert(path.span.start, t);
                }
                Err(e) => errors.extend(e),
            }
        }
        errors
    }

    fn exports(&self, t: &Target) -> UseExports {
        match t {
            Target::Module(i) => UseExports {
                fns: self.modules[*i].fns.clone(),
                vars: Vec::new(),
            },
            Target::Preset(p) => UseExports {
                fns: Vec::new(),
                vars: p
                    .values
                    .iter()
                    .map(|(k, v)| (k.clone(), value_ty(v)))
                    .collect(),
            },
        }
    }

    fn resolve(
        &mut self,
        path: &StrLit,
        map: &mut SourceMap,
        host: &mut dyn Host,
    ) -> Result<Target, Vec<ExtError>> {
        let load_err = |reason: String, help: Option<String>| {
            vec![ExtError::Load {
                path: path.value.clone(),
                reason,
                span: path.span,
                help,
            }]
        };
        let (name, text, preset) = if let Some(rest) = path.value.strip_prefix("stdlib::") {
            if let Some(p) = rest.strip_prefix("presets::") {
                match lase_stdlib::preset(p) {
                    Some(t) => (format!("<stdlib>/presets/{p}.toml"), t.to_string(), true),
                    None => {
                        return Err(load_err(
                            format!("no stock preset `{p}`"),
                            Some(format!(
                                "presets: {}",
                                lase_stdlib::preset_names().collect::<Vec<_>>().join(", ")
                            )),
                        ));
                    }
                }
            } else {
                match lase_stdlib::module(rest) {
                    Some(t) => (format!("<stdlib>/lib/{rest}.rhai"), t.to_string(), false),
                    None => {
                        return Err(load_err(
                            format!("no standard library module `{rest}`"),
                            lase_lang::diag::did_you_mean(rest, lase_stdlib::module_names())
                                .or_else(|| {
                                    Some(format!(
                                        "modules: {}; presets: stdlib::presets::NAME",
                                        lase_stdlib::module_names()
                                            .map(|m| format!("stdlib::{m}"))
                                            .collect::<Vec<_>>()
                                            .join(", ")
                                    ))
                                }),
                        ));
                    }
                }
            }
        } else if path.value.ends_with(".rhai") || path.value.ends_with(".toml") {
            let importer = map
                .file_of(path.span.start as usize)
                .map(|f| map.name(f).to_string())
                .unwrap_or_default();
            let (name, text) = host
                .extension_file(&importer, &path.value)
                .map_err(|r| load_err(r, Some("the path is relative to the recipe".into())))?;
            let preset = path.value.ends_with(".toml");
            (name, text, preset)
        } else {
            return Err(load_err(
                "not an extension".into(),
                Some(
                    "`use` takes a Rhai module (\"file.rhai\"), a preset (\"file.toml\"), \
                     `stdlib::cams`, `stdlib::patterns` or `stdlib::presets::NAME`"
                        .into(),
                ),
            ));
        };
        if !preset && let Some(i) = self.modules.iter().position(|m| m.name == name) {
            return Ok(Target::Module(i));
        }
        let id = match map.find(&name) {
            Some(id) => id,
            None => map.add(name.clone(), text),
        };
        let base = map.base(id);
        let text: Rc<str> = map.text(id).into();
        let short = short_name(&name, &path.value);
        if preset {
            return preset::parse(&text)
                .map(|p| Target::Preset(Rc::new(p)))
                .map_err(|(message, r)| {
                    vec![ExtError::Preset {
                        file: short,
                        message,
                        span: Span::new(base + r.start, base + r.end),
                        used: path.span,
                    }]
                });
        }
        self.compile(short, text, base, path.span)
            .map(Target::Module)
    }

    /// Compiles a Rhai module already in the source map and reads its signatures.
    fn compile(
        &mut self,
        short: String,
        text: Rc<str>,
        base: usize,
        used: Span,
    ) -> Result<usize, Vec<ExtError>> {
        let ast = self.engine().compile(&*text).map_err(|e| {
            let ft = FileText { text: &text, base };
            vec![ExtError::Syntax {
                file: short.clone(),
                message: e.err_type().to_string(),
                span: ft.span_at(e.position()).unwrap_or(Span::new(base, base)),
                used,
            }]
        })?;
        let ft = FileText { text: &text, base };
        let mut fns = Vec::new();
        let mut errors = Vec::new();
        for f in ast.iter_functions() {
            let comments: Vec<&str> = f.comments.to_vec();
            match sig::parse(f.name, &f.params, &comments) {
                Some(Ok(s)) => fns.push(s),
                Some(Err(message)) => errors.push(ExtError::Signature {
                    function: f.name.to_string(),
                    file: short.clone(),
                    message,
                    span: ft.fn_span(f.name),
                }),
                None => {}
            }
        }
        if !errors.is_empty() {
            return Err(errors);
        }
        fns.sort_by_key(|s| ft.fn_span(&s.name).start);
        self.modules.push(Module {
            name: short,
            text,
            base,
            ast,
            fns,
        });
        Ok(self.modules.len() - 1)
    }

    /// Loads a Rhai module from text (adding it to the source map as `name`) and makes all its
    /// declared functions callable at once: for tools, tests and benchmarks that have no
    /// recipe `use`. Returns the signatures.
    pub fn load_module(
        &mut self,
        map: &mut SourceMap,
        name: &str,
        text: &str,
    ) -> Result<Vec<ExtSig>, Vec<ExtError>> {
        let id = map.add(name, text);
        let base = map.base(id);
        let i = self.compile(name.to_string(), text.into(), base, Span::new(base, base))?;
        for s in &self.modules[i].fns {
            self.active.insert(s.name.clone(), (i, s.clone()));
        }
        Ok(self.modules[i].fns.clone())
    }

    /// The signatures of a standard library module (`cams`, `patterns`), for `lase doc`.
    pub fn stdlib_signatures(name: &str) -> Option<Vec<ExtSig>> {
        let text = lase_stdlib::module(name)?;
        let mut ext = Extensions::new();
        ext.load_module(&mut SourceMap::new(), &format!("stdlib::{name}"), text)
            .ok()
    }

    /// `use` at run time: the module's functions become callable; a preset's values are
    /// returned for the evaluator to bind.
    pub fn activate(&mut self, path: &StrLit) -> Result<Vec<(String, Value)>, ExtError> {
        match self.targets.get(&path.span.start).cloned() {
            Some(Target::Module(i)) => {
                for s in &self.modules[i].fns {
                    self.active.insert(s.name.clone(), (i, s.clone()));
                }
                Ok(Vec::new())
            }
            Some(Target::Preset(p)) => Ok(p.values.clone()),
            None => Err(ExtError::Load {
                path: path.value.clone(),
                reason: "it was not loaded before evaluation".into(),
                span: path.span,
                help: Some("load the program's uses with `Extensions::load_uses` first".into()),
            }),
        }
    }

    /// The signature of a callable extension function.
    pub fn lookup(&self, name: &str) -> Option<&ExtSig> {
        self.active.get(name).map(|(_, s)| s)
    }

    /// Every loaded module's name and exported signatures (for docs and completion).
    pub fn modules(&self) -> impl Iterator<Item = (&str, &[ExtSig])> {
        self.modules.iter().map(|m| (m.name.as_str(), &m.fns[..]))
    }

    /// Calls an active extension function with arguments in parameter order (each with the
    /// span of the recipe expression it came from), under the sandbox's limits. `call` is the
    /// recipe call site that diagnostics point at.
    pub fn call(
        &mut self,
        name: &str,
        args: &[(Value, Span)],
        call: Span,
    ) -> Result<Value, ExtError> {
        let Some((mi, sig)) = self.active.get(name).cloned() else {
            return Err(ExtError::Script {
                function: name.into(),
                message: "no such extension function is in scope".into(),
                span: None,
                call,
                help: Some("`use` its module first".into()),
            });
        };
        let mut rargs = Vec::with_capacity(args.len());
        for ((pname, ty), (v, span)) in sig.params.iter().zip(args) {
            rargs.push(to_rhai(v, ty).map_err(|found| ExtError::Argument {
                function: name.into(),
                param: pname.clone(),
                expected: ty.describe(),
                found,
                span: *span,
            })?);
        }
        let engine = self.engine.get_or_insert_with(engine::sandbox);
        let m = &self.modules[mi];
        let mut scope = Scope::new();
        let r = engine.call_fn_with_options::<Dynamic>(
            CallFnOptions::new().eval_ast(false).rewind_scope(false),
            &mut scope,
            &m.ast,
            name,
            rargs,
        );
        let out = r.map_err(|e| {
            error::from_rhai(
                *e,
                FileText {
                    text: &m.text,
                    base: m.base,
                },
                name,
                call,
                LimitText {
                    operations: MAX_OPERATIONS,
                    call_levels: MAX_CALL_LEVELS,
                },
            )
        })?;
        from_rhai(out, &sig.ret).map_err(|(found, help)| ExtError::Result {
            function: name.into(),
            expected: sig.ret.describe(),
            found,
            call,
            help,
        })
    }
}

/// The points of a spot pattern (a recipe list of points), for `scan raster` and other Rust
/// callers: `None` if the value is not a list of points.
pub fn spots(v: &Value) -> Option<Vec<[f64; 3]>> {
    match v {
        Value::List(items) => items
            .iter()
            .map(|p| match p {
                Value::Point(p, _) => Some(*p),
                _ => None,
            })
            .collect(),
        _ => None,
    }
}

fn short_name(resolved: &str, written: &str) -> String {
    if written.starts_with("stdlib::") {
        return written.to_string();
    }
    std::path::Path::new(resolved)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| written.to_string())
}

fn collect_uses(stmts: &[Stmt], out: &mut Vec<StrLit>) {
    for s in stmts {
        match &s.kind {
            StmtKind::Use(p) => out.push(p.clone()),
            StmtKind::If { then, els, .. } => {
                collect_uses(then, out);
                if let Some(e) = els {
                    collect_uses(e, out);
                }
            }
            StmtKind::For { body, .. } => collect_uses(body, out),
            StmtKind::Fn(f) => collect_uses(&f.body, out),
            _ => {}
        }
    }
}

fn value_ty(v: &Value) -> Ty {
    match v {
        Value::Num(_, d) => Ty::Num(*d),
        Value::Zero => Ty::Zero,
        Value::Bool(_) => Ty::Bool,
        Value::Str(_) => Ty::Str,
        Value::Point(..) => Ty::Point,
        Value::Profile(_) => Ty::Profile,
        Value::List(_) | Value::Nothing => Ty::Unknown,
    }
}

/// A recipe value → Rhai, by the declared type; `Err` describes what was found instead.
fn to_rhai(v: &Value, ty: &Ty) -> Result<Dynamic, String> {
    Ok(match (ty, v) {
        (Ty::Num(_), Value::Zero) => Dynamic::from_float(0.0),
        (Ty::Num(d), Value::Num(x, vd)) if d == vd => Dynamic::from_float(*x),
        (Ty::Unknown | Ty::Zero, Value::Num(x, _)) => Dynamic::from_float(*x),
        (Ty::Unknown | Ty::Zero, Value::Zero) => Dynamic::from_float(0.0),
        (Ty::Bool | Ty::Unknown, Value::Bool(b)) => Dynamic::from_bool(*b),
        (Ty::Str | Ty::Unknown, Value::Str(s)) => Dynamic::from(s.to_string()),
        (Ty::Point | Ty::Unknown, Value::Point(p, n)) => {
            Dynamic::from(ExtPoint { p: *p, dims: *n })
        }
        (Ty::Profile | Ty::Unknown, Value::Profile(p)) => Dynamic::from(ExtProfile(p.clone())),
        (Ty::List(elem), Value::List(items)) => {
            let mut a = Array::with_capacity(items.len());
            for it in items.iter() {
                a.push(to_rhai(it, elem).map_err(|f| format!("a list holding {f}"))?);
            }
            Dynamic::from_array(a)
        }
        (Ty::Unknown, Value::List(items)) => {
            let mut a = Array::with_capacity(items.len());
            for it in items.iter() {
                a.push(to_rhai(it, &Ty::Unknown)?);
            }
            Dynamic::from_array(a)
        }
        (_, other) => return Err(other.type_name()),
    })
}

/// A Rhai result → a recipe value, by the declared type; `Err` holds what was found and a
/// hint.
fn from_rhai(d: Dynamic, ty: &Ty) -> Result<Value, (String, Option<String>)> {
    let found = |d: &Dynamic| (rhai_type(d), None);
    let number = |d: &Dynamic| -> Option<f64> {
        d.as_float()
            .ok()
            .or_else(|| d.as_int().ok().map(|i| i as f64))
    };
    Ok(match ty {
        Ty::Num(dim) => {
            let x = number(&d).ok_or_else(|| found(&d))?;
            if !x.is_finite() {
                return Err((
                    format!("{x}"),
                    Some("the function returned a number that is not finite".into()),
                ));
            }
            Value::Num(x, *dim)
        }
        Ty::Nothing => Value::Nothing,
        Ty::Bool => Value::Bool(d.as_bool().map_err(|_| found(&d))?),
        Ty::Str => Value::Str(
            d.into_immutable_string()
                .map_err(|_| ("?".into(), None))?
                .as_str()
                .into(),
        ),
        Ty::Point => {
            let p = d.clone().try_cast::<ExtPoint>().ok_or_else(|| found(&d))?;
            Value::Point(p.p, p.dims)
        }
        Ty::Profile => {
            let p = d
                .clone()
                .try_cast::<ExtProfile>()
                .ok_or_else(|| found(&d))?;
            Value::Profile(p.0)
        }
        Ty::List(elem) => {
            let a = d.clone().try_cast::<Array>().ok_or_else(|| found(&d))?;
            let mut out = Vec::with_capacity(a.len());
            for (i, it) in a.into_iter().enumerate() {
                out.push(from_rhai(it, elem).map_err(|(f, _)| {
                    (
                        format!("a list whose item {i} is {f}"),
                        Some(format!("every item must be {}", elem.describe())),
                    )
                })?);
            }
            Value::List(Rc::new(out))
        }
        Ty::Zero | Ty::Unknown => {
            if let Some(x) = number(&d) {
                Value::Num(x, Dim::NONE)
            } else if d.is_unit() {
                Value::Nothing
            } else if let Ok(b) = d.as_bool() {
                Value::Bool(b)
            } else if d.is::<ExtPoint>() || d.is::<ExtProfile>() || d.is_array() {
                let t = if d.is::<ExtPoint>() {
                    Ty::Point
                } else if d.is::<ExtProfile>() {
                    Ty::Profile
                } else {
                    Ty::List(Box::new(Ty::Unknown))
                };
                return from_rhai(d, &t);
            } else if d.is_string() {
                return from_rhai(d, &Ty::Str);
            } else {
                return Err(found(&d));
            }
        }
    })
}

fn rhai_type(d: &Dynamic) -> String {
    match d.type_name() {
        "f64" => "a number".into(),
        "i64" => "an integer".into(),
        "()" => "nothing".into(),
        "array" => "an array".into(),
        "map" => "a map".into(),
        "string" => "a string".into(),
        "bool" => "a bool".into(),
        t if t.ends_with("ExtPoint") || t == "point" => "a point".into(),
        t if t.ends_with("ExtProfile") || t == "profile" => "a profile".into(),
        t => format!("a {t}"),
    }
}
