//! The sandbox every extension runs in: a raw Rhai engine with only the packages it needs and
//! hard limits, so that an extension can compute but never touch the world or hang a recipe.
//!
//! - Packages: core (arithmetic, strings, iterators, function pointers), logic, math, arrays,
//!   maps, string building (for error messages). No file, network, process or clock access exists in the engine at all; `import`
//!   is compiled out (`no_module`), `eval` is disabled, `print`/`debug` go nowhere.
//! - Limits (per call from the recipe): [`MAX_OPERATIONS`] operations, [`MAX_CALL_LEVELS`]
//!   nested calls, expression depth [`MAX_EXPR_DEPTH`] ([`MAX_FN_EXPR_DEPTH`] in functions),
//!   strings of [`MAX_STRING`] bytes, arrays of [`MAX_ARRAY`] items, maps of [`MAX_MAP`].
//!   The operation budget is what stops an endless loop: deterministically, whatever the
//!   machine's speed, in well under a second.

use rhai::Engine;
use rhai::packages::{
    BasicArrayPackage, BasicMapPackage, BasicMathPackage, CorePackage, LogicPackage,
    MoreStringPackage, Package,
};

/// Operations one call from the recipe may run (a profile generator sampling 1000 points of
/// a 100-operation law uses a tenth of it).
pub const MAX_OPERATIONS: u64 = 1_000_000;
/// Nested Rhai function calls. Kept low enough for the evaluator's stack in debug builds.
pub const MAX_CALL_LEVELS: usize = 24;
pub const MAX_EXPR_DEPTH: usize = 64;
pub const MAX_FN_EXPR_DEPTH: usize = 32;
pub const MAX_STRING: usize = 16 * 1024;
/// Items in an array, nested ones counted. Rhai checks an array's whole size after every
/// `push`, so growing one item by item costs the square of its length: at 1 000 000 the
/// operation budget let a script run for minutes; at 100 000 the worst growth stops within
/// about 3 s of a debug build (tests/ext_rhai.rs). A profile of 30 000 points fits.
pub const MAX_ARRAY: usize = 100_000;
pub const MAX_MAP: usize = 10_000;
pub const MAX_VARIABLES: usize = 1_000;
pub const MAX_FUNCTIONS: usize = 1_000;

/// A fresh sandboxed engine with lase's types and functions registered.
pub(crate) fn sandbox() -> Engine {
    let mut e = Engine::new_raw();
    e.register_global_module(CorePackage::new().as_shared_module());
    e.register_global_module(LogicPackage::new().as_shared_module());
    e.register_global_module(BasicMathPackage::new().as_shared_module());
    e.register_global_module(BasicArrayPackage::new().as_shared_module());
    e.register_global_module(BasicMapPackage::new().as_shared_module());
    e.register_global_module(MoreStringPackage::new().as_shared_module());
    e.disable_symbol("eval");
    e.on_print(|_| {});
    e.on_debug(|_, _, _| {});
    e.set_max_operations(MAX_OPERATIONS);
    e.set_max_call_levels(MAX_CALL_LEVELS);
    e.set_max_expr_depths(MAX_EXPR_DEPTH, MAX_FN_EXPR_DEPTH);
    e.set_max_string_size(MAX_STRING);
    e.set_max_array_size(MAX_ARRAY);
    e.set_max_map_size(MAX_MAP);
    e.set_max_variables(MAX_VARIABLES);
    e.set_max_functions(MAX_FUNCTIONS);
    super::api::register(&mut e);
    e
}
