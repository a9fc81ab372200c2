//! Helpers for the controller-link tests: compile a recipe to its planned job and NC lines
//! through the library (as the `lase` binary does), run the binary, and compare what the
//! simulated controller executed with the plan.

#![allow(dead_code)]

use lase_lang::{SourceMap, Span};
use lase_runtime::FsFiles;
use lase_runtime::axes::Axes;
use lase_runtime::emit::{EmitOptions, NcLine};
use lase_runtime::link::sim::{self, Recording, SimHandle, SimOptions};
use lase_runtime::link::{AxisPos, ControllerAxes, MAX_AXES};
use lase_runtime::machine::Machine;
use lase_runtime::motion::Job;
use lase_runtime::program::OpKind;
use std::path::{Path, PathBuf};
use std::process::Command;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A compiled example: its planned job and its lines for the controller, as `lase run`
/// plans and sends them (the grbl dialect, or grblhal for machines with rotary axes).
pub struct Compiled {
    pub job: Job,
    pub lines: Vec<NcLine>,
    pub map: SourceMap,
}

pub fn compile(path: &Path) -> Compiled {
    fn ok<T>(path: &Path, r: Result<T, lase_runtime::compile::Failure>) -> T {
        r.unwrap_or_else(|f| panic!("{}: {f}", path.display()))
    }
    let mut recipe = lase_runtime::compile::load(&mut FsFiles, &path.to_string_lossy())
        .unwrap_or_else(|(_, f)| panic!("{}: {f}", path.display()));
    ok(path, lase_runtime::compile::check(&recipe));
    let mut program = ok(
        path,
        lase_runtime::compile::evaluate(&mut recipe, &mut FsFiles),
    );
    // Planned for the link's controller, as `lase run` does (`Machine::run_on`).
    let dialect = lase_runtime::link::live_dialect(&program.machine);
    program.machine.run_on(dialect.name());
    let job = ok(path, lase_runtime::compile::plan(program));
    let locate = |s: Span| recipe.locate(s);
    let (lines, _) = lase_runtime::emit::emit_lines(
        &job,
        dialect,
        &EmitOptions {
            locate: Some(&locate),
            comments: true,
            live: true,
        },
    )
    .unwrap();
    Compiled {
        job,
        lines,
        map: recipe.map,
    }
}

/// Every example recipe, sorted: GRBL runs the Cartesian ones, grblHAL those with rotary
/// axes.
pub fn examples() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("examples"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "lase"))
        .collect();
    v.sort();
    v
}

/// Machine axes in a controller's position: X Y Z A B C by letter, rotary axes in degrees.
pub fn to_controller(m: &Machine) -> impl Fn(&Axes) -> AxisPos {
    let axes = ControllerAxes::of(m);
    move |q: &Axes| axes.to_controller(q)
}

fn dist(a: AxisPos, b: AxisPos) -> f64 {
    (0..MAX_AXES)
        .map(|i| (b[i] - a[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Runs `lase ARGS` from the repository root: (exit code, stdout, stderr).
pub fn lase(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lase"))
        .args(args)
        .current_dir(root())
        .env("NO_COLOR", "1")
        .output()
        .expect("the lase binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A simulator for `machine` on a free loopback port.
pub fn sim_for(job: &Job, opts: SimOptions) -> SimHandle {
    sim::serve(&job.program.machine, "127.0.0.1:0".parse().unwrap(), opts).unwrap()
}

pub fn url(h: &SimHandle) -> String {
    format!("tcp://{}", h.addr().unwrap())
}

/// The G-code lines the controller received (system `$` commands left out), in order.
pub fn gcode_lines(rec: &Recording) -> Vec<String> {
    rec.lines
        .iter()
        .filter(|l| l.result != sim::LineResult::System)
        .map(|l| l.text.clone())
        .collect()
}

/// `bed.toml` in `dir`: the stock `xy_table` with X travel `x` and Y travel `y` (two lengths
/// each, as the file writes them, e.g. `["20 mm", "320 mm"]`), and `extra` appended.
pub fn write_bed(dir: &Path, x: &str, y: &str, extra: &str) {
    let stock = std::fs::read_to_string(root().join("stdlib/machines/xy_table.toml")).unwrap();
    let bed = stock
        .replace("[\"-150 mm\", \"150 mm\"]", x)
        .replace("[\"-100 mm\", \"100 mm\"]", y)
        + extra;
    std::fs::write(dir.join("bed.toml"), bed).unwrap();
}

/// The simulator of `dir`'s `bed.toml` over a socket, at the fastest time scale, holding
/// the work offsets `work_offsets` (G54…G59, as `$#` reports them).
pub fn bed_sim(dir: &Path, work_offsets: [[f64; 6]; 6]) -> SimHandle {
    let text = std::fs::read_to_string(dir.join("bed.toml")).unwrap();
    let machine = lase_runtime::machine::parse_machine(&text, 0).unwrap();
    let opts = SimOptions {
        time_scale: sim::TimeScale::Max,
        work_offsets,
        ..SimOptions::default()
    };
    sim::serve(&machine, "127.0.0.1:0".parse().unwrap(), opts).unwrap()
}

/// The extent of what the controller executed lit, `[min x, min y, max x, max y]` of its lit
/// blocks' ends (machine coordinates).
pub fn lit_extent(rec: &Recording) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for blk in rec.blocks.iter().filter(|blk| blk.laser_s > 0.0) {
        for p in [blk.from, blk.to] {
            b = [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ];
        }
    }
    b
}

/// Planned end position of every motion op (in the controller's axes), by op index.
pub fn planned_op_ends(job: &Job) -> Vec<(usize, AxisPos)> {
    let map = to_controller(&job.program.machine);
    let mut out: Vec<(usize, AxisPos)> = Vec::new();
    for (tag, target) in planned_moves(job) {
        let p = map(&target);
        match out.last_mut() {
            Some((op, q)) if *op == tag as usize => *q = p,
            _ => out.push((tag as usize, p)),
        }
    }
    out
}

/// The planned moves in order: the tag (op index) and the axes each ends at, as programmed —
/// a move whose end the plan rounds (a corner blend, `planner::blend`) ends at the corner the
/// NC names, not on the blend curve where its segments meet.
fn planned_moves(job: &Job) -> impl Iterator<Item = (u32, Axes)> + '_ {
    let plan = &job.plan;
    let segs = plan.segments();
    (0..segs.len())
        .filter(move |&i| i + 1 == segs.len() || segs[i + 1].move_index != segs[i].move_index)
        .map(move |i| {
            let end = match plan.blend_of(i) {
                Some((blend, false)) => blend.corner,
                _ => plan.segment_target(i),
            };
            (segs[i].tag, end)
        })
}

/// Lit runs of the plan: (start, end, length) of each maximal run of consecutive lit moves,
/// in the controller's axes (the length in axis space, degrees counting as mm, as the
/// controller's own blocks are measured), and the pulse pitch when the run fires pulses by
/// distance.
pub type PlannedRun = (AxisPos, AxisPos, f64, Option<f64>);

pub fn planned_lit_runs(job: &Job) -> Vec<PlannedRun> {
    let map = to_controller(&job.program.machine);
    let mut runs: Vec<PlannedRun> = Vec::new();
    let mut prev = map(&job.start);
    let mut in_run = false;
    let mut part = job.program.start;
    for (tag, target) in planned_moves(job) {
        let end = map(&target);
        let op = &job.program.ops[tag as usize];
        let pitch = op
            .laser()
            .and_then(|l| match l.pulse.as_ref().map(|p| p.mode) {
                Some(lase_runtime::program::PulseMode::Distance { pitch_mm }) => Some(pitch_mm),
                _ => None,
            });
        // Pieces (end, lit) of the move: an image row's runs (the NC writes a block per run,
        // part of the way along the row's straight move), else the move whole. An op or a run
        // lit at 0 W (a white run inside an image row) is dark, as its S0 block is.
        let pieces: Vec<(AxisPos, bool)> = match &op.kind {
            OpKind::Line {
                to, row: Some(row), ..
            } => {
                let total = lase_runtime::program::dist(part, *to);
                let from = prev;
                row.runs
                    .iter()
                    .map(|&(c, shade)| {
                        let [x, y] = row.end_of(c);
                        let f = (lase_runtime::program::dist(part, [x, y, to[2]]) / total).min(1.0);
                        let at = std::array::from_fn(|i| from[i] + f * (end[i] - from[i]));
                        (at, row.power_w(shade) > 0.0)
                    })
                    .collect()
            }
            _ => vec![(
                end,
                op.laser().is_some_and(|l| l.power_w > 0.0)
                    && !matches!(op.kind, OpKind::Rapid { .. }),
            )],
        };
        for (to, lit) in pieces {
            let length = dist(prev, to);
            // A run is lit moves in a row with one pulse pitch: a scan of explicit spots (a
            // Data Matrix's module centres) lights runs of different pitch end to end.
            let same_pitch = runs.last().is_some_and(|r| r.3 == pitch);
            if lit {
                if in_run && same_pitch {
                    let r = runs.last_mut().unwrap();
                    r.1 = to;
                    r.2 += length;
                } else {
                    runs.push((prev, to, length, pitch));
                }
            }
            in_run = lit;
            prev = to;
        }
        prev = end;
        part = op.target().unwrap_or(part);
    }
    runs
}

/// Lit runs the controller executed.
pub fn executed_lit_runs(rec: &Recording) -> Vec<(AxisPos, AxisPos, f64)> {
    let mut runs: Vec<(AxisPos, AxisPos, f64)> = Vec::new();
    let mut in_run = false;
    for b in &rec.blocks {
        let lit = b.laser_s > 0.0;
        let len = dist(b.from, b.to);
        if lit {
            if in_run {
                let r = runs.last_mut().unwrap();
                r.1 = b.to;
                r.2 += len;
            } else {
                runs.push((b.from, b.to, len));
            }
        }
        in_run = lit;
    }
    runs
}

fn close(a: AxisPos, b: AxisPos, tol: f64) -> bool {
    (0..MAX_AXES).all(|i| (a[i] - b[i]).abs() <= tol)
}

/// The executed trajectory equals the plan: every op's end position within 1 µm (the end of
/// the last executed block of the op's last line), the same lit runs (ends within 1 µm,
/// lengths within the chord tolerance of arcs), the same final position.
pub fn assert_trajectory_matches(c: &Compiled, rec: &Recording, job_line_seqs: &[Option<u64>]) {
    // Position after each job line: the end of its last executed block, else the previous.
    let mut pos_after = Vec::with_capacity(c.lines.len());
    let start = to_controller(&c.job.program.machine)(&c.job.start);
    let mut cur = start;
    let mut by_seq = std::collections::HashMap::new();
    for b in &rec.blocks {
        by_seq.insert(b.seq, b.to);
    }
    for s in job_line_seqs {
        if let Some(p) = s.and_then(|s| by_seq.get(&s)) {
            cur = *p;
        }
        pos_after.push(cur);
    }
    for (op, planned) in planned_op_ends(&c.job) {
        let last_line = c
            .lines
            .iter()
            .rposition(|l| l.op == Some(op as u32))
            .unwrap_or_else(|| panic!("op {op} has no NC line"));
        let got = pos_after[last_line];
        assert!(
            close(got, planned, 1e-3),
            "op {op} (line {} `{}`): executed {got:?}, planned {planned:?}",
            last_line + 1,
            c.lines[last_line].text
        );
    }
    let end = rec.blocks.last().map(|b| b.to).unwrap_or(start);
    let planned_end = planned_op_ends(&c.job).last().map(|e| e.1).unwrap_or(start);
    assert!(close(end, planned_end, 1e-3), "{end:?} vs {planned_end:?}");
    let planned = planned_lit_runs(&c.job);
    let executed = executed_lit_runs(rec);
    let mut j = 0;
    for (i, p) in planned.iter().enumerate() {
        if let Some(pitch) = p.3 {
            // Pulses by distance reach GRBL as one short lit block per pulse: the run is
            // executed as dashes, about one every `pitch`, up to the next planned run.
            let next = planned.get(i + 1).map(|n| n.0);
            let first = j;
            while j < executed.len() && !next.is_some_and(|s| close(executed[j].0, s, 1e-3)) {
                j += 1;
            }
            let dashes = (j - first) as f64;
            let expected = p.2 / pitch;
            assert!(
                dashes >= expected.floor() && dashes <= expected.ceil() + 1.0,
                "{dashes} pulses executed along {p:?}, about {expected:.1} planned"
            );
            continue;
        }
        let e = executed
            .get(j)
            .unwrap_or_else(|| panic!("planned run {p:?} was not executed: {executed:?}"));
        assert!(
            close(p.0, e.0, 1e-3) && close(p.1, e.1, 1e-3),
            "{p:?} vs {e:?}"
        );
        assert!(
            (p.2 - e.2).abs() <= 1e-3 * p.2.max(1.0),
            "length {p:?} vs {e:?}"
        );
        j += 1;
    }
    assert_eq!(
        j,
        executed.len(),
        "executed lit runs beyond the plan: {executed:?}"
    );
}

/// For each job line, the sequence number under which the controller executed it (the last
/// connection that sent it), matching received G-code lines to job lines in order. A
/// resumed connection (the k-th resume: connection k + 2) starts with `resumes[k].1`
/// re-approach lines, then job line `resumes[k].0`.
pub fn job_line_seqs(
    c: &Compiled,
    rec: &Recording,
    resumes: &[(usize, usize)],
) -> Vec<Option<u64>> {
    let mut out = vec![None; c.lines.len()];
    let mut next = 0usize;
    let mut conn = 0u32;
    let mut skip = 0usize;
    for l in &rec.lines {
        if l.result == sim::LineResult::System {
            continue;
        }
        if l.connection != conn {
            conn = l.connection;
            if conn >= 2
                && let Some(&(from, pre)) = resumes.get(conn as usize - 2)
            {
                next = from;
                skip = pre;
            }
        }
        if skip > 0 {
            skip -= 1;
            continue;
        }
        // A resumed modal arc may carry its motion word.
        let same = |t: &str| l.text == t || l.text.ends_with(&format!(" {t}"));
        assert!(
            next < c.lines.len() && same(&c.lines[next].text),
            "received `{}` where job line {} `{}` belongs",
            l.text,
            next + 1,
            c.lines
                .get(next)
                .map(|l| l.text.as_str())
                .unwrap_or("<end>")
        );
        out[next] = Some(l.seq);
        next += 1;
    }
    out
}

/// What each line did, for the lines that did something, as the controller saw them:
/// re-approach lines and system commands left out.
pub fn effective(rec: &Recording, resumes: &[(usize, usize)]) -> Vec<(String, sim::Effect)> {
    let mut out = Vec::new();
    let mut conn = 0u32;
    let mut skip = 0usize;
    for l in &rec.lines {
        if l.result == sim::LineResult::System {
            continue;
        }
        if l.connection != conn {
            conn = l.connection;
            skip = if conn >= 2 {
                resumes.get(conn as usize - 2).map_or(0, |r| r.1)
            } else {
                0
            };
        }
        if skip > 0 {
            skip -= 1;
            continue;
        }
        assert_eq!(l.result, sim::LineResult::Ok, "`{}`", l.text);
        if let Some(e) = &l.effect
            && !e.is_noop()
        {
            out.push((l.text.clone(), e.clone()));
        }
    }
    out
}

/// The effects of running `lines` once on a fresh simulated controller.
pub fn baseline(c: &Compiled) -> Vec<(String, sim::Effect)> {
    let m = &c.job.program.machine;
    let mut ctl = sim::Controller::new(sim::ControllerConfig {
        rx_buffer: 1024,
        ..sim::ControllerConfig::for_machine(m)
    });
    for l in &c.lines {
        for b in l.text.bytes().chain(std::iter::once(b'\n')) {
            ctl.receive(b);
        }
        ctl.run(f64::INFINITY);
    }
    effective(ctl.recording(), &[])
}

/// Reads the resume records (`r EXECUTED PREAMBLE`) of a journal.
pub fn journal_resumes(path: &Path) -> Vec<(usize, usize)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("r "))
        .map(|r| {
            let mut it = r.split_whitespace().map(|v| v.parse::<usize>().unwrap());
            (it.next().unwrap(), it.next().unwrap())
        })
        .collect()
}
