//! A LinuxCNC 2.9 configuration for a lase machine: the INI (per-axis and per-joint
//! `MAX_VELOCITY`, `MAX_ACCELERATION` and travel from the machine file, trivkins with the
//! machine's axis letters, linuxcncrsh as the display) and a HAL file for a simulated machine
//! (each joint's command looped back as its feedback) that records what motion did every
//! servo period with `sampler`: the joint positions, the beam's digital outputs 0 and 1, its
//! analog output 0 and the program line. The headless test harness runs it; an integrator
//! can start from it.
//!
//! With `ConfigOptions::scales` the HAL also stands in for the linear scales an NC program
//! settles its row starts on (issue 15, `emit::writer::settle`): each of X and Y reads its
//! joint's position through a `sum2` (reading = gain · position + offset, a scale mounted
//! off by a constant and a scale whose length is off), fed to the analog input the machine
//! file's `[settle] linuxcnc` names and sampled after the columns above. HAL alone has to
//! model the error: a program cannot be paused between rows to change it from outside.

use crate::axes::to_external;
use crate::machine::{AxisKind, Machine};

/// What the generated configuration needs besides the machine.
#[derive(Debug, Clone)]
pub struct ConfigOptions {
    /// linuxcncrsh's TCP port.
    pub port: u16,
    /// Samples the HAL `sampler` FIFO holds before `halsampler` must have read them.
    pub sampler_depth: u32,
    /// `[EMCMOT]COMM_TIMEOUT`, s: how long task waits for motion to take a command. When it
    /// runs out, task aborts the program *without an error message* (its EXEC_ERROR path;
    /// only "USRMOT: ERROR: command timeout" in its print file), and linuxcncrsh reports the
    /// program idle. LinuxCNC's usual 1 s suits a realtime kernel; a POSIX non-realtime
    /// LinuxCNC on a loaded computer misses it (1 start in about 12 ended its first program
    /// early with load 15 on two cores), so the default here is generous.
    pub comm_timeout_s: f64,
    /// Scales on X and Y with an injected error, wired to the machine's settle inputs.
    pub scales: Option<ScaleError>,
}

/// How far the simulated scales' readings are off the joints' positions: for X and Y,
/// reading = `gain` · position + `offset_mm` (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleError {
    pub offset_mm: [f64; 2],
    pub gain: [f64; 2],
}

impl ScaleError {
    /// What the scales read with the joints at `x`, `y` (mm).
    pub fn reading(&self, x: f64, y: f64) -> [f64; 2] {
        [
            self.gain[0] * x + self.offset_mm[0],
            self.gain[1] * y + self.offset_mm[1],
        ]
    }
}

impl Default for ConfigOptions {
    fn default() -> Self {
        ConfigOptions {
            port: super::DEFAULT_PORT,
            sampler_depth: 16_000,
            comm_timeout_s: 60.0,
            scales: None,
        }
    }
}

/// The sampled columns, in order, after `halsampler`'s sample number: one per joint, then
/// these.
pub const SAMPLED_AFTER_JOINTS: [&str; 4] = [
    "motion.digital-out-00",
    "motion.digital-out-01",
    "motion.analog-out-00",
    "motion.program-line",
];

/// The INI and HAL texts; the INI names the HAL file `lase.hal`, the parameter file
/// `lase.var` and the tool table `lase.tbl`, all beside it.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    pub ini: String,
    pub hal: String,
    /// The sampled columns after `SAMPLED_AFTER_JOINTS`: the scales' analog inputs (X, Y)
    /// when `ConfigOptions::scales` asks for them.
    pub extra_sampled: Vec<String>,
}

/// The NC letter of each machine axis (its name's first character).
fn letters(machine: &Machine) -> Vec<char> {
    machine
        .axes
        .iter()
        .map(|a| a.name.chars().next().unwrap_or('X').to_ascii_uppercase())
        .collect()
}

/// A number as the INI takes it: plain decimals, no exponent.
fn num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// `[TRAJ] MAX_LINEAR_VELOCITY` of the generated INI: the fastest linear axis, mm/s. The
/// trajectory-planner model (`tp`) caps its moves with the same number.
pub(crate) fn max_linear_velocity(machine: &Machine) -> f64 {
    machine
        .axes
        .iter()
        .filter(|a| a.kind == AxisKind::Linear)
        .map(|a| a.v_max)
        .fold(0.0, f64::max)
}

/// How many digital outputs motion must have (`num_dio`): one past the highest `P` of any
/// `M62`–`M65` the machine's LinuxCNC lines write (beam, pulses, events, switched outputs such
/// as the xy_table's air assist on `M62 P2`), and at least the two the sampler records. A
/// program writing an output motion lacks fails in LinuxCNC's interpreter.
fn digital_outputs(machine: &Machine) -> u32 {
    let mut lines: Vec<&String> = Vec::new();
    if let Some(p) = machine.post.get("linuxcnc") {
        lines.extend(p.laser_on.iter().chain(&p.laser_off).chain(&p.power));
        lines.extend(p.pulse_on.iter().chain(&p.pulse_off).chain(&p.pso));
    }
    for e in machine.events.values() {
        lines.extend(e.codes.get("linuxcnc").into_iter().flatten());
    }
    for o in machine.outputs.values() {
        if let Some(l) = o.posts.get("linuxcnc") {
            lines.extend(l.on.iter().chain(&l.off));
        }
    }
    let index = |line: &str| -> Option<u32> {
        let up = line.to_ascii_uppercase();
        let words: Vec<&str> = up.split_whitespace().collect();
        // M62-M65: the digital outputs, synchronized or immediate.
        let digital = words.iter().any(|w| {
            w.strip_prefix('M')
                .and_then(|n| n.parse::<u32>().ok())
                .is_some_and(|n| (62..=65).contains(&n))
        });
        let p = words.iter().find_map(|w| w.strip_prefix('P')?.parse().ok());
        p.filter(|_| digital)
    };
    lines
        .iter()
        .filter_map(|l| index(l))
        .map(|p| p + 1)
        .fold(2, u32::max)
}

pub fn generate(machine: &Machine, options: &ConfigOptions) -> Config {
    let letters = letters(machine);
    let coords: String = letters.iter().collect();
    let n = machine.axes.len();
    let ext = |kind: AxisKind, v: f64| to_external(kind, v);
    let max_linear_v = max_linear_velocity(machine);
    let max_linear_a = machine
        .axes
        .iter()
        .filter(|a| a.kind == AxisKind::Linear)
        .map(|a| a.a_max)
        .fold(0.0, f64::max);
    let mut ini = format!(
        "# LinuxCNC 2.9 configuration for lase machine `{name}`, generated by lase.\n\
         [EMC]\nVERSION = 1.1\nMACHINE = lase-{name}\n\n\
         [DISPLAY]\nDISPLAY = linuxcncrsh --port {port}\n\n\
         [TASK]\nTASK = milltask\nCYCLE_TIME = 0.001\n\n\
         [RS274NGC]\nPARAMETER_FILE = lase.var\n\n\
         [EMCMOT]\nEMCMOT = motmod\nCOMM_TIMEOUT = {comm}\nSERVO_PERIOD = {servo}\n\n\
         [EMCIO]\nEMCIO = io\nCYCLE_TIME = 0.100\nTOOL_TABLE = lase.tbl\n\n\
         [HAL]\nHALFILE = lase.hal\n\n\
         [TRAJ]\nCOORDINATES = {spaced}\nLINEAR_UNITS = mm\nANGULAR_UNITS = degree\n\
         MAX_LINEAR_VELOCITY = {vmax}\nMAX_LINEAR_ACCELERATION = {amax}\nNO_FORCE_HOMING = 1\n\n\
         [KINS]\nKINEMATICS = trivkins coordinates={coords}\nJOINTS = {n}\n",
        name = machine.name,
        port = options.port,
        // The machine file's servo period (`[post.linuxcnc] servo_period`), which the writer's
        // beam-switch lead (`emit::lead`) and the tp model read too.
        servo = (machine.servo_period_s() * 1e9).round() as u64,
        comm = num(options.comm_timeout_s),
        spaced = letters
            .iter()
            .map(char::to_string)
            .collect::<Vec<_>>()
            .join(" "),
        vmax = num(max_linear_v),
        amax = num(max_linear_a),
    );
    let limits = |kind, a: &crate::machine::Axis| {
        format!(
            "MAX_VELOCITY = {}\nMAX_ACCELERATION = {}\nMIN_LIMIT = {}\nMAX_LIMIT = {}\n",
            num(ext(kind, a.v_max)),
            num(ext(kind, a.a_max)),
            num(ext(kind, a.min)),
            num(ext(kind, a.max)),
        )
    };
    for (a, l) in machine.axes.iter().zip(&letters) {
        ini += &format!("\n[AXIS_{l}]\n{}", limits(a.kind, a));
    }
    for (j, a) in machine.axes.iter().enumerate() {
        let ty = match a.kind {
            AxisKind::Linear => "LINEAR",
            AxisKind::Rotary => "ANGULAR",
        };
        // The simulated joints follow their command exactly: following error cannot occur,
        // so its limits are only wide.
        ini += &format!(
            "\n[JOINT_{j}]\nTYPE = {ty}\n{}FERROR = 1000\nMIN_FERROR = 1000\nHOME_SEQUENCE = 0\n",
            limits(a.kind, a)
        );
    }
    // The scales: (joint, analog input) of X and Y.
    let scales: Vec<(usize, u32)> = match options.scales {
        Some(_) => {
            let inputs = machine.settle.linuxcnc_inputs.unwrap_or([0, 1]);
            ["X", "Y"]
                .iter()
                .zip(inputs)
                .filter_map(|(l, e)| Some((machine.axis_index(l)?, e)))
                .collect()
        }
        None => Vec::new(),
    };
    let extra_sampled: Vec<String> = scales
        .iter()
        .map(|(_, e)| format!("motion.analog-in-{e:02}"))
        .collect();
    // Analog output 0 is the power; the inputs share the count.
    let num_aio = scales.iter().map(|(_, e)| e + 1).fold(1, u32::max);
    let mut hal = format!(
        "# HAL for lase machine `{name}`: simulated joints, sampled every servo period.\n\
         loadrt [KINS]KINEMATICS\n\
         loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS num_dio={num_dio} num_aio={num_aio}\n\
         loadrt sampler depth={depth} cfg={cfg}\n\
         addf motion-command-handler servo-thread\n\
         addf motion-controller servo-thread\n",
        name = machine.name,
        num_dio = digital_outputs(machine),
        depth = options.sampler_depth,
        cfg = "f".repeat(n) + "bbfs" + "f".repeat(scales.len()).as_str(),
    );
    for j in 0..n {
        hal += &format!(
            "net j{j} joint.{j}.motor-pos-cmd => joint.{j}.motor-pos-fb sampler.0.pin.{j}\n"
        );
    }
    if let (Some(err), false) = (options.scales, scales.is_empty()) {
        hal += &format!("loadrt sum2 count={}\n", scales.len());
        for (k, &(j, e)) in scales.iter().enumerate() {
            // The joint's net carries its position; the scale reads it through sum2.
            hal += &format!(
                "addf sum2.{k} servo-thread\n\
                 setp sum2.{k}.gain0 {}\nsetp sum2.{k}.offset {}\n\
                 net j{j} => sum2.{k}.in0\n\
                 net scale{k} sum2.{k}.out => motion.analog-in-{e:02} sampler.0.pin.{}\n",
                num(err.gain[k]),
                num(err.offset_mm[k]),
                n + SAMPLED_AFTER_JOINTS.len() + k,
            );
        }
    }
    for (k, pin) in SAMPLED_AFTER_JOINTS.iter().enumerate() {
        hal += &format!("net s{k} {pin} => sampler.0.pin.{}\n", n + k);
    }
    hal += "addf sampler.0 servo-thread\n\
            net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in\n";
    Config {
        ini,
        hal,
        extra_sampled,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cam_machine_gets_its_letters_limits_and_units() {
        let m = crate::machine::parse_machine(lase_stdlib::machine("cam_xwb").unwrap(), 0).unwrap();
        let c = generate(&m, &ConfigOptions::default());
        assert!(
            c.ini.contains("KINEMATICS = trivkins coordinates=XCB"),
            "{}",
            c.ini
        );
        assert!(c.ini.contains("COORDINATES = X C B"));
        // X: 50 mm/s, 0.5 m/s²; C: 180 deg/s, 1800 deg/s² (the machine file's units back).
        assert!(c.ini.contains("[AXIS_X]\nMAX_VELOCITY = 50\nMAX_ACCELERATION = 500\nMIN_LIMIT = 0\nMAX_LIMIT = 300\n"), "{}", c.ini);
        assert!(c.ini.contains("[AXIS_C]\nMAX_VELOCITY = 180\nMAX_ACCELERATION = 1800\nMIN_LIMIT = -36000\nMAX_LIMIT = 36000\n"), "{}", c.ini);
        assert!(c.ini.contains("[JOINT_2]\nTYPE = ANGULAR\n"));
        assert!(c.hal.contains("cfg=fffbbfs"));
        assert!(c.ini.contains("COMM_TIMEOUT = 60\n"), "{}", c.ini);
        assert!(
            c.hal
                .contains("net s3 motion.program-line => sampler.0.pin.6")
        );
    }

    #[test]
    fn the_arm_gets_trivkins_over_its_joints_in_degrees() {
        // The arm's program is in joint space (X slide, A B C joints): trivkins maps each
        // letter to its joint, the rotary joints in degrees.
        let m = crate::machine::parse_machine(lase_stdlib::machine("arm_3r").unwrap(), 0).unwrap();
        let c = generate(&m, &ConfigOptions::default());
        assert!(
            c.ini
                .contains("KINEMATICS = trivkins coordinates=XABC\nJOINTS = 4\n")
        );
        assert!(c.ini.contains("COORDINATES = X A B C\n"));
        assert!(c.ini.contains("[AXIS_B]\nMAX_VELOCITY = 90\nMAX_ACCELERATION = 900\nMIN_LIMIT = -175\nMAX_LIMIT = 175\n"), "{}", c.ini);
        for j in 1..=3 {
            assert!(c.ini.contains(&format!("[JOINT_{j}]\nTYPE = ANGULAR\n")));
        }
        assert!(c.ini.contains("[JOINT_0]\nTYPE = LINEAR\n"));
        assert!(c.hal.contains("num_dio=2 num_aio=1\n"), "{}", c.hal);
    }

    #[test]
    fn scales_read_x_and_y_through_sum2_on_the_settle_inputs() {
        let m =
            crate::machine::parse_machine(lase_stdlib::machine("xy_table").unwrap(), 0).unwrap();
        let c = generate(
            &m,
            &ConfigOptions {
                scales: Some(ScaleError {
                    offset_mm: [0.0037, -0.0042],
                    gain: [1.0015, 0.999],
                }),
                ..ConfigOptions::default()
            },
        );
        // Two inputs beside the power output; the sampler records them after the program line.
        // Three digital outputs: beam, pulses and the air assist's `M62 P2`.
        assert!(c.hal.contains("num_dio=3 num_aio=2\n"), "{}", c.hal);
        assert!(c.hal.contains("cfg=ffbbfsff"), "{}", c.hal);
        assert!(
            c.hal.contains(
                "setp sum2.0.gain0 1.0015\nsetp sum2.0.offset 0.0037\nnet j0 => sum2.0.in0\n"
            ),
            "{}",
            c.hal
        );
        assert!(
            c.hal
                .contains("net scale1 sum2.1.out => motion.analog-in-01 sampler.0.pin.7\n"),
            "{}",
            c.hal
        );
        assert_eq!(
            c.extra_sampled,
            ["motion.analog-in-00", "motion.analog-in-01"]
        );
        let r = ScaleError {
            offset_mm: [0.0037, -0.0042],
            gain: [1.0015, 0.999],
        }
        .reading(2.0, 1.0);
        assert!(
            (r[0] - 2.0067).abs() < 1e-12 && (r[1] - 0.9948).abs() < 1e-12,
            "{r:?}"
        );
        // Without scales nothing changes.
        let plain = generate(&m, &ConfigOptions::default());
        assert!(plain.hal.contains("num_aio=1\n") && !plain.hal.contains("sum2"));
        assert!(plain.extra_sampled.is_empty());
    }
}
