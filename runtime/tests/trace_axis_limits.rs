//! Per-axis limits of every plan, measured from the 1 kHz trace's positions
//! (`common::axis_limits`): each axis's velocity, acceleration and (S-curve) jerk recomputed
//! by finite differences, against that axis's limits (issue 13, item 3).
//!
//! Corners taken at speed follow a planned blend (`planner::Blend`) — rapids, unlit feeds,
//! leads, every junction between them and the lit paths, and the lit corners too (a lit
//! polyline's corners, the chords of a lit arc or of a cam's lit section: the blend's own
//! limits slow the path there as much as every axis needs, on a flat bed; on an oriented
//! machine the plan must hold the lit speed) — and must stay within every limit at every
//! sample (1e-6 relative), on every example and on random paths on every stock machine. What
//! is left: where blending an oriented machine's lit chords would lower the lit speed below
//! the programmed one (`lase::plan::speed_not_held`: the arm's sections at 10 mm/s, whose runs
//! of chords share their curvature but break where the chord refinement halves the chords),
//! the plan is made again with the junction-deviation velocity step at those corners (at
//! 6 mm/s the arm's section needs none: `the_arm_section_at_6_mm_s_…`). [`WORST`] pins the
//! examples that have such corners (none since the arm example follows at 3.5 mm/s, what
//! LinuxCNC's parabolic blends hold), each at its measured worst, so they can only get better;
//! the random paths are checked everywhere but within 4 ms of such a corner.

mod common;

use common::examples;

use common::axis_limits::{AxisWorst, worst_per_axis, worst_per_axis_outside};
use lase_runtime::compile::{self, FsFiles, MemFiles};
use lase_runtime::motion::Job;
use lase_runtime::planner::{self, AxisLimits, Corners, MAX_AXES, PlannerConfig, ProfileKind};
use proptest::prelude::*;
use std::path::Path;

/// Relative slack of "within the limit": finite differences of exact positions.
const REL: f64 = 1e-6;

fn report(name: &str, w: &AxisWorst) -> String {
    let j = w.j.map_or(String::from("-"), |j| {
        format!(
            "{:.4} ({:.0}/{:.0} {}/s³ at {:.3} s, op {})",
            j.ratio, j.value, j.limit, w.unit, j.t, j.tag
        )
    });
    format!(
        "{name} {}: v {:.4} ({:.2}/{:.1} {u}/s at {:.3} s, op {}); a {:.4} ({:.1}/{:.1} {u}/s² \
         at {:.3} s, op {}); j {j}",
        w.axis,
        w.v.ratio,
        w.v.value,
        w.v.limit,
        w.v.t,
        w.v.tag,
        w.a.ratio,
        w.a.value,
        w.a.limit,
        w.a.t,
        w.a.tag,
        u = w.unit
    )
}

/// Measured worst |v|/v_max, |a|/a_max, |j|/j_max at 1 kHz of the examples whose lit paths
/// have corners between two lit moves taken at speed with the velocity step (module doc: the
/// lit chords of the arm, until it followed at 3.5 mm/s), rounded up in the fourth digit;
/// every other example
/// and axis, and every sample away from those corners, is held to 1. Measured with `cargo
/// test -p lase-runtime --test trace_axis_limits -- --nocapture`, which prints each example's
/// row. Each peak lies at a lit chord corner, an acceleration step only: a is within its
/// limits, j is not. Before the blends the same table also held every rapid↔feed junction: up
/// to a/a_max 26.9 (cam X), 12.6 (arm X), 9.5 (arm A), 3.4 (codes, image_engrave,
/// texture_array); before the flat beds' lit corners were blended, their velocity steps: a/a_max
/// 2.14 (air_assist), 4.90 (material_test), 2.50 (nested_parts), 6.03 (serial_number), 6.16
/// (rotary_engrave), and j/j_max 18.3 (dial_marks), 38.2 (frame_marking); before the cams'
/// lit chords were blended, j/j_max 4.54 (cam_hardening B), 7.64 (rhai_cam B); before the arm
/// example followed at 3.5 mm/s, the speed LinuxCNC's parabolic blends hold on its blocks
/// (`motion::parabolic`), j/j_max 23.67 (A), 22.48 (B), 46.01 (C) at its stepped lit corners:
/// at 3.5 mm/s the blends hold its lit speed and every axis is within every limit, so no
/// example is pinned any more.
const WORST: &[(&str, &str, f64, f64, f64)] = &[];

/// Job times of the corners between two lit moves taken at speed, which keep the
/// junction-deviation velocity step (module doc), sorted.
fn stepped_lit_corners(job: &Job) -> Vec<f64> {
    let p = &job.plan;
    let segs = p.segments();
    let lit = |i: usize| job.program.ops[segs[i].tag as usize].laser().is_some();
    (1..segs.len())
        .filter(|&i| {
            let (u, w) = (p.direction(i - 1), p.direction(i));
            p.blend_of(i - 1).is_none()
                && p.blend_of(i).is_none()
                && segs[i - 1].v_exit > 0.0
                && lit(i - 1)
                && lit(i)
                && (0..6).any(|k| (u[k] - w[k]).abs() > 1e-12)
        })
        .map(|i| job.initial_dwell_s + segs[i].t_start)
        .collect()
}

/// The limit violations of `job` (the worst per axis of `worst`), one line each, against
/// `bound(axis)` = (v, a, j) ratios.
fn violations_of(
    name: &str,
    worst: &[AxisWorst],
    bound: impl Fn(&str) -> (f64, f64, f64),
) -> Vec<String> {
    let mut out = Vec::new();
    for w in worst {
        let line = report(name, w);
        eprintln!("{line}");
        let (v, a, j) = bound(&w.axis);
        for (what, ratio, max) in [
            ("velocity", Some(w.v.ratio), v),
            ("acceleration", Some(w.a.ratio), a),
            ("jerk", w.j.map(|j| j.ratio), j),
        ] {
            if ratio.is_some_and(|r| r > max * (1.0 + REL)) {
                out.push(format!("{what}: {line}"));
            }
        }
    }
    out
}

/// The limit violations of `job` at any sample, one line each.
fn violations(name: &str, job: &Job) -> Vec<String> {
    violations_of(name, &worst_per_axis(job, 1e-3), |_| (1.0, 1.0, 1.0))
}

#[test]
fn every_example_stays_within_every_axis_limit_at_1_khz() {
    let mut bad = Vec::new();
    let mut seen = 0;
    for ex in examples() {
        let name = ex.file_stem().unwrap().to_string_lossy().into_owned();
        let (_, job) = compile::compile(&mut FsFiles, ex.to_str().unwrap())
            .unwrap_or_else(|(_, f)| panic!("{f}"));
        let worst = worst_per_axis(&job, 1e-3);
        for w in &worst {
            let up = |x: f64| ((x * 1e4 * (1.0 - 1e-12)).ceil() / 1e4).max(1.0);
            eprintln!(
                "    (\"{name}\", \"{}\", {:.4}, {:.4}, {:.4}),",
                w.axis,
                up(w.v.ratio),
                up(w.a.ratio),
                w.j.map_or(1.0, |j| up(j.ratio))
            );
        }
        bad.extend(violations_of(&name, &worst, |axis| {
            WORST
                .iter()
                .find(|(e, a, ..)| *e == name && *a == axis)
                .map_or((1.0, 1.0, 1.0), |&(_, _, v, a, j)| (v, a, j))
        }));
        // Outside its lit corners every example is within every limit.
        let skip = stepped_lit_corners(&job);
        bad.extend(violations_of(
            &name,
            &worst_per_axis_outside(&job, 1e-3, &skip),
            |_| (1.0, 1.0, 1.0),
        ));
        seen += 1;
    }
    assert!(bad.is_empty(), "over the limits:\n{}", bad.join("\n"));
    assert_eq!(seen, 15, "examples");
}

/// The checker itself: a plan with no junctions at speed (the notcher switches its beam at
/// rest, so every corner is a stop) is within every limit at every sample, and a plain 90°
/// corner taken at speed shows the velocity step junction deviation allows: `v·|Δu|` within
/// one sample, on each axis.
#[test]
fn the_checker_finds_no_violation_where_there_is_none_and_the_corner_step_where_there_is() {
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/conrod_notch.lase");
    let (_, job) =
        compile::compile(&mut FsFiles, ex.to_str().unwrap()).unwrap_or_else(|(_, f)| panic!("{f}"));
    for w in worst_per_axis(&job, 1e-3) {
        let line = report("conrod_notch", &w);
        assert!(w.v.ratio <= 1.0 + REL, "{line}");
        assert!(w.a.ratio <= 1.0 + REL, "{line}");
        assert!(w.j.is_some_and(|j| j.ratio <= 1.0 + REL), "{line}");
    }

    // An unlit 90° corner at 20 mm/s: the plan rounds it within the corner tolerance and takes
    // it at speed, within every limit; planned instead by junction deviation (GRBL's model, a
    // velocity step per axis), the checker sees X stop and Y start within one sample.
    let mut job = common::job(
        "machine xy_table\nplanner { ramp trapezoid }\n\
         move to (20 mm, 0) at 20 mm/s\nmove to (20 mm, 20 mm) at 20 mm/s\n",
    );
    assert!(violations("corner", &job).is_empty());
    let blend = job.plan.blends().get(0).expect("the corner is blended");
    assert!((blend.corner[0] - 20.0).abs() < 1e-9 && blend.corner[1].abs() < 1e-9);
    let corner_v = (0..job.plan.segments().len())
        .filter(|&i| job.plan.blend_of(i).is_some())
        .map(|i| job.plan.segments()[i].v_exit)
        .fold(f64::INFINITY, f64::min);
    assert!(corner_v > 1.0, "taken at {corner_v} mm/s");
    let mut limits = AxisLimits {
        v: [f64::INFINITY; MAX_AXES],
        a: [f64::INFINITY; MAX_AXES],
        j: [f64::INFINITY; MAX_AXES],
    };
    for (i, l) in job.program.limits.iter().enumerate() {
        (limits.v[i], limits.a[i], limits.j[i]) = (l.v, l.a, l.j);
    }
    let cfg = PlannerConfig {
        profile: ProfileKind::Trapezoid,
        junction_deviation: job.program.planner.junction_deviation_mm,
        n_axes: 2,
        corners: Corners::JunctionDeviation,
        ..PlannerConfig::default()
    };
    // The same two moves, as `motion` lowers them (the job keeps no move list).
    let moves: Vec<planner::Move> = (0..job.op_axes.len())
        .map(|i| {
            let from = if i == 0 {
                job.start
            } else {
                job.op_axes.get(i - 1)
            };
            let to = job.op_axes.get(i);
            planner::Move {
                target: to,
                length: (0..2)
                    .map(|k| (to[k] - from[k]).powi(2))
                    .sum::<f64>()
                    .sqrt(),
                feed: 20.0,
                stop_after: false,
                dwell_after: 0.0,
                tag: i as u32,
            }
        })
        .filter(|m| m.length > 0.0)
        .collect();
    assert_eq!(moves.len(), 2);
    job.plan = planner::plan(job.start, &moves, &limits, &cfg).unwrap();
    let corner = job
        .plan
        .segments()
        .windows(2)
        .find(|s| s[0].v_exit > 1.0 && s[0].length > 10.0 && s[1].length > 10.0)
        .expect("the corner is taken at speed");
    let v = corner[0].v_exit;
    let worst = worst_per_axis(&job, 1e-3);
    for w in &worst {
        // X stops and Y starts at v within one sample: a step of v in 1 ms.
        assert!(
            w.a.value >= 0.5 * v / 1e-3 && w.a.value <= 1.01 * v / 1e-3 + w.a.limit,
            "{} at the corner ({v} mm/s): {:?}",
            w.axis,
            w.a
        );
    }
}

/// One random piece of a flat-bed path: a rapid, an unlit feed, a lit polyline or a lit arc.
fn flat_piece(kind: u8, p: &[(f64, f64)], f: f64, r: f64, a0: f64, sweep: f64) -> String {
    let pt = |&(x, y): &(f64, f64)| format!("({x:.3} mm, {y:.3} mm)");
    match kind % 4 {
        0 => format!("move to {} rapid\n", pt(&p[0])),
        1 => format!("move to {} at {f:.1} mm/s\n", pt(&p[0])),
        2 => format!(
            "follow profile polyline [{}] at {f:.1} mm/s\n",
            p.iter().map(pt).collect::<Vec<_>>().join(", ")
        ),
        _ => format!(
            "follow profile arc(center: {}, radius: {r:.2} mm, start: {a0:.1} deg, end: {:.1} deg) \
             at {f:.1} mm/s\n",
            pt(&p[0]),
            a0 + sweep
        ),
    }
}

/// A random recipe on `machine`: flat beds mix rapids, feeds, polylines and arcs; the notcher
/// its X/Z moves with the beam switched at rest; `cam_xwb` a cam law and `arm_3r` spline
/// sections fed along X, each with rapids between the oriented sections.
fn recipe() -> impl Strategy<Value = (String, String)> {
    let ramp = prop_oneof![Just("scurve"), Just("trapezoid")];
    let corner = prop_oneof![Just(0.005), Just(0.01), Just(0.05)];
    let piece = (
        any::<u8>(),
        prop::collection::vec((-60.0..60.0f64, -50.0..50.0f64), 1..5),
        2.0..120.0f64,
        1.0..25.0f64,
        -180.0..180.0f64,
        prop_oneof![-300.0..-10.0f64, 10.0..300.0f64],
    );
    let flat = (
        prop_oneof![Just("xy_table"), Just("xyz")],
        ramp.clone(),
        corner.clone(),
        prop::collection::vec(piece, 1..7),
    )
        .prop_map(|(m, ramp, corner, pieces)| {
            // xyz's travel is X 0..600, Y 0..400: shift the part into it.
            let shift = if m == "xyz" { (200.0, 150.0) } else { (0.0, 0.0) };
            let mut src = format!(
                "machine {m}\nplanner {{ ramp {ramp}, corner {corner} mm }}\nlaser {{ power 10 W }}\n"
            );
            for (kind, pts, f, r, a0, sweep) in pieces {
                let pts: Vec<_> = pts.iter().map(|(x, y)| (x + shift.0, y + shift.1)).collect();
                src.push_str(&flat_piece(kind, &pts, f, r, a0, sweep));
            }
            (m.to_string(), src)
        });
    let notcher = (
        ramp.clone(),
        prop::collection::vec(
            (10.0..190.0f64, -55.0..-1.0f64, 5.0..90.0f64, any::<bool>()),
            1..6,
        ),
    )
        .prop_map(|(ramp, moves)| {
            let mut src =
                format!("machine notcher\nplanner {{ ramp {ramp} }}\nlaser {{ power 300 W }}\n");
            for (x, z, f, lit) in moves {
                src.push_str(if lit { "laser on\n" } else { "laser off\n" });
                src.push_str(&format!(
                    "move to ({x:.3} mm, 0, {z:.3} mm) at {f:.1} mm/s\n"
                ));
            }
            src.push_str("laser off\n");
            ("notcher".to_string(), src)
        });
    let cam = (
        ramp.clone(),
        corner.clone(),
        25.0..40.0f64,
        2.0..10.0f64,
        prop_oneof![Just("cycloidal"), Just("345"), Just("modified_trapezoid")],
        1..3usize,
        3.0..10.0f64,
    )
        .prop_map(|(ramp, corner, base, lift, law, passes, v)| {
            let mut src = format!(
                "machine cam_xwb\nplanner {{ ramp {ramp}, corner {corner} mm, tolerance 1 um }}\n\
                 let cam = profile cam(base: {base:.2} mm, lift: {lift:.2} mm, rise: 120 deg, \
                 top: 40 deg, fall: 120 deg, law: \"{law}\")\n\
                 laser {{ power 1 kW, spot 4 mm, standoff 12 mm }}\n"
            );
            for _ in 0..passes {
                src.push_str(&format!("follow cam at {v:.1} mm/s {{ step 1 mm }}\n"));
            }
            ("cam_xwb".to_string(), src)
        });
    let arm = (
        ramp,
        corner,
        prop::collection::vec(0.0..12.0f64, 5),
        1..3usize,
        4.0..12.0f64,
    )
        .prop_map(|(ramp, corner, ys, sections, v)| {
            let pts: Vec<String> = ys
                .iter()
                .enumerate()
                .map(|(i, y)| format!("({} mm, {y:.2} mm)", -60 + 30 * i as i32))
                .collect();
            let mut src = format!(
                "machine arm_3r\nplanner {{ ramp {ramp}, corner {corner} mm, tolerance 2 um }}\n\
                 let section = profile spline [{}]\n\
                 laser {{ power 1 kW, spot 3 mm, standoff 15 mm }}\n",
                pts.join(", ")
            );
            for k in 0..sections {
                let (path, side) = if k % 2 == 0 {
                    ("section", "left")
                } else {
                    ("reverse(section)", "right")
                };
                src.push_str(&format!(
                    "follow {path} at {v:.1} mm/s {{ side {side}, step 1 mm }}\n"
                ));
                src.push_str("move by (0, 0, 2 mm) rapid\n");
            }
            ("arm_3r".to_string(), src)
        });
    prop_oneof![flat, notcher, cam, arm]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, max_global_rejects: 4096, ..ProptestConfig::default() })]

    /// Random paths on every stock machine: a recipe the pipeline accepts plans within every
    /// axis limit at every 1 kHz sample. (Recipes it refuses — a lead-in outside the travel, a
    /// spline section the arm cannot reach — are not plans; they are skipped.)
    #[test]
    fn random_paths_on_every_machine_stay_within_every_axis_limit((machine, src) in recipe()) {
        let mut files = MemFiles::new([("test.lase", src.as_str())]);
        let job = compile::compile(&mut files, "test.lase");
        prop_assume!(job.is_ok());
        let (_, job) = job.unwrap();
        let skip = stepped_lit_corners(&job);
        let worst = worst_per_axis_outside(&job, 1e-3, &skip);
        let bad = violations_of(&machine, &worst, |_| (1.0, 1.0, 1.0));
        prop_assert!(bad.is_empty(), "{src}\nover the limits:\n{}", bad.join("\n"));
    }
}

/// The arm example's section at `feed` mm/s (its own tolerance, one pass and back).
fn arm_section(feed: f64) -> String {
    let src = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/surface_hardening_arm.lase"),
    )
    .unwrap();
    src.replace("let sections = 6", "let sections = 2")
        .replace("at 10 mm/s", &format!("at {feed} mm/s"))
}

/// Every blended corner whose blend shares its curvature (a lit chord run of an oriented
/// machine) passes its corner within the corner tolerance δ in part space, measured through
/// the forward kinematics (`blend.rs` bounds it to first order from the spot's part-space
/// directions); returns how many such corners and the worst distance over δ.
fn shared_corners_within_tolerance(job: &Job, standoff: f64) -> (usize, f64) {
    let p = &job.plan;
    let delta = job.program.planner.junction_deviation_mm;
    let (mut count, mut worst) = (0, 0.0f64);
    for (i, s) in p.segments().iter().enumerate() {
        // The half after its corner starts at the corner's σ = 0.
        let Some((b, true)) = p.blend_of(i) else {
            continue;
        };
        if b.shared == 0 {
            continue;
        }
        let at = p.sample(s.t_start).pos;
        let spot = job.kin.forward_at(&at, standoff).spot;
        let corner = job.kin.forward_at(&b.corner, standoff).spot;
        worst = worst.max((spot - corner).norm() / delta);
        count += 1;
    }
    (count, worst)
}

/// The arm's section at 6 mm/s: its lit chord runs share their curvature (part-space bound,
/// `blend.rs` "Runs of chords"), so the plan holds the programmed speed with every lit corner
/// blended — no velocity step — and every axis stays within its velocity, acceleration and
/// jerk; each shared blend passes within δ of its corner, through the forward kinematics.
/// (At the example's 10 mm/s the runs break where the chord refinement halves the chords:
/// there the blend of a 0.05 mm chord cannot bend from zero within the jerk limits, and the
/// plan keeps the velocity step — `WORST`.)
#[test]
fn the_arm_section_at_6_mm_s_holds_its_speed_with_blended_lit_chords() {
    let src = arm_section(6.0);
    let mut files = MemFiles::new([("arm.lase", src.as_str())]);
    let (_, job) = compile::compile(&mut files, "arm.lase").unwrap_or_else(|(_, f)| panic!("{f}"));
    assert!(
        stepped_lit_corners(&job).is_empty(),
        "no stepped lit corner"
    );
    let bad = violations("arm at 6 mm/s", &job);
    assert!(bad.is_empty(), "over the limits:\n{}", bad.join("\n"));
    let (count, worst) = shared_corners_within_tolerance(&job, 15.0);
    eprintln!("arm at 6 mm/s: {count} shared blends, worst spot deviation {worst:.4} δ");
    assert!(count > 100, "{count} blends share their curvature");
    assert!(
        worst <= 1.0,
        "a shared blend passes {worst} δ from its corner"
    );
}

/// rotary_engrave's lit glyph curves are chord runs on an oriented machine (mm and rad): their
/// blends share the curvature and pass within δ of their corners on the surface.
#[test]
fn rotary_engrave_shares_curvature_within_the_corner_tolerance() {
    let ex = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rotary_engrave.lase");
    let (_, job) =
        compile::compile(&mut FsFiles, ex.to_str().unwrap()).unwrap_or_else(|(_, f)| panic!("{f}"));
    let (count, worst) = shared_corners_within_tolerance(&job, 0.0);
    eprintln!("rotary_engrave: {count} shared blends, worst spot deviation {worst:.4} δ");
    assert!(count > 0);
    assert!(worst <= 1.0 + 1e-9, "{worst} δ");
}
