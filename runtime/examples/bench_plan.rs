//! End-to-end planner benchmark on a generated path (CONVENTIONS.md: the input is generated,
//! not checked in), and a planning front end for `scripts/toppra_compare.py`.
//!
//! ```text
//! cargo run --release --example bench_plan -- 1000000
//! cargo run --release --example bench_plan -- --sweep
//! cargo run --release --example bench_plan -- 1000000 --windows
//! cargo run --release --example bench_plan -- --polyline path.csv [--jd 0.01] [--v 250]
//!     [--a 2000] [--j 50000] [--profile trapezoid|scurve]
//! cargo run --release --example bench_plan -- --path pieces.txt [--arc-tol 0.002] [...]
//! ```
//!
//! The first form (`--profile` picks one profile) generates an N-segment cornered 2-axis path (chords of 0.2–2 mm turning by
//! 0–150° at every junction, kept inside a 200 × 200 mm field, a stop every 10 000 moves) and
//! an N-segment path of an oriented machine (X and three joints, part-space chords, corners
//! judged per axis), plans each offline with the trapezoid and the S-curve profile, and prints segments/s (one
//! core; the best run by the wall clock, and the mean of the planning thread's own CPU time, which
//! other processes on a shared machine do not inflate), the memory planning takes per segment
//! (counted by a counting global allocator: the bytes the plan holds, and all bytes allocated
//! while planning, scratch included, over N) and the cycle time. Small N are planned more times
//! (at least 3, about 2 M segments in all) so the clock has something to measure.
//! `--sweep` runs N = 10⁴, 10⁵, 10⁶ and 10⁷, to show the cost per segment stays flat.
//! `--windows` plans in windows (`planner::plan_along_windows`, what `lase check` and `lase
//! emit` do), each window read into the fingerprint and dropped: the fingerprint is the whole
//! plan's, and the bytes held after planning are none.
//!
//! The second form plans the polyline in a CSV file (one `x,y` point in mm per line, the first
//! is the start) and prints `{"segments": n, "duration_s": t, ...}` as JSON.
//!
//! The third form reads a path of lines and circular arcs (`start x y`, then `line x y` and
//! `arc x y cx cy ccw|cw` pieces, one a line, mm) and lowers it as `lase plan` does for a
//! Cartesian machine before planning it: lines whole, every arc through lase's own
//! [`arc_points`] at the machine's arc tolerance (`--arc-tol`, default 0.002 mm as a machine
//! file without `arc_tolerance`). So `scripts/toppra_compare.py` times lase's plan of lase's
//! own chords, not a Python imitation of them. It prints the same JSON, with `"moves"`.

use lase_runtime::motion::arc_points;
use lase_runtime::planner::{
    Along, AxisLimits, MAX_AXES, Move, Plan, PlannerConfig, ProfileKind, Segment, plan,
    plan_along_windows,
};
use std::time::Instant;

/// Every allocation counted (a counting global allocator, not RSS: resident memory moves in
/// pages and lags the heap, which made small runs print 0 or 16 bytes per segment).
#[global_allocator]
static ALLOC: cap::Cap<std::alloc::System> = cap::Cap::new(std::alloc::System, usize::MAX);

/// CPU time this thread has run, in s (`/proc/thread-self/schedstat`, ns on the CPU): on a
/// machine shared with other work, the wall clock counts the time other processes hold the
/// core, the thread's own CPU time does not.
fn cpu_time() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: u64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns as f64 * 1e-9)
}

struct Options {
    v: f64,
    a: f64,
    j: f64,
    jd: f64,
    arc_tol: f64,
    profile: Option<ProfileKind>,
    /// Plan in windows (`planner::plan_along_windows`), each read and dropped.
    windows: bool,
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut opts = Options {
        v: 250.0,
        a: 2000.0,
        j: 50_000.0,
        jd: 0.01,
        arc_tol: 0.002,
        profile: None,
        windows: false,
    };
    let mut n = 1_000_000usize;
    let mut polyline: Option<String> = None;
    let mut pieces: Option<String> = None;
    let mut sweep = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| -> f64 {
            it.next()
                .and_then(|s| s.parse().ok())
                .unwrap_or_else(|| fail(&format!("{name} needs a number")))
        };
        match a.as_str() {
            "--v" => opts.v = value("--v"),
            "--a" => opts.a = value("--a"),
            "--j" => opts.j = value("--j"),
            "--jd" => opts.jd = value("--jd"),
            "--arc-tol" => opts.arc_tol = value("--arc-tol"),
            "--profile" => {
                opts.profile = match it.next().map(String::as_str) {
                    Some("trapezoid") => Some(ProfileKind::Trapezoid),
                    Some("scurve") => Some(ProfileKind::SCurve),
                    _ => fail("--profile is trapezoid or scurve"),
                }
            }
            "--polyline" => polyline = it.next().cloned(),
            "--path" => pieces = it.next().cloned(),
            "--sweep" => sweep = true,
            "--windows" => opts.windows = true,
            s => {
                n = s
                    .parse()
                    .unwrap_or_else(|_| fail(&format!("unknown argument `{s}`")))
            }
        }
    }
    if let Some(path) = pieces {
        return plan_pieces(&path, &opts);
    }
    match polyline {
        Some(path) => plan_polyline(&path, &opts),
        None if sweep => {
            for n in [10_000, 100_000, 1_000_000, 10_000_000] {
                throughput(n, &opts);
            }
        }
        None => throughput(n, &opts),
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("bench_plan: {msg}");
    std::process::exit(2)
}

fn limits(o: &Options) -> AxisLimits {
    AxisLimits {
        v: [o.v; MAX_AXES],
        a: [o.a; MAX_AXES],
        j: [o.j; MAX_AXES],
    }
}

fn config(profile: ProfileKind, jd: f64) -> PlannerConfig {
    PlannerConfig {
        profile,
        junction_deviation: jd,
        n_axes: 2,
        ..PlannerConfig::default()
    }
}

/// Deterministic uniform numbers in [0, 1) (xorshift64).
fn uniform(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A deterministic cornered path: xorshift-driven turns and lengths, reflected at the field's
/// edges, feed 100 mm/s, a stop every 10 000 moves.
fn cornered_path(n: usize) -> Vec<Move> {
    let mut rnd = uniform(0x9e37_79b9_7f4a_7c15);
    let mut moves = Vec::with_capacity(n);
    let mut q = [0.0; MAX_AXES];
    let mut heading: f64 = 0.0;
    for k in 0..n {
        let turn = (rnd() * 150.0).to_radians() * if rnd() < 0.5 { 1.0 } else { -1.0 };
        heading += turn;
        let len = 0.2 + 1.8 * rnd();
        let mut t = q;
        t[0] += len * heading.cos();
        t[1] += len * heading.sin();
        for axis in 0..2 {
            if t[axis].abs() > 100.0 {
                t[axis] = q[axis] - (t[axis] - q[axis]);
                heading = if axis == 0 {
                    std::f64::consts::PI - heading
                } else {
                    -heading
                };
            }
        }
        let mut m = Move::linear(q, t, 100.0);
        m.stop_after = k % 10_000 == 9_999;
        m.tag = k as u32;
        moves.push(m);
        q = t;
    }
    moves
}

/// A deterministic path of an oriented machine, like the arm's: X (mm) and three joints (rad)
/// along a smooth curve, each move a part-space chord of 0.2–2 mm whose length is not its
/// axis-space length (so corners are judged per axis), the joints' rates drifting and
/// reversing, feed 10 mm/s, a stop every 10 000 moves.
fn oriented_path(n: usize) -> Vec<Move> {
    let mut rnd = uniform(0x2545_f491_4f6c_dd1d);
    let mut moves = Vec::with_capacity(n);
    let mut q = [0.0; MAX_AXES];
    let mut s = 0.0f64;
    for k in 0..n {
        let len = 0.2 + 1.8 * rnd();
        s += len;
        let mut t = q;
        // Slide X steps 2 mm every 2 000 moves; the joints follow slow waves of the arc length.
        t[0] = 2.0 * (k / 2_000) as f64;
        t[1] = 0.6 * (s / 37.0).sin();
        t[2] = 0.9 * (s / 23.0).cos();
        t[3] = 0.3 * (s / 11.0).sin();
        let mut m = Move::new(t, len, 10.0);
        m.stop_after = k % 10_000 == 9_999;
        m.tag = k as u32;
        moves.push(m);
        q = t;
    }
    moves
}

/// FNV-1a over the bits of every number of the plan: equal fingerprints mean bit-identical
/// plans (a refactoring of the planner must keep it).
/// `moves` planned in windows (`planner::plan_along_windows`), each handed to `each`.
fn plan_in_windows(
    moves: &[Move],
    lim: &AxisLimits,
    cfg: &PlannerConfig,
    each: impl FnMut(Plan),
) -> lase_runtime::planner::Planned {
    let along = moves.iter().map(|m| (*m, Along::default()));
    plan_along_windows([0.0; MAX_AXES], along, lim, cfg, each)
        .unwrap_or_else(|e| fail(&format!("planning failed: {e}")))
}

fn fingerprint(p: &Plan) -> u64 {
    let mut h = FNV;
    fingerprint_segments(&mut h, p);
    fingerprint_end(&mut h, p.duration());
    h
}

const FNV: u64 = 0xcbf2_9ce4_8422_2325;

fn fingerprint_eat(h: &mut u64, x: u64) {
    for b in x.to_le_bytes() {
        *h = (*h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
}

/// The plan's duration closes the fingerprint.
fn fingerprint_end(h: &mut u64, duration: f64) {
    fingerprint_eat(h, duration.to_bits());
}

/// Feeds a plan's (or a window's) segments into a fingerprint: the windows of a plan feed the
/// whole plan's.
fn fingerprint_segments(h: &mut u64, p: &Plan) {
    let mut eat = |x: u64| fingerprint_eat(h, x);
    for (i, s) in p.segments().iter().enumerate() {
        for x in [
            s.t_start, s.s_start, s.length, s.v_entry, s.v_peak, s.v_exit, s.t_j1, s.t_a1,
            s.t_cruise, s.t_j2, s.t_a2, s.dwell, s.feed,
        ] {
            eat(x.to_bits());
        }
        eat(((s.tag as u64) << 32) | s.move_index as u64);
        for x in p.segment_target(i) {
            eat(x.to_bits());
        }
    }
}

fn throughput(n: usize, o: &Options) {
    let cornered = cornered_path(n);
    let oriented = oriented_path(n);
    let lim = limits(o);
    println!(
        "{n} segments, input {} bytes/segment (Move), axis v {} mm/s, a {} mm/s², j {} mm/s³, \
         junction deviation {} mm",
        std::mem::size_of::<Move>(),
        o.v,
        o.a,
        o.j,
        o.jd
    );
    for (name, profile, moves, n_axes) in [
        ("trapezoid", ProfileKind::Trapezoid, &cornered, 2),
        ("s-curve", ProfileKind::SCurve, &cornered, 2),
        // Part-space chords of an X + 3 joints machine: the per-axis corner rule.
        ("trapezoid, oriented", ProfileKind::Trapezoid, &oriented, 4),
        ("s-curve, oriented", ProfileKind::SCurve, &oriented, 4),
    ] {
        if o.profile.is_some_and(|p| p != profile) {
            continue;
        }
        let cfg = PlannerConfig {
            n_axes,
            ..config(profile, o.jd)
        };
        let mut best = f64::INFINITY;
        // CPU time is summed over the runs: the scheduler's count is too coarse for one run of
        // a small N (it read 0 s, and the rate came out infinite).
        let (mut cpu_total, mut cpu_runs) = (0.0, 0usize);
        let (mut held, mut churn) = (0usize, 0usize);
        let mut cycle = 0.0;
        let mut print = 0;
        let runs = (2_000_000 / n.max(1)).clamp(3, 200);
        for _ in 0..runs {
            let (live0, total0) = (ALLOC.allocated(), ALLOC.total_allocated());
            let t0 = Instant::now();
            let c0 = cpu_time();
            if o.windows {
                // Planned in windows, each dropped once it is read (the fingerprint is taken
                // after the timed runs, as the whole plan's is).
                let planned = plan_in_windows(moves, &lim, &cfg, |w| {
                    std::hint::black_box(&w);
                });
                best = best.min(t0.elapsed().as_secs_f64());
                if let (Some(c0), Some(c1)) = (c0, cpu_time()) {
                    cpu_total += c1 - c0;
                    cpu_runs += 1;
                }
                held = ALLOC.allocated().saturating_sub(live0);
                churn = ALLOC.total_allocated().saturating_sub(total0);
                cycle = planned.duration;
                continue;
            }
            let p = plan([0.0; MAX_AXES], moves, &lim, &cfg)
                .unwrap_or_else(|e| fail(&format!("planning failed: {e}")));
            best = best.min(t0.elapsed().as_secs_f64());
            if let (Some(c0), Some(c1)) = (c0, cpu_time()) {
                cpu_total += c1 - c0;
                cpu_runs += 1;
            }
            held = ALLOC.allocated().saturating_sub(live0);
            churn = ALLOC.total_allocated().saturating_sub(total0);
            cycle = p.duration();
            print = fingerprint(&p);
            std::hint::black_box(&p);
        }
        if o.windows {
            let mut h = FNV;
            let planned = plan_in_windows(moves, &lim, &cfg, |w| fingerprint_segments(&mut h, &w));
            fingerprint_end(&mut h, planned.duration);
            print = h;
        }
        let per_n = |b: usize| b as f64 / n.max(1) as f64;
        // The streaming look-ahead on the first 100 000 moves, for its fingerprint.
        let window = PlannerConfig {
            lookahead: Some(64),
            ..cfg
        };
        let streamed = plan([0.0; MAX_AXES], &moves[..n.min(100_000)], &lim, &window)
            .unwrap_or_else(|e| fail(&format!("planning failed: {e}")));
        println!(
            "{name:>19}: {:6.2} M segments/s wall (best of {runs}), {:6.2} M/s CPU time (mean), {:.1} bytes/segment \
             held by the plan ({:.1} allocated while planning; Segment is {} bytes), cycle time \
             {:.3} s, fingerprint {print:016x} (window 64: {:016x})",
            n as f64 / best.max(1e-9) / 1e6,
            if cpu_total > 0.0 {
                (n * cpu_runs) as f64 / cpu_total / 1e6
            } else {
                f64::NAN
            },
            per_n(held),
            per_n(churn),
            std::mem::size_of::<Segment>(),
            cycle,
            fingerprint(&streamed)
        );
    }
}

fn plan_polyline(path: &str, o: &Options) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| fail(&format!("{path}: {e}")));
    let mut pts = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let xy: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| fail(&format!("{path}:{}: {e}", i + 1)));
        if xy.len() != 2 {
            fail(&format!("{path}:{}: expected x,y", i + 1));
        }
        let mut q = [0.0; MAX_AXES];
        q[0] = xy[0];
        q[1] = xy[1];
        pts.push(q);
    }
    let Some(&start) = pts.first() else {
        fail("the polyline is empty")
    };
    let moves: Vec<Move> = pts
        .windows(2)
        .map(|w| Move::linear(w[0], w[1], f64::INFINITY))
        .collect();
    report(start, &moves, o);
}

/// Plans `moves` from `start` and prints the JSON line the comparison script reads.
fn report(start: [f64; MAX_AXES], moves: &[Move], o: &Options) {
    let profile = o.profile.unwrap_or(ProfileKind::Trapezoid);
    let t0 = Instant::now();
    let p = plan(start, moves, &limits(o), &config(profile, o.jd))
        .unwrap_or_else(|e| fail(&format!("planning failed: {e}")));
    let dt = t0.elapsed().as_secs_f64();
    println!(
        "{{\"moves\": {}, \"segments\": {}, \"duration_s\": {}, \"profile\": \"{}\", \
         \"junction_deviation\": {}, \"plan_seconds\": {}}}",
        moves.len(),
        p.segments().len(),
        p.duration(),
        if profile == ProfileKind::SCurve {
            "scurve"
        } else {
            "trapezoid"
        },
        o.jd,
        dt
    );
}

/// Lines and arcs lowered to planner moves as `lase plan` lowers them on a Cartesian machine
/// (`motion::plan_program`: a line is one move, an arc its [`arc_points`] chords; feed
/// unbounded, so the axis limits alone bound the speed, as they bound TOPP-RA's).
fn plan_pieces(path: &str, o: &Options) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| fail(&format!("{path}: {e}")));
    let mut start: Option<[f64; 3]> = None;
    let mut pos = [0.0; 3];
    let mut moves = Vec::new();
    let axes = |p: [f64; 3]| {
        let mut q = [0.0; MAX_AXES];
        q[..3].copy_from_slice(&p);
        q
    };
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let at = |msg: &str| -> ! { fail(&format!("{path}:{}: {msg}", i + 1)) };
        let num = |k: usize| -> f64 {
            words
                .get(k)
                .and_then(|w| w.parse().ok())
                .unwrap_or_else(|| at("expected a number"))
        };
        let to = [num(1), num(2), 0.0];
        match (words[0], start.is_some()) {
            ("start", false) => {
                start = Some(to);
                pos = to;
                continue;
            }
            (_, false) => at("the path begins with `start x y`"),
            ("line", true) => moves.push(Move::linear(axes(pos), axes(to), f64::INFINITY)),
            ("arc", true) => {
                let ccw = match words.get(5) {
                    Some(&"ccw") => true,
                    Some(&"cw") => false,
                    _ => at("an arc ends with ccw or cw"),
                };
                let mut from = pos;
                for p in arc_points(pos, to, [num(3), num(4)], ccw, o.arc_tol) {
                    moves.push(Move::linear(axes(from), axes(p), f64::INFINITY));
                    from = p;
                }
            }
            (w, true) => at(&format!("unknown piece `{w}` (line, arc)")),
        }
        pos = to;
    }
    let Some(start) = start else {
        fail("the path is empty")
    };
    report(axes(start), &moves, o);
}
