//! The pulse budget checked on a plan made in windows (`emit::PlanFacts` with
//! `report::PulseStream`) finds what the whole plan's check finds: the pulses handed on as the
//! windows pass are the whole plan's `report::pulse_events`, in the same order, with the same
//! times to the last bit and the same ops (so every budget meets the same first pulse over it:
//! same op, count and interval), and `lase emit` in windows gives the whole plan's NC text or
//! its very `lase::emit::pulse_budget` diagnostic, in every dialect. On every example and on
//! random pulse jobs (pitch and period pulses, sections that change their pulse or go dark,
//! dwells between lit moves, dot-mode windows at rest) under random budgets.

mod common;

use common::program_of;
use common::rng::Rng;

use lase_runtime::compile::{FsFiles, MemFiles};
use lase_runtime::emit::{self, Dialect, PlanFacts};
use lase_runtime::motion;
use lase_runtime::planner;
use lase_runtime::program::ProcessProgram;
use lase_runtime::report::{self, PulseStream, PulseTime};

/// `(time bits, op)` of every pulse.
type Pulses = Vec<(u64, u32)>;

/// The whole plan's pulses, and the pulses streamed from windows from `min_window` segments
/// up; then the NC text (or refusal) of every dialect, whole and in windows.
fn same_pulses_and_nc(what: &str, program: &ProcessProgram) -> usize {
    let whole = motion::plan_program(program.clone()).unwrap_or_else(|e| panic!("{what}: {e}"));
    let want: Pulses = report::pulse_events(&whole)
        .map(|p| (p.t.to_bits(), p.op))
        .collect();
    for min_window in [1, 3, planner::MIN_WINDOW] {
        let mut stream = PulseStream::new();
        let mut got: Pulses = Vec::new();
        let mut each = |p: PulseTime| got.push((p.t.to_bits(), p.op));
        let (job, _) = motion::plan_program_windows_sized(program.clone(), min_window, |p, w| {
            stream.window(p, &w, &mut each)
        })
        .unwrap_or_else(|e| panic!("{what}: {e}"));
        stream.finish(&job.program, &mut each);
        assert_eq!(
            job.initial_dwell_s.to_bits(),
            whole.initial_dwell_s.to_bits(),
            "{what}"
        );
        if let Some(k) = (0..want.len().max(got.len())).find(|&k| want.get(k) != got.get(k)) {
            panic!(
                "{what}, windows from {min_window}: pulse {k} of {} (whole) / {} (windows): {:?} \
                 against the whole plan's {:?}",
                want.len(),
                got.len(),
                got.get(k).map(|&(t, op)| (f64::from_bits(t), op)),
                want.get(k).map(|&(t, op)| (f64::from_bits(t), op)),
            );
        }
    }
    for dialect in Dialect::ALL {
        let want = emit::emit_to_string(&whole, dialect).map_err(|e| format!("{e:?}"));
        let facts = PlanFacts::for_dialects(program, &Dialect::ALL);
        let got = common::emit_in_windows(what, program, facts, dialect, 3);
        match (&got, &want) {
            (Err(g), Err(w)) => assert_eq!(g, w, "{what}, {dialect}: the refusal"),
            _ => assert!(got == want, "{what}, {dialect}: the NC differs"),
        }
    }
    want.len()
}

#[test]
fn every_examples_pulses_and_budget_from_windows_are_the_whole_plans() {
    let examples = common::examples();
    assert!(examples.len() >= 10, "{} examples", examples.len());
    let mut pulses = 0;
    for ex in examples {
        let path = ex.to_str().unwrap();
        pulses += same_pulses_and_nc(path, &program_of(&mut FsFiles, path));
    }
    assert!(pulses > 900, "{pulses} pulses in the examples");
}

/// A random pulse job on xy_table (its LinuxCNC and GRBL budgets, and maybe a `max_pulses`).
fn random_job(rng: &mut Rng) -> (String, String) {
    let mut src = String::from(
        "machine \"m.toml\"\nlaser { power 20 W, spot 40 um }\nplanner { corner 0.01 mm }\n",
    );
    if rng.below(3) == 0 {
        src += "dwell 0.05 s\n";
    }
    let interval = |rng: &mut Rng| {
        if rng.below(2) == 0 {
            format!("pulse {{ interval {:.3} mm }}\n", 0.02 + rng.next() * 0.8)
        } else {
            format!("pulse {{ interval {:.2} ms }}\n", 0.5 + rng.next() * 10.0)
        }
    };
    src += &interval(rng);
    let mut lit = false;
    for _ in 0..4 + rng.below(14) {
        let (x, y) = (rng.next() * 40.0, rng.next() * 40.0);
        match rng.below(9) {
            0 => {
                src += &format!("move to ({x:.3} mm, {y:.3} mm) rapid\n");
                lit = false;
            }
            1 => src += &format!("dwell {:.3} s\n", 0.001 + rng.next() * 0.02),
            2 => src += &interval(rng),
            3 => {
                src += if lit { "laser off\n" } else { "laser on\n" };
                lit = !lit;
            }
            4 => {
                let mode = if rng.below(2) == 0 {
                    ", mode dot, pulses 2"
                } else {
                    ""
                };
                src += &format!(
                    "scan dots ({x:.3} mm, {y:.3} mm) {{ rows {}, cols {}, passes 1, pitch 0.5 mm, \
                     speed {} mm/s{mode} }}\n",
                    1 + rng.below(3),
                    2 + rng.below(4),
                    5 + rng.below(15)
                );
                lit = false;
            }
            _ => {
                if !lit && rng.below(2) == 0 {
                    src += "laser on\n";
                    lit = true;
                }
                src += &format!(
                    "move to ({x:.3} mm, {y:.3} mm) at {} mm/s\n",
                    2 + rng.below(30)
                );
            }
        }
    }
    let extra = match rng.below(3) {
        0 => format!("max_pulses = {}\n", 1 + rng.below(400)),
        _ => String::new(),
    };
    let machine = lase_stdlib::machine("xy_table").unwrap().replace(
        "pulse_off = [\"M63 P1\"]\n",
        &format!("pulse_off = [\"M63 P1\"]\n{extra}"),
    );
    (src, machine)
}

#[test]
fn random_pulse_jobs_find_the_same_first_pulse_over_the_budget_in_windows() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let (mut refused, mut pulses) = (0, 0);
    for case in 0..120 {
        let (src, machine) = random_job(&mut rng);
        let mut files = MemFiles::new([("m.toml", machine), ("r.lase", src.clone())]);
        let program = program_of(&mut files, "r.lase");
        let what = format!("case {case}:\n{src}");
        pulses += same_pulses_and_nc(&what, &program);
        let whole = motion::plan_program(program).unwrap();
        refused += usize::from(emit::emit_to_string(&whole, Dialect::LinuxCnc).is_err());
    }
    eprintln!("{refused} of 120 random jobs refused on LinuxCNC, {pulses} pulses");
    // The jobs meet the budgets both ways: some are refused, some written.
    assert!((10..110).contains(&refused), "{refused} of 120 refused");
    assert!(pulses > 2000, "{pulses} pulses");
}
