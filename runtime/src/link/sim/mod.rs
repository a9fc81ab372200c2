//! The simulated GRBL 1.1 (or, for machines with rotary axes, grblHAL) controller: a [`Controller`] (the firmware, no IO) served over a
//! byte transport — a TCP listener (`lase sim --listen`) or an in-memory pipe (the `sim`
//! link) — on its own thread, with a simulated serial line and fault injection.
//!
//! The serial line: with a baud rate, bytes reach the controller one at a time at `baud/10`
//! bytes per second in each direction, as over a UART with 8N1 framing; without, as fast as
//! the transport carries them. The controller's clock runs in real time, a multiple of it,
//! or as fast as possible (time passes only while the controller waits for its planner, and
//! what is buffered runs once the client is quiet, so a fast run is still GRBL's motion).
//!
//! Faults: drop the connection once the controller has received N lines or after T seconds
//! (bytes in transit are lost, the controller keeps executing what it received, as a real
//! controller does when a cable is pulled); answer `error:CODE` to line K; send garbage after
//! line N. A client that overruns the RX buffer is reported on stderr and in the recording.
//!
//! One client at a time, like a serial port; the machine state survives reconnections.

pub mod controller;
pub mod gcode;
pub mod motion;
pub mod poserr;

pub use controller::{
    Controller, ControllerConfig, Effect, ExecutedBlock, Firmware, LaserEvent, LineRecord,
    LineResult, MotionEffect, Recording,
};

use super::transport::{self, PipeEnd, TcpTransport, Transport};
use crate::machine::Machine;
use std::collections::VecDeque;
use std::fmt;
use std::io;
use std::net::{SocketAddr, TcpListener};
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// With `TimeScale::Max`, how long the client must have sent no line bytes before everything
/// buffered executes at once.
const MAX_QUIET: Duration = Duration::from_millis(5);

/// How simulated time relates to wall time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeScale {
    Real,
    /// This many simulated seconds per wall second.
    Factor(f64),
    /// As fast as possible, still modelled: simulated time passes while the controller waits
    /// for its planner, and everything left executes once the client is quiet.
    Max,
}

impl FromStr for TimeScale {
    type Err = String;

    fn from_str(s: &str) -> Result<TimeScale, String> {
        match s {
            "real" | "1" => Ok(TimeScale::Real),
            "max" => Ok(TimeScale::Max),
            n => n
                .parse::<f64>()
                .ok()
                .filter(|f| *f > 0.0 && f.is_finite())
                .map(TimeScale::Factor)
                .ok_or_else(|| format!("time scale `{s}`: give real, max or a factor like 100")),
        }
    }
}

impl fmt::Display for TimeScale {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TimeScale::Real => f.write_str("real"),
            TimeScale::Factor(k) => write!(f, "{k}"),
            TimeScale::Max => f.write_str("max"),
        }
    }
}

impl TimeScale {
    fn sim_dt(self, wall: Duration) -> f64 {
        match self {
            TimeScale::Real => wall.as_secs_f64(),
            TimeScale::Factor(k) => wall.as_secs_f64() * k,
            TimeScale::Max => f64::INFINITY,
        }
    }
}

/// Injected faults. Line counts are lines received since the simulator started, across
/// connections; each listed fault fires once.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Faults {
    pub drop_after_lines: Vec<u64>,
    /// Seconds after a connection opens; the n-th value applies to the n-th connection.
    pub drop_after_secs: Vec<f64>,
    pub error_at_line: Vec<(u64, u32)>,
    pub garbage_after_lines: Vec<u64>,
}

/// `K` or `K:CODE` (code 20, unsupported command, by default).
pub fn parse_error_at(s: &str) -> Result<(u64, u32), String> {
    let (k, code) = match s.split_once(':') {
        Some((k, c)) => (
            k,
            c.parse().map_err(|_| format!("bad error code in `{s}`"))?,
        ),
        None => (s, 20),
    };
    let k: u64 = k
        .parse()
        .ok()
        .filter(|k| *k > 0)
        .ok_or_else(|| format!("bad line number in `{s}`: lines count from 1"))?;
    Ok((k, code))
}

#[derive(Debug, Clone)]
pub struct SimOptions {
    pub time_scale: TimeScale,
    pub baud: Option<u32>,
    /// The RX buffer, bytes; `None`: the firmware's own ([`Firmware::rx_buffer`]).
    pub rx_buffer: Option<usize>,
    /// Usable planner blocks; `None`: the firmware's own ([`Firmware::planner_blocks`]).
    pub planner_blocks: Option<usize>,
    pub faults: Faults,
    /// Settings that differ from the machine file's (`$32=0` …).
    pub settings: Vec<(u32, f64)>,
    /// Log connections and faults to stderr.
    pub log: bool,
    /// Record only about the latest this-many lines, blocks and laser edges (`lase run`,
    /// `lase sim`: jobs of any length in bounded memory); `None` records all, for tests.
    pub keep: Option<usize>,
    /// The table's positioning error, reported through `MPos` (`--position-error`).
    pub position_error: Option<poserr::PositionErrorConfig>,
    /// The work offsets G54 … G59 the controller holds (X Y Z A B C, mm and deg).
    pub work_offsets: [crate::link::AxisPos; 6],
}

/// What `lase run` and `lase sim` keep of the recording: enough to look back over the last
/// planner's worth of lines many times over, a few MB at most.
pub const KEEP_LIVE: usize = 4096;

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            time_scale: TimeScale::Real,
            baud: None,
            rx_buffer: None,
            planner_blocks: None,
            faults: Faults::default(),
            settings: Vec::new(),
            log: false,
            keep: None,
            position_error: None,
            work_offsets: [[0.0; 6]; 6],
        }
    }
}

/// A running simulator.
#[derive(Debug)]
pub struct SimHandle {
    addr: Option<SocketAddr>,
    ctl: Arc<Mutex<Controller>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

fn lock(ctl: &Mutex<Controller>) -> MutexGuard<'_, Controller> {
    ctl.lock().unwrap_or_else(|p| p.into_inner())
}

impl SimHandle {
    /// The address it listens on (TCP).
    pub fn addr(&self) -> Option<SocketAddr> {
        self.addr
    }

    /// A copy of what it recorded so far.
    pub fn recording(&self) -> Recording {
        lock(&self.ctl).recording().clone()
    }

    /// Runs `f` on the controller.
    pub fn with<R>(&self, f: impl FnOnce(&mut Controller) -> R) -> R {
        f(&mut lock(&self.ctl))
    }

    /// Waits until the controller has nothing left to do.
    pub fn wait_quiet(&self, timeout: Duration) -> bool {
        let end = Instant::now() + timeout;
        while Instant::now() < end {
            if lock(&self.ctl).is_quiet() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        false
    }

    /// Stops the simulator and returns its recording.
    pub fn stop(mut self) -> Recording {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.recording()
    }

    /// Blocks until the simulator's thread ends (never, for a TCP server).
    pub fn join(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn controller_for(machine: &Machine, opts: &SimOptions) -> Controller {
    let mut cfg = ControllerConfig::for_machine(machine);
    cfg.settings.extend(opts.settings.iter().copied());
    cfg.position_error = opts.position_error;
    cfg.work_offsets = opts.work_offsets;
    cfg.rx_buffer = opts.rx_buffer.unwrap_or(cfg.rx_buffer).max(16);
    cfg.planner_blocks = opts.planner_blocks.unwrap_or(cfg.planner_blocks).max(1);
    cfg.error_at_line = opts.faults.error_at_line.clone();
    cfg.keep = opts.keep;
    Controller::new(cfg)
}

/// Serves the simulator on a TCP address (port 0 picks a free one).
pub fn serve(machine: &Machine, listen: SocketAddr, opts: SimOptions) -> io::Result<SimHandle> {
    let listener = TcpListener::bind(listen)?;
    listener.set_nonblocking(true)?;
    let addr = listener.local_addr()?;
    let polled = opts.baud.is_some();
    start(machine, Acceptor::Tcp(listener, polled), opts, Some(addr))
}

/// Starts the simulator in this process, connected to the returned transport.
pub fn spawn_in_process(
    machine: &Machine,
    opts: SimOptions,
) -> Result<(SimHandle, Box<dyn Transport>), String> {
    let (client, server) = transport::pipe("sim");
    let handle =
        start(machine, Acceptor::Pipe(Some(server)), opts, None).map_err(|e| e.to_string())?;
    Ok((handle, Box::new(client)))
}

fn start(
    machine: &Machine,
    acceptor: Acceptor,
    opts: SimOptions,
    addr: Option<SocketAddr>,
) -> io::Result<SimHandle> {
    let ctl = Arc::new(Mutex::new(controller_for(machine, &opts)));
    let stop = Arc::new(AtomicBool::new(false));
    let mut server = Server::new(ctl.clone(), acceptor, opts, stop.clone());
    let thread = std::thread::Builder::new()
        .name("lase-sim".into())
        .spawn(move || server.run())?;
    Ok(SimHandle {
        addr,
        ctl,
        stop,
        thread: Some(thread),
    })
}

enum Acceptor {
    /// With `true`, connections are polled for a precise serial-line clock (see
    /// [`TcpTransport::polled`]).
    Tcp(TcpListener, bool),
    Pipe(Option<PipeEnd>),
}

impl Acceptor {
    fn accept(&mut self) -> Option<Box<dyn Transport>> {
        match self {
            Acceptor::Tcp(l, polled) => match l.accept() {
                Ok((s, _)) => {
                    let t = if *polled {
                        TcpTransport::polled(s)
                    } else {
                        s.set_nonblocking(false)
                            .and_then(|_| TcpTransport::from_stream(s))
                    };
                    t.ok().map(|t| Box::new(t) as Box<dyn Transport>)
                }
                Err(_) => None,
            },
            Acceptor::Pipe(p) => p.take().map(|p| Box::new(p) as Box<dyn Transport>),
        }
    }

    fn exhausted(&self) -> bool {
        matches!(self, Acceptor::Pipe(None))
    }
}

struct Server {
    ctl: Arc<Mutex<Controller>>,
    acceptor: Acceptor,
    conn: Option<Box<dyn Transport>>,
    conn_since: Instant,
    connections: usize,
    opts: SimOptions,
    byte_time: Option<Duration>,
    wire_in: VecDeque<(Instant, u8)>,
    in_free: Instant,
    wire_out: VecDeque<(Instant, u8)>,
    out_free: Instant,
    drops: Vec<u64>,
    garbage: Vec<u64>,
    last_tick: Instant,
    /// When the last byte of a line (not a real-time command) arrived.
    last_line_byte: Instant,
    busy: bool,
    overflows_seen: u64,
    /// Line ends received from clients, for `drop_after_lines`.
    lines_in: u64,
    stop: Arc<AtomicBool>,
}

impl Server {
    fn new(
        ctl: Arc<Mutex<Controller>>,
        acceptor: Acceptor,
        opts: SimOptions,
        stop: Arc<AtomicBool>,
    ) -> Server {
        let now = Instant::now();
        let mut drops = opts.faults.drop_after_lines.clone();
        drops.sort_unstable();
        let mut garbage = opts.faults.garbage_after_lines.clone();
        garbage.sort_unstable();
        Server {
            ctl,
            acceptor,
            conn: None,
            conn_since: now,
            connections: 0,
            byte_time: opts
                .baud
                .map(|b| Duration::from_secs_f64(10.0 / f64::from(b.max(1)))),
            opts,
            wire_in: VecDeque::new(),
            in_free: now,
            wire_out: VecDeque::new(),
            out_free: now,
            drops,
            garbage,
            last_tick: now,
            last_line_byte: now,
            busy: false,
            overflows_seen: 0,
            lines_in: 0,
            stop,
        }
    }

    fn log(&self, msg: &str) {
        if self.opts.log {
            eprintln!("lase sim: {msg}");
        }
    }

    fn timeout(&self, now: Instant) -> Duration {
        let mut t = if self.busy && self.opts.time_scale != TimeScale::Max {
            Duration::from_millis(1)
        } else {
            Duration::from_millis(10)
        };
        for q in [&self.wire_in, &self.wire_out] {
            if let Some(&(due, _)) = q.front() {
                t = t.min(due.saturating_duration_since(now));
            }
        }
        t.max(Duration::from_micros(20))
    }

    fn drop_connection(&mut self, why: &str) {
        if self.conn.take().is_some() {
            self.log(&format!("connection dropped ({why})"));
        }
        self.wire_in.clear();
        self.wire_out.clear();
    }

    fn run(&mut self) {
        let mut buf = [0u8; 4096];
        while !self.stop.load(Ordering::SeqCst) {
            let now = Instant::now();
            if self.conn.is_none() {
                if let Some(t) = self.acceptor.accept() {
                    self.log(&format!("client connected ({})", t.describe()));
                    self.conn = Some(t);
                    self.conn_since = now;
                    self.connections += 1;
                    lock(&self.ctl).connected();
                } else if self.acceptor.exhausted() {
                    break;
                }
            }
            let timeout = self.timeout(now);
            match self.conn.as_mut() {
                Some(c) => match c.read(&mut buf, timeout) {
                    Ok(n) => {
                        let arrived = Instant::now();
                        for &b in &buf[..n] {
                            let due = match self.byte_time {
                                Some(bt) => {
                                    self.in_free = self.in_free.max(arrived) + bt;
                                    self.in_free
                                }
                                None => arrived,
                            };
                            self.wire_in.push_back((due, b));
                        }
                    }
                    Err(_) => {
                        self.log("client closed the connection");
                        self.drop_connection("client left");
                    }
                },
                None => std::thread::sleep(timeout.min(Duration::from_millis(5))),
            }
            let now = Instant::now();
            let mut cut = false;
            let mut ctl = lock(&self.ctl);
            let dt = now.saturating_duration_since(self.last_tick);
            self.last_tick = now;
            if self.opts.time_scale != TimeScale::Max {
                // The time that passed while the read waited runs before the bytes it brought:
                // run after them, it would run their first block alone for that long (an idle
                // controller's wait is 10 ms, a row's whole lead-in at `time-scale=10`) and
                // stop it at its end before the next line could join it (issue 15's rows).
                ctl.run(self.opts.time_scale.sim_dt(dt));
            }
            while let Some(&(due, b)) = self.wire_in.front() {
                if due > now {
                    break;
                }
                self.wire_in.pop_front();
                if crate::link::grbl::codes::realtime_of(b).is_none() {
                    self.last_line_byte = now;
                }
                ctl.receive(b);
                if b == b'\n' {
                    self.lines_in += 1;
                    if self.drops.first().is_some_and(|&n| self.lines_in >= n) {
                        self.drops.remove(0);
                        cut = true;
                        break;
                    }
                }
            }
            if self.opts.time_scale != TimeScale::Max {
                // What just arrived is read at once (lines parsed, a status answered) without
                // moving time on.
                ctl.run(0.0);
            } else {
                // Still modelled: time runs only while the controller waits for its planner,
                // until the client has been quiet a moment; then everything left executes. A
                // status query does not hurry it, so a report asked for while lines are still
                // coming says `Run`, as the firmware's would, not `Idle` after the fact.
                if now.saturating_duration_since(self.last_line_byte) >= MAX_QUIET
                    && ctl.input_drained()
                {
                    ctl.run(f64::INFINITY);
                } else {
                    ctl.run_while_blocked();
                }
            }
            let mut out = ctl.take_output();
            if self
                .garbage
                .first()
                .is_some_and(|&n| ctl.lines_completed >= n)
            {
                self.garbage.remove(0);
                out.extend_from_slice(b"\xff\xfe\x00garbage\r\n<Idle|MPos:1.0\r\n");
            }
            self.busy = !ctl.is_quiet();
            let overflows = ctl.recording().rx_overflows;
            if overflows > self.overflows_seen {
                for l in ctl
                    .recording()
                    .overflow_log
                    .iter()
                    .skip(self.overflows_seen as usize)
                {
                    eprintln!("lase sim: CLIENT BUG: {l}");
                }
                self.overflows_seen = overflows;
            }
            drop(ctl);
            if cut {
                let n = self.lines_in;
                self.drop_connection(&format!("fault: after {n} lines"));
                continue;
            }
            if let Some(&secs) = self
                .opts
                .faults
                .drop_after_secs
                .get(self.connections.wrapping_sub(1))
                && self.conn.is_some()
                && self.conn_since.elapsed().as_secs_f64() >= secs
            {
                self.drop_connection(&format!("fault: after {secs} s"));
                continue;
            }
            if self.conn.is_none() {
                continue;
            }
            match self.byte_time {
                None => {
                    if !out.is_empty()
                        && let Some(c) = self.conn.as_mut()
                        && c.write_all(&out).is_err()
                    {
                        self.drop_connection("write failed");
                    }
                }
                Some(bt) => {
                    for b in out {
                        self.out_free = self.out_free.max(now) + bt;
                        self.wire_out.push_back((self.out_free, b));
                    }
                    let mut due = Vec::new();
                    while let Some(&(t, b)) = self.wire_out.front() {
                        if t > now {
                            break;
                        }
                        self.wire_out.pop_front();
                        due.push(b);
                    }
                    if !due.is_empty()
                        && let Some(c) = self.conn.as_mut()
                        && c.write_all(&due).is_err()
                    {
                        self.drop_connection("write failed");
                    }
                }
            }
        }
    }
}
