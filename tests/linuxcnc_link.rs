//! `lase run --link linuxcnc://…` against a real, headless LinuxCNC 2.9 (`common::linuxcnc`):
//! a flat-bed and the cam example run end to end from the command line, hold and resume,
//! abort, and a dropped link followed again with the journal; what LinuxCNC did is read from
//! its HAL samples (beam edges, pulses, standstill during a hold). Runs wherever LinuxCNC
//! is installed (see `common::linuxcnc::available`).

mod common;

use common::linuxcnc::{Headless, Sample, available};
use lase_runtime::FsFiles;
use lase_runtime::emit::{Dialect, EmitOptions};
use lase_runtime::link::journal::{self, Journal};
use lase_runtime::link::linuxcnc::Rsh;
use lase_runtime::link::linuxcnc::job::{self as lcjob, LinuxCncJob, Placement, Resumed};
use lase_runtime::link::stream::{Control, Outcome};
use lase_runtime::link::transport::{TcpTransport, Transport};
use std::time::{Duration, Instant};

fn machine(name: &str) -> lase_runtime::machine::Machine {
    lase_runtime::machine::parse_machine(lase_stdlib::machine(name).unwrap(), 0).unwrap()
}

/// Beam-gate edges and pulse rising edges in samples.
fn beam(samples: &[Sample]) -> (usize, usize) {
    let edges = samples
        .windows(2)
        .filter(|w| w[0].dout[0] != w[1].dout[0])
        .count();
    let pulses = samples
        .windows(2)
        .filter(|w| !w[0].dout[1] && w[1].dout[1])
        .count();
    (edges, pulses)
}

/// The plan's beam edges (lit on and off) and pulses of an example.
fn planned(example: &str) -> (lase_runtime::Job, usize, u64) {
    let name = common::root()
        .join("examples")
        .join(format!("{example}.lase"))
        .display()
        .to_string();
    let (_, job) =
        lase_runtime::compile(&mut FsFiles, &name).unwrap_or_else(|(_, f)| panic!("{name}: {f}"));
    let s = lase_runtime::report::summarize(&job);
    let t0 = job.initial_dwell_s;
    let n = (job.plan.duration() / 1e-4) as usize;
    let mut edges = 0;
    let mut last = false;
    for k in 0..=n {
        let (_, lit, _) = lase_runtime::report::beam_at(&job, t0 + k as f64 * 1e-4);
        edges += usize::from(lit != last);
        last = lit;
    }
    (job, edges, s.pulses)
}

/// The newest sample number so far (samples after it belong to what follows), after
/// restarting LinuxCNC if its task vanished at the end of the step before (see
/// `Headless::task_alive`).
fn mark(lcnc: &mut Headless) -> u64 {
    if !lcnc.task_alive() {
        eprintln!("LinuxCNC's task (milltask) vanished after the step before; restarting LinuxCNC");
        lcnc.restart();
    }
    lcnc.last_sample()
}

fn lines_of(job: &lase_runtime::Job) -> Vec<String> {
    lase_runtime::emit::emit_to_string_with(
        job,
        Dialect::LinuxCnc,
        &EmitOptions {
            locate: None,
            comments: true,
            live: false,
        },
    )
    .unwrap()
    .lines()
    .map(String::from)
    .collect()
}

fn lc_job<'a>(
    lcnc: &Headless,
    lines: &'a [String],
    name: &str,
    letters: Vec<char>,
) -> LinuxCncJob<'a> {
    LinuxCncJob {
        lines,
        placement: Placement::new(Some(lcnc.dir()), None, name),
        letters,
        post: machine("xy_table").post["linuxcnc"].clone(),
        poll: Duration::from_millis(20),
    }
}

/// `lase run` from the command line; returns its exit code and stderr+stdout.
fn lase_run(lcnc: &Headless, example: &str, journal: &std::path::Path) -> (i32, String) {
    let url = format!(
        "linuxcnc://127.0.0.1:{}?dir={}",
        lcnc.port,
        lcnc.dir().display()
    );
    let (code, out, err) = common::lase(&[
        "run",
        &format!("examples/{example}.lase"),
        "--link",
        &url,
        "--journal",
        &journal.display().to_string(),
    ]);
    (code, format!("{err}{out}"))
}

/// A transport that fails after `reads` reads: the link dropping mid-job.
struct Dropping {
    inner: TcpTransport,
    reads: usize,
}

impl Transport for Dropping {
    fn write_all(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.inner.write_all(bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> std::io::Result<usize> {
        if self.reads == 0 {
            return Err(std::io::Error::new(
                std::io::ErrorKind::ConnectionReset,
                "cable pulled",
            ));
        }
        self.reads -= 1;
        self.inner.read(buf, timeout)
    }
    fn describe(&self) -> String {
        "dropping".into()
    }
}

#[test]
fn flat_bed_runs_holds_aborts_and_survives_a_dropped_link() {
    if !available() {
        return;
    }
    let mut lcnc = Headless::start(&machine("xy_table"));
    let (job, plan_edges, plan_pulses) = planned("texture_array");

    // 1. The command line, end to end: every beam edge and pulse of the plan.
    let before = mark(&mut lcnc);
    let j = lcnc.dir().join("texture.journal");
    let (code, out) = lase_run(&lcnc, "texture_array", &j);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("done"), "{out}");
    let (edges, pulses) = beam(&lcnc.samples_since(before));
    assert_eq!((edges, pulses as u64), (plan_edges, plan_pulses), "{out}");
    assert_eq!(journal::read(&j).unwrap().end.as_deref(), Some("done"));

    // 2. Hold for half a second mid-job, then resume: the table stands still while held and
    // no pulse is lost or added.
    let lines = lines_of(&job);
    let lc = lc_job(&lcnc, &lines, "hold.ngc", vec!['X', 'Y']);
    let before = mark(&mut lcnc);
    let mut rsh = lcnc.rsh();
    lcjob::start(&mut rsh, &lc, None).unwrap();
    let t0 = Instant::now();
    let mut held_at: Option<Instant> = None;
    let report = lcjob::follow(&mut rsh, &lc, None, &mut |p| match held_at {
        None if t0.elapsed() > Duration::from_secs(2) => {
            held_at = Some(Instant::now());
            Some(Control::Hold)
        }
        Some(h) if p.held && h.elapsed() > Duration::from_millis(1500) => Some(Control::Resume),
        _ => None,
    });
    assert_eq!(report.outcome, Outcome::Done);
    let samples = lcnc.samples_since(before);
    let still = samples
        .windows(2)
        .map(|w| w[0].joints == w[1].joints && w[0].line > 0)
        .collect::<Vec<_>>();
    let longest_rest = still.split(|s| !s).map(|r| r.len()).max().unwrap_or(0);
    assert!(longest_rest >= 500, "held only {longest_rest} ms");
    let (edges, pulses) = beam(&samples);
    assert_eq!(
        (edges, pulses as u64),
        (plan_edges, plan_pulses),
        "after hold/resume"
    );

    // 3. Abort: LinuxCNC stops, and the beam's outputs are off at once.
    let lc = lc_job(&lcnc, &lines, "abort.ngc", vec!['X', 'Y']);
    let before = mark(&mut lcnc);
    lcjob::start(&mut rsh, &lc, None).unwrap();
    let t0 = Instant::now();
    let report = lcjob::follow(&mut rsh, &lc, None, &mut |_| {
        (t0.elapsed() > Duration::from_secs(2)).then_some(Control::Abort)
    });
    assert_eq!(report.outcome, Outcome::Aborted, "{report:?}");
    let samples = lcnc.samples_since(before);
    let last = samples.last().unwrap();
    assert!(
        !last.dout[0] && !last.dout[1] && last.aout == 0.0,
        "{last:?}"
    );
    let (_, pulses) = beam(&samples);
    assert!((pulses as u64) < plan_pulses, "aborted before the end");

    // 4. The link drops mid-job: LinuxCNC goes on; `resume` follows it again and the journal
    // ends `done`, with every pulse fired once.
    let lc = lc_job(&lcnc, &lines, "drop.ngc", vec!['X', 'Y']);
    let jpath = lcnc.dir().join("drop.journal");
    let _ = std::fs::remove_file(&jpath);
    let header = lcjob::header("texture_array", "linuxcnc://test", &lines, [0.0; 6]);
    let mut journal = Journal::create(&jpath, &header).unwrap();
    let before = mark(&mut lcnc);
    let tcp = TcpTransport::connect("127.0.0.1", lcnc.port).unwrap();
    // The handshake and start take about 20 reads; polls take 5 or more each.
    let mut flaky = Rsh::over(
        Box::new(Dropping {
            inner: tcp,
            reads: 200,
        }),
        "linuxcnc://flaky".into(),
    )
    .unwrap();
    flaky.set_reply_timeout(Duration::from_secs(60));
    lcjob::start(&mut flaky, &lc, None).unwrap();
    let report = lcjob::follow(&mut flaky, &lc, Some(&mut journal), &mut |_| None);
    assert!(matches!(report.outcome, Outcome::Lost(_)), "{report:?}");
    drop(journal);
    drop(flaky);
    let (mut journal, state) = Journal::append(&jpath).unwrap();
    assert!(state.end.is_none());
    let mut rsh = lcnc.rsh();
    let how = lcjob::resume(&mut rsh, &lc, &state, Some(&mut journal)).unwrap();
    assert!(matches!(how, Resumed::Reattached { .. }), "{how:?}");
    let report = lcjob::follow(&mut rsh, &lc, Some(&mut journal), &mut |_| None);
    assert_eq!(report.outcome, Outcome::Done);
    drop(journal);
    assert_eq!(journal::read(&jpath).unwrap().end.as_deref(), Some("done"));
    let (edges, pulses) = beam(&lcnc.samples_since(before));
    assert_eq!(
        (edges, pulses as u64),
        (plan_edges, plan_pulses),
        "dropped link"
    );
}

#[test]
fn the_cam_example_runs_from_the_command_line() {
    if !available() {
        return;
    }
    let mut lcnc = Headless::start(&machine("cam_xwb"));
    let (_, plan_edges, _) = planned("cam_hardening");
    let before = mark(&mut lcnc);
    let j = lcnc.dir().join("cam.journal");
    let (code, out) = lase_run(&lcnc, "cam_hardening", &j);
    assert_eq!(code, 0, "{out}");
    let samples = lcnc.samples_since(before);
    let (edges, _) = beam(&samples);
    assert_eq!(edges, plan_edges, "{out}");
    // The beam comes on while the table moves (a flying start), never at rest.
    for w in samples.windows(3) {
        if !w[0].dout[0] && w[1].dout[0] {
            assert!(w[2].joints != w[1].joints, "the beam came on at rest");
        }
    }
}
