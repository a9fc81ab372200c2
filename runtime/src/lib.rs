//! lase runtime: everything after the language.
//!
//! The evaluator turns a checked AST into a [`program::ProcessProgram`]; the motion core
//! (`geometry`, `kinematics`, `planner`, `motion`) is plain math on plain data; `emit` is the
//! only code that knows NC text; `link` the only code that knows a controller protocol.

pub mod axes;
pub mod compile;
pub mod emit;
pub mod eval;
pub mod ext;
pub mod geometry;
pub mod host;
pub mod kinematics;
pub mod link;
pub mod machine;
pub mod motion;
pub mod planner;
pub mod program;
pub mod raster;
pub mod report;
pub mod value;

pub use compile::{Failure, Files, FsFiles, MemFiles, Recipe, compile};
