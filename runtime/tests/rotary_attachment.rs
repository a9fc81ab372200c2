//! A rotary attachment on a flat bed (issue 20), measured from the NC programs lase writes for
//! `examples/rotary_engrave.lase` (a 60 mm tube in a chuck on A): every block's axes, read back
//! from the text and mapped onto the surface by the attachment's own formula (written here,
//! not lase's), land on the programmed points; and every feed block's surface length over its
//! time (G93: 60 / F seconds) is the programmed surface speed within 0.1 %. The drive formulas
//! (chuck, roller, a Y-substituted axis) are checked against hand-computed numbers.

use lase_runtime::compile::{self, FsFiles};
use lase_runtime::emit::{self, Dialect, EmitOptions, NcLine};
use lase_runtime::kinematics::{self, ToolPose};
use lase_runtime::machine::parse_machine;
use lase_runtime::motion::{Job, power};
use lase_runtime::program::OpKind;
use std::f64::consts::PI;
use std::path::Path;

/// The example's object: radius 30 mm.
const R: f64 = 30.0;

fn example() -> Job {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/rotary_engrave.lase");
    let (_, job) = compile::compile(&mut FsFiles, path.to_str().unwrap())
        .unwrap_or_else(|(_, f)| panic!("{f}"));
    job
}

fn lines(job: &Job, dialect: Dialect) -> Vec<NcLine> {
    emit::emit_lines(job, dialect, &EmitOptions::default())
        .unwrap()
        .0
}

/// One motion block as the controller reads it: where it ends (X mm, A deg), its motion word
/// and F, the inverse-time mode in force, and the op lase wrote it for.
#[derive(Debug, Clone)]
struct Block {
    g: u32,
    x: f64,
    a: f64,
    f: Option<f64>,
    g93: bool,
    op: Option<u32>,
}

fn word(text: &str, letter: char) -> Option<f64> {
    text.split_whitespace()
        .find_map(|w| w.strip_prefix(letter).and_then(|v| v.parse().ok()))
}

/// The modal walk over the NC text: G0/G1 and G93/G94 stay in force, X and A keep their last
/// value (the machine starts at X0 A0, the example's start).
fn blocks(lines: &[NcLine]) -> Vec<Block> {
    let (mut g, mut x, mut a, mut g93) = (0, 0.0, 0.0, false);
    let mut out = Vec::new();
    for l in lines {
        let t = l
            .text
            .trim_start_matches(|c: char| c == 'N' || c.is_ascii_digit())
            .trim();
        if t.starts_with('(') {
            continue;
        }
        for w in t.split_whitespace() {
            match w {
                "G93" => g93 = true,
                "G94" => g93 = false,
                "G0" | "G00" => g = 0,
                "G1" | "G01" => g = 1,
                _ => {}
            }
        }
        let (nx, na) = (word(t, 'X'), word(t, 'A'));
        if nx.is_none() && na.is_none() {
            continue;
        }
        assert!(
            !t.contains("G2") && !t.contains("G3"),
            "no arc on a rotary: {t}"
        );
        x = nx.unwrap_or(x);
        a = na.unwrap_or(a);
        out.push(Block {
            g,
            x,
            a,
            f: word(t, 'F'),
            g93,
            op: l.op,
        });
    }
    out
}

/// Where the next op after `i` that moves goes, on the surface.
fn next_target(job: &Job, i: usize) -> Option<[f64; 2]> {
    let ops = &job.program.ops;
    let to = ops[i].target()?;
    ops[i + 1..]
        .iter()
        .find(|o| o.moves_from(to))
        .and_then(|o| o.target())
        .map(|t| [t[0], t[1]])
}

/// How far `p` lies from the segment `a`–`b`.
fn off_line(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let n2 = dx * dx + dy * dy;
    let t = if n2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / n2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// The chuck's map from axes to the surface, from the machine's geometry alone: y = A · r.
fn surface(b: &Block) -> [f64; 2] {
    [b.x, b.a.to_radians() * R]
}

#[test]
fn every_block_lands_on_the_programmed_surface_point() {
    let job = example();
    for dialect in [Dialect::LinuxCnc, Dialect::GrblHal, Dialect::Iso] {
        let bs = blocks(&lines(&job, dialect));
        assert!(bs.len() > 50, "{dialect}: {} blocks", bs.len());
        let mut checked = 0;
        for (k, b) in bs.iter().enumerate() {
            // The last block an op writes ends at the op's target.
            let last = bs.get(k + 1).is_none_or(|n| n.op != b.op);
            let Some(op) = b.op.map(|i| &job.program.ops[i as usize]) else {
                continue;
            };
            let (Some(to), true) = (op.target(), last) else {
                continue;
            };
            let p = surface(b);
            let err = ((p[0] - to[0]).powi(2) + (p[1] - to[1]).powi(2)).sqrt();
            // X is written to 1 µm, A to 1e-6° (0.5 nm of surface at r = 30 mm). On LinuxCNC
            // a block that ends at a flying beam switch runs on past it along the next op by
            // 1.5 servo periods of the edge speed (at most 60 mm/s here: 0.09 mm), where tp
            // switches (`emit::writer::lead::shift`), ±½ period where the off-edge is timed by
            // tp.c's replay (`emit::writer::block::off_edge_timing`): on the programmed path
            // still.
            let on_path = dialect == Dialect::LinuxCnc
                && err <= 2.0e-3 * 60.0 + 1e-3
                && next_target(&job, b.op.unwrap() as usize)
                    .is_some_and(|n| off_line(p, [to[0], to[1]], n) < 1e-3);
            assert!(
                err < 1e-3 || on_path,
                "{dialect}: block {k} at {p:?}, op wants {to:?}"
            );
            checked += 1;
        }
        assert!(checked > 50, "{dialect}: {checked} blocks checked");
        // The rings: the tube turned once, a lit line of pi * 60 mm ending at A360 (its
        // lead-out runs on past it); on LinuxCNC its block runs 1.5 ms of 114.6 °/s on, ±½ ms
        // (`emit::writer::block::off_edge_timing`).
        let (lo, hi) = if dialect == Dialect::LinuxCnc {
            let ms = (60.0 / R).to_degrees() * 1e-3;
            (360.0 + ms, 360.0 + 2.0 * ms)
        } else {
            (360.0, 360.0)
        };
        assert!(
            bs.iter()
                .any(|b| b.a > lo - 1e-4 && b.a < hi + 1e-4 && b.g == 1),
            "{dialect}: no block ends at A{lo}..A{hi}"
        );
    }
}

#[test]
fn surface_speed_from_the_nc_is_the_programmed_one_within_a_tenth_of_a_percent() {
    let job = example();
    for dialect in [Dialect::LinuxCnc, Dialect::GrblHal, Dialect::Iso] {
        let bs = blocks(&lines(&job, dialect));
        let mut worst: f64 = 0.0;
        let mut n = 0;
        for w in bs.windows(2) {
            let (from, b) = (&w[0], &w[1]);
            if b.g != 1 {
                continue;
            }
            let op = &job.program.ops[b.op.expect("a feed block has its op") as usize];
            let OpKind::Line { feed_mm_s, .. } = op.kind else {
                panic!("{dialect}: feed block of a {:?}", op.kind);
            };
            assert!(
                b.g93,
                "{dialect}: feed moves on a rotary are in inverse time"
            );
            let (p, q) = (surface(from), surface(b));
            let len = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
            if len < 0.05 {
                // A block shorter than 50 µm: its F (7 digits) and X (1 µm) round by more.
                continue;
            }
            let f = b.f.expect("G93 blocks carry F");
            let seconds = 60.0 / f;
            let v = len / seconds;
            // The speed the block is programmed at: the feed, or where lase's plan holds a lit
            // move below it (a blended lit corner of a glyph) the plan's mean speed over the
            // move, and for the unlit move into such a lit start the plan's speed where the
            // beam comes on (`motion::power::lit_blocks`, emit's held blocks).
            let i = b.op.unwrap() as usize;
            let segs = &job.plan.segments()[power::op_segments(&job, i)];
            let held = segs.iter().map(|s| s.length).sum::<f64>()
                / segs.iter().map(|s| s.motion_duration()).sum::<f64>();
            let lead = segs.last().map_or(feed_mm_s, |s| s.v_exit);
            // On LinuxCNC a lead-in whose junction with the lit block moved into it runs up to
            // three times the mean gain of tp's parabolic blend slower, A·T/2 with A half the
            // path acceleration canon gives the block (`emit::writer::lead::lead_in_speed`,
            // `blend_gain`): X at 2000 mm/s², A at 3600 °/s² (r 30 mm), T 1 ms.
            let (dx, da) = ((b.x - from.x).abs(), (b.a - from.a).abs().to_radians() * R);
            let a_path = [(dx, 2000.0), (da, 3600f64.to_radians() * R)]
                .iter()
                .filter(|(d, _)| *d > 1e-12)
                .map(|(d, a)| a * len / d)
                .fold(f64::INFINITY, f64::min);
            let gain = a_path * 1e-3 / 4.0;
            let lead_in = op.laser().is_none();
            let trimmed = if lead_in && v <= feed_mm_s && v >= feed_mm_s - 3.0 * gain - 1e-6 {
                v
            } else {
                feed_mm_s
            };
            let wants: &[f64] = if dialect.is_grbl_family() {
                &[feed_mm_s]
            } else {
                &[feed_mm_s, held, lead, trimmed]
            };
            let mut err = wants
                .iter()
                .map(|want| (v / want - 1.0).abs())
                .fold(f64::INFINITY, f64::min);
            // On LinuxCNC a lit move the plan slows in (out of a corner) is written in
            // sub-blocks at the plan's mean speed over each, as long as tp.c's parabolic
            // blends carry them (`power::merge_short`): each between the slowest the plan is
            // there and the feed.
            let several = bs.iter().filter(|x| x.op == b.op && x.g == 1).count() > 1;
            if dialect == Dialect::LinuxCnc && several && op.laser().is_some() {
                let slowest = segs
                    .iter()
                    .map(|s| s.v_entry.min(s.v_exit))
                    .fold(f64::INFINITY, f64::min);
                if v >= slowest * (1.0 - 1e-3) && v <= feed_mm_s * (1.0 + 1e-3) {
                    err = 0.0;
                }
            }
            worst = worst.max(err);
            n += 1;
        }
        assert!(n > 50, "{dialect}: {n} feed blocks");
        assert!(
            worst < 1e-3,
            "{dialect}: worst surface-speed error {worst:.2e}"
        );
        eprintln!("{dialect}: {n} feed blocks, worst surface-speed error {worst:.2e}");
    }
}

#[test]
fn grbl_refuses_the_a_axis_and_the_circle_is_chords_on_its_radius() {
    let job = example();
    assert!(emit::emit_lines(&job, Dialect::Grbl, &EmitOptions::default()).is_err());
    // The circle (center (0, 120), radius 10) became chords whose ends lie on it.
    let bs = blocks(&lines(&job, Dialect::LinuxCnc));
    let on_circle: Vec<f64> = bs
        .iter()
        .filter(|b| b.g == 1)
        .map(|b| {
            let p = surface(b);
            (p[0].powi(2) + (p[1] - 120.0).powi(2)).sqrt()
        })
        .filter(|d| (d - 10.0).abs() < 0.01)
        .collect();
    assert!(on_circle.len() > 100, "{} chord ends", on_circle.len());
    for d in on_circle {
        assert!((d - 10.0).abs() < 2e-3, "chord end {d} mm from the centre");
    }
}

/// A machine file with the given `[rotary]` table and turning axis.
fn machine(rotary: &str, turning: &str) -> lase_runtime::machine::Machine {
    let text = format!(
        "name = \"r\"\nkinematics = \"rotary\"\n[rotary]\n{rotary}\n\
         [[axes]]\nname = \"X\"\nkind = \"linear\"\npart_axis = \"x\"\n\
         travel = [\"-100 mm\", \"100 mm\"]\nv_max = \"100 mm/s\"\na_max = \"1 m/s^2\"\nj_max = \"10 m/s^3\"\n\
         [[axes]]\n{turning}\ntravel = [\"-36000 deg\", \"36000 deg\"]\nv_max = \"100 mm/s\"\na_max = \"1 m/s^2\"\nj_max = \"10 m/s^3\"\n\
         [laser]\nmax_power = \"10 W\"\nmax_pulse_rate = \"1 kHz\"\n[post.linuxcnc]\nlaser_on = [\"M3\"]\nlaser_off = [\"M5\"]\n"
    );
    let text = if turning.contains("linear") {
        text.replace(
            "[\"-36000 deg\", \"36000 deg\"]",
            "[\"-9000 mm\", \"9000 mm\"]",
        )
    } else {
        text.replace(
            "v_max = \"100 mm/s\"\na_max = \"1 m/s^2\"\nj_max = \"10 m/s^3\"\n[laser]",
            "v_max = \"360 deg/s\"\na_max = \"3600 deg/s^2\"\nj_max = \"36000 deg/s^3\"\n[laser]",
        )
    };
    parse_machine(&text, 0).unwrap_or_else(|e| panic!("{e:?}\n{text}"))
}

/// The turning axis's value for a point `y` mm around the surface.
fn turn(m: &lase_runtime::machine::Machine, y: f64) -> f64 {
    let k = kinematics::for_machine(m);
    let q = k.inverse(&ToolPose::down([5.0, y, 0.0]), None).unwrap();
    assert_eq!(q[0], 5.0, "X is the surface's x");
    let back = k.forward(&q).spot;
    assert!((back.y - y).abs() < 1e-9, "forward undoes inverse");
    q[1]
}

#[test]
fn chuck_roller_and_y_substitution_turn_by_their_own_diameters() {
    let rotary_a = "name = \"A\"\nkind = \"rotary\"";
    // Chuck, 60 mm object: one circumference (pi * 60) is one turn.
    let chuck = machine(
        "drive = \"chuck\"\naxis = \"A\"\ndiameter = \"60 mm\"",
        rotary_a,
    );
    assert!((turn(&chuck, PI * 60.0) - 2.0 * PI).abs() < 1e-12);
    // Roller of 30 mm under an object of 80 mm: the surface moves as far as the roller's, so
    // pi * 30 mm of surface is one roller turn, whatever the object.
    let roller = machine(
        "drive = \"roller\"\naxis = \"A\"\ndiameter = \"80 mm\"\nroller_diameter = \"30 mm\"",
        rotary_a,
    );
    assert!((turn(&roller, PI * 30.0) - 2.0 * PI).abs() < 1e-12);
    // A chuck on the Y driver, 40 mm of "Y" per chuck turn, 60 mm object: Y = y · 40 / (pi·60).
    let on_y = machine(
        "drive = \"chuck\"\naxis = \"Y\"\ndiameter = \"60 mm\"\nmm_per_rev = \"40 mm\"",
        "name = \"Y\"\nkind = \"linear\"",
    );
    assert!((turn(&on_y, PI * 60.0) - 40.0).abs() < 1e-12);
    assert!((turn(&on_y, 10.0) - 10.0 * 40.0 / (PI * 60.0)).abs() < 1e-12);
}

#[test]
fn a_rotary_table_that_does_not_fit_is_refused_with_its_span() {
    for (rotary, want) in [
        (
            "drive = \"belt\"\naxis = \"A\"\ndiameter = \"60 mm\"",
            "unknown rotary drive",
        ),
        (
            "drive = \"chuck\"\naxis = \"B\"\ndiameter = \"60 mm\"",
            "not one of the machine's axes",
        ),
        (
            "drive = \"roller\"\naxis = \"A\"\ndiameter = \"60 mm\"",
            "needs `roller_diameter`",
        ),
        (
            "drive = \"chuck\"\naxis = \"A\"\ndiameter = \"0 mm\"",
            "greater than zero",
        ),
    ] {
        let text = format!(
            "name = \"r\"\nkinematics = \"rotary\"\n[rotary]\n{rotary}\n\
             [[axes]]\nname = \"A\"\nkind = \"rotary\"\ntravel = [\"-1 deg\", \"1 deg\"]\n\
             v_max = \"1 deg/s\"\na_max = \"1 deg/s^2\"\nj_max = \"1 deg/s^3\"\n\
             [laser]\nmax_power = \"10 W\"\nmax_pulse_rate = \"1 kHz\"\n[post.linuxcnc]\nlaser_on = [\"M3\"]\nlaser_off = [\"M5\"]\n"
        );
        let e = parse_machine(&text, 0).unwrap_err();
        let shown = format!("{e}");
        assert!(shown.contains(want), "{rotary}: {shown}");
        let span = e.span();
        assert!(
            span.end > span.start && (span.end as usize) <= text.len(),
            "{e:?}"
        );
    }
}

/// LinuxCNC joins blocks that turn A only by parabolic blends (tp.c), which run at a block's
/// speed only if it lasts its triangle time `sqrt(2 · t_a)`, `t_a = max(|ΔX| / 2000 mm/s²,
/// |ΔA| / 3600 °/s²)` (the machine file's accelerations), and switch a synchronized output in
/// the middle of the blend (`tpDoParabolicBlending`). Measured from the LinuxCNC program of
/// the rotary example: every beam switch (`M62`/`M63 P0`) on such a junction sits between two
/// feed blocks that each last at least their triangle time and a servo period more (before:
/// the rings' lead-ins ran 5.13° in 44.8 ms where their triangle time is 53.4 ms, and
/// LinuxCNC crossed the edge at 96.8 of 114.6 °/s); a lead-out is two feed blocks before the
/// rapid after it (one ending in STOP ramps at twice the lit block's acceleration); and the
/// rings switch 1.5 servo periods of 114.6 °/s past their planned edges A0 and A360, where
/// the blend's middle puts tp's switch ahead of the joints (`emit::writer::lead::shift`).
#[test]
fn linuxcnc_switches_sit_in_parabolic_blends_that_carry_the_speed() {
    let job = example();
    let ls = lines(&job, Dialect::LinuxCnc);
    let bs = blocks(&ls);
    // Each beam switch: on or off, and how many motion blocks come before it.
    let mut switches = Vec::new();
    let mut n = 0;
    for l in &ls {
        let t = l.text.trim();
        if word(t, 'X').is_some() || word(t, 'A').is_some() {
            n += 1;
        } else if t == "M62 P0" || t == "M63 P0" {
            switches.push((t == "M62 P0", n));
        }
    }
    assert_eq!(switches.len(), 24, "{switches:?}");
    let period = job.program.machine.servo_period_s();
    assert_eq!(period, 0.001);
    // A feed block's time and its triangle time, s.
    let times = |from: &Block, b: &Block| -> Option<(f64, f64)> {
        let (dx, da) = ((b.x - from.x).abs(), (b.a - from.a).abs());
        let t_a = (dx / 2000.0).max(da / 3600.0);
        (b.g == 1 && da > 1e-9).then(|| (60.0 / b.f.unwrap(), (2.0 * t_a).sqrt()))
    };
    let mut parabolic = 0;
    let mut worst = f64::INFINITY;
    for &(on, k) in &switches {
        let (before, after) = ((&bs[k - 2], &bs[k - 1]), (&bs[k - 1], &bs[k]));
        let turns = (after.1.a - after.0.a).abs() > 1e-9 || (before.1.a - before.0.a).abs() > 1e-9;
        if !turns {
            continue;
        }
        parabolic += 1;
        // The lead: a servo period over its triangle time (the margin `motion::leadin`
        // keeps is two periods of travel, on a longer lead). The lit block: its triangle time
        // rounded up to the servo period, `lase check`'s rule (`motion::parabolic`).
        let (lead, lit) = if on { (before, after) } else { (after, before) };
        for (_, b) in [lead, lit] {
            assert_eq!(b.g, 1, "switch {on} after block {k}: {b:?}");
        }
        if let Some((t, tri)) = times(lead.0, lead.1) {
            if on {
                worst = worst.min(t - tri);
                assert!(
                    t - tri >= period,
                    "lead at switch {on} after block {k}: {t} s, {tri} s"
                );
            } else {
                // A lead-out's first block is as long as a block whose triangle speed is the
                // lit speed less k of the blend's mean gain A·T/2: k = 1 (`lead::split_at`),
                // or, where tp.c's replay times the off-edge, 0 to 3
                // (`emit::writer::block::off_edge_timing`). With A = L / tri² and its speed
                // L / t, that is t · (1 + k · T / (2 · tri)) = tri.
                let gains = (tri / t - 1.0) * 2.0 * tri / period;
                assert!(
                    (-1e-3..=3.001).contains(&gains),
                    "lead-out at switch after block {k}: {t} s, {tri} s ({gains} gains)"
                );
            }
        }
        if let Some((t, tri)) = times(lit.0, lit.1) {
            let shortest = (tri / period - 1e-9).ceil() * period;
            assert!(
                t >= shortest - 1e-9,
                "lit at switch {on} after block {k}: {t} s, {tri} s"
            );
        }
        if !on {
            // The lead-out: two feed blocks, then the rapid.
            assert_eq!(bs[k + 1].g, 1, "lead-out after block {k}: {:?}", bs[k + 1]);
        }
    }
    // The rings, the A strokes of the glyphs and the circle; X-only strokes meet their leads
    // tangentially.
    assert_eq!(parabolic, 15);
    eprintln!("{parabolic} switches on parabolic blends, least lead slack {worst:.4} s");
    // The rings: on at A0 and off at A360, carried 1.5 ms of 114.59 °/s (60 mm/s at r 30);
    // the off-edge's junction timed by tp.c's replay within ±½ ms of that
    // (`emit::writer::block::off_edge_timing`).
    let ms = period * (60.0 / R).to_degrees();
    let ring: Vec<f64> = switches.iter().take(4).map(|&(_, k)| bs[k - 1].a).collect();
    for (k, (a, want)) in ring.iter().zip([0.0, 360.0, 0.0, 360.0]).enumerate() {
        let carried = (a - want) / ms;
        let ok = if k % 2 == 0 {
            (carried - 1.5).abs() < 1e-4
        } else {
            (1.0 - 1e-4..=2.0 + 1e-4).contains(&carried)
        };
        assert!(ok, "{ring:?}: switch {k} carried {carried} ms");
    }
}
