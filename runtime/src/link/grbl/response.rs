//! GRBL 1.1's and grblHAL's messages, one line at a time: `ok`, `error:N`, `ALARM:N`, the
//! welcome banner, `<…>` status reports, `[…]` feedback (`[MSG:…]`, `[GC:…]`, …), `$N=value`
//! settings and `>line:ok` startup lines. Any byte sequence either parses or gives a reason;
//! nothing here panics (a property test feeds it arbitrary bytes).
//!
//! grblHAL says more than GRBL (its core's `report.c`): feedback types with spaces
//! (`[NVS STORAGE:…]`, `[DRIVER VERSION:…]`, `[MAX STEP RATE:…]`, `[AUX IO:…]`), plugin lines
//! (`[PLUGIN:…]`), states with sub-states (`Run:1` feed hold pending, `Run:2` probing,
//! `Alarm:N`, `Tool` for a manual tool change), status fields GRBL lacks (`FS:` with a third
//! value, `WCS:`, `Sc:`, `MPG:`, `H:`, `D:`, `T:`, `TLR:`, `In:`, `FW:`, `AR` without a
//! value, `SP1:` …, and whatever a plugin appends). Every bracketed line parses, so a message
//! lase has not met is shown and ignored rather than ending a job; [`documented_feedback`]
//! tells the link which ones deserve a warning.

use crate::link::{BufferState, MachineState, ModalState, MotionMode, Plane, Spindle, Status};

/// One line from the controller.
#[derive(Debug, Clone, PartialEq)]
pub enum Response {
    Ok,
    Error(u32),
    Alarm(u32),
    Status(Status),
    /// `Grbl 1.1h ['$' for help]` (or grblHAL's `GrblHAL 1.1f ['$' or '$HELP' for help]`):
    /// the controller (re)started.
    Banner {
        version: String,
        text: String,
    },
    /// `[MSG:…]`
    Message(String),
    /// `[GC:…]`, the answer to `$G`.
    ParserState(String),
    /// Any other bracketed feedback: `[HLP:…]`, `[VER:…]`, `[OPT:…]`, `[G54:…]`, `[echo:…]`,
    /// grblHAL's `[NVS STORAGE:…]`, …; `kind` is the text before the first `:` (the whole
    /// text, and an empty `body`, when there is none).
    Feedback {
        kind: String,
        body: String,
    },
    /// `$N=value`, part of the answer to `$$`.
    Setting {
        id: u32,
        value: f64,
    },
    /// `$Nx=line`, a stored startup line.
    StartupLineSetting {
        index: u32,
        line: String,
    },
    /// `>G54G20:ok`: a startup line ran (not an answer to a sent line).
    StartupLine {
        line: String,
        error: Option<u32>,
    },
    Empty,
}

/// Why a line is not a GRBL message.
#[derive(Debug, Clone, PartialEq)]
pub struct Malformed {
    pub text: String,
    pub reason: String,
}

/// Longest line a GRBL controller sends (settings, `[OPT:…]`, status with every field are
/// far shorter); anything longer is noise.
pub const MAX_RESPONSE: usize = 256;

/// Shows a line for people: printable ASCII as is, anything else escaped, bounded.
pub fn printable(bytes: &[u8]) -> String {
    let mut s = String::new();
    for &b in bytes.iter().take(80) {
        match b {
            b' '..=b'~' => s.push(b as char),
            _ => s.push_str(&format!("\\x{b:02x}")),
        }
    }
    if bytes.len() > 80 {
        s.push('…');
    }
    s
}

/// Parses one line (without its line end).
pub fn parse(line: &[u8]) -> Result<Response, Malformed> {
    let bad = |reason: &str| Malformed {
        text: printable(line),
        reason: reason.to_string(),
    };
    if line.len() > MAX_RESPONSE {
        return Err(bad("line too long for a controller message"));
    }
    let Ok(text) = std::str::from_utf8(line) else {
        return Err(bad("not text"));
    };
    if text.bytes().any(|b| !(b' '..=b'~').contains(&b)) {
        return Err(bad("control or non-ASCII bytes"));
    }
    let text = text.trim_end();
    if text.is_empty() {
        return Ok(Response::Empty);
    }
    if text == "ok" {
        return Ok(Response::Ok);
    }
    if let Some(n) = text.strip_prefix("error:") {
        return code(n)
            .map(Response::Error)
            .ok_or_else(|| bad("bad error code"));
    }
    if let Some(n) = text.strip_prefix("ALARM:") {
        return code(n)
            .map(Response::Alarm)
            .ok_or_else(|| bad("bad alarm code"));
    }
    if text.starts_with('<') {
        return parse_status(text)
            .map(Response::Status)
            .map_err(|r| bad(&r));
    }
    if let Some(rest) = text
        .strip_prefix("Grbl ")
        .or_else(|| text.strip_prefix("GrblHAL "))
    {
        let version = rest.split_whitespace().next().unwrap_or("").to_string();
        if version.is_empty() || !version.as_bytes()[0].is_ascii_digit() {
            return Err(bad("banner without a version"));
        }
        return Ok(Response::Banner {
            version,
            text: text.to_string(),
        });
    }
    if let Some(inner) = text.strip_prefix('[') {
        let inner = inner
            .strip_suffix(']')
            .ok_or_else(|| bad("feedback message without its closing `]`"))?;
        // GRBL's types are letters and digits; grblHAL's may hold spaces (`NVS STORAGE`), and a
        // plugin may print anything. The line is printable ASCII already (checked above).
        let (kind, body) = inner.split_once(':').unwrap_or((inner, ""));
        return Ok(match kind {
            "MSG" => Response::Message(body.to_string()),
            "GC" => Response::ParserState(body.to_string()),
            _ => Response::Feedback {
                kind: kind.to_string(),
                body: body.to_string(),
            },
        });
    }
    if let Some(rest) = text.strip_prefix('$') {
        let (key, value) = rest
            .split_once('=')
            .ok_or_else(|| bad("setting without `=`"))?;
        if let Some(idx) = key.strip_prefix('N') {
            let index = idx.parse().map_err(|_| bad("bad startup line index"))?;
            return Ok(Response::StartupLineSetting {
                index,
                line: value.to_string(),
            });
        }
        let id = key.parse().map_err(|_| bad("bad setting number"))?;
        let value = number(value).ok_or_else(|| bad("bad setting value"))?;
        return Ok(Response::Setting { id, value });
    }
    if let Some(rest) = text.strip_prefix('>') {
        let (line, result) = rest
            .rsplit_once(":ok")
            .map(|(l, _)| (l, None))
            .or_else(|| {
                rest.rsplit_once(":error:")
                    .map(|(l, c)| (l, Some(code(c).unwrap_or(0))))
            })
            .ok_or_else(|| bad("startup line without its result"))?;
        return Ok(Response::StartupLine {
            line: line.to_string(),
            error: result,
        });
    }
    Err(bad("not a GRBL 1.1 message"))
}

/// Whether a bracketed message type is one GRBL 1.1 or grblHAL documents (answers to `$I`,
/// `$#`, `$G`, `$N`, `$$` in machine-readable form, probing, echo). Any other one still parses;
/// the link shows it as an unknown message and goes on.
pub fn documented_feedback(kind: &str) -> bool {
    const KINDS: &[&str] = &[
        "MSG",
        "GC",
        "HLP",
        "VER",
        "OPT",
        "echo",
        "PRB",
        "HOME",
        "TLO",
        "TLR",
        "T",
        "PARAM",
        "AXS",
        "NEWOPT",
        "FIRMWARE",
        "NVS STORAGE",
        "DRIVER",
        "DRIVER VERSION",
        "DRIVER OPTIONS",
        "BOARD",
        "MAX STEP RATE",
        "COMPATIBILITY LEVEL",
        "AUX IO",
        "PLUGIN",
        "SIGNALS",
        "SETTING",
        "SETTINGGROUP",
        "SETTINGDESCR",
        "ALARMCODE",
        "ERRORCODE",
        "SPINDLE",
        "SD",
        "FILE",
        "FS",
        "IP",
        "WIFI",
        "NETCON",
        "MODE",
        "AP",
        "STA",
        "ETHERNET",
        "MAC",
        "HOSTNAME",
        "KEYPAD",
    ];
    // `$#` reports coordinate systems and offsets by their G number: G54…G59.3, G28, G30,
    // G92, and G51 (scaling) on grblHAL.
    let coordinates = kind.strip_prefix('G').is_some_and(|n| {
        !n.is_empty() && n.len() <= 4 && n.bytes().all(|b| b.is_ascii_digit() || b == b'.')
    });
    KINDS.contains(&kind) || coordinates
}

/// A `$#` coordinate line's values, `12.000,-3.500,0.000` (what follows `[G55:`).
pub fn parse_offset(body: &str) -> Result<Vec<f64>, String> {
    let v: Option<Vec<f64>> = body.split(',').map(number).collect();
    match v {
        Some(v) if !v.is_empty() && v.len() <= 6 => Ok(v),
        _ => Err("expected 1 to 6 comma-separated numbers".into()),
    }
}

fn code(s: &str) -> Option<u32> {
    if s.is_empty() || s.len() > 4 || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// A finite decimal number as GRBL prints it (`12.345`, `-0.5`, `0.`).
fn number(s: &str) -> Option<f64> {
    let ok = !s.is_empty()
        && s.len() <= 24
        && s.bytes()
            .all(|b| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'+');
    if !ok {
        return None;
    }
    let s = s.strip_suffix('.').unwrap_or(s);
    s.parse::<f64>().ok().filter(|v| v.is_finite())
}

fn numbers(s: &str, min: usize, max: usize) -> Result<Vec<f64>, String> {
    let v: Option<Vec<f64>> = s.split(',').map(number).collect();
    match v {
        Some(v) if v.len() >= min && v.len() <= max => Ok(v),
        Some(v) => Err(format!("{} values where {min} to {max} belong", v.len())),
        None => Err(format!("bad number in `{s}`")),
    }
}

fn integers(s: &str, n: usize) -> Result<Vec<u32>, String> {
    let v: Option<Vec<u32>> = s.split(',').map(code_u32).collect();
    match v {
        Some(v) if v.len() == n => Ok(v),
        _ => Err(format!("expected {n} integers in `{s}`")),
    }
}

fn code_u32(s: &str) -> Option<u32> {
    if s.is_empty() || s.len() > 9 || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// Parses `<Idle|MPos:0.000,0.000,0.000|FS:0,0|…>`.
pub fn parse_status(text: &str) -> Result<Status, String> {
    let inner = text
        .strip_prefix('<')
        .and_then(|t| t.strip_suffix('>'))
        .ok_or("status report without its closing `>` (truncated?)")?;
    let mut fields = inner.split('|');
    let state_field = fields.next().unwrap_or("");
    let (name, sub) = match state_field.split_once(':') {
        Some((n, s)) => (
            n,
            Some(s.parse::<u8>().map_err(|_| "bad machine sub-state")?),
        ),
        None => (state_field, None),
    };
    let state = match (name, sub) {
        ("Idle", None) => MachineState::Idle,
        // grblHAL: `Run:1` a feed hold is pending, `Run:2` probing; both are still moving.
        ("Run", _) => MachineState::Run,
        ("Hold", s) => MachineState::Hold {
            complete: s.unwrap_or(0) == 0,
        },
        ("Jog", None) => MachineState::Jog,
        // grblHAL may add the alarm's code as a sub-state.
        ("Alarm", _) => MachineState::Alarm,
        ("Door", s) => MachineState::Door(s.unwrap_or(0)),
        ("Check", None) => MachineState::Check,
        ("Home", None) => MachineState::Home,
        ("Sleep", None) => MachineState::Sleep,
        // grblHAL waits at a manual tool change (`M6`) for a cycle start: a completed hold,
        // as far as streaming is concerned.
        ("Tool", None) => MachineState::Hold { complete: true },
        _ => return Err(format!("unknown machine state `{state_field}`")),
    };
    let mut st = Status {
        state,
        ..Status::default()
    };
    for f in fields {
        // grblHAL's auto-report flag is a bare `AR` when the interval is off.
        let (key, value) = f.split_once(':').unwrap_or((f, ""));
        let field_err = |e: String| format!("{key}: {e}");
        match key {
            "MPos" => st.mpos = Some(numbers(value, 3, 6).map_err(field_err)?),
            "WPos" => st.wpos = Some(numbers(value, 3, 6).map_err(field_err)?),
            "WCO" => st.wco = Some(numbers(value, 3, 6).map_err(field_err)?),
            "Bf" => {
                let v = integers(value, 2).map_err(field_err)?;
                st.buffer = Some(BufferState {
                    planner_free: v[0],
                    rx_free: v[1],
                });
            }
            "Ln" => st.line = Some(code_u32(value).ok_or("Ln: bad line number")?),
            "F" => st.feed = Some(numbers(value, 1, 1).map_err(field_err)?[0]),
            "FS" => {
                // grblHAL adds the spindle's measured speed as a third value.
                let v = numbers(value, 2, 3).map_err(field_err)?;
                st.feed = Some(v[0]);
                st.spindle = Some(v[1]);
            }
            "Ov" => {
                let v = integers(value, 3).map_err(field_err)?;
                st.overrides = Some([v[0], v[1], v[2]]);
            }
            "Pn" => {
                if value.is_empty() || !value.bytes().all(|b| b.is_ascii_uppercase()) {
                    return Err("Pn: bad pin letters".into());
                }
                st.pins = Some(value.to_string());
            }
            "A" => {
                // S/C spindle, F/M coolant; grblHAL adds E (encoder error) and T (tool change).
                if !value.bytes().all(|b| b"SCFMET".contains(&b)) {
                    return Err("A: bad accessory letters".into());
                }
                st.accessories = Some(value.to_string());
            }
            // GRBL says any field may appear; one lase does not know is kept out of the way.
            _ if !key.is_empty() && key.bytes().all(|b| b.is_ascii_alphanumeric()) => {}
            _ => return Err(format!("bad status field `{f}`")),
        }
    }
    if st.mpos.is_none() && st.wpos.is_none() {
        return Err("status report without a position".into());
    }
    Ok(st)
}

/// Parses the body of `[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`.
pub fn parse_parser_state(body: &str) -> Result<ModalState, String> {
    let mut m = ModalState::default();
    for w in body.split_whitespace() {
        let mut chars = w.chars();
        let letter = chars.next().map(String::from).unwrap_or_default();
        let letter = letter.as_str();
        // grblHAL reports active scaling as `G51:XY` (the scaled axes after the colon).
        let value = chars.as_str().split(':').next().unwrap_or("");
        let v = number(value).ok_or_else(|| format!("bad word `{w}`"))?;
        match (letter, (v * 10.0).round() as i64) {
            ("G", 0) => m.motion = MotionMode::Rapid,
            ("G", 10) => m.motion = MotionMode::Linear,
            ("G", 20) => m.motion = MotionMode::ArcCw,
            ("G", 30) => m.motion = MotionMode::ArcCcw,
            ("G", 800) => m.motion = MotionMode::None,
            ("G", 170) => m.plane = Plane::Xy,
            ("G", 180) => m.plane = Plane::Zx,
            ("G", 190) => m.plane = Plane::Yz,
            ("G", 200) => m.inches = true,
            ("G", 210) => m.inches = false,
            ("G", 900) => m.incremental = false,
            ("G", 910) => m.incremental = true,
            ("G", 930) => m.inverse_time = true,
            ("G", 940) => m.inverse_time = false,
            ("G", _) => {}
            ("M", 30) => m.spindle = Spindle::Cw,
            ("M", 40) => m.spindle = Spindle::Ccw,
            ("M", 50) => m.spindle = Spindle::Off,
            ("M", 70) => m.mist = true,
            ("M", 80) => m.flood = true,
            ("M", 90) => {
                m.flood = false;
                m.mist = false;
            }
            ("M", _) | ("T", _) => {}
            ("F", _) => m.feed = v,
            ("S", _) => m.s = v,
            _ => return Err(format!("unknown word `{w}`")),
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_coordinate_line_of_the_parameters_report_parses() {
        // report.c `report_ngc_parameters`: `[G55:100.000,50.000,0.000]`.
        let r = parse(b"[G55:100.000,-50.500,0.000]");
        let Ok(Response::Feedback { kind, body }) = r else {
            panic!("{r:?}");
        };
        assert_eq!(kind, "G55");
        assert_eq!(parse_offset(&body), Ok(vec![100.0, -50.5, 0.0]));
        assert!(parse_offset("1,x").is_err());
        assert!(parse_offset("").is_err());
        assert!(parse_offset("1,2,3,4,5,6,7").is_err());
    }

    #[test]
    fn parses_every_message_kind() {
        assert_eq!(parse(b"ok"), Ok(Response::Ok));
        assert_eq!(parse(b"error:22"), Ok(Response::Error(22)));
        assert_eq!(parse(b"ALARM:2"), Ok(Response::Alarm(2)));
        assert_eq!(
            parse(b"[MSG:Reset to continue]"),
            Ok(Response::Message("Reset to continue".into()))
        );
        assert!(matches!(
            parse(b"Grbl 1.1h ['$' for help]"),
            Ok(Response::Banner { version, .. }) if version == "1.1h"
        ));
        assert!(matches!(
            parse(b"GrblHAL 1.1f ['$' or '$HELP' for help]"),
            Ok(Response::Banner { version, .. }) if version == "1.1f"
        ));
        let Ok(Response::Status(st)) =
            parse(b"<Idle|MPos:1.000,0.000,0.000,0.000,-12.500,720.125|FS:0,0>")
        else {
            panic!("a six-axis status report parses");
        };
        assert_eq!(st.mpos, Some(vec![1.0, 0.0, 0.0, 0.0, -12.5, 720.125]));
        // grblHAL's extra fields and an alarm with its code.
        let Ok(Response::Status(st)) =
            parse(b"<Alarm:11|MPos:0.000,0.000,0.000,0.000|Bf:35,1023|FS:0,0|H:0|MPG:0>")
        else {
            panic!("a grblHAL alarm report parses");
        };
        assert_eq!(st.state, MachineState::Alarm);
        assert_eq!(
            parse(b"$110=15000.000"),
            Ok(Response::Setting {
                id: 110,
                value: 15000.0
            })
        );
        assert!(matches!(
            parse(b">G54G20:ok"),
            Ok(Response::StartupLine { error: None, .. })
        ));
        assert!(matches!(
            parse(b"[VER:1.1h.20190825:]"),
            Ok(Response::Feedback { kind, .. }) if kind == "VER"
        ));
    }

    #[test]
    fn status_reports_parse_fully() {
        let Ok(Response::Status(s)) = parse(
            b"<Hold:1|MPos:1.000,-2.500,0.000|Bf:15,128|Ln:99|FS:1200,400|WCO:0.000,1.000,0.000|Ov:100,50,120|Pn:XP|A:SF>",
        ) else {
            panic!("status did not parse");
        };
        assert_eq!(s.state, MachineState::Hold { complete: false });
        assert_eq!(s.mpos, Some(vec![1.0, -2.5, 0.0]));
        assert_eq!(
            s.buffer,
            Some(BufferState {
                planner_free: 15,
                rx_free: 128
            })
        );
        assert_eq!(s.line, Some(99));
        assert_eq!((s.feed, s.spindle), (Some(1200.0), Some(400.0)));
        assert_eq!(s.overrides, Some([100, 50, 120]));
        assert_eq!(s.pins.as_deref(), Some("XP"));
        assert_eq!(s.accessories.as_deref(), Some("SF"));
        assert_eq!(s.work_position(None), Some(vec![1.0, -3.5, 0.0]));
    }

    /// What a real grblHAL (its core's `report.c`, the Simulator driver) says to `$I`, with
    /// the plugin lines a board may add: every line parses, and the RX buffer and axis count
    /// are where the link reads them.
    #[test]
    fn grblhal_build_info_parses_line_by_line() {
        let reply = [
            "[VER:1.1f.20240901:]",
            "[OPT:VNMSL+,35,1024,6,0]",
            "[AXS:6:XYZABC]",
            "[NEWOPT:ENUMS,RT+,HOME,TC,SED]",
            "[FIRMWARE:grblHAL]",
            "[SIGNALS:HSE]",
            "[NVS STORAGE:*EEPROM]",
            "[DRIVER:Simulator]",
            "[DRIVER VERSION:260324]",
            "[DRIVER OPTIONS:SIM]",
            "[BOARD:Linux host]",
            "[MAX STEP RATE:50000 Hz]",
            "[COMPATIBILITY LEVEL:0]",
            "[AUX IO:2,2,0,0]",
            "[PLUGIN:Laser PPI v0.07]",
            "[SOMETHING NEW FROM A PLUGIN]",
            "ok",
        ];
        let mut kinds = Vec::new();
        for line in reply {
            match parse(line.as_bytes()) {
                Ok(Response::Feedback { kind, body }) => kinds.push((kind, body)),
                Ok(Response::Ok) => {}
                other => panic!("{line}: {other:?}"),
            }
        }
        let get = |k: &str| {
            kinds
                .iter()
                .find(|(kind, _)| kind == k)
                .map(|(_, b)| b.as_str())
        };
        assert_eq!(get("OPT").unwrap().split(',').nth(2), Some("1024"));
        assert_eq!(get("AXS"), Some("6:XYZABC"));
        assert_eq!(get("NVS STORAGE"), Some("*EEPROM"));
        assert_eq!(get("DRIVER VERSION"), Some("260324"));
        assert_eq!(get("MAX STEP RATE"), Some("50000 Hz"));
        assert_eq!(get("SOMETHING NEW FROM A PLUGIN"), Some(""));
        let undocumented: Vec<&str> = kinds
            .iter()
            .map(|(k, _)| k.as_str())
            .filter(|k| !documented_feedback(k))
            .collect();
        assert_eq!(undocumented, ["SOMETHING NEW FROM A PLUGIN"]);
        assert!(
            matches!(parse(b"[echo: G1X10]"), Ok(Response::Feedback { kind, .. }) if kind == "echo")
        );
    }

    /// grblHAL's status reports with every field its `report_realtime_status` can print.
    #[test]
    fn grblhal_status_reports_parse() {
        let Ok(Response::Status(s)) = parse(
            b"<Run:1|MPos:10.000,2.000,0.000,0.000,90.000,-45.500|Bf:34,1023|Ln:12|FS:1200,0,0|SP1:0,,,100|Pn:POXT|WCO:0.000,0.000,0.000,0.000,0.000,0.000|WCS:G54|Ov:100,100,100|A:ST|Sc:|MPG:0|H:1,7|D:0|T:0|TLR:0|In:-1|FW:grblHAL|AR>",
        ) else {
            panic!("a full grblHAL status report parses");
        };
        assert_eq!(s.state, MachineState::Run);
        assert_eq!(s.mpos.as_ref().unwrap()[4], 90.0);
        assert_eq!(s.feed, Some(1200.0));
        assert_eq!(s.buffer.unwrap().rx_free, 1023);
        assert_eq!(s.accessories.as_deref(), Some("ST"));
        assert_eq!(s.line, Some(12));
        for (line, state) in [
            (&b"<Run:2|MPos:0,0,0>"[..], MachineState::Run),
            (
                b"<Tool|MPos:0,0,0|A:T>",
                MachineState::Hold { complete: true },
            ),
            (b"<Alarm:11|MPos:0,0,0|AR:50>", MachineState::Alarm),
            (
                b"<Hold:0|WPos:0,0,0|FS:0,0>",
                MachineState::Hold { complete: true },
            ),
        ] {
            let Ok(Response::Status(s)) = parse(line) else {
                panic!("{}", printable(line));
            };
            assert_eq!(s.state, state);
        }
        let m =
            parse_parser_state("G1 G54 G17 G21 G90 G94 G49 G98 G51:XY M5 M9 T0 F600 S0").unwrap();
        assert_eq!((m.motion, m.feed), (MotionMode::Linear, 600.0));
    }

    #[test]
    fn malformed_output_is_an_error_with_a_reason() {
        for bad in [
            &b"<Idle|MPos:1.0,2"[..],
            b"<Idle|MPos:1.0,2.0,x>",
            b"<Dancing|MPos:0,0,0>",
            b"<Idle|FS:0,0>",
            b"okay",
            b"error:",
            b"error:abc",
            b"\xff\xfe garbage",
            b"ALARM:99999",
            b"[MSG:unterminated",
            b"hello",
        ] {
            let e = parse(bad).expect_err(&printable(bad));
            assert!(!e.reason.is_empty());
        }
    }

    #[test]
    fn parser_state_reads_modal_words() {
        let m = parse_parser_state("G1 G54 G17 G21 G91 G93 M3 M8 T0 F1200. S400.").unwrap();
        assert_eq!(m.motion, MotionMode::Linear);
        assert!(m.incremental && m.inverse_time && m.flood && !m.inches);
        assert_eq!((m.spindle, m.feed, m.s), (Spindle::Cw, 1200.0, 400.0));
        assert!(parse_parser_state("G1 Q%").is_err());
    }

    proptest! {
        #[test]
        fn any_bytes_parse_or_fail_without_panicking(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = parse(&bytes);
        }

        #[test]
        fn status_like_noise_never_panics(s in "<[A-Za-z:|0-9.,\\-]{0,80}>?") {
            let _ = parse(s.as_bytes());
            let _ = parse_parser_state(&s);
        }

        #[test]
        fn printed_status_reports_parse_back(
            x in -1000.0f64..1000.0, y in -1000.0f64..1000.0, z in -100.0f64..100.0,
            free in 0u32..16, rx in 0u32..128, feed in 0u32..20000,
        ) {
            let line = format!("<Run|MPos:{x:.3},{y:.3},{z:.3}|Bf:{free},{rx}|FS:{feed},0>");
            let Ok(Response::Status(s)) = parse(line.as_bytes()) else { panic!("{line}") };
            let p = s.mpos.unwrap();
            prop_assert!((p[0] - x).abs() < 0.001 && (p[1] - y).abs() < 0.001 && (p[2] - z).abs() < 0.001);
            prop_assert_eq!(s.buffer, Some(BufferState { planner_free: free, rx_free: rx }));
        }
    }
}
