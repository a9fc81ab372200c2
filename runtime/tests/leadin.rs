//! Lead-ins, lead-outs and transition points (PROCESS.md §4): on every lit section the plan
//! reaches the programmed feed exactly at the first lit point and still has it at the last one,
//! on both machine styles (beam switched at rest: notcher; motion-synchronized: xy_table), with
//! both profiles, entered from rest or at speed; and where the travel leaves no room, planning
//! fails with a diagnostic at the lit move.

mod common;

use common::{compile, job};
use lase_runtime::motion::{Job, LeadKind, MotionError, power};
use lase_runtime::planner::{lead_distance, speed_change_distance};
use lase_runtime::program::OpKind;
use lase_runtime::report::beam_at;

/// The paper's program (PROCESS.md §4, N10–N70), as examples/conrod_notch.lase writes it.
const NOTCH: &str = "machine notcher
laser { power 300 W, spot 0.2 mm }
move to (68.5 mm, 0, 0) at 3000 mm/min
event swing_right
move to (68.5 mm, 0, -15.53 mm) at 5000 mm/min
laser on
move to (68.5 mm, 0, -33.63 mm) at 950 mm/min
laser off
move to (73.5 mm, 0, -33.63 mm) at 3000 mm/min
event swing_left
";

const FRAME: &str = "machine xy_table
laser { power 40 W, spot 50 um }
let part = profile polyline [(0, 0), (40 mm, 0), (40 mm, 20 mm), (0, 20 mm)] closed
follow part at 20 mm/s
follow translate(part, (0, 30 mm)) at 35 mm/s
move to (0, 0) rapid
";

const DIAL: &str = "machine xy_table
laser { power 25 W }
follow profile circle(center: (0, 0), radius: 30 mm) at 40 mm/s
follow profile line((5 mm, 5 mm), (20 mm, 5 mm)) at 50 mm/s
";

/// Speeds at the first and last lit point of every section, from the plan's segments.
fn section_speeds(job: &Job) -> Vec<(f64, f64, f64, f64)> {
    job.sections
        .iter()
        .map(|sec| {
            let segs = job.plan.segments();
            let first = power::op_segments(job, sec.first_op as usize);
            let last = power::op_segments(job, sec.last_op as usize);
            (
                segs[first.start].v_entry,
                sec.start_feed_mm_s,
                segs[last.end - 1].v_exit,
                sec.end_feed_mm_s,
            )
        })
        .collect()
}

fn assert_exact_at_section_ends(job: &Job, rel: f64) {
    assert!(!job.sections.is_empty());
    for (k, (v_in, f_in, v_out, f_out)) in section_speeds(job).into_iter().enumerate() {
        assert!(
            (v_in - f_in).abs() <= rel * f_in,
            "section {k}: {v_in} mm/s at the first lit point, feed {f_in}"
        );
        assert!(
            (v_out - f_out).abs() <= rel * f_out,
            "section {k}: {v_out} mm/s at the last lit point, feed {f_out}"
        );
    }
}

/// Time of the first instant the path distance reaches `s` (bisection on the plan).
fn time_at_distance(job: &Job, s: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, job.plan.duration());
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if job.plan.sample(mid).s < s {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[test]
fn notch_transition_point_moves_back_by_the_ramp_distance() {
    let j = job(NOTCH);
    // S-curve on Z alone: a = 1000 mm/s², J = 20 000 mm/s³, F = 950 mm/min.
    let f = 950.0 / 60.0;
    let d = speed_change_distance(0.0, f, 1000.0, 20_000.0);
    // F < a²/J: no constant-acceleration phase, d = F·√(F/J) (PROCESS.md §4, T2 = 0).
    assert!((d - f * (f / 20_000.0).sqrt()).abs() < 1e-12);
    assert_eq!(j.leads.len(), 2);
    let lead_in = &j.leads[0];
    assert_eq!(lead_in.kind, LeadKind::In);
    assert!(
        lead_in.lit,
        "the notcher switches the beam at rest: the ramp is lit"
    );
    assert_eq!(lead_in.length_mm, d);
    // The approach (N30) now ends d above Z-15.53: that is where M27 happens, at rest.
    let approach = &j.program.ops[lead_in.op as usize - 1];
    let OpKind::Line {
        to, laser: None, ..
    } = approach.kind
    else {
        panic!("{approach:?}")
    };
    assert_eq!(to[2], -15.53 + d);
    // The lead-in ends at Z-15.53 at exactly 950 mm/min, and the cut keeps it to Z-33.63.
    assert_exact_at_section_ends(&j, 1e-12);
    let sec = &j.sections[0];
    assert_eq!(sec.start, [68.5, 0.0, -15.53]);
    assert_eq!(sec.end, [68.5, 0.0, -33.63]);
    let segs = j.plan.segments();
    let cut = power::op_segments(&j, sec.first_op as usize);
    let seg = &segs[cut.start];
    assert_eq!(
        j.plan.segment_start(cut.start)[1],
        -15.53,
        "the cut segment starts at Z-15.53"
    );
    assert_eq!((seg.v_entry, seg.v_peak, seg.v_exit), (f, f, f));
    // The lead-out: d more below Z-33.63 (then M28 at rest), within the travel.
    assert_eq!(j.leads[1].kind, LeadKind::Out);
    assert_eq!(j.leads[1].length_mm, d);
}

#[test]
fn notch_with_trapezoid_ramps_uses_v_squared_over_2a() {
    let j = job(&NOTCH.replace(
        "machine notcher",
        "machine notcher\nplanner { ramp trapezoid }",
    ));
    let f = 950.0 / 60.0;
    assert!((j.leads[0].length_mm - f * f / 2000.0).abs() < 1e-12);
    assert_exact_at_section_ends(&j, 1e-12);
}

#[test]
fn leadin_off_keeps_the_program_as_written() {
    let j = job(&NOTCH.replace(
        "machine notcher",
        "machine notcher\nplanner { leadin none }",
    ));
    assert!(j.leads.is_empty());
    // The cut then starts from rest at Z-15.53: the beam is on while the speed ramps.
    let segs = j.plan.segments();
    let first = power::op_segments(&j, j.sections[0].first_op as usize);
    assert_eq!(segs[first.start].v_entry, 0.0);
}

#[test]
fn synchronized_machine_reaches_the_feed_at_every_laser_on_point() {
    for ramp in ["scurve", "trapezoid"] {
        for src in [FRAME, DIAL] {
            let src = src.replace(
                "machine xy_table",
                &format!("machine xy_table\nplanner {{ ramp {ramp} }}"),
            );
            let j = job(&src);
            assert_exact_at_section_ends(&j, 1e-9);
            // Unlit leads, one in and one out per section.
            assert_eq!(j.leads.len(), 2 * j.sections.len());
            assert!(j.leads.iter().all(|l| !l.lit));
            // Measured like a trace: at every instant the beam goes on (1 kHz grid, refined
            // by bisection to the switching instant) the speed is the feed within 0.1 %.
            let total = j.cycle_time();
            let n = (total * 1000.0) as usize;
            let mut was = false;
            let mut ons = 0;
            for k in 0..=n {
                let t = k as f64 / 1000.0;
                let (_, lit, _) = beam_at(&j, t);
                if lit && !was {
                    let (mut lo, mut hi) = (t - 1e-3, t);
                    for _ in 0..60 {
                        let mid = 0.5 * (lo + hi);
                        if beam_at(&j, mid).1 {
                            hi = mid;
                        } else {
                            lo = mid;
                        }
                    }
                    let (s, _, _) = beam_at(&j, hi);
                    let feed = j.plan.segments()[s.segment].feed;
                    assert!(
                        (s.v - feed).abs() <= 1e-3 * feed,
                        "{ramp}: beam on at {} mm/s, feed {feed}",
                        s.v
                    );
                    ons += 1;
                }
                was = lit;
            }
            assert_eq!(ons, j.sections.len());
        }
    }
}

#[test]
fn lead_in_entered_at_speed_still_reaches_the_feed() {
    // A rapid straight into the lead-in's line (no stop): the lead-in is entered at speed, and
    // a jerk-limited ramp entered at speed may need more room than one from rest.
    let src = "machine xy_table
laser { power 10 W }
move to (-100 mm, 1 mm) rapid
move to (0, 0) at 30 mm/s
laser on
move to (30 mm, 0) at 30 mm/s
move to (30 mm, 10 mm) at 30 mm/s
laser off
move to (60 mm, 50 mm) at 200 mm/s
";
    let j = job(src);
    assert_exact_at_section_ends(&j, 1e-9);
    let (v, a, jerk) = (30.0, 2000.0, 50_000.0);
    // Entered at speed, the lead-in's corners are blended (`planner::Blend`): it keeps the
    // blends' largest reach at both ends (4 × the corner tolerance, 0.01 mm, each) besides its
    // ramp.
    let room = 2.0 * lase_runtime::planner::BLEND_REACH_MAX * 0.01;
    assert_eq!(j.leads[0].length_mm, lead_distance(v, v, a, jerk) + room);
    assert!(lead_distance(v, v, a, jerk) > speed_change_distance(0.0, v, a, jerk));
}

#[test]
fn lead_distance_is_the_worst_ramp_over_the_other_end_speed() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..2000 {
        let v = 1.0 + 300.0 * rnd();
        let a = 100.0 + 5000.0 * rnd();
        let j = if rnd() < 0.2 {
            f64::INFINITY
        } else {
            1000.0 + 1e5 * rnd()
        };
        let w_max = v * rnd();
        let d = lead_distance(v, w_max, a, j);
        for k in 0..=200 {
            let w = w_max * k as f64 / 200.0;
            let r = speed_change_distance(w, v, a, j);
            assert!(r <= d * (1.0 + 1e-12), "v {v} a {a} j {j} w {w}: {r} > {d}");
        }
        assert_eq!(
            lead_distance(v, 0.0, a, j),
            speed_change_distance(0.0, v, a, j)
        );
    }
}

#[test]
fn no_room_for_a_lead_in_is_a_diagnostic_at_the_lit_move() {
    // The cut starts at the top of Z's travel: the ramp would have to start above it.
    let src = "machine notcher
laser { power 300 W }
move to (68.5 mm, 0, 0) at 3000 mm/min
laser on
move to (68.5 mm, 0, -20 mm) at 950 mm/min
";
    let err = compile(src).unwrap_err();
    let MotionError::NoRoomForLeadIn {
        needed,
        available,
        span,
        ..
    } = &err
    else {
        panic!("{err:?}")
    };
    assert_eq!(available, "0 mm");
    assert!(needed.starts_with("0.445"), "{needed}");
    assert_eq!(
        &src[span.start as usize..span.end as usize],
        "move to (68.5 mm, 0, -20 mm) at 950 mm/min"
    );
    let code = miette::Diagnostic::code(&err).unwrap().to_string();
    assert_eq!(code, "lase::plan::no_room_for_lead_in");
    // The same recipe without leads plans (with the beam on during the ramp).
    assert!(
        compile(&src.replace("laser { power", "planner { leadin none }\nlaser { power")).is_ok()
    );
}

#[test]
fn a_lit_feed_above_the_axis_limits_is_a_diagnostic() {
    let src = "machine notcher
laser { power 300 W }
move to (10 mm, 0, -1 mm) rapid
laser on
move to (10 mm, 0, -20 mm) at 200 mm/s
";
    let err = compile(src).unwrap_err();
    assert!(
        matches!(err, MotionError::FeedUnreachable { .. }),
        "{err:?}"
    );
}

#[test]
fn lit_distance_between_section_ends_is_covered_at_the_feed() {
    // On the notch, every instant between Z-15.53 and Z-33.63 runs at 950 mm/min.
    let j = job(NOTCH);
    let f = 950.0 / 60.0;
    let sec = &j.sections[0];
    let segs = j.plan.segments();
    let s0 = segs[power::op_segments(&j, sec.first_op as usize).start].s_start;
    let s1 = s0 + 18.1;
    let (t0, t1) = (time_at_distance(&j, s0), time_at_distance(&j, s1));
    assert!((t1 - t0 - 18.1 / f).abs() < 1e-9, "{}", t1 - t0);
    for k in 0..=1000 {
        let t = t0 + (t1 - t0) * k as f64 / 1000.0;
        let v = j.plan.sample(t).v;
        assert!((v - f).abs() <= 1e-9 * f, "{v} at {t}");
    }
}
