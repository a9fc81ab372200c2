//! The simulated firmware's build and configuration: GRBL or grblHAL (axis count, line
//! buffer, banner), buffer sizes, travel, and the `$` settings a machine file implies (rates
//! and accelerations in mm or degrees, as the controller counts them).

use crate::link::{AXIS_LETTERS, AxisPos, MAX_AXES};
use crate::machine::Machine;
use std::collections::BTreeMap;

/// GRBL's version string.
pub const BANNER: &str = "Grbl 1.1h ['$' for help]";

/// grblHAL's version string.
pub const BANNER_HAL: &str = "GrblHAL 1.1f ['$' or '$HELP' for help]";

/// The firmware the simulator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firmware {
    /// GRBL 1.1: X, Y, Z.
    Grbl,
    /// grblHAL with `axes` axes (4 to 6): X Y Z A B C, the first `axes` of them.
    GrblHal { axes: usize },
}

impl Firmware {
    /// The firmware a machine file needs: GRBL when its axes are X, Y, Z, else grblHAL with as
    /// many axes as its highest letter (a machine with C has all six).
    pub fn for_machine(machine: &Machine) -> Firmware {
        match crate::link::controller_axes(machine) {
            3 => Firmware::Grbl,
            axes => Firmware::GrblHal { axes },
        }
    }

    pub fn axes(self) -> usize {
        match self {
            Firmware::Grbl => 3,
            Firmware::GrblHal { axes } => axes.clamp(3, MAX_AXES),
        }
    }

    /// The line buffer with its terminating zero (the simulator counts the characters it
    /// keeps, as GRBL does).
    pub fn line_buffer(self) -> usize {
        match self {
            Firmware::Grbl => crate::link::grbl::LINE_BUFFER,
            Firmware::GrblHal { .. } => crate::link::grbl::LINE_BUFFER_HAL,
        }
    }

    /// The serial RX buffer, bytes, as `$I` reports it: GRBL's `RX_BUFFER_SIZE` (128 on an
    /// Uno, serial.h), grblHAL's (1024, its stream.h; `[OPT:VNML+,100,1024,6,0]` from the
    /// grblHAL Simulator, CONTROLLERS.md).
    pub fn rx_buffer(self) -> usize {
        match self {
            Firmware::Grbl => 128,
            Firmware::GrblHal { .. } => 1024,
        }
    }

    /// Usable planner blocks, as `$I` reports them: GRBL's ring of `BLOCK_BUFFER_SIZE` 16
    /// holds 15 (its report prints `BLOCK_BUFFER_SIZE-1`); grblHAL allocates `$398` blocks
    /// plus one, `DEFAULT_PLANNER_BUFFER_BLOCKS` 100 (config.h), and reports the 100.
    pub fn planner_blocks(self) -> usize {
        match self {
            Firmware::Grbl => 15,
            Firmware::GrblHal { .. } => 100,
        }
    }

    /// Simulated seconds GRBL's protocol loop spends on each byte it reads while the machine
    /// stands (see [`crate::link::sim::motion`]'s restart after a stop). GRBL as grbl-sim
    /// runs it: grbl-sim's `serial_read()` (its serial.c) calls `platform_sleep(0)` before
    /// every byte, a zero `nanosleep` (platform_LINUX.c) that Linux ends no sooner than the
    /// thread's timer slack, 50 µs by default (`/proc/self/timerslack_ns` = 50000), and the
    /// simulated clock follows the wall clock (`sim_loop`, `-t 1`). Its serial line is faster
    /// than that (a byte every `2·UBRR0+1`, doubled with U2X0: 66 ticks, 4.1 µs, whenever the
    /// 128-byte ring has room), so the loop, not the line, sets the pace. grblHAL's simulator
    /// was not measured: 0, no cost.
    pub fn byte_s(self) -> f64 {
        match self {
            Firmware::Grbl => 50e-6,
            Firmware::GrblHal { .. } => 0.0,
        }
    }

    /// The motion model's limits from `$` settings on this firmware.
    pub fn limits(
        self,
        settings: &BTreeMap<u32, f64>,
        planner_blocks: usize,
    ) -> crate::link::sim::motion::Limits {
        crate::link::sim::motion::Limits {
            byte_s: self.byte_s(),
            ..crate::link::sim::motion::Limits::from_settings(settings, self.axes(), planner_blocks)
        }
    }

    pub fn banner(self) -> &'static str {
        match self {
            Firmware::Grbl => BANNER,
            Firmware::GrblHal { .. } => BANNER_HAL,
        }
    }
}

/// How the controller is built and configured.
#[derive(Debug, Clone)]
pub struct ControllerConfig {
    /// Serial RX buffer size (GRBL: 128, of which 127 usable; grblHAL 1024).
    pub rx_buffer: usize,
    /// Usable planner blocks (GRBL on an Uno: 15; grblHAL: 100).
    pub planner_blocks: usize,
    pub firmware: Firmware,
    /// Travel per axis X Y Z A B C, mm or degrees; `None` for an axis the machine lacks (it
    /// cannot move).
    pub travel: [Option<(f64, f64)>; MAX_AXES],
    pub settings: BTreeMap<u32, f64>,
    /// Answer `error:CODE` to line `K` (1-based count of lines received) instead of running it.
    pub error_at_line: Vec<(u64, u32)>,
    /// Record only about the latest this-many lines, blocks and laser edges
    /// ([`super::Recording::keep`]); `None` records everything.
    pub keep: Option<usize>,
    /// The table's positioning error model; `None`: the table is where the controller is.
    pub position_error: Option<crate::link::sim::poserr::PositionErrorConfig>,
    /// The work offsets G54 … G59 (X Y Z A B C; machine = work + offset), `$#`'s answer.
    pub work_offsets: [crate::link::AxisPos; 6],
}

impl ControllerConfig {
    /// A machine's controller: its firmware, travel and settings.
    pub fn for_machine(machine: &Machine) -> ControllerConfig {
        let firmware = Firmware::for_machine(machine);
        ControllerConfig {
            rx_buffer: firmware.rx_buffer(),
            planner_blocks: firmware.planner_blocks(),
            firmware,
            travel: travel_for(machine),
            settings: settings_for(machine),
            error_at_line: Vec::new(),
            keep: None,
            position_error: None,
            work_offsets: [[0.0; 6]; 6],
        }
    }

    /// Where the machine is after power-up or homing: the origin, clamped into the travel.
    pub fn home(&self) -> AxisPos {
        std::array::from_fn(|k| self.travel[k].map_or(0.0, |(lo, hi)| 0.0f64.clamp(lo, hi)))
    }
}

/// GRBL settings matching a machine file: rates and accelerations from each axis's limits
/// (in mm or degrees), travel, laser mode, S of full power from the post of its firmware.
pub fn settings_for(machine: &Machine) -> BTreeMap<u32, f64> {
    let mut s: BTreeMap<u32, f64> = [
        (0, 10.0),
        (1, 25.0),
        (2, 0.0),
        (3, 0.0),
        (4, 0.0),
        (5, 0.0),
        (6, 0.0),
        (10, 3.0),
        (11, machine.junction_deviation_mm),
        (12, machine.arc_tolerance_mm.max(0.001)),
        (13, 0.0),
        (20, 1.0),
        (21, 0.0),
        (22, 1.0),
        (23, 0.0),
        (24, 25.0),
        (25, 500.0),
        (26, 250.0),
        (27, 1.0),
        (30, 1000.0),
        (31, 0.0),
        (32, 1.0),
    ]
    .into_iter()
    .collect();
    let firmware = Firmware::for_machine(machine);
    if let Some((_, p)) = crate::link::live_dialect(machine).lookup(&machine.post) {
        s.insert(30, p.s_max);
    }
    for (k, letter) in AXIS_LETTERS[..firmware.axes()].iter().enumerate() {
        let k = k as u32;
        let axis = machine
            .axes
            .iter()
            .find(|a| a.name.eq_ignore_ascii_case(&letter.to_string()));
        let unit = axis.map_or(1.0, |a| crate::link::controller_scale(a.kind));
        s.insert(100 + k, 250.0);
        s.insert(110 + k, axis.map_or(500.0, |a| a.v_max * 60.0 * unit));
        s.insert(120 + k, axis.map_or(10.0, |a| a.a_max * unit));
        s.insert(130 + k, axis.map_or(0.0, |a| (a.max - a.min) * unit));
    }
    s
}

/// Travel per axis X Y Z A B C from a machine file, mm or degrees.
pub fn travel_for(machine: &Machine) -> [Option<(f64, f64)>; MAX_AXES] {
    std::array::from_fn(|k| {
        machine
            .axes
            .iter()
            .find(|a| a.name.eq_ignore_ascii_case(&AXIS_LETTERS[k].to_string()))
            .map(|a| {
                let unit = crate::link::controller_scale(a.kind);
                (a.min * unit, a.max * unit)
            })
    })
}
