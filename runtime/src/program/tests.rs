//! Unit tests of the process program: ops, limits, validation.

use super::*;

/// A program of `ops` on the stock `xy_table`, with its default settings.
pub(super) fn program(ops: Vec<Op>) -> ProcessProgram {
    let m = crate::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    ProcessProgram {
        recipe: "t".into(),
        limits: AxisLimit::of_machine(&m),
        path_limits: PathLimits::default(),
        planner: PlannerSettings {
            ramp: m.ramp,
            junction_deviation_mm: m.junction_deviation_mm,
            arc_tolerance_mm: m.arc_tolerance_mm,
            lookahead: None,
            leadin: LeadIn::Auto,
            order: CutOrder::Source,
            origin: JobOrigin::Absolute,
        },
        start: [0.0; 3],
        ordering: None,
        ops,
        settles: Vec::new(),
        machine: m,
    }
}

fn lit(power_w: f64, mode: PulseMode, feed_mm_s: f64, at: usize) -> Op {
    Op {
        kind: OpKind::Line {
            to: [1.0, 0.0, 0.0],
            feed_mm_s,
            laser: Some(Arc::new(Laser {
                power_w,
                spot_mm: 0.05,
                pulse: Some(Pulse {
                    mode,
                    width_s: None,
                    energy_j: None,
                }),
                couple: Coupling::None,
                kerf_mm: 0.0,
            })),
            orient: None,
            row: None,
        },
        span: Span::new(at, at + 1),
    }
}

/// The pulse estimate is the lit length over the pitch (or the lit time over the period)
/// plus the first pulse, measured from where the previous op left the spot; arcs by
/// their arc length.
#[test]
fn pulses_are_counted_from_the_lit_length() {
    let by_distance = PulseMode::Distance { pitch_mm: 0.001 };
    assert!((pulses_of(&lit(1.0, by_distance, 10.0, 0), [0.0; 3]) - 1001.0).abs() < 1e-6);
    // From x = 0.5 the same op is half as long.
    assert!((pulses_of(&lit(1.0, by_distance, 10.0, 0), [0.5, 0.0, 0.0]) - 501.0).abs() < 1e-6);
    // 1 mm at 10 mm/s is 0.1 s: 10 000 periods of 10 us.
    let by_time = PulseMode::Time { period_s: 1e-5 };
    assert!((pulses_of(&lit(1.0, by_time, 10.0, 0), [0.0; 3]) - 10_001.0).abs() < 1e-6);
    // Half a turn of radius 1 mm from (1, 0) to (-1, 0): pi mm.
    let mut arc = lit(1.0, by_distance, 10.0, 0);
    let OpKind::Line { laser, .. } = arc.kind else {
        unreachable!()
    };
    arc.kind = OpKind::Arc {
        to: [-1.0, 0.0, 0.0],
        center: [0.0, 0.0],
        ccw: true,
        feed_mm_s: 10.0,
        laser,
    };
    let n = pulses_of(&arc, [1.0, 0.0, 0.0]);
    assert!(
        (n - (std::f64::consts::PI / 0.001 + 1.0)).abs() < 1e-6,
        "{n}"
    );
}

/// Two ops of 10 000 001 pulses each (1 mm every 0.1 nm, slowly enough for the laser's
/// rate): the budget is passed at the first, and reported once.
#[test]
fn validate_refuses_more_pulses_than_the_budget_once() {
    let fine = PulseMode::Distance { pitch_mm: 1e-7 };
    let mut second = lit(1.0, fine, 0.001, 5);
    if let OpKind::Line { to, .. } = &mut second.kind {
        *to = [2.0, 0.0, 0.0];
    }
    let errs = program(vec![lit(1.0, fine, 0.001, 0), second])
        .validate()
        .unwrap_err();
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert_eq!(errs[0].span().start, 0);
    assert_eq!(
        errs[0].to_string(),
        "the program would fire about 10000001 pulses, above the 10000000 lase handles"
    );
}

/// The xy_table: 100 W, 100 kHz. Each (span, problem) is reported once.
#[test]
fn validate_holds_every_lit_op_to_the_laser() {
    let by_distance = PulseMode::Distance { pitch_mm: 0.001 };
    let ok = program(vec![lit(100.0, by_distance, 100.0, 0)]);
    assert_eq!(ok.validate(), Ok(()));
    let bad = program(vec![
        lit(100.0, by_distance, 101.0, 0),
        lit(100.0, by_distance, 120.0, 0),
        lit(150.0, PulseMode::Time { period_s: 5e-6 }, 1.0, 5),
    ]);
    let errs = bad.validate().unwrap_err();
    let codes: Vec<String> = errs
        .iter()
        .map(|e| format!("{} {}", e.code().unwrap(), e.span().start))
        .collect();
    assert_eq!(
        codes,
        [
            "lase::eval::pulse_rate 0",
            "lase::eval::above_machine 5",
            "lase::eval::pulse_rate 5"
        ]
    );
    assert_eq!(
        errs[0].to_string(),
        "pulse rate 101000 Hz is above the laser's maximum 100000 Hz"
    );
    assert_eq!(
        errs[1].to_string(),
        "laser power 150 W is above the machine's 100 W"
    );
}

/// An image row's power along it: forward, the run whose end column lies past the spot;
/// backward (run ends falling) the one whose end lies before it; turned rows alike.
#[test]
fn a_pixel_row_gives_the_power_of_the_run_under_the_spot() {
    let row = |angle: f64, shift: f64, runs: Vec<(u32, u8)>| PixelRow {
        origin: [1.0, 2.0],
        angle,
        v: 0.05,
        px: 0.1,
        shift,
        min_w: 10.0,
        max_w: 40.0,
        runs,
    };
    // Columns 2..4 at shade 255 (40 W), 4..5 white, 5..7 at 51 (16 W).
    let fwd = row(0.0, 0.0, vec![(4, 255), (5, 0), (7, 51)]);
    let at = |r: &PixelRow, u: f64| {
        let (s, c) = r.angle.sin_cos();
        r.power_w_at([1.0 + u * c - 0.05 * s, 2.0 + u * s + 0.05 * c])
    };
    assert_eq!(at(&fwd, 0.25), 40.0);
    assert_eq!(at(&fwd, 0.45), 0.0);
    assert!((at(&fwd, 0.65) - 16.0).abs() < 1e-12);
    // The same runs backward, shifted by 0.02 mm, on a row turned 30°.
    let back = row(30f64.to_radians(), 0.02, vec![(5, 51), (4, 0), (2, 255)]);
    assert!((at(&back, 0.67) - 16.0).abs() < 1e-12);
    assert_eq!(at(&back, 0.47), 0.0);
    assert_eq!(at(&back, 0.27), 40.0);
}
