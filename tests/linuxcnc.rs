//! Every example LinuxCNC can run (flat bed, notcher, cams, the rotary chuck, the arm in joint
//! space; nested_parts, codes and material_test only with `LASE_LINUXCNC_LONG=1`, for CI's
//! time), one LinuxCNC session per machine, on a real, headless LinuxCNC 2.9 (`common::linuxcnc`),
//! measured from its HAL samples (1 ms): executed cycle time against `lase plan`, the beam's
//! edges (motion.digital-out-00) at the planned places and speeds, pulse counts
//! (motion.digital-out-01 rising edges) against the plan, how far the lit path strays from
//! the planned one, and the cycle and beam-on times against `lase plan`'s LinuxCNC 2.9
//! trajectory planner model (`link::linuxcnc::tp`, within 1 %). Each test prints its table;
//! skips (saying so) without LinuxCNC.
//!
//! Run one machine's examples: `cargo test --test linuxcnc flat_bed --
//! --nocapture`.

mod common;

use common::linuxcnc::{Headless, Sample, available};
use lase_runtime::FsFiles;
use lase_runtime::axes::to_external;
use lase_runtime::emit::{Dialect, EmitOptions};
use lase_runtime::motion::Job;

/// What one run measured.
#[derive(Debug)]
struct Measured {
    name: String,
    planned_s: f64,
    executed_s: f64,
    /// Time in motion (samples whose position changed), planned and executed: what motion
    /// did, without the waits at queue busters (`M64`/`M65`, `G4`), which on a non-realtime
    /// LinuxCNC last as long as a loaded computer's scheduler lets task take (conrod_notch
    /// ran 4.73 s against 4.24 s planned under load, every extra ms standing still).
    planned_moving_s: f64,
    executed_moving_s: f64,
    beam_on_planned_s: f64,
    beam_on_executed_s: f64,
    edges_planned: usize,
    edges_executed: usize,
    /// Largest distance between a planned and an executed beam edge, axis space (mm, deg).
    edge_place: f64,
    /// Largest difference of the axis-space speed at an edge, mm/s (deg/s).
    edge_speed: f64,
    /// Largest relative speed error at a beam-on edge passed moving ([`MOVING_EDGE`]): |executed
    /// / planned − 1|, the speed the lit stretch starts at.
    on_edge_rel: f64,
    /// The same at a beam-off edge passed moving: the speed the lit stretch ends at.
    off_edge_rel: f64,
    /// Largest relative error of the joints' speed, sample by sample, over the five samples
    /// lit at each edge passed moving ([`LIT_SAMPLES`]: from an on-edge's switch on, up to
    /// an off-edge's), against the speed the plan passes the edge at: what the beam sees
    /// where a blend of a few periods (an arm's) still settles as it switches.
    lit_rel: f64,
    /// Where the executed edges fall along the path from the planned ones, in servo periods
    /// of the edge's speed (negative: early), least, mean and greatest over the edges passed
    /// moving ([`MOVING_EDGE`]).
    edge_periods: [f64; 3],
    pulses_planned: u64,
    pulses_executed: u64,
    /// Largest distance of a lit sample from the planned lit path, axis space (mm, deg).
    deviation: f64,
    /// What `lase plan`'s LinuxCNC 2.9 trajectory planner model predicts (`link::linuxcnc::tp`).
    model_s: f64,
    beam_on_model_s: f64,
    /// The largest gap, in servo periods, between the model's start of an NC line
    /// ([`line_starts`]) and the first sample in which the real machine reports it, both from
    /// the first motion line's.
    line_starts: f64,
}

/// The largest gap, in servo periods of `dt`, between the model's start of each NC line it
/// queues (`starts`: line, s from its first motion) and the first sample whose
/// `motion.program-line` is that line, both counted from the first line the model starts
/// (the task's start-up latency before it is not the planner's).
fn line_starts(samples: &[Sample], starts: &[(usize, f64)], dt: f64) -> f64 {
    let mut first = std::collections::HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        first.entry(s.line).or_insert(i);
    }
    let real = |line: usize| first.get(&(line as i32)).map(|&i| i as f64 * dt);
    let Some((base_real, base_model)) =
        starts.first().and_then(|&(line, t)| Some((real(line)?, t)))
    else {
        return f64::INFINITY;
    };
    starts
        .iter()
        .filter_map(|&(line, t)| Some((real(line)? - base_real - (t - base_model)).abs() / dt))
        .fold(0.0, f64::max)
}

/// Axis positions (external units) and beam of the plan `t` s after the first move.
fn planned_at(job: &Job, t: f64) -> (Vec<f64>, bool) {
    let axes = &job.program.machine.axes;
    let t = job.initial_dwell_s + t.clamp(0.0, job.plan.duration());
    let (s, lit, _) = lase_runtime::report::beam_at(job, t);
    let q = axes
        .iter()
        .enumerate()
        .map(|(i, a)| to_external(a.kind, s.pos[i]))
        .collect();
    (q, lit)
}

/// [`planned_at`] every `dt` from the first move.
fn planned(job: &Job, dt: f64) -> Vec<(Vec<f64>, bool)> {
    let n = (job.plan.duration() / dt).ceil() as usize;
    (0..=n).map(|k| planned_at(job, k as f64 * dt)).collect()
}

/// Where the plan's beam edge found between samples `i - 1` and `i` (every `dt`) lies
/// exactly: the edge's time bisected to 1 ns, so the planned place carries no sampling
/// error (a 1 ms sample lands up to 0.1 mm past an edge passed at 100 mm/s).
fn planned_edge(job: &Job, i: usize, dt: f64) -> Vec<f64> {
    let (mut a, mut b) = ((i.max(1) - 1) as f64 * dt, i as f64 * dt);
    let lit_b = planned_at(job, b).1;
    while b - a > 1e-9 {
        let m = 0.5 * (a + b);
        if planned_at(job, m).1 == lit_b {
            b = m;
        } else {
            a = m;
        }
    }
    planned_at(job, b).0
}

fn dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// Distance from `p` to the segment `a`–`b`. Without allocations: the lit-path deviation
/// calls it hundreds of times per executed sample, and test code builds unoptimized.
fn seg_dist(p: &[f64], a: &[f64], b: &[f64]) -> f64 {
    let (mut l2, mut dot) = (0.0, 0.0);
    for i in 0..a.len() {
        let d = b[i] - a[i];
        l2 += d * d;
        dot += d * (p[i] - a[i]);
    }
    let t = if l2 > 0.0 {
        (dot / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let mut s = 0.0;
    for i in 0..a.len() {
        let e = p[i] - (a[i] + t * (b[i] - a[i]));
        s += e * e;
    }
    s.sqrt()
}

/// Edges of a beam signal: (index, on) at each change.
fn edges(beam: impl Iterator<Item = bool>) -> Vec<(usize, bool)> {
    let mut out = Vec::new();
    let mut last = false;
    for (i, b) in beam.enumerate() {
        if b != last {
            out.push((i, b));
            last = b;
        }
    }
    out
}

/// Axis-space speed at index `i` of a 1 ms position series (central difference).
fn speed(q: &[Vec<f64>], i: usize, dt: f64) -> f64 {
    let a = i.saturating_sub(1);
    let b = (i + 1).min(q.len() - 1);
    dist(&q[a], &q[b]) / ((b - a).max(1) as f64 * dt)
}

/// With `LASE_LINUXCNC_DUMP=<folder>`, writes each run's program (`<example>.ngc`), its
/// samples (`<example>.samples`: joints, beam, pulse output, program line per 1 ms) and the
/// model's segment starts (`<example>.model`: NC line, s) there, for comparing LinuxCNC with
/// the model line by line.
fn dump(example: &str, nc: &str, samples: &[Sample], model_starts: &[(usize, f64)]) {
    let Some(dir) = std::env::var_os("LASE_LINUXCNC_DUMP") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(format!("{example}.ngc")), nc).unwrap();
    let text: String = samples
        .iter()
        .map(|s| {
            let q: Vec<String> = s.joints.iter().map(|x| format!("{x:.6}")).collect();
            format!(
                "{} {} {} {}\n",
                q.join(" "),
                u8::from(s.dout[0]),
                u8::from(s.dout[1]),
                s.line
            )
        })
        .collect();
    std::fs::write(dir.join(format!("{example}.samples")), text).unwrap();
    let starts: String = model_starts
        .iter()
        .map(|(line, t)| format!("{line} {t:.6}\n"))
        .collect();
    std::fs::write(dir.join(format!("{example}.model")), starts).unwrap();
}

/// The least planned axis-space speed (mm/s, °/s) at which an edge counts as passed moving:
/// the arm's joints pass its edges at 0.75-1.2 °/s.
const MOVING_EDGE: f64 = 0.3;

/// Samples about an edge counted lit (`Measured::lit_rel`), the switch's included.
const LIT_SAMPLES: usize = 5;

/// `example` names a recipe in `examples/`, or one elsewhere by its path from the project's
/// root (`tests/linuxcnc/arm_short`).
fn measure(lcnc: &mut Headless, example: &str) -> Measured {
    let (dir, example) = example.rsplit_once('/').unwrap_or(("examples", example));
    let path = common::root().join(dir).join(format!("{example}.lase"));
    let name = path.display().to_string();
    let (_, job) =
        lase_runtime::compile(&mut FsFiles, &name).unwrap_or_else(|(_, f)| panic!("{name}: {f}"));
    let nc = lase_runtime::emit::emit_to_string_with(
        &job,
        Dialect::LinuxCnc,
        &EmitOptions {
            locate: None,
            comments: true,
            live: false,
        },
    )
    .unwrap();
    let samples: Vec<Sample> = lcnc.run_program(&format!("{example}.ngc"), &nc);
    // The run: from the first sample that moves to the last one that does.
    let moved = |i: usize| dist(&samples[i].joints, &samples[i - 1].joints) > 1e-9;
    let first = (1..samples.len())
        .find(|&i| moved(i))
        .expect("LinuxCNC moved")
        - 1;
    let last = (1..samples.len()).rev().find(|&i| moved(i)).unwrap();
    let run = &samples[first..=last];
    // The harness samples every servo period, the machine file's (`servo_period`).
    let dt = job.program.machine.servo_period_s();
    let executed_s = (last - first) as f64 * dt;
    let moving = |q: &[Vec<f64>]| q.windows(2).filter(|w| dist(&w[0], &w[1]) > 1e-9).count();
    let summary = lase_runtime::report::summarize(&job);

    let plan = planned(&job, dt);
    let plan_q: Vec<Vec<f64>> = plan.iter().map(|(q, _)| q.clone()).collect();
    let run_q: Vec<Vec<f64>> = run.iter().map(|s| s.joints.clone()).collect();
    let plan_edges = edges(plan.iter().map(|(_, lit)| *lit));
    let run_edges = edges(run.iter().map(|s| s.dout[0]));
    let mut edge_place: f64 = 0.0;
    let mut edge_speed: f64 = 0.0;
    let mut on_edge_rel: f64 = 0.0;
    let mut off_edge_rel: f64 = 0.0;
    let mut lit_rel: f64 = 0.0;
    let mut along: Vec<f64> = Vec::new();
    for (&(pi, pon), &(ri, ron)) in plan_edges.iter().zip(&run_edges) {
        assert_eq!(pon, ron, "{example}: the edges alternate alike");
        let edge = planned_edge(&job, pi, dt);
        edge_place = edge_place.max(dist(&edge, &run_q[ri]));
        let (vp, vr) = (speed(&plan_q, pi, dt), speed(&run_q, ri, dt));
        edge_speed = edge_speed.max((vr - vp).abs());
        if vp > MOVING_EDGE {
            if pon {
                on_edge_rel = on_edge_rel.max((vr / vp - 1.0).abs());
            } else {
                off_edge_rel = off_edge_rel.max((vr / vp - 1.0).abs());
            }
            let lit = if pon {
                ri..ri + LIT_SAMPLES
            } else {
                ri.saturating_sub(LIT_SAMPLES - 1)..ri + 1
            };
            let edge_lit = lit
                .filter(|&k| k >= 1 && k < run_q.len())
                .map(|k| (dist(&run_q[k - 1], &run_q[k]) / dt / vp - 1.0).abs())
                .fold(0.0, f64::max);
            lit_rel = lit_rel.max(edge_lit);
            // Signed along the planned direction of travel there.
            let (a, b) = (
                &plan_q[pi.saturating_sub(1)],
                &plan_q[(pi + 1).min(plan_q.len() - 1)],
            );
            let d: Vec<f64> = a.iter().zip(b.iter()).map(|(x, y)| y - x).collect();
            let n = d.iter().map(|x| x * x).sum::<f64>().sqrt();
            if n > 0.0 {
                let s: f64 = run_q[ri]
                    .iter()
                    .zip(&edge)
                    .zip(&d)
                    .map(|((r, e), u)| (r - e) * u / n)
                    .sum();
                along.push(s / (vp * dt));
                if std::env::var_os("LASE_LINUXCNC_EDGES").is_some() {
                    // Every edge passed moving: where, how far along, at what speeds.
                    eprintln!(
                        "{example} edge {} {}: planned {edge:.4?} executed {:.4?} along {:+.4} mm \
                         ({:+.2} periods) v {vp:.2}/{vr:.2} lit ±{:.1} % line {}",
                        along.len(),
                        if pon { "on" } else { "off" },
                        run_q[ri],
                        s,
                        s / (vp * dt),
                        100.0 * edge_lit,
                        run[ri].line
                    );
                }
            }
        }
    }
    let edge_periods = if along.is_empty() {
        [0.0; 3]
    } else {
        [
            along.iter().copied().fold(f64::INFINITY, f64::min),
            along.iter().sum::<f64>() / along.len() as f64,
            along.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    };
    // Each lit run against its planned lit run (the k-th with the k-th: the edges pair up),
    // walking forward along the planned one.
    let runs = |e: &[(usize, bool)], n: usize| -> Vec<(usize, usize)> {
        e.chunks(2)
            .map(|c| (c[0].0, c.get(1).map_or(n, |off| off.0)))
            .collect()
    };
    let mut deviation: f64 = 0.0;
    for (&(pa, pb), &(ra, rb)) in runs(&plan_edges, plan_q.len())
        .iter()
        .zip(&runs(&run_edges, run_q.len()))
    {
        // From the exact planned edges (`planned_edge`): the first lit sample lies up to a
        // period of travel past the edge, and a lit sample before it counted as off the path.
        let mut lit_plan = vec![planned_edge(&job, pa, dt)];
        lit_plan.extend_from_slice(&plan_q[pa..pb.max(pa + 2).min(plan_q.len())]);
        if pb < plan_q.len() {
            lit_plan.push(planned_edge(&job, pb, dt));
        }
        let mut j = 0usize;
        for q in &run_q[ra..rb] {
            let (mut best, mut at) = (f64::INFINITY, j);
            for k in j..(j + 400).min(lit_plan.len().saturating_sub(1)) {
                let d = seg_dist(q, &lit_plan[k], &lit_plan[k + 1]);
                if d < best {
                    best = d;
                    at = k;
                }
            }
            if best.is_finite() {
                deviation = deviation.max(best);
                j = at;
            }
        }
    }
    // Digital output 1 is the pulse trigger where the post fires pulses with it (elsewhere,
    // e.g. the notcher's swing valve, it is something else).
    let pulse_output = job.program.machine.post["linuxcnc"]
        .pulse_on
        .iter()
        .any(|l| l.contains("P1"));
    let pulses_executed = if pulse_output {
        run.windows(2)
            .filter(|w| !w[0].dout[1] && w[1].dout[1])
            .count() as u64
            + u64::from(run[0].dout[1])
    } else {
        0
    };
    // The model from where this run started (the previous program's end), on the program
    // LinuxCNC ran.
    let limits = lase_runtime::link::linuxcnc::tp::TpLimits::for_machine(
        &job.program.machine,
        job.program.machine.servo_period_s(),
    );
    let model = lase_runtime::link::linuxcnc::tp::run_program_from(&nc, &limits, &run[0].joints)
        .unwrap_or_else(|e| panic!("{example}: {e}"));
    dump(example, &nc, &samples, &model.starts);
    Measured {
        line_starts: line_starts(&samples, &model.starts, dt),
        model_s: model.total_s,
        beam_on_model_s: model.beam_on_s,
        name: example.to_string(),
        planned_s: job.plan.duration(),
        executed_s,
        planned_moving_s: moving(&plan_q) as f64 * dt,
        executed_moving_s: moving(&run_q) as f64 * dt,
        beam_on_planned_s: summary.laser_on_time_s,
        beam_on_executed_s: run.iter().filter(|s| s.dout[0]).count() as f64 * dt,
        edges_planned: plan_edges.len(),
        edges_executed: run_edges.len(),
        edge_place,
        edge_speed,
        on_edge_rel,
        off_edge_rel,
        lit_rel,
        edge_periods,
        pulses_planned: summary.pulses,
        pulses_executed,
        deviation,
    }
}

fn report(ms: &[Measured]) {
    eprintln!(
        "{:<30} {:>9} {:>9} {:>7} {:>8} {:>7} {:>9} {:>7} {:>7} {:>6} {:>8} {:>7} {:>13} {:>8} {:>6} edge periods min/mean/max",
        "example",
        "plan s",
        "LinuxCNC",
        "ratio",
        "moving",
        "beam",
        "model s",
        "/model",
        "beam/m",
        "edges",
        "edge Δ",
        "edge Δv",
        "pulses",
        "dev",
        "lines"
    );
    for m in ms {
        eprintln!(
            "{:<30} {:>9.3} {:>9.3} {:>7.4} {:>8.4} {:>7.4} {:>9.3} {:>7.4} {:>7.4} {:>3}/{:<3} {:>8.4} {:>7.3} {:>6}/{:<6} {:>8.4} {:>6.1} {:>6.2}/{:.2}/{:.2}",
            m.name,
            m.planned_s,
            m.executed_s,
            m.executed_s / m.planned_s,
            m.executed_moving_s / m.planned_moving_s,
            m.beam_on_executed_s / m.beam_on_planned_s.max(1e-9),
            m.model_s,
            m.executed_s / m.model_s,
            m.beam_on_executed_s / m.beam_on_model_s.max(1e-9),
            m.edges_executed,
            m.edges_planned,
            m.edge_place,
            m.edge_speed,
            m.pulses_executed,
            m.pulses_planned,
            m.deviation,
            m.line_starts,
            m.edge_periods[0],
            m.edge_periods[1],
            m.edge_periods[2]
        );
    }
}

fn machine(name: &str) -> lase_runtime::machine::Machine {
    lase_runtime::machine::parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

/// Runs `examples` on machine `machine_name`'s LinuxCNC; with `LASE_LINUXCNC_ONLY=<a,b>` only
/// those of them (to look into one example's edges without the whole suite's minutes).
fn run_all(machine_name: &str, examples: &[&str]) -> Vec<Measured> {
    let only = std::env::var("LASE_LINUXCNC_ONLY").ok();
    let all = examples;
    let examples: Vec<&str> = examples
        .iter()
        .copied()
        .filter(|e| {
            only.as_deref().is_none_or(|o| {
                o.split(',')
                    .any(|x| e.rsplit('/').next() == Some(x.trim()) || x.trim() == *e)
            })
        })
        .collect();
    if examples.is_empty() {
        // Each test filters its own examples: say which this one has, for a misspelt name.
        eprintln!(
            "LASE_LINUXCNC_ONLY={}: none of this test's examples on {machine_name} ({})",
            only.as_deref().unwrap_or(""),
            all.join(", ")
        );
        return Vec::new();
    }
    let mut lcnc = Headless::start(&machine(machine_name));
    let ms: Vec<Measured> = examples.iter().map(|e| measure(&mut lcnc, e)).collect();
    drop(lcnc);
    report(&ms);
    ms
}

/// What a run must show: each planned beam edge and pulse executed (`pulses_missing` at
/// most missing), the edges within `place` (mm, deg) of the planned point and `dv` of the
/// planned speed, the lit path within `place` of the planned one, LinuxCNC's time in motion
/// at most `moving_max` times lase's own plan's (LinuxCNC 2.9 ramps with trapezoids and
/// rounds corners its own way, so it is faster than lase's jerk-limited, per-axis-feasible
/// plan wherever jerk binds: the blended corners of the texture rows run in 54 % of lase's
/// time), and its cycle and beam-on times within `cycle` and `beam` of `lase plan`'s
/// LinuxCNC model (issue 13: 1 %).
#[derive(Debug, Clone, Copy)]
struct Bounds {
    place: f64,
    dv: f64,
    cycle: f64,
    beam: f64,
    moving_max: f64,
    pulses_missing: u64,
}

impl Bounds {
    /// Issue 13's bounds: the model within 1 %, LinuxCNC's motion at most 1 % over lase's.
    const fn new(place: f64, dv: f64) -> Bounds {
        Bounds {
            place,
            dv,
            cycle: 0.01,
            beam: 0.01,
            moving_max: 1.01,
            pulses_missing: 0,
        }
    }
}

fn assert_close(m: &Measured, b: Bounds) {
    assert!(
        m.edges_executed == m.edges_planned
            && m.pulses_executed <= m.pulses_planned
            && m.pulses_executed + b.pulses_missing >= m.pulses_planned,
        "edges and pulses: {m:?}"
    );
    assert!(m.edge_place <= b.place, "edge place: {m:?}");
    assert!(m.edge_speed <= b.dv, "edge speed: {m:?}");
    assert!(m.deviation <= b.place, "lit path: {m:?}");
    let ratio = m.executed_moving_s / m.planned_moving_s;
    assert!(
        ratio <= b.moving_max,
        "moving vs lase's plan {ratio}: {m:?}"
    );
    // `lase plan`'s LinuxCNC model: the cycle and the beam-on time.
    let vs_model = m.executed_s / m.model_s;
    assert!(
        (vs_model - 1.0).abs() <= b.cycle,
        "cycle vs model {vs_model}: {m:?}"
    );
    let beam_vs_model = m.beam_on_executed_s / m.beam_on_model_s;
    assert!(
        (beam_vs_model - 1.0).abs() <= b.beam,
        "beam-on vs model {beam_vs_model}: {m:?}"
    );
}

/// Whether to run the long examples too (`LASE_LINUXCNC_LONG=1`): nested_parts (60 s on
/// LinuxCNC), codes (98 s), material_test (165 s), surface_hardening_arm (218 s) and rhai_cam
/// (30 s, a cam like cam_hardening's) would more than double the suite's LinuxCNC time, which
/// CI's 20 minutes for everything cannot take.
fn long_examples() -> bool {
    std::env::var_os("LASE_LINUXCNC_LONG").is_some_and(|v| v == "1")
}

/// The flat bed's bounds per example. Measured on the real LinuxCNC 2.9 (2026-12-02, executed
/// / model, cycle and beam-on; edge place mm, edge speed mm/s, lit path mm).
///
/// Edge places are measured from the exact planned edge (`planned_edge`) since the beam-switch
/// lead (`emit::writer::lead`); before, from the first lit 1 ms sample of the plan, up to a
/// period of travel past it. LinuxCNC's synchronized outputs lead its joints by 1.5 servo
/// periods (cubic interpolator), so the writer carries each switch passed on the fly that far
/// along the path. Measured with `cargo test --test linuxcnc flat_bed -- --nocapture` (the
/// last column: where the edges fall along the path, in servo periods, least/mean/greatest;
/// `LASE_LINUXCNC_EDGES=1` lists them), before (the lead set to 0, exact edges) → after:
/// frame_marking 0.0270 → 0.0152 mm (−1.35/0.09/1.53 → −0.35/0.59/1.53: its on-edges lie on
/// arcs, which are not cut, and come 1.5 periods late, after tp's blend into the arc),
/// texture rows 0.0355 → 0.0355 (the gate-off now on time, +0.22; the gate-on goes with the
/// pulse writer and stays 1.78 periods early), air_assist 0.0184 → 0.0099 mm (edge speed
/// 0.320 → 0.197 mm/s).
///
/// Since the writer also carries the pulse triggers (`M62`/`M63 P1`), the image rows' power
/// steps (`M67`) and the switches on arcs, cutting arcs too (2026-12-02, branch pulselead,
/// before → after): frame_marking 0.0152 → 0.0059 mm (its on-edges on arcs +1.53 → +0.59
/// periods; edge speed 0.357 → 0.307 mm/s), texture rows 0.0355 → 0.0045 mm (the gate-on now
/// carried with the triggers: −1.78/−0.78/0.22 → 0.22/0.22/0.22 periods, lit path 0.0355 →
/// 0.0000, beam-on 1.0043 → 1.0000 of the model), air_assist 0.0099 → 0.0076 mm; every
/// pulse still fired (360/360).
///
/// Edge speeds (2026-12-02, `LASE_LINUXCNC_LONG=1 LASE_LINUXCNC_EDGES=1 cargo test --test
/// linuxcnc flat_bed -- --nocapture`): tp.c passes a tangent junction at the lower of its two
/// blocks' feeds (`tpGetRealFinalVel`); the writer held a lit stroke's last sub-block at the
/// plan's mean over it and wrote its lead-out at the full feed, so where the plan speeds up
/// or slows down through an edge LinuxCNC crossed it at the block's mean. Now the block from
/// an edge to its carried switch is at the plan's speed at the edge and a lit block next to
/// an off-edge no slower (`emit::writer::write_block`): edge Δv frame_marking 0.307 → 0.027,
/// air_assist 0.309 → 0.009, serial_number 1.179 → 0.126, nested_parts 0.547 → 0.036,
/// material_test 0.607 → 0.042 mm/s; places unchanged (frame_marking 0.0059 → 0.0061).
fn flat_bed_bounds(example: &str) -> Bounds {
    match example {
        "frame_marking" | "texture_array" | "texture_array_unidirectional" | "air_assist" => {
            Bounds::new(0.01, 0.05)
        }
        // Each tick's edges within 0.13 periods (−1.5 to −2 before: 0.1 mm early). The
        // circle's end: its switch rides on the lead-out, which meets the circle 0.66° off
        // its tangent, so tp lays a blend arc over that junction and switched only after it,
        // 8.8 periods (0.35 mm) late; the writer now cuts the lead-out past the blend
        // (`lead::cut_at`), 3.2 periods (0.128 mm) late: tp swallows the short first part into
        // the blend (`blendCheckConsume`), which then reaches further. The dotted arc's end
        // gate (25 mm/s) 1.86 periods early. Edges 0.3529 → 0.1284 mm, lit path 0.3156 →
        // 0.0466 (after: from the exact edges), edge speed 0.000, cycle 1.0012, beam 1.0043.
        // Now arcs are cut too (branch pulselead): the circle's beam-on is carried into the
        // circle past the lead-in's blend (+3.21 → +0.21 periods), the dotted arc's triggers
        // along it; its on-edge, whose lead-in meets the arc 0.6° off its tangent, is cut
        // past tp's blend (`lead::cut_at`, +0.63 periods; cut at the bare lead it was −0.40
        // but tp passed it at 24.2 of 25 mm/s). Edges 0.1284 → 0.0328 mm (the circle's end,
        // +0.82 periods), lit path 0.0077, edge speed 0.000, cycle 1.0016, beam 1.0001.
        "dial_marks" => Bounds::new(0.04, 0.05),
        // Rows at 100 mm/s: −1.99/−1.52/−1.49 periods → −1.49/−0.63/0.01, edges 0.1986 →
        // 0.1486 mm (0.279 with the old sampling), lit path 0.2451 → 0.1486 (after: from the
        // exact edges); cycle 1.0031, beam 0.9979 of the model. Every row's edges are carried
        // but the starts of rows whose first run is one 0.25 mm pixel: a cut would leave
        // 0.1 mm, under the 1.25 periods tp needs at 100 mm/s, and a switch after that run
        // would land with the next run's power line (M67 steps are not carried), so those stay
        // where the run starts, 1.5 periods early. Carrying every edge measured 0.0514 mm.
        // Now every run's end (its `M67`) is carried with the beam switch and the last run
        // runs on into the lead-out (`row::Carry`, branch pulselead): every edge carried,
        // −1.49/−0.63/0.01 → −0.49/−0.46/0.01 periods, edges and lit path 0.1486 → 0.0486 mm,
        // beam-on 0.9979 → 1.0011 of the model. What is left is tp's switching once per servo
        // period: at 100 mm/s half a period is 0.05 mm, so issue 13's 0.04 mm is out of reach
        // for an edge whose place within its period the writer does not know.
        "image_engrave" => Bounds::new(0.05, 0.05),
        // Pinned (issue 13), at lit↔lit corners: its characters' strokes turn at sharp
        // corners between short lit lines. Before they were blended and held (branch
        // litfeed), LinuxCNC rounded them with its own blend arcs within G64 P0.01 (14.7 mm/s
        // at the S's 45° turns) and the model ran 88-105 ms long on every such stroke (cycle
        // 0.951 and beam-on 0.879 of the model; 0.913 and 0.780 before the model joined
        // collinear lines as canon's naive-CAM detector does). Now lase plans those corners
        // and writes the held sub-blocks: cycle 1.0168 and beam-on 1.0256 of the model
        // (2026-12-02, merge of main into litfeed), the model now a little short. The edges
        // (0.600 mm, 39.4 mm/s) and the lit path (3.00 mm) miss lase's plan. Found (2026-12-02,
        // `LASE_LINUXCNC_EDGES=1`): the worst edges (+17 periods, 0.70 mm at 40 mm/s, strokes
        // of the top row) switch on where canon's naive CAM joins the lit lines after the
        // switch into one chord (the program line jumps from the switch's block to the fourth
        // after it), which meets the collinear lead-in ~1° off, so tp lays a blend arc over
        // that junction and switches after it. With the lead the other edges fall within
        // −0.58..+0.6 periods; these five stayed late: edges 0.6097 → 0.7015 mm (exact edges,
        // before → after), edge speed 39.4 mm/s, lit path 0.5899 mm. Now the header writes
        // `G64 P0.01 Q0` (canon's naive CAM off, `emit/writer.rs`), so LinuxCNC runs lase's lit
        // lines as written and the switch as the lead-in meets the first, in line: edges
        // 0.7015 → 0.0199 mm (−0.56/0.03/0.50 periods), edge speed 39.4 → 1.18 mm/s, lit path
        // 0.5899 → 0.0193 mm; cycle 1.0167, beam-on 1.0235 of the model (2026-12-02, branch
        // naivecam): the model ran the glyphs' held strokes short. Found (branch tpquant,
        // comparing each NC line's start, `LASE_LINUXCNC_DUMP`): at the strokes' slow corners
        // (0.6 mm/s) the model laid the tolerance's whole blend arc, LinuxCNC one only as large
        // as the corner speed needs (`blendComputeParameters`' R_plan), 25 ms a corner; the
        // held sub-blocks under 10 ms ramp at one acceleration (`TC_ACCEL_RAMP`); each run from
        // rest to rest ends on a servo period. Now cycle 0.9940, beam-on 0.9905 (2026-12-02).
        // Edge speed 1.179 → 0.126 mm/s (the edges held at the plan's speed, above), cycle
        // 0.9938, beam-on 0.9903.
        "serial_number" => Bounds::new(0.07, 0.2),
        // Every one of its 105 pulses fires. Where two dots touch (rows y = 1.05, 1.65, 2.25,
        // 3.75, 4.05) lase once wrote `M63 P1` and the next `M62 P1` before the same move, and
        // LinuxCNC keeps one synchronized switch per output and segment (tp.c `tpSetDout`),
        // so 5 pulses merged into their neighbours; the trigger now falls on a block of its
        // own (`emit::writer::pulse`). Edges 0.126 mm off. Cycle 1.0101 of the model before
        // the model ended each rest-to-rest run on a servo period (its dots are short stops),
        // now 1.0000, beam-on 1.0006 (branch tpquant, 2026-12-02, edges 0.0355 mm). With the
        // triggers carried like the beam switch (branch pulselead, LASE_LINUXCNC_LONG=1,
        // 2026-12-02): edges 0.126 → 0.0237 mm (−0.28/0.44/0.47 periods), edge speed
        // 0.001 mm/s, pulses 105/105.
        "codes" => Bounds::new(0.03, 0.05),
        // Pinned (issue 13): edges 0.248 mm off. 1 300 of its 1 316 edges switch at cruise
        // (20-100 mm/s; on the 20 mm/s rows 1.8 ms early at both ends, as on frame_marking);
        // the 16 others sit in the labels' text, strokes with lit↔lit corners as in
        // serial_number. Before those corners were blended and held (branch litfeed) the
        // beam-on was 0.978 of the model (cycle 0.991), the edges 12.07 mm/s and the lit path
        // 1.51 mm off; now (2026-12-02) cycle 1.0039, beam-on 1.0050, edge speed 0.237 mm/s
        // and the lit path 0.248 mm. Under `G64 P0.01 Q0` (branch naivecam, LASE_LINUXCNC_LONG=1,
        // 2026-12-02) edges 0.0486 mm and lit path 0.0486 mm, but edge speed 0.607 mm/s, over
        // this pin (not loosened: which edges, not yet found; LASE_LINUXCNC_EDGES=1 lists them).
        // Branch pulselead (2026-12-02): edges 0.0486 mm, lit path 0.0486, edge speed still
        // 0.607 mm/s (not looked into), cycle 1.0039, beam-on 1.0035.
        // Main after the merges of tpquant, pulselead and rotedge (2026-12-02, LONG=1, quiet
        // machine): edges 0.0486 mm, cycle 0.9989, beam-on 0.9965 of the model; the edge
        // speed still 0.607 mm/s over this pin: every edge over 0.3 mm/s is an off-edge at a
        // stroke's end in the labels, where lase's S-curve plan decelerates through it
        // (6.9 mm/s) and LinuxCNC's trapezoid, within the same held sub-block, is 0.4-0.6 mm/s
        // faster there (7.3-7.9 mm/s, at the planned place within 0.13 periods).
        // Edges held at the plan's speed (above): edge speed 0.607 → 0.042 mm/s, cycle 0.9989,
        // beam-on 0.9966.
        "material_test" => Bounds::new(0.05, 0.1),
        // Same run: edges 0.0111 mm, cycle 0.9992, beam-on 0.9991; edge speed 0.547 mm/s over
        // the pin at the tabbed plate's corner arcs (edges 13 and 17 on at 2.11 where the plan
        // says 2.66 mm/s: the arc's held F is the plan's mean over it; edges 22/26/30 off at
        // 3.05 against 2.67).
        // Edges held at the plan's speed (above): edge speed 0.547 → 0.036 mm/s, cycle 0.9993,
        // beam-on 0.9992.
        "nested_parts" => Bounds::new(0.07, 0.1),
        _ => Bounds::new(0.07, 0.1),
    }
}

#[test]
fn flat_bed_examples_on_linuxcnc() {
    if !available() {
        return;
    }
    let mut examples = vec![
        "frame_marking",
        "dial_marks",
        "texture_array",
        "texture_array_unidirectional",
        "air_assist",
        "image_engrave",
        "serial_number",
    ];
    if long_examples() {
        examples.extend(["nested_parts", "codes", "material_test"]);
    } else {
        eprintln!("nested_parts, codes and material_test: LASE_LINUXCNC_LONG=1 runs them too");
    }
    for m in &run_all("xy_table", &examples) {
        assert_close(m, flat_bed_bounds(&m.name));
    }
}

#[test]
fn rotary_example_on_linuxcnc() {
    if !available() {
        return;
    }
    // X along the object, A turning it, every feed move in inverse time (G93). Every block
    // that turns A meets its neighbours in a parabolic blend (tp.c gives up on tangent joins
    // and blend arcs with A B C motion), and tp switches a synchronized output in the middle
    // of it, when the block carrying it becomes the faster (`tpDoParabolicBlending` →
    // `tpToggleDIOs`). Before (branch rotedge; LASE_LINUXCNC_EDGES=1 lists the edges): edges
    // 0.526 (mm, deg) off place, 18.09 off speed, the rings on at 96.8 of 114.6 °/s (their
    // 5.13° lead-ins could not carry the blend's speed, `tpComputeBlendVelocity`), off
    // 0.53° early at 106.7 (a lead-out ending in STOP ramps at full acceleration against the
    // lit block's half), every edge 1-6 periods early (G93 switches were not carried). Now
    // leads that turn A reach 2·v²/a plus two periods, the junction moves 1.5 periods past
    // the edge (`emit::writer::lead::shift`), a lead-out is two blocks, a lit move the plan
    // slows in keeps sub-blocks as long as a blend carries (`power::merge_short`), and the
    // circle, whose 0.76° chords LinuxCNC holds at 18.9 mm/s at most (`lase check` now
    // judges the attachment's G93 blocks too), follows at 18: edges 0.0413 off place, 3.88
    // off speed (the "S"'s last lit block, which the plan accelerates through to 45.7 where
    // its merged sub-block runs 41.9; the rings pass at 115.8: tp's first blend period adds
    // the lead's last step, ~1 % at a/2·T), cycle 0.9934 and beam-on 0.9991 of the model.
    //
    // The S's last lit block now merged from the back (the shortest tp carries at the edge)
    // and held no slower than the plan's speed there (`emit::writer`): its off-edge 41.85 →
    // 46.33 of 45.73, edge speed 3.88 → 2.03 (2026-12-02). What is left: on-edges in
    // parabolic blends 1-4 % fast (the "S"'s start 47.76 of 45.73), where the lit block
    // gains speed along its own direction faster than the lead-in loses it.
    //
    // Found (2026-12-03): in the blend's first servo period the lit block takes a whole step
    // of its half acceleration while the lead-in decelerates only for the part after its
    // turning point, so the summed speeds run up to A·T above the lead-in's until the switch.
    // The lead-in now gives up the mean, A·T/2 (`emit::writer::lead::blend_gain`): on-edges
    // (planned → executed, °/s or mm/s of axis space) rings 114.59 → 115.79 before, 114.07
    // after; 57.30 → 58.80, 57.16; 54.60 → 55.98, 54.32; the S 45.73 → 47.76, 46.09; 34.37 →
    // 35.70, 34.45 (+1.0..+4.4 % → −0.5..+0.8 %). Edge speed 2.03 → 1.21, now an off-edge
    // (58.51 of 57.30: there the lit block is the finishing one, and slowing it would run
    // its lit stretch before the blend slow instead); cycle 0.9927, beam-on 0.9988 of the
    // model.
    //
    // The lead-out before a stop is split where its first block's triangle speed is the lit
    // speed less that mean gain (`lead::split_at`; it was halved), so tp starts the blend as
    // the lit block has slowed by it: off-edges 115.67 → 113.87 (rings), 58.51 → 56.71,
    // 35.45 → 33.65 (+0.9..+3.1 % → −0.6..−2.1 %); edge speed 1.21 → 0.73, edge place 0.0413
    // → 0.0235; cycle 0.9928, beam-on 0.9988 of the model. What is left is where in its servo
    // period the blend begins (±A·T/2), which the writer does not follow.
    //
    // It does where the lead-in starts at rest (after a rapid, where tp stops): the servo
    // clock is then known, and tp.c's arithmetic (`motion::parabolic::chain`) picks the
    // lead-in speed whose summed speed crosses the on-edge at the plan's
    // (`lead::lead_in_speed`): on-edges 114.07 → 114.20, 57.16 → 57.29, 54.32 → 54.53, 46.09 →
    // 45.74, 34.45 → 34.36 (−0.5..+0.8 % → −0.34..+0.02 %), 2026-12-03.
    //
    // The off-edges into a lead-out that stops: through that blend the summed speed is the
    // lit speed less A·(T − φ), φ where in its servo period the lit block's deceleration
    // turns (or a period later A·φ above it), which the writer now times by the same replay
    // from the lead-in's rest (`emit::writer::block::off_edge_timing`: the junction moved by
    // up to half a period of travel, the lit block's time by up to a period and 0.05 %, the
    // lead-out's first block chosen, the beam kept within half a period of its place):
    // rings 113.87 → 114.54 of 114.59, 55.27 → 54.58 of 54.60, 56.71 → 57.31 of 57.30, the
    // S's end 33.65 → 34.32 of 34.37; their places −0.12 → +0.06, +0.43 → +0.13, −0.23 →
    // −0.17, +0.18 → +0.34 periods; edge speed 0.73 → 0.59, now the one off-edge into a
    // lead-out that does not stop (the S's, 46.33 of 45.73), 2026-12-03.
    //
    // The S's lit run holds 63 X-only blocks, which tp joins tangentially between the blocks
    // that turn A: the replay now runs tangent joins too (`motion::parabolic::chain`: the
    // look-ahead's final speeds, split periods carrying the speed on), so the S's off-edge is
    // timed like the rest: 46.33 → 45.81 of 45.73 °/s, place +0.08 → −0.03 periods. Two
    // rules the real machine showed and the sources did not: a block after a parabolic blend
    // ramps at half its acceleration only where its own term condition is parabolic (the
    // lead-out ending in a stop, an X-only block, at full), and a tangent split switches to
    // the next block. With them every NC line starts in the model within a servo period of
    // the real one (`line_starts`; the model's lines drifted 121 ms behind by the program's
    // end before), cycle 0.9935 → 1.0002 of the model, beam-on 0.9996 → 0.9999, 2026-12-03.
    for m in &run_all("xy_rotary", &["rotary_engrave"]) {
        let tight = Bounds {
            cycle: 0.002,
            beam: 0.002,
            ..Bounds::new(0.03, 0.7)
        };
        assert_close(m, tight);
        assert!(m.on_edge_rel <= 0.005, "on-edge speed: {m:?}");
        assert!(m.off_edge_rel <= 0.004, "off-edge speed: {m:?}");
        assert!(m.line_starts <= 1.5, "NC line starts vs the model: {m:?}");
    }
}

#[test]
fn arm_example_on_linuxcnc() {
    if !available() {
        return;
    }
    // The arm's program is in joint space (X slide, A B C joints in degrees): trivkins over
    // its joints runs it as written, and the model times it within 1 % (cycle and beam-on
    // 1.0000).
    //
    // Before (10 mm/s at 1.5 kW): LinuxCNC ran each lit section 14.27 s where lase's plan
    // (and the power coupled to it) said 12.64 s: moving 1.1045 of the plan, beam on 1.129.
    // Where the arm's path bends, lase writes G93 blocks as short as 5.4 ms (0.19° of joint
    // motion) to keep the spot within the 1 µm tolerance and its speed within 0.1 %. LinuxCNC
    // 2.9 joins moves with rotary axes only by parabolic blends (tpSetupTangent gives up on
    // ABC motion), ramps both ends at half the acceleration and caps the blend's speed at the
    // segment's triangle speed sqrt(a/2 · L) (tpComputeBlendVelocity): the samples showed
    // 15 ms a block, 36 % of the recipe's speed. `lase check` now refuses that
    // (`motion::parabolic`: 10 mm/s, LinuxCNC holds 3.57 mm/s there) and the example follows
    // at 3.5 mm/s at 525 W, the same 150 J/mm. The model (which replays those chains servo
    // period by servo period) puts LinuxCNC at 218.08 s against lase's plan's 220.68 s: 0.988,
    // so the pin is issue 13's 1.01. On 2026-12-02 (four builders on two cores, load 2-6)
    // its milltask vanished in each of seven runs, at varying NC lines (256, 380, ...); on an
    // otherwise idle machine (2026-12-03) the real LinuxCNC ran it whole: 218.085 s against
    // the model's 218.084 (1.0000) and the plan's 220.68 (0.9882), beam-on 1.0000 of the
    // model, 12/12 edges within 0.0024 (mm, °) of their places but 1.4-2.2 servo periods
    // early (the arm's switches are not carried: its 2 ms blends), on-edges at 1.29 of 1.11
    // joint °/s. Its 218 s program is more than the rest of the suite together, which CI's
    // 20 minutes for everything cannot take: `LASE_LINUXCNC_LONG=1` runs it; CI runs
    // tests/linuxcnc/arm_short.lase, two 7 s sections of the same arm, speed and tolerance.
    //
    // Its switches are timed by tp.c's replay since (`emit::writer::timing`: the arm's blends
    // last 2 servo periods, too short for the cams' rule): junctions moved 0-4 periods on,
    // lead-ins from rest slowed, so that the joints' speed at each lit sample about the switch
    // (the cubic interpolator's, `ChainRun::switch_window`) is the lit speed with the beam
    // within half a period of its place. Real LinuxCNC, `LASE_LINUXCNC_LONG=1
    // LASE_LINUXCNC_EDGES=1 cargo test --test linuxcnc arm_example -- --nocapture`,
    // 2026-12-03, before → after: arm_short's edges −2.05/−1.76/−1.08 → −0.10/+0.10/+0.40
    // periods (least/mean/most), place 0.0022 → 0.0003, edge speed 0.050 → 0.010, lit speed
    // about the edges (`lit_rel`) ±10.4 % → ±3.0 %, off-edge at the switch sample +4.2 % →
    // +1.4 % (that sample's central difference takes in the lead-out's blend, beam off);
    // surface_hardening_arm's 12 edges −2.15..−1.44 → −0.49..+0.17 periods, place 0.0024 →
    // 0.0005, lit ±2.7 %, on-edges 1.29 → 1.03-1.11 of 1.06-1.11 °/s, cycle and beam-on
    // 1.0000 of the model. Ranked instead by the speed at the switch sample alone, a lead-in
    // ran at 0.83 of the lit speed and the joints, lit, at +21 % in the blend after it.
    let examples: &[&str] = if long_examples() {
        &["tests/linuxcnc/arm_short", "surface_hardening_arm"]
    } else {
        eprintln!("surface_hardening_arm: LASE_LINUXCNC_LONG=1 runs it");
        &["tests/linuxcnc/arm_short"]
    };
    for m in &run_all("arm_3r", examples) {
        // The lit path within 0.02° of the plan's (LinuxCNC's blends round the 5 ms blocks
        // where the section bends: 0.0106° on arm_short, 0.0039° on the example), every edge
        // within 0.001 and half a period of its place.
        assert_close(m, Bounds::new(0.02, 0.05));
        assert!(m.edge_place <= 0.001, "edge place: {m:?}");
        assert!(m.on_edge_rel <= 0.03, "on-edge speed: {m:?}");
        assert!(m.off_edge_rel <= 0.03, "off-edge speed: {m:?}");
        assert!(m.lit_rel <= 0.04, "lit speed about the edges: {m:?}");
        let [least, _, most] = m.edge_periods;
        assert!(least >= -0.5 && most <= 0.5, "edge places: {m:?}");
    }
}

#[test]
fn notcher_example_on_linuxcnc() {
    if !available() {
        return;
    }
    // The notcher switches its beam with immediate outputs at rest (M64/M65): edges at the
    // planned stops.
    for m in &run_all("notcher", &["conrod_notch"]) {
        assert_close(m, Bounds::new(0.01, 0.5));
    }
}

#[test]
fn cam_examples_on_linuxcnc() {
    if !available() {
        return;
    }
    // The beam switches on the fly (M67/M62 synchronized): on at cruise, not at rest.
    // Every junction of their lit sections is a parabolic blend between G93 blocks, which
    // the model replays servo period by servo period (`tp::servo`): LinuxCNC runs them
    // ~0.4 ms a block faster than their inverse times.
    // rhai_cam is a cam of the same machine and kind of motion, its law (modified sine) from
    // a Rhai extension, 30 s more: `LASE_LINUXCNC_LONG=1` runs it too.
    let examples: &[&str] = if long_examples() {
        &["cam_hardening", "rhai_cam"]
    } else {
        &["cam_hardening"]
    };
    //
    // Their switches were not carried: on and off 1.6-1.7 servo periods early (0.026°, the
    // cubic interpolator's lag). Now the lead-in and lead-out run on the lit chord's line in
    // the axes (C and B together), so their junctions move 1.5 periods on as on the rotary
    // attachment (`lead::shift`, `blend_gain`, `split_at`; `motion::leadin` makes the
    // lead-out long enough for two blocks): cam_hardening's edges 0.0262 → 0.0036 (−1.72 /
    // −1.58 → −0.24 / +0.21 periods), rhai_cam's 0.0257 → 0.0032 (2026-12-03). The speeds at
    // the edges stay within the blend's ±A·T/2 (C at 1800 °/s²: ±0.45 of 15.3 °/s): on 15.65
    // and off 14.98 of 15.25/15.28 (15.62 and 15.42 before), rhai_cam's 15.60 / 15.08 (15.57
    // / 15.53). With the lead-in's speed from tp.c's arithmetic (`lead::lead_in_speed`, its
    // lead-in starts at rest after the rapid): on at 15.25 of 15.25, 0.0005° from its place.
    // The off-edge timed by the same replay (`emit::writer::block::off_edge_timing`): 14.98
    // → 15.31 of 15.28, place +0.21 → +0.37 periods (0.0056°), 2026-12-03.
    for m in &run_all("cam_xwb", examples) {
        assert_close(m, Bounds::new(0.01, 0.1));
        assert!(m.on_edge_rel <= 0.005, "on-edge speed: {m:?}");
        assert!(m.off_edge_rel <= 0.005, "off-edge speed: {m:?}");
    }
}
