//! lase runtime: everything after the language.
//!
//! The evaluator turns a checked AST into a [`program::ProcessProgram`]; the motion core
//! (`geometry`, `kinematics`, `planner`) is plain math on plain data; `emit` is the only code
//! that knows NC text; `link` the only code that knows a controller protocol.

pub mod planner;
