//! Row-start settling (issue 15) run by a real, headless LinuxCNC 2.9 (`common::linuxcnc`):
//! `examples/texture_array.lase` with `settle`, its `o<lase_settle>` subroutine reading X and
//! Y scales that HAL models off the joints by a constant and a length error
//! (`config::ScaleError`). From the HAL samples (1 ms), at each row start: what the scales read
//! when the approach arrived (open loop) and when the table last stood there before its row
//! (settled), against the target the program names; and how many corrective moves it took.
//! Skips, saying so, without LinuxCNC (or with `LASE_LINUXCNC_TESTS=0`).
//!
//! `cargo test --test linuxcnc_settle -- --nocapture`

mod common;

use common::linuxcnc::{Headless, Sample, available};
use lase_runtime::compile::MemFiles;
use lase_runtime::emit::{Dialect, emit_to_string};
use lase_runtime::link::linuxcnc::config::ScaleError;

/// The injected error: X reads 3.7 µm long plus 1.5 µm per mm of travel, Y 4.2 µm short and
/// 1 µm per mm short — every row start (x = −0.537 or 2.737 mm, the rows' run-ups; y = 0 …
/// 1 mm) off by 2.9 or 7.8 µm along and 4.2 … 5.2 µm across, outside the seed's window.
const SCALES: ScaleError = ScaleError {
    offset_mm: [0.0037, -0.0042],
    gain: [1.0015, 0.999],
};

/// The settle calls of a LinuxCNC program in order: target X, Y and row direction.
fn settle_calls(nc: &str) -> Vec<([f64; 2], [f64; 2])> {
    nc.lines()
        .filter_map(|l| l.strip_prefix("o<lase_settle> call "))
        .map(|args| {
            let v: Vec<f64> = args
                .split(['[', ']'])
                .filter(|w| !w.trim().is_empty())
                .map(|w| w.trim().parse().unwrap())
                .collect();
            ([v[0], v[1]], [v[2], v[3]])
        })
        .collect()
}

/// One row start as LinuxCNC ran it.
#[derive(Debug)]
struct RowStart {
    /// Scale error along and across the row (µm) when the approach had arrived.
    open: (f64, f64),
    /// The same when the table last stood there before its row ran.
    settled: (f64, f64),
    /// Moves from arrival to the settled rest (each step's one or two).
    moves: usize,
    /// Corrective steps of 0.5 µm: the larger of the corrections along and across over it.
    steps: f64,
    /// From arrival to the settled rest, ms (the time settling costs the row).
    ms: usize,
}

/// Along/across error (µm) of the scales' reading in `s` from `target` on a row along `u`.
fn error(s: &Sample, target: [f64; 2], u: [f64; 2]) -> (f64, f64) {
    let dx = s.ain[0] - target[0];
    let dy = s.ain[1] - target[1];
    ((dx * u[0] + dy * u[1]) * 1e3, (dy * u[0] - dx * u[1]) * 1e3)
}

/// Each row start in the samples: the table comes within `NEAR` of the target, rests, steps,
/// and leaves on its row; the settled position is the last sample at rest before it leaves.
/// `None` when the samples end before a row start (the program ended early).
fn row_starts(samples: &[Sample], calls: &[([f64; 2], [f64; 2])]) -> Option<Vec<RowStart>> {
    const NEAR: f64 = 0.03; // mm: wider than the error and the preload, short of a pitch
    let near = |s: &Sample, t: [f64; 2]| {
        (s.joints[0] - t[0]).abs() < NEAR && (s.joints[1] - t[1]).abs() < NEAR
    };
    // At rest: three samples alike (a reversal's one slow sample is not a rest).
    let rest = |k: usize| {
        k > 1
            && samples[k].joints == samples[k - 1].joints
            && samples[k].joints == samples[k - 2].joints
    };
    let mut out = Vec::new();
    let mut k = 0;
    for &(t, u) in calls {
        // Arrival: the first sample at rest near the target.
        while k < samples.len() && !(near(&samples[k], t) && rest(k)) {
            k += 1;
        }
        if k >= samples.len() {
            eprintln!("row start {t:?} never reached");
            return None;
        }
        let arrived = k;
        let mut last_rest = k;
        let mut moves: usize = 0;
        // A move starts where the table leaves a stand of two samples alike or more: between
        // two steps LinuxCNC may rest for only a period or two (a busy machine's CI once
        // counted 14 moves for 15 steps with three), and a reversal counted as a rest only
        // adds a move to a count that is held as a least.
        let still = |k: usize| k > 0 && samples[k].joints == samples[k - 1].joints;
        while k < samples.len() && near(&samples[k], t) {
            if rest(k) {
                last_rest = k;
            }
            if !still(k) && still(k - 1) {
                moves += 1;
            }
            k += 1;
        }
        // The row's own first move left the rest too.
        moves = moves.saturating_sub(1);
        let open = error(&samples[arrived], t, u);
        let settled = error(&samples[last_rest], t, u);
        out.push(RowStart {
            open,
            settled,
            moves,
            steps: ((settled.0 - open.0).abs()).max((settled.1 - open.1).abs()) / 0.5,
            ms: last_rest - arrived,
        });
    }
    Some(out)
}

#[test]
fn linuxcnc_settles_every_row_start_on_scales_with_an_injected_error() {
    if !available() {
        return;
    }
    let src = std::fs::read_to_string(common::root().join("examples/texture_array.lase"))
        .unwrap()
        .replace("order serpentine }", "order serpentine, settle }");
    let mut files = MemFiles::new([("texture_settle.lase", src.as_str())]);
    let (_, job) = lase_runtime::compile(&mut files, "texture_settle.lase")
        .unwrap_or_else(|(_, f)| panic!("{f}"));
    let nc = emit_to_string(&job, Dialect::LinuxCnc).unwrap();
    let calls = settle_calls(&nc);
    assert_eq!(calls.len(), 30, "6 rows × 5 passes");

    let m =
        lase_runtime::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    let mut lcnc = Headless::with_scales(&m, Some(SCALES));
    // On this loaded computer LinuxCNC sometimes reports a program IDLE part-way, without an
    // error, and the table stays where it was (seen once in three runs, at a row start after
    // a settling step): the intermittent early end `common::linuxcnc` describes. Such a run
    // is told and run again, up to three times.
    let mut attempt = 0;
    let (samples, rows, wall) = loop {
        attempt += 1;
        let t0 = std::time::Instant::now();
        let samples = lcnc.run_program(&format!("texture_settle{attempt}.ngc"), &nc);
        let wall = t0.elapsed().as_secs_f64();
        match row_starts(&samples, &calls) {
            Some(rows) => break (samples, rows, wall),
            None if attempt < 3 => eprintln!("run {attempt} ended early: run again"),
            None => panic!("three runs ended early"),
        }
    };
    drop(lcnc);
    assert!(samples.iter().all(|s| s.ain.len() == 2));
    // The scales read what the model says of the joints.
    for s in samples.iter().step_by(97) {
        let r = SCALES.reading(s.joints[0], s.joints[1]);
        assert!((r[0] - s.ain[0]).abs() < 2e-6 && (r[1] - s.ain[1]).abs() < 2e-6);
    }
    let stat = |f: &dyn Fn(&RowStart) -> f64| {
        let v: Vec<f64> = rows.iter().map(f).collect();
        let worst = v.iter().fold(0f64, |m, e| m.max(e.abs()));
        (
            worst,
            v.iter().map(|e| e.abs()).sum::<f64>() / v.len() as f64,
        )
    };
    let (ow, om) = stat(&|r| r.open.0);
    let (sw, sm) = stat(&|r| r.settled.0);
    let (cw, _) = stat(&|r| r.settled.1);
    let steps: f64 = rows.iter().map(|r| r.steps).sum();
    let max_steps = rows.iter().map(|r| r.steps).fold(0.0, f64::max);
    let mean_ms = rows.iter().map(|r| r.ms).sum::<usize>() as f64 / rows.len() as f64;
    let max_ms = rows.iter().map(|r| r.ms).max().unwrap();
    let run_s = samples.len() as f64 * 1e-3;
    eprintln!(
        "LinuxCNC settle, 30 row starts: open loop |along| worst {ow:.2} µm, mean {om:.2} µm; \
         settled |along| worst {sw:.2} µm, mean {sm:.2} µm, |across| worst {cw:.2} µm; \
         steps {steps:.0} (most {max_steps:.0} at a row); settling {mean_ms:.0} ms a row (most \
         {max_ms} ms); {run_s:.1} s of samples, {wall:.1} s wall"
    );
    for (k, r) in rows.iter().enumerate() {
        eprintln!(
            "  row {k:2}: open {:+6.2} {:+6.2} µm, settled {:+6.2} {:+6.2} µm, {:.0} steps, {} moves, {} ms",
            r.open.0, r.open.1, r.settled.0, r.settled.1, r.steps, r.moves, r.ms
        );
    }
    for (k, r) in rows.iter().enumerate() {
        // Open loop every row start is off by the model's 2.9 µm or more.
        assert!(
            r.open.0.abs() > 2.5 && r.open.1.abs() > 4.0,
            "row {k}: {r:?}"
        );
        // Settled: within the window along (a reading on its edge counts), ±1 µm across.
        assert!(
            (-0.5 - 1e-3..=1.5 + 1e-3).contains(&r.settled.0),
            "row {k}: {r:?}"
        );
        assert!(r.settled.1.abs() <= 1.0 + 1e-3, "row {k}: {r:?}");
        // Each took the steps its error asks for (≥ 3.5 µm across: 7 steps), none more
        // than the recipe's 20.
        assert!((7.0..=20.0).contains(&r.steps.round()), "row {k}: {r:?}");
        assert!(r.moves as f64 >= r.steps.round(), "row {k}: {r:?}");
    }
}
