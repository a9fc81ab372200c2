//! The beam on GRBL and grblHAL, computed from the NC lase writes for every example: GRBL
//! syncs every `M3`/`M4`/`M5` (the table stops first, even in laser mode), so
//!
//! * with a post that flies (`motion::beam::flies`: every stock machine but the notcher) no
//!   `M3`/`M4`/`M5` stands between the lead-in and the lead-out of a lit run: the NC's lit
//!   runs are its feed blocks with an S > 0 under `M3`/`M4`, the lead-in the feed block right
//!   before one, the lead-out the feed block right after;
//! * every `M3`/`M4`/`M5` of any post stands where the plan is at rest (the motion before it
//!   ends at speed 0), so no switch the controller makes at rest was planned as flying;
//! * each lit block's S is the power the plan gives its op, scaled to the post's `s_max` (S0
//!   for an op lit at 0 W, a white run inside an image row); a feed block of an op the plan
//!   keeps dark is dark.
//!
//! One trial per example and dialect (`beam::grbl::frame_marking`).

mod common;

use common::cases::{per_file, run};
use common::{lase_files, nc_words, root};
use lase_runtime::FsFiles;
use lase_runtime::emit::{Dialect, EmitOptions, NcLine};
use lase_runtime::motion::{Job, beam};
use lase_runtime::program::{Laser, OpKind};
use std::path::Path;

fn main() {
    let examples = lase_files(&root().join("examples"));
    let mut trials = Vec::new();
    for dialect in [Dialect::Grbl, Dialect::GrblHal] {
        trials.extend(per_file(
            &format!("beam::{dialect}"),
            &examples,
            move |ex| check(ex, dialect),
        ));
    }
    run(trials)
}

/// One NC block as the controller reads it.
struct Block {
    /// Index in the program's lines.
    line: usize,
    op: Option<u32>,
    /// A motion block with axis words, in G0 (`false`) or G1/G2/G3 (`true`).
    motion: Option<bool>,
    /// The block has an M3, M4 or M5.
    spindle_word: bool,
    /// Laser on with power in this block: a feed block under M3/M4 with S > 0.
    lit: bool,
    /// The S in force.
    s: f64,
}

fn parse(lines: &[NcLine]) -> Vec<Block> {
    let (mut mode, mut s, mut on) = (0.0, 0.0, false);
    lines
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let words = nc_words(&l.text);
            let mut spindle_word = false;
            let mut axes = false;
            for &(c, v) in &words {
                match c {
                    'G' if [0.0, 1.0, 2.0, 3.0].contains(&v) => mode = v,
                    'M' if v == 3.0 || v == 4.0 => (on, spindle_word) = (true, true),
                    'M' if v == 5.0 || v == 2.0 || v == 30.0 => {
                        on = false;
                        spindle_word |= v == 5.0;
                    }
                    'S' => s = v,
                    'X' | 'Y' | 'Z' | 'A' | 'B' | 'C' => axes = true,
                    _ => {}
                }
            }
            let feed = mode != 0.0;
            Block {
                line: i,
                op: l.op,
                motion: axes.then_some(feed),
                spindle_word,
                lit: axes && feed && on && s > 0.0,
                s,
            }
        })
        .collect()
}

fn check(ex: &Path, dialect: Dialect) {
    let name = ex.display().to_string();
    let (_, job) =
        lase_runtime::compile(&mut FsFiles, &name).unwrap_or_else(|(_, f)| panic!("{name}: {f}"));
    let options = EmitOptions {
        locate: None,
        comments: true,
        live: false,
    };
    let Ok((lines, _)) = lase_runtime::emit::emit_lines(&job, dialect, &options) else {
        // GRBL refuses the rotary machines (pinned by the golden tests).
        assert_eq!(dialect, Dialect::Grbl, "{name}: grblHAL runs every example");
        return;
    };
    let machine = &job.program.machine;
    let (_, post) = dialect.lookup(&machine.post).expect("validated");
    let blocks = parse(&lines);
    let text = |b: &Block| format!("{name} line {}: {}", b.line + 1, lines[b.line].text);

    // Lit runs, as indices into `blocks` of their first and last lit block.
    let motions: Vec<usize> = (0..blocks.len())
        .filter(|&i| blocks[i].motion.is_some())
        .collect();
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for (k, &i) in motions.iter().enumerate() {
        if blocks[i].lit && (k == 0 || !blocks[motions[k - 1]].lit) {
            let end = motions[k..]
                .iter()
                .take_while(|&&j| blocks[j].lit)
                .last()
                .copied()
                .unwrap_or(i);
            runs.push((i, end));
        }
    }
    assert!(!runs.is_empty(), "{name}: the program lights the beam");

    if beam::flies(post) {
        for &(a, b) in &runs {
            let k = motions.iter().position(|&i| i == a).unwrap();
            let lead_in = k
                .checked_sub(1)
                .map(|k| motions[k])
                .filter(|&i| blocks[i].motion == Some(true))
                .unwrap_or(a);
            let k = motions.iter().position(|&i| i == b).unwrap();
            let lead_out = motions
                .get(k + 1)
                .copied()
                .filter(|&i| blocks[i].motion == Some(true))
                .unwrap_or(b);
            for blk in &blocks[lead_in..=lead_out] {
                assert!(
                    !blk.spindle_word,
                    "{}: a spindle switch between lead-in and lead-out stops GRBL",
                    text(blk)
                );
            }
        }
    }

    // Every M3/M4/M5 at a planned rest: the motion before it ends at speed 0.
    for (i, blk) in blocks.iter().enumerate() {
        if !blk.spindle_word {
            continue;
        }
        let before = blocks[..i].iter().rev().find(|b| b.motion.is_some());
        if let Some(op) = before.and_then(|b| b.op) {
            let v = exit_speed(&job, op);
            assert!(
                v.is_none_or(|v| v.abs() < 1e-9),
                "{}: GRBL stops here, the plan passes at {v:?} mm/s",
                text(blk)
            );
        }
    }

    // Power per lit block, and dark where the plan is dark.
    let ops = &job.program.ops;
    let mut lit_blocks = 0;
    // The blocks written so far of the current op: an image row's k-th block is its k-th run.
    let mut seen: (Option<u32>, usize) = (None, 0);
    for blk in blocks.iter().filter(|b| b.motion == Some(true)) {
        let op = &ops[blk.op.expect("a motion block comes from an op") as usize];
        seen = if seen.0 == blk.op {
            (blk.op, seen.1 + 1)
        } else {
            (blk.op, 0)
        };
        let run_laser = match &op.kind {
            OpKind::Line {
                laser: Some(l),
                row: Some(row),
                ..
            } => Some(Laser {
                power_w: row.power_w(row.runs[seen.1].1),
                ..(**l).clone()
            }),
            _ => None,
        };
        match run_laser.as_ref().or(op.laser()) {
            // A lit op at 0 W (a white run inside an image row: the row stays one lit
            // section) is S0, and checked to be.
            Some(l) if blk.lit || l.power_w == 0.0 => {
                let want = l.power_w / machine.laser.max_power_w * post.s_max;
                assert!(
                    (blk.s - want).abs() <= 0.5e-4,
                    "{}: S {} where the plan has {} W (S {want})",
                    text(blk),
                    blk.s,
                    l.power_w
                );
                lit_blocks += 1;
            }
            // A pulse gate's low block of a lit op (S0 between the spots).
            Some(l) => assert!(
                l.pulse.is_some(),
                "{}: dark in a lit section without pulses",
                text(blk)
            ),
            None => assert!(!blk.lit, "{}: lit where the plan is dark", text(blk)),
        }
    }
    assert!(lit_blocks > 0, "{name}");
}

/// The planned speed at the end of op `op`'s last move (`None`: the op has no move).
fn exit_speed(job: &Job, op: u32) -> Option<f64> {
    job.plan
        .segments()
        .iter()
        .rev()
        .find(|s| s.tag == op)
        .map(|s| s.v_exit)
}
