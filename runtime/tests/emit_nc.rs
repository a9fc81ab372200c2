//! NC emitters: content checks on hand-built programs, and LinuxCNC's own interpreter
//! (`rs274 -g`) on the emitted LinuxCNC programs.

mod common;

use common::program;
use lase_lang::Span;
use lase_runtime::emit::{
    self, Dialect, EmitError, EmitOptions, EmitWarning, NcLine, emit_to_string, emit_to_string_with,
};
use lase_runtime::machine::{Axis, AxisKind, parse_machine};
use lase_runtime::motion::{Job, plan_program};
use lase_runtime::program::{Coupling, Laser, Op, OpKind, P3};
use std::collections::BTreeMap;

#[path = "../../tests/common/rs274.rs"]
mod rs274;

// ------------------------------------------------------------------ helpers

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
        couple: Coupling::None,
        kerf_mm: 0.0,
    })
}

fn rapid(line: usize, to: P3) -> Op {
    op(line, OpKind::Rapid { to, orient: None })
}

fn line(line: usize, to: P3, feed_mm_s: f64, laser: Option<Laser>) -> Op {
    op(
        line,
        OpKind::Line {
            to,
            feed_mm_s,
            laser: laser.map(std::sync::Arc::new),
            orient: None,
            row: None,
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
            laser: laser.map(std::sync::Arc::new),
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

fn lines(job: &Job, dialect: Dialect) -> Vec<NcLine> {
    let mut out = Vec::new();
    emit::emit(job, dialect, &EmitOptions::default(), &mut |l: &NcLine| {
        out.push(l.clone());
        Ok(())
    })
    .expect("emits");
    out
}

/// The words of a block: letter → value, without block number and comments.
fn words(text: &str) -> Vec<(char, f64)> {
    let mut out = Vec::new();
    let mut depth = 0;
    let mut cur: Option<(char, String)> = None;
    let flush = |cur: &mut Option<(char, String)>, out: &mut Vec<(char, f64)>| {
        if let Some((c, v)) = cur.take() {
            out.push((
                c,
                v.parse()
                    .unwrap_or_else(|_| panic!("bad number `{v}` in `{text}`")),
            ));
        }
    };
    if text.starts_with('%') || text.starts_with('O') {
        return out;
    }
    for ch in text.chars() {
        match ch {
            '(' => {
                flush(&mut cur, &mut out);
                depth += 1
            }
            ')' => depth -= 1,
            _ if depth > 0 => {}
            'A'..='Z' => {
                flush(&mut cur, &mut out);
                cur = Some((ch, String::new()));
            }
            ' ' => flush(&mut cur, &mut out),
            _ => cur.as_mut().expect("word letter").1.push(ch),
        }
    }
    flush(&mut cur, &mut out);
    out.retain(|(c, _)| *c != 'N');
    out
}

fn word(text: &str, letter: char) -> Option<f64> {
    words(text)
        .into_iter()
        .find(|(c, _)| *c == letter)
        .map(|(_, v)| v)
}

/// Replays the motion of a program: for each G2/G3 block, (start, center from I/J, end).
/// An arc block replayed: start, center, end, counter-clockwise.
type ArcBlock = ([f64; 2], [f64; 2], [f64; 2], bool);

fn arcs_of(text: &str) -> Vec<ArcBlock> {
    let mut pos = [0.0, 0.0];
    let mut mode = 0.0;
    let mut out = Vec::new();
    for l in text.lines() {
        let w = words(l);
        if w.iter()
            .any(|(c, v)| *c == 'G' && [0.0, 1.0, 2.0, 3.0].contains(v))
        {
            mode = w.iter().find(|(c, v)| *c == 'G' && *v <= 3.0).unwrap().1;
        }
        let dwell = w.contains(&('G', 4.0));
        let has_motion = !dwell && w.iter().any(|(c, _)| *c == 'X' || *c == 'Y');
        if !has_motion {
            continue;
        }
        let end = [
            word(l, 'X').unwrap_or(pos[0]),
            word(l, 'Y').unwrap_or(pos[1]),
        ];
        if mode == 2.0 || mode == 3.0 {
            let c = [
                pos[0] + word(l, 'I').unwrap(),
                pos[1] + word(l, 'J').unwrap(),
            ];
            out.push((pos, c, end, mode == 3.0));
        }
        pos = end;
    }
    out
}

// ------------------------------------------------------------------ content

/// Axis words are the plan's (`Job::op_axes`), not a second run of the kinematics: what
/// motion recorded for an op is what its block says.
#[test]
fn axis_words_are_the_planned_axes() {
    let mut j = job(
        "xy_table",
        vec![
            rapid(1, [10.0, 10.0, 0.0]),
            line(2, [30.0, 10.0, 0.0], 20.0, lit(50.0)),
        ],
    );
    assert_eq!(j.op_axes.len(), j.program.ops.len());
    let i = j
        .program
        .ops
        .iter()
        .position(|o| matches!(o.kind, OpKind::Rapid { .. }))
        .expect("a rapid");
    let mut q = j.op_axes.get(i);
    q[0] = 12.5;
    j.op_axes.set(i, &q);
    let nc = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
    assert!(
        nc.lines()
            .any(|l| l.starts_with("G0") && l.contains("X12.5")),
        "{nc}"
    );
}

#[test]
fn dialect_names_round_trip() {
    for d in Dialect::ALL {
        assert_eq!(d.name().parse::<Dialect>().unwrap(), d);
    }
    assert_eq!("LinuxCNC".parse::<Dialect>().unwrap(), Dialect::LinuxCnc);
    assert_eq!("grblHAL".parse::<Dialect>().unwrap(), Dialect::GrblHal);
    assert!("fanuc".parse::<Dialect>().is_err());
    let family: Vec<_> = Dialect::ALL
        .into_iter()
        .filter(|d| d.is_grbl_family())
        .collect();
    assert_eq!(family, [Dialect::Grbl, Dialect::GrblHal]);
}

#[test]
fn feed_is_mm_per_min_and_only_written_when_it_changes() {
    let j = job(
        "xy_table",
        vec![
            // Unlit: a lit corner the plan slows through is written at the plan's speed
            // (`motion::power::lit_blocks`, runtime/tests/lit_feed.rs), not at the feed.
            line(1, [10.0, 0.0, 0.0], 20.0, None),
            line(2, [10.0, 10.0, 0.0], 20.0, None),
            line(3, [0.0, 10.0, 0.0], 5.0, None),
            rapid(4, [0.0, 0.0, 0.0]),
            line(5, [5.0, 0.0, 0.0], 5.0, None),
        ],
    );
    let out = lines(&j, Dialect::LinuxCnc);
    let motion: Vec<&str> = out
        .iter()
        .filter(|l| {
            l.op.is_some_and(|i| j.program.ops[i as usize].target().is_some())
        })
        .filter(|l| !l.text.starts_with('M'))
        .map(|l| l.text.as_str())
        .collect();
    let nc = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
    assert_eq!(
        motion,
        [
            "G1 X10 Y0 F1200", // first move: every axis, 20 mm/s = F1200
            "Y10",             // same mode, same feed: only what changes
            "X0 F300",
            "G0 Y0",
            "G1 X5 F300", // first feed move after a rapid repeats F
        ],
        "{nc}"
    );
}

#[test]
fn arcs_reproduce_their_centers() {
    let j = xy_demo();
    for d in Dialect::ALL {
        let nc = emit_to_string(&j, d).unwrap();
        let arcs = arcs_of(&nc);
        assert_eq!(arcs.len(), 2, "{nc}");
        let expected = [
            ([30.0, 10.0], [30.0, 20.0], [40.0, 20.0], true),
            ([-20.0, 40.0], [-10.0, 40.0], [-20.0, 40.0], false),
        ];
        for ((s, c, e, ccw), (s0, c0, e0, ccw0)) in arcs.iter().zip(expected) {
            for k in 0..2 {
                assert!((s[k] - s0[k]).abs() < 1e-4);
                assert!((c[k] - c0[k]).abs() < 1e-4, "center {c:?} != {c0:?}\n{nc}");
                assert!((e[k] - e0[k]).abs() < 1e-4);
            }
            assert_eq!(*ccw, ccw0);
            let r0 = ((s[0] - c[0]).powi(2) + (s[1] - c[1]).powi(2)).sqrt();
            let r1 = ((e[0] - c[0]).powi(2) + (e[1] - c[1]).powi(2)).sqrt();
            assert!((r0 - r1).abs() < 1e-4);
        }
        // The full circle names its end although it equals its start.
        assert!(nc.contains("G2 X-20 Y40 I10 J0 F600"), "{nc}");
    }
}

#[test]
fn helix_moves_z_with_the_arc() {
    let j = job(
        "xyz",
        vec![
            rapid(1, [100.0, 100.0, -10.0]),
            arc(
                2,
                [100.0, 100.0, -12.0],
                [110.0, 100.0],
                true,
                10.0,
                lit(200.0),
            ),
        ],
    );
    let nc = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
    assert!(nc.contains("G3 X100 Y100 Z-12 I10 J0 F600"), "{nc}");
}

#[test]
fn laser_goes_on_before_the_first_lit_move_and_off_after_the_run() {
    let j = xy_demo();
    let out = lines(&j, Dialect::LinuxCnc);
    let texts: Vec<&str> = out.iter().map(|l| l.text.as_str()).collect();
    let at = |t: &str| {
        texts
            .iter()
            .position(|x| *x == t)
            .unwrap_or_else(|| panic!("no `{t}` in {texts:#?}"))
    };
    // Run 1: on before op 1's G1 (power 50 % of 100 W), power change before op 3, off after op 3.
    // Both edges sit at corners LinuxCNC does not pass tangentially (rapid → feed, 90° into
    // the rapid), so neither switch is carried along the path (`emit::writer::lead`).
    let on = at("M62 P0");
    assert_eq!(texts[on - 1], "M67 E0 Q50");
    assert_eq!(texts[on + 1], "G1 X30 F1200");
    assert_eq!(out[on].op, Some(1));
    let q80 = at("M67 E0 Q80");
    assert_eq!(out[q80].op, Some(3));
    assert_eq!(texts[q80 + 1], "G1 Y40");
    assert_eq!(texts[q80 + 2], "M63 P0");
    assert_eq!(out[q80 + 2].op, Some(3));
    assert!(
        texts[q80 + 3].starts_with("G0"),
        "the rapid follows the beam off"
    );
    // Run 2: the full circle, with its own power.
    let on2 = texts.iter().rposition(|x| *x == "M62 P0").unwrap();
    assert_eq!(texts[on2 - 1], "M67 E0 Q30");
    assert!(texts[on2 + 1].starts_with("G2"));
    assert_eq!(texts[on2 + 2], "M63 P0");
    // Every lit motion block sits between an on and an off.
    let mut beam = false;
    for (l, t) in out.iter().zip(&texts) {
        match *t {
            "M62 P0" => beam = true,
            "M63 P0" | "M65 P0" => beam = false,
            _ => {}
        }
        if let Some(i) = l.op
            && (t.starts_with("G0")
                || t.starts_with("G1")
                || t.starts_with("G2")
                || t.starts_with("G3")
                || t.starts_with('X')
                || t.starts_with('Y'))
        {
            let is_lit = j.program.ops[i as usize].laser().is_some();
            assert_eq!(beam, is_lit, "line `{t}` of op {i}");
        }
    }
    // Program end: the immediate beam-off (M62/M63 wait for a motion that never comes), M2.
    assert_eq!(&texts[texts.len() - 2..], ["M65 P0", "M2"]);
    assert!(texts.contains(&"G4 P0.5"));
    assert!(texts.contains(&"M8 (air assist [on])"));
}

#[test]
fn header_names_recipe_machine_and_dialect() {
    let j = xy_demo();
    let nc = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
    let head: Vec<&str> = nc.lines().take(5).collect();
    assert!(
        head[0].contains("generated by lase") && head[0].contains("linuxcnc"),
        "{nc}"
    );
    assert!(head[1].contains("test.lase"));
    assert!(head[2].contains("xy_table"));
    assert_eq!(head[3], "G21 G90 G17 G94");
    // Q0: canon's naive CAM off, so LinuxCNC runs lase's own lines (writer.rs).
    assert_eq!(head[4], "G64 P0.01 Q0");
    assert!(nc.lines().all(|l| !l.is_empty() && !l.contains('\n')));
}

#[test]
fn iso_numbers_every_block_and_ends_with_m30() {
    let j = xy_demo();
    let nc = emit_to_string(&j, Dialect::Iso).unwrap();
    let v: Vec<&str> = nc.lines().collect();
    assert_eq!(v[0], "%");
    assert_eq!(v[1], "O0001");
    assert_eq!(*v.last().unwrap(), "%");
    let blocks = &v[2..v.len() - 1];
    for (k, b) in blocks.iter().enumerate() {
        let n = format!("N{} ", 10 * (k + 1));
        assert!(
            b.starts_with(&n),
            "block {k}: `{b}` should start with `{n}`"
        );
    }
    assert!(blocks.last().unwrap().ends_with(" M30"));
    assert!(
        nc.contains(" G4 X0.5\n"),
        "ISO dwell is G4 X<seconds>: {nc}"
    );
    assert!(
        nc.contains(" M3 S500\n"),
        "50 W of 100 W with s_max 1000: {nc}"
    );
    assert!(nc.contains(" S800\n"), "power change: {nc}");
    assert!(!nc.contains("G64"));
}

#[test]
fn grbl_lines_fit_the_buffer_and_use_grbl_words_only() {
    let mut p = xy_demo().program;
    p.recipe =
        "a-very-long-recipe-name/with/many/directories/and/a/long/file/name_that_goes_on.lase"
            .into();
    p.ops.push(op(
        10,
        OpKind::MCode {
            code: 9,
            comment: Some("x".repeat(200)),
        },
    ));
    let j = plan_program(p).unwrap();
    let locate = |s: Span| format!("{}:{}", "r".repeat(120), s.start / 100);
    let nc = emit_to_string_with(
        &j,
        Dialect::Grbl,
        &EmitOptions {
            locate: Some(&locate),
            comments: true,
            live: false,
        },
    )
    .unwrap();
    for l in nc.lines() {
        assert!(l.len() <= 80, "{} characters: `{l}`", l.len());
    }
    assert!(!nc.contains("G64"));
    assert!(!nc.contains("M62") && !nc.contains("M63") && !nc.contains("M68"));
    assert!(nc.contains("G4 P0.5"));
    // Armed once at rest, the power on the block: GRBL stops at every M3/M5.
    assert!(nc.contains("\nM3 S0\n"), "{nc}");
    assert!(nc.lines().any(|l| l.ends_with(" S500")), "{nc}");
    assert!(nc.trim_end().ends_with("M5\nM2"), "{nc}");
}

/// An axis of ±10 units with unit limits.
fn axis(name: &str, kind: AxisKind) -> Axis {
    Axis {
        name: name.into(),
        kind,
        part_axis: None,
        min: -10.0,
        max: 10.0,
        v_max: 1.0,
        a_max: 1.0,
        j_max: 1.0,
    }
}

#[test]
fn grbl_refuses_axes_other_than_xyz() {
    let mut j = xy_demo();
    j.program.machine.axes.push(axis("A", AxisKind::Rotary));
    let err = emit_to_string(&j, Dialect::Grbl).unwrap_err();
    assert!(matches!(err, EmitError::Dialect { .. }), "{err:?}");
    assert!(err.to_string().contains("rotary axis A"), "{err}");
    assert_eq!(code(&err), "lase::emit::dialect");
    assert!(emit_to_string(&j, Dialect::Iso).is_ok());
}

fn code(e: &dyn miette::Diagnostic) -> String {
    e.code().map(|c| c.to_string()).unwrap_or_default()
}

#[test]
fn unsupported_mcode_points_at_the_op_and_nothing_is_written() {
    let ops = vec![
        line(1, [10.0, 0.0, 0.0], 20.0, lit(10.0)),
        op(
            2,
            OpKind::MCode {
                code: 24,
                comment: None,
            },
        ),
    ];
    let j = job("xy_table", ops);
    for d in [Dialect::LinuxCnc, Dialect::Grbl] {
        let mut written = 0;
        let err = emit::emit(&j, d, &EmitOptions::default(), &mut |_: &NcLine| {
            written += 1;
            Ok(())
        })
        .unwrap_err();
        assert_eq!(written, 0, "validation comes before the first line");
        let EmitError::UnsupportedMCode {
            code: c,
            span,
            ref help,
            ..
        } = err
        else {
            panic!("{err:?}")
        };
        assert_eq!(c, 24);
        assert_eq!(span, Span::new(200, 207));
        assert!(help.contains("event"), "{help}");
        assert_eq!(code(&err), "lase::emit::unsupported_mcode");
        let labels: Vec<_> = miette::Diagnostic::labels(&err).unwrap().collect();
        assert_eq!(labels[0].offset(), 200);
    }
    assert!(
        emit_to_string(&j, Dialect::Iso)
            .unwrap()
            .contains("N40 M24")
            || emit_to_string(&j, Dialect::Iso).unwrap().contains(" M24\n")
    );
    // GRBL has no M56 even where LinuxCNC does not either; M7 is fine for both.
    let j = job(
        "xy_table",
        vec![op(
            1,
            OpKind::MCode {
                code: 56,
                comment: None,
            },
        )],
    );
    assert!(emit_to_string(&j, Dialect::Grbl).is_err());
}

#[test]
fn user_mcodes_warn_on_linuxcnc() {
    let j = job(
        "xy_table",
        vec![
            line(1, [1.0, 0.0, 0.0], 5.0, None),
            op(
                2,
                OpKind::MCode {
                    code: 101,
                    comment: None,
                },
            ),
        ],
    );
    let stats = emit::emit(
        &j,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut |_: &NcLine| Ok(()),
    )
    .unwrap();
    assert_eq!(
        stats.warnings,
        vec![EmitWarning::UserMCode {
            code: 101,
            span: Span::new(200, 207)
        }]
    );
    assert!(emit_to_string(&j, Dialect::Grbl).is_err());
}

#[test]
fn events_use_the_machine_codes_and_dwell() {
    let j = notcher_demo();
    let nc = emit_to_string(&j, Dialect::Iso).unwrap();
    let blocks: Vec<String> = nc
        .lines()
        .map(|l| l.split_once(' ').map_or(l, |x| x.1).to_string())
        .collect();
    let swing = blocks.iter().position(|b| b == "M24").expect("M24");
    assert_eq!(blocks[swing + 1], "G4 X0.5");
    let on = blocks
        .iter()
        .position(|b| b == "M27")
        .expect("laser on M27");
    assert!(on > swing);
    assert_eq!(blocks[on + 1], "Z-33.63 F949.8");
    assert_eq!(blocks[on + 2], "M28");
    assert!(blocks.iter().any(|b| b == "M25"));
    // Without a GRBL mapping the diagnostic names the dialects that have one.
    let mut j = j;
    for ev in j.program.machine.events.values_mut() {
        ev.codes.remove("grbl");
    }
    let err = emit_to_string(&j, Dialect::Grbl).unwrap_err();
    let EmitError::UnsupportedEvent {
        ref name,
        span,
        ref help,
        ..
    } = err
    else {
        panic!("{err:?}")
    };
    assert_eq!(name, "swing_right");
    assert_eq!(span, Span::new(200, 207));
    assert!(help.contains("iso, linuxcnc"), "{help}");
    assert_eq!(code(&err), "lase::emit::unsupported_event");
}

#[test]
fn unknown_event_lists_the_machine_events() {
    let j = job(
        "notcher",
        vec![op(
            1,
            OpKind::Event {
                name: "shutter".into(),
            },
        )],
    );
    let err = emit_to_string(&j, Dialect::Iso).unwrap_err();
    let EmitError::UnsupportedEvent { help, .. } = err else {
        panic!()
    };
    assert!(help.contains("swing_left, swing_right"), "{help}");
}

#[test]
fn recipe_lines_are_traced_in_comments() {
    let j = xy_demo();
    let locate = |s: Span| format!("demo.lase:{}", s.start / 100);
    let opts = EmitOptions {
        locate: Some(&locate),
        comments: true,
        live: false,
    };
    let nc = emit_to_string_with(&j, Dialect::LinuxCnc, &opts).unwrap();
    for k in 1..=9 {
        assert_eq!(nc.matches(&format!("(demo.lase:{k})\n")).count(), 1, "{nc}");
    }
    let quiet = emit_to_string_with(
        &j,
        Dialect::LinuxCnc,
        &EmitOptions {
            locate: Some(&locate),
            comments: false,
            live: false,
        },
    )
    .unwrap();
    assert!(!quiet.contains("demo.lase"));
    assert!(quiet.contains("\nM8\n"));
}

#[test]
fn stats_count_what_was_written() {
    let j = xy_demo();
    let mut n = 0u64;
    let mut bytes = 0u64;
    let stats = emit::emit(
        &j,
        Dialect::LinuxCnc,
        &EmitOptions::default(),
        &mut |l: &NcLine| {
            n += 1;
            bytes += l.text.len() as u64 + 1;
            Ok(())
        },
    )
    .unwrap();
    assert_eq!(stats.lines, n);
    assert_eq!(stats.bytes, bytes);
    // Every motion line written (a lit arc the plan holds below its feed is several).
    let motion = emit_to_string(&j, Dialect::LinuxCnc)
        .unwrap()
        .lines()
        .filter(|l| {
            l.starts_with('G') && !l.starts_with("G2") && !l.starts_with("G6")
                || l.starts_with('X')
                || l.starts_with('Y')
                || l.starts_with("G2 ")
        })
        .filter(|l| l.contains('X') || l.contains('Y'))
        .count() as u64;
    assert_eq!(stats.motion_blocks, motion);
    assert!(motion >= 7);
}

// ------------------------------------------------------------------ LinuxCNC's interpreter

/// Runs `rs274 -g` on a program. None when rs274 is not installed (an error under CI).
fn rs274(name: &str, nc: &str) -> Option<(bool, String)> {
    let path = std::env::temp_dir().join(format!("lase-emit-{}-{name}.ngc", std::process::id()));
    std::fs::write(&path, nc).unwrap();
    let out = rs274::rs274_g(&path);
    let _ = std::fs::remove_file(&path);
    match out {
        Ok(o) => {
            let text = format!(
                "{}{}",
                String::from_utf8_lossy(&o.stdout),
                String::from_utf8_lossy(&o.stderr)
            );
            Some((o.status.success(), text))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            if std::env::var_os("CI").is_some() {
                panic!("rs274 (LinuxCNC) is not on PATH; CI must install linuxcnc-uspace");
            }
            eprintln!("skipping the rs274 check: rs274 (LinuxCNC) is not on PATH");
            None
        }
        Err(e) => panic!("cannot run rs274: {e}"),
    }
}

/// The arguments of every canonical call `NAME(...)` in rs274's output.
fn canon(out: &str, name: &str) -> Vec<Vec<f64>> {
    out.lines()
        .filter_map(|l| l.split_once(&format!("{name}(")))
        .map(|(_, rest)| {
            rest.trim_end_matches(')')
                .split(',')
                .map(|x| x.trim().parse().unwrap())
                .collect()
        })
        .collect()
}

#[test]
fn linuxcnc_interpreter_accepts_the_xy_table_program() {
    let nc = emit_to_string(&xy_demo(), Dialect::LinuxCnc).unwrap();
    let Some((ok, out)) = rs274("xy", &nc) else {
        return;
    };
    assert!(
        ok && !out.contains("Unknown"),
        "rs274 rejected:\n{nc}\n{out}"
    );
    // The interpreter's arcs have the program's centers and directions.
    let arcs = canon(&out, "ARC_FEED");
    assert_eq!(arcs.len(), 2, "{out}");
    let expect = [
        [40.0, 20.0, 30.0, 20.0, 1.0],
        [-20.0, 40.0, -10.0, 40.0, -1.0],
    ];
    for (a, e) in arcs.iter().zip(expect) {
        for k in 0..5 {
            assert!((a[k] - e[k]).abs() < 1e-4, "{a:?} vs {e:?}");
        }
    }
    assert_eq!(canon(&out, "DWELL"), vec![vec![0.5]]);
    assert_eq!(
        canon(&out, "SET_FEED_RATE")
            .iter()
            .filter(|f| f[0] == 1200.0)
            .count(),
        1
    );
    assert!(out.contains("FLOOD_ON()"), "M8 ran: {out}");
    assert_eq!(
        out.matches("SET_MOTION_OUTPUT_BIT(0)").count(),
        2,
        "beam on twice: {out}"
    );
    assert!(out.contains("PROGRAM_END()"));
}

#[test]
fn linuxcnc_interpreter_accepts_the_notcher_program_with_events() {
    let nc = emit_to_string(&notcher_demo(), Dialect::LinuxCnc).unwrap();
    let Some((ok, out)) = rs274("notcher", &nc) else {
        return;
    };
    assert!(
        ok && !out.contains("Unknown"),
        "rs274 rejected:\n{nc}\n{out}"
    );
    // Swing right (M64 P1) + 0.5 s, laser (M64 P0), swing left (M65 P1) + 0.5 s.
    assert_eq!(canon(&out, "DWELL"), vec![vec![0.5], vec![0.5]], "{out}");
    assert!(
        out.contains("SET_AUX_OUTPUT_BIT(1)") && out.contains("CLEAR_AUX_OUTPUT_BIT(1)"),
        "{out}"
    );
    assert!(
        out.contains("SET_AUX_OUTPUT_BIT(0)") && out.contains("CLEAR_AUX_OUTPUT_BIT(0)"),
        "{out}"
    );
}

#[test]
fn linuxcnc_interpreter_rejects_a_broken_program() {
    // Guards the check above: rs274 does fail on what LinuxCNC cannot run.
    let Some((ok, out)) = rs274("bad", "G21\nG1 X1 F100\nM24\nM2\n") else {
        return;
    };
    assert!(!ok && out.contains("Unknown"), "{out}");
}

#[test]
fn every_stock_machine_emits_in_every_dialect_it_supports() {
    let mut seen = BTreeMap::new();
    for name in lase_stdlib::machine_names() {
        let m = parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap();
        let is_oriented = lase_runtime::kinematics::for_machine(&m).oriented();
        let rotary = m.axes.iter().any(|a| a.kind == AxisKind::Rotary);
        let ops = if is_oriented {
            // A short lit chord on a surface at y = 20 mm, the head above it at 12 mm, beam −y.
            oriented(vec![
                rapid(1, [0.0, 20.0, 0.0]),
                line(2, [1.0, 20.0, 0.0], 10.0, lit(5.0)),
            ])
        } else {
            vec![
                line(1, [1.0, 0.0, 0.0], 10.0, lit(5.0)),
                rapid(2, [0.0, 0.0, 0.0]),
            ]
        };
        let j = job(name, ops);
        for d in Dialect::ALL {
            let r = emit_to_string(&j, d);
            if d == Dialect::Grbl && rotary {
                // GRBL has X, Y and Z only: a rotary machine is refused, with the reason.
                let e = r.expect_err("GRBL cannot drive rotary axes");
                assert!(e.to_string().contains("rotary"), "{e}");
                continue;
            }
            seen.insert((name, d.name()), r.map(|_| ()).map_err(|e| e.to_string()));
        }
    }
    assert!(seen.values().all(|r| r.is_ok()), "{seen:?}");
}

/// An oriented machine's program: axis words through the inverse kinematics, feed moves in
/// inverse time (G93) with F = feed / chord length, G94 restored at the end.
/// The moves with the beam along −y at a 12 mm standoff: a surface at y = 20 mm, the head
/// above it.
fn oriented(mut ops: Vec<Op>) -> Vec<Op> {
    let o = Some(lase_runtime::program::Orient {
        beam: [0.0, -1.0, 0.0],
        standoff_mm: 12.0,
    });
    for op in &mut ops {
        if let OpKind::Rapid { orient, .. } | OpKind::Line { orient, .. } = &mut op.kind {
            *orient = o.map(Box::new);
        }
    }
    ops
}

#[test]
fn oriented_moves_are_written_in_inverse_time() {
    let ops = oriented(vec![
        rapid(1, [0.0, 20.0, 0.0]),
        line(2, [2.0, 20.0, 0.0], 10.0, lit(5.0)),
    ]);
    let mut p = program("cam_xwb", ops);
    p.planner.leadin = lase_runtime::program::LeadIn::Off;
    let j = plan_program(p).expect("plans");
    let out = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    let g93 = lines.iter().position(|l| *l == "G93").expect(&out);
    let g94 = lines.iter().rposition(|l| *l == "G94").expect(&out);
    assert!(g93 < g94, "{out}");
    // 2 mm at 10 mm/s = 0.2 s = 1/300 min.
    let feed_line = lines[g93..g94]
        .iter()
        .find(|l| l.starts_with("G1"))
        .expect(&out);
    let f: f64 = feed_line
        .split(' ')
        .find_map(|w| w.strip_prefix('F'))
        .expect(feed_line)
        .parse()
        .unwrap();
    assert!((f - 300.0).abs() < 1e-3, "{feed_line}");
}

// ------------------------------------------------------------------ grblHAL

/// The lines of an NC program that move or set modes: no comments, no M-code lines (the
/// dialects switch the beam differently), no LinuxCNC blending mode.
fn motion_lines(nc: &str) -> Vec<&str> {
    nc.lines()
        .filter(|l| !l.starts_with('(') && !l.starts_with('M') && !l.starts_with("G64"))
        .collect()
}

#[test]
fn grblhal_writes_rotary_words_in_inverse_time_for_oriented_machines() {
    for (machine, letters) in [("cam_xwb", "XCB"), ("arm_3r", "XABC")] {
        let ops = oriented(vec![
            rapid(1, [0.0, 20.0, 0.0]),
            line(2, [2.0, 20.0, 0.0], 10.0, lit(5.0)),
        ]);
        let j = job(machine, ops);
        let nc = emit_to_string(&j, Dialect::GrblHal).unwrap();
        let lines: Vec<&str> = nc.lines().collect();
        let g93 = lines.iter().position(|l| *l == "G93").expect(&nc);
        let g94 = lines.iter().rposition(|l| *l == "G94").expect(&nc);
        assert!(g93 < g94, "{nc}");
        // Every axis has its word; rotary words to 1e-6°, never more.
        for c in letters.chars() {
            assert!(
                lines.iter().any(|l| word(l, c).is_some()),
                "{machine}: no {c} word\n{nc}"
            );
        }
        for l in lines.iter().filter(|l| !l.starts_with('(')) {
            for w in l.split(' ').filter(|w| w.starts_with(['A', 'B', 'C'])) {
                let decimals = w.split_once('.').map_or(0, |(_, d)| d.len());
                assert!(decimals <= 6, "{w} in `{l}`");
            }
        }
        // 2 mm at 10 mm/s = 0.2 s = 1/300 min, on the lit G1 block.
        let lit_block = lines[g93..g94]
            .iter()
            .find(|l| l.starts_with("G1"))
            .expect(&nc);
        let f = word(lit_block, 'F').expect(lit_block);
        assert!((f - 300.0).abs() < 1e-3, "{lit_block}");
        // GRBL's laser mode and program end; nothing of LinuxCNC's.
        assert!(nc.contains("\nM3 S"), "{nc}");
        assert!(nc.trim_end().ends_with("M5\nM2"), "{nc}");
        assert!(!nc.contains("G64") && !nc.contains("M62") && !nc.contains("M68"));
        // The axis words and feeds are LinuxCNC's, block for block (grblHAL's blocks carry
        // the beam's S word besides).
        let cnc = emit_to_string(&j, Dialect::LinuxCnc).unwrap();
        let without_s: Vec<String> = motion_lines(&nc)
            .iter()
            .map(|l| {
                l.split(' ')
                    .filter(|w| !w.starts_with('S'))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect();
        assert_eq!(without_s, motion_lines(&cnc), "{machine}");
    }
}

#[test]
fn grblhal_drives_linear_xyz_and_abc_only() {
    // A linear A is a grblHAL axis (GRBL 1.1 still refuses it).
    let mut j = xy_demo();
    j.program.machine.axes.push(axis("A", AxisKind::Linear));
    assert!(emit_to_string(&j, Dialect::GrblHal).is_ok());
    assert!(emit_to_string(&j, Dialect::Grbl).is_err());
    // A seventh letter, U, is not.
    j.program.machine.axes.push(axis("U", AxisKind::Linear));
    let mut written = 0;
    let err = emit::emit(
        &j,
        Dialect::GrblHal,
        &EmitOptions::default(),
        &mut |_: &NcLine| {
            written += 1;
            Ok(())
        },
    )
    .unwrap_err();
    assert_eq!(written, 0, "validation comes before the first line");
    let EmitError::Dialect {
        ref message,
        dialect,
        ref label,
        ref help,
        ..
    } = err
    else {
        panic!("{err:?}")
    };
    assert_eq!(dialect, Dialect::GrblHal);
    assert!(
        message.contains("grblHAL") && message.contains("linear axis U"),
        "{message}"
    );
    assert!(label.contains("grblHAL"), "{label}");
    assert!(help.contains("A, B, C"), "{help}");
    assert_eq!(code(&err), "lase::emit::dialect");
    assert!(emit_to_string(&j, Dialect::LinuxCnc).is_ok());
    // X, Y and Z are linear on grblHAL.
    let mut j = xy_demo();
    j.program.machine.axes[0].kind = AxisKind::Rotary;
    let err = emit_to_string(&j, Dialect::GrblHal).unwrap_err();
    assert!(err.to_string().contains("rotary axis X"), "{err}");
}

#[test]
fn grblhal_lines_fit_its_256_character_buffer() {
    // `M5 (` + pad + `)`: 256 characters with a pad of 251.
    let with_off = |pad: usize| {
        let mut j = xy_demo();
        let post = j.program.machine.post.get_mut("grbl").unwrap();
        post.laser_off = vec![format!("M5 ({})", "x".repeat(pad))];
        j
    };
    let j = with_off(251);
    let nc = emit_to_string(&j, Dialect::GrblHal).unwrap();
    assert!(nc.lines().any(|l| l.len() == 256), "{nc}");
    assert!(nc.lines().all(|l| l.len() <= 256));
    // GRBL 1.1 reads 80.
    assert!(emit_to_string(&j, Dialect::Grbl).is_err());
    let err = emit_to_string(&with_off(252), Dialect::GrblHal).unwrap_err();
    let EmitError::Dialect {
        ref message,
        ref label,
        ..
    } = err
    else {
        panic!("{err:?}")
    };
    assert!(
        message.contains("257 characters; grblHAL reads at most 256"),
        "{message}"
    );
    assert!(label.contains("too long for grblHAL"), "{label}");
    // Traceability comments stay within GRBL's 80 on grblHAL too.
    let locate = |s: Span| format!("{}:{}", "r".repeat(300), s.start / 100);
    let nc = emit_to_string_with(
        &xy_demo(),
        Dialect::GrblHal,
        &EmitOptions {
            locate: Some(&locate),
            comments: true,
            live: false,
        },
    )
    .unwrap();
    assert!(nc.lines().all(|l| l.len() <= 80), "{nc}");
}

#[test]
fn grblhal_falls_back_to_the_grbl_post_and_event_codes() {
    // xy_table has no [post.grblhal]: the program is GRBL's but for the header.
    let j = xy_demo();
    let hal = emit_to_string(&j, Dialect::GrblHal).unwrap();
    let grbl = emit_to_string(&j, Dialect::Grbl).unwrap();
    assert!(hal.starts_with("(generated by lase "), "{hal}");
    assert!(
        hal.lines().next().unwrap().ends_with(" for grblhal)"),
        "{hal}"
    );
    assert_eq!(
        hal.lines().skip(1).collect::<Vec<_>>(),
        grbl.lines().skip(1).collect::<Vec<_>>()
    );
    // Its own section wins when there is one.
    let mut j = xy_demo();
    let mut own = j.program.machine.post["grbl"].clone();
    own.laser_on = vec!["M4 S{s}".into()];
    j.program.machine.post.insert("grblhal".into(), own);
    let hal = emit_to_string(&j, Dialect::GrblHal).unwrap();
    assert!(hal.contains("\nM4 S0\n") && !hal.contains("M3"), "{hal}");
    assert!(
        emit_to_string(&j, Dialect::Grbl)
            .unwrap()
            .contains("\nM3 S0\n")
    );
    // Events: the notcher maps its swing valve for grbl only; grblHAL uses that mapping, and
    // its own when the machine has one.
    let mut j = notcher_demo();
    let hal = emit_to_string(&j, Dialect::GrblHal).unwrap();
    assert!(hal.contains("\nM8\n") && hal.contains("\nM9\n"), "{hal}");
    j.program
        .machine
        .events
        .get_mut("swing_right")
        .unwrap()
        .codes
        .insert("grblhal".into(), vec!["M7".into()]);
    let hal = emit_to_string(&j, Dialect::GrblHal).unwrap();
    assert!(hal.contains("\nM7\n") && !hal.contains("\nM8\n"), "{hal}");
    // Neither: the diagnostics name both keys.
    for ev in j.program.machine.events.values_mut() {
        ev.codes.remove("grbl");
        ev.codes.remove("grblhal");
    }
    let err = emit_to_string(&j, Dialect::GrblHal).unwrap_err();
    let EmitError::UnsupportedEvent { ref help, .. } = err else {
        panic!("{err:?}")
    };
    assert!(
        help.contains("`grblhal = [...]` or `grbl = [...]`"),
        "{help}"
    );
    let mut j = xy_demo();
    j.program.machine.post.remove("grbl");
    let err = emit_to_string(&j, Dialect::GrblHal).unwrap_err();
    let EmitError::NoPost { ref help, .. } = err else {
        panic!("{err:?}")
    };
    assert!(help.contains("[post.grblhal] or [post.grbl]"), "{help}");
}

#[test]
fn grblhal_mcode_diagnostics_name_the_section_they_came_from() {
    // An M-code grblHAL does not take, in the GRBL post it falls back to.
    let mut j = xy_demo();
    j.program.machine.post.get_mut("grbl").unwrap().laser_on = vec!["M62 P0".into()];
    let err = emit_to_string(&j, Dialect::GrblHal).unwrap_err();
    let EmitError::UnsupportedMCode {
        code: c, ref help, ..
    } = err
    else {
        panic!("{err:?}")
    };
    assert_eq!(c, 62);
    assert!(help.contains("[post.grbl] laser_on"), "{help}");
}
