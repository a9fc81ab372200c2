//! Planning in windows gives the whole plan, bit for bit (issue 18): every example and a few
//! hundred random paths are planned whole and in windows, and every field of every segment, every
//! segment's start point, every blend a segment follows and the totals must be the very same
//! numbers. Small windows (from one segment on) cut each program in many places, so the
//! look-ahead's commit rule and the corner blends at window boundaries are exercised
//! everywhere, not only past `planner::MIN_WINDOW` segments.

mod common;

use common::rng::Rng;
use common::{examples, program_of};
use lase_runtime::compile::{self, FsFiles, MemFiles};
use lase_runtime::emit::{self, Dialect, PlanFacts};
use lase_runtime::motion;
use lase_runtime::planner::{
    self, Along, AxisLimits, Corners, MAX_AXES, Move, Plan, PlannerConfig, ProfileKind, Segment,
};
use lase_runtime::program::ProcessProgram;

#[path = "support/short_moves.rs"]
mod short_moves;

/// Every field of a segment as bits: `==` on floats would let −0 pass for 0.
fn bits(s: &Segment) -> [u64; 16] {
    [
        s.t_start.to_bits(),
        s.s_start.to_bits(),
        s.length.to_bits(),
        s.v_entry.to_bits(),
        s.v_peak.to_bits(),
        s.v_exit.to_bits(),
        s.t_j1.to_bits(),
        s.t_a1.to_bits(),
        s.t_cruise.to_bits(),
        s.t_j2.to_bits(),
        s.t_a2.to_bits(),
        s.dwell.to_bits(),
        s.feed.to_bits(),
        u64::from(s.tag),
        u64::from(s.move_index),
        u64::from(s.blend),
    ]
}

fn axes_bits(q: &planner::Axes) -> Vec<u64> {
    q.iter().map(|x| x.to_bits()).collect()
}

/// Compares the windows with the whole plan; returns how many windows there were.
fn same_plan(what: &str, whole: &Plan, windows: &[Plan], planned: &planner::Planned) -> usize {
    let mut g = 0;
    for (w, win) in windows.iter().enumerate() {
        assert!(!win.segments().is_empty(), "{what}: window {w} is empty");
        assert_eq!(
            axes_bits(&win.start()),
            axes_bits(&whole.segment_start(g)),
            "{what}: window {w}'s start"
        );
        for (i, seg) in win.segments().iter().enumerate() {
            let want = whole
                .segments()
                .get(g)
                .unwrap_or_else(|| panic!("{what}: more segments in windows than whole"));
            assert_eq!(
                bits(seg),
                bits(want),
                "{what}: segment {g} (window {w}, {i}):\n{seg:?}\n{want:?}"
            );
            assert_eq!(
                axes_bits(&win.segment_start(i)),
                axes_bits(&whole.segment_start(g)),
                "{what}: segment {g}'s start point"
            );
            assert_eq!(
                win.blend_of(i),
                whole.blend_of(g),
                "{what}: segment {g}'s blend"
            );
            g += 1;
        }
        assert_eq!(
            axes_bits(&win.end()),
            axes_bits(&whole.segment_start(g)),
            "{what}: window {w}'s end"
        );
        let t_end = win.segments().last().map_or(0.0, |s| s.t_end());
        assert_eq!(
            win.duration().to_bits(),
            t_end.to_bits(),
            "{what}: window {w}'s duration"
        );
    }
    assert_eq!(g, whole.segments().len(), "{what}: segments in windows");
    assert_eq!(planned.segments, g, "{what}: segments counted");
    assert_eq!(
        planned.duration.to_bits(),
        whole.duration().to_bits(),
        "{what}: duration"
    );
    assert_eq!(
        planned.length.to_bits(),
        whole.length().to_bits(),
        "{what}: length"
    );
    assert_eq!(
        axes_bits(&planned.end),
        axes_bits(&whole.end()),
        "{what}: end"
    );
    windows.len()
}

#[test]
fn every_example_planned_in_windows_is_its_whole_plan_bit_for_bit() {
    let examples = examples();
    assert!(examples.len() >= 10, "{} examples", examples.len());
    for ex in examples {
        let name = ex.file_stem().unwrap().to_string_lossy().into_owned();
        let path = ex.to_str().unwrap();
        let mut files = FsFiles;
        let mut recipe = compile::load(&mut files, path).unwrap_or_else(|(_, f)| panic!("{f}"));
        compile::check(&recipe).unwrap_or_else(|f| panic!("{name}: {f}"));
        let program =
            compile::evaluate(&mut recipe, &mut files).unwrap_or_else(|f| panic!("{name}: {f}"));
        let whole = motion::plan_program(program.clone()).unwrap_or_else(|e| panic!("{e}"));
        for min_window in [1, 3, 64, planner::MIN_WINDOW] {
            let mut windows = Vec::new();
            let (job, planned) =
                motion::plan_program_windows_sized(program.clone(), min_window, |_, w| {
                    windows.push(w)
                })
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            let what = format!("{name}, windows from {min_window}");
            let count = same_plan(&what, &whole.plan, &windows, &planned);
            assert!(
                job.plan.segments().is_empty(),
                "{what}: the job keeps no plan"
            );
            assert_eq!(
                job.cycle_time().to_bits(),
                whole.cycle_time().to_bits(),
                "{what}"
            );
            assert_eq!(job.op_axes, whole.op_axes, "{what}: op axes");
            assert_eq!(
                job.program.ops.len(),
                whole.program.ops.len(),
                "{what}: ops"
            );
            // A flat bed's plan is cut into many windows when they are small; an oriented
            // machine's, and a rotary attachment's run on LinuxCNC (its lit G93 blocks judged
            // by `motion::parabolic`), are planned whole (`motion::plan_program_windows`).
            if min_window == 1 && !job.kin.inverse_time() && whole.plan.segments().len() > 20 {
                assert!(count > 2, "{what}: {count} windows");
            }
            // Planned again from the job, as emit's writer reads the lit sub-blocks
            // (`motion::replan_windows`, `emit::PlanFacts`): the same plan again.
            if min_window == 1 && !job.kin.oriented() {
                let mut again = Vec::new();
                motion::replan_windows(&job, |_, w| {
                    again.push(w);
                    true
                })
                .unwrap_or_else(|e| panic!("{what}, planned again: {e}"));
                same_plan(
                    &format!("{what}, planned again"),
                    &whole.plan,
                    &again,
                    &planned,
                );
            }
        }
    }
}

/// `lase plan`'s summary and time split counted from windows (`report::PlanTotals`) are the
/// whole plan's, to the last bit (the JSON rounds to 9 digits; this does not).
#[test]
fn every_examples_summary_counted_from_windows_is_the_whole_plans() {
    use lase_runtime::report::{self, PlanTotals};
    for ex in examples() {
        let path = ex.to_str().unwrap();
        let program = program_of(&mut FsFiles, path);
        let whole = motion::plan_program(program.clone()).unwrap_or_else(|e| panic!("{e}"));
        let want = report::summarize(&whole);
        let split = report::time_split(&whole);
        for min_window in [1, 3, planner::MIN_WINDOW] {
            let what = format!("{path}, windows from {min_window}");
            let mut totals = PlanTotals::new(&program);
            let (job, planned) =
                motion::plan_program_windows_sized(program.clone(), min_window, |p, w| {
                    totals.window(p, &w)
                })
                .unwrap_or_else(|e| panic!("{what}: {e}"));
            totals.finish(&job.program, planned.length);
            assert_eq!(
                format!("{:?}", totals.summary(&job)),
                format!("{want:?}"),
                "{what}: summary"
            );
            assert_eq!(
                format!("{:?}", totals.time_split(&job)),
                format!("{split:?}"),
                "{what}: time split"
            );
        }
        // The pulse count is the pulse events' (`lase plan --pulses`).
        assert_eq!(
            want.pulses,
            report::pulse_events(&whole).count() as u64,
            "{path}: pulses"
        );
    }
}

/// The program of recipe `path` in `files`.
/// `lase emit`'s two ways, whole and in windows (`emit::PlanFacts`), give the same NC text, or
/// the same refusal, in every dialect.
fn same_nc(what: &str, program: &ProcessProgram) {
    let whole = motion::plan_program(program.clone()).unwrap_or_else(|e| panic!("{what}: {e}"));
    for dialect in Dialect::ALL {
        let want = emit::emit_to_string(&whole, dialect).map_err(|e| format!("{e:?}"));
        for min_window in [1, 3, planner::MIN_WINDOW] {
            // Also as `lase plan` gathers them, once for every dialect: each reads its own.
            let facts = if min_window == 3 {
                PlanFacts::for_dialects(program, &Dialect::ALL)
            } else {
                PlanFacts::new(program, dialect)
            };
            let got = common::emit_in_windows(what, program, facts, dialect, min_window);
            if got != want {
                let (g, w) = (format!("{got:?}"), format!("{want:?}"));
                let at = g.bytes().zip(w.bytes()).take_while(|(a, b)| a == b).count();
                let from = g[..at].rfind("\\n").unwrap_or(0);
                panic!(
                    "{what}, {dialect}, windows from {min_window}: the NC differs from the whole \
                     plan's from {:?} (windows) / {:?} (whole)",
                    &g[from..(at + 80).min(g.len())],
                    &w[from..(at + 80).min(w.len())]
                );
            }
        }
    }
}

#[test]
fn every_example_emitted_from_windows_is_the_nc_of_its_whole_plan() {
    for ex in examples() {
        let path = ex.to_str().unwrap();
        same_nc(path, &program_of(&mut FsFiles, path));
    }
}

/// Power coupled to speed (sub-blocks from each op's segments, across windows) and a LinuxCNC
/// post whose immediate output word is refused where the plan flies (the planned speeds at each
/// op, across windows) and accepted where it stops.
#[test]
fn coupled_power_and_flying_switches_emitted_from_windows_are_those_of_the_whole_plan() {
    let stock = include_str!("../../stdlib/machines/xy_table.toml");
    let flying = stock.replace("\"M62 P0\"]", "\"M64 P0\"]");
    assert_ne!(flying, stock, "xy_table's LinuxCNC laser_on ends with M62");
    let at_rest = flying.replace(
        "[post.linuxcnc]\n",
        "[post.linuxcnc]\nlaser_switch_stops = true\n",
    );
    let rect = "laser { power 40 W, couple speed }\n\
                let part = profile polyline [(0, 0), (30 mm, 0), (30 mm, 10 mm), (0, 10 mm)] closed\n\
                follow part at 20 mm/s\n\
                move to (0, -20 mm) rapid\n";
    let short = "planner { leadin none }\n\
                 laser { power 30 W, couple speed }\n\
                 laser on\n\
                 move to (0.5 mm, 0) at 40 mm/s\n\
                 move to (0.5 mm, 0.4 mm) at 40 mm/s\n\
                 dwell 0.1 s\n\
                 move to (2 mm, 0.4 mm) at 40 mm/s\n\
                 laser off\n\
                 move to (0, 0) rapid\n";
    let mut refused = Vec::new();
    for (machine, toml) in [("stock", stock), ("flying", &flying), ("at_rest", &at_rest)] {
        for (name, body) in [("rect", rect), ("short", short)] {
            let recipe = format!("machine \"{machine}.toml\"\n{body}");
            let mut files = MemFiles::new([
                (format!("{machine}.toml"), toml.to_string()),
                ("r.lase".to_string(), recipe),
            ]);
            let program = program_of(&mut files, "r.lase");
            same_nc(&format!("{name} on {machine}"), &program);
            let whole = motion::plan_program(program).unwrap();
            if emit::emit_to_string(&whole, Dialect::LinuxCnc).is_err() {
                refused.push(format!("{name} on {machine}"));
            }
        }
    }
    // The flying M64 is refused where the beam goes on at speed (after the lead-in), and nowhere
    // else (`short` switches it on at rest): the check ran, on the windows' speeds too.
    assert_eq!(refused, ["rect on flying"]);
}

/// A random path of `n` moves in `n_axes` axes: short and long moves, straight runs, sharp and
/// shallow corners, reversals, stops, dwells, zero-length moves, rapids, lit runs that keep
/// their velocity steps, and chords whose length is not their axis-space length (oriented
/// machines).
fn random_path(rng: &mut Rng, n: usize, n_axes: usize) -> (planner::Axes, Vec<(Move, Along)>) {
    let start = planner::Axes::ZERO;
    let mut q = start;
    let mut dir = [0.0; MAX_AXES];
    let mut moves = Vec::with_capacity(n);
    for _ in 0..n {
        let kind = rng.below(20);
        if kind == 0 {
            // No motion: a dwell or a stop merged into the previous move.
            let mut m = Move::new(q, 0.0, 10.0);
            m.dwell_after = if rng.below(2) == 0 { 0.0 } else { 0.01 };
            m.stop_after = true;
            moves.push((m, Along::default()));
            continue;
        }
        if kind < 12 || dir.iter().all(|&d| d == 0.0) {
            // A new direction (sometimes almost the old one, sometimes its reverse).
            let turn = rng.next();
            for d in dir.iter_mut().take(n_axes) {
                let fresh = rng.next() * 2.0 - 1.0;
                *d = if turn < 0.3 {
                    *d + 0.01 * fresh
                } else if turn < 0.35 {
                    -*d
                } else {
                    fresh
                };
            }
        }
        let norm = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
        if norm < 1e-6 {
            continue;
        }
        let len = match rng.below(4) {
            0 => 0.01 + 0.05 * rng.next(),
            1 => 0.1 + rng.next(),
            2 => 1.0 + 20.0 * rng.next(),
            _ => 0.5,
        };
        let mut target = q;
        for k in 0..n_axes {
            target[k] = q[k] + dir[k] / norm * len;
        }
        let feed = match rng.below(5) {
            0 => f64::INFINITY,
            1 => 5.0,
            2 => 50.0,
            _ => 20.0 + 200.0 * rng.next(),
        };
        let mut m = Move::linear(q, target, feed);
        let mut along = Along::default();
        if rng.below(6) == 0 {
            // A chord measured in part space: its length is not its axis-space length.
            m.length *= 0.5 + 1.5 * rng.next();
            along.part_dir = [rng.next(), rng.next(), rng.next()];
        } else if feed.is_finite() {
            along.part_dir = [dir[0] / norm, dir[1] / norm, 0.0];
        }
        along.step_corners = rng.below(4) == 0;
        m.stop_after = rng.below(40) == 0;
        m.dwell_after = if rng.below(60) == 0 { 0.005 } else { 0.0 };
        m.tag = moves.len() as u32;
        moves.push((m, along));
        q = target;
    }
    (start, moves)
}

#[test]
fn random_paths_planned_in_windows_are_their_whole_plans_bit_for_bit() {
    let limits = AxisLimits {
        v: [300.0, 250.0, 100.0, 8.0, 8.0, 8.0],
        a: [3000.0, 2000.0, 1000.0, 100.0, 100.0, 100.0],
        j: [60_000.0, 50_000.0, 20_000.0, 2000.0, 2000.0, 2000.0],
    };
    let mut cut = 0;
    for seed in 1..=240u64 {
        let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
        let n_axes = 2 + rng.below(3);
        let count = 20 + rng.below(400);
        let (start, moves) = random_path(&mut rng, count, n_axes);
        let cfg = PlannerConfig {
            profile: if seed % 2 == 0 {
                ProfileKind::Trapezoid
            } else {
                ProfileKind::SCurve
            },
            junction_deviation: [0.01, 0.05, 0.0, 0.2][rng.below(4)],
            path_a: if seed % 5 == 0 { 1500.0 } else { f64::INFINITY },
            n_axes,
            corners: if seed % 3 == 0 {
                Corners::JunctionDeviation
            } else {
                Corners::Blend
            },
            ..PlannerConfig::default()
        };
        let (only, along): (Vec<Move>, Vec<Along>) = moves.iter().copied().unzip();
        let whole = planner::plan_along(start, &only, &along, &limits, &cfg)
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        for min_window in [1, 2, 7, 50] {
            let mut windows = Vec::new();
            let planned = planner::plan_along_windows_sized(
                start,
                moves.iter().copied(),
                &limits,
                &cfg,
                min_window,
                |w| windows.push(w),
            )
            .unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let what = format!("seed {seed}, {cfg:?}, windows from {min_window}");
            cut += same_plan(&what, &whole, &windows, &planned);
        }
    }
    // The paths were cut into many windows, not planned whole.
    assert!(cut > 5000, "{cut} windows");
}

#[test]
fn a_refused_move_ends_the_windows_with_the_planners_error() {
    let limits = AxisLimits {
        v: [100.0; MAX_AXES],
        a: [1000.0; MAX_AXES],
        j: [f64::INFINITY; MAX_AXES],
    };
    let cfg = PlannerConfig {
        n_axes: 2,
        corners: Corners::Blend,
        ..PlannerConfig::default()
    };
    let mut moves: Vec<(Move, Along)> = (1..=100)
        .map(|k| {
            let m = Move::linear(
                [k as f64 - 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                [k as f64, 0.0, 0.0, 0.0, 0.0, 0.0],
                50.0,
            );
            (m, Along::default())
        })
        .collect();
    moves[90].0.feed = -1.0;
    let whole = planner::plan_along_iter([0.0; MAX_AXES], moves.iter().copied(), 0, &limits, &cfg);
    let windowed =
        planner::plan_along_windows_sized([0.0; MAX_AXES], moves, &limits, &cfg, 1, |_| {});
    assert_eq!(windowed.err(), whole.err());
}

/// A writer that stops early (its sink fails, a controller model refuses a line) ends the
/// second pass that plans its lit sub-blocks (`emit::PlanFacts`): the pass stops planning at
/// the next window its reader refuses, and the writer returns its own error, not a hang.
#[test]
fn a_second_pass_ends_where_its_reader_stops() {
    let mut files = MemFiles::new([("moves.lase", short_moves::recipe(20_000))]);
    let program = program_of(&mut files, "moves.lase");
    let dialect = Dialect::LinuxCnc;
    let mut facts = PlanFacts::new(&program, dialect);
    let (job, _) = motion::plan_program_windows(program, |p, w| facts.window(p, &w))
        .unwrap_or_else(|e| panic!("{e}"));
    facts.finish(&job.program);
    let mut all = 0;
    motion::replan_windows(&job, |_, _| {
        all += 1;
        true
    })
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(all > 3, "{all} windows");
    let mut read = 0;
    motion::replan_windows(&job, |_, _| {
        read += 1;
        read < 2
    })
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(read, 2, "windows read of {all}");
    // The sink fails at line 100 (of some 100 000: five held sub-blocks a move).
    let mut lines = 0;
    let r = emit::emit_planned(&job, &facts, dialect, &Default::default(), &mut |_| {
        lines += 1;
        if lines == 100 {
            return Err(std::io::Error::other("disk full"));
        }
        Ok(())
    });
    assert!(
        matches!(&r, Err(emit::EmitError::Io(e)) if e.to_string() == "disk full"),
        "{r:?}"
    );
    assert_eq!(lines, 100);
    // A controller model that refuses line 50.
    let mut lines = 0;
    let r = emit::emit_nc_lines(&job, Some(&facts), dialect, &mut |_| {
        lines += 1;
        if lines == 50 {
            return Err("refused".into());
        }
        Ok(())
    });
    assert_eq!(r, Err("refused".to_string()));
    assert_eq!(lines, 50);
}
