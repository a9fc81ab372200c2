//! A real LinuxCNC 2.9 (Debian's `linuxcnc-uspace`), started headless for one machine: the
//! configuration from `link::linuxcnc::config` (trivkins, simulated joints, linuxcncrsh as the
//! display), POSIX non-realtime, `halsampler` recording the joints, the beam's outputs and
//! the program line every 1 ms servo period. Programs run in AUTO mode over linuxcncrsh, as
//! `lase run --link linuxcnc://…` drives it; the samples of each run come back for the tests
//! to measure. One instance at a time on a computer (LinuxCNC allows one): instances
//! serialise through a lock file, and each stops with linuxcncrsh's `shutdown`.
//!
//! As root (CI), LinuxCNC's `rtapi_app` needs `RTAPI_UID`, an unprivileged uid it runs as,
//! and `RTAPI_FIFO_PATH`, the path of its master socket in a folder that uid can write.

use lase_runtime::link::linuxcnc::config::{self, ConfigOptions, ScaleError};
use lase_runtime::link::linuxcnc::{ProgramStatus, Rsh};
use lase_runtime::machine::Machine;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Whether to run on LinuxCNC: it is installed (CI installs it), unless
/// `LASE_LINUXCNC_TESTS=0` opts out; when not, says why the caller skips.
///
/// Only one LinuxCNC may run on a computer at a time, whoever started it: LinuxCNC's own
/// `linuxcnc` script, when an instance shuts down, kills every `milltask`, `linuxcncsvr` and
/// `linuxcncrsh` it finds by name (`pidof`, its `Cleanup`) and stops the realtime side. A
/// second instance then loses its task, rtapi_app and halsampler at once with nothing in its
/// own logs — what these tests saw while several instances ran on one machine (the harness's
/// lock serialises its own instances only). The first-program failures were task's
/// motion-command timeout, fixed (`ConfigOptions::comm_timeout_s`).
pub fn available() -> bool {
    let found = ["linuxcnc", "halsampler", "linuxcncrsh"]
        .iter()
        .all(|p| Path::new("/usr/bin").join(p).exists());
    if !found {
        eprintln!(
            "SKIPPED: LinuxCNC is not installed (apt-get install linuxcnc-uspace; .ci/run does)"
        );
        return false;
    }
    let off = std::env::var_os("LASE_LINUXCNC_TESTS").is_some_and(|v| v == "0");
    if off {
        eprintln!("SKIPPED: LASE_LINUXCNC_TESTS=0 turns the real-LinuxCNC tests off");
    }
    !off
}

/// The machine-wide lock: a file created exclusively, holding the owner's pid (a lock whose
/// owner died is taken over).
struct Lock(PathBuf);

impl Lock {
    fn take() -> Lock {
        let path = std::env::temp_dir().join("lase-linuxcnc-harness.lock");
        let deadline = Instant::now() + Duration::from_secs(900);
        loop {
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
            {
                Ok(mut f) => {
                    use std::io::Write;
                    let _ = write!(f, "{}", std::process::id());
                    return Lock(path);
                }
                Err(_) => {
                    let owner = std::fs::read_to_string(&path).unwrap_or_default();
                    let alive = owner
                        .trim()
                        .parse::<u32>()
                        .is_ok_and(|pid| Path::new(&format!("/proc/{pid}")).exists());
                    if !alive && !owner.is_empty() {
                        let _ = std::fs::remove_file(&path);
                        continue;
                    }
                    assert!(
                        Instant::now() < deadline,
                        "the LinuxCNC harness lock stayed taken"
                    );
                    std::thread::sleep(Duration::from_millis(200));
                }
            }
        }
    }
}

impl Drop for Lock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// One servo period's record.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Joint positions (mm, degrees), machine axis order.
    pub joints: Vec<f64>,
    /// `motion.digital-out-00` (beam gate) and `-01` (pulse output).
    pub dout: [bool; 2],
    /// `motion.analog-out-00` (power, %).
    pub aout: f64,
    /// `motion.program-line`.
    pub line: i32,
    /// The scales' readings (`motion.analog-in-NN` of X, Y) when started `with_scales`;
    /// empty otherwise.
    pub ain: Vec<f64>,
}

/// A headless LinuxCNC for one machine.
pub struct Headless {
    dir: PathBuf,
    pub port: u16,
    n_joints: usize,
    /// Sampled columns after the joints and `SAMPLED_AFTER_JOINTS`.
    n_extra: usize,
    linuxcnc: Child,
    sampler: Option<Child>,
    samples_path: PathBuf,
    _lock: Lock,
}

/// A port nothing listens on now.
fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .map(|l| l.split_whitespace().nth(1) == Some("0"))
        })
        .unwrap_or(false)
}

/// The unprivileged uid `rtapi_app` runs as under root: `nobody`.
const RTAPI_UID: u32 = 65534;

impl Headless {
    /// Starts LinuxCNC for `machine` and waits until linuxcncrsh answers.
    pub fn start(machine: &Machine) -> Headless {
        Headless::with_scales(machine, None)
    }

    /// As `start`, with X and Y scales reading the joints with the error `scales` on the
    /// machine's settle inputs (`config::ScaleError`), sampled into `Sample::ain`.
    pub fn with_scales(machine: &Machine, scales: Option<ScaleError>) -> Headless {
        let lock = Lock::take();
        let port = free_port();
        let dir = std::env::temp_dir().join(format!(
            "lase-linuxcnc-{}-{}",
            machine.name,
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("rtapi")).unwrap();
        let cfg = config::generate(
            machine,
            &ConfigOptions {
                port,
                scales,
                ..ConfigOptions::default()
            },
        );
        let cfg_extra = cfg.extra_sampled.len();
        std::fs::write(dir.join("lase.ini"), cfg.ini).unwrap();
        std::fs::write(dir.join("lase.hal"), cfg.hal).unwrap();
        std::fs::write(dir.join("lase.tbl"), "").unwrap();
        std::fs::write(dir.join("lase.var"), "").unwrap();
        let root = is_root();
        {
            use std::os::unix::fs::PermissionsExt;
            // The folder holds programs the controller's user reads and a parameter file it
            // writes; its socket folder belongs to the uid rtapi_app runs as.
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o777)).unwrap();
            if root {
                std::os::unix::fs::chown(dir.join("rtapi"), Some(RTAPI_UID), None).unwrap();
            }
        }
        let linuxcnc = spawn_linuxcnc(&dir, root);
        let mut h = Headless {
            samples_path: dir.join("samples.txt"),
            dir,
            port,
            n_joints: machine.axes.len(),
            n_extra: cfg_extra,
            linuxcnc,
            sampler: None,
            _lock: lock,
        };
        h.await_and_sample();
        h
    }

    /// Waits until linuxcncrsh answers, then starts recording with halsampler.
    fn await_and_sample(&mut self) {
        let port = self.port;
        let deadline = Instant::now() + Duration::from_secs(90);
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            if let Ok(Some(status)) = self.linuxcnc.try_wait() {
                panic!(
                    "LinuxCNC ended before linuxcncrsh listened ({status}):\n{}",
                    self.log()
                );
            }
            assert!(
                Instant::now() < deadline,
                "linuxcncrsh did not listen on {port} within 90 s:\n{}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        let sampler = Command::new("halsampler")
            .args(["-c", "0", "-t"])
            .envs(rtapi_env(&self.dir, is_root()))
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&self.samples_path).unwrap())
            .stderr(std::fs::File::create(self.dir.join("halsampler.err")).unwrap())
            .spawn()
            .expect("halsampler starts");
        self.sampler = Some(sampler);
    }

    /// The pid of this instance's process named `name` (its command line names this
    /// instance's INI file).
    fn pid_of(&self, name: &str) -> Option<u32> {
        let ini = self.dir.join("lase.ini").display().to_string();
        std::fs::read_dir("/proc").ok()?.flatten().find_map(|e| {
            let pid: u32 = e.file_name().to_str()?.parse().ok()?;
            let cmd = std::fs::read(e.path().join("cmdline")).ok()?;
            let cmd = String::from_utf8_lossy(&cmd);
            let mut words = cmd.split('\0');
            let exe = words.next()?;
            (exe.rsplit('/').next() == Some(name) && words.any(|w| w == ini)).then_some(pid)
        })
    }

    /// Whether this instance's task (milltask) still runs. On a computer shared with other
    /// builds it has been seen to vanish, together with rtapi_app and halsampler and with no
    /// message in LinuxCNC's logs (cause not found); the status linuxcncrsh serves then stays
    /// frozen (a program RUNNING forever: the hang once blamed on the first program) and
    /// every `set` goes unanswered.
    pub fn task_alive(&self) -> bool {
        self.pid_of("milltask").is_some()
    }

    /// Stops this LinuxCNC (linuxcncrsh's `shutdown`; without a task, which `shutdown`
    /// needs, by ending this instance's linuxcncrsh, which makes the start script clean up)
    /// and waits until its start script has ended.
    fn stop(&mut self) {
        if let Some(mut s) = self.sampler.take() {
            // The sampler is this harness's own child: stopped by its id.
            let _ = s.kill();
            let _ = s.wait();
        }
        // LinuxCNC stops itself on linuxcncrsh's `shutdown`; its start script then cleans up.
        // That cleanup stops LinuxCNC's programs *by name* (milltask, linuxcncsvr, …), so the
        // lock is held until the script has ended: a next instance started earlier would lose
        // its own milltask to it. On a loaded computer the cleanup takes minutes.
        let asked = self.task_alive()
            && Rsh::connect("127.0.0.1", self.port)
                .and_then(|rsh| rsh.shutdown())
                .is_ok();
        if !asked && let Some(pid) = self.pid_of("linuxcncrsh") {
            let _ = Command::new("kill").arg(pid.to_string()).status();
        }
        let deadline = Instant::now() + Duration::from_secs(600);
        while Instant::now() < deadline {
            // The script's end is not enough: seen on a restart, this instance's milltask and
            // rtapi_app outlived it, and the next instance's start cleaned them up by name,
            // taking its own milltask with them.
            let gone = ["milltask", "linuxcncsvr", "io"]
                .iter()
                .all(|n| self.pid_of(n).is_none())
                && !process_named("rtapi_app");
            if matches!(self.linuxcnc.try_wait(), Ok(Some(_))) && gone {
                return;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        eprintln!(
            "LinuxCNC did not stop within 600 s of `shutdown`:\n{}",
            self.log()
        );
    }

    /// Stops this LinuxCNC and starts it again with the same configuration (its samples
    /// start again from 0).
    pub fn restart(&mut self) {
        self.stop();
        self.linuxcnc = spawn_linuxcnc(&self.dir, is_root());
        self.await_and_sample();
    }

    /// The folder of the configuration, programs and logs.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn log(&self) -> String {
        let read = |n: &str| std::fs::read_to_string(self.dir.join(n)).unwrap_or_default();
        format!("{}{}", read("linuxcnc.out"), read("linuxcnc.err"))
    }

    /// The newest sample number halsampler has written.
    pub fn last_sample(&self) -> u64 {
        let text = std::fs::read_to_string(&self.samples_path).unwrap_or_default();
        text.lines()
            .rev()
            .filter(|l| l.split_whitespace().count() == 1 + self.n_joints + 4 + self.n_extra)
            .find_map(|l| l.split_whitespace().next()?.parse().ok())
            .unwrap_or(0)
    }

    /// Samples after sample number `after`, once halsampler has written 300 more than the
    /// newest one now.
    pub fn samples_since(&self, after: u64) -> Vec<Sample> {
        // halsampler's output is block-buffered: wait until later samples push these out.
        let target = self.last_sample() + 300;
        let deadline = Instant::now() + Duration::from_secs(10);
        while self.last_sample() < target && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(50));
        }
        let f = std::fs::File::open(&self.samples_path).unwrap();
        let mut out = Vec::new();
        for line in BufReader::new(f).lines() {
            let Ok(line) = line else { break };
            let w: Vec<&str> = line.split_whitespace().collect();
            if w.len() != 1 + self.n_joints + 4 + self.n_extra {
                continue; // a torn last line
            }
            let Ok(n) = w[0].parse::<u64>() else { continue };
            if n <= after {
                continue;
            }
            let f = |s: &str| s.parse::<f64>().unwrap_or(f64::NAN);
            let j = self.n_joints;
            out.push(Sample {
                joints: w[1..=j].iter().map(|s| f(s)).collect(),
                dout: [w[j + 1] == "1", w[j + 2] == "1"],
                aout: f(w[j + 3]),
                line: w[j + 4].parse().unwrap_or(-1),
                ain: w[j + 5..].iter().map(|s| f(s)).collect(),
            });
        }
        out
    }

    /// What LinuxCNC says about itself when a run goes wrong: linuxcncrsh's view, motion's
    /// pins, and the start script's print file (where task and motion write what they do not
    /// send to the error channel, such as "USRMOT: ERROR: command timeout").
    pub fn diagnose(&self, rsh: &mut Rsh) -> String {
        let mut out = String::new();
        for key in [
            "program_status",
            "program_line",
            "mode",
            "machine",
            "estop",
            "abs_act_pos",
        ] {
            out += &format!("get {key}: {:?}\n", rsh.get(key));
        }
        let halcmd = Command::new("halcmd")
            .args(["show", "pin", "motion."])
            .envs(rtapi_env(&self.dir, is_root()))
            .output();
        if let Ok(o) = halcmd {
            out += &String::from_utf8_lossy(&o.stdout);
        }
        let prints = std::fs::read_dir(std::env::temp_dir())
            .into_iter()
            .flatten()
            .flatten()
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with("linuxcnc.print.")
            });
        for e in prints {
            out += &std::fs::read_to_string(e.path()).unwrap_or_default();
        }
        out
    }

    /// Connects a linuxcncrsh session.
    /// Its replies may take long: a non-realtime LinuxCNC shares this computer's cores with
    /// the build and the other tests.
    pub fn rsh(&self) -> Rsh {
        let mut rsh = Rsh::connect("127.0.0.1", self.port).expect("linuxcncrsh answers");
        rsh.set_reply_timeout(Duration::from_secs(60));
        rsh
    }

    /// Runs an NC program in AUTO mode to its end and returns the samples from `set run` to
    /// idle. When LinuxCNC's task vanished (see [`Headless::task_alive`]) before the program
    /// was seen to end, LinuxCNC is restarted and the program run again, twice at most.
    pub fn run_program(&mut self, name: &str, nc: &str) -> Vec<Sample> {
        for attempt in 1..=3 {
            match self.try_program(name, nc) {
                Some(samples) => return samples,
                None => {
                    eprintln!(
                        "LinuxCNC's task (milltask) vanished while running {name} (attempt {attempt}); restarting LinuxCNC"
                    );
                    self.restart();
                }
            }
        }
        panic!("LinuxCNC's task vanished three times running {name}");
    }

    /// One run of a program; `None` when the task vanished before it was seen idle again.
    fn try_program(&self, name: &str, nc: &str) -> Option<Vec<Sample>> {
        let path = self.dir.join(name);
        std::fs::write(&path, nc).unwrap();
        if !self.task_alive() {
            return None;
        }
        // A task that vanishes between two commands leaves linuxcncrsh without answers (seen:
        // `set mode auto` unanswered for 60 s right after a restart): a vanished task too, for
        // the caller to restart, not a failed run.
        macro_rules! or_vanished {
            ($e:expr) => {
                match $e {
                    Ok(v) => v,
                    Err(_) if !self.task_alive() => return None,
                    Err(e) => panic!("linuxcncrsh: {e:?}"),
                }
            };
        }
        let mut rsh = self.rsh();
        or_vanished!(rsh.start_auto());
        or_vanished!(rsh.errors());
        // `lase run`'s check that the task still takes commands (`Rsh::probe_task`), on the
        // real linuxcncrsh: ACKed and changing nothing.
        or_vanished!(rsh.probe_task());
        or_vanished!(rsh.set(&format!("open {}", path.display())));
        let before = self.last_sample();
        or_vanished!(rsh.set("run"));
        let t0 = Instant::now();
        let mut seen_running = false;
        loop {
            let st = or_vanished!(rsh.status());
            let errors = or_vanished!(rsh.errors());
            assert!(errors.is_empty(), "LinuxCNC: {errors:?}");
            seen_running |= st.program != ProgramStatus::Idle;
            if st.program == ProgramStatus::Idle && (seen_running || t0.elapsed().as_secs() > 2) {
                break;
            }
            // A vanished task leaves its last status (RUNNING) behind for linuxcncrsh.
            if !self.task_alive() {
                return None;
            }
            // material_test, the longest example, runs 165 s.
            if t0.elapsed().as_secs() >= 600 {
                panic!("{name} ran over 10 minutes:\n{}", self.diagnose(&mut rsh));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        Some(self.samples_since(before))
    }
}

/// Whether a process named `name` runs (rtapi_app's command line names no INI file; one
/// LinuxCNC at a time runs here, by the lock).
fn process_named(name: &str) -> bool {
    std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .any(|e| std::fs::read_to_string(e.path().join("comm")).is_ok_and(|c| c.trim() == name))
}

/// `linuxcnc lase.ini` in `dir`, in its own process group.
fn spawn_linuxcnc(dir: &Path, root: bool) -> Child {
    let mut cmd = Command::new("linuxcnc");
    cmd.arg("lase.ini")
        .current_dir(dir)
        .envs(rtapi_env(dir, root))
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(dir.join("linuxcnc.out")).unwrap())
        .stderr(std::fs::File::create(dir.join("linuxcnc.err")).unwrap());
    {
        use std::os::unix::process::CommandExt;
        cmd.process_group(0);
    }
    cmd.spawn().expect("linuxcnc starts")
}

fn rtapi_env(dir: &Path, root: bool) -> Vec<(String, String)> {
    let mut env = vec![(
        "RTAPI_FIFO_PATH".to_string(),
        dir.join("rtapi").join("fifo").display().to_string(),
    )];
    if root {
        env.push(("RTAPI_UID".into(), RTAPI_UID.to_string()));
    }
    env
}

impl Drop for Headless {
    fn drop(&mut self) {
        self.stop();
    }
}
