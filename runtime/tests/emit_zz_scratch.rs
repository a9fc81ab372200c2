//! NC emitters: content checks on hand-built programs, and LinuxCNC's own interpreter
//! (`rs274 -g`) on the emitted LinuxCNC programs.

use lase_lang::Span;
use lase_runtime::emit::{
    self, Dialect, EmitError, EmitOptions, EmitWarning, NcLine, emit_to_string, emit_to_string_with,
};
use lase_runtime::machine::{Axis, AxisKind, parse_machine};
use lase_runtime::motion::{Job, plan_program};
use lase_runtime::program::{
    AxisLimit, Laser, Op, OpKind, P3, PathLimits, PlannerSettings, ProcessProgram,
};
use std::collections::BTreeMap;

// ------------------------------------------------------------------ helpers

fn program(machine: &str, ops: Vec<Op>) -> ProcessProgram {
    let m = parse_machine(lase_stdlib::machine(machine).unwrap(), 0).unwrap();
    ProcessProgram {
        recipe: "test.lase".into(),
        limits: m
            .axes
            .iter()
            .map(|a| AxisLimit {
                v: a.v_max,
                a: a.a_max,
                j: a.j_max,
            })
            .collect(),
        path_limits: PathLimits::default(),
        planner: PlannerSettings {
            ramp: m.ramp,
            junction_deviation_mm: m.junction_deviation_mm,
            arc_tolerance_mm: m.arc_tolerance_mm,
            lookahead: None,
        },
        start: [0.0; 3],
        ops,
        machine: m,
    }
}

/// An op whose span encodes its recipe line: line n is bytes 100n..100n+7.
fn op(line: usize, kind: OpKind) -> Op {
    Op {
        kind,
        span: Span::new(100 * line, 100 * line + 7),
    }
}

fn lit(power_w: f64) -> Option<Laser> {
    Some(Laser {
        power_w,
        spot_mm: 0.1,
        pulse: None,
    })
}

fn rapid(line: usize, to: P3) -> Op {
    op(line, OpKind::Rapid { to })
}

fn line(line: usize, to: P3, feed_mm_s: f64, laser: Option<Laser>) -> Op {
    op(
        line,
        OpKind::Line {
            to,
            feed_mm_s,
            laser,
        },
    )
}

fn arc(
    line: usize,
    to: P3,
    center: [f64; 2],
    ccw: bool,
    feed_mm_s: f64,
    laser: Option<Laser>,
) -> Op {
    op(
        line,
        OpKind::Arc {
            to,
            center,
            ccw,
            feed_mm_s,
            laser,
        },
    )
}

fn job(machine: &str, ops: Vec<Op>) -> Job {
    plan_program(program(machine, ops)).expect("plans")
}

/// Lines, lines, arcs (one a full circle), power change, laser on/off, dwell and an M-code.
fn xy_demo() -> Job {
    job(
        "xy_table",
        vec![
            rapid(1, [10.0, 10.0, 0.0]),
            line(2, [30.0, 10.0, 0.0], 20.0, lit(50.0)),
            arc(3, [40.0, 20.0, 0.0], [30.0, 20.0], true, 20.0, lit(50.0)),
            line(4, [40.0, 40.0, 0.0], 20.0, lit(80.0)),
            rapid(5, [-20.0, 40.0, 0.0]),
            op(6, OpKind::Dwell { seconds: 0.5 }),
            op(
                7,
                OpKind::MCode {
                    code: 8,
                    comment: Some("air assist (on)".into()),
                },
            ),
            arc(8, [-20.0, 40.0, 0.0], [-10.0, 40.0], false, 10.0, lit(30.0)),
            rapid(9, [0.0, 0.0, 0.0]),
        ],
    )
}

/// The notcher of PROCESS.md §4: swing, plunge, laser on, cut, swing back.
fn notcher_demo() -> Job {
    job(
        "notcher",
        vec![
            line(1, [68.5, 0.0, 0.0], 50.0, None),
            op(
                2,
                OpKind::Event {
                    name: "swing_right".into(),
                },
            ),
            line(3, [68.5, 0.0, -15.53], 83.33, None),
            line(4, [68.5, 0.0, -33.63], 15.83, lit(400.0)),
            line(5, [73.5, 0.0, -33.63], 50.0, None),
            op(
                6,
                OpKind::Event {
                    name: "swing_left".into(),
                },
            ),
        ],
    )
}

#[test]
fn show() {
    let j = xy_demo();
    println!("{}", emit_to_string(&j, Dialect::LinuxCnc).unwrap());
    println!("{}", emit_to_string(&j, Dialect::Iso).unwrap());
    println!("{}", emit_to_string(&notcher_demo(), Dialect::LinuxCnc).unwrap());
    println!("{}", serde_json::to_string_pretty(&lase_runtime::report::summarize(&j)).unwrap());
    let svg = lase_runtime::report::plot_svg(&j).unwrap();
    std::fs::write("/tmp/xy.svg", svg).unwrap();
    let svg = lase_runtime::report::plot_svg(&notcher_demo()).unwrap();
    std::fs::write("/tmp/notch.svg", svg).unwrap();
    let mut out = Vec::new();
    lase_runtime::report::write_trace(&j, 0.05, &mut out).unwrap();
    std::fs::write("/tmp/xy.csv", out).unwrap();
}
