//! The simulated GRBL under jogs shorter than a step (issue 15's settling steps across a row:
//! 0.5 µm against 4 µm steps at `$100=250`). GRBL's planner drops a block of zero steps, and
//! its `jog_execute` (grbl/jog.c) enters the Jog state only "if there is a block to execute";
//! the simulator entered it regardless, and with nothing to run never left it: after a dozen
//! or so alternating 0.5 µm Y jogs (the first zero-step one) every status said `Jog`.

use lase_runtime::link::sim::{Controller, ControllerConfig};

fn send(ctl: &mut Controller, line: &str) -> String {
    for b in line.bytes().chain(std::iter::once(b'\n')) {
        ctl.receive(b);
    }
    ctl.run(f64::INFINITY);
    ctl.receive(b'?');
    ctl.run(0.0);
    String::from_utf8(ctl.take_output()).unwrap()
}

#[test]
fn jogs_shorter_than_a_step_leave_the_simulator_idle() {
    let m =
        lase_runtime::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
    let mut ctl = Controller::new(ControllerConfig::for_machine(&m));
    for k in 0..40 {
        let dy = if k % 2 == 0 { 0.0005 } else { -0.0005 };
        let before = send(&mut ctl, "");
        let out = send(&mut ctl, &format!("$J=G91 Y{dy} F60"));
        assert!(out.starts_with("ok"), "jog {k}: {out}");
        assert!(
            out.contains("<Idle|"),
            "jog {k} left it in {out} (before: {before})"
        );
    }
    // A jog of whole steps after them still runs, and ends Idle where it was sent.
    let out = send(&mut ctl, "$J=G91 Y0.1 F600");
    assert!(out.contains("<Idle|"), "{out}");
    let at = out.find("MPos:").unwrap() + 5;
    let y: f64 = out[at..].split(',').nth(1).unwrap().parse().unwrap();
    assert!((y - 0.1).abs() < 0.004 + 1e-9, "{out}");
}
