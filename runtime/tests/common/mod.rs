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
