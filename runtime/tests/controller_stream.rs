//! The controller models fed a line at a time are the models run over the whole program
//! (issue 18): `lase plan` times a job on LinuxCNC (`tp::TpStream`) and GRBL or grblHAL
//! (`sim::motion::ModelStream`) holding only their own queues, and must print exactly the
//! times the tabled models (`tp::run_program_from`, `sim::motion::run_program`) give. Every
//! example in every dialect it has a post for, planned whole and in windows, and 400
//! random programs (arcs, blends, stops, dwells, synced and immediate outputs, inverse time,
//! rotary axes, beam switches, comments) compare every number by its bits.

mod common;

use common::rng::Rng;
use common::{examples, program_of};
use lase_runtime::compile::FsFiles;
use lase_runtime::emit::{self, Dialect, PlanFacts};
use lase_runtime::link::linuxcnc::tp::{self, TpLimits, TpStream, TpTime};
use lase_runtime::link::sim::ControllerConfig;
use lase_runtime::link::sim::motion::{self, ModelStream, Timeline};
use lase_runtime::machine::{Machine, parse_machine};
use lase_runtime::motion as planning;

fn tp_bits(t: &TpTime) -> (u64, u64, usize, usize, Vec<(usize, u64)>) {
    (
        t.total_s.to_bits(),
        t.beam_on_s.to_bits(),
        t.segments,
        t.stops,
        t.starts.iter().map(|&(l, s)| (l, s.to_bits())).collect(),
    )
}

/// LinuxCNC's model on `nc`, tabled and streamed (keeping `starts`): the same, or the same
/// refusal.
fn same_tp(what: &str, nc: &str, limits: &TpLimits, start: &[f64]) -> Result<TpTime, String> {
    let tabled = tp::run_program_from(nc, limits, start);
    let mut s = TpStream::new(limits, start, true);
    let streamed = nc.lines().try_for_each(|l| s.line(l)).map(|()| s.finish());
    match (&tabled, &streamed) {
        (Ok(a), Ok(b)) => assert_eq!(tp_bits(a), tp_bits(b), "{what}: {a:?}\n{b:?}"),
        (a, b) => assert_eq!(a.as_ref().err(), b.as_ref().err(), "{what}"),
    }
    tabled
}

/// The GRBL model on `nc`, tabled and streamed (keeping spans, and not): every span, edge and
/// total alike (`{:?}` tells −0 from 0).
fn same_grbl(
    what: &str,
    nc: &str,
    limits: &motion::Limits,
    start: [f64; 6],
) -> Result<Timeline, String> {
    let tabled = motion::run_program(nc, limits, start).map_err(|e| e.to_string());
    for keep in [true, false] {
        let mut s = ModelStream::new(limits, start, keep);
        let streamed = nc
            .lines()
            .try_for_each(|l| s.line(l))
            .map(|()| s.finish())
            .map_err(|e| e.to_string());
        match (&tabled, &streamed) {
            (Ok(a), Ok(b)) if keep => {
                assert_eq!(format!("{a:?}"), format!("{b:?}"), "{what}: timelines")
            }
            (Ok(a), Ok(b)) => assert_eq!(
                (a.total_s.to_bits(), a.motion_s.to_bits(), a.blocks, a.syncs),
                (b.total_s.to_bits(), b.motion_s.to_bits(), b.blocks, b.syncs),
                "{what}: totals"
            ),
            (a, b) => assert_eq!(a.as_ref().err(), b.as_ref().err(), "{what}"),
        }
    }
    tabled
}

fn grbl_limits(machine: &Machine, dialect: Dialect) -> (motion::Limits, [f64; 6]) {
    let mut cfg = ControllerConfig::for_machine(machine);
    if dialect == Dialect::GrblHal {
        cfg.firmware = lase_runtime::link::sim::Firmware::GrblHal {
            axes: lase_runtime::link::controller_axes(machine).max(3),
        };
    } else {
        cfg.firmware = lase_runtime::link::sim::Firmware::Grbl;
    }
    cfg.planner_blocks = cfg.firmware.planner_blocks();
    (
        cfg.firmware.limits(&cfg.settings, cfg.planner_blocks),
        cfg.home(),
    )
}

fn tp_limits(machine: &Machine) -> TpLimits {
    TpLimits::for_machine(machine, 0.001)
}

#[test]
fn every_example_streamed_through_the_controller_models_times_as_the_tabled_models() {
    let examples = examples();
    assert!(examples.len() >= 10, "{} examples", examples.len());
    let mut modelled = 0;
    for ex in examples {
        let name = ex.file_stem().unwrap().to_string_lossy().into_owned();
        let program = program_of(&mut FsFiles, ex.to_str().unwrap());
        let whole = planning::plan_program(program.clone()).unwrap_or_else(|e| panic!("{e}"));
        let machine = &whole.program.machine;
        for dialect in [Dialect::LinuxCnc, Dialect::Grbl, Dialect::GrblHal] {
            if dialect.lookup(&machine.post).is_none() {
                continue;
            }
            let Ok(nc) = emit::emit_to_string(&whole, dialect) else {
                continue;
            };
            let what = format!("{name} in {dialect}");
            // The tabled model and the streamed one, on the whole program's text …
            let tabled = if dialect == Dialect::LinuxCnc {
                same_tp(&what, &nc, &tp_limits(machine), &[]).map(|t| t.total_s)
            } else {
                let (limits, home) = grbl_limits(machine, dialect);
                same_grbl(&what, &nc, &limits, home).map(|t| t.total_s)
            };
            modelled += usize::from(tabled.is_ok());
            // … and `lase plan`'s estimate, streamed from the emitter, whole and in windows.
            let estimate = |job: &lase_runtime::motion::Job, facts: Option<&PlanFacts>| {
                if dialect == Dialect::LinuxCnc {
                    tp::controller_time_from(job, facts)
                        .unwrap()
                        .map(|t| t.total_s)
                } else {
                    motion::controller_time_from(job, facts, dialect)
                        .unwrap()
                        .map(|t| t.timeline.total_s)
                }
            };
            let bits = |r: Result<f64, String>| r.map(f64::to_bits).map_err(|_| ());
            assert_eq!(
                bits(estimate(&whole, None)),
                bits(tabled.clone()),
                "{what}: streamed from the emitter"
            );
            // `lase plan` gathers one set of facts for every controller it times (each post's
            // pulse budget checked as the windows pass).
            let mut facts = PlanFacts::for_dialects(&program, &Dialect::ALL);
            let (job, _) = planning::plan_program_windows_sized(program.clone(), 3, |p, w| {
                facts.window(p, &w)
            })
            .unwrap_or_else(|e| panic!("{what}: {e}"));
            facts.finish(&job.program);
            assert_eq!(
                bits(estimate(&job, Some(&facts))),
                bits(tabled),
                "{what}: planned in windows"
            );
        }
    }
    assert!(modelled >= 20, "{modelled} programs modelled");
}

/// A coordinate: short and long moves, repeats (zero-length moves) and a grid (collinear runs).
fn coord(rng: &mut Rng) -> f64 {
    match rng.below(4) {
        0 => (rng.next() * 100.0 - 50.0).round() / 4.0,
        1 => rng.next() * 2.0 - 1.0,
        _ => (rng.next() * 40.0 - 20.0).round(),
    }
}

/// A random LinuxCNC program for `letters` (X first; a rotary letter among them gets G93
/// blocks).
fn random_lcnc(rng: &mut Rng, n: usize, letters: &[char]) -> String {
    let mut out = String::from("G21 G90 G17 G94\nG64 P0.02\n");
    let rotary = letters.iter().any(|c| "ABC".contains(*c));
    for _ in 0..n {
        let mut axes = String::new();
        for &c in letters {
            if rng.below(3) > 0 {
                axes.push_str(&format!(" {c}{:.4}", coord(rng)));
            }
        }
        let line = match rng.below(24) {
            0..=2 => format!("G0{axes}"),
            3..=11 => format!("G1{axes} F{}", [600, 1200, 3000, 12000][rng.below(4)]),
            12 | 13 if !rotary => format!(
                "G{} X{:.4} Y{:.4} I{:.4} J{:.4} F1500",
                2 + rng.below(2),
                coord(rng),
                coord(rng),
                coord(rng),
                coord(rng)
            ),
            12 | 13 => format!("G93 G1{axes} F{:.3}", 1.0 + rng.next() * 400.0),
            14 => "G94".into(),
            15 => format!("M62 P0{axes}"),
            16 => format!("M63 P0{axes}"),
            17 => ["M64 P0", "M65 P0", "M68 E0 Q50"][rng.below(3)].into(),
            18 => format!("G4 P{}", [0.0, 0.01, 0.2][rng.below(3)]),
            19 => [
                "G61",
                "G64 P0.05",
                "G64 P0.01 Q0.005",
                "G64",
                "G64 P0.01 Q0",
            ][rng.below(5)]
            .into(),
            20 => "(a comment) M67 E0 Q20".into(),
            21 => "M8".into(),
            22 => String::new(),
            _ => format!("G1{axes}"),
        };
        out.push_str(&line);
        out.push('\n');
    }
    out.push_str("M2\n");
    out
}

/// A random GRBL program for `letters` (X and Y first): arcs end on their circle, as GRBL
/// requires (error 33 otherwise).
fn random_grbl(rng: &mut Rng, n: usize, letters: &[char], home: [f64; 6]) -> String {
    let mut out = String::from("G21 G90 G17 G94\nM4 S0\nG1 F1000\n");
    let mut pos = home;
    for _ in 0..n {
        let mut axes = String::new();
        let mut to = pos;
        for (k, &c) in letters.iter().enumerate() {
            if rng.below(3) > 0 {
                to[k] = coord(rng);
                axes.push_str(&format!(" {c}{:.3}", to[k]));
            }
        }
        let line = match rng.below(22) {
            0..=2 => format!("G0{axes}"),
            3..=11 => format!(
                "G1{axes} F{} S{}",
                [600, 1200, 3000, 12000][rng.below(4)],
                [0, 0, 250, 1000][rng.below(4)]
            ),
            12 | 13 => {
                let (i, j) = (coord(rng) / 4.0 + 0.5, coord(rng) / 4.0);
                let r = i.hypot(j);
                let a = rng.next() * std::f64::consts::TAU;
                to = pos;
                to[0] = pos[0] + i + r * a.cos();
                to[1] = pos[1] + j + r * a.sin();
                format!(
                    "G{} X{:.3} Y{:.3} I{i:.3} J{j:.3} F1500 S500",
                    2 + rng.below(2),
                    to[0],
                    to[1]
                )
            }
            14 => ["M3 S100", "M4 S0", "M5", "M8", "M9"][rng.below(5)].into(),
            15 => format!("G4 P{}", [0.0, 0.01, 0.2][rng.below(3)]),
            16 => format!("S{}", rng.below(1000)),
            17 => "(comment) ; more".into(),
            18 => String::new(),
            // Inverse time for one block, as lase writes it (every G93 block has its F).
            19 | 20 => format!("G93 G1{axes} F{:.3}\nG94 F1000", 1.0 + rng.next() * 400.0),
            _ => format!("G1{axes}"),
        };
        if line.starts_with("G0")
            || line.starts_with("G1")
            || line.starts_with("G2")
            || line.starts_with("G3")
            || line.starts_with("G93")
        {
            // Only the lines with axis words move.
            for k in 0..letters.len() {
                pos[k] = (to[k] * 1000.0).round() / 1000.0;
            }
        }
        out.push_str(&line);
        out.push('\n');
    }
    out.push_str("M5\nM2\n");
    out
}

fn stock(name: &str) -> Machine {
    parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

#[test]
fn random_programs_streamed_through_the_linuxcnc_model_time_as_the_tabled_model() {
    let mut rng = Rng(0x5eed_1234_9876_abcd);
    let mut ran = 0;
    for (machine, letters) in [
        ("xy_table", &['X', 'Y'][..]),
        ("xy_rotary", &['X', 'A'][..]),
        ("xyz", &['X', 'Y', 'Z'][..]),
    ] {
        let limits = tp_limits(&stock(machine));
        for k in 0..80 {
            // Longer than the look-ahead's 50 pieces, and some far longer.
            let n = [5, 40, 120, 400][k % 4];
            let nc = random_lcnc(&mut rng, n, letters);
            let start: Vec<f64> = (0..letters.len()).map(|_| coord(&mut rng)).collect();
            let what = format!("{machine} program {k}:\n{nc}");
            ran += usize::from(same_tp(&what, &nc, &limits, &start).is_ok());
        }
    }
    assert!(ran > 150, "{ran} programs ran");
}

#[test]
fn random_programs_streamed_through_the_grbl_model_time_as_the_tabled_model() {
    let mut rng = Rng(0x0dd_ba11_cafe_f00d);
    let mut ran = 0;
    for (machine, letters, dialect) in [
        ("xy_table", &['X', 'Y'][..], Dialect::Grbl),
        ("xyz", &['X', 'Y', 'Z'][..], Dialect::GrblHal),
    ] {
        let (limits, home) = grbl_limits(&stock(machine), dialect);
        for k in 0..80 {
            let n = [5, 30, 120, 400][k % 4];
            let nc = random_grbl(&mut rng, n, letters, home);
            let what = format!("{machine} program {k}:\n{nc}");
            ran += usize::from(same_grbl(&what, &nc, &limits, home).is_ok());
        }
    }
    assert!(ran > 150, "{ran} programs ran");
}
