//! The planner's diagnostics: every way `plan` can refuse its input.
//!
//! The planner validates the whole program before it computes any timing, so a job never
//! starts with a move it could not execute (CONVENTIONS.md, "Validate the whole recipe before
//! anything moves"). Each variant carries a stable `lase::plan::*` code and a help line.
//! Indices are positions in the `moves` slice handed to [`plan`](fn@super::plan).

use miette::Diagnostic;
use thiserror::Error;

/// Why a program could not be planned.
#[derive(Debug, Clone, PartialEq, Error, Diagnostic)]
pub enum PlanError {
    /// A field of [`super::PlannerConfig`] is out of range.
    #[error("planner setting `{field}` = {value} is invalid: {why}")]
    #[diagnostic(
        code(lase::plan::bad_config),
        help(
            "path limits must be > 0 (f64::INFINITY for none), junction_deviation >= 0, n_axes in 1..=6"
        )
    )]
    BadConfig {
        field: &'static str,
        value: f64,
        why: &'static str,
    },

    /// An axis limit of an axis in use is NaN, zero or negative.
    #[error("axis {axis}: {kind} limit = {value} is invalid, it must be > 0")]
    #[diagnostic(
        code(lase::plan::bad_limit),
        help(
            "give every axis in use a positive speed, acceleration and jerk limit; use f64::INFINITY for unlimited"
        )
    )]
    BadLimit {
        axis: usize,
        kind: &'static str,
        value: f64,
    },

    /// The start position is not finite.
    #[error("start position of axis {axis} = {value} is not a finite number")]
    #[diagnostic(
        code(lase::plan::bad_start),
        help("the planner starts from a known, finite machine position")
    )]
    BadStart { axis: usize, value: f64 },

    /// A field of a move is NaN, infinite where it must not be, or negative.
    #[error("move {index}: `{field}` = {value} is invalid: {why}")]
    #[diagnostic(
        code(lase::plan::bad_move),
        help("check the geometry and feed that produced this move")
    )]
    BadMove {
        index: usize,
        field: &'static str,
        value: f64,
        why: &'static str,
    },

    /// A move of length 0 changes an axis: it would need infinite speed.
    #[error("move {index} has length 0 but moves axis {axis} by {delta}")]
    #[diagnostic(
        code(lase::plan::zero_length_motion),
        help("the caller must give every move that changes an axis a positive path length")
    )]
    ZeroLengthWithMotion {
        index: usize,
        axis: usize,
        delta: f64,
    },

    /// A move has a positive length but changes no axis, so nothing would move.
    #[error("move {index} has length {length} but changes no axis")]
    #[diagnostic(
        code(lase::plan::length_without_motion),
        help("a move of length > 0 must change at least one axis; use dwell_after for a pause")
    )]
    LengthWithoutMotion { index: usize, length: f64 },

    /// A move changes an axis beyond `n_axes`.
    #[error("move {index} moves axis {axis}, but only {n_axes} axes are in use")]
    #[diagnostic(
        code(lase::plan::unused_axis),
        help("raise PlannerConfig::n_axes or keep unused axes at their start value")
    )]
    UnusedAxis {
        index: usize,
        axis: usize,
        n_axes: usize,
    },

    /// The limits leave a quantity the profile needs unbounded (e.g. a trapezoid with no
    /// acceleration limit), so no finite-acceleration timing exists.
    #[error("move {index}: the path {what} is unbounded, so the move cannot be timed")]
    #[diagnostic(
        code(lase::plan::unbounded),
        help(
            "give the axes this move uses a finite acceleration limit (S-curve: a finite acceleration or jerk limit)"
        )
    )]
    Unbounded { index: usize, what: &'static str },

    /// More moves than a segment index can address.
    #[error("{count} moves are more than the planner can index")]
    #[diagnostic(
        code(lase::plan::too_many_moves),
        help("split the program into several plans")
    )]
    TooManyMoves { count: usize },
}
