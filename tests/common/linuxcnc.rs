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

/// Whether to run on LinuxCNC: it is installed and `LASE_LINUXCNC_TESTS=1` asks for it; when
/// not, says why the caller skips. Opt-in for now: on a loaded two-core machine the first
/// program of a freshly started instance sometimes stays RUNNING without finishing (seen in
/// 3 of about 12 starts; cause not found yet), which would make CI flaky.
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
    let asked = std::env::var_os("LASE_LINUXCNC_TESTS").is_some_and(|v| v == "1");
    if !asked {
        eprintln!(
            "SKIPPED: the real-LinuxCNC tests run with LASE_LINUXCNC_TESTS=1 (opt-in until an intermittent hang is fixed)"
        );
    }
    asked
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
        let mut cmd = Command::new("linuxcnc");
        cmd.arg("lase.ini")
            .current_dir(&dir)
            .envs(rtapi_env(&dir, root))
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(dir.join("linuxcnc.out")).unwrap())
            .stderr(std::fs::File::create(dir.join("linuxcnc.err")).unwrap());
        {
            use std::os::unix::process::CommandExt;
            cmd.process_group(0);
        }
        let linuxcnc = cmd.spawn().expect("linuxcnc starts");
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
        let deadline = Instant::now() + Duration::from_secs(90);
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            if let Ok(Some(status)) = h.linuxcnc.try_wait() {
                panic!(
                    "LinuxCNC ended before linuxcncrsh listened ({status}):\n{}",
                    h.log()
                );
            }
            assert!(
                Instant::now() < deadline,
                "linuxcncrsh did not listen on {port} within 90 s:\n{}",
                h.log()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        let sampler = Command::new("halsampler")
            .args(["-c", "0", "-t"])
            .envs(rtapi_env(&h.dir, root))
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(&h.samples_path).unwrap())
            .stderr(std::fs::File::create(h.dir.join("halsampler.err")).unwrap())
            .spawn()
            .expect("halsampler starts");
        h.sampler = Some(sampler);
        h
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

    /// Connects a linuxcncrsh session.
    /// Its replies may take long: a non-realtime LinuxCNC shares this computer's cores with
    /// the build and the other tests.
    pub fn rsh(&self) -> Rsh {
        let mut rsh = Rsh::connect("127.0.0.1", self.port).expect("linuxcncrsh answers");
        rsh.set_reply_timeout(Duration::from_secs(60));
        rsh
    }

    /// Runs an NC program in AUTO mode to its end and returns the samples from `set run` to
    /// idle.
    pub fn run_program(&self, name: &str, nc: &str) -> Vec<Sample> {
        let path = self.dir.join(name);
        std::fs::write(&path, nc).unwrap();
        let mut rsh = self.rsh();
        rsh.start_auto().unwrap();
        rsh.errors().unwrap();
        rsh.set(&format!("open {}", path.display())).unwrap();
        let before = self.last_sample();
        rsh.set("run").unwrap();
        let t0 = Instant::now();
        let mut seen_running = false;
        loop {
            let st = rsh.status().unwrap();
            let errors = rsh.errors().unwrap();
            assert!(errors.is_empty(), "LinuxCNC: {errors:?}");
            seen_running |= st.program != ProgramStatus::Idle;
            if st.program == ProgramStatus::Idle && (seen_running || t0.elapsed().as_secs() > 2) {
                break;
            }
            assert!(t0.elapsed().as_secs() < 300, "{name} ran over 5 minutes");
            std::thread::sleep(Duration::from_millis(50));
        }
        self.samples_since(before)
    }
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
        if let Some(mut s) = self.sampler.take() {
            // The sampler is this harness's own child: stopped by its id.
            let _ = s.kill();
            let _ = s.wait();
        }
        // LinuxCNC stops itself on linuxcncrsh's `shutdown`; its start script then cleans up.
        // That cleanup stops LinuxCNC's programs *by name* (milltask, linuxcncsvr, …), so the
        // lock is held until the script has ended: a next instance started earlier would lose
        // its own milltask to it. On a loaded computer the cleanup takes minutes.
        if let Ok(rsh) = Rsh::connect("127.0.0.1", self.port) {
            let _ = rsh.shutdown();
        }
        let deadline = Instant::now() + Duration::from_secs(600);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.linuxcnc.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        eprintln!(
            "LinuxCNC did not stop within 600 s of `shutdown`:\n{}",
            self.log()
        );
    }
}
