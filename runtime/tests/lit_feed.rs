//! The controller runs what lase plans where the beam is lit (issue 13 item 3): where lase's
//! plan holds a lit move below its feed (a blended lit corner, an arc's chords under the
//! S-curve jerk limit), the LinuxCNC and ISO programs cut it into sub-blocks whose `F` is the
//! plan's mean speed over each (`motion::power::PowerBlock::v_cap`). Measured here from the
//! emitted NC text against the plan over each block's stretch of path: the block's feed is
//! the plan's mean speed there, so the controller takes at least the plan's time over it and
//! the energy per mm it delivers is never below what the plan (and the power coupled to it)
//! assume; where the plan holds the feed, the block keeps the programmed `F`.

mod common;

use common::{job, time_at};
use lase_runtime::emit::{Dialect, EmitOptions, emit_lines};
use lase_runtime::motion::{Job, power};

/// A rectangle with sharp lit corners, taken well below the feed by their blends.
const RECT: &str = "machine xy_table
laser { power 40 W }
let part = profile polyline [(0, 0), (30 mm, 0), (30 mm, 10 mm), (0, 10 mm)] closed
follow part at 20 mm/s
move to (0, -20 mm) rapid
";

/// A lit move of one block: (op, feed mm/s, start, end) in part x/y.
struct Block {
    op: u32,
    feed: f64,
    from: [f64; 2],
    to: [f64; 2],
}

/// Every straight feed block of a lit op of a LinuxCNC or ISO program, with its modal feed.
/// A block the writer cut only to carry a beam switch along it (LinuxCNC's outputs lead its
/// joints: `emit::writer::lead`) is one block here: its two parts run at one F.
fn lit_lines(j: &Job, dialect: Dialect) -> Vec<Block> {
    let (lines, _) = emit_lines(j, dialect, &EmitOptions::default()).unwrap();
    let mut out: Vec<Block> = Vec::new();
    let (mut feed, mut pos, mut g) = (0.0, [0.0f64; 2], "G0");
    let mut switched = false;
    for l in &lines {
        let words: Vec<&str> = l.text.split(' ').filter(|w| !w.starts_with('N')).collect();
        let num = |p: char| {
            words
                .iter()
                .find(|w| w.starts_with(p))
                .and_then(|w| w[1..].parse::<f64>().ok())
        };
        if matches!(words.first().copied(), Some("M62" | "M63" | "M67")) {
            switched = true;
        }
        let lit =
            l.op.is_some_and(|i| j.program.ops[i as usize].laser().is_some());
        for w in &words {
            if matches!(*w, "G0" | "G1" | "G2" | "G3") {
                g = w;
            }
        }
        if let Some(f) = num('F') {
            feed = f / 60.0;
        }
        let (x, y) = (num('X'), num('Y'));
        if words.first() == Some(&"G4") || (x.is_none() && y.is_none()) {
            continue;
        }
        let to = [x.unwrap_or(pos[0]), y.unwrap_or(pos[1])];
        if lit && g == "G1" {
            let op = l.op.unwrap();
            match out.last_mut() {
                Some(b) if switched && b.op == op && b.feed == feed && b.to == pos => b.to = to,
                _ => out.push(Block {
                    op,
                    feed,
                    from: pos,
                    to,
                }),
            }
        }
        switched = false;
        pos = to;
    }
    out
}

/// NC coordinates are written to 0.1 µm: a block's ends on the plan's path are known to half
/// that.
const ROUNDING_MM: f64 = 0.5e-4;

/// (the plan's mean speed over the block, the largest error of that mean from the rounding of
/// the block's ends, its highest speed, the op's programmed feed), the block located on its
/// op's planned path by its distance from the op's start.
fn planned_over(j: &Job, b: &Block, op_start: [f64; 2]) -> (f64, f64, f64, f64) {
    let d = |p: [f64; 2]| ((p[0] - op_start[0]).powi(2) + (p[1] - op_start[1]).powi(2)).sqrt();
    let range = power::op_segments(j, b.op as usize);
    let seg = &j.plan.segments()[range.start];
    let (sa, sb) = (seg.s_start + d(b.from), seg.s_start + d(b.to));
    let (ta, tb) = (time_at(j, sa, true), time_at(j, sb, false));
    let v: Vec<f64> = (0..=200)
        .map(|i| j.plan.sample(ta + (tb - ta) * i as f64 / 200.0).v)
        .collect();
    let (v_lo, v_max) = v.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &x| {
        (lo.min(x), hi.max(x))
    });
    let mean = (sb - sa) / (tb - ta);
    // Each end moved by ε moves Δs by ε and Δt by at most ε / v_lo.
    let err = mean * 2.0 * ROUNDING_MM / (sb - sa) * (1.0 + mean / v_lo.max(1e-9));
    (mean, err, v_max, seg.feed)
}

/// The checks on one program: returns (blocks held below the feed, lowest such feed).
fn check(j: &Job, dialect: Dialect) -> (usize, f64) {
    let blocks = lit_lines(j, dialect);
    assert!(blocks.len() > 4, "{} lit blocks", blocks.len());
    let (mut capped, mut lowest) = (0, f64::INFINITY);
    let mut op_start = [0.0; 2];
    let mut prev_op = u32::MAX;
    for b in &blocks {
        if b.op != prev_op {
            op_start = b.from;
            prev_op = b.op;
        }
        let (mean, err, v_max, feed) = planned_over(j, b, op_start);
        // F is written to 4 decimals of mm/min.
        let resolution = 1e-4 / 60.0;
        if b.feed < feed - resolution {
            capped += 1;
            lowest = lowest.min(b.feed);
            // Held to the plan: the block's feed is the plan's mean speed over it (to the
            // 0.1 µm of the NC's coordinates that locate it), so the controller takes at
            // least the plan's time there and delivers at least its energy per mm.
            assert!(
                (b.feed - mean).abs() <= err + 1e-6 * mean + resolution,
                "{dialect}: op {} block to {:?}: F {} mm/s, the plan's mean {mean}",
                b.op,
                b.to,
                b.feed
            );
            assert!(b.feed <= v_max + err + resolution);
        } else {
            // Written at the feed: the plan holds it there (a block the plan runs slower
            // is held).
            assert!((b.feed - feed).abs() <= resolution, "{} vs {feed}", b.feed);
            assert!(
                mean + err >= feed * (1.0 - 1e-6),
                "{dialect}: op {} block to {:?} at the feed, the plan's mean {mean}",
                b.op,
                b.to
            );
        }
    }
    (capped, lowest)
}

#[test]
fn lit_blocks_are_held_to_the_planned_speed() {
    for couple in ["", ", couple speed"] {
        let j = job(&RECT.replace("40 W", &format!("40 W{couple}")));
        for dialect in [Dialect::LinuxCnc, Dialect::Iso] {
            let (capped, lowest) = check(&j, dialect);
            // The three lit corners (the fourth is where the section starts and ends) are
            // each approached and left through held blocks, down to the corner's speed.
            assert!(
                capped >= 3 * 2 * 10,
                "{dialect}{couple}: {capped} held blocks"
            );
            assert!(
                lowest < 0.5 * 20.0,
                "{dialect}{couple}: lowest F {lowest} mm/s"
            );
        }
    }
}

#[test]
fn a_lit_move_the_plan_holds_at_its_feed_stays_one_block() {
    // One straight lit line between lead-in and lead-out: cruise throughout.
    let j = job("machine xy_table
laser { power 40 W }
follow profile polyline [(0, 0), (30 mm, 0)] at 20 mm/s
");
    let blocks = lit_lines(&j, Dialect::LinuxCnc);
    assert_eq!(blocks.len(), 1);
    assert!((blocks[0].feed - 20.0).abs() < 1e-9);
    assert!(power::lit_blocks(&j, blocks[0].op as usize).is_empty());
}

/// frame_marking's sections start on a 1.5 mm corner arc the plan takes at 9–13 of 20 mm/s.
/// On LinuxCNC: the lead-in ends at the plan's speed at the beam's edge (tp.c would run the
/// blend arc into the arc at the lead-in's higher feed and switch the beam after it), and the
/// arc's first held block is long enough to stay an arc to LinuxCNC (sagitta at least the
/// `G64 P` tolerance; a shorter one runs as its chord and meets the lead-in at a kink).
#[test]
fn a_lit_start_on_a_slow_arc_is_led_in_at_the_planned_speed() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../examples/frame_marking.lase"
    );
    let j = job(&std::fs::read_to_string(path).unwrap());
    let (lines, _) = emit_lines(&j, Dialect::LinuxCnc, &EmitOptions::default()).unwrap();
    let text: Vec<&str> = lines.iter().map(|l| l.text.as_str()).collect();
    let tol: f64 = text
        .iter()
        .find_map(|l| l.strip_prefix("G64 P"))
        .and_then(|l| l.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    // The plan's speed at each beam-on edge, in order.
    let dt = 1e-4;
    let mut edges = Vec::new();
    let mut was_lit = false;
    for k in 0..(j.cycle_time() / dt) as usize {
        let (s, lit, _) = lase_runtime::report::beam_at(&j, k as f64 * dt);
        if lit && !was_lit {
            edges.push(s.v);
        }
        was_lit = lit;
    }
    assert_eq!(edges.len(), 3);
    let word = |l: &str, c: char| {
        l.split(' ')
            .find_map(|w| w.strip_prefix(c))
            .and_then(|v| v.parse::<f64>().ok())
    };
    let mut seen = 0;
    for (k, l) in text.iter().enumerate() {
        if *l != "M62 P0" {
            continue;
        }
        let v_edge = edges[seen];
        seen += 1;
        assert!(v_edge < 0.6 * 20.0, "the plan's edge at {v_edge} mm/s");
        // The lead-in: the last G1 line before the edge; between it and the switch, the
        // arc's first piece the switch is carried over (`emit::writer::lead`). The feed in
        // force over both (the last F word before the switch) is the plan's at the edge.
        let lead = text[..k]
            .iter()
            .rev()
            .find(|l| l.starts_with("G1"))
            .unwrap();
        let f = text[..k]
            .iter()
            .rev()
            .find_map(|l| word(l, 'F'))
            .expect("the lead-in carries its held feed")
            / 60.0;
        assert!(
            (f - v_edge).abs() < 0.01 * v_edge,
            "lead-in F {f} mm/s, edge {v_edge}"
        );
        // The first lit block, from the lead-in's end to the end of the first motion line
        // after the switch: an arc whose sagitta LinuxCNC sees (r = 1.5 mm).
        let first = text[k + 1..]
            .iter()
            .find(|l| l.starts_with('X') || l.starts_with('Y') || l.starts_with("G3"))
            .unwrap();
        let (x0, y0) = (word(lead, 'X').unwrap_or(-1.5), word(lead, 'Y').unwrap());
        let (x1, y1) = (word(first, 'X').unwrap(), word(first, 'Y').unwrap());
        let chord = (x1 - x0).hypot(y1 - y0);
        let sagitta = 1.5 - (1.5f64 * 1.5 - chord * chord / 4.0).sqrt();
        assert!(sagitta >= tol * (1.0 - 1e-3), "sagitta {sagitta} < {tol}");
    }
    assert_eq!(seen, 3);
}
