//! `lase sim`: the simulated GRBL/grblHAL controller served on a TCP port, for `lase run`
//! and the REPL to stream to.

use super::{CmdResult, io_fail};
use crate::driver::Failure;
use crate::output::outln;
use lase_lang::SourceMap;
use lase_runtime::link::sim::{self, Faults, SimOptions, TimeScale};
use std::net::SocketAddr;

/// `lase sim` options.
#[derive(Debug, Clone, clap::Args)]
pub struct SimArgs {
    /// Address to listen on (loopback unless --allow-remote); port 0 picks a free one.
    #[arg(long, default_value = "127.0.0.1:0")]
    pub listen: String,
    /// Stock machine name or machine file path.
    #[arg(long, default_value = "xy_table")]
    pub machine: String,
    /// Simulated time: real, max or a speed-up factor (e.g. 100).
    #[arg(long, default_value = "real")]
    pub time_scale: String,
    /// Drop the connection once N lines have been received (repeatable).
    #[arg(long, value_name = "N")]
    pub drop_after_lines: Vec<u64>,
    /// Drop the n-th connection T seconds after it opens (repeatable).
    #[arg(long, value_name = "T")]
    pub drop_after_secs: Vec<f64>,
    /// Answer error:CODE (default 20) to line K instead of running it (repeatable).
    #[arg(long, value_name = "K[:CODE]")]
    pub error_at_line: Vec<String>,
    /// Send garbage once N lines have been answered (repeatable).
    #[arg(long, value_name = "N", hide = true)]
    pub garbage_after_lines: Vec<u64>,
    /// Throttle the link to this baud rate (8N1: baud/10 bytes per second each way).
    #[arg(long)]
    pub baud: Option<u32>,
    /// Serial RX buffer, bytes (default: the firmware's, GRBL 128, grblHAL 1024).
    #[arg(long)]
    pub rx_buffer: Option<usize>,
    /// Usable planner blocks (default: the firmware's, GRBL 15, grblHAL 100).
    #[arg(long)]
    pub planner_blocks: Option<usize>,
    /// A GRBL setting different from the machine file's, N=VALUE (e.g. 32=0; repeatable).
    #[arg(long = "setting", value_name = "N=VALUE")]
    pub settings: Vec<String>,
    /// Allow listening on a non-loopback address.
    #[arg(long)]
    pub allow_remote: bool,
    /// The table's positioning error, reported through MPos as a 1 µm scale reads it:
    /// backlash=3um,random=5um,drift=0.1um/s,scale=1um,seed=7 (any subset).
    #[arg(long, value_name = "SPEC")]
    pub position_error: Option<String>,
}

/// Loads a stock machine by name or a machine file by path.
fn load_machine(name: &str) -> Result<lase_runtime::machine::Machine, (SourceMap, Failure)> {
    let (file, text) = match lase_stdlib::machine(name) {
        Some(t) => (format!("<stdlib>/{name}.toml"), t.to_string()),
        None => match std::fs::read_to_string(name) {
            Ok(t) => (name.to_string(), t),
            Err(e) => {
                let stock: Vec<&str> = lase_stdlib::machine_names().collect();
                return Err(io_fail(format!(
                    "machine `{name}` is neither a stock machine ({}) nor a readable file: {e}",
                    stock.join(", ")
                )));
            }
        },
    };
    let mut map = SourceMap::new();
    let id = map.add(file, text);
    lase_runtime::machine::parse_machine(map.text(id), map.base(id))
        .map_err(|e| (map.clone(), Failure::one(e)))
}

pub fn cmd_sim(args: SimArgs) -> CmdResult {
    let machine = load_machine(&args.machine)?;
    let addr: SocketAddr = args.listen.parse().map_err(|_| {
        io_fail(format!(
            "--listen `{}`: give an address and port, e.g. 127.0.0.1:5000",
            args.listen
        ))
    })?;
    if !addr.ip().is_loopback() && !args.allow_remote {
        return Err(io_fail(format!(
            "--listen {addr} is not a loopback address: the simulator listens on 127.0.0.1 or ::1 unless --allow-remote is given"
        )));
    }
    let time_scale: TimeScale = args.time_scale.parse().map_err(io_fail)?;
    let mut error_at_line = Vec::new();
    for e in &args.error_at_line {
        error_at_line.push(sim::parse_error_at(e).map_err(io_fail)?);
    }
    let mut settings = Vec::new();
    for s in &args.settings {
        let parsed = s
            .trim_start_matches('$')
            .split_once('=')
            .and_then(|(k, v)| Some((k.parse::<u32>().ok()?, v.parse::<f64>().ok()?)));
        settings.push(
            parsed.ok_or_else(|| io_fail(format!("--setting `{s}`: give N=VALUE, e.g. 32=0")))?,
        );
    }
    let opts = SimOptions {
        time_scale,
        baud: args.baud,
        rx_buffer: args.rx_buffer,
        planner_blocks: args.planner_blocks,
        faults: Faults {
            drop_after_lines: args.drop_after_lines.clone(),
            drop_after_secs: args.drop_after_secs.clone(),
            error_at_line,
            garbage_after_lines: args.garbage_after_lines.clone(),
        },
        settings,
        log: true,
        keep: Some(sim::KEEP_LIVE),
        work_offsets: Default::default(),
        position_error: args
            .position_error
            .as_deref()
            .map(str::parse)
            .transpose()
            .map_err(io_fail)?,
    };
    let handle = sim::serve(&machine, addr, opts)
        .map_err(|e| io_fail(format!("cannot listen on {addr}: {e}")))?;
    let bound = handle.addr().unwrap_or(addr);
    let built = sim::Firmware::for_machine(&machine);
    let firmware = match built {
        sim::Firmware::Grbl => "GRBL 1.1".to_string(),
        sim::Firmware::GrblHal { axes } => format!("grblHAL ({axes} axes)"),
    };
    outln!(
        "lase sim: {firmware} simulator for `{}` listening on {bound} (time scale {time_scale}{}, RX buffer {} bytes, {} planner blocks)",
        machine.name,
        args.baud.map(|b| format!(", {b} baud")).unwrap_or_default(),
        args.rx_buffer.unwrap_or(built.rx_buffer()),
        args.planner_blocks.unwrap_or(built.planner_blocks())
    );
    outln!("lase sim: stream to it with `lase run FILE --link tcp://{bound}`");
    use std::io::Write;
    let _ = std::io::stdout().flush();
    handle.join();
    Ok(())
}
