//! The resume logic trusts `link::modal::Tracker` to predict, line by line, what a GRBL-family
//! controller's interpreter does with a job. This property test holds it to the simulated
//! controller's interpreter (`sim::gcode`, GRBL's checks and error codes) on random programs of
//! six-axis moves, units, distance and feed modes, laser words and program ends: after every
//! line the controller accepts, both agree on the position of all six axes and on the modal
//! state a resume compares.

use lase_runtime::link::modal::Tracker;
use lase_runtime::link::sim::gcode::{self, Gc};
use lase_runtime::link::{MAX_AXES, ModalState, MotionMode};
use proptest::prelude::*;

/// One block: a few modal words, some axis words, maybe F and S.
fn block() -> impl Strategy<Value = String> {
    let modal = prop::sample::subsequence(
        vec![
            "G0", "G1", "G20", "G21", "G90", "G91", "G93", "G94", "M3", "M4", "M5", "M2", "G17",
        ],
        0..=3,
    );
    let axes = prop::collection::vec(
        (
            prop::sample::select(vec!['X', 'Y', 'Z', 'A', 'B', 'C']),
            -2000i32..2000,
        ),
        0..=4,
    );
    let feed = prop::option::of(1u32..5000);
    let power = prop::option::of(0u32..1000);
    (modal, axes, feed, power).prop_map(|(modal, axes, feed, power)| {
        let mut line = String::new();
        for w in modal {
            line.push_str(w);
        }
        let mut seen = Vec::new();
        for (c, v) in axes {
            // A letter twice is GRBL's error 25: keep the first.
            if !seen.contains(&c) {
                seen.push(c);
                line.push_str(&format!("{c}{}", f64::from(v) / 8.0));
            }
        }
        if let Some(f) = feed {
            line.push_str(&format!("F{f}"));
        }
        if let Some(s) = power {
            line.push_str(&format!("S{s}"));
        }
        line
    })
}

/// The modal state a resume compares (`resume::fits`); G2/G3 stand for G1 there.
fn compared(m: &ModalState) -> (MotionMode, bool, bool, bool, String, String) {
    let motion = match m.motion {
        MotionMode::ArcCw | MotionMode::ArcCcw => MotionMode::Linear,
        other => other,
    };
    (
        motion,
        m.inches,
        m.incremental,
        m.inverse_time,
        format!("{:?}{:?}", m.plane, m.spindle),
        // The feed counts in G94 only (in G93 every move carries its own); S always.
        format!("{} {}", if m.inverse_time { 0.0 } else { m.feed }, m.s),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn the_tracker_predicts_what_the_controller_executes(lines in prop::collection::vec(block(), 1..40)) {
        let mut gc = Gc::new([0.0; MAX_AXES], MAX_AXES);
        let mut tracker = Tracker::new([0.0; MAX_AXES]);
        for line in &lines {
            // A line the controller refuses changes nothing, and a job never sends one on.
            let Ok(block) = gcode::execute(line.as_bytes(), &gc, true) else {
                continue;
            };
            gc = block.next;
            tracker.apply(line).map_err(|e| TestCaseError::fail(format!("{line}: {e}")))?;
            for k in 0..MAX_AXES {
                prop_assert!(
                    (gc.pos[k] - tracker.pos[k]).abs() <= 1e-9,
                    "after `{}`: controller {:?}, tracker {:?}", line, gc.pos, tracker.pos
                );
            }
            prop_assert_eq!(
                compared(&gc.modal),
                compared(&tracker.state),
                "after `{}`", line
            );
        }
    }
}

/// Most random blocks are valid, so the property above compares something. Counted over many
/// programs from a fixed seed: one short program of refused blocks (`G90G91`, `M3M5`, `G1`
/// with no feed) is a fair draw, not a sign of a vacuous test.
#[test]
fn most_random_blocks_are_accepted() {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    let programs = prop::collection::vec(block(), 1..40);
    let (mut accepted, mut total) = (0usize, 0usize);
    for _ in 0..200 {
        let lines = programs.new_tree(&mut runner).unwrap().current();
        let mut gc = Gc::new([0.0; MAX_AXES], MAX_AXES);
        for line in &lines {
            total += 1;
            if let Ok(block) = gcode::execute(line.as_bytes(), &gc, true) {
                accepted += 1;
                gc = block.next;
            }
        }
    }
    assert!(
        accepted * 2 >= total,
        "{accepted} of {total} random blocks accepted"
    );
}
