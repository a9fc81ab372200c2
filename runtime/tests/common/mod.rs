//! Shared helpers of the runtime's integration tests: recipe text to a planned job.

#![allow(dead_code)]

use lase_runtime::compile::{self, MemFiles};
use lase_runtime::motion::{Job, MotionError, plan_program};

/// Parses, checks, evaluates and plans recipe text (stock machines only), through the
/// pipeline `lase` runs; the planner's error comes back as it is, for the tests to match.
pub fn compile(src: &str) -> Result<Job, MotionError> {
    let mut files = MemFiles::new([("test.lase", src)]);
    let mut recipe = compile::load(&mut files, "test.lase").unwrap_or_else(|(_, f)| panic!("{f}"));
    compile::check(&recipe).unwrap_or_else(|f| panic!("{f}"));
    let program = compile::evaluate(&mut recipe, &mut files).unwrap_or_else(|f| panic!("{f}"));
    plan_program(program)
}

/// [`compile`], which must succeed.
pub fn job(src: &str) -> Job {
    compile(src).unwrap_or_else(|e| panic!("{e:?}"))
}

/// A hand-built program on a stock machine, with the machine's own limits and planner
/// settings and no lead-ins (the tests of hand-built moves pin closed forms from rest; leads
/// have their own tests in leadin.rs).
pub fn program(
    machine: &str,
    ops: Vec<lase_runtime::program::Op>,
) -> lase_runtime::program::ProcessProgram {
    use lase_runtime::program::{AxisLimit, LeadIn, PathLimits, PlannerSettings};
    let m =
        lase_runtime::machine::parse_machine(lase_stdlib::machine(machine).unwrap(), 0).unwrap();
    lase_runtime::program::ProcessProgram {
        recipe: "test.lase".into(),
        limits: AxisLimit::of_machine(&m),
        path_limits: PathLimits::default(),
        planner: PlannerSettings {
            ramp: m.ramp,
            junction_deviation_mm: m.junction_deviation_mm,
            arc_tolerance_mm: m.arc_tolerance_mm,
            lookahead: None,
            leadin: LeadIn::Off,
            order: Default::default(),
            origin: Default::default(),
        },
        start: [0.0; 3],
        ordering: None,
        ops,
        settles: Vec::new(),
        machine: m,
    }
}

pub mod axis_limits;

/// Every example recipe (`examples/*.lase`), sorted by path.
pub fn examples() -> Vec<std::path::PathBuf> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "lase"))
        .collect();
    v.sort();
    v
}

/// A recipe file loaded, checked and evaluated (not planned): the program `lase` plans.
pub fn program_of(
    files: &mut impl lase_runtime::compile::Files,
    path: &str,
) -> lase_runtime::program::ProcessProgram {
    let mut recipe = compile::load(files, path).unwrap_or_else(|(_, f)| panic!("{path}: {f}"));
    compile::check(&recipe).unwrap_or_else(|f| panic!("{path}: {f}"));
    compile::evaluate(&mut recipe, files).unwrap_or_else(|f| panic!("{path}: {f}"))
}

/// `lase emit`'s windowed path: `program` planned in windows of at least `min_window`
/// segments, read by `facts`, then written in `dialect`: the NC text, or the refusal's `Debug`.
pub fn emit_in_windows(
    what: &str,
    program: &lase_runtime::program::ProcessProgram,
    mut facts: lase_runtime::emit::PlanFacts,
    dialect: lase_runtime::emit::Dialect,
    min_window: usize,
) -> Result<String, String> {
    let (job, _) =
        lase_runtime::motion::plan_program_windows_sized(program.clone(), min_window, |p, w| {
            facts.window(p, &w)
        })
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    facts.finish(&job.program);
    let mut got = String::new();
    let r =
        lase_runtime::emit::emit_planned(&job, &facts, dialect, &Default::default(), &mut |l| {
            got.push_str(&l.text);
            got.push('\n');
            Ok(())
        });
    r.map(|_| got).map_err(|e| format!("{e:?}"))
}

pub mod rng;
mod uncarried;
#[allow(unused_imports)]
pub use uncarried::{uncarried, uncarried_text};

/// Plan time at which the path distance reaches `s` (`leave`: the last instant still at `s`,
/// i.e. after any standstill there).
pub fn time_at(j: &Job, s: f64, leave: bool) -> f64 {
    let (mut lo, mut hi) = (0.0, j.plan.duration());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        let here = j.plan.sample(mid).s;
        if here < s || (leave && here <= s) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
