//! Texturing arrays (PROCESS.md §3, issue 5) measured from lase's real outputs: the pulse
//! list of `lase plan --pulses`, the summary, and the emitted NC programs. Every pulse is
//! checked against the spot lattice computed here from the recipe's numbers.

mod common;

use common::*;
use std::collections::HashMap;
use std::path::Path;

/// One pulse of `lase plan --pulses`.
#[derive(Debug, Clone, Copy)]
struct Pulse {
    t: f64,
    x: f64,
    y: f64,
    v: f64,
}

fn pulses_of(recipe: &Path) -> Vec<Pulse> {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("pulses.csv");
    let (code, _, err) = lase(&[
        "plan",
        recipe.to_str().unwrap(),
        "--pulses",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("t,px,py,pz,v,op"));
    lines
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            Pulse {
                t: f[0],
                x: f[1],
                y: f[2],
                v: f[4],
            }
        })
        .collect()
}

fn summary_of(recipe: &Path) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let (code, _, err) = lase(&[
        "plan",
        recipe.to_str().unwrap(),
        "--summary",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

/// The lattice spot (row, col) nearest to a pulse, and the distance to it, mm.
fn nearest(p: &Pulse, pitch: f64) -> ((i64, i64), f64) {
    let (r, c) = ((p.y / pitch).round() as i64, (p.x / pitch).round() as i64);
    let d = (p.x - c as f64 * pitch).hypot(p.y - r as f64 * pitch);
    ((r, c), d)
}

const ROWS: i64 = 6;
const COLS: i64 = 12;
const PASSES: usize = 5;
const PITCH: f64 = 0.2;

#[test]
fn every_spot_gets_one_pulse_per_pass_on_its_position_at_speed() {
    let pulses = pulses_of(&root().join("examples/texture_array.lase"));
    assert_eq!(pulses.len(), (ROWS * COLS) as usize * PASSES);
    let mut hits: HashMap<(i64, i64), usize> = HashMap::new();
    let mut worst = 0.0f64;
    for p in &pulses {
        let (rc, d) = nearest(p, PITCH);
        worst = worst.max(d);
        assert!(d <= 0.5e-3, "pulse {p:?} is {d} mm from spot {rc:?}");
        assert!(
            (0..ROWS).contains(&rc.0) && (0..COLS).contains(&rc.1),
            "pulse {p:?} off the array"
        );
        *hits.entry(rc).or_default() += 1;
        // On the fly every pulse fires at the programmed 20 mm/s.
        assert!(
            (p.v - 20.0).abs() <= 1e-6,
            "pulse {p:?} fired at {} mm/s",
            p.v
        );
    }
    assert_eq!(hits.len(), (ROWS * COLS) as usize);
    assert!(hits.values().all(|&n| n == PASSES));
    eprintln!("largest pulse-to-spot distance: {:.3e} mm", worst);
    // Pulses are 10 ms apart along a row: 0.2 mm at 20 mm/s.
    assert!((pulses[1].t - pulses[0].t - 0.01).abs() < 1e-9);
}

#[test]
fn serpentine_rows_alternate_and_an_even_row_count_ends_on_the_start_side() {
    let pulses = pulses_of(&root().join("examples/texture_array.lase"));
    let per_pass = (ROWS * COLS) as usize;
    for pass in pulses.chunks(per_pass) {
        for (r, row) in pass.chunks(COLS as usize).enumerate() {
            let cols: Vec<i64> = row.iter().map(|p| nearest(p, PITCH).0.1).collect();
            let rows: Vec<i64> = row.iter().map(|p| nearest(p, PITCH).0.0).collect();
            assert!(
                rows.iter().all(|&x| x == r as i64),
                "row {r} visited in order"
            );
            let expect: Vec<i64> = if r % 2 == 0 {
                (0..COLS).collect()
            } else {
                (0..COLS).rev().collect()
            };
            assert_eq!(
                cols,
                expect,
                "row {r} runs {}",
                if r % 2 == 0 { "+x" } else { "-x" }
            );
        }
        // Six rows: the pass ends at B on the start side (column 0).
        assert_eq!(nearest(pass.last().unwrap(), PITCH).0, (ROWS - 1, 0));
    }
}

#[test]
fn unidirectional_rows_all_run_forward() {
    let pulses = pulses_of(&root().join("examples/texture_array_unidirectional.lase"));
    assert_eq!(pulses.len(), (ROWS * COLS) as usize * PASSES);
    for row in pulses.chunks(COLS as usize) {
        let cols: Vec<i64> = row.iter().map(|p| nearest(p, PITCH).0.1).collect();
        assert_eq!(cols, (0..COLS).collect::<Vec<_>>());
    }
}

#[test]
fn an_odd_row_count_ends_each_pass_on_the_far_side() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = write_file(
        dir.path(),
        "odd.lase",
        "machine xy_table\nlaser { power 20 W, spot 40 um }\n\
         scan dots (0, 0) { rows 5, cols 8, pitch 0.2 mm, passes 3, speed 20 mm/s }\n",
    );
    let pulses = pulses_of(&recipe);
    assert_eq!(pulses.len(), 5 * 8 * 3);
    for pass in pulses.chunks(40) {
        assert_eq!(nearest(&pass[0], PITCH).0, (0, 0), "every pass starts at A");
        assert_eq!(nearest(pass.last().unwrap(), PITCH).0, (4, 7), "far side");
    }
}

/// One NC line: where the spot is after it, where it was before, the modal motion (G0/G1)
/// and the line's words.
struct Block {
    from: [f64; 2],
    to: [f64; 2],
    rapid: bool,
    words: Vec<(char, f64)>,
}

fn nc_path(ngc: &str) -> Vec<Block> {
    let mut pos = [0.0f64; 2];
    let mut rapid = true;
    let mut out = Vec::new();
    for line in ngc.lines() {
        let words = nc_words(line);
        let get = |c: char| words.iter().find(|(l, _)| *l == c).map(|(_, v)| *v);
        if let Some(g) = words.iter().find(|(c, v)| *c == 'G' && *v <= 3.0) {
            rapid = g.1 == 0.0;
        }
        let from = pos;
        if let Some(x) = get('X') {
            pos[0] = x;
        }
        if let Some(y) = get('Y') {
            pos[1] = y;
        }
        out.push(Block {
            from,
            to: pos,
            rapid,
            words,
        });
    }
    out
}

fn spot_distance(p: [f64; 2]) -> f64 {
    let q = Pulse {
        t: 0.0,
        x: p[0],
        y: p[1],
        v: 0.0,
    };
    nearest(&q, PITCH).1
}

#[test]
fn linuxcnc_triggers_each_pulse_where_its_spot_is_and_rs274_accepts_it() {
    let (code, ngc, err) = lase(&["emit", "examples/texture_array.lase"]);
    assert_eq!(code, 0, "{err}");
    // A synchronized `M62 P1` switches at the start of the block it stands on, which the
    // writer puts 1.5 servo periods of the rows' 20 mm/s (0.03 mm) past the spot: LinuxCNC
    // switches it that far ahead of its joints (`emit::writer::lead`).
    let path = nc_path(&ngc);
    let triggers: Vec<[f64; 2]> = path
        .iter()
        .filter(|b| b.words.contains(&('M', 62.0)) && b.words.contains(&('P', 1.0)))
        .map(|b| {
            let (dx, dy) = (b.to[0] - b.from[0], b.to[1] - b.from[1]);
            let n = dx.hypot(dy);
            [b.from[0] - 0.03 * dx / n, b.from[1] - 0.03 * dy / n]
        })
        .collect();
    assert_eq!(triggers.len(), (ROWS * COLS) as usize * PASSES);
    for t in &triggers {
        // NC numbers carry 0.1 µm.
        let d = spot_distance(*t);
        assert!(d <= 0.5e-3, "trigger at {t:?} is {d} mm off its spot");
    }
    // Every row is entered from below (+y): the last rapid before each beam-on comes up.
    let mut rows = 0;
    for (k, b) in path.iter().enumerate() {
        if b.words.contains(&('M', 62.0)) && b.words.contains(&('P', 0.0)) {
            let r = path[..k]
                .iter()
                .rev()
                .find(|b| b.rapid && b.to != b.from)
                .unwrap();
            assert!(
                r.to[1] > r.from[1] + 0.1,
                "row entered from {:?} to {:?}, not from below",
                r.from,
                r.to
            );
            rows += 1;
        }
    }
    assert_eq!(rows, ROWS as usize * PASSES);
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("t.ngc");
    std::fs::write(&f, &ngc).unwrap();
    if let Ok(out) = rs274_g(&f) {
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success() && !text.contains("error") && text.contains("PROGRAM_END"));
        // rs274's canonical calls: one SET_MOTION_OUTPUT_BIT(1) per pulse.
        assert_eq!(
            text.matches("SET_MOTION_OUTPUT_BIT(1)").count(),
            (ROWS * COLS) as usize * PASSES
        );
    }
}

#[test]
fn grbl_lights_each_spot_with_an_s_word_at_its_position() {
    let (code, nc, err) = lase(&["emit", "examples/texture_array.lase", "--dialect", "grbl"]);
    assert_eq!(code, 0, "{err}");
    let mut on = 0;
    for b in nc_path(&nc) {
        let s = b.words.iter().find(|(c, _)| *c == 'S').map(|(_, v)| *v);
        if b.to != b.from && s.is_some_and(|s| s > 0.0) {
            let d = spot_distance(b.from);
            assert!(d <= 0.5e-3, "GRBL pulse block starts {d} mm off its spot");
            on += 1;
        }
    }
    assert_eq!(on, (ROWS * COLS) as usize * PASSES);
}

#[test]
fn serpentine_idle_travel_is_a_fraction_of_the_unidirectional_one() {
    let s = summary_of(&root().join("examples/texture_array.lase"));
    let u = summary_of(&root().join("examples/texture_array_unidirectional.lase"));
    let idle = |j: &serde_json::Value| {
        j["path_length_mm"].as_f64().unwrap() - j["laser_on_length_mm"].as_f64().unwrap()
    };
    let (si, ui) = (idle(&s), idle(&u));
    eprintln!(
        "idle travel: serpentine {si:.3} mm, unidirectional {ui:.3} mm (ratio {:.2}); \
         cycle time {:.3} s vs {:.3} s",
        si / ui,
        s["cycle_time_s"].as_f64().unwrap(),
        u["cycle_time_s"].as_f64().unwrap()
    );
    assert_eq!(s["laser_on_length_mm"], u["laser_on_length_mm"]);
    assert_eq!(s["pulses"].as_u64(), Some(360));
    assert!(
        si < 0.6 * ui,
        "serpentine {si} mm vs unidirectional {ui} mm"
    );
    assert!(s["cycle_time_s"].as_f64().unwrap() < u["cycle_time_s"].as_f64().unwrap());
}

#[test]
fn dot_mode_fires_n_pulses_at_rest_on_each_spot() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = write_file(
        dir.path(),
        "dots.lase",
        "machine xy_table\nlaser { power 20 W, spot 40 um }\npulse { rate 5 kHz }\n\
         scan dots (1 mm, 2 mm) { rows 3, cols 4, pitch 0.5 mm, pulses 3, speed 10 mm/s }\n",
    );
    let pulses = pulses_of(&recipe);
    assert_eq!(pulses.len(), 3 * 4 * 3);
    for (k, trio) in pulses.chunks(3).enumerate() {
        let (r, c) = (k / 4, k % 4);
        // Serpentine in dot mode too.
        let c = if r % 2 == 0 { c } else { 3 - c };
        for p in trio {
            let (x, y) = (1.0 + c as f64 * 0.5, 2.0 + r as f64 * 0.5);
            assert!((p.x - x).hypot(p.y - y) <= 0.5e-3, "{p:?} vs ({x}, {y})");
            assert_eq!(p.v, 0.0, "dot pulses fire at rest");
        }
        // 5 kHz: 0.2 ms apart.
        assert!((trio[1].t - trio[0].t - 2e-4).abs() < 1e-9);
    }
    // 5 kHz bursts are over both controllers' pulse budgets (xy_table: LinuxCNC 500 Hz,
    // GRBL 300 Hz), refused at the scan; at 250 Hz both write every pulse.
    for dialect in ["linuxcnc", "grbl"] {
        let (code, _, err) = lase(&["emit", recipe.to_str().unwrap(), "--dialect", dialect]);
        assert_eq!(code, 1, "{dialect}: {err}");
        assert!(err.contains("lase::emit::pulse_budget"), "{dialect}: {err}");
    }
    let slow = write_file(
        dir.path(),
        "dots_250.lase",
        &std::fs::read_to_string(&recipe)
            .unwrap()
            .replace("rate 5 kHz", "rate 250 Hz"),
    );
    let (code, ngc, err) = lase(&["emit", slow.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(ngc.matches("M64 P1").count(), 36);
    let (code, nc, err) = lase(&["emit", slow.to_str().unwrap(), "--dialect", "grbl"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(nc.matches("M3 S").count(), 36);
}

#[test]
fn regions_hatches_and_explicit_spots_emit_valid_linuxcnc() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = write_file(
        dir.path(),
        "ring.lase",
        "machine xy_table\nlaser { power 20 W, spot 40 um }\n\
         let ring = [profile circle((0, 0), 2.5 mm), profile circle((0, 0), 1.5 mm)]\n\
         scan dots ring { pitch 0.2 mm, passes 2, speed 20 mm/s }\n\
         scan raster profile rect((5 mm, 0), 2 mm, 1 mm) { pitch 0.25 mm, angle 30 deg, cross, \
         inset 0.1 mm, speed 50 mm/s }\n\
         scan dots [(20 mm, 0), (20.3 mm, 0), (20.6 mm, 0), (21 mm, 0)] { speed 10 mm/s, mode dot }\n",
    );
    let pulses = pulses_of(&recipe);
    // Ring pulses: every spot of the lattice with 1.5 ≤ r ≤ 2.5, twice.
    let mut expect = 0;
    for r in -13i64..=13 {
        for c in -13i64..=13 {
            let d = (r as f64 * 0.2).hypot(c as f64 * 0.2);
            if (1.5 - 1e-6..=2.5 + 1e-6).contains(&d) {
                expect += 1;
            }
        }
    }
    let ring: Vec<&Pulse> = pulses.iter().filter(|p| p.x < 4.0).collect();
    assert_eq!(ring.len(), 2 * expect);
    for p in &ring {
        let r = p.x.hypot(p.y);
        assert!(
            (1.5 - 1e-6..=2.5 + 1e-6).contains(&r),
            "{p:?} outside the ring"
        );
        assert!((p.v - 20.0).abs() < 1e-6);
    }
    assert_eq!(pulses.iter().filter(|p| p.x > 19.0).count(), 4);
    let (code, ngc, err) = lase(&["emit", recipe.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let f = dir.path().join("ring.ngc");
    std::fs::write(&f, &ngc).unwrap();
    if let Ok(out) = rs274_g(&f) {
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && !text.contains("error") && text.contains("PROGRAM_END"),
            "{text}"
        );
    }
}

#[test]
fn a_pulse_rate_above_the_laser_says_the_fastest_speed() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = write_file(
        dir.path(),
        "fast.lase",
        "machine xy_table\nlaser { power 20 W }\n\
         scan dots (0, 0) { rows 2, cols 10, pitch 1 um, speed 200 mm/s }\n",
    );
    let (code, _, err) = lase(&["check", recipe.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::eval::pulse_rate"), "{err}");
    assert!(
        err.contains("200000 Hz") && err.contains("100000 Hz"),
        "{err}"
    );
    assert!(err.contains("fastest allowed speed is 100 mm/s"), "{err}");
}

#[test]
fn bad_scans_get_diagnostics_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    for (body, want) in [
        (
            "scan dots (0, 0) { rows 2, cols 3, pitch 0.2 mm, pulses 3, mode fly, speed 5 mm/s }",
            "cannot be fired on the fly",
        ),
        (
            "scan dots (0, 0) { pitch 0.2 mm, speed 5 mm/s }",
            "needs `rows` and `cols`",
        ),
        (
            "scan dots (0, 0) { rows 2, cols 2, pitch 0.2 mm }",
            "needs a `speed`",
        ),
        (
            "scan raster profile circle((0, 0), 1 mm) { speed 5 mm/s }",
            "needs a `pitch`",
        ),
        (
            "scan raster profile line((0, 0), (1 mm, 0)) { pitch 0.1 mm, speed 5 mm/s }",
            "region needs closed profiles",
        ),
        (
            "scan dots (0, 0) { rows 2, cols 2, pitch 0.2 mm, speed 20 mm/s, overscan 1 um }",
            "shorter than",
        ),
        ("scan spiral (0, 0) { speed 20 mm/s }", "scan kinds"),
        (
            "scan raster (0, 0) { speed 20 mm/s, pitch 1 mm }",
            "region of `scan raster`",
        ),
        (
            "scan dots (0, 0) { rows 2, cols 2, pitch 0.2 mm, speed 20 mm/s, order zigzag }",
            "serpentine",
        ),
    ] {
        let recipe = write_file(
            dir.path(),
            "bad.lase",
            &format!("machine xy_table\nlaser {{ power 20 W }}\n{body}\n"),
        );
        let (code, _, err) = lase(&["check", recipe.to_str().unwrap()]);
        assert_eq!(code, 1, "{body}: {err}");
        assert!(err.contains(want), "{body}: expected `{want}` in\n{err}");
        assert!(err.contains("help"), "{body}: no help in\n{err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn a_pso_post_configures_distance_firing_once_per_pitch() {
    let dir = tempfile::tempdir().unwrap();
    let toml = lase_stdlib::machine("xy_table").unwrap().replace(
        "pulse_on = [\"M62 P1\"]",
        "pso = [\"M68 E1 Q{pitch}\"]\npulse_on = [\"M62 P1\"]",
    );
    std::fs::write(dir.path().join("pso.toml"), toml).unwrap();
    let recipe = write_file(
        dir.path(),
        "pso.lase",
        "machine \"pso.toml\"\nlaser { power 20 W, spot 40 um }\n\
         scan dots (0, 0) { rows 4, cols 50, pitch 0.2 mm, passes 2, speed 20 mm/s }\n",
    );
    let (code, ngc, err) = lase(&["emit", recipe.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(ngc.matches("M68 E1 Q0.2").count(), 1, "{ngc}");
    assert_eq!(ngc.matches("M62 P1").count(), 0);
    // One beam-on per row and pass, each a single block through the row.
    assert_eq!(ngc.matches("M62 P0").count(), 8);
    assert_eq!(pulses_of(&recipe).len(), 4 * 50 * 2);
}

/// The row's speed before its first pulse, from the sampled trace (`lase plan --trace` at
/// 1 ms), recomputed from the spot positions: the ramp ends `PULSE_CRUISE_MARGIN_S` (5 ms)
/// or more before the first spot of each row, so every whole 1 ms window of the trace's grid in
/// the 5 ms before it (at least four) runs at the scan speed. (Before the margin the first spot sat where the ramp ends: the millisecond
/// before it averaged 19.95 of 20 mm/s.)
#[test]
fn every_row_of_a_dot_array_is_at_cruise_before_its_first_pulse_in_the_trace() {
    for ex in ["texture_array", "texture_array_unidirectional"] {
        let recipe = root().join(format!("examples/{ex}.lase"));
        let pulses = pulses_of(&recipe);
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("trace.csv");
        let (code, _, err) = lase(&[
            "plan",
            recipe.to_str().unwrap(),
            "--trace",
            csv.to_str().unwrap(),
            "--period",
            "1ms",
        ]);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(csv).unwrap();
        let mut lines = text.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
        let (ct, cx, cy) = (col("t"), col("px"), col("py"));
        let rows: Vec<(f64, f64, f64)> = lines
            .map(|l| {
                let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                (f[ct], f[cx], f[cy])
            })
            .collect();
        // First pulse of each row: none in the 1.5 pulse periods (15 ms) before it.
        let firsts: Vec<f64> = pulses
            .iter()
            .enumerate()
            .filter(|(i, p)| *i == 0 || p.t - pulses[i - 1].t > 0.015)
            .map(|(_, p)| p.t)
            .collect();
        assert_eq!(
            firsts.len(),
            ROWS as usize * PASSES,
            "{ex}: one start per row"
        );
        let mut slowest = f64::INFINITY;
        for &tp in &firsts {
            // Whole 1 ms windows [t − 1 ms, t] of the trace grid inside [tp − 5 ms, tp].
            let windows = rows
                .windows(2)
                .filter(|w| w[0].0 >= tp - 0.005 - 1e-9 && w[1].0 <= tp + 1e-9);
            let mut n = 0;
            for w in windows {
                let v = (w[1].1 - w[0].1).hypot(w[1].2 - w[0].2) / (w[1].0 - w[0].0);
                slowest = slowest.min(v);
                // 6-decimal positions: 1.4e-3 mm/s of rounding over 1 ms.
                assert!(
                    (v - 20.0).abs() <= 4e-3,
                    "{ex}: {v} mm/s in the ms before {} s, {} ms before the first pulse at {tp} s",
                    w[1].0,
                    (tp - w[1].0) * 1e3
                );
                n += 1;
            }
            assert!(n >= 4, "{ex}: {n} whole windows before {tp}");
        }
        eprintln!("{ex}: slowest 1 ms before a row's first pulse: {slowest:.4} mm/s");
    }
}
