//! lase runtime: everything after the language.
//!
//! The evaluator turns a checked AST into a [`program::ProcessProgram`]; the motion core
//! (`geometry`, `kinematics`, `planner`, `motion`) is plain math on plain data; `emit` is the
//! only code that knows NC text; `link` the only code that knows a controller protocol.
//!
//! The facade: the pipeline ([`compile`] and its stages, [`Files`]), what it produces
//! ([`ProcessProgram`], [`Job`]) and the outputs (`emit`, `report`, `link`) are public, with the
//! motion core's modules for their own tests and benchmarks. Modules that only serve other
//! modules (`raster`, `value`, `host`, and inside `link` the resume logic and the settings
//! requirements) are crate-private; what callers need of them is re-exported where it is used
//! (`eval::{Value, Host}`, `link::{AxisNeed, Requirements, SettingMismatch}`).

pub mod axes;
pub mod compile;
pub mod emit;
pub mod eval;
pub mod ext;
pub mod geometry;
pub(crate) mod host;
pub mod kinematics;
pub mod link;
pub mod machine;
pub mod marking;
pub mod motion;
pub mod planner;
pub mod program;
pub(crate) mod raster;
pub mod report;
pub(crate) mod value;

pub use compile::{Failure, Files, FsFiles, MemFiles, Recipe, compile};
pub use emit::Dialect;
pub use machine::Machine;
pub use motion::Job;
pub use program::ProcessProgram;
