//! GRBL 1.1's error and alarm codes with their messages (grbl's `doc/csv` tables), and its
//! real-time command bytes.

use crate::link::{OverrideStep, Realtime};

/// The message of `error:N`.
pub fn error_message(code: u32) -> &'static str {
    match code {
        1 => {
            "expected command letter: G-code words consist of a letter and a value, and the letter was not found"
        }
        2 => {
            "bad number format: missing the expected G-code word value or the numeric format is not valid"
        }
        3 => "invalid statement: the '$' system command was not recognized or supported",
        4 => "value < 0: negative value received for an expected positive value",
        5 => "setting disabled: homing is not enabled via settings",
        6 => "value < 3 usec: minimum step pulse time must be greater than 3 usec",
        7 => "EEPROM read fail: restored affected settings to default values",
        8 => "not idle: the '$' command cannot be used unless the controller is idle",
        9 => "G-code lock: G-code commands are locked out during alarm or jog state",
        10 => "homing not enabled: soft limits cannot be enabled without homing also enabled",
        11 => "line overflow: max characters per line exceeded, the line was not executed",
        12 => "step rate > 30 kHz: the '$' setting value exceeds the maximum step rate supported",
        13 => "check door: safety door detected as opened and door state initiated",
        14 => {
            "line length exceeded: build info or startup line exceeded the EEPROM line length limit"
        }
        15 => "travel exceeded: jog target exceeds machine travel, the command was ignored",
        16 => "invalid jog command: no '=' or it contains prohibited G-code",
        17 => "setting disabled: laser mode requires PWM output",
        20 => "unsupported command: unsupported or invalid G-code command found in block",
        21 => {
            "modal group violation: more than one G-code command from the same modal group in the block"
        }
        22 => "undefined feed rate: the feed rate has not yet been set or is undefined",
        23 => "the G-code command in the block requires an integer value",
        24 => "more than one G-code command that requires axis words found in the block",
        25 => "repeated G-code word found in the block",
        26 => {
            "no axis words found in the block for a G-code command or modal state that requires them"
        }
        27 => "line number value is invalid (1 to 9,999,999)",
        28 => "the G-code command is missing a required value word (P or L)",
        29 => "G59.x work coordinate systems are not supported",
        30 => "G53 is only allowed with G0 and G1 motion modes",
        31 => "axis words found in the block when no command or modal state uses them",
        32 => "G2 and G3 arcs require at least one in-plane axis word",
        33 => "the motion command target is invalid",
        34 => "the arc radius value is invalid",
        35 => "G2 and G3 arcs require at least one in-plane offset word",
        36 => "unused value words found in the block",
        37 => "G43.1 dynamic tool length offset is not assigned to the configured tool length axis",
        38 => "tool number greater than max supported value",
        _ => "unknown error code",
    }
}

/// The message of `ALARM:N`.
pub fn alarm_message(code: u32) -> &'static str {
    match code {
        1 => {
            "hard limit triggered: machine position is likely lost due to the sudden halt, re-homing is highly recommended"
        }
        2 => {
            "soft limit: a G-code motion target exceeds machine travel; machine position retained, the alarm may be safely unlocked"
        }
        3 => {
            "reset while in motion: machine position is likely lost due to the sudden halt, re-homing is highly recommended"
        }
        4 => "probe fail: the probe is not in the expected initial state before the probe cycle",
        5 => "probe fail: the probe did not contact the workpiece within the programmed travel",
        6 => "homing fail: the active homing cycle was reset",
        7 => "homing fail: the safety door was opened during the homing cycle",
        8 => "homing fail: pull-off travel failed to clear the limit switch",
        9 => "homing fail: could not find the limit switch within the search distance",
        _ => "unknown alarm code",
    }
}

/// What a GRBL controller makes of a byte when it arrives, before the line buffer: a real-time
/// command, or `None` for a byte that goes to the line buffer (or, ≥ 0x80, is dropped).
pub fn realtime_of(byte: u8) -> Option<Realtime> {
    Some(match byte {
        b'?' => Realtime::StatusQuery,
        b'!' => Realtime::FeedHold,
        b'~' => Realtime::CycleStart,
        0x18 => Realtime::SoftReset,
        0x84 => Realtime::SafetyDoor,
        0x85 => Realtime::JogCancel,
        0x90 => Realtime::Feed(OverrideStep::Reset),
        0x91 => Realtime::Feed(OverrideStep::Plus10),
        0x92 => Realtime::Feed(OverrideStep::Minus10),
        0x93 => Realtime::Feed(OverrideStep::Plus1),
        0x94 => Realtime::Feed(OverrideStep::Minus1),
        0x95 => Realtime::Rapid(100),
        0x96 => Realtime::Rapid(50),
        0x97 => Realtime::Rapid(25),
        0x99 => Realtime::Spindle(OverrideStep::Reset),
        0x9A => Realtime::Spindle(OverrideStep::Plus10),
        0x9B => Realtime::Spindle(OverrideStep::Minus10),
        0x9C => Realtime::Spindle(OverrideStep::Plus1),
        0x9D => Realtime::Spindle(OverrideStep::Minus1),
        0x9E => Realtime::SpindleStop,
        0xA0 => Realtime::FloodToggle,
        0xA1 => Realtime::MistToggle,
        _ => return None,
    })
}

/// The byte of a real-time command.
pub fn realtime_byte(cmd: Realtime) -> u8 {
    let step = |s: OverrideStep, base: u8| {
        base + match s {
            OverrideStep::Reset => 0,
            OverrideStep::Plus10 => 1,
            OverrideStep::Minus10 => 2,
            OverrideStep::Plus1 => 3,
            OverrideStep::Minus1 => 4,
        }
    };
    match cmd {
        Realtime::StatusQuery => b'?',
        Realtime::FeedHold => b'!',
        Realtime::CycleStart => b'~',
        Realtime::SoftReset => 0x18,
        Realtime::SafetyDoor => 0x84,
        Realtime::JogCancel => 0x85,
        Realtime::Feed(s) => step(s, 0x90),
        Realtime::Rapid(p) if p >= 100 => 0x95,
        Realtime::Rapid(p) if p >= 50 => 0x96,
        Realtime::Rapid(_) => 0x97,
        Realtime::Spindle(s) => step(s, 0x99),
        Realtime::SpindleStop => 0x9E,
        Realtime::FloodToggle => 0xA0,
        Realtime::MistToggle => 0xA1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn realtime_bytes_round_trip() {
        for b in 0..=255u8 {
            if let Some(cmd) = realtime_of(b) {
                assert_eq!(realtime_byte(cmd), b, "{b:#x}");
            }
        }
        assert_eq!(realtime_of(b'G'), None);
    }

    #[test]
    fn every_documented_code_has_a_message() {
        for c in (1..=17).chain(20..=38) {
            assert_ne!(error_message(c), "unknown error code", "{c}");
        }
        for c in 1..=9 {
            assert_ne!(alarm_message(c), "unknown alarm code");
        }
    }
}
