//! The controller's pulse budget (issue 15): a job's pulses held to the `max_pulse_rate` and
//! `max_pulses` of the machine file's `[post.<dialect>]` before a line is written, refused
//! with `lase::emit::pulse_budget` at the scan that fires the first pulse over it. One case per
//! row: the recipe's scan settings, the dialect, and what must come of it.

use lase_runtime::compile::{self, MemFiles};
use lase_runtime::emit::{Dialect, EmitError, EmitOptions, PlanFacts, emit_lines, emit_planned};
use lase_runtime::motion::Job;
use miette::Diagnostic;

const RECIPE: &str = "machine \"m.toml\"\nlaser { power 20 W, spot 40 um }\nPULSE\n\
scan dots (0, 0) { rows 2, cols 11, passes 1, SETTINGS }\n";

/// xy_table's own file, with `extra` added to its LinuxCNC post.
fn machine(extra: &str) -> String {
    lase_stdlib::machine("xy_table").unwrap().replace(
        "pulse_off = [\"M63 P1\"]\n",
        &format!("pulse_off = [\"M63 P1\"]\n{extra}"),
    )
}

fn job(pulse: &str, settings: &str, extra: &str) -> (String, Job) {
    let src = RECIPE.replace("PULSE", pulse).replace("SETTINGS", settings);
    let mut files = MemFiles::new([("m.toml", machine(extra)), ("r.lase", src.clone())]);
    match compile::compile(&mut files, "r.lase") {
        Ok((_, job)) => (src, job),
        Err((_, f)) => panic!("the recipe compiles: {f:?}"),
    }
}

/// [`job`]'s lines in `dialect`, planned in windows as `lase emit` plans it.
fn in_windows(
    pulse: &str,
    settings: &str,
    extra: &str,
    dialect: Dialect,
) -> Result<Vec<String>, EmitError> {
    let src = RECIPE.replace("PULSE", pulse).replace("SETTINGS", settings);
    let mut files = MemFiles::new([("m.toml", machine(extra)), ("r.lase", src)]);
    let mut recipe = compile::load(&mut files, "r.lase").unwrap_or_else(|(_, f)| panic!("{f:?}"));
    compile::check(&recipe).unwrap_or_else(|f| panic!("{f:?}"));
    let program = compile::evaluate(&mut recipe, &mut files).unwrap_or_else(|f| panic!("{f:?}"));
    let mut facts = PlanFacts::new(&program, dialect);
    let (job, _) = compile::plan_in_windows(program, |p, w| facts.window(p, &w))
        .unwrap_or_else(|f| panic!("{f:?}"));
    facts.finish(&job.program);
    let mut lines = Vec::new();
    emit_planned(&job, &facts, dialect, &EmitOptions::default(), &mut |l| {
        lines.push(l.text.clone());
        Ok(())
    })?;
    Ok(lines)
}

struct Case {
    pulse: &'static str,
    settings: &'static str,
    /// Added to the machine's LinuxCNC post.
    extra: &'static str,
    dialect: Dialect,
    /// `None`: the program is written; else fragments of the message, label and help.
    refused: Option<[&'static str; 3]>,
}

const RATE_20K: &str = "pulse { rate 20 kHz, width 100 ns, energy 1 mJ }";

const CASES: &[(&str, Case)] = &[
    (
        // 0.02 mm at 20 mm/s: 1000 Hz, twice what LinuxCNC's synchronized output switches.
        "linuxcnc_flying_dots_too_dense",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.02 mm, speed 20 mm/s",
            extra: "",
            dialect: Dialect::LinuxCnc,
            refused: Some([
                "pulses at 1000 Hz are faster than LinuxCNC triggers them (500 Hz at most)",
                "pulse 2 follows the one before it too soon",
                "with pulses every 0.02 mm the fastest speed LinuxCNC triggers is 10 mm/s; `max_pulse_rate` of [post.linuxcnc] in machine `xy_table`",
            ]),
        },
    ),
    (
        // The same pitch at 10 mm/s is 500 Hz: the limit itself passes.
        "linuxcnc_flying_dots_at_the_limit",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.02 mm, speed 10 mm/s",
            extra: "",
            dialect: Dialect::LinuxCnc,
            refused: None,
        },
    ),
    (
        // 0.05 mm at 20 mm/s: 400 Hz, within LinuxCNC's 500 Hz, over GRBL's 300 Hz.
        "grbl_serial_line_too_slow",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.05 mm, speed 20 mm/s",
            extra: "",
            dialect: Dialect::Grbl,
            refused: Some([
                "pulses at 400 Hz are faster than GRBL triggers them (300 Hz at most)",
                "too soon",
                "the fastest speed GRBL triggers is 15 mm/s; `max_pulse_rate` of [post.grbl]",
            ]),
        },
    ),
    (
        "linuxcnc_takes_what_grbl_cannot",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.05 mm, speed 20 mm/s",
            extra: "",
            dialect: Dialect::LinuxCnc,
            refused: None,
        },
    ),
    (
        // grblHAL runs GRBL's lines: the same budget.
        "grblhal_inherits_grbls_budget",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.05 mm, speed 20 mm/s",
            extra: "",
            dialect: Dialect::GrblHal,
            refused: Some([
                "faster than grblHAL triggers them (300 Hz at most)",
                "too soon",
                "[post.grbl]",
            ]),
        },
    ),
    (
        // Dot mode, three pulses at rest per spot at 5 kHz: LinuxCNC's dwells cannot.
        "linuxcnc_dot_mode_bursts",
        Case {
            pulse: "pulse { rate 5 kHz }",
            settings: "pitch 0.5 mm, speed 10 mm/s, mode dot, pulses 3",
            extra: "",
            dialect: Dialect::LinuxCnc,
            refused: Some([
                "pulses at 5000 Hz are faster than LinuxCNC triggers them",
                "pulse 2 follows",
                "space the pulses at least 0.002 s apart",
            ]),
        },
    ),
    (
        // ISO controls: no budget in xy_table's file, nothing held.
        "iso_has_no_budget",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.02 mm, speed 20 mm/s",
            extra: "",
            dialect: Dialect::Iso,
            refused: None,
        },
    ),
    (
        // 22 spots against a budget of 20 pulses a job.
        "max_pulses_a_job",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.2 mm, speed 20 mm/s",
            extra: "max_pulses = 20\n",
            dialect: Dialect::LinuxCnc,
            refused: Some([
                "the job fires more than 20 pulses, the most LinuxCNC takes in one job",
                "pulse 21 is fired here",
                "`max_pulses` of [post.linuxcnc] in machine `xy_table`",
            ]),
        },
    ),
    (
        "max_pulses_met",
        Case {
            pulse: RATE_20K,
            settings: "pitch 0.2 mm, speed 20 mm/s",
            extra: "max_pulses = 22\n",
            dialect: Dialect::LinuxCnc,
            refused: None,
        },
    ),
];

fn run(name: &str) {
    let (_, case) = CASES.iter().find(|(n, _)| *n == name).unwrap();
    let (src, job) = job(case.pulse, case.settings, case.extra);
    let result = emit_lines(&job, case.dialect, &EmitOptions::default());
    // `lase emit` plans in windows and checks the budget on the pulses as they pass
    // (`emit::PlanFacts`): the same lines, or the very same diagnostic.
    let windowed = in_windows(case.pulse, case.settings, case.extra, case.dialect);
    assert_eq!(
        format!("{windowed:?}"),
        format!(
            "{:?}",
            result
                .as_ref()
                .map(|(lines, _)| lines.iter().map(|l| l.text.clone()).collect::<Vec<_>>())
        ),
        "{name}: planned in windows"
    );
    match (case.refused, result) {
        (None, Ok(_)) => {}
        (None, Err(e)) => panic!("{name}: refused: {e:?}"),
        (Some(_), Ok(_)) => panic!("{name}: written"),
        (Some([message, label, help]), Err(e)) => {
            let EmitError::PulseBudget { span, label: l, .. } = &e else {
                panic!("{name}: {e:?}")
            };
            assert_eq!(
                e.code().unwrap().to_string(),
                "lase::emit::pulse_budget",
                "{name}"
            );
            assert!(e.to_string().contains(message), "{name}: {e}");
            assert!(l.contains(label), "{name}: {l}");
            let h = e.help().unwrap().to_string();
            assert!(h.contains(help), "{name}: {h}");
            // At the scan statement that fires the pulses.
            assert!(
                src[span.start as usize..].starts_with("scan dots"),
                "{name}: {:?}",
                &src[span.start as usize..]
            );
        }
    }
}

macro_rules! cases {
    ($($name:ident)*) => { $( #[test] fn $name() { run(stringify!($name)); } )* };
}

cases! {
    linuxcnc_flying_dots_too_dense
    linuxcnc_flying_dots_at_the_limit
    grbl_serial_line_too_slow
    linuxcnc_takes_what_grbl_cannot
    grblhal_inherits_grbls_budget
    linuxcnc_dot_mode_bursts
    iso_has_no_budget
    max_pulses_a_job
    max_pulses_met
}

/// Every case above has its test.
#[test]
fn every_case_runs() {
    assert_eq!(CASES.len(), 9);
}
