//! The evaluator: a checked recipe → a [`ProcessProgram`].
//!
//! It runs the recipe's statements in order, keeping the state a process sheet implies (the
//! machine, limits, laser and pulse settings, the spot position), and appends one [`Op`] per
//! motion or machine event, each with the span of the statement that produced it. It checks
//! at run time what only running can know: the machine's axes and limits, geometry that
//! cannot be built, values out of range, and the dimension of values the checker could not
//! type (unannotated function parameters). A runaway recipe is stopped by a step budget.

mod error;
mod scan;
mod value;

pub use error::EvalError;
pub use value::Value;

use crate::geometry::{GeomError, Profile, Seg, V2};
use crate::machine::{AxisKind, Machine, parse_machine};
use crate::program::*;
use lase_lang::ast::*;
use lase_lang::diag::did_you_mean;
use lase_lang::units::{self, Dim, format_quantity};
use lase_lang::{Program, Resolved, SourceMap, Span, schema};
use std::collections::{HashMap, HashSet};
use std::rc::Rc;

/// Where machine files and data files (lift tables, DXF drawings) come from: the standard
/// library, or a path next to the recipe.
pub trait Host {
    /// Reads a machine file given by path, relative to the file `importer`. Returns the
    /// resolved name and the text.
    fn machine_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String>;
    /// Reads a data file (a cam lift table, a DXF drawing) given by path, relative to the file
    /// `importer`. Returns the resolved name and the text.
    fn data_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let _ = importer;
        Err(format!("data files are not available here (\"{path}\")"))
    }
    /// Reads an extension module (`use "file.rhai"`) or a preset (`use "file.toml"`) given by
    /// path, relative to the file `importer`. Returns the resolved name and the text.
    fn extension_file(&mut self, importer: &str, path: &str) -> Result<(String, String), String> {
        let _ = importer;
        Err(format!(
            "extension files are not available here (\"{path}\")"
        ))
    }
}

/// A host with no file system: stock machines only.
#[derive(Debug, Default)]
pub struct StdlibOnly;

impl Host for StdlibOnly {
    fn machine_file(&mut self, _importer: &str, path: &str) -> Result<(String, String), String> {
        Err(format!("machine files are not available here (\"{path}\")"))
    }
}

/// Statements executed before the recipe is stopped as runaway.
const STEP_BUDGET: u64 = 200_000_000;
/// Ops (moves, pulses, machine events) a program may hold: about a gigabyte of process program
/// and far beyond any real job (a million-spot raster is a few thousand ops). A loop that
/// produces more is stopped before it exhausts memory or runs for hours.
const MAX_OPS: usize = 10_000_000;
/// Nested function calls before the recipe is stopped as runaway recursion.
const MAX_DEPTH: usize = 200;

use lase_lang::{STACK_RED_ZONE, STACK_SEGMENT};

enum Flow {
    Normal,
    Return(Value),
}

#[derive(Debug, Clone)]
struct LaserState {
    power_w: Option<f64>,
    spot_mm: f64,
    couple: Coupling,
    /// Lens-to-spot distance on machines that orient the beam.
    standoff_mm: Option<f64>,
    on: bool,
}

/// Where the head stands relative to a followed profile (`follow ... { side ... }`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Outside,
    Inside,
    Left,
    Right,
}

/// What one `laser { ... }` or `follow ... { ... }` settings list sets; `None` keeps the value in
/// force.
#[derive(Debug, Default)]
struct LaserSet {
    power: Option<f64>,
    spot: Option<f64>,
    couple: Option<Coupling>,
    standoff: Option<f64>,
    side: Option<(Side, Span)>,
    step: Option<f64>,
    /// `normals chord`: seed 1's discrete method instead of exact normals.
    chord_normals: bool,
}

/// The evaluator's state. A REPL session keeps one alive across lines.
#[derive(Debug)]
pub struct Evaluator {
    scopes: Vec<HashMap<String, Value>>,
    fns: HashMap<String, Rc<FnDef>>,
    machine: Option<Machine>,
    /// Whether that machine orients the beam (from its kinematics, once per `machine`).
    orients_beam: bool,
    limits: Vec<AxisLimit>,
    path_limits: PathLimits,
    planner: Option<PlannerSettings>,
    laser: LaserState,
    pulse: Option<Pulse>,
    /// Default scan step of `follow` on oriented machines (`planner { step }`).
    scan_step_mm: Option<f64>,
    /// The beam orientation the last move left (oriented machines), kept by `move`.
    orient: Option<Orient>,
    pos: P3,
    start: P3,
    ops: Vec<Op>,
    steps: u64,
    depth: usize,
    imported: HashSet<usize>,
    /// Rhai extension modules and presets (`use`), loaded before checking.
    ext: crate::ext::Extensions,
}

impl Default for Evaluator {
    fn default() -> Self {
        Self::new()
    }
}

type R<T> = Result<T, EvalError>;

impl Evaluator {
    pub fn new() -> Evaluator {
        let mut globals = HashMap::new();
        for (name, v, _) in schema::CONSTANTS {
            globals.insert((*name).to_string(), Value::Num(*v, Dim::NONE));
        }
        Evaluator {
            scopes: vec![globals],
            fns: HashMap::new(),
            machine: None,
            orients_beam: false,
            limits: Vec::new(),
            path_limits: PathLimits::default(),
            planner: None,
            laser: LaserState {
                power_w: None,
                spot_mm: 0.05,
                couple: Coupling::None,
                standoff_mm: None,
                on: false,
            },
            pulse: None,
            scan_step_mm: None,
            orient: None,
            pos: [0.0; 3],
            start: [0.0; 3],
            ops: Vec::new(),
            steps: 0,
            depth: 0,
            imported: HashSet::new(),
            ext: crate::ext::Extensions::new(),
        }
    }

    /// Runs top-level statements (the main recipe, or one REPL line).
    pub fn run(
        &mut self,
        stmts: &[Stmt],
        program: &Program,
        map: &mut SourceMap,
        host: &mut dyn Host,
    ) -> R<()> {
        let mut cx = Cx { program, map, host };
        self.hoist(stmts);
        for s in stmts {
            if let Flow::Return(_) = self.stmt(s, &mut cx)? {
                break;
            }
        }
        Ok(())
    }

    /// Evaluates an expression in the session (the REPL prints it).
    pub fn eval_expr(
        &mut self,
        e: &Expr,
        program: &Program,
        map: &mut SourceMap,
        host: &mut dyn Host,
    ) -> R<Value> {
        let mut cx = Cx { program, map, host };
        self.expr(e, &mut cx)
    }

    /// The extension modules this evaluator runs; load a program's `use`s into it
    /// ([`crate::ext::Extensions::load_uses`]) before checking and evaluating.
    pub fn extensions_mut(&mut self) -> &mut crate::ext::Extensions {
        &mut self.ext
    }

    /// Hands over extension modules loaded before checking.
    pub fn set_extensions(&mut self, ext: crate::ext::Extensions) {
        self.ext = ext;
    }

    pub fn machine(&self) -> Option<&Machine> {
        self.machine.as_ref()
    }

    /// The spot position now.
    pub fn position(&self) -> P3 {
        self.pos
    }

    /// Names bound in the session (variables and functions).
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

    /// The ops produced so far.
    pub fn ops(&self) -> &[Op] {
        &self.ops
    }

    /// Where the ops produced so far start from: the machine's actual position, when it is
    /// not where the session left it (a jog, an aborted job). With no ops yet, the spot is
    /// there too.
    pub fn rebase(&mut self, p: P3) {
        self.start = p;
        if self.ops.is_empty() {
            self.pos = p;
        }
    }

    /// Drops the ops produced so far: they never ran, so the spot is back where they began.
    pub fn discard(&mut self) {
        self.ops.clear();
        self.pos = self.start;
    }

    /// Where the ops produced so far start from.
    pub fn start(&self) -> P3 {
        self.start
    }

    /// Takes the ops produced so far (the REPL runs them), continuing from where they end.
    pub fn take_program(&mut self, recipe: &str, span: Span) -> R<ProcessProgram> {
        let p = self.program(recipe, span)?;
        self.ops.clear();
        self.start = self.pos;
        Ok(p)
    }

    /// The process program of everything evaluated so far.
    pub fn program(&self, recipe: &str, span: Span) -> R<ProcessProgram> {
        let machine = self.machine.clone().ok_or_else(|| no_machine(span))?;
        let planner = self.planner_settings_now();
        Ok(ProcessProgram {
            recipe: recipe.to_string(),
            limits: self.limits.clone(),
            path_limits: self.path_limits.clone(),
            planner,
            start: self.start,
            ops: self.ops.clone(),
            machine,
        })
    }

    // ------------------------------------------------------------------ statements

    fn hoist(&mut self, stmts: &[Stmt]) {
        for s in stmts {
            if let StmtKind::Fn(f) = &s.kind {
                self.fns.insert(f.name.name.clone(), f.clone());
            }
        }
    }

    fn tick(&mut self, span: Span) -> R<()> {
        self.steps += 1;
        if self.steps > STEP_BUDGET {
            return Err(EvalError::Budget {
                message: format!("the recipe ran more than {STEP_BUDGET} steps"),
                span,
                help: Some("a loop runs far longer than intended; check its range".into()),
            });
        }
        if self.ops.len() > MAX_OPS {
            return Err(EvalError::Budget {
                message: format!(
                    "the program holds more than {} moves and machine events",
                    units::format_number(MAX_OPS as f64)
                ),
                span,
                help: Some(
                    "a loop produces far more motion than a job needs; check its range (a job \
                     this size, if meant, belongs in several recipes)"
                        .into(),
                ),
            });
        }
        Ok(())
    }

    fn block(&mut self, stmts: &[Stmt], cx: &mut Cx) -> R<Flow> {
        self.scopes.push(HashMap::new());
        self.hoist(stmts);
        let mut flow = Flow::Normal;
        for s in stmts {
            match self.stmt(s, cx) {
                Ok(Flow::Normal) => {}
                Ok(f @ Flow::Return(_)) => {
                    flow = f;
                    break;
                }
                Err(e) => {
                    self.scopes.pop();
                    return Err(e);
                }
            }
        }
        self.scopes.pop();
        Ok(flow)
    }

    fn bind(&mut self, name: &str, v: Value) {
        self.scopes
            .last_mut()
            .expect("there is always a scope")
            .insert(name.to_string(), v);
    }

    fn need_machine(&self, span: Span) -> R<&Machine> {
        self.machine.as_ref().ok_or_else(|| no_machine(span))
    }

    /// Statements and expressions recurse (a function calling itself up to `MAX_DEPTH`,
    /// nested blocks and expressions): near the end of the stack, it continues on a new
    /// segment, so no recipe overflows it, however its frames are sized (a debug build's are
    /// large).
    fn stmt(&mut self, s: &Stmt, cx: &mut Cx) -> R<Flow> {
        stacker::maybe_grow(STACK_RED_ZONE, STACK_SEGMENT, || self.stmt_here(s, cx))
    }

    fn stmt_here(&mut self, s: &Stmt, cx: &mut Cx) -> R<Flow> {
        self.tick(s.span)?;
        match &s.kind {
            StmtKind::Machine(m) => self.select_machine(m, s.span, cx)?,
            StmtKind::Limits(groups) => self.set_limits(groups, cx)?,
            StmtKind::Let { name, value, .. } => {
                let v = self.expr(value, cx)?;
                self.bind(&name.name, v);
            }
            StmtKind::Fn(f) => {
                self.fns.insert(f.name.name.clone(), f.clone());
            }
            StmtKind::Import(path) => self.import(path, cx)?,
            StmtKind::Use(path) => {
                for (name, v) in self.ext.activate(path)? {
                    self.bind(&name, v);
                }
            }
            StmtKind::Scan {
                kind,
                region,
                settings,
            } => self.scan(kind, region, settings, s.span, cx)?,
            StmtKind::If { cond, then, els } => {
                let c = self.expr(cond, cx)?;
                let c = self.as_bool(&c, cond.span, "the condition of `if`")?;
                if c {
                    return self.block(then, cx);
                } else if let Some(e) = els {
                    return self.block(e, cx);
                }
            }
            StmtKind::For { var, iter, body } => return self.for_loop(var, iter, body, cx),
            StmtKind::Return(e) => {
                let v = match e {
                    Some(e) => self.expr(e, cx)?,
                    None => Value::Nothing,
                };
                return Ok(Flow::Return(v));
            }
            StmtKind::Laser(l) => match l {
                LaserStmt::On => self.laser.on = true,
                LaserStmt::Off => self.laser.on = false,
                LaserStmt::Settings(set) => {
                    let ls = self.laser_settings(set, cx)?;
                    if let Some(p) = ls.power {
                        self.laser.power_w = Some(p);
                    }
                    if let Some(d) = ls.spot {
                        self.laser.spot_mm = d;
                    }
                    if let Some(c) = ls.couple {
                        self.laser.couple = c;
                    }
                    if let Some(d) = ls.standoff {
                        self.laser.standoff_mm = Some(d);
                    }
                }
            },
            StmtKind::Pulse(PulseStmt::Off) => self.pulse = None,
            StmtKind::Pulse(PulseStmt::Settings(set)) => self.pulse_settings(set, cx)?,
            StmtKind::Planner(set) => self.planner_settings(set, s.span, cx)?,
            StmtKind::Move {
                kind,
                target,
                speed,
            } => self.move_stmt(*kind, target, speed, s.span, cx)?,
            StmtKind::Follow {
                path,
                speed,
                settings,
            } => self.follow(path, speed, settings, s.span, cx)?,
            StmtKind::Dwell(e) => {
                let v = self.expr(e, cx)?;
                let t = self.as_dim(&v, Dim::TIME, e.span, "`dwell`")?;
                if t < 0.0 {
                    return Err(bad(e.span, "a dwell cannot be negative", "negative", None));
                }
                self.need_machine(s.span)?;
                self.push(OpKind::Dwell { seconds: t }, s.span);
            }
            StmtKind::MCode { code, comment } => {
                let v = self.expr(code, cx)?;
                let c = self.as_count(&v, code.span, "an M-code")?;
                if !(0..1000).contains(&c) {
                    return Err(bad(
                        code.span,
                        "M-codes run from 0 to 999",
                        "out of range",
                        None,
                    ));
                }
                self.need_machine(s.span)?;
                self.push(
                    OpKind::MCode {
                        code: c as u32,
                        comment: comment.as_ref().map(|c| c.value.clone()),
                    },
                    s.span,
                );
            }
            StmtKind::Event(name) => {
                let m = self.need_machine(s.span)?;
                if !m.events.contains_key(&name.name) {
                    let machine = m.name.clone();
                    let help = did_you_mean(&name.name, m.events.keys().map(String::as_str))
                        .or_else(|| {
                            Some(if m.events.is_empty() {
                                format!("machine `{machine}` defines no events")
                            } else {
                                format!(
                                    "`{machine}` has: {}",
                                    m.events.keys().cloned().collect::<Vec<_>>().join(", ")
                                )
                            })
                        });
                    return Err(EvalError::UnknownEvent {
                        machine,
                        name: name.name.clone(),
                        span: name.span,
                        help,
                    });
                }
                self.push(
                    OpKind::Event {
                        name: name.name.clone(),
                    },
                    s.span,
                );
            }
            StmtKind::Expr(e) => {
                self.expr(e, cx)?;
            }
        }
        Ok(Flow::Normal)
    }

    fn push(&mut self, kind: OpKind, span: Span) {
        if let Some(t) = match &kind {
            OpKind::Rapid { to, .. } | OpKind::Line { to, .. } | OpKind::Arc { to, .. } => {
                Some(*to)
            }
            _ => None,
        } {
            self.pos = t;
        }
        if let OpKind::Rapid {
            orient: Some(o), ..
        }
        | OpKind::Line {
            orient: Some(o), ..
        } = &kind
        {
            self.orient = Some(*o);
        }
        self.ops.push(Op { kind, span });
    }

    fn select_machine(&mut self, m: &MachineRef, span: Span, cx: &mut Cx) -> R<()> {
        let (name, text, at) = match m {
            MachineRef::Named(id) => match lase_stdlib::machine(&id.name) {
                Some(t) => (
                    format!("<stdlib>/machines/{}.toml", id.name),
                    t.to_string(),
                    id.span,
                ),
                None => {
                    return Err(EvalError::UnknownMachine {
                        name: id.name.clone(),
                        span: id.span,
                        help: did_you_mean(&id.name, lase_stdlib::machine_names()).or_else(|| {
                            Some(format!(
                                "stock machines: {}; or give a file: `machine \"my_machine.toml\"`",
                                lase_stdlib::machine_names().collect::<Vec<_>>().join(", ")
                            ))
                        }),
                    });
                }
            },
            MachineRef::Path(p) => {
                let importer = cx
                    .map
                    .file_of(p.span.start as usize)
                    .map(|f| cx.map.name(f).to_string())
                    .unwrap_or_default();
                let (name, text) = cx
                    .host
                    .machine_file(&importer, &p.value)
                    .map_err(|reason| EvalError::MachineFile {
                        path: p.value.clone(),
                        reason,
                        span: p.span,
                    })?;
                (name, text, p.span)
            }
        };
        let _ = at;
        if !self.ops.is_empty() {
            return Err(EvalError::MachineChanged { span });
        }
        let id = match cx.map.find(&name) {
            Some(id) => id,
            None => cx.map.add(name, text),
        };
        let machine = parse_machine(cx.map.text(id), cx.map.base(id))?;
        self.limits = AxisLimit::of_machine(&machine);
        self.orients_beam = crate::kinematics::for_machine(&machine).oriented();
        self.machine = Some(machine);
        Ok(())
    }

    fn set_limits(&mut self, groups: &[LimitGroup], cx: &mut Cx) -> R<()> {
        let span = groups.first().map(|g| g.axis.span).unwrap_or_default();
        let machine = self.need_machine(span)?.clone();
        for g in groups {
            let path = g.axis.name == "path";
            let axis =
                if path {
                    None
                } else {
                    Some(machine.axis_index(&g.axis.name).ok_or_else(|| {
                        EvalError::UnknownAxis {
                            machine: machine.name.clone(),
                            axis: g.axis.name.clone(),
                            span: g.axis.span,
                            help: Some(format!(
                                "`{}` has axes {}; `path:` limits the motion along the path",
                                machine.name,
                                machine
                                    .axes
                                    .iter()
                                    .map(|a| a.name.to_ascii_lowercase())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            )),
                        }
                    })?)
                };
            let rotary = axis.is_some_and(|i| machine.axes[i].kind == AxisKind::Rotary);
            for s in &g.settings {
                let Some(e) = &s.value else { continue };
                let v = self.expr(e, cx)?;
                let (want, name) = match (s.key.name.as_str(), rotary) {
                    ("v", false) => (Dim::SPEED, "speed"),
                    ("v", true) => (Dim::ANGULAR_SPEED, "speed"),
                    ("a", false) => (Dim::ACCEL, "acceleration"),
                    ("a", true) => (Dim::ANGULAR_ACCEL, "acceleration"),
                    ("j", false) => (Dim::JERK, "jerk"),
                    _ => (Dim::ANGULAR_JERK, "jerk"),
                };
                let x = self.as_dim(&v, want, e.span, &format!("limit `{}`", s.key.name))?;
                if !(x > 0.0) {
                    return Err(bad(
                        e.span,
                        "limits must be greater than zero",
                        "not positive",
                        None,
                    ));
                }
                match axis {
                    None => match s.key.name.as_str() {
                        "v" => self.path_limits.v = x,
                        "a" => self.path_limits.a = x,
                        _ => self.path_limits.j = x,
                    },
                    Some(i) => {
                        let a = &machine.axes[i];
                        let cap = match s.key.name.as_str() {
                            "v" => a.v_max,
                            "a" => a.a_max,
                            _ => a.j_max,
                        };
                        if x > cap * (1.0 + 1e-12) {
                            return Err(EvalError::AboveMachine {
                                what: format!("{} {name} limit", a.name),
                                value: format_quantity(x, want),
                                limit: format_quantity(cap, want),
                                span: e.span,
                                help: Some(
                                    "a recipe can only tighten the machine's limits; raise them in the machine file if the machine allows it"
                                        .into(),
                                ),
                            });
                        }
                        let l = &mut self.limits[i];
                        match s.key.name.as_str() {
                            "v" => l.v = x,
                            "a" => l.a = x,
                            _ => l.j = x,
                        }
                    }
                }
            }
        }
        Ok(())
    }

    fn laser_settings(&mut self, set: &[Setting], cx: &mut Cx) -> R<LaserSet> {
        let mut power = None;
        let mut spot = None;
        let mut couple = None;
        let mut standoff = None;
        let mut side = None;
        let mut step = None;
        let mut chord_normals = false;
        for s in set {
            let Some(e) = &s.value else { continue };
            if s.key.name == "normals" {
                chord_normals = matches!(&e.kind, ExprKind::Var(w) if w == "chord");
                continue;
            }
            if s.key.name == "side" {
                // A word, checked against the schema's list by the checker.
                side = Some((
                    match &e.kind {
                        ExprKind::Var(w) if w == "inside" => Side::Inside,
                        ExprKind::Var(w) if w == "left" => Side::Left,
                        ExprKind::Var(w) if w == "right" => Side::Right,
                        _ => Side::Outside,
                    },
                    e.span,
                ));
                continue;
            }
            if s.key.name == "couple" {
                // A word, checked against the schema's list: anything but `speed` is `none`.
                couple = Some(match &e.kind {
                    ExprKind::Var(w) if w == "speed" => Coupling::Speed,
                    _ => Coupling::None,
                });
                continue;
            }
            let v = self.expr(e, cx)?;
            match s.key.name.as_str() {
                "power" => {
                    let p = self.as_dim(&v, Dim::POWER, e.span, "`power`")?;
                    if p < 0.0 {
                        return Err(bad(
                            e.span,
                            "laser power cannot be negative",
                            "negative",
                            None,
                        ));
                    }
                    check_power(p, self.need_machine(e.span)?, e.span)?;
                    power = Some(p);
                }
                "standoff" => {
                    let d = self.as_dim(&v, Dim::LENGTH, e.span, "`standoff`")?;
                    if !(d >= 0.0 && d.is_finite()) {
                        return Err(bad(
                            e.span,
                            "the standoff cannot be negative",
                            "negative",
                            None,
                        ));
                    }
                    standoff = Some(d);
                }
                "step" => step = Some(self.positive_length(&v, e.span, "`step`")?),
                _ => {
                    let d = self.as_dim(&v, Dim::LENGTH, e.span, "`spot`")?;
                    if !(d > 0.0) {
                        return Err(bad(
                            e.span,
                            "the spot diameter must be greater than zero",
                            "not positive",
                            None,
                        ));
                    }
                    spot = Some(d);
                }
            }
        }
        Ok(LaserSet {
            power,
            spot,
            couple,
            standoff,
            side,
            step,
            chord_normals,
        })
    }

    fn positive_length(&self, v: &Value, span: Span, ctx: &str) -> R<f64> {
        let x = self.as_dim(v, Dim::LENGTH, span, ctx)?;
        if !(x > 0.0 && x.is_finite()) {
            return Err(bad(span, "must be greater than zero", "not positive", None));
        }
        Ok(x)
    }

    fn pulse_settings(&mut self, set: &[Setting], cx: &mut Cx) -> R<()> {
        let mut pulse = self.pulse.clone().unwrap_or(Pulse {
            mode: PulseMode::Time {
                period_s: f64::INFINITY,
            },
            width_s: None,
            energy_j: None,
        });
        let mut mode_set = self.pulse.is_some();
        for s in set {
            let Some(e) = &s.value else { continue };
            let v = self.expr(e, cx)?;
            let positive = |x: f64| {
                if x > 0.0 {
                    Ok(x)
                } else {
                    Err(bad(
                        e.span,
                        "pulse settings must be greater than zero",
                        "not positive",
                        None,
                    ))
                }
            };
            match s.key.name.as_str() {
                "interval" => {
                    mode_set = true;
                    pulse.mode = match &v {
                        Value::Num(x, d) if *d == Dim::LENGTH => PulseMode::Distance {
                            pitch_mm: positive(*x)?,
                        },
                        Value::Num(x, d) if *d == Dim::TIME => PulseMode::Time {
                            period_s: positive(*x)?,
                        },
                        other => {
                            return Err(type_err(
                                "a length or a time",
                                other,
                                e.span,
                                "`interval`",
                            ));
                        }
                    }
                }
                "rate" => {
                    mode_set = true;
                    let f = positive(self.as_dim(&v, Dim::FREQUENCY, e.span, "`rate`")?)?;
                    check_pulse_rate(f, None, self.need_machine(e.span)?, e.span)?;
                    pulse.mode = PulseMode::Time { period_s: 1.0 / f };
                }
                "width" => {
                    pulse.width_s =
                        Some(positive(self.as_dim(&v, Dim::TIME, e.span, "`width`")?)?)
                }
                _ => {
                    pulse.energy_j = Some(positive(self.as_dim(
                        &v,
                        Dim::ENERGY,
                        e.span,
                        "`energy`",
                    )?)?)
                }
            }
        }
        if !mode_set {
            let span = set.first().map(|s| s.span).unwrap_or_default();
            return Err(bad(
                span,
                "pulses need an interval or a rate",
                "no interval",
                Some(
                    "add `interval 0.2 mm` (by distance), `interval 50 us` or `rate 20 kHz` (by time)",
                ),
            ));
        }
        self.pulse = Some(pulse);
        Ok(())
    }

    fn planner_settings(&mut self, set: &[Setting], span: Span, cx: &mut Cx) -> R<()> {
        self.need_machine(span)?;
        let mut p = self.planner_settings_now();
        for s in set {
            let Some(e) = &s.value else { continue };
            match s.key.name.as_str() {
                "ramp" => {
                    p.ramp = match &e.kind {
                        ExprKind::Var(w) if w == "trapezoid" => Ramp::Trapezoid,
                        _ => Ramp::Scurve,
                    }
                }
                "step" => {
                    let v = self.expr(e, cx)?;
                    self.scan_step_mm = Some(self.positive_length(&v, e.span, "`step`")?);
                }
                "leadin" => {
                    p.leadin = match &e.kind {
                        ExprKind::Var(w) if w == "none" => LeadIn::Off,
                        _ => LeadIn::Auto,
                    }
                }
                "corner" | "tolerance" => {
                    let v = self.expr(e, cx)?;
                    let x = self.as_dim(&v, Dim::LENGTH, e.span, &format!("`{}`", s.key.name))?;
                    if !(x > 0.0) {
                        return Err(bad(
                            e.span,
                            "must be greater than zero",
                            "not positive",
                            None,
                        ));
                    }
                    if s.key.name == "corner" {
                        p.junction_deviation_mm = x;
                    } else {
                        p.arc_tolerance_mm = x;
                    }
                }
                _ => {
                    let v = self.expr(e, cx)?;
                    let n = self.as_count(&v, e.span, "`lookahead`")?;
                    if n < 1 {
                        return Err(bad(
                            e.span,
                            "look-ahead needs at least 1 move",
                            "too small",
                            None,
                        ));
                    }
                    p.lookahead = Some(n as usize);
                }
            }
        }
        self.planner = Some(p);
        Ok(())
    }

    fn current_laser(&self, span: Span, set: &LaserSet) -> R<Laser> {
        let power_w = set
            .power
            .or(self.laser.power_w)
            .ok_or(EvalError::NoPower { span })?;
        Ok(Laser {
            power_w,
            spot_mm: set.spot.unwrap_or(self.laser.spot_mm),
            pulse: self.pulse.clone(),
            couple: set.couple.unwrap_or(self.laser.couple),
        })
    }

    /// Pulses by distance at `feed`, held to the laser's maximum rate at the speed's span
    /// (pulses by time are held by `ProcessProgram::validate`, at the move).
    fn check_pulse_rate(&self, laser: &Laser, feed: f64, span: Span) -> R<()> {
        let Some(Pulse {
            mode: PulseMode::Distance { .. },
            ..
        }) = &laser.pulse
        else {
            return Ok(());
        };
        Ok(laser.check_pulse_rate(feed, self.need_machine(span)?, span)?)
    }

    fn move_stmt(
        &mut self,
        kind: MoveKind,
        target: &Expr,
        speed: &MoveSpeed,
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        let v = self.expr(target, cx)?;
        let (p, n) = self.as_point(&v, target.span, "the target of `move`")?;
        self.need_machine(span)?;
        let mut to = self.pos;
        for k in 0..n as usize {
            to[k] = match kind {
                MoveKind::To => p[k],
                MoveKind::By => self.pos[k] + p[k],
            };
        }
        let orient = self.move_orient(span)?;
        match speed {
            MoveSpeed::Rapid => self.push(OpKind::Rapid { to, orient }, span),
            MoveSpeed::At(e) => {
                let v = self.expr(e, cx)?;
                let feed = self.feed(&v, e.span)?;
                let laser = if self.laser.on {
                    let l = self.current_laser(span, &LaserSet::default())?;
                    self.check_pulse_rate(&l, feed, e.span)?;
                    Some(l)
                } else {
                    None
                };
                self.push(
                    OpKind::Line {
                        to,
                        feed_mm_s: feed,
                        laser,
                        orient,
                    },
                    span,
                );
            }
        }
        Ok(())
    }

    /// Whether the selected machine orients the beam (cam X-ω-B, arm).
    fn oriented(&self) -> bool {
        self.machine.is_some() && self.orients_beam
    }

    /// The orientation a `move` keeps: the last one on an oriented machine (a move there
    /// needs one), none on a flat bed.
    fn move_orient(&self, span: Span) -> R<Option<Orient>> {
        if !self.oriented() {
            return Ok(None);
        }
        match self.orient {
            Some(o) => Ok(Some(o)),
            None => Err(bad(
                span,
                "this machine orients the beam, and no path has set its direction yet",
                "which way does the beam point here?",
                Some(
                    "`follow` a profile first (it sets the beam along the surface normal); a \
                     `move` keeps the beam direction and standoff of the move before it",
                ),
            )),
        }
    }

    fn feed(&self, v: &Value, span: Span) -> R<f64> {
        let f = self.as_dim(v, Dim::SPEED, span, "a speed")?;
        if !(f > 0.0) {
            return Err(bad(
                span,
                "a speed must be greater than zero",
                "not positive",
                None,
            ));
        }
        Ok(f)
    }

    fn follow(
        &mut self,
        path: &Expr,
        speed: &Expr,
        settings: &[Setting],
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        let v = self.expr(path, cx)?;
        let Value::Profile(profile) = v else {
            return Err(type_err("a profile", &v, path.span, "the path of `follow`"));
        };
        let sv = self.expr(speed, cx)?;
        let feed = self.feed(&sv, speed.span)?;
        let set = self.laser_settings(settings, cx)?;
        self.need_machine(span)?;
        let laser = self.current_laser(span, &set)?;
        self.check_pulse_rate(&laser, feed, speed.span)?;
        if self.oriented() {
            return self.follow_oriented(&profile, feed, laser, &set, span);
        }
        if let Some((_, side_span)) = set.side {
            return Err(bad(
                side_span,
                "`side` only applies to machines that orient the beam",
                "the beam of this machine always points down",
                Some("remove `side`, or choose a machine such as cam_xwb or arm_3r"),
            ));
        }
        let z = self.pos[2];
        let start = profile.start();
        if (start.x - self.pos[0]).hypot(start.y - self.pos[1]) > 1e-9 {
            // Going to the start of a path is part of following it: a rapid, laser off.
            self.push(
                OpKind::Rapid {
                    to: [start.x, start.y, z],
                    orient: None,
                },
                span,
            );
        }
        for seg in &profile.segs {
            match seg {
                Seg::Line { b, .. } => self.push(
                    OpKind::Line {
                        to: [b.x, b.y, z],
                        feed_mm_s: feed,
                        laser: Some(laser.clone()),
                        orient: None,
                    },
                    span,
                ),
                Seg::Arc {
                    center,
                    r,
                    a0,
                    sweep,
                } => {
                    // Arcs longer than a half turn are split so every dialect reads them
                    // unambiguously.
                    let pieces =
                        (sweep.abs() / std::f64::consts::PI - 1e-9).ceil().max(1.0) as usize;
                    for k in 1..=pieces {
                        let a = a0 + sweep * k as f64 / pieces as f64;
                        let to = if k == pieces {
                            seg.end()
                        } else {
                            center + V2::new(a.cos(), a.sin()) * *r
                        };
                        self.push(
                            OpKind::Arc {
                                to: [to.x, to.y, z],
                                center: [center.x, center.y],
                                ccw: *sweep > 0.0,
                                feed_mm_s: feed,
                                laser: Some(laser.clone()),
                            },
                            span,
                        );
                    }
                }
            }
        }
        Ok(())
    }

    /// `follow` on a machine that orients the beam (PROCESS.md §1 and §2): the profile is
    /// resampled at a constant arc-length step with exact frames, and every sample becomes a
    /// pose — the spot on the surface, the beam back along the exact normal on the head's side,
    /// the lens at the standoff. Equal steps at one feed give constant surface speed.
    fn follow_oriented(
        &mut self,
        profile: &Profile,
        feed: f64,
        laser: Laser,
        set: &LaserSet,
        span: Span,
    ) -> R<()> {
        let machine = self.need_machine(span)?.name.clone();
        let standoff = set.standoff.or(self.laser.standoff_mm).ok_or_else(|| {
            bad(
                span,
                &format!("machine `{machine}` orients the beam: it needs a standoff"),
                "no standoff in force",
                Some("write `laser { standoff 12 mm }`, or `follow ... { standoff 12 mm }`"),
            )
        })?;
        let side = match set.side {
            Some((s @ (Side::Outside | Side::Inside), sp)) if !profile.closed => {
                let word = if s == Side::Outside {
                    "outside"
                } else {
                    "inside"
                };
                return Err(bad(
                    sp,
                    &format!("`side {word}` needs a closed profile"),
                    "this path is open",
                    Some(
                        "say which side of the direction of travel the head stands on: `side left` or `side right`",
                    ),
                ));
            }
            Some((s, _)) => s,
            None if profile.closed => Side::Outside,
            None => Side::Left,
        };
        // The head-side normal is ±left: a counter-clockwise closed profile has its outside on
        // the right of travel.
        let ccw = profile.signed_area() > 0.0;
        let head_on_left = match side {
            Side::Left => true,
            Side::Right => false,
            Side::Outside => !ccw,
            Side::Inside => ccw,
        };
        let step = set.step.or(self.scan_step_mm).unwrap_or(1.0);
        let tol = self.planner_settings_now().arc_tolerance_mm;
        let rs = profile
            .resample_even(step, Some(tol))
            .map_err(|g| geom_error(g, span, None))?;
        // Where the surface is concave seen from the head with a radius below the standoff,
        // the normals cross before they reach the lens: the lens path folds over (seed 2's
        // offset rule, for the offset the head travels on) and the head would have to jump.
        let toward_head = if head_on_left { 1.0 } else { -1.0 };
        let folds: Vec<&crate::geometry::resample::Sample> = rs
            .samples
            .iter()
            .filter(|smp| smp.curvature * toward_head * standoff >= 1.0 - 1e-9)
            .collect();
        if let (Some(a), Some(b)) = (folds.first(), folds.last()) {
            let r_min = folds
                .iter()
                .map(|smp| 1.0 / smp.curvature.abs())
                .fold(f64::INFINITY, f64::min);
            return Err(EvalError::Geometry {
                message: format!(
                    "the surface is concave with a radius down to {} toward the head, less than \
                     the standoff {}: the lens path folds over between s = {} and {}",
                    format_quantity(r_min, Dim::LENGTH),
                    format_quantity(standoff, Dim::LENGTH),
                    format_quantity(a.s, Dim::LENGTH),
                    format_quantity(b.s, Dim::LENGTH)
                ),
                span,
                label: "this path".into(),
                help: Some(format!(
                    "use a standoff below {}, or round the concave region of the profile",
                    format_quantity(r_min, Dim::LENGTH)
                )),
            });
        }
        let z = self.pos[2];
        let pose = |smp: &crate::geometry::resample::Sample| {
            let n = if head_on_left { smp.left } else { -smp.left };
            (
                [smp.point.x, smp.point.y, z],
                Orient {
                    beam: [-n.x, -n.y, 0.0],
                    standoff_mm: standoff,
                },
            )
        };
        let mut samples = rs.samples;
        if set.chord_normals {
            // PROCESS.md §1's discrete method: the scan point is the chord's midpoint M and the
            // normal the chord's perpendicular bisector (on an open profile the ends are kept).
            let chords: Vec<crate::geometry::resample::Sample> = samples
                .windows(2)
                .map(|w| {
                    let t = (w[1].point - w[0].point).normalize();
                    crate::geometry::resample::Sample {
                        s: 0.5 * (w[0].s + w[1].s),
                        point: 0.5 * (w[0].point + w[1].point),
                        tangent: t,
                        left: V2::new(-t.y, t.x),
                        curvature: 0.0,
                    }
                })
                .collect();
            samples = if profile.closed {
                let mut c = chords.clone();
                c.extend(chords.first().copied());
                c
            } else {
                chords
            };
        }
        let Some(first) = samples.first() else {
            return Ok(());
        };
        let (p0, o0) = pose(first);
        if crate::motion::dist(p0, self.pos) > 1e-9 || self.orient != Some(o0) {
            // Going to the start of a path, beam already along its normal: a rapid, laser off.
            self.push(
                OpKind::Rapid {
                    to: p0,
                    orient: Some(o0),
                },
                span,
            );
        }
        for smp in &samples[1..] {
            let (p, o) = pose(smp);
            if crate::motion::dist(p, self.pos) <= 1e-12 {
                continue;
            }
            self.push(
                OpKind::Line {
                    to: p,
                    feed_mm_s: feed,
                    laser: Some(laser.clone()),
                    orient: Some(o),
                },
                span,
            );
        }
        Ok(())
    }

    /// The planner settings in force (machine defaults, overridden by `planner`).
    fn planner_settings_now(&self) -> PlannerSettings {
        self.planner.clone().unwrap_or_else(|| {
            let m = self.machine.as_ref();
            PlannerSettings {
                ramp: m.map_or(Ramp::Trapezoid, |m| m.ramp),
                junction_deviation_mm: m.map_or(0.01, |m| m.junction_deviation_mm),
                arc_tolerance_mm: m.map_or(0.001, |m| m.arc_tolerance_mm),
                lookahead: None,
                leadin: LeadIn::Auto,
            }
        })
    }

    fn for_loop(&mut self, var: &Ident, iter: &ForIter, body: &[Stmt], cx: &mut Cx) -> R<Flow> {
        let items: Box<dyn Iterator<Item = Value>> = match iter {
            ForIter::Range {
                start,
                end,
                inclusive,
            } => {
                let a = self.expr(start, cx)?;
                let a = self.as_count(&a, start.span, "a range bound")?;
                let b = self.expr(end, cx)?;
                let b = self.as_count(&b, end.span, "a range bound")?;
                let b = if *inclusive { b + 1 } else { b };
                Box::new((a..b).map(|i| Value::Num(i as f64, Dim::NONE)))
            }
            ForIter::Expr(e) => match self.expr(e, cx)? {
                Value::List(items) => Box::new((*items).clone().into_iter()),
                other => return Err(type_err("a list or a range", &other, e.span, "`for`")),
            },
        };
        for item in items {
            self.tick(var.span)?;
            self.scopes.push(HashMap::new());
            self.bind(&var.name, item);
            let r = self.block(body, cx);
            self.scopes.pop();
            if let Flow::Return(v) = r? {
                return Ok(Flow::Return(v));
            }
        }
        Ok(Flow::Normal)
    }

    fn import(&mut self, path: &StrLit, cx: &mut Cx) -> R<()> {
        let Some(Resolved::Module(idx)) = cx.program.imports.get(&path.span.start).cloned() else {
            return Err(bad(
                path.span,
                "this import could not be loaded",
                "not loaded",
                None,
            ));
        };
        if !self.imported.insert(idx) {
            return Ok(());
        }
        let stmts = cx.program.modules[idx].stmts.clone();
        // An imported file's definitions land in the importer's scope.
        self.hoist(&stmts);
        for s in &stmts {
            self.stmt(s, cx)?;
        }
        Ok(())
    }

    // ------------------------------------------------------------------ value helpers

    fn as_bool(&self, v: &Value, span: Span, ctx: &str) -> R<bool> {
        match v {
            Value::Bool(b) => Ok(*b),
            other => Err(type_err("a bool", other, span, ctx)),
        }
    }

    fn as_dim(&self, v: &Value, want: Dim, span: Span, ctx: &str) -> R<f64> {
        match v {
            Value::Zero => Ok(0.0),
            Value::Num(x, d) if *d == want => Ok(*x),
            Value::Num(_, d) => Err(EvalError::Type {
                expected: lase_lang::Ty::Num(want).describe(),
                found: lase_lang::Ty::Num(*d).describe(),
                context: ctx.into(),
                span,
                help: Some(format!(
                    "{} is measured in {}",
                    lase_lang::Ty::Num(want).describe(),
                    want.base_unit()
                )),
            }),
            other => Err(type_err(
                &lase_lang::Ty::Num(want).describe(),
                other,
                span,
                ctx,
            )),
        }
    }

    fn as_count(&self, v: &Value, span: Span, ctx: &str) -> R<i64> {
        let x = self.as_dim(v, Dim::NONE, span, ctx)?;
        if x.fract() != 0.0 || !x.is_finite() || x.abs() > 1e15 {
            return Err(bad(
                span,
                &format!("{ctx} must be a whole number"),
                "not a whole number",
                None,
            ));
        }
        Ok(x as i64)
    }

    fn as_point(&self, v: &Value, span: Span, ctx: &str) -> R<([f64; 3], u8)> {
        match v {
            Value::Point(p, n) => Ok((*p, *n)),
            other => Err(type_err("a point", other, span, ctx)),
        }
    }

    fn as_profile(&self, v: &Value, span: Span, ctx: &str) -> R<Rc<Profile>> {
        match v {
            Value::Profile(p) => Ok(p.clone()),
            other => Err(type_err("a profile", other, span, ctx)),
        }
    }

    // ------------------------------------------------------------------ expressions

    fn expr(&mut self, e: &Expr, cx: &mut Cx) -> R<Value> {
        stacker::maybe_grow(STACK_RED_ZONE, STACK_SEGMENT, || self.expr_here(e, cx))
    }

    fn expr_here(&mut self, e: &Expr, cx: &mut Cx) -> R<Value> {
        match &e.kind {
            ExprKind::Number { value, unit } => match unit {
                None if *value == 0.0 => Ok(Value::Zero),
                None => Ok(Value::Num(*value, Dim::NONE)),
                Some((u, uspan)) => {
                    let unit = units::parse_unit(u)
                        .map_err(|_| bad(*uspan, "unknown unit", "not a unit", None))?;
                    Ok(Value::Num(value * unit.factor, unit.dim))
                }
            },
            ExprKind::Bool(b) => Ok(Value::Bool(*b)),
            ExprKind::Str(s) => Ok(Value::Str(s.as_str().into())),
            ExprKind::Var(name) => self
                .scopes
                .iter()
                .rev()
                .find_map(|s| s.get(name))
                .cloned()
                .ok_or_else(|| {
                    bad(
                        e.span,
                        &format!("`{name}` is not defined here"),
                        "undefined",
                        None,
                    )
                }),
            ExprKind::Point(items) => {
                let mut p = [0.0; 3];
                for (k, it) in items.iter().enumerate().take(3) {
                    let v = self.expr(it, cx)?;
                    p[k] = self.as_dim(&v, Dim::LENGTH, it.span, "a point coordinate")?;
                }
                if items.len() == 2 {
                    p[2] = 0.0;
                }
                Ok(Value::Point(p, items.len().min(3) as u8))
            }
            ExprKind::List(items) => {
                let mut out = Vec::with_capacity(items.len());
                for it in items {
                    out.push(self.expr(it, cx)?);
                }
                Ok(Value::List(Rc::new(out)))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                if matches!(op, BinOp::And | BinOp::Or) {
                    let l = self.expr(lhs, cx)?;
                    let l = self.as_bool(&l, lhs.span, op.symbol())?;
                    if (*op == BinOp::And && !l) || (*op == BinOp::Or && l) {
                        return Ok(Value::Bool(l));
                    }
                    let r = self.expr(rhs, cx)?;
                    return Ok(Value::Bool(self.as_bool(&r, rhs.span, op.symbol())?));
                }
                let l = self.expr(lhs, cx)?;
                let r = self.expr(rhs, cx)?;
                binary(*op, l, r, lhs.span, rhs.span)
            }
            ExprKind::Unary { op, expr } => {
                let v = self.expr(expr, cx)?;
                match (op, v) {
                    (UnOp::Neg, Value::Num(x, d)) => Ok(Value::Num(-x, d)),
                    (UnOp::Neg, Value::Zero) => Ok(Value::Zero),
                    (UnOp::Neg, Value::Point(p, n)) => Ok(Value::Point([-p[0], -p[1], -p[2]], n)),
                    (UnOp::Not, Value::Bool(b)) => Ok(Value::Bool(!b)),
                    (_, other) => Err(type_err(
                        "a number, point or bool",
                        &other,
                        expr.span,
                        "a unary operator",
                    )),
                }
            }
            ExprKind::Field { expr, field } => {
                let v = self.expr(expr, cx)?;
                match (&v, field.name.as_str()) {
                    (Value::Point(p, _), "x") => Ok(Value::Num(p[0], Dim::LENGTH)),
                    (Value::Point(p, _), "y") => Ok(Value::Num(p[1], Dim::LENGTH)),
                    (Value::Point(p, _), "z") => Ok(Value::Num(p[2], Dim::LENGTH)),
                    (Value::Profile(p), "length") => Ok(Value::Num(p.length(), Dim::LENGTH)),
                    (Value::Profile(p), "start") => Ok(point2(p.start())),
                    (Value::Profile(p), "end") => Ok(point2(p.end())),
                    _ => Err(bad(
                        field.span,
                        &format!("{} has no field `{}`", v.type_name(), field.name),
                        "no such field",
                        None,
                    )),
                }
            }
            ExprKind::Index { expr, index } => {
                let v = self.expr(expr, cx)?;
                let i = self.expr(index, cx)?;
                let i = self.as_count(&i, index.span, "an index")?;
                match v {
                    Value::List(items) => {
                        let len = items.len() as i64;
                        let k = if i < 0 { len + i } else { i };
                        items
                            .get(k as usize)
                            .filter(|_| k >= 0)
                            .cloned()
                            .ok_or_else(|| {
                                bad(
                                    index.span,
                                    &format!("index {i} is out of range for a list of {len}"),
                                    "out of range",
                                    Some("indices run from 0; negative ones count from the end"),
                                )
                            })
                    }
                    other => Err(type_err("a list", &other, expr.span, "indexing")),
                }
            }
            ExprKind::Call { callee, args } => self.call(callee, args, e.span, cx),
            ExprKind::Profile { kind, args, flags } => self.profile(kind, args, flags, e.span, cx),
        }
    }

    /// Binds arguments to named parameters (positional first, then by name).
    fn bind_args(
        &mut self,
        names: &[&str],
        args: &[Arg],
        cx: &mut Cx,
    ) -> R<Vec<Option<(Value, Span)>>> {
        let mut out: Vec<Option<(Value, Span)>> = vec![None; names.len()];
        let mut pos = 0;
        for a in args {
            let v = self.expr(&a.value, cx)?;
            let idx = match &a.name {
                Some(n) => names.iter().position(|p| *p == n.name),
                None => {
                    pos += 1;
                    Some(pos - 1)
                }
            };
            if let Some(i) = idx.filter(|i| *i < names.len()) {
                out[i] = Some((v, a.value.span));
            }
        }
        Ok(out)
    }

    fn call(&mut self, callee: &Ident, args: &[Arg], span: Span, cx: &mut Cx) -> R<Value> {
        if let Some(f) = self.fns.get(&callee.name).cloned() {
            let names: Vec<&str> = f.params.iter().map(|p| p.name.name.as_str()).collect();
            let bound = self.bind_args(&names, args, cx)?;
            if self.depth >= MAX_DEPTH {
                return Err(EvalError::Budget {
                    message: format!("functions nest more than {MAX_DEPTH} calls deep"),
                    span,
                    help: Some("a recursive function never reaches its base case".into()),
                });
            }
            let mut scope = HashMap::new();
            for (p, b) in f.params.iter().zip(bound) {
                let (v, vspan) = b.ok_or_else(|| {
                    bad(
                        span,
                        &format!("missing argument `{}`", p.name.name),
                        "in this call",
                        None,
                    )
                })?;
                if let Some(ty) = &p.ty {
                    self.check_annotation(
                        &v,
                        &ty.name,
                        vspan,
                        &format!("parameter `{}`", p.name.name),
                    )?;
                }
                scope.insert(p.name.name.clone(), v);
            }
            // A function sees the recipe's globals and its parameters, not its caller's locals.
            let saved = self.scopes.split_off(1);
            self.scopes.push(scope);
            self.depth += 1;
            let r = self.block(&f.body, cx);
            self.depth -= 1;
            self.scopes.truncate(1);
            self.scopes.extend(saved);
            let v = match r? {
                Flow::Return(v) => v,
                Flow::Normal => Value::Nothing,
            };
            if let Some(ty) = &f.ret {
                self.check_annotation(
                    &v,
                    &ty.name,
                    span,
                    &format!("the result of `{}`", callee.name),
                )?;
            }
            return Ok(v);
        }
        if let Some(sig) = self.ext.lookup(&callee.name) {
            // A Rhai extension function: bound like a recipe `fn`, converted and run by `ext`.
            let names: Vec<String> = sig.params.iter().map(|(n, _)| n.clone()).collect();
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let bound = self.bind_args(&names, args, cx)?;
            let mut values = Vec::with_capacity(bound.len());
            for (n, b) in names.iter().zip(bound) {
                values.push(b.ok_or_else(|| {
                    bad(
                        span,
                        &format!("missing argument `{n}`"),
                        "in this call",
                        None,
                    )
                })?);
            }
            return Ok(self.ext.call(&callee.name, &values, span)?);
        }
        let Some(b) = schema::builtin(&callee.name) else {
            return Err(bad(
                callee.span,
                &format!("unknown function `{}`", callee.name),
                "unknown",
                None,
            ));
        };
        let names: Vec<&str> = b.params.iter().map(|p| p.name).collect();
        let a = self.bind_args(&names, args, cx)?;
        let arg = |i: usize| {
            a.get(i).cloned().flatten().ok_or_else(|| {
                bad(
                    span,
                    &format!("missing argument `{}`", names[i]),
                    "in this call",
                    None,
                )
            })
        };
        let num = |_: &Self, i: usize| -> R<(f64, Dim, Span)> {
            let (v, sp) = arg(i)?;
            match v {
                Value::Num(x, d) => Ok((x, d, sp)),
                Value::Zero => Ok((0.0, Dim::NONE, sp)),
                other => Err(type_err(
                    "a number",
                    &other,
                    sp,
                    &format!("`{}`", callee.name),
                )),
            }
        };
        let prof = |s: &Self, i: usize| -> R<Rc<Profile>> {
            let (v, sp) = arg(i)?;
            s.as_profile(&v, sp, &format!("`{}`", callee.name))
        };
        let len = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = arg(i)?;
            s.as_dim(&v, Dim::LENGTH, sp, &format!("`{}`", names[i]))
        };
        let ang = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = arg(i)?;
            s.as_dim(&v, Dim::ANGLE, sp, &format!("`{}`", names[i]))
        };
        let pt = |s: &Self, i: usize| -> R<[f64; 3]> {
            let (v, sp) = arg(i)?;
            Ok(s.as_point(&v, sp, &format!("`{}`", names[i]))?.0)
        };
        Ok(match b.name {
            "offset" => {
                let p = prof(self, 0)?;
                let d = len(self, 1)?;
                let trim = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_bool(&v, sp, "`trim`")?,
                    None => false,
                };
                let opts = crate::geometry::offset::OffsetOptions {
                    trim,
                    tol_mm: self.planner_settings_now().arc_tolerance_mm,
                };
                let o = p.offset_with(d, &opts).map_err(|g| {
                    // A fold-over is a property of the profile: point at it.
                    let at = match g {
                        GeomError::FoldOver { .. } => {
                            a.first().cloned().flatten().map_or(span, |x| x.1)
                        }
                        _ => span,
                    };
                    geom_error(g, at, Some(d))
                })?;
                Value::Profile(Rc::new(o))
            }
            "reverse" => Value::Profile(Rc::new(prof(self, 0)?.reversed())),
            "translate" => {
                let p = prof(self, 0)?;
                let v = pt(self, 1)?;
                Value::Profile(Rc::new(p.transformed(0.0, V2::new(v[0], v[1]))))
            }
            "rotate" => {
                let p = prof(self, 0)?;
                let angle = ang(self, 1)?;
                let c = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_point(&v, sp, "`about`")?.0,
                    None => [0.0; 3],
                };
                // Turning about c is turning about the origin, then shifting c back onto itself.
                let cv = V2::new(c[0], c[1]);
                let rot = nalgebra::Rotation2::new(angle);
                Value::Profile(Rc::new(p.transformed(angle, cv - rot * cv)))
            }
            "length" => Value::Num(prof(self, 0)?.length(), Dim::LENGTH),
            "start" => point2(prof(self, 0)?.start()),
            "end" => point2(prof(self, 0)?.end()),
            "point_at" => {
                let p = prof(self, 0)?;
                let s = len(self, 1)?;
                point2(p.point_at(s))
            }
            "polar" => {
                let r = len(self, 0)?;
                let a = ang(self, 1)?;
                Value::Point([r * a.cos(), r * a.sin(), 0.0], 2)
            }
            "distance" => {
                let p = pt(self, 0)?;
                let q = pt(self, 1)?;
                Value::Num(
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt(),
                    Dim::LENGTH,
                )
            }
            "sqrt" => {
                let (x, d, sp) = num(self, 0)?;
                if x < 0.0 {
                    return Err(bad(
                        sp,
                        "square root of a negative number",
                        "negative",
                        None,
                    ));
                }
                if [d.length, d.time, d.angle, d.power]
                    .iter()
                    .any(|e| e % 2 != 0)
                {
                    return Err(bad(
                        sp,
                        "sqrt needs even unit powers",
                        "odd unit power",
                        None,
                    ));
                }
                Value::Num(
                    x.sqrt(),
                    Dim::new(d.length / 2, d.time / 2, d.angle / 2, d.power / 2),
                )
            }
            "abs" => {
                let (x, d, _) = num(self, 0)?;
                Value::Num(x.abs(), d)
            }
            "min" | "max" => {
                let (x, dx, _) = num(self, 0)?;
                let (y, dy, sy) = num(self, 1)?;
                let d = if a_is_zero(&a, 0) { dy } else { dx };
                if dx != dy && !a_is_zero(&a, 0) && !a_is_zero(&a, 1) {
                    return Err(bad(
                        sy,
                        "both operands need one dimension",
                        "different dimension",
                        None,
                    ));
                }
                Value::Num(if b.name == "min" { x.min(y) } else { x.max(y) }, d)
            }
            "sin" => Value::Num(ang(self, 0)?.sin(), Dim::NONE),
            "cos" => Value::Num(ang(self, 0)?.cos(), Dim::NONE),
            "tan" => Value::Num(ang(self, 0)?.tan(), Dim::NONE),
            "atan2" => {
                let (y, _, _) = num(self, 0)?;
                let (x, _, _) = num(self, 1)?;
                Value::Num(y.atan2(x), Dim::ANGLE)
            }
            "floor" | "ceil" | "round" => {
                let (x, d, sp) = num(self, 0)?;
                if !d.is_none() {
                    return Err(bad(
                        sp,
                        "rounding needs a plain number",
                        "has a unit",
                        Some("divide by a unit first: `round(x / 1 mm)`"),
                    ));
                }
                Value::Num(
                    match b.name {
                        "floor" => x.floor(),
                        "ceil" => x.ceil(),
                        _ => x.round(),
                    },
                    Dim::NONE,
                )
            }
            "len" => {
                let (v, sp) = arg(0)?;
                match v {
                    Value::List(items) => Value::Num(items.len() as f64, Dim::NONE),
                    other => return Err(type_err("a list", &other, sp, "`len`")),
                }
            }
            other => {
                return Err(bad(
                    callee.span,
                    &format!("`{other}` is not available"),
                    "not available",
                    None,
                ));
            }
        })
    }

    fn check_annotation(&self, v: &Value, ty: &str, span: Span, ctx: &str) -> R<()> {
        let ok = match (ty, v) {
            ("bool", Value::Bool(_))
            | ("string", Value::Str(_))
            | ("point", Value::Point(..))
            | ("profile", Value::Profile(_))
            | ("list", Value::List(_)) => true,
            (_, Value::Zero) => units::dim_by_name(ty).is_some(),
            (t, Value::Num(_, d)) => units::dim_by_name(t) == Some(*d),
            _ => false,
        };
        if ok {
            Ok(())
        } else {
            Err(EvalError::Type {
                expected: ty.to_string(),
                found: v.type_name(),
                context: ctx.into(),
                span,
                help: None,
            })
        }
    }

    fn profile(
        &mut self,
        kind: &Ident,
        args: &[Arg],
        flags: &[Ident],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        let Some(pk) = schema::profile_kind(&kind.name) else {
            return Err(bad(kind.span, "unknown profile", "unknown", None));
        };
        let names: Vec<&str> = pk.params.iter().map(|p| p.name).collect();
        let a = self.bind_args(&names, args, cx)?;
        let has = |f: &str| flags.iter().any(|x| x.name == f);
        let get = |i: usize| {
            a.get(i).cloned().flatten().ok_or_else(|| {
                bad(
                    span,
                    &format!("missing `{}`", names[i]),
                    "in this profile",
                    None,
                )
            })
        };
        let pt = |s: &Self, i: usize| -> R<V2> {
            let (v, sp) = get(i)?;
            let (p, _) = s.as_point(&v, sp, &format!("`{}`", names[i]))?;
            Ok(V2::new(p[0], p[1]))
        };
        let len = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = get(i)?;
            s.as_dim(&v, Dim::LENGTH, sp, &format!("`{}`", names[i]))
        };
        let ang = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = get(i)?;
            s.as_dim(&v, Dim::ANGLE, sp, &format!("`{}`", names[i]))
        };
        let r = match pk.name {
            "polyline" => {
                let (v, sp) = get(0)?;
                let Value::List(items) = v else {
                    return Err(type_err("a list of points", &v, sp, "`points`"));
                };
                let mut pts = Vec::with_capacity(items.len());
                for it in items.iter() {
                    let (p, _) = self.as_point(it, sp, "a polyline point")?;
                    pts.push(V2::new(p[0], p[1]));
                }
                Profile::polyline(&pts, has("closed"))
            }
            "line" => Profile::polyline(&[pt(self, 0)?, pt(self, 1)?], false),
            "arc" => Profile::arc(
                pt(self, 0)?,
                len(self, 1)?,
                ang(self, 2)?,
                ang(self, 3)?,
                !has("cw"),
            ),
            "circle" => {
                let a0 = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`start`")?,
                    None => 0.0,
                };
                Profile::circle(pt(self, 0)?, len(self, 1)?, a0, !has("cw"))
            }
            "rect" => {
                let c = pt(self, 0)?;
                let w = len(self, 1)?;
                let h = len(self, 2)?;
                if !(w > 0.0 && h > 0.0) {
                    return Err(bad(
                        span,
                        "a rectangle needs a positive width and height",
                        "empty rectangle",
                        None,
                    ));
                }
                Profile::polyline(
                    &[
                        c,
                        c + V2::new(w, 0.0),
                        c + V2::new(w, h),
                        c + V2::new(0.0, h),
                    ],
                    true,
                )
            }
            "spline" => {
                let (v, sp) = get(0)?;
                let Value::List(items) = v else {
                    return Err(type_err("a list of points", &v, sp, "`points`"));
                };
                let mut pts = Vec::with_capacity(items.len());
                for it in items.iter() {
                    let (p, _) = self.as_point(it, sp, "a spline point")?;
                    pts.push(V2::new(p[0], p[1]));
                }
                Profile::interpolate(&pts, has("closed"))
            }
            "cam" => return self.cam_profile(&a, span, cx),
            "dxf" | "svg" => return self.imported_profile(pk.name, &a, span, cx),
            other => {
                return Err(bad(
                    kind.span,
                    &format!("`profile {other}` is not supported yet"),
                    "not supported",
                    None,
                ));
            }
        };
        r.map(|p| Value::Profile(Rc::new(p)))
            .map_err(|g| geom_error(g, span, None))
    }

    /// `profile cam(...)`: a motion program (rise, top dwell, fall, base dwell) or a lift table.
    fn cam_profile(&mut self, a: &[Option<(Value, Span)>], span: Span, cx: &mut Cx) -> R<Value> {
        use crate::geometry::cam::{CamLaw, CamSegment, CamSegmentKind};
        let arg = |i: usize| a.get(i).cloned().flatten();
        let (bv, bs) = arg(0).ok_or_else(|| bad(span, "missing `base`", "in this cam", None))?;
        let base = self.positive_length(&bv, bs, "`base`")?;
        if let Some((tv, ts)) = arg(6) {
            let Value::Str(path) = &tv else {
                return Err(type_err("a file name", &tv, ts, "`table`"));
            };
            if let Some((_, ls)) = arg(1) {
                return Err(bad(
                    ls,
                    "a cam takes its lift from a motion program or from a table, not both",
                    "remove this",
                    Some("with `table`, the lift of every angle is in the file"),
                ));
            }
            let text = self.data_file(path, ts, cx)?;
            let prof =
                Profile::cam_from_lift_csv(base, &text).map_err(|e| EvalError::Geometry {
                    message: format!("lift table \"{path}\": {e}"),
                    span: ts,
                    label: "this table".into(),
                    help: Some(
                        "one `angle_deg, lift_mm` row a line, angles increasing within one turn"
                            .into(),
                    ),
                })?;
            return Ok(Value::Profile(Rc::new(prof)));
        }
        let need = |i: usize, name: &str| {
            arg(i).ok_or_else(|| {
                bad(
                    span,
                    &format!("a cam motion program needs `{name}`"),
                    "in this cam",
                    Some("give `lift`, `rise` (and optionally `top`, `fall`, `law`), or a lift `table`"),
                )
            })
        };
        let (lv, ls) = need(1, "lift")?;
        let lift = self.positive_length(&lv, ls, "`lift`")?;
        let (rv, rs) = need(2, "rise")?;
        let rise = self.as_dim(&rv, Dim::ANGLE, rs, "`rise`")?.to_degrees();
        let dwell = match arg(3) {
            Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`top`")?.to_degrees(),
            None => 0.0,
        };
        let fall = match arg(4) {
            Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`fall`")?.to_degrees(),
            None => rise,
        };
        let law = match arg(5) {
            None => CamLaw::Cycloidal,
            Some((Value::Str(w), sp)) => match &*w {
                "harmonic" => CamLaw::Harmonic,
                "cycloidal" => CamLaw::Cycloidal,
                "345" | "3-4-5" | "poly345" => CamLaw::Poly345,
                "modified_trapezoid" => CamLaw::ModifiedTrapezoid,
                other => {
                    let help = did_you_mean(
                        other,
                        ["harmonic", "cycloidal", "345", "modified_trapezoid"].into_iter(),
                    )
                    .unwrap_or_else(|| {
                        "the laws are \"harmonic\", \"cycloidal\", \"345\" and \"modified_trapezoid\"".into()
                    });
                    return Err(bad(
                        sp,
                        &format!("unknown cam law \"{other}\""),
                        "not a cam law",
                        Some(&help),
                    ));
                }
            },
            Some((v, sp)) => return Err(type_err("a law name", &v, sp, "`law`")),
        };
        for (name, deg, i) in [("rise", rise, 2), ("top", dwell, 3), ("fall", fall, 4)] {
            let neg = if name == "top" { deg < 0.0 } else { deg <= 0.0 };
            if neg || !deg.is_finite() {
                let sp = arg(i).map_or(span, |x| x.1);
                return Err(bad(
                    sp,
                    &format!("`{name}` must be a positive angle"),
                    "out of range",
                    None,
                ));
            }
        }
        let rest = 360.0 - rise - dwell - fall;
        if rest < -1e-9 {
            return Err(bad(
                span,
                &format!(
                    "rise, top and fall add up to {}°, more than a turn",
                    units::format_number(rise + dwell + fall)
                ),
                "this cam",
                Some("the base dwell takes what is left of 360°"),
            ));
        }
        let seg = |kind, duration_deg| CamSegment {
            kind,
            law,
            duration_deg,
            lift_mm: lift,
        };
        let mut segs = vec![seg(CamSegmentKind::Rise, rise)];
        if dwell > 0.0 {
            segs.push(seg(CamSegmentKind::Dwell, dwell));
        }
        segs.push(seg(CamSegmentKind::Return, fall));
        if rest > 1e-9 {
            segs.push(seg(CamSegmentKind::Dwell, rest));
        }
        // 0.25° samples: the spline through them follows the law's lift to well under a µm.
        let prof = Profile::cam(base, &segs, 1440).map_err(|g| geom_error(g, span, None))?;
        Ok(Value::Profile(Rc::new(prof)))
    }

    /// `profile dxf(file)` and `profile svg(path data)`.
    fn imported_profile(
        &mut self,
        kind: &str,
        a: &[Option<(Value, Span)>],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        use crate::geometry::import::{ImportOptions, dxf_profiles, svg_path_profiles};
        let (v, sp) = a
            .first()
            .cloned()
            .flatten()
            .ok_or_else(|| bad(span, "missing the source", "in this profile", None))?;
        let Value::Str(src) = &v else {
            return Err(type_err("a string", &v, sp, "the source"));
        };
        let tol = self.planner_settings_now().arc_tolerance_mm;
        let opts = ImportOptions {
            tol_mm: tol,
            flip_y: kind == "svg",
            ..ImportOptions::default()
        };
        let (profiles, what) = if kind == "dxf" {
            let text = self.data_file(src, sp, cx)?;
            (dxf_profiles(&text, &opts), format!("DXF file \"{src}\""))
        } else {
            (svg_path_profiles(src, &opts), "SVG path data".to_string())
        };
        let profiles = profiles.map_err(|e| EvalError::Geometry {
            message: format!("{what}: {e}"),
            span: sp,
            label: "cannot be read".into(),
            help: None,
        })?;
        let index = match a.get(1).cloned().flatten() {
            Some((v, isp)) => Some((self.as_count(&v, isp, "`index`")?, isp)),
            None => None,
        };
        let n = profiles.len();
        let pick = match index {
            Some((i, isp)) if i < 0 || i as usize >= n => {
                return Err(bad(
                    isp,
                    &format!("{what} holds {n} contour(s)"),
                    "no such contour",
                    Some(&format!("`index` runs from 0 to {}", n.saturating_sub(1))),
                ));
            }
            Some((i, _)) => i as usize,
            None if n == 1 => 0,
            None => {
                return Err(bad(
                    sp,
                    &format!("{what} holds {n} contours"),
                    "which one?",
                    Some(&format!(
                        "pick one with `index: 0` … `index: {}`",
                        n.saturating_sub(1)
                    )),
                ));
            }
        };
        Ok(Value::Profile(Rc::new(
            profiles.into_iter().nth(pick).expect("checked"),
        )))
    }

    /// The text of a data file named in the recipe, relative to the file that names it.
    fn data_file(&self, path: &str, span: Span, cx: &mut Cx) -> R<String> {
        let importer = cx
            .map
            .file_of(span.start as usize)
            .map(|f| cx.map.name(f).to_string())
            .unwrap_or_default();
        cx.host
            .data_file(&importer, path)
            .map(|(_, text)| text)
            .map_err(|reason| EvalError::Geometry {
                message: format!("cannot read \"{path}\": {reason}"),
                span,
                label: "this file".into(),
                help: Some("paths are relative to the recipe's folder".into()),
            })
    }
}

fn a_is_zero(a: &[Option<(Value, Span)>], i: usize) -> bool {
    matches!(a.get(i), Some(Some((Value::Zero, _))))
}

struct Cx<'a> {
    program: &'a Program,
    map: &'a mut SourceMap,
    host: &'a mut dyn Host,
}

fn point2(v: V2) -> Value {
    Value::Point([v.x, v.y, 0.0], 2)
}

fn no_machine(span: Span) -> EvalError {
    EvalError::NoMachine {
        span,
        help: Some(format!(
            "start the recipe with `machine NAME` (stock machines: {}) or `machine \"file.toml\"`",
            lase_stdlib::machine_names().collect::<Vec<_>>().join(", ")
        )),
    }
}

fn bad(span: Span, message: &str, label: &str, help: Option<&str>) -> EvalError {
    EvalError::BadValue {
        message: message.into(),
        span,
        label: label.into(),
        help: help.map(String::from),
    }
}

fn type_err(expected: &str, found: &Value, span: Span, ctx: &str) -> EvalError {
    EvalError::Type {
        expected: expected.into(),
        found: found.type_name(),
        context: ctx.into(),
        span,
        help: None,
    }
}

fn geom_error(g: GeomError, span: Span, offset: Option<f64>) -> EvalError {
    let help = match (&g, offset) {
        (GeomError::FoldOver { radius, .. }, _) => Some(format!(
            "offset by less than {} here, round the profile's concave region to a radius above \
             the distance, or write `offset(..., trim: true)` for the clean offset with the \
             loops cut away",
            format_quantity(*radius, Dim::LENGTH)
        )),
        (GeomError::Split { .. }, Some(_)) => Some("use a smaller offset distance".into()),
        _ => None,
    };
    EvalError::Geometry {
        message: g.to_string(),
        span,
        label: if let GeomError::FoldOver { s_start, s_end, .. } = &g {
            format!(
                "this profile's concave region from s = {} to {} is too tight for the offset",
                format_quantity(*s_start, Dim::LENGTH),
                format_quantity(*s_end, Dim::LENGTH)
            )
        } else if offset.is_some() {
            "this offset".into()
        } else {
            "this profile".into()
        },
        help,
    }
}

fn binary(op: BinOp, l: Value, r: Value, ls: Span, rs: Span) -> R<Value> {
    use Value::*;
    let mismatch = |l: &Value, r: &Value| EvalError::Type {
        expected: format!("operands that `{}` accepts", op.symbol()),
        found: format!("{} and {}", l.type_name(), r.type_name()),
        context: format!("`{}`", op.symbol()),
        span: ls.to(rs),
        help: Some("both sides of + and - need one dimension".into()),
    };
    let num = |v: &Value| match v {
        Num(x, d) => Some((*x, Some(*d))),
        Zero => Some((0.0, None)),
        _ => None,
    };
    if let (Some((a, da)), Some((b, db))) = (num(&l), num(&r)) {
        let same = |da: Option<Dim>, db: Option<Dim>| -> Option<Option<Dim>> {
            match (da, db) {
                (Some(x), Some(y)) if x == y => Some(Some(x)),
                (Some(x), None) | (None, Some(x)) => Some(Some(x)),
                (None, None) => Some(None),
                _ => None,
            }
        };
        let mk = |x: f64, d: Option<Dim>| match d {
            Some(d) => Num(x, d),
            None => Zero,
        };
        return match op {
            BinOp::Add | BinOp::Sub | BinOp::Rem => {
                let d = same(da, db).ok_or_else(|| mismatch(&l, &r))?;
                Ok(match op {
                    BinOp::Add => mk(a + b, d),
                    BinOp::Sub => mk(a - b, d),
                    _ => {
                        if b == 0.0 {
                            return Err(bad(rs, "remainder by zero", "zero", None));
                        }
                        mk(a % b, d)
                    }
                })
            }
            BinOp::Mul => Ok(match (da, db) {
                (Some(x), Some(y)) => Num(a * b, x * y),
                (Some(x), None) | (None, Some(x)) => Num(0.0, x),
                (None, None) => Zero,
            }),
            BinOp::Div => {
                if b == 0.0 {
                    return Err(bad(rs, "division by zero", "this is zero", None));
                }
                Ok(Num(
                    a / b,
                    da.unwrap_or(Dim::NONE) / db.unwrap_or(Dim::NONE),
                ))
            }
            _ => {
                same(da, db).ok_or_else(|| mismatch(&l, &r))?;
                Ok(Bool(match op {
                    BinOp::Eq => a == b,
                    BinOp::Ne => a != b,
                    BinOp::Lt => a < b,
                    BinOp::Le => a <= b,
                    BinOp::Gt => a > b,
                    _ => a >= b,
                }))
            }
        };
    }
    match (op, &l, &r) {
        (BinOp::Add, Point(a, n), Point(b, m)) => {
            Ok(Point([a[0] + b[0], a[1] + b[1], a[2] + b[2]], (*n).max(*m)))
        }
        (BinOp::Sub, Point(a, n), Point(b, m)) => {
            Ok(Point([a[0] - b[0], a[1] - b[1], a[2] - b[2]], (*n).max(*m)))
        }
        (BinOp::Mul, Point(a, n), Num(k, d)) | (BinOp::Mul, Num(k, d), Point(a, n))
            if d.is_none() =>
        {
            Ok(Point([a[0] * k, a[1] * k, a[2] * k], *n))
        }
        (BinOp::Div, Point(a, n), Num(k, d)) if d.is_none() => {
            if *k == 0.0 {
                return Err(bad(rs, "division by zero", "this is zero", None));
            }
            Ok(Point([a[0] / k, a[1] / k, a[2] / k], *n))
        }
        (BinOp::Add, Str(a), Str(b)) => Ok(Str(format!("{a}{b}").into())),
        (BinOp::Eq, Bool(a), Bool(b)) => Ok(Bool(a == b)),
        (BinOp::Ne, Bool(a), Bool(b)) => Ok(Bool(a != b)),
        (BinOp::Eq, Str(a), Str(b)) => Ok(Bool(a == b)),
        (BinOp::Ne, Str(a), Str(b)) => Ok(Bool(a != b)),
        _ => Err(mismatch(&l, &r)),
    }
}
