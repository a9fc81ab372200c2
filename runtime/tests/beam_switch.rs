//! Beam switches that must stop on GRBL are planned as stops: a lit section whose power
//! follows the speed (`couple speed`, GRBL's `M4`) after one at constant power (`M3`) re-arms
//! the laser with `M4 S0`, a synced spindle change, so the NC writes it before that section's
//! lead-in and the plan is at rest exactly there; the switches inside either section fly on
//! S words.

mod common;

use common::job;
use lase_runtime::emit::{Dialect, EmitOptions, emit_lines};

const MIXED: &str = "machine xy_table
let part = profile polyline [(0, 0), (30 mm, 0), (30 mm, 10 mm), (0, 10 mm)] closed
laser { power 40 W }
follow part at 20 mm/s
laser { power 30 W, couple speed }
follow translate(part, (0, 20 mm)) at 20 mm/s
move to (0, -20 mm) rapid
";

#[test]
fn a_change_from_m3_to_m4_re_arms_at_a_planned_stop_before_the_lead_in() {
    let j = job(MIXED);
    let (lines, _) = emit_lines(&j, Dialect::Grbl, &EmitOptions::default()).unwrap();
    let text: Vec<&str> = lines.iter().map(|l| l.text.as_str()).collect();
    let spindle: Vec<(usize, &str)> = text
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with("M3") || l.starts_with("M4") || l.starts_with("M5"))
        .map(|(i, l)| (i, *l))
        .collect();
    // Armed in the header, re-armed once, off at the end: three spindle lines in all.
    let words: Vec<&str> = spindle.iter().map(|(_, l)| *l).collect();
    assert_eq!(words, ["M3 S0", "M4 S0", "M5"], "{text:#?}");
    let first_motion = text.iter().position(|l| l.contains('X') || l.contains('Y'));
    assert!(
        spindle[0].0 < first_motion.unwrap(),
        "the first arm is at rest, before any motion"
    );

    // The re-arm: the motion line before it ends where the plan stands still, and the line
    // after it is the coupled section's unlit lead-in (S0 in force, no S > 0 yet).
    let at = spindle[1].0;
    let before = lines[..at]
        .iter()
        .rev()
        .find(|l| l.text.contains('X') || l.text.contains('Y'))
        .unwrap();
    let op = before.op.unwrap();
    let seg = j
        .plan
        .segments()
        .iter()
        .rev()
        .find(|s| s.tag == op)
        .unwrap();
    assert_eq!(seg.v_exit, 0.0, "the plan stops before the re-arm");
    let after = &lines[at + 1..]
        .iter()
        .find(|l| l.text.contains('X') || l.text.contains('Y'))
        .unwrap();
    let lead = &j.program.ops[after.op.unwrap() as usize];
    assert!(
        lead.laser().is_none(),
        "the re-arm comes before the lead-in: {}",
        after.text
    );
    assert!(!after.text.contains(" S") || after.text.ends_with(" S0"));

    // The first section's corners are not stops: the S words fly (only the re-arm and the
    // end stop, and the program start; dwell-free recipe).
    let stops = j.plan.segments().iter().filter(|s| s.v_exit == 0.0).count();
    let without = job(&MIXED.replace(", couple speed", ""));
    let stops_without = without
        .plan
        .segments()
        .iter()
        .filter(|s| s.v_exit == 0.0)
        .count();
    assert_eq!(stops, stops_without + 1, "one stop more: the re-arm's");
}
