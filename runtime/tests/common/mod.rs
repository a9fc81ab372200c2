//! Shared helpers of the runtime's integration tests: recipe text to a planned job.

#![allow(dead_code)]

use lase_lang::{Loader, SourceMap};
use lase_runtime::eval::{Evaluator, StdlibOnly};
use lase_runtime::motion::{Job, MotionError, plan_program};

struct NoImports;
impl Loader for NoImports {
    fn load(&mut self, _: &str, path: &str) -> Result<(String, String), String> {
        Err(format!("no imports in these tests ({path})"))
    }
}

/// Parses, checks, evaluates and plans recipe text (stock machines only).
pub fn compile(src: &str) -> Result<Job, MotionError> {
    let mut map = SourceMap::new();
    let id = map.add("test.lase", src.to_string());
    let (program, perr) = lase_lang::load(&mut map, id, &mut NoImports);
    assert!(perr.is_empty(), "{perr:?}");
    let cerr = lase_lang::check_program(&program);
    assert!(cerr.is_empty(), "{cerr:#?}");
    let mut ev = Evaluator::new();
    let stmts = program.modules[0].stmts.clone();
    ev.run(&stmts, &program, &mut map, &mut StdlibOnly)
        .unwrap_or_else(|e| panic!("{e:?}"));
    plan_program(ev.program("test.lase", Default::default()).unwrap())
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
        },
        start: [0.0; 3],
        ops,
        machine: m,
    }
}
