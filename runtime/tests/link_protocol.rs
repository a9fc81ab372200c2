//! The GRBL 1.1 client against the simulated controller over real TCP sockets on 127.0.0.1:
//! answers and error codes, soft-limit alarms, both flow controls, the RX buffer under a full
//! planner, an overrunning client caught by the simulator, and a client that never panics
//! whatever bytes come back.

use lase_runtime::link::grbl::GrblLink;
use lase_runtime::link::sim::{self, SimHandle, SimOptions, TimeScale};
use lase_runtime::link::stream::{self, Outcome, Progress, StreamOptions};
use lase_runtime::link::transport::{TcpTransport, Transport};
use lase_runtime::link::{
    ConnectOptions, Event, Link, LinkError, MachineState, MotionMode, Reply, Requirements,
};
use lase_runtime::machine::{Machine, parse_machine};
use proptest::prelude::*;
use std::io::Write;
use std::time::Duration;

fn xy_table() -> Machine {
    parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap()
}

fn start(opts: SimOptions) -> SimHandle {
    sim::serve(&xy_table(), "127.0.0.1:0".parse().unwrap(), opts).unwrap()
}

fn max() -> SimOptions {
    SimOptions {
        time_scale: TimeScale::Max,
        ..SimOptions::default()
    }
}

fn connect(h: &SimHandle, options: &ConnectOptions) -> GrblLink {
    let a = h.addr().unwrap();
    let t = TcpTransport::connect(&a.ip().to_string(), a.port()).unwrap();
    GrblLink::connect(Box::new(t), format!("tcp://{a}"), options).unwrap()
}

fn lines(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn run(link: &mut dyn Link, l: &[String]) -> stream::Report {
    stream::stream(
        link,
        &stream::StreamJob::new(l),
        None,
        &StreamOptions::default(),
        &mut |_: &Progress, _: Option<&Event>| None,
    )
}

#[test]
fn answers_error_codes_status_and_parser_state() {
    let h = start(max());
    let mut link = connect(&h, &ConnectOptions::default());
    assert!(link.describe().contains("Grbl 1.1h"), "{}", link.describe());
    match link.send("G1 X1").unwrap() {
        Reply::Error { code, message } => {
            assert_eq!(code, 22);
            assert!(message.contains("feed rate"), "{message}");
        }
        r => panic!("{r:?}"),
    }
    assert_eq!(
        link.send("G5 X1").unwrap(),
        Reply::Error {
            code: 20,
            message: lase_runtime::link::grbl::codes::error_message(20).into()
        }
    );
    assert_eq!(link.send("G0 X1 Y-2 (a comment)").unwrap(), Reply::Ok);
    assert_eq!(link.send("").unwrap(), Reply::Ok);
    // The rapid runs for a moment (the firmware says `Run` meanwhile); then the table is at rest.
    let mut s = link.query_status(Duration::from_secs(2)).unwrap();
    for _ in 0..200 {
        if s.state == MachineState::Idle {
            break;
        }
        assert_eq!(s.state, MachineState::Run);
        std::thread::sleep(Duration::from_millis(10));
        s = link.query_status(Duration::from_secs(2)).unwrap();
    }
    assert_eq!(s.state, MachineState::Idle);
    assert_eq!(s.mpos, Some(vec![1.0, -2.0, 0.0]));
    assert!(s.buffer.is_some() && s.feed.is_some());
    let m = link.modal_state().unwrap();
    assert_eq!(m.motion, MotionMode::Rapid);
    assert!(!m.inches && !m.incremental);
    assert!(
        link.check_settings(&Requirements::default())
            .unwrap()
            .is_empty()
    );
    assert_eq!(
        link.send("$Q").unwrap(),
        Reply::Error {
            code: 3,
            message: lase_runtime::link::grbl::codes::error_message(3).into()
        }
    );
    drop(link);
    let rec = h.stop();
    assert_eq!(rec.rx_overflows, 0);
}

fn stock(name: &str) -> Machine {
    parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

#[test]
fn a_rotary_machine_gets_a_six_axis_grblhal_that_times_g93_blocks() {
    let cam = stock("cam_xwb");
    let h = sim::serve(&cam, "127.0.0.1:0".parse().unwrap(), max()).unwrap();
    let mut link = connect(&h, &ConnectOptions::default());
    // grblHAL greets a TCP client with no banner; its `$I` (`[FIRMWARE:grblHAL]`) says what it
    // is, and the RX buffer its `[OPT:…]` reports is the one lines are counted against.
    assert!(link.banner().is_none(), "{:?}", link.banner());
    assert!(link.is_grblhal());
    assert_eq!(link.rx_buffer(), 1024);
    // Rates and accelerations in degrees: C at 180 deg/s is $115 = 10800 deg/min.
    let needs = |letter: char, v: f64, a: f64| Requirements {
        axes: vec![lase_runtime::link::AxisNeed {
            letter,
            rotary: true,
            v_per_min: v,
            a_per_s2: a,
            v_span: Default::default(),
            a_span: Default::default(),
        }],
        ..Requirements::default()
    };
    assert!(
        link.check_settings(&needs('C', 10800.0, 1800.0))
            .unwrap()
            .is_empty()
    );
    let too_fast = link.check_settings(&needs('B', 10900.0, 1800.0)).unwrap();
    assert_eq!(too_fast.len(), 1, "{too_fast:?}");
    assert!(
        too_fast[0].setting.contains("$114"),
        "{}",
        too_fast[0].setting
    );
    // One G93 block: X, B and C together, in 0.5 s (F = 120 per minute).
    assert_eq!(link.send("G21 G90 G93").unwrap(), Reply::Ok);
    assert_eq!(link.send("G1 X10 B-5.5 C90 F120").unwrap(), Reply::Ok);
    assert!(h.wait_quiet(Duration::from_secs(5)));
    let s = link.query_status(Duration::from_secs(2)).unwrap();
    assert_eq!(s.mpos, Some(vec![10.0, 0.0, 0.0, 0.0, -5.5, 90.0]));
    let m = link.modal_state().unwrap();
    assert!(m.inverse_time);
    // Beyond B's travel (±100°, checked in degrees): soft limit, ALARM:2 instead of an answer.
    link.send_line("G1 B120 F60").unwrap();
    let mut alarm = None;
    for _ in 0..100 {
        if let Some(Event::Alarm { code, .. }) = link.poll(Duration::from_millis(50)).unwrap() {
            alarm = Some(code);
            break;
        }
    }
    assert_eq!(alarm, Some(2));
    drop(link);
    let rec = h.stop();
    let b = &rec.blocks[0];
    assert_eq!(b.to, [10.0, 0.0, 0.0, 0.0, -5.5, 90.0]);
    // G93 sets the block's programmed speed (its length over 0.5 s); like GRBL, the machine
    // ramps up and down to it at the acceleration the axes allow along the block, from rest to
    // rest: t = L/v + v/a when it reaches v.
    let d = [10.0f64, 0.0, 0.0, 0.0, -5.5, 90.0];
    let len = d.iter().map(|x| x * x).sum::<f64>().sqrt();
    let settings = sim::ControllerConfig::for_machine(&cam).settings;
    let a = (0..6)
        .filter(|&k| d[k] != 0.0)
        .map(|k| settings[&(120 + k as u32)] / (d[k].abs() / len))
        .fold(f64::INFINITY, f64::min);
    let v = len / 0.5;
    assert!(v * v / a < len, "reaches its speed");
    let expected = len / v + v / a;
    assert!(
        (b.duration - expected).abs() < 1e-9,
        "{} vs {expected}",
        b.duration
    );
    assert_eq!(rec.alarms, vec![2]);
}

#[test]
fn a_grbl_controller_is_refused_for_a_job_that_moves_c() {
    // An xy_table simulator is GRBL 1.1: three axes in its status report.
    let h = start(max());
    let mut link = connect(&h, &ConnectOptions::default());
    let needs = Requirements {
        axes: vec![lase_runtime::link::AxisNeed {
            letter: 'C',
            rotary: true,
            v_per_min: 600.0,
            a_per_s2: 100.0,
            v_span: Default::default(),
            a_span: Default::default(),
        }],
        ..Requirements::default()
    };
    let errs = link.check_settings(&needs).unwrap();
    assert_eq!(errs.len(), 1, "{errs:?}");
    assert_eq!(errs[0].setting, "axis count");
    assert!(errs[0].help.contains("grblHAL"), "{}", errs[0].help);
    drop(link);
    h.stop();
}

#[test]
fn a_soft_limit_raises_alarm_2_at_its_line_and_the_job_stops() {
    let h = start(max());
    let mut link = connect(&h, &ConnectOptions::default());
    let job = lines(&["G21 G90 G94", "G0 X10 Y10", "G1 X1000 F600", "G0 X0 Y0"]);
    let r = run(&mut link, &job);
    match r.outcome {
        Outcome::Alarm { index, code, .. } => {
            assert_eq!(code, 2);
            assert_eq!(index, Some(2), "the line that would leave the travel");
        }
        o => panic!("{o:?}"),
    }
    assert!(r.stop_note.unwrap().contains("soft reset"));
    // Alarm survives the reset; `$X` unlocks. As in GRBL the alarm stopped the motion
    // already planned (somewhere on the way to X10 Y10) and the position was kept.
    let s = link.query_status(Duration::from_secs(2)).unwrap();
    assert_eq!(s.state, MachineState::Alarm);
    let p = s.mpos.unwrap();
    assert!(p[0] == p[1] && (0.0..=10.0).contains(&p[0]), "{p:?}");
    assert!(matches!(
        link.send("G0 X0").unwrap(),
        Reply::Error { code: 9, .. }
    ));
    assert_eq!(link.send("$X").unwrap(), Reply::Ok);
    assert_eq!(link.send("G0 X0").unwrap(), Reply::Ok);
    drop(link);
    let rec = h.stop();
    assert_eq!(rec.alarms, vec![2]);
}

#[test]
fn a_soft_reset_while_moving_raises_alarm_3() {
    let h = start(SimOptions {
        time_scale: TimeScale::Real,
        ..SimOptions::default()
    });
    let mut link = connect(&h, &ConnectOptions::default());
    assert_eq!(link.send("G1 X100 F600").unwrap(), Reply::Ok);
    std::thread::sleep(Duration::from_millis(50));
    link.realtime(lase_runtime::link::Realtime::SoftReset)
        .unwrap();
    let mut alarm = None;
    for _ in 0..100 {
        match link.poll(Duration::from_millis(20)).unwrap() {
            Some(Event::Alarm { code, .. }) => alarm = Some(code),
            Some(Event::Reset { .. }) => break,
            _ => {}
        }
    }
    assert_eq!(alarm, Some(3));
    drop(link);
    h.stop();
}

/// A generated raster: short lit lines, as a texturing job streams them.
fn raster(n: usize) -> Vec<String> {
    let mut v = lines(&["G21 G90 G17 G94", "G0 X0 Y0", "M3 S300"]);
    for i in 0..n {
        let y = i as f64 * 0.05;
        let x = if i % 2 == 0 { 20.0 } else { 0.0 };
        v.push(format!("G1 X{x} Y{} F3000", lase_runtime::emit::number(y)));
    }
    v.push("M5".into());
    v.push("M2".into());
    v
}

#[test]
fn send_response_and_character_counting_deliver_the_same_lines() {
    let job = raster(300);
    let mut fills = Vec::new();
    for send_response in [false, true] {
        let h = start(max());
        let mut link = connect(
            &h,
            &ConnectOptions {
                send_response,
                ..ConnectOptions::default()
            },
        );
        let r = run(&mut link, &job);
        assert_eq!(r.outcome, Outcome::Done);
        assert_eq!(r.acked, job.len());
        drop(link);
        assert!(h.wait_quiet(Duration::from_secs(5)));
        let rec = h.stop();
        let got: Vec<String> = rec
            .lines
            .iter()
            .filter(|l| l.result != sim::LineResult::System)
            .map(|l| l.text.clone())
            .collect();
        assert_eq!(got, job);
        assert_eq!(
            rec.blocks.last().unwrap().to,
            [0.0, 14.95, 0.0, 0.0, 0.0, 0.0]
        );
        fills.push(rec.max_rx_fill);
    }
    let longest = job.iter().map(|l| l.len() + 1).max().unwrap();
    assert!(
        fills[1] <= longest,
        "send-response: one line at a time ({fills:?})"
    );
}

#[test]
fn lines_wait_in_the_rx_buffer_while_the_planner_is_full_and_it_never_overflows() {
    let h = start(SimOptions {
        time_scale: TimeScale::Factor(50.0),
        rx_buffer: Some(64),
        planner_blocks: Some(4),
        ..SimOptions::default()
    });
    let mut link = connect(
        &h,
        &ConnectOptions {
            rx_buffer: Some(64),
            ..ConnectOptions::default()
        },
    );
    let job = raster(60);
    let r = run(&mut link, &job);
    assert_eq!(r.outcome, Outcome::Done);
    drop(link);
    let rec = h.stop();
    assert_eq!(rec.rx_overflows, 0, "{:?}", rec.overflow_log);
    assert_eq!(rec.max_planner_fill, 4);
    assert!(
        rec.max_rx_fill > 30 && rec.max_rx_fill <= 63,
        "several lines waited in the buffer: {}",
        rec.max_rx_fill
    );
}

/// Without a configured size the client asks `$I` and fills the buffer the controller has (a
/// grblHAL's is 1024 bytes), never more.
#[test]
fn the_rx_buffer_the_controller_reports_is_used_and_never_overrun() {
    let h = start(SimOptions {
        time_scale: TimeScale::Factor(50.0),
        rx_buffer: Some(1024),
        planner_blocks: Some(4),
        ..SimOptions::default()
    });
    let mut link = connect(
        &h,
        &ConnectOptions {
            rx_buffer: None,
            ..ConnectOptions::default()
        },
    );
    assert_eq!(link.rx_buffer(), 1024);
    let r = run(&mut link, &raster(200));
    assert_eq!(r.outcome, Outcome::Done);
    drop(link);
    let rec = h.stop();
    assert_eq!(rec.rx_overflows, 0, "{:?}", rec.overflow_log);
    assert!(
        rec.max_rx_fill > 127 && rec.max_rx_fill <= 1023,
        "more than GRBL's 128 bytes waited in the buffer: {}",
        rec.max_rx_fill
    );
}

/// A simulated grblHAL has grblHAL's own buffers, not GRBL's: `$I` says 100 planner blocks
/// and a 1024-byte RX buffer (`[OPT:VNML+,100,1024,6,0]`, as the grblHAL Simulator reports),
/// the default link counts characters against those 1024 bytes, and the planner holds more
/// than GRBL's 15 blocks.
#[test]
fn a_grblhal_has_grblhals_buffers_and_the_link_counts_against_them() {
    let cam = parse_machine(lase_stdlib::machine("cam_xwb").unwrap(), 0).unwrap();
    let h = sim::serve(
        &cam,
        "127.0.0.1:0".parse().unwrap(),
        SimOptions {
            time_scale: TimeScale::Factor(50.0),
            ..SimOptions::default()
        },
    )
    .unwrap();
    let mut link = connect(&h, &ConnectOptions::default());
    assert_eq!(link.rx_buffer(), 1024);
    let mut job = lines(&["G21 G90 G17 G94", "G0 X0", "M3 S300"]);
    for i in 0..300 {
        let x = if i % 2 == 0 { 20.0 } else { 0.0 };
        job.push(format!("G1 X{x} C{} F3000", i % 360));
    }
    job.extend(lines(&["M5", "M2"]));
    let r = run(&mut link, &job);
    assert_eq!(r.outcome, Outcome::Done);
    drop(link);
    let rec = h.stop();
    assert_eq!(rec.rx_overflows, 0, "{:?}", rec.overflow_log);
    assert!(
        rec.max_rx_fill > 127 && rec.max_rx_fill <= 1023,
        "the RX buffer held {} bytes at most",
        rec.max_rx_fill
    );
    let mut c = sim::Controller::new(sim::ControllerConfig::for_machine(&cam));
    for b in b"$I\n" {
        c.receive(*b);
    }
    c.run(0.0);
    let info = String::from_utf8_lossy(&c.take_output()).into_owned();
    assert!(info.contains("[OPT:VNML+,100,1024,6,0]"), "{info}");
}

#[test]
fn a_client_that_overruns_the_rx_buffer_is_caught() {
    let h = start(SimOptions {
        time_scale: TimeScale::Factor(1.0),
        planner_blocks: Some(2),
        ..SimOptions::default()
    });
    let a = h.addr().unwrap();
    let mut s = std::net::TcpStream::connect(a).unwrap();
    // No flow control at all: 40 lines at once while the planner holds two slow moves.
    let mut burst = String::new();
    for i in 0..40 {
        burst.push_str(&format!("G1 X{} F60\n", i % 2));
    }
    s.write_all(burst.as_bytes()).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    drop(s);
    let rec = h.stop();
    assert!(rec.rx_overflows > 0);
    assert!(
        rec.overflow_log[0].contains("RX buffer overflow"),
        "{:?}",
        rec.overflow_log
    );
}

/// A transport that replays scripted bytes, then reports the connection closed.
struct Script {
    chunks: Vec<Vec<u8>>,
}

impl Transport for Script {
    fn write_all(&mut self, _bytes: &[u8]) -> std::io::Result<()> {
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> std::io::Result<usize> {
        if self.chunks.is_empty() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                "end",
            ));
        }
        let mut c = self.chunks.remove(0);
        let n = c.len().min(buf.len());
        buf[..n].copy_from_slice(&c[..n]);
        if n < c.len() {
            self.chunks.insert(0, c.split_off(n));
        }
        Ok(n)
    }

    fn describe(&self) -> String {
        "script".into()
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// Whatever the controller sends after a valid greeting, the client answers with events
    /// or an error, and never panics.
    #[test]
    fn any_controller_output_gives_events_or_a_clear_error(
        noise in proptest::collection::vec(
            prop_oneof![
                proptest::collection::vec(any::<u8>(), 0..40),
                Just(b"ok\r\n".to_vec()),
                Just(b"error:22\r\n".to_vec()),
                Just(b"ALARM:2\r\n".to_vec()),
                Just(b"<Run|MPos:1.000,2.000,0.000|Bf:3,100|FS:1200,300>\r\n".to_vec()),
                Just(b"<Idle|MPos:1.0".to_vec()),
                Just(b"[MSG:Pgm End]\r\n".to_vec()),
                Just(b"[FOO:bar]\r\n".to_vec()),
                Just(b"Grbl 1.1h ['$' for help]\r\n".to_vec()),
                Just(b"\r\n".to_vec()),
            ],
            0..20,
        )
    ) {
        let mut chunks = vec![
            b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n".to_vec(),
            b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\nok\r\n".to_vec(),
            // The answer to `$I`, which every connection asks.
            b"[VER:1.1h.20190825:]\r\n[OPT:V,15,128]\r\nok\r\n".to_vec(),
        ];
        chunks.extend(noise);
        let mut link = GrblLink::connect(
            Box::new(Script { chunks }),
            "script".into(),
            &ConnectOptions::default(),
        ).unwrap();
        for _ in 0..3 {
            if link.can_send("G1 X1 F100") {
                let _ = link.send_line("G1 X1 F100");
            }
        }
        for _ in 0..100 {
            match link.poll(Duration::from_millis(1)) {
                Ok(Some(_)) | Ok(None) => {}
                Err(e) => {
                    prop_assert!(matches!(
                        e,
                        LinkError::Protocol { .. } | LinkError::Lost { .. }
                    ), "{e:?}");
                    prop_assert!(!e.to_string().is_empty());
                    break;
                }
            }
        }
    }
}

#[test]
fn a_connection_dropped_after_some_seconds_is_a_lost_link() {
    let h = start(SimOptions {
        time_scale: TimeScale::Factor(1.0),
        faults: sim::Faults {
            drop_after_secs: vec![0.3],
            ..sim::Faults::default()
        },
        ..SimOptions::default()
    });
    let mut link = connect(&h, &ConnectOptions::default());
    let r = run(&mut link, &raster(400));
    assert!(matches!(r.outcome, Outcome::Lost(_)), "{:?}", r.outcome);
    assert!(r.acked < 400);
    drop(link);
    h.stop();
}
