//! Reports: summary numbers recomputed from closed forms, exact pulses, the trace's grid and
//! columns, and the plot's structure.

mod common;

use common::program;
use lase_lang::Span;
use lase_runtime::motion::{Job, plan_program};
use lase_runtime::program::{
    Coupling, Laser, Op, OpKind, P3, ProcessProgram, Pulse, PulseMode, Ramp,
};
use lase_runtime::report::{
    DOT_LIMIT, PNG_SCALE, PlotOptions, SpeedUnit, plot_png, plot_svg, pulse_events, summarize,
    write_trace,
};

// ------------------------------------------------------------------ helpers

fn op(kind: OpKind) -> Op {
    Op {
        kind,
        span: Span::new(0, 1),
    }
}

fn laser(power_w: f64, pulse: Option<PulseMode>) -> Option<Laser> {
    Some(Laser {
        power_w,
        spot_mm: 0.1,
        pulse: pulse.map(|mode| Pulse {
            mode,
            width_s: None,
            energy_j: None,
        }),
        couple: Coupling::None,
        kerf_mm: 0.0,
    })
}

fn line(to: P3, feed_mm_s: f64, laser: Option<Laser>) -> Op {
    op(OpKind::Line {
        to,
        feed_mm_s,
        laser: laser.map(std::sync::Arc::new),
        orient: None,
        row: None,
    })
}

fn plan(p: ProcessProgram) -> Job {
    plan_program(p).expect("plans")
}

/// 10 mm along x at 20 mm/s, lit, on the xy_table (S-curve unless changed).
fn ten_mm(ramp: Ramp, pulse: Option<PulseMode>) -> Job {
    let mut p = program(
        "xy_table",
        vec![line([10.0, 0.0, 0.0], 20.0, laser(50.0, pulse))],
    );
    p.planner.ramp = ramp;
    plan(p)
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

// ------------------------------------------------------------------ summary

#[test]
fn summary_of_a_ten_mm_scurve_line_matches_the_closed_form() {
    let job = ten_mm(Ramp::Scurve, None);
    let s = summarize(&job);
    // xy_table: J = 50 m/s³, a_max = 2 m/s². v = 20 mm/s < a²/J = 80 mm/s, so the ramp has no
    // constant-acceleration phase (PROCESS.md §4): T1 = √(v/J), ramp time 2·T1, ramp
    // distance v·T1, peak acceleration J·T1.
    let (v, j): (f64, f64) = (20.0, 50_000.0);
    let t1 = (v / j).sqrt();
    let ramp_d = v * t1;
    let expected = 2.0 * (2.0 * t1) + (10.0 - 2.0 * ramp_d) / v;
    assert!(
        close(s.cycle_time_s, expected, 1e-7),
        "{} vs {expected}",
        s.cycle_time_s
    );
    assert!(close(s.path_length_mm, 10.0, 1e-9));
    assert!(close(s.laser_on_length_mm, 10.0, 1e-9));
    assert!(close(s.laser_on_time_s, expected, 1e-7));
    assert_eq!(s.rapid_length_mm, 0.0);
    assert_eq!((s.blocks, s.ops, s.pulses), (1, 1, 0));
    assert_eq!(s.ramp, Ramp::Scurve);
    let x = &s.axes["X"];
    assert!(close(x.v_max, 20.0, 1e-6));
    assert!(close(x.a_max, j * t1, 1e-3), "{}", x.a_max);
    assert!(close(x.j_max.unwrap(), j, 1e-3));
    let y = &s.axes["Y"];
    assert_eq!((y.v_max, y.a_max, y.j_max), (0.0, 0.0, Some(0.0)));
}

#[test]
fn summary_of_a_trapezoid_line_has_no_jerk() {
    let job = ten_mm(Ramp::Trapezoid, None);
    let s = summarize(&job);
    // Ramp time v/a, ramp distance v²/2a.
    let (v, a) = (20.0, 2000.0);
    let expected = 2.0 * v / a + (10.0 - v * v / a) / v;
    assert!(
        close(s.cycle_time_s, expected, 1e-9),
        "{} vs {expected}",
        s.cycle_time_s
    );
    assert!(close(s.axes["X"].a_max, a, 1e-6));
    assert_eq!(s.axes["X"].j_max, None);
    let json = serde_json::to_string(&s).unwrap();
    assert!(json.contains(r#""j_max":null"#), "{json}");
    // Field order as documented.
    let keys = [
        "recipe",
        "machine",
        "ramp",
        "cycle_time_s",
        "path_length_mm",
        "rapid_length_mm",
        "laser_on_length_mm",
        "laser_on_time_s",
        "pulses",
        "blocks",
        "ops",
        "axes",
    ];
    let pos: Vec<usize> = keys
        .iter()
        .map(|k| json.find(&format!("\"{k}\"")).unwrap())
        .collect();
    assert!(pos.windows(2).all(|w| w[0] < w[1]), "{json}");
    assert!(json.contains(r#""ramp":"trapezoid""#));
}

#[test]
fn axis_peaks_follow_the_direction_of_the_move() {
    // A 3-4-5 diagonal: X carries 0.6, Y 0.8 of every path quantity.
    let mut p = program(
        "xy_table",
        vec![
            op(OpKind::Rapid {
                to: [30.0, 40.0, 0.0],
                orient: None,
            }),
            line([0.0, 0.0, 0.0], 20.0, None),
        ],
    );
    p.planner.ramp = Ramp::Trapezoid;
    let job = plan(p);
    let s = summarize(&job);
    assert!(close(s.rapid_length_mm, 50.0, 1e-9));
    assert!(close(s.path_length_mm, 100.0, 1e-9));
    assert_eq!(s.laser_on_length_mm, 0.0);
    // The rapid is limited by Y: v ≤ 250 / 0.8, a ≤ 2000 / 0.8 along the path.
    assert!(close(s.axes["Y"].v_max, 250.0, 1e-6) || s.axes["Y"].v_max < 250.0);
    assert!(close(s.axes["Y"].a_max, 2000.0, 1e-6), "{:?}", s.axes);
    assert!(close(s.axes["X"].a_max, 1500.0, 1e-6), "{:?}", s.axes);
    // Cross-check against the plan's own axis accelerations, sampled densely.
    let mut peak = [0.0f64; 2];
    let n = 20_000;
    for k in 0..=n {
        let smp = job.plan.sample(job.plan.duration() * k as f64 / n as f64);
        for (p, v) in peak.iter_mut().zip(smp.vel) {
            *p = p.max(v.abs());
        }
    }
    assert!(
        close(peak[0], s.axes["X"].v_max, 1e-3),
        "{peak:?} {:?}",
        s.axes
    );
    assert!(close(peak[1], s.axes["Y"].v_max, 1e-3));
}

// ------------------------------------------------------------------ pulses

#[test]
fn distance_pulses_land_every_pitch_including_both_ends() {
    let job = ten_mm(Ramp::Scurve, Some(PulseMode::Distance { pitch_mm: 1.0 }));
    let pulses: Vec<_> = pulse_events(&job).collect();
    assert_eq!(pulses.len(), 11);
    assert_eq!(summarize(&job).pulses, 11);
    for (k, p) in pulses.iter().enumerate() {
        assert!(close(p.s, k as f64, 1e-9), "pulse {k} at s = {}", p.s);
        assert!(close(p.pos[0], k as f64, 1e-9));
        assert_eq!(p.op, 0);
        // The time is where the plan really is at that distance.
        let at = job.plan.sample(p.t - job.initial_dwell_s);
        assert!(close(at.s, k as f64, 1e-9));
    }
    assert!(pulses.windows(2).all(|w| w[0].t < w[1].t));
    assert_eq!(pulses[0].t, 0.0);
    assert!(close(pulses[10].t, job.cycle_time(), 1e-12));
}

#[test]
fn time_pulses_fire_every_period_of_lit_time() {
    let job = ten_mm(Ramp::Trapezoid, Some(PulseMode::Time { period_s: 0.1 }));
    let t_end = job.cycle_time(); // 0.51 s
    let pulses: Vec<_> = pulse_events(&job).collect();
    assert_eq!(pulses.len(), (t_end / 0.1).floor() as usize + 1);
    for (k, p) in pulses.iter().enumerate() {
        assert!(close(p.t, 0.1 * k as f64, 1e-12));
        assert!(close(p.s, job.plan.sample(p.t).s, 1e-12));
    }
}

#[test]
fn each_lit_section_starts_its_own_count() {
    let d1 = Some(PulseMode::Distance { pitch_mm: 1.0 });
    let d2 = Some(PulseMode::Distance { pitch_mm: 0.5 });
    let job = plan(program(
        "xy_table",
        vec![
            line([2.5, 0.0, 0.0], 20.0, laser(10.0, d1)), // 0, 1, 2
            line([4.5, 0.0, 0.0], 20.0, laser(20.0, d1)), // same pulse: 3, 4 (s from 0)
            line([5.5, 0.0, 0.0], 20.0, laser(20.0, d2)), // new section: 4.5, 5, 5.5
            line([7.5, 0.0, 0.0], 20.0, None),            // unlit
            line([8.0, 0.0, 0.0], 20.0, laser(20.0, d1)), // new section: 7.5 only (0.5 < 1)
        ],
    ));
    let s: Vec<f64> = pulse_events(&job).map(|p| p.s).collect();
    let want = [0.0, 1.0, 2.0, 3.0, 4.0, 4.5, 5.0, 5.5, 7.5];
    assert_eq!(s.len(), want.len(), "{s:?}");
    for (a, b) in s.iter().zip(want) {
        assert!(close(*a, b, 1e-9), "{s:?}");
    }
    let ops: Vec<u32> = pulse_events(&job).map(|p| p.op).collect();
    assert_eq!(ops, [0, 0, 0, 1, 1, 2, 2, 2, 4]);
    assert_eq!(summarize(&job).pulses, 9);
}

// ------------------------------------------------------------------ trace

fn trace(job: &Job, period: f64) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    write_trace(job, period, &mut out).unwrap();
    String::from_utf8(out)
        .unwrap()
        .lines()
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

#[test]
fn trace_rows_cover_the_cycle_and_end_exactly_at_it() {
    let job = ten_mm(Ramp::Scurve, Some(PulseMode::Distance { pitch_mm: 1.0 }));
    let t_end = job.cycle_time();
    for period in [0.001, 0.01, 0.07, 0.54, 1.0] {
        let rows = trace(&job, period);
        assert_eq!(
            rows[0],
            [
                "t", "X", "Y", "px", "py", "pz", "v", "a", "laser", "power", "pulses"
            ]
        );
        let n = (t_end / period + 1e-9).floor() as usize + 1;
        let on_grid = (t_end - (n - 1) as f64 * period).abs() < 1e-9;
        assert_eq!(rows.len() - 1, n + usize::from(!on_grid), "period {period}");
        let last = rows.last().unwrap();
        assert!(close(last[0].parse().unwrap(), t_end, 1e-6));
        assert_eq!(last[1], "10");
        assert_eq!(last[10], "11", "every pulse has fired by the end");
        // Cumulative pulses are exact: compare with the pulse times.
        let times: Vec<f64> = pulse_events(&job).map(|p| p.t).collect();
        for r in &rows[1..] {
            let t: f64 = r[0].parse().unwrap();
            let fired = times.iter().filter(|&&p| p <= t + 1e-9).count();
            let col: usize = r[10].parse().unwrap();
            // The row's t is printed with 6 decimals; allow a pulse within that rounding.
            assert!(col.abs_diff(fired) <= 1, "t = {t}: {col} vs {fired}");
        }
    }
    // Mid-move: lit at 50 W, at cruise speed, px = X.
    let rows = trace(&job, 0.01);
    let mid = &rows[1 + 27];
    assert_eq!(mid[8], "1");
    assert_eq!(mid[9], "50");
    assert_eq!(mid[6], "20");
    assert_eq!(mid[1], mid[3]);
}

#[test]
fn trace_counts_the_initial_dwell() {
    let job = plan(program(
        "xy_table",
        vec![
            op(OpKind::Dwell { seconds: 0.25 }),
            line([10.0, 0.0, 0.0], 20.0, laser(50.0, None)),
        ],
    ));
    assert!(close(job.initial_dwell_s, 0.25, 1e-12));
    let rows = trace(&job, 0.05);
    let expected_rows = (job.cycle_time() / 0.05 + 1e-9).floor() as usize + 2;
    assert_eq!(rows.len() - 1, expected_rows);
    for r in &rows[1..=5] {
        // 0 .. 0.2 s: standing at the start, beam off.
        assert_eq!(
            (r[1].as_str(), r[6].as_str(), r[8].as_str()),
            ("0", "0", "0"),
            "{r:?}"
        );
    }
    // 0.25 s: the lit move starts (lit intervals are half-open: on at the start).
    assert_eq!(
        (rows[6][6].as_str(), rows[6][8].as_str()),
        ("0", "1"),
        "{:?}",
        rows[6]
    );
    assert_eq!(rows[7][8], "1", "{:?}", rows[7]);
    assert!(trace_err(&job, 0.0) && trace_err(&job, f64::NAN));
}

fn trace_err(job: &Job, period: f64) -> bool {
    write_trace(job, period, &mut Vec::new()).is_err()
}

// ------------------------------------------------------------------ plot

#[test]
fn plot_is_an_svg_with_paths_and_speeds() {
    let job = plan(program(
        "xy_table",
        vec![
            op(OpKind::Rapid {
                to: [10.0, 10.0, 0.0],
                orient: None,
            }),
            line([30.0, 10.0, 0.0], 20.0, laser(50.0, None)),
            op(OpKind::Arc {
                to: [40.0, 20.0, 0.0],
                center: [30.0, 20.0],
                ccw: true,
                feed_mm_s: 10.0,
                laser: laser(50.0, None).map(std::sync::Arc::new),
            }),
            line([0.0, 20.0, 0.0], 40.0, None),
        ],
    ));
    let svg = plot_svg(&job, &PlotOptions::default()).unwrap();
    assert!(svg.starts_with("<svg xmlns=\"http://www.w3.org/2000/svg\""));
    assert!(svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<svg").count(), 1);
    assert!(svg.contains("<polyline"));
    assert!(svg.contains("stroke-dasharray"), "rapids are dashed");
    assert!(svg.contains("#1f5fbf"), "unlit feeds are blue");
    assert!(
        svg.contains("fill-opacity"),
        "laser-on intervals are shaded"
    );
    assert!(svg.contains(">t [s]<") && svg.contains(">v [mm/s]<"));
    // Every element with content is closed (a cheap well-formedness check).
    for (open, close) in [("<text", "</text>"), ("<g", "</g>"), ("<title", "</title>")] {
        assert_eq!(
            svg.matches(open).count(),
            svg.matches(close).count(),
            "{open}"
        );
    }
    assert!(!svg.contains("NaN") && !svg.contains("inf"));
}

#[test]
fn plot_sampling_is_capped_for_long_jobs() {
    // 12 000 short moves: more segments than the per-segment budget allows.
    let ops: Vec<Op> = (1..=12_000)
        .map(|k| {
            let x = 0.01 * k as f64;
            let y = if k % 2 == 0 { 0.0 } else { 0.5 };
            line([x, y, 0.0], 50.0, laser(10.0, None))
        })
        .collect();
    let job = plan(program("xy_table", ops));
    let svg = plot_svg(&job, &PlotOptions::default()).unwrap();
    // 20 000 samples, drawn twice (path and speed), plus the points repeated where a
    // polyline changes color.
    let points = svg.matches(',').count();
    assert!(points <= 60_000, "{points} coordinate pairs");
    assert!(svg.contains("<polyline"));
}

/// Past `DOT_LIMIT` pulses the toolpath is a density view: no marks, and cells whose counts
/// add up to every pulse.
#[test]
fn plot_shows_a_density_view_past_the_dot_limit() {
    // 100 mm at a 5 µm pitch: 20 001 pulses.
    let job = plan(program(
        "xy_table",
        vec![line(
            [100.0, 0.0, 0.0],
            20.0,
            laser(50.0, Some(PulseMode::Distance { pitch_mm: 0.005 })),
        )],
    ));
    let pulses = summarize(&job).pulses;
    assert_eq!(pulses, 20_001);
    assert!(pulses > DOT_LIMIT);
    let svg = plot_svg(&job, &PlotOptions::default()).unwrap();
    assert!(!svg.contains(r#"class="pulse""#));
    let counted: u64 = svg
        .lines()
        .filter(|l| l.contains(r#"class="density""#))
        .map(|l| {
            let at = l.find("data-n=\"").unwrap() + 8;
            l[at..at + l[at..].find('"').unwrap()]
                .parse::<u64>()
                .unwrap()
        })
        .sum();
    assert_eq!(counted, pulses);
    assert!(svg.contains("20001 pulses: density"));
}

/// The PNG is the SVG at `PNG_SCALE` pixels per unit, and the lit path is inked.
#[test]
fn plot_png_is_the_svg_rasterized() {
    let job = ten_mm(Ramp::Scurve, None);
    let opts = PlotOptions::default();
    let svg = plot_svg(&job, &opts).unwrap();
    let png = plot_png(&job, &opts).unwrap();
    let pixmap = resvg::tiny_skia::Pixmap::decode_png(&png).unwrap();
    let head = svg.lines().next().unwrap();
    let attr = |name: &str| -> f64 {
        let at = head.find(&format!(" {name}=\"")).unwrap() + name.len() + 3;
        head[at..at + head[at..].find('"').unwrap()]
            .parse()
            .unwrap()
    };
    assert_eq!(pixmap.width() as f64, attr("width") * f64::from(PNG_SCALE));
    assert_eq!(
        pixmap.height() as f64,
        attr("height") * f64::from(PNG_SCALE)
    );
    let lit = svg.lines().find(|l| l.contains(r#"class="lit""#)).unwrap();
    let at = lit.find("points=\"").unwrap() + 8;
    let (x, y) = lit[at..]
        .split(' ')
        .next()
        .unwrap()
        .split_once(',')
        .unwrap();
    let (x, y): (f64, f64) = (x.parse().unwrap(), y.parse().unwrap());
    let s = f64::from(PNG_SCALE);
    let p = pixmap.pixel((x * s) as u32 + 2, (y * s) as u32).unwrap();
    assert!(p.red() < 230 || p.green() < 230 || p.blue() < 230, "{p:?}");
}

#[test]
fn the_speed_unit_is_the_recipes() {
    let min = "let cut = 950 mm/min\nmove to (1 mm, 0) at 3000 mm/min // 50 mm/s\n";
    assert_eq!(SpeedUnit::of_source(min), SpeedUnit::MmPerMin);
    let s = "follow p at 20 mm/s\nlimits { a 500 mm/s^2 } // 3 m/min\n";
    assert_eq!(SpeedUnit::of_source(s), SpeedUnit::MmPerS);
    assert_eq!(SpeedUnit::of_source(""), SpeedUnit::MmPerS);
    assert_eq!(SpeedUnit::MmPerMin.per_mm_s(), 60.0);
}

/// The live progress counts pulses from the plan: all of them by the end, none before the
/// start, never decreasing, and within one segment's pulses of the exact count at any time.
#[test]
fn live_progress_counts_the_pulses_fired_by_a_time() {
    let job = ten_mm(Ramp::Scurve, Some(PulseMode::Distance { pitch_mm: 1.0 }));
    let eta = lase_runtime::link::eta::Eta::new(&job, &[]);
    let times: Vec<f64> = pulse_events(&job).map(|p| p.t).collect();
    assert_eq!(eta.pulses(), times.len() as u64);
    assert_eq!(eta.pulses_done(-1.0), 0);
    assert_eq!(eta.pulses_done(job.cycle_time()), 11);
    let mut last = 0;
    for k in 0..=100 {
        let t = job.cycle_time() * k as f64 / 100.0;
        let got = eta.pulses_done(t);
        let exact = times.iter().filter(|&&p| p <= t).count() as u64;
        assert!(got >= last, "{got} after {last} at t = {t}");
        assert!(got.abs_diff(exact) <= 11, "{got} vs {exact} at t = {t}");
        last = got;
    }
    assert_eq!(eta.letters(), ['X', 'Y']);
    // A dotted arc split into many chords: the count stays within a chord's pulses.
    let job = common::compile(
        "machine xy_table\nlaser { power 25 W, spot 30 um }\npulse interval 0.5 mm\n\
         follow profile arc(center: (0, 0), radius: 33 mm, start: 30 deg, end: 150 deg) at 25 mm/s\n",
    )
    .unwrap();
    let eta = lase_runtime::link::eta::Eta::new(&job, &[]);
    let times: Vec<f64> = pulse_events(&job).map(|p| p.t).collect();
    assert!(times.len() > 50, "{}", times.len());
    let per_chord = job
        .plan
        .segments()
        .iter()
        // The lit chords (the rapid to the arc fires nothing).
        .filter(|s| s.feed.is_finite())
        .map(|s| (s.length / 0.5).ceil() as u64 + 1)
        .max()
        .unwrap();
    assert!(per_chord * 10 < times.len() as u64, "{per_chord}");
    let mut last = 0;
    for k in 0..=400 {
        let t = job.cycle_time() * k as f64 / 400.0;
        let got = eta.pulses_done(t);
        let exact = times.iter().filter(|&&p| p <= t).count() as u64;
        assert!(got >= last);
        assert!(
            got.abs_diff(exact) <= per_chord,
            "{got} vs {exact} at t = {t}"
        );
        last = got;
    }
    assert_eq!(last, times.len() as u64);
}
