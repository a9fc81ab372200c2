//! Look-ahead motion planner: timed motion from a sequence of straight moves in axis space.
//!
//! (The helper building this module replaces this header with the real one.)

/// Most machine axes one plan can carry (X Y Z A B C). Unused axes stay at zero.
pub const MAX_AXES: usize = 6;

/// A position or a per-axis quantity, in machine units (mm for linear axes, rad for rotary).
pub type Axes = [f64; MAX_AXES];
