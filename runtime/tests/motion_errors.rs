//! A planner diagnostic reaches the user with the planner's own code and help, placed at the
//! recipe span of the move it names (it used to be flattened into a string under one code).

use lase_lang::Span;
use lase_runtime::motion::{MotionError, PlannerFailure};
use lase_runtime::planner::PlanError;
use miette::Diagnostic;

#[test]
fn planner_errors_keep_their_code_and_help_at_the_move() {
    let e = MotionError::Planner(PlannerFailure {
        error: PlanError::BadStart {
            axis: 2,
            value: f64::NAN,
        },
        span: Span::new(10, 14),
    });
    assert_eq!(e.code().unwrap().to_string(), "lase::plan::bad_start");
    assert_eq!(
        e.help().unwrap().to_string(),
        "the planner starts from a known, finite machine position"
    );
    assert_eq!(
        e.to_string(),
        "start position of axis 2 = NaN is not a finite number"
    );
    let labels: Vec<_> = e.labels().unwrap().collect();
    assert_eq!(labels.len(), 1);
    assert_eq!((labels[0].offset(), labels[0].len()), (10, 4));
    assert_eq!(labels[0].label(), Some("this move"));
}
