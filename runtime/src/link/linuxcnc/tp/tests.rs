//! The model on hand-computed cases: each expected time from the rules the module states.

use super::*;

fn table() -> TpLimits {
    let m = crate::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    TpLimits::for_machine(&m, 0.001)
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn the_table_limits_are_the_ini_ones() {
    let l = table();
    assert_eq!(l.axes.len(), 2);
    assert_eq!((l.axes[0].v, l.axes[0].a), (250.0, 2000.0));
    assert_eq!(l.max_linear_v, 250.0);
    assert_eq!(l.beam_output, Some(0));
}

#[test]
fn the_last_segment_before_the_queue_ends_ramps_at_half_the_acceleration() {
    // 100 mm at F6000 (100 mm/s): its term condition stays parabolic, so 1000 mm/s², not
    // 2000: 0.1 s up and down (5 mm each), 90 mm at 100 mm/s.
    let t = run_program("G21 G90 G17 G94\nG1 X100 F6000\nM2\n", &table()).unwrap();
    assert!(close(t.total_s, 1.1), "{t:?}");
    assert_eq!((t.segments, t.stops), (1, 0));
}

#[test]
fn a_diagonal_line_gets_sqrt2_times_the_axis_limits_and_the_traj_cap() {
    let a = 2000.0 * 2f64.sqrt() * 0.5;
    let t = run_program("G1 X100 Y100 F60000\n", &table()).unwrap();
    let len = 100.0 * 2f64.sqrt();
    let v = 250.0; // MAX_LINEAR_VELOCITY caps the path speed
    // Rest to rest: it ends in the servo period its trapezoid reaches the end in.
    let expected = quantised(v / a * 2.0 + (len - v * v / a) / v, 0.001);
    assert!(close(t.total_s, expected), "{t:?} vs {expected}");
}

#[test]
fn rapid_to_feed_stops_and_collinear_feeds_carry_through() {
    let l = table();
    // Collinear lines (a synced output between them) run through at 20 mm/s: up at 2000,
    // down at 1000 (the last segment's parabolic term condition).
    let split = run_program("G1 X10 F1200\nM62 P1 X20\n", &l).unwrap();
    assert!(
        close(split.total_s, 0.01 + 0.02 + (20.0 - 0.3) / 20.0),
        "{split:?}"
    );
    assert_eq!(split.stops, 0);
    let rapid = run_program("G0 X10\nG1 X20 F1200\n", &l).unwrap();
    assert_eq!(rapid.stops, 1);
}

#[test]
fn a_square_corner_gets_a_blend_arc_within_the_tolerance() {
    // 90°: half the interior angle 45°, d = P·cos45°/(1 − sin45°) = 0.0483 mm for P0.02,
    // R = d·tan45°, v = sqrt(0.866·2000·R) = 9.14 mm/s; the arc, R·π/2 long, at half the
    // acceleration along it.
    let l = table();
    let corner = run_program("G64 P0.02\nG1 X20 F1200\nY20\n", &l).unwrap();
    let stop = run_program("G61\nG1 X20 F1200\nY20\n", &l).unwrap();
    assert!(stop.total_s > corner.total_s);
    assert_eq!((corner.stops, stop.stops), (0, 1));
    let d = 0.02 * 0.5f64.sqrt() / (1.0 - 0.5f64.sqrt());
    let v = (ACC_RATIO_NORMAL * 2000.0 * d).sqrt();
    let arc = d * std::f64::consts::FRAC_PI_2;
    // v_plan is the arc's own limit here, so R_plan is the tolerance's radius
    // (blendComputeParameters); the run ends on a servo period.
    let expected = quantised(
        trapezoid(20.0 - d, 0.0, v, 20.0, 2000.0)
            + arc / v
            + trapezoid(20.0 - d, v, 0.0, 20.0, 1000.0),
        0.001,
    );
    assert!(close(corner.total_s, expected), "{corner:?} vs {expected}");
}

#[test]
fn small_arcs_in_blending_mode_run_as_their_chords() {
    // A 0.25 mm arc on r = 33 mm strays 0.24 µm from its chord: under G64 P0.02 it is a
    // line (its junctions are chord corners), under G61 an arc.
    let l = table();
    let nc = |mode: &str| format!("{mode}G0 X33\nG1 X33 Y0 F1500\nG3 X32.999 Y0.25 I-33 J0\n");
    let blended = run_program(&nc("G64 P0.02\n"), &l).unwrap();
    let exact = run_program(&nc("G61\n"), &l).unwrap();
    // The chord ramps at the line's acceleration, the arc at half of it.
    assert!(blended.total_s < exact.total_s, "{blended:?} {exact:?}");
    // Q0 (what emit writes) turns the naive CAM off: canon keeps the arc an arc, since no
    // chord deviation is below 0 (emccanon.cc ARC_FEED), so it ramps at half acceleration.
    let kept = run_program(&nc("G64 P0.02 Q0\n"), &l).unwrap();
    assert!(blended.total_s < kept.total_s, "{blended:?} {kept:?}");
}

#[test]
fn beam_time_follows_the_synced_output() {
    let l = table();
    let t = run_program("G1 X10 F1200\nM62 P0\nX20\nM63 P0\nX30\n", &l).unwrap();
    // The lit middle 10 mm at 20 mm/s, all at cruise (tangent, 0.1 mm ramps at the ends).
    assert!(close(t.beam_on_s, 0.5), "{t:?}");
}

#[test]
fn immediate_outputs_and_dwells_drain_the_queue() {
    let l = table();
    let t = run_program("G1 X10 F1200\nM64 P0\nG4 P0.5\nX20\nM65 P0\nX30\n", &l).unwrap();
    assert_eq!(t.stops, 2);
    // Lit: the first drain (off → on) and the dwell, the middle segment from rest to rest
    // at half the acceleration (the queue ends on it), the second drain (on → off).
    let middle = trapezoid(10.0, 0.0, 0.0, 20.0, 1000.0);
    let drains = 2.0 * DRAIN_CYCLES * 0.001;
    assert!(close(t.beam_on_s, 0.5 + middle + drains), "{t:?}");
}

#[test]
fn a_program_starts_where_the_machine_is() {
    let l = table();
    let from_zero = run_program("G0 X10\n", &l).unwrap();
    let from_ten = run_program_from("G0 X10\n", &l, &[10.0, 0.0]).unwrap();
    assert!(from_zero.total_s > 0.0);
    assert_eq!(from_ten.segments, 0);
}

#[test]
fn words_it_does_not_know_are_refused() {
    assert!(run_program("G1 X10 F1200\nG2 X20 R5\n", &table()).is_err());
    assert!(run_program("G1 W10 F100\n", &table()).is_err());
    assert!(run_program("G1 X10 F1200\nG7\n", &table()).is_err());
}

fn cam() -> TpLimits {
    let m = crate::machine::parse_machine(lase_stdlib::machine("cam_xwb").unwrap(), 0).unwrap();
    TpLimits::for_machine(&m, 0.001)
}

/// The lit chain of a cam program as the real LinuxCNC 2.9 ran it (`tests/linuxcnc.rs` with
/// `LASE_LINUXCNC_DUMP`, from its 1 ms HAL samples): from the first lead-in move (NC line 8)
/// to the end of motion, and how long `motion.digital-out-00` was on. Every junction is a
/// parabolic blend between G93 blocks of 20–41 ms; continuous trapezoids put the chain at
/// 27.36 s (1.2 % over), the servo-period replay at the sampled number.
fn cam_chain(nc: &str, executed_chain_s: f64, executed_beam_s: f64) {
    // From where its rapid (NC line 6) ends: the chain starts at rest there either way.
    let start: Vec<f64> = nc.lines().nth(5).unwrap()[3..]
        .split(' ')
        .map(|w| w[1..].parse().unwrap())
        .collect();
    let t = run_program_from(nc, &cam(), &start).unwrap();
    let lead_in = t.starts.iter().find(|(line, _)| *line == 8).unwrap().1;
    let chain = t.total_s - lead_in;
    assert!(
        (chain - executed_chain_s).abs() <= 0.0015,
        "chain {chain} s: {t:?}"
    );
    assert!(
        (t.beam_on_s - executed_beam_s).abs() <= 0.0015,
        "beam {} s",
        t.beam_on_s
    );
}

#[test]
fn a_cam_chain_of_parabolic_blends_runs_as_linuxcnc_ran_it() {
    cam_chain(
        include_str!("../../../../tests/fixtures/linuxcnc/rhai_cam.ngc"),
        27.019,
        26.939,
    );
    cam_chain(
        include_str!("../../../../tests/fixtures/linuxcnc/cam_hardening.ngc"),
        27.290,
        27.210,
    );
}

#[test]
fn the_kink_test_counts_the_next_segments_own_acceleration() {
    // tpSetupTangent: a_inst = v / cycleTime + tc->maxaccel. At 25 mm/s on the table
    // (2000 mm/s²) a turn of θ needs 27000·sin θ / 2000 of Y's limit: under 0.1 (tangent)
    // up to θ = 7.41 mrad; without the segment's own 2000 mm/s² it would be 8.0 mrad.
    let l = table();
    let kind = |dy: f64| {
        let nc = format!("G64 P0.01\nG1 X10 F1500\nX20 Y{dy}\n");
        let q = read::read(&nc, &l, &[]).unwrap();
        junction(&q.segs[0], &q.segs[1], q.tolerances[1], 0.001)
    };
    assert!(matches!(kind(0.070), Kind::Tangent { .. }));
    assert!(
        !matches!(kind(0.077), Kind::Tangent { .. }),
        "{:?}",
        kind(0.077)
    );
}

#[test]
fn a_short_line_between_two_blend_arcs_is_swallowed_not_crawled() {
    // 40 chords of 0.05 mm around a 1.5 mm circle at 10 mm/s: each turn (0.033 rad) is past
    // the kink ratio (12000 mm/s² · 0.033 / 2000 = 0.2), so each corner is a blend arc taking
    // half of the next chord and the rest of the one before (`tcCanConsume`): nothing is
    // left of a chord between two arcs, which blendCheckConsume folds into the arc. Before,
    // the model ran that remnant at its length per servo period, nearly a stop per chord.
    let (r, n, step) = (1.5f64, 40, 0.05 / 1.5);
    let mut nc = String::from("G64 P0.01\nG1 X1.5 Y0 F600\n");
    for k in 1..=n {
        let a = k as f64 * step;
        nc.push_str(&format!("X{:.6} Y{:.6}\n", r * a.cos(), r * a.sin()));
    }
    let t = run_program(&nc, &table()).unwrap();
    let first = 1.5 / 10.0; // the first line, from X0 Y0, at 10 mm/s
    let chords = n as f64 * 0.05 / 10.0;
    // At 10 mm/s throughout but for the ramps from and to rest (10 ms each at 1000 mm/s²
    // or more, 5 ms lost each) and the arcs' share of the corners.
    assert!(t.total_s < 1.05 * (first + chords) + 0.02, "{t:?}");
    assert_eq!(t.stops, 0);
}

#[test]
fn collinear_feeds_join_into_one_segment_as_canons_naive_cam_detector_does() {
    // Three 1 mm lines, the middle point 1 µm off the line through the ends: within
    // G64 P0.01 (Q defaults to P), so LinuxCNC runs them as one 3 mm line at the feed.
    let joined = "G21 G90 G17 G94\nG64 P0.01\nG1 X1 F600\nX2 Y0.001\nX3 Y0\nM2\n";
    let t = run_program(joined, &table()).unwrap();
    let one = run_program("G21 G90 G17 G94\nG64 P0.01\nG1 X3 F600\nM2\n", &table()).unwrap();
    assert_eq!(t.segments, 1, "{t:?}");
    assert!(close(t.total_s, one.total_s), "{t:?} vs {one:?}");
    // The line number is the last one's.
    assert_eq!(t.starts.last().map(|s| s.0), Some(5), "{t:?}");
    // Q0 turns the detector off; a point 0.02 off, or a synchronized output between them,
    // breaks the chain (canon flushes it before queueing the output).
    for nc in [
        "G64 P0.01 Q0\nG1 X1 F600\nX2 Y0.001\nX3 Y0\n",
        "G64 P0.01\nG1 X1 F600\nX2 Y0.02\nX3 Y0\n",
        "G64 P0.01\nG1 X1 F600\nM62 P0\nX2 Y0.001\nX3 Y0\n",
    ] {
        assert!(run_program(nc, &table()).unwrap().segments > 1, "{nc}");
    }
    // A new F flushes the chain and starts the next one.
    let t = run_program("G64 P0.01\nG1 X1 F600\nX2 F1200\nX3\n", &table()).unwrap();
    assert_eq!(t.segments, 2, "{t:?}");
}

/// `motion::parabolic`'s rule against this model's servo-period replay of tp.c: a chain of
/// equal G93 blocks on the arm's C (1800 °/s²) runs each block in its triangle time
/// `sqrt(2·Δ/a)` rounded up to the servo period when its inverse time asks for less (the
/// arm's bends: 0.19° in 5.4 ms run in 15 ms, as the real LinuxCNC's samples showed), and in
/// its inverse time or a little less from that period on: the share `held_shares` gives is
/// the speed the chain runs at.
#[test]
fn a_chain_of_short_rotary_blocks_runs_at_the_share_of_speed_the_motion_rule_predicts() {
    use crate::motion::parabolic::{self, Block};
    let m = crate::machine::parse_machine(lase_stdlib::machine("arm_3r").unwrap(), 0).unwrap();
    let period = m.servo_period_s();
    let l = TpLimits::for_machine(&m, period);
    let delta = 0.19f64;
    let per_block = |t: f64| {
        let mut nc = String::from("G64 P0.01\nG93\n");
        for k in 1..=120 {
            nc += &format!("G1 C{:.6} F{:.6}\n", delta * k as f64, 60.0 / t);
        }
        let run = run_program_from(&nc, &l, &[0.0; 4]).unwrap();
        // Away from the chain's ends: blocks 40 to 80 (NC lines 43 to 83).
        let at = |line: usize| run.starts.iter().find(|(n, _)| *n == line).unwrap().1;
        (at(83) - at(43)) / 40.0
    };
    let mut to = crate::axes::Axes::ZERO;
    to[3] = delta.to_radians();
    let share = |t: f64| {
        let b = Block::of(&m, &crate::axes::Axes::ZERO, &to, t);
        parabolic::held_shares(&[b; 3])[1]
    };
    for t in [0.0054, 0.010, 0.0146, 0.015, 0.0162, 0.020, 0.040] {
        let (ran, s) = (per_block(t), share(t));
        assert!(
            (ran - t / s).abs() < 1e-6 || (s == 1.0 && ran <= t),
            "a block of {t} s ran in {ran} s; the rule holds {s} of its speed"
        );
    }
    assert!((share(0.0054) - 0.36).abs() < 1e-9);
}

#[test]
fn a_slow_corner_gets_only_the_blend_arc_its_speed_needs() {
    // 90° at F60 (1 mm/s) under G64 P0.02 (blendComputeParameters): the tolerance allows
    // d = 0.02·cos45°/(1 − sin45°) = 0.0483 mm (R_geom the same), but v_plan = min(sqrt(0.866
    // ·2000·0.0483), 1) = 1 mm/s, so R_plan = max(v²/a_n, R_blend): v²/a_n = 1/1732 = 5.77e-4,
    // and the equivalent parabolic blend's t = min(sqrt(2·1000·0.0483), 1)/1000 = 1 ms covers
    // s = 1e-3 mm, R_blend = s/(π/2) = 6.366e-4 mm. The arc (1e-3 mm) takes d = R/tan45° =
    // 6.366e-4 mm of each line: 20 − d at 1 mm/s up at 2000 (0.25 µm in 0.5 ms) and down at
    // 1000 (the last segment: 0.5 µm in 1 ms), the arc at 1 mm/s. Continuous: 2·(20 − d)
    // + 0.0005 − 0.00025 + 0.001 + 0.001 − 0.0005 = 40.000477 s, which ends in the servo
    // period of 40.001 s. The tolerance's own arc (R = 0.0483) would have taken 39.98 s.
    let t = run_program("G64 P0.02\nG1 X20 F60\nY20\n", &table()).unwrap();
    assert!(close(t.total_s, 40.001), "{t:?}");
    assert_eq!(t.stops, 0);
}

#[test]
fn a_short_tangent_block_ramps_at_one_acceleration() {
    // X10 F1200, X10.05 F900, X20 F600: collinear, so tangent. The middle block enters at
    // min(20, 15) = 15 mm/s and ends at min(15, 10) = 10 mm/s; at their mean it takes
    // 2·0.05/25 = 4 ms, under 1/ARC_BLEND_RAMP_FREQ (10 ms), so tpActivateSegment sets
    // TC_ACCEL_RAMP: one constant acceleration, (10² − 15²)/(2·0.05) = −1250 mm/s² (within
    // 2000), 4 ms. A trapezoid (cruise at 15, then 2000 mm/s² down) would take 3.75 ms. The
    // beam is on for that block alone.
    let t = run_program(
        "G1 X10 F1200\nM62 P0\nX10.05 F900\nM63 P0\nX20 F600\n",
        &table(),
    )
    .unwrap();
    assert!(close(t.beam_on_s, 0.004), "{t:?}");
}

#[test]
fn a_run_from_rest_to_rest_ends_on_a_servo_period() {
    // 0.3 mm at F2400 from rest to rest, the last segment (1000 mm/s²): a triangle of
    // 2·sqrt(0.3/1000) = 34.64 ms, which tp.c's trapezoid (tpCalculateTrapezoidalAccel,
    // tcUpdateDistFromAccel) lands on its end in the 35th period.
    let t = run_program("G1 X0.3 F2400\n", &table()).unwrap();
    assert!(close(t.total_s, 0.035), "{t:?}");
}
