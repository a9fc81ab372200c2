//! `lase plan --trace`'s `pulses` column (docs/reference.md, "Trace columns") for dot-mode
//! pulses, fired at rest: it counts exactly the plan's pulses, and each one where the plan
//! fires it — the rows where the count rises stand at a planned spot.

mod common;

use common::*;
use lase_runtime::report::{pulse_events, summarize, write_trace};

#[test]
fn the_trace_counts_dot_mode_pulses_at_their_spots() {
    // 3 × 4 spots at 0.5 mm from (1 mm, 2 mm), two pulses of 5 kHz at rest on each: windows
    // of 0.4 ms, sampled every 0.1 ms.
    let j = job(
        "machine xy_table\nlaser { power 20 W, spot 40 um }\npulse { rate 5 kHz }\n\
         scan dots (1 mm, 2 mm) { rows 3, cols 4, pitch 0.5 mm, pulses 2, speed 10 mm/s, mode dot }\n",
    );
    let planned = summarize(&j).pulses;
    assert_eq!(planned, 24);
    assert_eq!(pulse_events(&j).count() as u64, planned);
    let mut out = Vec::new();
    write_trace(&j, 1e-4, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (px, py, laser, pulses) = (col("px"), col("py"), col("laser"), col("pulses"));
    // Pulses counted at each planned spot, from the rows where the column rises.
    let mut at = std::collections::BTreeMap::<(i64, i64), u64>::new();
    let mut last = 0u64;
    for l in lines {
        let w: Vec<&str> = l.split(',').collect();
        let n: u64 = w[pulses].parse().unwrap();
        if n > last {
            let (x, y): (f64, f64) = (w[px].parse().unwrap(), w[py].parse().unwrap());
            // On the 0.5 mm grid from (1, 2) mm, to the trace's 6 decimals.
            let (c, r) = ((x - 1.0) / 0.5, (y - 2.0) / 0.5);
            assert!(
                (c - c.round()).abs() < 1e-5 && (r - r.round()).abs() < 1e-5,
                "pulse {n} at ({x}, {y}) is off the grid"
            );
            // `laser` is the beam of lit moves: a window at rest shows in `pulses` alone.
            assert_eq!(w[laser], "0", "pulse {n}");
            *at.entry((c.round() as i64, r.round() as i64)).or_default() += n - last;
            last = n;
        }
    }
    assert_eq!(last, planned, "the column ends at the plan's count");
    assert_eq!(at.len(), 12, "{at:?}");
    assert!(at.values().all(|&n| n == 2), "{at:?}");
    for r in 0..3 {
        for c in 0..4 {
            assert!(at.contains_key(&(c, r)), "spot ({c}, {r}): {at:?}");
        }
    }
}
