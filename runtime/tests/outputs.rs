//! Machine outputs (issue 20): `output NAME on|off` writes the machine file's
//! `[outputs.NAME]` lines per dialect, and the plan stops there only where the controller
//! stops (GRBL's `M8` empties its planner; LinuxCNC's `M62` switches with the next move).
//! Measured on the emitted NC and on the plan's speeds.

mod common;

use lase_runtime::compile::{self, MemFiles};
use lase_runtime::emit::{Dialect, emit_to_string};
use lase_runtime::motion::Job;
use lase_runtime::program::OpKind;

const AXES: &str = r#"
name = "air_table"
kinematics = "cartesian"
[[axes]]
name = "X"
kind = "linear"
part_axis = "x"
travel = ["-150 mm", "150 mm"]
v_max = "250 mm/s"
a_max = "2 m/s^2"
j_max = "50 m/s^3"
[[axes]]
name = "Y"
kind = "linear"
part_axis = "y"
travel = ["-100 mm", "100 mm"]
v_max = "250 mm/s"
a_max = "2 m/s^2"
j_max = "50 m/s^3"
[laser]
max_power = "100 W"
max_pulse_rate = "100 kHz"
[post.linuxcnc]
laser_on = ["M67 E0 Q{pct}", "M62 P0"]
laser_off = ["M63 P0"]
power = ["M67 E0 Q{pct}"]
[post.grbl]
laser_on = ["M3 S{s}"]
laser_off = ["M5"]
power = ["S{s}"]
"#;

/// A straight cut along x in two collinear moves with the air switched on between them, so
/// the junction's speed is the cut's unless the output stops the table.
const RECIPE: &str = r#"
machine "m.toml"
laser { power 20 W }
move to (0 mm, 0 mm) rapid
laser on
move to (20 mm, 0 mm) at 20 mm/s
output air on
move to (40 mm, 0 mm) at 20 mm/s
output air off
laser off
"#;

fn job(outputs: &str) -> Job {
    job_of(outputs, RECIPE)
}

fn job_of(outputs: &str, recipe: &str) -> Job {
    let mut files = MemFiles::new([
        ("m.toml", format!("{AXES}{outputs}")),
        ("r.lase", recipe.to_string()),
    ]);
    match compile::compile(&mut files, "r.lase") {
        Ok((_, job)) => job,
        Err((_, f)) => panic!("the recipe compiles: {f:?}"),
    }
}

/// The planned speed where the first cut move (to x = 20) ends.
fn junction_speed(job: &Job) -> f64 {
    let ops = &job.program.ops;
    let out = ops
        .iter()
        .position(|o| matches!(o.kind, OpKind::Output { on: true, .. }))
        .expect("the output op");
    let before = (0..out).rev().find(|&i| ops[i].target().is_some()).unwrap();
    let seg = job
        .plan
        .segments()
        .iter()
        .rfind(|s| s.tag as usize == before)
        .expect("a segment of the move before the output");
    seg.v_exit
}

/// The program's lines without comments.
fn lines(nc: &str) -> Vec<String> {
    nc.lines()
        .map(|l| l.split(['(', ';']).next().unwrap().trim().to_string())
        .filter(|l| !l.is_empty())
        .collect()
}

/// The line after the one whose X is `x` (to within 1 µm).
fn after_x(nc: &[String], x: f64) -> Vec<String> {
    let i = nc
        .iter()
        .position(|l| {
            l.split_whitespace().any(|w| {
                w.strip_prefix('X')
                    .and_then(|v| v.parse::<f64>().ok())
                    .is_some_and(|v| (v - x).abs() < 1e-3)
            })
        })
        .unwrap_or_else(|| panic!("a line ending at X{x}"));
    nc[i + 1..].to_vec()
}

#[test]
fn linuxcnc_synchronized_output_flies_and_is_written_between_the_moves() {
    let j = job(r#"
[outputs.air]
doc = "air assist"
linuxcnc = { on = ["M62 P2"], off = ["M63 P2"], stops = false }
"#);
    let v = junction_speed(&j);
    assert!(
        (v - 20.0).abs() < 1e-6,
        "M62 does not stop LinuxCNC: the cut runs through at 20 mm/s, planned {v}"
    );
    let nc = lines(&emit_to_string(&j, Dialect::LinuxCnc).unwrap());
    let rest = after_x(&nc, 20.0);
    assert_eq!(rest[0], "M62 P2", "{nc:#?}");
    assert!(rest[1].contains("X40"), "the next move follows: {nc:#?}");
    assert!(nc.iter().any(|l| l == "M63 P2"), "{nc:#?}");
    // GRBL has no lines for it: a diagnostic naming the output, not a program without air.
    let e = emit_to_string(&j, Dialect::Grbl).unwrap_err();
    assert!(e.to_string().contains("output `air`"), "{e}");
}

#[test]
fn grbl_coolant_output_stops_the_plan_and_writes_m8_m9() {
    let j = job(r#"
[outputs.air]
linuxcnc = { on = ["M62 P2"], off = ["M63 P2"], stops = false }
grbl = { on = ["M8"], off = ["M9"] }
"#);
    assert_eq!(
        junction_speed(&j),
        0.0,
        "GRBL's M8 empties the planner: the one plan stops where the strictest dialect does"
    );
    for (d, on, off) in [
        (Dialect::Grbl, "M8", "M9"),
        (Dialect::GrblHal, "M8", "M9"),
        (Dialect::LinuxCnc, "M62 P2", "M63 P2"),
    ] {
        // Where the beam lights: carried switches put back (`common::uncarried`).
        let nc = lines(&common::uncarried_text(&emit_to_string(&j, d).unwrap()));
        assert_eq!(after_x(&nc, 20.0)[0], on, "{d}: {nc:#?}");
        // After the cut, at most its lead-out and the beam's switch-off come first.
        let rest = after_x(&nc, 40.0);
        let k = rest.iter().position(|l| l == off);
        assert!(
            k.is_some_and(|k| k <= 2),
            "{d}: {off} after the cut: {nc:#?}"
        );
    }
}

/// The GRBL 1.1 planner model that streams the program (`lase plan`'s controller time) runs
/// the emitted lines: it empties its buffer at the `M8` between the cuts, one stop more than the
/// same cut without air (the `M9` stops where the `M5` after the cut stopped already: a sync
/// counts only with motion pending), as the ideal plan stops at the `M8`.
#[test]
fn grbl_planner_model_syncs_at_the_air_switches() {
    let air = r#"
[outputs.air]
grbl = { on = ["M8"], off = ["M9"] }
"#;
    let syncs = |j: &Job| {
        lase_runtime::link::sim::motion::controller_time(j)
            .expect("a GRBL machine")
            .expect("the model runs")
            .timeline
            .syncs
    };
    let with = job(air);
    let without = job_of(
        air,
        &RECIPE
            .replace("output air on", "")
            .replace("output air off", ""),
    );
    assert_eq!(syncs(&with), syncs(&without) + 1);
    assert_eq!(junction_speed(&with), 0.0);
}

#[test]
fn stops_false_is_refused_where_the_controller_stops() {
    for (outputs, want) in [
        (
            r#"grbl = { on = ["M8"], off = ["M9"], stops = false }"#,
            "GRBL empties its planner",
        ),
        (
            r#"linuxcnc = { on = ["M8"], off = ["M9"], stops = false }"#,
            "`M7`/`M8`/`M9`",
        ),
        (
            r#"linuxcnc = { on = ["M64 P2"], off = ["M65 P2"], stops = false }"#,
            "M62",
        ),
    ] {
        let text = format!("{AXES}[outputs.air]\n{outputs}\n");
        let e = lase_runtime::machine::parse_machine(&text, 0).unwrap_err();
        let help = format!("{:?}", e);
        assert!(help.contains(want), "{outputs}: {help}");
        let at = e.span();
        assert_eq!(
            &text[at.start as usize..at.end as usize],
            "false",
            "the span is the flag"
        );
    }
}

#[test]
fn an_unknown_output_is_refused_with_the_names_the_machine_has() {
    let mut files = MemFiles::new([
        (
            "m.toml",
            format!("{AXES}[outputs.air]\ngrbl = {{ on = [\"M8\"], off = [\"M9\"] }}\n"),
        ),
        ("r.lase", "machine \"m.toml\"\noutput aire on\n".to_string()),
    ]);
    let Err((_, f)) = compile::compile(&mut files, "r.lase") else {
        panic!("an unknown output must not compile");
    };
    let text = format!("{f:?}");
    assert!(
        text.contains("UnknownOutput") && text.contains("air"),
        "{text}"
    );
}
