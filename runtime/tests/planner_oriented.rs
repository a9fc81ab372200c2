//! The planner on oriented machines (PROCESS.md §1, §2), measured from the plan through the
//! `Job` API: their moves are part-space chords of axes in mm and rad, so corners are judged
//! per axis (`planner::junction`). The lit speed is then the programmed surface speed wherever
//! no axis limit binds, every axis stays within the limits of its machine file (read here on
//! its own), and a slow joint that reverses costs no speed.

mod common;

use common::job;
use lase_runtime::machine::{Machine, parse_machine};
use lase_runtime::motion::Job;
use lase_runtime::planner::{AxisLimits, MAX_AXES, Move, Plan, PlannerConfig, ProfileKind, plan};
use lase_runtime::report::beam_at;

/// Relative slack on limits: rounding only.
const LIM: f64 = 1.0 + 1e-9;

fn example(name: &str) -> Job {
    let path = format!("{}/../examples/{name}.lase", env!("CARGO_MANIFEST_DIR"));
    job(&std::fs::read_to_string(path).unwrap())
}

/// The stock machine file, parsed on its own (mm, rad, s).
fn machine(name: &str) -> Machine {
    parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

/// What axis `k` needs at the junction where segment `i` starts when it is passed at path
/// speed `v`: its rate per unit of path changes by `Δu_k` there, and taken within the shorter
/// of the two adjacent half-moves (all the room the corner has without leaving them) that is
/// an acceleration of `|Δu_k|·v² / min(L)`. On chords sampling a smooth axis curve this is its
/// second difference `q_k''·v²`. Zero before the first segment, and where either segment is
/// half of a corner blend (`Plan::blend_of`: the cam's lit chords, issue 13 item 3): there no
/// axis velocity steps, and the blend's own axis acceleration is what the samples of
/// `every_axis_stays_within_its_machine_limits` measure.
fn corner_accel(p: &Plan, i: usize, k: usize, v: f64) -> f64 {
    let segs = p.segments();
    if i == 0 || i >= segs.len() || p.blend_of(i).is_some() || p.blend_of(i - 1).is_some() {
        return 0.0;
    }
    let du = p.direction(i)[k] - p.direction(i - 1)[k];
    du.abs() * v * v / segs[i - 1].length.min(segs[i].length)
}

/// The highest share of one of its limits axis `k` would need on segment `i` at path speed
/// `v`: its speed `|u_k|·v` against `v_max`, the corners at both ends against `a_max`.
fn need(p: &Plan, m: &Machine, i: usize, k: usize, v: f64) -> f64 {
    let a = &m.axes[k];
    (p.direction(i)[k].abs() * v / a.v_max)
        .max(corner_accel(p, i, k, v) / a.a_max)
        .max(corner_accel(p, i + 1, k, v) / a.a_max)
}

/// Every 1 ms of the job with the beam on: (sample, programmed feed).
fn lit_samples(j: &Job) -> Vec<(lase_runtime::planner::Sample, f64)> {
    let total = j.cycle_time();
    let n = (total * 1000.0).ceil() as usize;
    (0..=n)
        .filter_map(|k| {
            let (s, lit, _) = beam_at(j, (k as f64 * 1e-3).min(total));
            lit.then(|| (s, j.plan.segments()[s.segment].feed))
        })
        .collect()
}

#[test]
fn lit_speed_is_the_programmed_speed_unless_an_axis_limit_binds() {
    for (name, mach) in [
        ("surface_hardening_arm", "arm_3r"),
        ("cam_hardening", "cam_xwb"),
    ] {
        let j = example(name);
        let m = machine(mach);
        let p = &j.plan;
        let lit = lit_samples(&j);
        assert!(lit.len() > 20_000, "{name}: {} lit samples", lit.len());
        let mut worst_dev = 0.0f64;
        let mut bound = Vec::new();
        // The highest share of a limit any axis needs at the programmed speed on a lit move.
        let mut headroom = vec![0.0f64; m.axes.len()];
        for (s, feed) in &lit {
            let needs: Vec<f64> = (0..m.axes.len())
                .map(|k| need(p, &m, s.segment, k, *feed))
                .collect();
            for (h, n) in headroom.iter_mut().zip(&needs) {
                *h = h.max(*n);
            }
            let dev = (s.v / feed - 1.0).abs();
            if dev <= 5e-3 {
                worst_dev = worst_dev.max(dev);
                continue;
            }
            // Below the programmed speed: only an axis that could not follow it may be why.
            let (k, n) = needs
                .iter()
                .copied()
                .enumerate()
                .fold((0, 0.0), |b, (k, n)| if n > b.1 { (k, n) } else { b });
            assert!(
                n >= 1.0 && s.v <= *feed,
                "{name}: lit at {:.4} mm/s (programmed {feed}) at t = {:.3} s, segment {}, \
                 though no axis limit binds: the most any axis needs is {:.3} of {}'s",
                s.v,
                s.t,
                s.segment,
                n,
                m.axes[k].name
            );
            bound.push((s.t, s.v, m.axes[k].name.clone(), n));
        }
        eprintln!(
            "{name}: {} lit samples, worst deviation from the programmed speed {:.2e}; \
             below it where an axis binds: {:?}; highest need per axis at the programmed speed: {}",
            lit.len(),
            worst_dev,
            bound,
            m.axes
                .iter()
                .zip(&headroom)
                .map(|(a, h)| format!("{} {:.4}", a.name, h))
                .collect::<Vec<_>>()
                .join(", ")
        );
        // At 10 mm/s (arm) and 8 mm/s (cam) every joint has room to spare: the whole lit
        // track is at the programmed speed.
        assert!(bound.is_empty(), "{name}: {bound:?}");
        assert!(headroom.iter().all(|&h| h < 0.5), "{name}: {headroom:?}");
    }
}

#[test]
fn cam_is_lit_at_exactly_its_surface_speed() {
    let j = example("cam_hardening");
    let lit = lit_samples(&j);
    assert!(lit.len() > 27_000, "{}", lit.len());
    for (s, feed) in lit {
        assert_eq!(feed, 8.0);
        assert!((s.v - 8.0).abs() <= 8.0 * 1e-9, "lit at {} mm/s", s.v);
    }
}

#[test]
fn every_axis_stays_within_its_machine_limits() {
    for (name, mach) in [
        ("surface_hardening_arm", "arm_3r"),
        ("cam_hardening", "cam_xwb"),
    ] {
        let j = example(name);
        let m = machine(mach);
        let p = &j.plan;
        let segs = p.segments();
        let n = m.axes.len();
        // Along each move, sampled at 1 kHz and at every segment boundary: speed,
        // acceleration and jerk of every axis.
        let mut times: Vec<f64> = (0..=(p.duration() * 1000.0).ceil() as usize)
            .map(|k| k as f64 * 1e-3)
            .collect();
        for seg in segs {
            times.push(seg.t_start);
            times.push(seg.t_start + seg.motion_duration());
        }
        let mut peak = vec![[0.0f64; 4]; n];
        for t in times {
            let s = p.sample(t);
            for (k, a) in m.axes.iter().enumerate() {
                let share = [
                    s.vel[k].abs() / a.v_max,
                    s.acc[k].abs() / a.a_max,
                    s.jerk[k].abs() / a.j_max,
                ];
                for (q, x) in share.into_iter().enumerate() {
                    peak[k][q] = peak[k][q].max(x);
                }
            }
        }
        // Through each corner, at the speed it is passed at.
        for (i, seg) in segs.iter().enumerate() {
            for (k, a) in m.axes.iter().enumerate() {
                peak[k][3] = peak[k][3].max(corner_accel(p, i, k, seg.v_entry) / a.a_max);
            }
        }
        for (k, a) in m.axes.iter().enumerate() {
            eprintln!(
                "{name} {}: share of v_max {:.4}, a_max {:.4}, j_max {:.4}, a_max at corners {:.4}",
                a.name, peak[k][0], peak[k][1], peak[k][2], peak[k][3]
            );
            assert!(
                peak[k].iter().all(|&x| x <= LIM),
                "{name}: axis {} above its limits: {:?}",
                a.name,
                peak[k]
            );
        }
    }
}

/// Moves along a path sampled every `step` mm of part space whose axis rates per mm are
/// `rate(s)` (taken at each chord's middle): a multi-axis chord's length is its part-space
/// length, not its axis-space one.
fn chords(rate: impl Fn(f64) -> [f64; MAX_AXES], n: usize, step: f64, feed: f64) -> Vec<Move> {
    let mut q = [0.0; MAX_AXES];
    (0..n)
        .map(|i| {
            let r = rate((i as f64 + 0.5) * step);
            for k in 0..MAX_AXES {
                q[k] += r[k] * step;
            }
            Move::new(q, step, feed)
        })
        .collect()
}

/// The arm's limits (X mm; A, B, C rad).
fn arm_limits() -> AxisLimits {
    let m = machine("arm_3r");
    let mut l = AxisLimits {
        v: [f64::INFINITY; MAX_AXES],
        a: [f64::INFINITY; MAX_AXES],
        j: [f64::INFINITY; MAX_AXES],
    };
    for (k, a) in m.axes.iter().enumerate() {
        (l.v[k], l.a[k], l.j[k]) = (a.v_max, a.a_max, a.j_max);
    }
    l
}

#[test]
fn a_rotary_axis_reversing_at_a_tiny_rate_costs_no_speed() {
    // A rotary-dominant path (X still, A and C turning at 8e-4 and 5e-4 rad per mm) on which B
    // reverses: its rate goes from −1e-3 to +1e-3 rad/mm over 2 mm around s = 20 mm. In axis
    // space the direction swings by about 90° within five 0.4 mm chords; physically B
    // accelerates at B''·v² = 1e-3 · 10² = 0.1 rad/s², 0.6 % of its 15.7 rad/s².
    let (step, feed, s0) = (0.4, 10.0, 20.0);
    let rate = |s: f64| {
        [
            0.0,
            8e-4,
            1e-3 * ((s - s0) / 1.0).clamp(-1.0, 1.0),
            5e-4,
            0.0,
            0.0,
        ]
    };
    let moves = chords(rate, 100, step, feed);
    let limits = arm_limits();
    for profile in [ProfileKind::Trapezoid, ProfileKind::SCurve] {
        let cfg = PlannerConfig {
            profile,
            n_axes: 4,
            ..PlannerConfig::default()
        };
        let p = plan([0.0; MAX_AXES], &moves, &limits, &cfg).unwrap();
        let segs = p.segments();
        // Every chord from 10 mm to 30 mm, the reversal in the middle, runs at the feed.
        for (i, seg) in segs.iter().enumerate() {
            let s = seg.s_start;
            if (10.0..30.0).contains(&s) {
                assert!(
                    (seg.v_entry - feed).abs() <= 1e-9 * feed && (seg.v_peak - feed).abs() <= 1e-9,
                    "{profile:?}: chord {i} at s = {s} mm: {seg:?}"
                );
            }
            let b = corner_accel(&p, i, 2, seg.v_entry);
            assert!(b <= 0.2, "B at {b} rad/s² at s = {s}");
        }
    }
    // The same path with B's rate jumping from −0.05 to +0.05 rad/mm at one junction: that is
    // a genuine corner for B (1 rad/s in one instant at 10 mm/s), and there the speed dips, B
    // being the axis that sets it.
    let jump = |s: f64| [0.0, 8e-4, if s < s0 { -0.05 } else { 0.05 }, 5e-4, 0.0, 0.0];
    let moves = chords(jump, 100, step, feed);
    let cfg = PlannerConfig {
        n_axes: 4,
        ..PlannerConfig::default()
    };
    let p = plan([0.0; MAX_AXES], &moves, &limits, &cfg).unwrap();
    let i = (s0 / step).round() as usize;
    let v = p.segments()[i].v_entry;
    assert!(v < 0.9 * feed, "{v}");
    let share = |k: usize| corner_accel(&p, i, k, v) / limits.a[k];
    assert!((0..4).all(|k| k == 2 || share(k) < share(2)));
}
