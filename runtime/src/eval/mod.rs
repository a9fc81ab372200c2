//! The evaluator: a checked recipe → a [`ProcessProgram`].
//!
//! It runs the recipe's statements in order, keeping the state a process sheet implies (the
//! machine, limits, laser and pulse settings, the spot position), and appends one [`Op`] per
//! motion or machine event, each with the span of the statement that produced it. It checks
//! at run time what only running can know: the machine's axes and limits, geometry that
//! cannot be built, values out of range, and the dimension of values the checker could not
//! type (unannotated function parameters). A runaway recipe is stopped by a step budget.

mod bounds;
mod builtins;
mod error;
mod expr;
mod image;
mod marking;
mod moves;
mod order;
mod profiles;
mod scan;
mod sheet;
mod stmt;

pub use crate::value::Value;
pub use error::EvalError;
use error::Kind;

use crate::geometry::toolpath::HeadSide;
use crate::geometry::{GeomError, V2};
use crate::machine::Machine;
use crate::program::*;
use lase_lang::ast::*;
use lase_lang::units::{Dim, format_quantity};
use lase_lang::{Program, SourceMap, Span, schema};
use std::collections::{HashMap, HashSet};
use std::rc::Rc;
use std::sync::Arc;

pub use crate::host::{Host, StdlibOnly};

/// Evaluation steps (every statement, every expression node, every loop turn, every function
/// call) before the recipe is stopped as runaway. Twenty million steps is a few seconds in a
/// debug build and well under one in a release build, and some thousand times what the largest
/// example takes; a recipe that needs more is computing, not describing a job, and an
/// exponential recursion (`f(n - 1) + f(n - 1)`) reaches it long before it would finish.
const STEP_BUDGET: u64 = 20_000_000;
/// Ops (moves, dot-mode stops, machine events) a program may hold. Two million holds issue 18's
/// million short moves from a `for` loop with room to spare; at the budget `lase check`, `plan`
/// and `emit` (planned in windows) hold some 180 MB, the commands that keep the whole plan
/// (`run`, `trace`, the REPL) some 450 MB, and the NC program streams for hours — far beyond a
/// real job (a million-spot raster on the fly is a few thousand ops). A loop that produces more
/// is stopped at the statement that passes it; a path or a scan that would is refused before any
/// of its ops is made (`bounds::room_for_ops`).
const MAX_OPS: usize = 2_000_000;
/// Pixel runs the image rows of a program may carry (`scan image`): a run is 8 B inside its
/// row's op and one NC block when written, so 20 million (a 4096 × 4096 photo at one run per
/// pixel, passes aside) is some 160 MB held and an NC program of a few hundred MB, written as
/// it streams. Counted by `bounds::room_for_runs`.
const MAX_RUNS: usize = 20_000_000;
/// Nested function calls before the recipe is stopped as runaway recursion.
const MAX_DEPTH: usize = 200;

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
    /// Width of the cut (`laser { kerf }`), mm.
    kerf_mm: f64,
    on: bool,
}

/// What one `laser { ... }` or `follow ... { ... }` settings list sets; `None` keeps the value in
/// force.
#[derive(Debug, Default)]
struct LaserSet {
    power: Option<f64>,
    spot: Option<f64>,
    couple: Option<Coupling>,
    standoff: Option<f64>,
    kerf: Option<f64>,
    side: Option<(HeadSide, Span)>,
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
    /// The laser the last lit op carries, shared by every op after it that carries the same
    /// ([`Evaluator::share_laser`]).
    shared_laser: Option<Arc<Laser>>,
    /// Default scan step of `follow` on oriented machines (`planner { step }`).
    scan_step_mm: Option<f64>,
    /// The beam orientation the last move left (oriented machines), kept by `move`.
    orient: Option<Orient>,
    pos: P3,
    start: P3,
    ops: Vec<Op>,
    /// Pixel runs carried by the image rows among `ops` (see [`MAX_RUNS`]).
    runs: usize,
    /// Row starts to settle (`scan … { settle }`), indices into `ops`.
    settles: Vec<crate::program::Settle>,
    steps: u64,
    /// The statement running now: where a step budget overrun inside an expression points.
    at: Span,
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
                kerf_mm: 0.0,
                on: false,
            },
            pulse: None,
            shared_laser: None,
            scan_step_mm: None,
            orient: None,
            pos: [0.0; 3],
            start: [0.0; 3],
            ops: Vec::new(),
            runs: 0,
            settles: Vec::new(),
            steps: 0,
            at: Span::new(0, 0),
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
        // Each recipe, and each REPL line, gets the whole budget.
        self.steps = 0;
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
        self.steps = 0;
        self.at = e.span;
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
        self.settles.clear();
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
        self.settles.clear();
        // An ordered program may end elsewhere than the ops as written.
        self.pos = p.ops.iter().rev().find_map(Op::target).unwrap_or(self.pos);
        self.start = self.pos;
        Ok(p)
    }

    /// The process program of everything evaluated so far.
    pub fn program(&self, recipe: &str, span: Span) -> R<ProcessProgram> {
        self.program_of(self.ops.clone(), recipe, span)
    }

    /// [`program`](Self::program) of an evaluator that is done: its ops move into the program
    /// instead of being copied (issue 18: a second copy of a million ops was the peak of
    /// memory of `lase check`).
    pub fn into_program(mut self, recipe: &str, span: Span) -> R<ProcessProgram> {
        let mut ops = std::mem::take(&mut self.ops);
        // The room the list grew into while evaluating (up to as much again) is given back.
        ops.shrink_to_fit();
        self.program_of(ops, recipe, span)
    }

    /// The process program of `ops` with this evaluator's machine and settings.
    fn program_of(&self, ops: Vec<Op>, recipe: &str, span: Span) -> R<ProcessProgram> {
        let machine = self.machine.clone().ok_or_else(|| no_machine(span))?;
        let planner = self.planner_settings_now();
        // Settled row starts are indices into the ops as written, so a program that settles
        // keeps its source order and no kerf (cut order and kerf serve cutting; settling,
        // texturing).
        let (ops, ordering) = if self.settles.is_empty() {
            order::order_ops(ops, self.start, planner.order, planner.arc_tolerance_mm)?
        } else {
            (ops, None)
        };
        Ok(ProcessProgram {
            recipe: recipe.to_string(),
            limits: self.limits.clone(),
            path_limits: self.path_limits.clone(),
            planner,
            start: self.start,
            ops,
            ordering,
            settles: self.settles.clone(),
            machine,
        })
    }
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

/// A diagnostic of one of the kinds that share a shape (`error::Kind`): a message, a label on
/// `span`, an optional help.
fn bad(kind: Kind, span: Span, message: &str, label: &str, help: Option<&str>) -> EvalError {
    EvalError::of_kind(
        kind,
        span,
        message.into(),
        label.into(),
        help.map(String::from),
    )
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
        (GeomError::Crosses { .. }, _) => Some(
            "order the points so the outline goes once round without crossing (a bow-tie's are \
             out of order), or make each lobe a profile of its own"
                .into(),
        ),
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
        } else if let GeomError::Crosses { .. } = &g {
            "this profile crosses itself".into()
        } else if offset.is_some() {
            "this offset".into()
        } else {
            "this profile".into()
        },
        help,
    }
}
