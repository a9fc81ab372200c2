//! GRBL 1.1's motion model (`link::sim::motion`) against the real firmware: the executed
//! times grbl-sim measured for lase's GRBL programs (CONTROLLERS.md), each within 2 %.
//!
//! The programs are frozen copies of the GRBL NC lase emitted when the firmware was measured
//! (`fixtures/grbl_model/`), so a later change to the emit cannot silently move the
//! comparison; the machine settings come from the stock machine files as the simulator
//! derives them.

use lase_runtime::link::sim::motion::{Activity, Timeline, run_program};
use lase_runtime::link::sim::{Controller, ControllerConfig, Recording};
use lase_runtime::machine::parse_machine;

/// A frozen program and its machine's controller configuration.
fn program(name: &str) -> (String, ControllerConfig) {
    let dir = format!("{}/tests/fixtures/grbl_model", env!("CARGO_MANIFEST_DIR"));
    let nc = std::fs::read_to_string(format!("{dir}/{name}.grbl.nc")).unwrap();
    let machine_name = nc
        .lines()
        .find_map(|l| l.strip_prefix("(machine ")?.strip_suffix(')'))
        .unwrap();
    let machine = parse_machine(lase_stdlib::machine(machine_name).unwrap(), 0).unwrap();
    (nc, ControllerConfig::for_machine(&machine))
}

/// Runs a frozen program through the model with its machine's settings.
fn model(name: &str) -> Timeline {
    let (nc, cfg) = program(name);
    let limits = cfg.firmware.limits(&cfg.settings, cfg.planner_blocks);
    run_program(&nc, &limits, cfg.home()).unwrap()
}

/// Time from the first block's start to the last block's end (dwells and waits between them
/// count): what grbl-sim's step trace measures, from the first step to the last. The wait
/// before the first block (the protocol loop reading up to the first cycle start) has no step
/// in it.
fn motion_span(t: &Timeline) -> f64 {
    let moves: Vec<_> = t
        .spans
        .iter()
        .filter(|s| matches!(s.activity, Activity::Move { .. }))
        .collect();
    moves.last().map_or(0.0, |l| l.t0 + l.duration) - moves.first().map_or(0.0, |f| f.t0)
}

/// Streams a program to the simulated controller as lase's link does (character counting
/// against the 128-byte RX buffer), as fast as possible but modelled, and returns what it
/// recorded. Every line must be `ok`.
fn stream(name: &str) -> Recording {
    let (nc, cfg) = program(name);
    let mut c = Controller::new(cfg);
    let mut in_flight: std::collections::VecDeque<usize> = Default::default();
    let mut lines = nc.lines().map(|l| format!("{l}\n")).peekable();
    let mut out = String::new();
    loop {
        while let Some(l) = lines.peek() {
            if in_flight.iter().sum::<usize>() + l.len() > 127 {
                break;
            }
            in_flight.push_back(l.len());
            for b in l.bytes() {
                c.receive(b);
            }
            lines.next();
        }
        if lines.peek().is_none() {
            c.run(f64::INFINITY);
        } else {
            c.run_while_blocked();
        }
        out.push_str(&String::from_utf8_lossy(&c.take_output()));
        while let Some(i) = out.find("\r\n") {
            let reply: String = out.drain(..i + 2).collect();
            if reply.starts_with("ok") {
                in_flight.pop_front();
            }
            assert!(!reply.starts_with("error"), "{name}: {reply}");
        }
        if lines.peek().is_none() && in_flight.is_empty() {
            break;
        }
    }
    c.recording().clone()
}

/// `modelled` within 2 % of `measured`.
fn within(name: &str, modelled: f64, measured: f64) {
    within_pct(name, modelled, measured, 2.0);
}

fn within_pct(name: &str, modelled: f64, measured: f64, pct: f64) {
    let r = modelled / measured;
    eprintln!("{name}: model {modelled:.3} s, GRBL {measured:.2} s, ratio {r:.4}");
    assert!(
        (r - 1.0).abs() <= pct / 100.0,
        "{name}: model {modelled:.3} s vs GRBL {measured:.2} s (more than {pct} % apart)"
    );
}

#[test]
fn frame_marking() {
    within("frame_marking", motion_span(&model("frame_marking")), 20.22);
}

#[test]
fn dial_marks() {
    within("dial_marks", motion_span(&model("dial_marks")), 12.78);
}

/// Each texture row stops twice (its `M3` and `M5`), and after each stop the machine stands
/// while GRBL's protocol loop reads up to the next cycle start: 16 lines after an `M3` (the
/// planner full), the three lines and the `M3` after an `M5`, about 195 bytes a row.
#[test]
fn texture_array() {
    within("texture_array", motion_span(&model("texture_array")), 6.47);
}

#[test]
fn texture_array_unidirectional() {
    within(
        "texture_array_unidirectional",
        motion_span(&model("texture_array_unidirectional")),
        8.26,
    );
}

/// grbl-sim's 3.56 s "of motion" runs from the first step to the last, across the 0.5 s
/// swing dwell between them.
#[test]
fn conrod_notch() {
    within(
        "conrod_notch motion",
        motion_span(&model("conrod_notch")),
        3.56,
    );
}

/// After a stop nothing moves until GRBL's protocol loop has read up to its next cycle start,
/// 50 µs a byte (grbl-sim): at a sync (the `M3` line's own bytes count before the first
/// start), and when a line finds the planner full (the 16th after the stop, 15 queued).
#[test]
fn restart_waits_for_the_bytes_read() {
    let (_, cfg) = program("frame_marking");
    let limits = cfg.firmware.limits(&cfg.settings, cfg.planner_blocks);
    let moves: String = (1..=20).map(|k| format!("X{k}\n")).collect();
    let nc = format!("G1 X0.5 F600\nM3 S100\n{moves}M5\n");
    let t = run_program(&nc, &limits, cfg.home()).unwrap();
    let waits: Vec<(f64, f64)> = t
        .spans
        .iter()
        .filter(|s| s.activity == Activity::Rest && s.duration > 0.0)
        .map(|s| (s.t0, s.duration))
        .collect();
    // "G1 X0.5 F600\n" and "M3 S100\n": 21 bytes before the lead-in starts.
    assert_eq!(waits[0].0, 0.0);
    assert!((waits[0].1 - 21.0 * 50e-6).abs() < 1e-12, "{waits:?}");
    // After the M3 stop: X1 … X9 (3 bytes each), X10 … X16 (4 each).
    let first_move_after = t.spans.iter().find(|s| s.line == 3).unwrap();
    assert_eq!(waits.len(), 2, "{waits:?}");
    assert!(
        (waits[1].1 - (9.0 * 3.0 + 7.0 * 4.0) * 50e-6).abs() < 1e-12,
        "{waits:?}"
    );
    assert!((first_move_after.t0 - (waits[1].0 + waits[1].1)).abs() < 1e-12);
    assert_eq!(t.syncs, 2);
}

/// The simulator executes with the model: streamed like lase streams, its executed time and
/// blocks are the model's (the model assumes a slot is refilled the moment it frees; the
/// stream refills it when the protocol loop next reads, which changes nothing here).
#[test]
fn simulator_runs_the_model() {
    for name in [
        "frame_marking",
        "dial_marks",
        "texture_array",
        "conrod_notch",
    ] {
        let t = model(name);
        let rec = stream(name);
        eprintln!(
            "{name}: simulator {:.4} s, model {:.4} s",
            rec.executed_s, t.total_s
        );
        assert_eq!(rec.blocks.len(), t.blocks, "{name}");
        assert!(
            (rec.executed_s - t.total_s).abs() <= 1e-6 * t.total_s.max(1.0),
            "{name}: simulator {} s vs model {} s",
            rec.executed_s,
            t.total_s
        );
    }
}

/// Feeds `text` to the controller and lets `dt` simulated seconds pass; returns its answers.
fn send(c: &mut Controller, text: &str, dt: f64) -> String {
    for b in text.bytes() {
        c.receive(b);
    }
    c.run(dt);
    String::from_utf8_lossy(&c.take_output()).into_owned()
}

/// While it moves the simulator says `Run`, with the position interpolated along the
/// trapezoid and the planner blocks it holds; a feed hold decelerates at `$120` over
/// v²/2a before `Hold:0`, and the beam edges carry the speed they happened at.
#[test]
fn status_motion_and_feed_hold() {
    let (nc, cfg) = program("frame_marking");
    let mut c = Controller::new(cfg);
    // Everything up to the first long side (G1 X40 at 20 mm/s, 2 s), queued at once (the
    // lines after the `M3` wait in the RX buffer until its sync).
    for l in nc.lines().take(12) {
        let s = send(&mut c, &format!("{l}\n"), 0.0);
        assert!(!s.contains("error"), "{s}");
    }
    // Nothing moves until the protocol loop has read the bytes before a cycle start (GRBL's
    // restart, motion.rs): sent a line at a time, the RX buffer runs dry after the `G0`, the
    // first line that moves, so it starts once its 142 bytes are read at grbl-sim's 50 µs.
    let s = send(&mut c, "?", 0.0);
    assert!(s.contains("<Idle|MPos:0.000,0.000,0.000|Bf:13,"), "{s}");
    let s = send(&mut c, "?", 142.0 * 50e-6 - 1e-6);
    assert!(s.contains("<Idle|MPos:0.000,0.000,0.000|"), "{s}");
    let s = send(&mut c, "?", 2e-6);
    assert!(s.contains("<Run|"), "{s}");
    // 1 s in, the table cruises along X at 20 mm/s.
    let s = send(&mut c, "?", 1.0);
    let x0 = c.position()[0];
    assert!(s.contains("<Run|"), "{s}");
    assert!((c.speed() - 20.0).abs() < 1e-9, "speed {}", c.speed());
    assert!(x0 > 0.0 && x0 < 40.0, "x {x0}");
    // Feed hold: 5 ms later still decelerating (Hold:1) at half speed.
    let s = send(&mut c, "!?", 0.005);
    assert!(s.contains("<Hold:1|"), "{s}");
    assert!((c.speed() - 10.0).abs() < 1e-6, "speed {}", c.speed());
    let s = send(&mut c, "?", 0.1);
    assert!(s.contains("<Hold:0|"), "{s}");
    // Stopped v²/2a = 20²/(2·2000) = 0.1 mm past where the hold began.
    let dx = c.position()[0] - x0;
    assert!((dx - 0.1).abs() < 1e-6, "stopping distance {dx}");
    // Resume: runs to the end; the beam went on at rest (M3 syncs) and every edge is recorded
    // with its speed.
    send(&mut c, "~", f64::INFINITY);
    let s = send(&mut c, "?", 0.0);
    assert!(s.contains("<Idle|"), "{s}");
    let edges = &c.recording().laser;
    assert!(!edges.is_empty());
    assert_eq!(edges[0].power_s, 400.0);
    assert_eq!(edges[0].speed_mm_s, 0.0);
}

/// In laser mode S words on moves switch the beam without a stop: texture_array's dots come
/// on and go off at the 20 mm/s cruise speed, never at rest, except where `M3`/`M5` stop.
#[test]
fn s_word_edges_at_cruise_speed() {
    let rec = stream("texture_array");
    let moving: Vec<f64> = rec
        .laser
        .iter()
        .filter(|e| e.speed_mm_s > 0.0)
        .map(|e| e.speed_mm_s)
        .collect();
    assert!(moving.len() > 500, "{} moving edges", moving.len());
    let at_cruise = moving.iter().filter(|v| (**v - 20.0).abs() < 1e-9).count();
    assert!(
        at_cruise * 10 >= moving.len() * 9,
        "{at_cruise} of {}",
        moving.len()
    );
}

/// grblHAL answers `$I` with its extra lines and sends no banner to a new TCP client.
#[test]
fn grblhal_build_info_and_no_banner() {
    let machine = parse_machine(lase_stdlib::machine("cam_xwb").unwrap(), 0).unwrap();
    let mut c = Controller::new(ControllerConfig::for_machine(&machine));
    c.connected();
    assert_eq!(String::from_utf8_lossy(&c.take_output()), "");
    let s = send(&mut c, "$I\n", 0.0);
    for l in [
        "[VER:1.1f.",
        "[OPT:VNML+,100,1024,6,0]",
        "[AXS:6:XYZABC]",
        "[NEWOPT:ENUMS,RT+,",
        "[FIRMWARE:grblHAL]",
        "[NVS STORAGE:*EEPROM]",
        "[DRIVER:",
        "[DRIVER VERSION:",
    ] {
        assert!(s.contains(l), "{l} missing from {s}");
    }
    assert!(s.ends_with("ok\r\n"), "{s}");
}
