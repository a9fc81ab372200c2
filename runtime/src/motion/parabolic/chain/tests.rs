//! The replay against the real LinuxCNC 2.9's runs.

use super::*;

/// The real LinuxCNC 2.9 (Debian's linuxcnc-uspace, headless, 1 ms servo period, the
/// xy_rotary INI lase generates: A at 3600 °/s²) ran rotary_engrave's first ring with its
/// lit block 0, ¼, ½, ¾ and 1 ms longer (hand-edited F words; lead-in and lead-out as
/// lase writes them). Through the parabolic blend into the lead-out the summed A speed,
/// recomputed from the sampled joint positions, sat at 113.8655, 112.5055, 112.9455,
/// 113.3885 and 113.8295 °/s: a sawtooth over the phase in which the lit block's final
/// deceleration turns, one servo period wide and `A·T` = 1.8 °/s high. The replay gives the
/// same speed at the lead-out's switch.
#[test]
fn the_replay_matches_the_real_linuxcncs_off_edge_blend_over_the_servo_phase() {
    let seg = |len: f64, f_per_min: f64| ChainSeg {
        len,
        v: len * f_per_min / 60.0,
        acc: 3600.0,
        u: [1.0, 0.0, 0.0],
        tolerance: 0.01,
        tangent: None,
    };
    let measured = [113.8655, 112.5055, 112.9455, 113.3885, 113.8295];
    for (k, real) in measured.into_iter().enumerate() {
        let lit_s = 60.0 / 19.09859 + k as f64 * 0.00025;
        let f = (60.0 / lit_s * 1e6).round() / 1e6;
        let chain = [
            seg(7.868083, 857.3745),
            seg(360.0, f),
            seg(6.980599, 984.9432),
            seg(8.068018, 852.1912),
        ];
        let run = run_chain(&chain, false, 0.001);
        // The on-edge as the real machine crossed it too (114.20 of 114.59 °/s).
        assert!((run.switch_speed[1] - 114.20).abs() < 0.005, "{run:?}");
        let model = run.switch_speed[2];
        assert!(
            (model - real).abs() < 0.002,
            "{k}/4 ms longer: replay {model:.4}, LinuxCNC {real:.4} °/s"
        );
    }
}

/// The real LinuxCNC 2.9 (the arm_3r INI lase generates: A and B at 900 °/s², C at
/// 1800) ran a lead-in from rest at F1190.8894 into a lit block at F426.1399 in line in
/// the joints (tests/linuxcnc/arm_short.lase as written while its timing was tuned on
/// tp's summed speed). The blend lasts about two servo periods: tp switched the beam as
/// its summed speed reached the lit speed (1.18 °/s), while the sampled joints, two
/// periods behind, still ran at the lead-in's 0.80: their central difference over the
/// switching sample was 0.8179 °/s, which the replay's switch window gives.
#[test]
fn the_joints_speed_at_a_short_blends_switch_is_the_real_linuxcncs() {
    let p0 = [-133.087689, 99.466378, -61.135992];
    let p1 = [-133.060975, 99.463241, -61.166172];
    let p2 = [-132.951481, 99.450385, -61.289873];
    let seg = |a: [f64; 3], b: [f64; 3], f_per_min: f64| {
        let d: Vec<f64> = (0..3).map(|k| (b[k] - a[k]).abs()).collect();
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let acc = [900.0, 900.0, 1800.0]
            .iter()
            .zip(&d)
            .map(|(a, d)| a * len / d)
            .fold(f64::INFINITY, f64::min);
        ChainSeg {
            len,
            v: len * f_per_min / 60.0,
            acc,
            u: [1.0, 0.0, 0.0],
            tolerance: 0.01,
            tangent: None,
        }
    };
    let chain = [seg(p0, p1, 1190.8894), seg(p1, p2, 426.1399)];
    // The lit block blends on into the blocks after it: its term condition is parabolic.
    let run = run_chain(&chain, true, 0.001);
    let lit = chain[1].v;
    assert!((lit - 1.18).abs() < 0.005, "{lit}");
    assert!((run.switch_speed[1] / lit - 1.0).abs() < 0.02, "{run:?}");
    // The central difference over the switching sample, (x[n+1] − x[n−1]) / 2T.
    let window = run.switch_window[1];
    let joints = (window[4] + window[5]) / 2.0;
    assert!(
        (joints - 0.8179).abs() < 0.002,
        "replay {joints:.4}, LinuxCNC 0.8179 °/s"
    );
    // Sample by sample from four before the switch's to four after: the blend's speeds
    // show in the joints from the sample after the switch's on.
    let real = [
        0.80221, 0.80229, 0.80221, 0.80221, 0.80287, 0.83283, 0.97841, 1.10065, 1.16537,
    ];
    for (k, (w, r)) in window.iter().zip(real).enumerate() {
        let at = k as i32 - 4;
        assert!(
            (w - r).abs() < 0.001,
            "sample {at}: replay {window:?}, LinuxCNC {real:?}"
        );
    }
}

#[test]
fn a_prefix_run_on_into_its_ending_is_the_whole_chains_run() {
    let seg = |len: f64, v: f64, u: [f64; 3]| ChainSeg {
        len,
        v,
        acc: 2000.0,
        u,
        tolerance: 0.01,
        tangent: None,
    };
    let x = [1.0, 0.0, 0.0];
    let head = [
        seg(3.0, 40.0, x),
        seg(0.8, 55.0, x),
        seg(0.05, 30.0, [0.6, 0.8, 0.0]),
    ];
    let tail = [seg(2.0, 50.0, x), seg(0.4, 50.0, x), seg(1.2, 50.0, x)];
    let all: Vec<ChainSeg> = head.iter().chain(&tail).cloned().collect();
    let whole = run_chain(&all, false, 0.001);
    let parts = Replay::prefix(&head, 0.001).then(&tail);
    assert_eq!(whole, parts);
    assert!(whole.total_s > 0.0 && whole.switch_s.windows(2).all(|w| w[0] <= w[1]));
}

/// The real LinuxCNC 2.9 (headless, 1 ms, the xy_rotary INI lase generates: X at
/// 2000 mm/s², A at 3600 °/s²) ran rotary_engrave's "S" from rest: blocks that turn A
/// (parabolic blends), then 30 X-only blocks of 2-20 ms joined tangentially, then A again.
/// The first sample reporting each NC line came at these servo periods from the first
/// block's; the replay starts every block in the same period. (Before tangent joins were
/// replayed the writer could not time this stroke's off-edge; with `blend_prev` halving
/// the first X-only block, as tc.c reads, the X-only blocks started 2-3 periods late.)
#[test]
fn a_chain_with_tangent_joins_runs_as_the_real_linuxcnc_ran_it() {
    let nc = "X1.777704 A51.354136 F1998.3719
X1.320447 A52.227432 F2604.9355
X1.168786 A52.517084 F4004.1633
X1.126263 A52.598297 F6257.1008
X1.047619 A52.748495 F2903.1543
X0.937508 A52.818594 F2781.9084
X0.890744 A52.848365 F7277.01
X0.704536 A52.966909 F3805.6114
X0.257146 A53.251726 F2537.1363
X0.089868 A53.358219 F4060.6485
X-0.095238 A53.476061 F2597.0332
X-0.261715 F3038.6522
X-0.290999 F17475.5773
X-0.313605 F23872.0826
X-0.337577 F24358.2784
X-0.363919 F24517.2188
X-0.39342 F24589.0496
X-0.421336 F29167.1556
X-0.45403 F27876.9113
X-0.488634 F29457.9809
X-0.531982 F25977.2627
X-0.578112 F26518.1654
X-0.625499 F27491.3932
X-0.67175 F29501.6586
X-0.738459 F21263.5925
X-0.857143 F12357.0992
X-0.941402 F17475.5773
X-1.001916 F23872.0826
X-1.059405 F24358.2784
X-1.113995 F24517.2188
X-1.16519 F24589.0496
X-1.205304 F29167.1556
X-1.243789 F27876.9113
X-1.276543 F29457.9809
X-1.309579 F25977.2627
X-1.338275 F26518.1654
X-1.363064 F27491.3932
X-1.384072 F29501.6586
X-1.410679 F21263.5925
X-1.452571 F12357.0992
X-1.619048 F3038.6522
X-1.776982 A53.375517 F3038.6522";
    let real = [
        0, 41, 66, 80, 87, 107, 128, 136, 155, 183, 197, 217, 236, 240, 242, 245, 247, 250, 252,
        254, 256, 259, 261, 263, 265, 268, 273, 277, 279, 282, 284, 287, 289, 291, 293, 296, 298,
        300, 302, 305, 310, 330,
    ];
    let (mut x, mut a) = (2.413911, 50.13907);
    let mut segs: Vec<ChainSeg> = Vec::new();
    let mut turned = Vec::new();
    for line in nc.lines() {
        let word = |c: char| {
            line.split_whitespace()
                .find_map(|w| w.strip_prefix(c)?.parse::<f64>().ok())
        };
        let (nx, na, f) = (
            word('X').unwrap_or(x),
            word('A').unwrap_or(a),
            word('F').unwrap(),
        );
        let (dx, da) = ((nx - x).abs(), (na - a).abs());
        // canon: the X length, at the acceleration that keeps X and A within theirs.
        let acc = dx / (dx / 2000.0).max(da / 3600.0);
        segs.push(ChainSeg {
            len: dx,
            v: dx * f / 60.0,
            acc,
            u: [(nx - x).signum(), 0.0, 0.0],
            tolerance: 0.01,
            tangent: None,
        });
        turned.push(da > 0.0);
        (x, a) = (nx, na);
    }
    for k in 0..segs.len() - 1 {
        if !turned[k] && !turned[k + 1] {
            let (s0, s1) = (&segs[k], &segs[k + 1]);
            let v_max = s0.v.min(s1.v);
            let bound = [2000.0, 0.0, 0.0];
            segs[k].tangent = tangent_join((s0.u, s1.u), v_max, s1.acc, bound, 0.001);
            assert_eq!(
                segs[k].tangent,
                Some(0.0),
                "block {k} in line with the next"
            );
        }
    }
    // The last block blends on into the rest of the S: its term condition is parabolic.
    let run = run_chain(&segs, true, 0.001);
    for (k, (&t, &r)) in run.switch_s.iter().zip(&real).enumerate() {
        let model = t / 0.001;
        assert!(
            (model - r as f64).abs() < 0.5,
            "block {k}: replay {model:.1}, LinuxCNC {r} periods"
        );
    }
}

/// With tangent joins the tail can change what the prefix ran on (the look-ahead's final
/// speeds of the segments joined tangentially into it): run on, or run again from rest, the
/// prefix gives the whole chain's run.
#[test]
fn a_prefix_joined_tangentially_into_its_ending_is_the_whole_chains_run() {
    let seg = |len: f64, v: f64, tangent: Option<f64>| ChainSeg {
        len,
        v,
        acc: 2000.0,
        u: [1.0, 0.0, 0.0],
        tolerance: 0.01,
        tangent,
    };
    let t = Some(0.0);
    for (head_end, tail_first) in [(None, t), (t, t), (t, None)] {
        let head = [
            seg(0.6, 30.0, None),
            seg(0.1, 25.0, t),
            seg(0.2, 28.0, head_end),
        ];
        let tail = [
            seg(0.05, 20.0, tail_first),
            seg(0.3, 30.0, None),
            seg(0.4, 30.0, None),
        ];
        let all: Vec<ChainSeg> = head.iter().chain(&tail).cloned().collect();
        let whole = run_chain(&all, false, 0.001);
        let parts = Replay::prefix(&head, 0.001).then(&tail);
        assert_eq!(whole, parts, "{head_end:?} {tail_first:?}");
        assert!(whole.total_s > 0.0 && whole.switch_s.windows(2).all(|w| w[0] <= w[1]));
    }
}
