//! Seeds 1 and 2 measured from the emitted NC program: every block of `lase emit --dialect
//! linuxcnc` (and of `--dialect grblhal`, the GRBL-protocol controller that drives rotary
//! axes) is read back, the axis words go through the machine's forward kinematics, and the
//! spot, lens and beam are compared with the surface computed independently of lase's
//! resampling — the cam from its motion law in closed form, the arm's section from the spline
//! through the measured points. The three conditions of PROCESS.md §1 and §2 are checked at
//! every lit block: constant standoff (≤ 1 µm), beam along the surface normal (≤ 0.01°),
//! constant surface speed from the G93 inverse-time feeds (within 0.1 %).

mod common;

use common::*;
use lase_runtime::axes::Axes;
use lase_runtime::geometry::{Profile, V2};
use lase_runtime::kinematics::{self, Kinematics};
use lase_runtime::machine::{AxisKind, Machine, parse_machine};
use std::f64::consts::{PI, TAU};

/// One motion block of the program: axis positions after it (internal units: mm, rad), its
/// inverse-time F (1/min) when in G93, and whether the beam is on during it.
#[derive(Debug, Clone)]
struct Block {
    q: Axes,
    prev: Axes,
    inverse_time: Option<f64>,
    lit: bool,
    /// A piece of an unlit block the beam is on in (LinuxCNC's switch ahead of the joints,
    /// [`blocks`]): in tp's parabolic blend, whose speed is the sum of two blocks', not its F.
    blend: bool,
}

fn machine(name: &str) -> Machine {
    parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

/// Reads a LinuxCNC or grblHAL program back into blocks (LinuxCNC: M62/M63 switch the beam at
/// the next motion; grblHAL in laser mode: armed by M3/M4, lit on a G1/G2/G3 block while the
/// S in force is above 0, dark in G0, off after M5).
///
/// The beam as it is at the joints: on LinuxCNC each switch 1.5 servo periods ahead of its
/// block boundary (below); [`nc_blocks`] has the blocks as written.
fn blocks(ngc: &str, m: &Machine) -> Vec<Block> {
    let (out, linuxcnc) = nc_blocks(ngc, m);
    if !linuxcnc {
        return out;
    }

    // LinuxCNC switches a synchronized output as tp takes up its block, 1.5 servo periods
    // ahead of the joints (control.c's cubic interpolator less tp's mean half period,
    // `emit::writer::lead`), so at the joints the beam goes on and off that much before the
    // block boundary the switch sits on: the last lit block of a run is lit up to there, and
    // the tail of the block before a run is lit.
    let lag = 1.5 * m.servo_period_s() / 60.0;
    let mut physical = Vec::with_capacity(out.len() + 8);
    for (i, b) in out.iter().enumerate() {
        let next_lit = out.get(i + 1).is_some_and(|n| n.lit);
        let phi = b.inverse_time.map_or(0.0, |f| (lag * f).min(1.0));
        if b.lit == next_lit || phi <= 0.0 || i + 1 == out.len() {
            physical.push(b.clone());
            continue;
        }
        let f = b.inverse_time.unwrap();
        let mid = b.prev.lerp(&b.q, 1.0 - phi);
        physical.push(Block {
            q: mid,
            inverse_time: Some(f / (1.0 - phi).max(1e-12)),
            ..b.clone()
        });
        physical.push(Block {
            prev: mid,
            inverse_time: Some(f / phi),
            lit: !b.lit,
            blend: !b.lit,
            ..b.clone()
        });
    }
    physical
}

/// The motion blocks as `ngc` writes them (see [`blocks`]), and whether it is a LinuxCNC
/// program (no S words).
fn nc_blocks(ngc: &str, m: &Machine) -> (Vec<Block>, bool) {
    let mut q = Axes::ZERO;
    let mut g93 = false;
    let mut lit = false;
    // grblHAL: the spindle armed, the S in force and whether the motion mode cuts.
    let (mut armed, mut s, mut feed) = (false, None::<f64>, false);
    let mut out = Vec::new();
    for line in ngc.lines() {
        let w = nc_words(line);
        for &(c, v) in &w {
            match (c, v as i32) {
                ('G', 93) => g93 = true,
                ('G', 94) => g93 = false,
                ('M', 62) => lit = true,
                ('M', 63) | ('M', 65) => lit = false,
                ('M', 3) | ('M', 4) => armed = true,
                ('M', 5) => armed = false,
                ('S', _) => s = Some(v),
                ('G', 0) => feed = false,
                ('G', 1..=3) => feed = true,
                _ => {}
            }
        }
        if let Some(s) = s {
            // A grblHAL program (LinuxCNC's has no S words).
            lit = armed && feed && s > 0.0;
        }
        let mut moved = false;
        let prev = q;
        for (k, a) in m.axes.iter().enumerate() {
            let letter = a.name.chars().next().unwrap();
            if let Some(&(_, v)) = w.iter().find(|(c, _)| *c == letter) {
                q[k] = match a.kind {
                    AxisKind::Linear => v,
                    AxisKind::Rotary => v.to_radians(),
                };
                moved = true;
            }
        }
        if moved {
            let f = w.iter().find(|(c, _)| *c == 'F').map(|(_, v)| *v);
            out.push(Block {
                q,
                prev,
                inverse_time: if g93 { f } else { None },
                lit,
                blend: false,
            });
        }
    }
    (out, s.is_none())
}

/// Worst errors over the lit blocks, against a surface given by `foot`: for a spot, the
/// nearest surface point and the outward unit normal there (head side).
struct Worst {
    standoff_um: f64,
    surface_um: f64,
    angle_deg: f64,
    speed_rel: f64,
    lit_blocks: usize,
    /// The worst of the spot's distance from the surface at interior points only, µm.
    interior_um: f64,
    /// The worst surface speed error at interior points only (relative).
    interior_speed_rel: f64,
    /// The spot's distance from the surface (µm) and the beam's angle to the normal (°) where
    /// LinuxCNC's switch ahead of the joints lights the block before a lit run ([`blocks`]).
    switch_um: f64,
    switch_deg: f64,
}

fn measure(
    kin: &dyn Kinematics,
    blocks: &[Block],
    standoff: f64,
    feed_mm_min: f64,
    foot: &dyn Fn([f64; 3]) -> ([f64; 3], [f64; 3]),
) -> Worst {
    let mut w = Worst {
        standoff_um: 0.0,
        surface_um: 0.0,
        angle_deg: 0.0,
        speed_rel: 0.0,
        lit_blocks: 0,
        interior_um: 0.0,
        interior_speed_rel: 0.0,
        switch_um: 0.0,
        switch_deg: 0.0,
    };
    for b in blocks.iter().filter(|b| b.lit) {
        if b.blend {
            // Where the beam is already on in the block before the switch's: the spot at its
            // ends and inside it, and the beam's angle (its speed is tp's blend's, not its F).
            for k in 0..=INTERIOR {
                let q = b.prev.lerp(&b.q, k as f64 / INTERIOR as f64);
                let spot = kin.forward_at(&q, standoff);
                let (f, n) = foot([spot.spot.x, spot.spot.y, spot.spot.z]);
                let d = [spot.spot.x - f[0], spot.spot.y - f[1], spot.spot.z - f[2]];
                let off = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() * 1e3;
                w.switch_um = w.switch_um.max(off);
                let cos = -(spot.beam.x * n[0] + spot.beam.y * n[1] + spot.beam.z * n[2]);
                let deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
                w.switch_deg = w.switch_deg.max(deg);
            }
            continue;
        }
        w.lit_blocks += 1;
        for q in [&b.prev, &b.q] {
            let lens = kin.forward_at(q, 0.0);
            let spot = kin.forward_at(q, standoff);
            let p = [spot.spot.x, spot.spot.y, spot.spot.z];
            let (f, n) = foot(p);
            // The lens is `standoff` out along the normal from the surface point.
            let l = [lens.spot.x - f[0], lens.spot.y - f[1], lens.spot.z - f[2]];
            let dist = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
            w.standoff_um = w.standoff_um.max((dist - standoff).abs() * 1e3);
            let d = [p[0] - f[0], p[1] - f[1], p[2] - f[2]];
            w.surface_um = w
                .surface_um
                .max((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() * 1e3);
            // The beam points into the surface: against the outward normal.
            let beam = spot.beam;
            let cos = -(beam.x * n[0] + beam.y * n[1] + beam.z * n[2]);
            w.angle_deg = w.angle_deg.max(cos.clamp(-1.0, 1.0).acos().to_degrees());
        }
        // Surface speed: the spot's chord over the block time 1/F.
        let f = b.inverse_time.expect("lit blocks are in G93");
        let a = kin.forward_at(&b.prev, standoff).spot;
        let c = kin.forward_at(&b.q, standoff).spot;
        let speed = (c - a).norm() * f;
        w.speed_rel = w.speed_rel.max((speed / feed_mm_min - 1.0).abs());
        // Inside the block the controller runs every axis linearly (issue 13 item 4): the spot
        // at interior points through the forward kinematics, its distance from the surface,
        // and its speed |d spot / dt| (a central difference in the block's fraction, times F).
        for k in 1..INTERIOR {
            let t = k as f64 / INTERIOR as f64;
            let at = |t: f64| kin.forward_at(&b.prev.lerp(&b.q, t), standoff).spot;
            let p = at(t);
            let (foot_p, _) = foot([p.x, p.y, p.z]);
            let d = [p.x - foot_p[0], p.y - foot_p[1], p.z - foot_p[2]];
            let off = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() * 1e3;
            w.surface_um = w.surface_um.max(off);
            w.interior_um = w.interior_um.max(off);
            let h = 1e-4;
            let v = (at(t + h) - at(t - h)).norm() / (2.0 * h) * f;
            let rel = (v / feed_mm_min - 1.0).abs();
            w.interior_speed_rel = w.interior_speed_rel.max(rel);
        }
    }
    w
}

/// Interior points measured per lit block: every sixteenth of it.
const INTERIOR: usize = 16;

/// Prints the worst errors and checks them against issue 3's and issue 13's tolerances, at the
/// poses and at every interior point of every lit block: spot within the recipe's
/// `tolerance_um` of the surface (and the lens within it of the standoff), beam to normal ≤
/// 0.01°, surface speed within 0.1 %, over more than `min_blocks` lit blocks.
fn assert_seed_tolerances(name: &str, w: &Worst, min_blocks: usize, tolerance_um: f64) {
    assert_seed_tolerances_with(name, w, min_blocks, tolerance_um, 1e-3);
}

/// The seed tolerances with the surface speed held to `speed_rel` instead of 0.1 %.
fn assert_seed_tolerances_with(
    name: &str,
    w: &Worst,
    min_blocks: usize,
    tolerance_um: f64,
    speed_rel: f64,
) {
    eprintln!(
        "{name}: {} lit blocks; standoff error {:.4} µm, spot off the surface {:.4} µm \
         (inside blocks {:.4} µm), beam to normal {:.5}°, surface speed over blocks {:.4} %, \
         inside blocks {:.4} %; where the beam comes on ahead of the lit blocks: spot {:.4} µm, \
         beam {:.5}°",
        w.lit_blocks,
        w.standoff_um,
        w.surface_um,
        w.interior_um,
        w.angle_deg,
        w.speed_rel * 100.0,
        w.interior_speed_rel * 100.0,
        w.switch_um,
        w.switch_deg
    );
    assert!(w.lit_blocks > min_blocks, "{}", w.lit_blocks);
    assert!(
        w.standoff_um <= tolerance_um,
        "standoff error {} µm",
        w.standoff_um
    );
    assert!(
        w.surface_um <= tolerance_um,
        "spot {} µm off the surface",
        w.surface_um
    );
    assert!(w.angle_deg <= 0.01, "beam {}° off the normal", w.angle_deg);
    assert!(
        w.speed_rel <= speed_rel,
        "surface speed off by {} over a block",
        w.speed_rel
    );
    // Where LinuxCNC lights the beam ahead of the lit blocks (`blocks`): the beam on the
    // normal there too.
    assert!(
        w.switch_deg <= 0.01,
        "beam {}° off the normal",
        w.switch_deg
    );
    assert!(
        w.interior_speed_rel <= speed_rel,
        "surface speed off by {} inside a block",
        w.interior_speed_rel
    );
}

fn emit(example: &str, dialect: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.nc");
    let (code, _, err) = lase(&[
        "emit",
        "--dialect",
        dialect,
        example,
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    std::fs::read_to_string(out).unwrap()
}

/// The cam of examples/cam_hardening.lase in closed form: r(θ) = 30 + 10·s(u) with the
/// cycloidal law s(u) = u − sin(2πu)/2π, rise 0–120°, top dwell 120–160°, return 160–280°.
fn cam_radius(theta: f64) -> (f64, f64) {
    let deg = theta.rem_euclid(TAU).to_degrees();
    let law = |u: f64| (u - (TAU * u).sin() / TAU, 1.0 - (TAU * u).cos());
    let (lift, dlift_ddeg) = if deg < 120.0 {
        let (s, v) = law(deg / 120.0);
        (10.0 * s, 10.0 * v / 120.0)
    } else if deg < 160.0 {
        (10.0, 0.0)
    } else if deg < 280.0 {
        let (s, v) = law((deg - 160.0) / 120.0);
        (10.0 * (1.0 - s), -10.0 * v / 120.0)
    } else {
        (0.0, 0.0)
    };
    (30.0 + lift, dlift_ddeg * 180.0 / PI)
}

/// The cam of examples/rhai_cam.lase in closed form: r(θ) = 30 + 10·s(u) with the modified
/// sine law of examples/rhai_cam_law.rhai, rise 0–120°, top dwell 120–160°, return 160–280°.
fn rhai_cam_radius(theta: f64) -> (f64, f64) {
    let deg = theta.rem_euclid(TAU).to_degrees();
    let k = 1.0 / (4.0 + PI);
    // (s, ds/du) of the modified sine.
    let law = |u: f64| {
        if u < 0.125 {
            (
                k * (PI * u - 0.25 * (4.0 * PI * u).sin()),
                k * (PI - PI * (4.0 * PI * u).cos()),
            )
        } else if u < 0.875 {
            let w = PI / 3.0 + 4.0 * PI * u / 3.0;
            (
                k * (2.0 + PI * u - 2.25 * w.sin()),
                k * (PI - 3.0 * PI * w.cos()),
            )
        } else {
            (
                k * (4.0 + PI * u - 0.25 * (4.0 * PI * u).sin()),
                k * (PI - PI * (4.0 * PI * u).cos()),
            )
        }
    };
    let (lift, dlift_ddeg) = if deg < 120.0 {
        let (s, v) = law(deg / 120.0);
        (10.0 * s, 10.0 * v / 120.0)
    } else if deg < 160.0 {
        (10.0, 0.0)
    } else if deg < 280.0 {
        let (s, v) = law((deg - 160.0) / 120.0);
        (10.0 * (1.0 - s), -10.0 * v / 120.0)
    } else {
        (0.0, 0.0)
    };
    (30.0 + lift, dlift_ddeg * 180.0 / PI)
}

fn cam_foot(p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    polar_foot(&cam_radius, p)
}

/// The foot of `p` on the counter-clockwise polar contour r(θ) (`radius` gives r and dr/dθ)
/// and the outward unit normal there.
fn polar_foot(radius: &dyn Fn(f64) -> (f64, f64), p: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let cam_radius = radius;
    let point = |t: f64| {
        let (r, _) = cam_radius(t);
        V2::new(r * t.cos(), r * t.sin())
    };
    let target = V2::new(p[0], p[1]);
    // The foot of a point this close to the contour lies within a hundredth of a radian of the
    // point's own polar angle (the contour is star-shaped about the cam centre): golden-section
    // search of the distance in θ there.
    let around = target.y.atan2(target.x);
    let (mut a, mut b) = (around - 0.02, around + 0.02);
    let g = (5f64.sqrt() - 1.0) / 2.0;
    for _ in 0..80 {
        let c = b - g * (b - a);
        let d = a + g * (b - a);
        if (point(c) - target).norm() < (point(d) - target).norm() {
            b = d;
        } else {
            a = c;
        }
    }
    let t = 0.5 * (a + b);
    let (r, dr) = cam_radius(t);
    let f = point(t);
    let tangent = V2::new(dr * t.cos() - r * t.sin(), dr * t.sin() + r * t.cos()).normalize();
    // Counter-clockwise contour: outward is the tangent turned clockwise.
    let n = V2::new(tangent.y, -tangent.x);
    ([f.x, f.y, 0.0], [n.x, n.y, 0.0])
}

/// Where the measured blocks come from: a program `lase emit` writes in a dialect, or what
/// the simulated grblHAL controller executed when `lase run` streamed the job to it over TCP.
#[derive(Clone, Copy)]
enum Source {
    Emitted(&'static str),
    Streamed,
}

impl std::fmt::Display for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Source::Emitted(d) => write!(f, "{d}"),
            Source::Streamed => write!(f, "streamed to grblHAL"),
        }
    }
}

fn blocks_of(example: &str, source: Source, m: &Machine) -> Vec<Block> {
    match source {
        Source::Emitted(dialect) => blocks(&emit(example, dialect), m),
        Source::Streamed => executed_blocks(example, m),
    }
}

/// Streams `example` with `lase run` to a simulated controller for `m` and reads back the
/// blocks it executed: axis positions from the controller's own interpolation (degrees back
/// to radians), the block time it took, the laser power it had.
fn executed_blocks(example: &str, m: &Machine) -> Vec<Block> {
    use lase_runtime::link::sim::{self, SimOptions, TimeScale};
    let sim = sim::serve(
        m,
        "127.0.0.1:0".parse().unwrap(),
        SimOptions {
            time_scale: TimeScale::Max,
            ..SimOptions::default()
        },
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let journal = dir.path().join("job.journal");
    let url = format!("tcp://{}", sim.addr().unwrap());
    let (code, out, err) = lase(&[
        "run",
        example,
        "--link",
        &url,
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("grblHAL"), "{err}");
    assert!(out.contains("done"), "{out}");
    assert!(sim.wait_quiet(std::time::Duration::from_secs(10)));
    let rec = sim.stop();
    let axes = lase_runtime::link::ControllerAxes::of(m);
    let q_of = |p: &[f64; 6]| axes.from_controller(p);
    // The simulator moves as grblHAL's planner does: every `M3`/`M5` empties the planner and
    // stops the machine (CONTROLLERS.md), so the first and last lit blocks of a section ramp
    // from and to rest. Those blocks (entered or left at rest) are counted, not measured; the
    // S-word beam switching of issue 14 removes the stops.
    let cruise =
        |b: &lase_runtime::link::sim::ExecutedBlock| b.entry_mm_s > 0.0 && b.exit_mm_s > 0.0;
    let lit = rec.blocks.iter().filter(|b| b.laser_s > 0.0).count();
    let ramping = rec
        .blocks
        .iter()
        .filter(|b| b.laser_s > 0.0 && !cruise(b))
        .count();
    eprintln!("{example}: {ramping} of {lit} lit blocks ramp at a stop");
    assert!(
        ramping * 20 <= lit,
        "{ramping} of {lit} lit blocks ramp at a stop"
    );
    rec.blocks
        .iter()
        .map(|b| Block {
            q: q_of(&b.to),
            prev: q_of(&b.from),
            // The controller's own block time, as an inverse-time F (1/min).
            inverse_time: Some(60.0 / b.duration),
            lit: b.laser_s > 0.0 && cruise(b),
            blend: false,
        })
        .collect()
}

fn check_cam_hardening(source: Source) {
    let m = machine("cam_xwb");
    let kin = kinematics::for_machine(&m);
    let b = blocks_of("examples/cam_hardening.lase", source, &m);
    let w = measure(&*kin, &b, 12.0, 8.0 * 60.0, &cam_foot);
    // The whole contour is hardened: its length over the mean step.
    // `planner { tolerance 0.5 um }`.
    assert_seed_tolerances(&format!("cam ({source})"), &w, 400, 0.5);
    // The beam comes on 1.5 servo periods ahead of the lit blocks on LinuxCNC: on the lit
    // chord's line in the axes, which the lead-in follows (0.007 µm off the surface).
    assert!(w.switch_um <= 0.5, "{} µm", w.switch_um);
}

/// examples/rhai_cam.lase, whose law is a Rhai function: measured against the modified sine
/// in closed form, at the poses and inside every block.
#[test]
fn rhai_cam_keeps_standoff_normal_and_surface_speed_inside_every_block() {
    let m = machine("cam_xwb");
    let kin = kinematics::for_machine(&m);
    let b = blocks(&emit("examples/rhai_cam.lase", "linuxcnc"), &m);
    let w = measure(&*kin, &b, 12.0, 8.0 * 60.0, &|p| {
        polar_foot(&rhai_cam_radius, p)
    });
    // `planner { tolerance 0.5 um }`.
    assert_seed_tolerances("rhai cam (linuxcnc)", &w, 400, 0.5);
    assert!(w.switch_um <= 0.5, "{} µm", w.switch_um);
}

#[test]
fn cam_hardening_keeps_standoff_normal_and_surface_speed_at_every_block() {
    check_cam_hardening(Source::Emitted("linuxcnc"));
}

#[test]
fn cam_hardening_on_grblhal_keeps_standoff_normal_and_surface_speed_at_every_block() {
    check_cam_hardening(Source::Emitted("grblhal"));
}

/// `lase run` to the simulated grblHAL: the motion the controller executed keeps the three
/// conditions, its block times giving the surface speed.
#[test]
fn cam_hardening_streamed_live_keeps_standoff_normal_and_surface_speed() {
    check_cam_hardening(Source::Streamed);
}

/// The measured section of examples/surface_hardening_arm.lase and the spline through it.
fn arm_section() -> Profile {
    let pts = [
        (-60.0, 0.0),
        (-40.0, 6.0),
        (-20.0, 14.0),
        (0.0, 11.0),
        (20.0, 3.0),
        (40.0, 4.0),
        (60.0, 12.0),
    ]
    .map(|(x, y)| V2::new(x, y));
    Profile::interpolate(&pts, false).unwrap()
}

/// The foot on an open section in the plane (the slide's z kept) and the head-side normal
/// (+y of the section, left of travel in +x), for measuring the arm's blocks.
fn section_foot(section: &Profile) -> impl Fn([f64; 3]) -> ([f64; 3], [f64; 3]) + '_ {
    let len = section.length();
    let n = 4000;
    let table: Vec<(f64, V2)> = (0..=n)
        .map(|k| {
            let s = len * k as f64 / n as f64;
            (s, section.point_at(s))
        })
        .collect();
    // Newton on (P(s) − p)·T(s) = 0 from `s`; the arc length and how far p is from P there.
    let newton = move |mut s: f64, target: V2| {
        for _ in 0..20 {
            let f = section.frame_at(s);
            let d = f.point - target;
            let g = d.dot(&f.tangent);
            let dg = 1.0 + d.dot(&f.left) * f.curvature;
            s = (s - g / dg).clamp(0.0, len);
            if g.abs() < 1e-12 {
                break;
            }
        }
        (s, (section.point_at(s) - target).norm())
    };
    // The foot of the last point measured: consecutive points are close, so Newton from there
    // converges in a step or two; the table search is the fallback.
    let hint = std::cell::Cell::new(f64::NAN);
    move |p: [f64; 3]| {
        let target = V2::new(p[0], p[1]);
        let near = Some(hint.get())
            .filter(|h| h.is_finite())
            .map(|h| newton(h, target))
            .filter(|(_, d)| *d < 0.05);
        let (s, _) = near.unwrap_or_else(|| {
            let mut best = (f64::INFINITY, 0.0);
            for (s, q) in &table {
                let d = (q - target).norm();
                if d < best.0 {
                    best = (d, *s);
                }
            }
            newton(best.1, target)
        });
        hint.set(s);
        let f = section.frame_at(s);
        // Past an end of the section (a lead, where LinuxCNC's switch lights the beam ahead of
        // the joints) the part's surface runs on along its tangent: the foot on that line, so
        // the distance is how far the spot is off the surface, not how far past its end.
        let along = if s <= 0.0 || s >= len {
            (target - f.point).dot(&f.tangent)
        } else {
            0.0
        };
        let q = f.point + f.tangent * along;
        // The head stands on +y of the section (left of travel in +x).
        ([q.x, q.y, p[2]], [f.left.x, f.left.y, 0.0])
    }
}

fn check_arm_hardening(source: Source) {
    check_arm_hardening_with(source, 1e-3);
}

fn check_arm_hardening_with(source: Source, speed_rel: f64) {
    let m = machine("arm_3r");
    let kin = kinematics::for_machine(&m);
    let b = blocks_of("examples/surface_hardening_arm.lase", source, &m);
    let section = arm_section();
    let foot = section_foot(&section);
    // 3.5 mm/s: under the 3.57 mm/s LinuxCNC's parabolic blends hold on its shortest blocks.
    let w = measure(&*kin, &b, 15.0, 3.5 * 60.0, &foot);
    // Six sections of about 130 mm at 0.5 mm steps.
    // `planner { tolerance 1 um }`.
    assert_seed_tolerances_with(&format!("arm ({source})"), &w, 6 * 250, 1.0, speed_rel);
    // LinuxCNC lights the beam 1.5 servo periods ahead of the arm's first lit block, in its
    // lead-in, which runs on the surface's tangent (0.004 µm off it; measured to the section's
    // end it read 5.25 µm, the 1.5 ms of travel at 3.5 mm/s before the section starts: the
    // arm's switches are not carried, its blends last 2 ms, `emit::writer::lead::carries`).
    assert!(w.switch_um <= 1.0, "{} µm", w.switch_um);
    // The slide steps 2 mm between sections: the lit blocks sit at z = 0, 2, …, 10 mm.
    let mut zs: Vec<i64> = b
        .iter()
        .filter(|b| b.lit)
        .map(|b| (b.q[0] * 1e3).round() as i64)
        .collect();
    zs.dedup();
    zs.sort();
    zs.dedup();
    assert_eq!(zs, vec![0, 2000, 4000, 6000, 8000, 10000]);
}

/// Issue 13 item 4 as a property: random sections of the arm's kind (five to seven measured
/// points 20–30 mm apart, heights up to 16 mm, so up to four inflections), each followed at
/// `planner { tolerance 1 um }` and measured from the NC program inside every block. A section
/// the rules refuse (its valley tighter than the standoff, or out of reach) is skipped and
/// counted; most must be measured.
#[test]
fn random_sections_stay_on_the_surface_and_at_speed_inside_every_block() {
    let m = machine("arm_3r");
    let kin = kinematics::for_machine(&m);
    let dir = tempfile::tempdir().unwrap();
    // xorshift64*: the cases are the same on every run.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut measured, mut refused) = (0, 0);
    for case in 0..6 {
        let n = 5 + (rnd() * 3.0) as usize;
        let pitch = 20.0 + 10.0 * rnd();
        let pts: Vec<V2> = (0..n)
            .map(|i| V2::new(pitch * (i as f64 - 0.5 * (n - 1) as f64), 16.0 * rnd()))
            .collect();
        let list: Vec<String> = pts
            .iter()
            .map(|p| format!("({:.3} mm, {:.3} mm)", p.x, p.y))
            .collect();
        let recipe = dir.path().join(format!("s{case}.lase"));
        std::fs::write(
            &recipe,
            format!(
                "machine arm_3r\nplanner {{ ramp scurve, tolerance 1 um }}\n\
                 let s = profile spline [{}]\n\
                 laser {{ power 1 kW, standoff 15 mm }}\n\
                 follow s at 2.5 mm/s {{ side left, step 0.5 mm }}\n",
                list.join(", ")
            ),
        )
        .unwrap();
        let out = dir.path().join(format!("s{case}.ngc"));
        let (code, _, err) = lase(&[
            "emit",
            "--dialect",
            "linuxcnc",
            recipe.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        if code != 0 {
            eprintln!("case {case} refused: {err}");
            assert!(
                err.contains("folds over")
                    || err.contains("cannot reach")
                    || err.contains("cannot hold"),
                "{err}"
            );
            refused += 1;
            continue;
        }
        // The measured surface: the same spline through the same (rounded) points.
        let rounded: Vec<V2> = pts
            .iter()
            .map(|p| V2::new((p.x * 1e3).round() / 1e3, (p.y * 1e3).round() / 1e3))
            .collect();
        let section = Profile::interpolate(&rounded, false).unwrap();
        let b = blocks(&std::fs::read_to_string(out).unwrap(), &m);
        let w = measure(&*kin, &b, 15.0, 150.0, &section_foot(&section));
        assert_seed_tolerances(&format!("random section {case}"), &w, 100, 1.0);
        // As the arm example's: on the surface's tangent where the beam comes on early.
        assert!(w.switch_um <= 1.0, "{} µm", w.switch_um);
        measured += 1;
    }
    eprintln!("{measured} random sections measured, {refused} refused by the rules");
    assert!(measured >= 4, "{measured} measured, {refused} refused");
}

#[test]
fn arm_hardening_keeps_standoff_normal_and_surface_speed_at_every_block() {
    check_arm_hardening(Source::Emitted("linuxcnc"));
}

#[test]
fn arm_hardening_on_grblhal_keeps_standoff_normal_and_surface_speed_at_every_block() {
    check_arm_hardening(Source::Emitted("grblhal"));
}

/// Streamed to the simulated grblHAL, whose planner (GRBL's, modelled) ramps between the
/// arm's G93 blocks where their axis-space speeds differ: the surface speed is measured off on
/// blocks away from any stop, where lase's own plan holds 0.1 %. That is a finding for issue 13
/// (the plan must be what the controller does), not a tolerance lase claims. It was 0.13 % with
/// 0.5 mm steps; since the steps are chosen so the spot stays true between poses (issue 13 item
/// 4: 3 360 lit blocks instead of 1 516, down to 0.054 mm) the modelled grblHAL loses 0.37 %:
/// every junction costs it a ramp (0.41 % at interior points). This test keeps it from growing
/// (0.42 %) while standoff and beam normal hold as everywhere; the controller time model is to
/// predict it.
#[test]
fn arm_hardening_streamed_live_keeps_standoff_normal_and_surface_speed() {
    check_arm_hardening_with(Source::Streamed, 4.2e-3);
}

#[test]
fn linuxcnc_accepts_both_oriented_programs() {
    if std::process::Command::new("rs274")
        .arg("--help")
        .output()
        .is_err()
    {
        eprintln!("rs274 not installed; .ci/run installs it");
        return;
    }
    for ex in [
        "examples/cam_hardening.lase",
        "examples/surface_hardening_arm.lase",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.ngc");
        std::fs::write(&path, emit(ex, "linuxcnc")).unwrap();
        let out = rs274_g(&path).unwrap();
        let text = String::from_utf8_lossy(&out.stdout).to_string()
            + String::from_utf8_lossy(&out.stderr).as_ref();
        assert!(out.status.success(), "{ex}: {text}");
        assert!(!text.contains("error"), "{ex}: {text}");
    }
}

#[test]
fn grbl_refuses_rotary_machines_with_a_diagnostic() {
    let (code, _, err) = lase(&["emit", "--dialect", "grbl", "examples/cam_hardening.lase"]);
    assert_ne!(code, 0);
    assert!(err.contains("rotary"), "{err}");
}

/// PROCESS.md §1's discrete method (`normals chord`) against exact normals on the same cam, at
/// the paper's kind of step (2 mm): measured from the NC program the same way, the chord
/// method's beam is visibly off the normal where exact normals are not.
#[test]
fn seed1_chord_normals_are_measurably_worse_than_exact_ones() {
    let m = machine("cam_xwb");
    let kin = kinematics::for_machine(&m);
    let dir = tempfile::tempdir().unwrap();
    let mut worst = Vec::new();
    for normals in ["exact", "chord"] {
        let recipe = dir.path().join(format!("{normals}.lase"));
        std::fs::write(
            &recipe,
            format!(
                "machine cam_xwb\n\
                 planner {{ leadin none }}\n\
                 let cam = profile cam(base: 30 mm, lift: 10 mm, rise: 120 deg, top: 40 deg, \
                 fall: 120 deg, law: \"cycloidal\")\n\
                 laser {{ power 1.2 kW, standoff 12 mm }}\n\
                 follow cam at 8 mm/s {{ step 2 mm, normals {normals} }}\n"
            ),
        )
        .unwrap();
        let out = dir.path().join(format!("{normals}.ngc"));
        let (code, _, err) = lase(&[
            "emit",
            "--dialect",
            "linuxcnc",
            recipe.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let ngc = std::fs::read_to_string(out).unwrap();
        let w = measure(&*kin, &blocks(&ngc, &m), 12.0, 480.0, &cam_foot);
        eprintln!(
            "normals {normals}, 2 mm step: beam to normal {:.5}°, spot off the surface {:.3} µm",
            w.angle_deg, w.surface_um
        );
        worst.push((w.angle_deg, w.surface_um));
    }
    let (exact, chord) = (worst[0], worst[1]);
    assert!(exact.0 <= 0.01 && exact.1 <= 1.0, "{exact:?}");
    // The bisector tilts with the change of curvature along the chord, and the midpoint sits
    // inside the curve by about h²/(8R) (h is the step after the chord tolerance shortened
    // it): the spot leaves the 1 µm standoff tolerance that exact normals keep.
    assert!(chord.0 > 10.0 * exact.0.max(1e-4), "{chord:?} vs {exact:?}");
    assert!(chord.1 > 1.0, "midpoints {} µm off the surface", chord.1);
}

/// Runs `lase plan --trace` on `example`, checks that every 1 ms sample with the beam on is at
/// `feed` mm/s (within 0.1 %), and returns how many there were and the plan's output.
fn lit_only_at(example: &str, feed: f64) -> (usize, String) {
    let dir = tempfile::tempdir().unwrap();
    let trace = dir.path().join("t.csv");
    let (code, out, err) = lase(&["plan", example, "--trace", trace.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(trace).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (v, laser) = (col("v"), col("laser"));
    let mut lit = 0;
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        if f[laser] == "1" {
            lit += 1;
            let speed: f64 = f[v].parse().unwrap();
            assert!(
                (speed / feed - 1.0).abs() <= 1e-3,
                "{example}: lit at {speed} mm/s: {l}"
            );
        }
    }
    (lit, out)
}

/// The planned cam track is lit only at the programmed surface speed: the lead-in and lead-out
/// continue the lit chords' axis-space direction, so there is no corner at the lit ends
/// (measured from `lase plan --trace`, every 1 ms sample with the beam on).
#[test]
fn cam_track_is_lit_only_at_the_programmed_speed() {
    let (lit, _) = lit_only_at("examples/cam_hardening.lase", 8.0);
    // 218 mm of track at 8 mm/s: about 27 300 samples.
    assert!(lit > 27_000, "{lit}");
}

/// The planned arm sections are lit only at the programmed 3.5 mm/s, measured from
/// `lase plan --trace` (every 1 ms sample with the beam on). The joints reverse on the way (C
/// near x ≈ −36 mm at tiny rates): the planner judges corners per axis against the joints' own
/// accelerations, so that costs no speed, and the 758 mm of lit track take exactly 216.6 s.
#[test]
fn arm_sections_are_lit_only_at_the_programmed_speed() {
    let (lit, out) = lit_only_at("examples/surface_hardening_arm.lase", 3.5);
    // 758.27 mm of lit track at 3.5 mm/s: about 216 600 samples, and the summary's laser-on
    // time is the lit length over the feed.
    assert!(lit > 216_000, "{lit}");
    let on = out
        .lines()
        .find_map(|l| l.trim().strip_prefix("laser on"))
        .unwrap_or_else(|| panic!("{out}"));
    let nums: Vec<f64> = on
        .split([',', ' '])
        .filter_map(|w| w.parse().ok())
        .collect();
    let (length, time) = (nums[0], nums[1]);
    assert!((time - length / 3.5).abs() <= 1e-3, "{on}");
}

/// Issue 13 item 5: the harmonic law's acceleration jumps at the ends of the rise and the
/// return, where the beam's turning rate steps. At 8 mm/s the plan cannot hold the surface
/// speed there; `lase check` says so at the `follow`, naming the stretch and the highest speed
/// the plan holds, and a recipe that follows at that speed is held: every 1 ms sample with the
/// beam on is at it (`lase plan --trace`).
#[test]
fn a_surface_speed_the_plan_cannot_hold_is_refused_with_the_speed_it_can() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = |feed: &str| {
        let path = dir
            .path()
            .join(format!("harmonic_{}.lase", feed.replace(['/', ' '], "_")));
        std::fs::write(
            &path,
            format!(
                "machine cam_xwb\nplanner {{ tolerance 0.5 um }}\n\
                 let cam = profile cam(base: 20 mm, lift: 10 mm, rise: 60 deg, top: 60 deg, \
                 fall: 60 deg, law: \"harmonic\")\n\
                 laser {{ power 1.2 kW, standoff 12 mm }}\n\
                 follow cam at {feed} {{ step 0.5 mm }}\n"
            ),
        )
        .unwrap();
        path
    };
    let fast = recipe("8 mm/s");
    let (code, _, err) = lase(&["check", fast.to_str().unwrap()]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("lase::plan::speed_not_held"), "{err}");
    assert!(err.contains("cannot hold 8 mm/s"), "{err}");
    // The help's "follow at X mm/s or slower" (miette may wrap the line after "at").
    let offered = |err: &str| -> f64 {
        err.split("follow at")
            .nth(1)
            .map(|t| {
                t.trim_start()
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.')
                    .collect::<String>()
            })
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{err}"))
    };
    let held = offered(&err);
    eprintln!("harmonic cam: 8 mm/s refused, {held} mm/s offered");
    assert!(held > 0.5 && held < 8.0, "{held}");
    // The plan alone holds 6.3 mm/s; the cam's controller, LinuxCNC, holds less on the
    // shortest blocks (`motion::parabolic`), and the offer is the lower of the two, so that a
    // recipe that follows at it is not refused again.
    assert!(err.contains("LinuxCNC's parabolic blends"), "{err}");
    let slow = recipe(&format!("{held} mm/s"));
    let (code, _, err) = lase(&["check", slow.to_str().unwrap()]);
    assert_eq!(code, 0, "{held} mm/s: {err}");
    let (lit, _) = lit_only_at(slow.to_str().unwrap(), held);
    assert!(lit > 1000, "{lit}");
    // Where the law's acceleration jumps the beam stays on the law's normal (it left it by up
    // to 0.08° when the cam was a B-spline through samples), and the spot on its surface.
    let m = machine("cam_xwb");
    let kin = kinematics::for_machine(&m);
    let b = blocks(&emit(slow.to_str().unwrap(), "linuxcnc"), &m);
    let w = measure(&*kin, &b, 12.0, held * 60.0, &|p| {
        polar_foot(&harmonic_cam_radius, p)
    });
    eprintln!(
        "harmonic cam (linuxcnc): {} lit blocks; spot off the surface {:.4} µm, beam to normal \
         {:.5}°, surface speed over blocks {:.4} %, inside blocks {:.4} %",
        w.lit_blocks,
        w.surface_um,
        w.angle_deg,
        w.speed_rel * 100.0,
        w.interior_speed_rel * 100.0
    );
    assert!(w.lit_blocks > 300, "{}", w.lit_blocks);
    assert!(
        w.surface_um <= 0.5,
        "spot {} µm off the surface",
        w.surface_um
    );
    assert!(w.angle_deg <= 0.01, "beam {}° off the normal", w.angle_deg);
    // Where LinuxCNC lights the beam ahead of the joints: its switches read where the joints
    // are (`blocks`), the beam leaves the normal by no more there. Read at the NC's block ends
    // instead, the lead-out's carried switch (1.5 periods on) counted a pose on the lead-out as
    // lit: 0.039° off the normal, where the joints are past the beam-off.
    assert!(w.switch_deg <= 0.01, "{}°", w.switch_deg);
    assert!(w.switch_um <= 0.5, "{} µm", w.switch_um);
    assert!(w.speed_rel <= 1e-3, "surface speed off by {}", w.speed_rel);
    // Inside the shortest blocks too (near the 16 mm concave radius, where the steps were
    // halved most): the speed measured 0.108 % when X was written to 0.1 µm, whose rounding
    // on a block a few hundredths of a mm long, whose time G93 fixes, added to the 0.085 %
    // ripple budget of the step choice; inverse-time programs now write linear axes to 1 nm.
    assert!(
        w.interior_speed_rel <= 1e-3,
        "surface speed inside blocks off by {}",
        w.interior_speed_rel
    );
}

#[path = "../runtime/tests/support/harmonic_cam.rs"]
mod harmonic_cam;
use harmonic_cam::radius as harmonic_cam_radius;

/// The shortest lit G93 block of `ngc` against its triangle time on LinuxCNC: each block's
/// time (60 / F) over `sqrt(2·max_i |Δq_i| / a_i)` rounded up to the 1 ms servo period, the
/// shortest a parabolic blend carries at speed (tp.c `tpComputeBlendVelocity`; the real
/// LinuxCNC ran the arm's 5.4 ms blocks in 15 ms). Read from the NC alone.
fn shortest_lit_block_share(ngc: &str, m: &Machine) -> f64 {
    nc_blocks(ngc, m)
        .0
        .iter()
        .filter(|b| b.lit)
        .filter_map(|b| {
            let t = 60.0 / b.inverse_time?;
            let t_a = m
                .axes
                .iter()
                .enumerate()
                .map(|(k, a)| (b.q[k] - b.prev[k]).abs() / a.a_max)
                .fold(0.0, f64::max);
            let triangle = (2.0 * t_a).sqrt();
            (t_a > 0.0).then(|| t / ((triangle * 1e3 * (1.0 - 1e-9)).ceil() * 1e-3))
        })
        .fold(f64::INFINITY, f64::min)
}

/// The arm at its first recipe's 10 mm/s: its bends need blocks shorter than LinuxCNC's
/// parabolic blends carry (36 % of the speed there), so `lase check` refuses it at the
/// `follow` with the speed LinuxCNC holds, and at that speed every lit block of the NC
/// program is at least its triangle time; the example's 3.5 mm/s too.
#[test]
fn the_arm_at_a_speed_linuxcnc_cannot_hold_is_refused_with_the_speed_it_can() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string("examples/surface_hardening_arm.lase").unwrap();
    let at = |feed: &str| {
        let path = dir
            .path()
            .join(format!("arm_{}.lase", feed.replace(['/', ' '], "_")));
        std::fs::write(&path, example.replace("at 3.5 mm/s", &format!("at {feed}"))).unwrap();
        path
    };
    let fast = at("10 mm/s");
    let (code, _, err) = lase(&["check", fast.to_str().unwrap()]);
    assert_ne!(code, 0, "{err}");
    assert!(err.contains("lase::plan::speed_not_held"), "{err}");
    assert!(err.contains("LinuxCNC runs its blocks at"), "{err}");
    let held: f64 = err
        .split("follow at")
        .nth(1)
        .and_then(|t| {
            t.trim_start()
                .chars()
                .take_while(|c| c.is_ascii_digit() || *c == '.')
                .collect::<String>()
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("{err}"));
    eprintln!("arm: 10 mm/s refused, {held} mm/s offered");
    assert!((3.0..4.0).contains(&held), "{held}");
    // That rule is LinuxCNC's planner's: a program for grblHAL is planned for grblHAL
    // (`Machine::run_on`), not refused by LinuxCNC's rule. Before, `--dialect grblhal`
    // refused the 10 mm/s recipe with LinuxCNC's message too.
    let (code, _, err) = lase(&["check", "--dialect", "grblhal", fast.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let ngc = dir.path().join("arm_grblhal.nc");
    let (code, _, err) = lase(&[
        "emit",
        "--dialect",
        "grblhal",
        fast.to_str().unwrap(),
        "-o",
        ngc.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    // Its lit blocks are then as short as lase's own plan makes them: under the triangle
    // time LinuxCNC would need, which is what the LinuxCNC rule refused.
    let share =
        shortest_lit_block_share(&std::fs::read_to_string(&ngc).unwrap(), &machine("arm_3r"));
    eprintln!(
        "arm at 10 mm/s for grblHAL: shortest lit block {share:.4} of LinuxCNC's triangle time"
    );
    assert!(share < 0.9, "{share}");
    // The REPL streams to a GRBL-family link, so its `:check FILE` judges as `:run FILE` runs.
    let mut repl = std::process::Command::new(env!("CARGO_BIN_EXE_lase"))
        .arg("repl")
        .env("NO_COLOR", "1")
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let script = format!(":check {}\n", fast.display());
    std::io::Write::write_all(&mut repl.stdin.take().unwrap(), script.as_bytes()).unwrap();
    let out = repl.wait_with_output().unwrap();
    let (said, err) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(said.contains(": ok — "), "{said}\n{err}");
    assert!(!err.contains("speed_not_held"), "{err}");
    let m = machine("arm_3r");
    for (feed, path) in [
        (held, at(&format!("{held} mm/s"))),
        (3.5, "examples/surface_hardening_arm.lase".into()),
    ] {
        let share = shortest_lit_block_share(&emit(path.to_str().unwrap(), "linuxcnc"), &m);
        eprintln!("arm at {feed} mm/s: shortest lit block {share:.4} of its triangle time");
        assert!(share >= 1.0 - 1e-3, "{feed} mm/s: {share}");
    }
}
