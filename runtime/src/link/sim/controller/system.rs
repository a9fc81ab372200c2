//! The `$` system commands (`$$`, `$G`, `$#`, `$I`, `$C`, `$X`, `$H`, `$SLP`, `$J=`,
//! `$RST=`, settings), jogging, and the `?` status report, as GRBL 1.1 and grblHAL answer them.

use super::{Controller, Firmware, St};
use crate::link::sim::gcode::{self, Step};
use crate::link::{AXIS_LETTERS, MotionMode, Spindle};

impl Controller {
    pub(super) fn system(&mut self, line: &[u8]) -> Result<(), u32> {
        let cmd = std::str::from_utf8(&line[1..]).map_err(|_| 3u32)?;
        let busy = matches!(self.state, St::Cycle | St::Hold { .. } | St::Jog);
        match cmd {
            "" => {
                self.say("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]")
            }
            "$" => {
                if busy {
                    return Err(8);
                }
                let lines: Vec<String> = self
                    .settings
                    .iter()
                    .map(|(id, v)| {
                        if matches!(id, 11 | 12 | 24 | 25 | 27 | 100..=135) {
                            format!("${id}={v:.3}")
                        } else {
                            format!("${id}={}", *v as i64)
                        }
                    })
                    .collect();
                for l in lines {
                    self.say(&l);
                }
            }
            "G" => {
                let r = self.gc.report();
                self.say(&r);
            }
            "#" => {
                // report.c `report_ngc_parameters`: G54…G59, then G28, G30, G92.
                let n = self.cfg.firmware.axes();
                let zeros = vec!["0.000"; n].join(",");
                let systems: Vec<String> = (self.cfg.work_offsets.iter().enumerate())
                    .map(|(k, o)| {
                        let v: Vec<String> = o[..n].iter().map(|v| format!("{v:.3}")).collect();
                        format!("[G{}:{}]", 54 + k, v.join(","))
                    })
                    .collect();
                for l in systems {
                    self.say(&l);
                }
                for name in ["G28", "G30", "G92"] {
                    self.say(&format!("[{name}:{zeros}]"));
                }
                self.say("[TLO:0.000]");
                self.say(&format!("[PRB:{zeros}:0]"));
            }
            "I" => match self.cfg.firmware {
                Firmware::Grbl => {
                    self.say("[VER:1.1h.20190825:lase sim]");
                    // report.c prints BLOCK_BUFFER_SIZE-1: the usable blocks.
                    let opt = format!("[OPT:V,{},{}]", self.cfg.planner_blocks, self.cfg.rx_buffer);
                    self.say(&opt);
                }
                // grblHAL: its own version, the axis count in OPT, then the lines its
                // report.c adds (message types with spaces among them).
                Firmware::GrblHal { axes } => {
                    let letters: String = AXIS_LETTERS[..axes].iter().collect();
                    let lines = [
                        "[VER:1.1f.20250101:lase sim]".to_string(),
                        format!(
                            "[OPT:VNML+,{},{},{axes},0]",
                            self.cfg.planner_blocks, self.cfg.rx_buffer
                        ),
                        format!("[AXS:{axes}:{letters}]"),
                        "[NEWOPT:ENUMS,RT+,TC,SED]".into(),
                        "[FIRMWARE:grblHAL]".into(),
                        "[NVS STORAGE:*EEPROM]".into(),
                        "[DRIVER:lase sim]".into(),
                        "[DRIVER VERSION:20250101]".into(),
                    ];
                    for l in lines {
                        self.say(&l);
                    }
                }
            },
            "N" => {
                self.say("$N0=");
                self.say("$N1=");
            }
            "C" => match self.state {
                St::Check => {
                    // Leaving check mode resets the controller, after the `ok`.
                    self.say("[MSG:Disabled]");
                    self.reset_after_reply = true;
                }
                St::Idle => {
                    self.state = St::Check;
                    self.say("[MSG:Enabled]");
                }
                _ => return Err(8),
            },
            "X" => {
                if let St::Alarm { .. } = self.state {
                    self.say("[MSG:Caution: Unlocked]");
                    self.state = St::Idle;
                }
            }
            "H" => {
                if self.setting(22) != 1.0 {
                    return Err(5);
                }
                if !matches!(self.state, St::Idle | St::Alarm { .. }) {
                    return Err(8);
                }
                self.mpos = self.cfg.home();
                self.gc.pos = self.mpos;
                self.state = St::Idle;
            }
            "SLP" => {
                self.say("[MSG:Sleeping]");
                self.state = St::Sleep;
            }
            _ if cmd.starts_with("J=") => return self.jog(&line[3..]),
            _ if cmd.starts_with("RST=") => {
                self.say("[MSG:Restoring defaults]");
                self.settings = self.cfg.settings.clone();
            }
            _ => {
                let (id, value) = cmd.split_once('=').ok_or(3u32)?;
                let id: u32 = id.parse().map_err(|_| 3u32)?;
                let value: f64 = value.parse().map_err(|_| 2u32)?;
                if busy {
                    return Err(8);
                }
                if !self.settings.contains_key(&id) {
                    return Err(3);
                }
                if value < 0.0 {
                    return Err(4);
                }
                self.settings.insert(id, value);
            }
        }
        Ok(())
    }

    fn jog(&mut self, body: &[u8]) -> Result<(), u32> {
        if !matches!(self.state, St::Idle | St::Jog) {
            return Err(8);
        }
        // Only G20/G21, G90/G91, G53, axis words and F.
        let mut i = 0;
        let mut has_f = false;
        while i < body.len() {
            let c = body[i];
            i += 1;
            let start = i;
            while i < body.len() && !body[i].is_ascii_uppercase() {
                i += 1;
            }
            let v: f64 = std::str::from_utf8(&body[start..i])
                .ok()
                .and_then(|s| s.parse().ok())
                .ok_or(2u32)?;
            match (c, v) {
                (b'G', g) if [20.0, 21.0, 90.0, 91.0, 53.0].contains(&g) => {}
                (c, _) if AXIS_LETTERS[..self.cfg.firmware.axes()].contains(&(c as char)) => {}
                (b'F', _) => has_f = true,
                _ => return Err(16),
            }
        }
        if !has_f {
            return Err(22);
        }
        let mut jog_gc = self.gc.clone();
        jog_gc.modal.motion = MotionMode::Linear;
        let mut text = b"G1".to_vec();
        text.extend_from_slice(body);
        let block = gcode::execute(&text, &jog_gc, false).map_err(|_| 16u32)?;
        for step in block.steps {
            if let Step::Move(mut mv) = step {
                if self.outside_travel(mv.target) {
                    return Err(15);
                }
                mv.laser_s = 0.0;
                let chords = self.chords(self.seq, &mv, self.rest_laser);
                for b in chords {
                    self.push_block(b);
                }
                // GRBL's jog_execute enters Jog only "if there is a block to execute": a jog
                // under a step is dropped by the planner, and a Jog state with nothing to run
                // would never end. The parser's position moves either way.
                if !self.planner.is_empty() {
                    self.state = St::Jog;
                }
                self.gc.pos = mv.target;
            }
        }
        Ok(())
    }

    pub(super) fn status_report(&mut self) -> String {
        let state = match self.state {
            // Blocks queued at rest while the client streams on as fast as possible: time
            // stands still until the protocol loop blocks, and a firmware fed that fast runs
            // them (its RX buffer never runs dry, `run_while_blocked`).
            St::Idle if self.streaming && !self.planner.is_empty() => "Run".into(),
            St::Idle => "Idle".to_string(),
            St::Cycle => "Run".into(),
            St::Hold { complete } => format!("Hold:{}", if complete { 0 } else { 1 }),
            St::Alarm { .. } => "Alarm".into(),
            St::Check => "Check".into(),
            St::Jog => "Jog".into(),
            St::Sleep => "Sleep".into(),
        };
        // With the error model on, the position is the scale's reading of the table (issue
        // 15): what a controller with feedback from a linear scale reports.
        let mut p = self.position();
        if let Some(m) = &mut self.perr {
            m.follow(&p);
            p = m.reading(self.now);
        }
        let mask = self.setting(10) as u32;
        let n = self.cfg.firmware.axes();
        // WPos = MPos − WCO, the offset of the coordinate system in force.
        let wco = self.gc.offsets[self.gc.coord];
        let pos: Vec<String> = p[..n]
            .iter()
            .zip(wco)
            .map(|(v, o)| format!("{:.3}", if mask & 1 == 1 { *v } else { v - o }))
            .collect();
        let mut s = format!(
            "<{state}|{}:{}",
            if mask & 1 == 1 { "MPos" } else { "WPos" },
            pos.join(",")
        );
        if mask & 2 == 2 {
            s.push_str(&format!(
                "|Bf:{},{}",
                self.cfg.planner_blocks - self.planner.len().min(self.cfg.planner_blocks),
                self.cfg.rx_buffer.saturating_sub(1) - self.rx.len()
            ));
        }
        // GRBL reports the speed it is running at now.
        let feed = self.speed() * 60.0;
        let spindle = if self.gc.modal.spindle == Spindle::Off {
            0.0
        } else {
            self.gc.modal.s
        };
        s.push_str(&format!("|FS:{:.0},{:.0}", feed, spindle));
        if self.reports.is_multiple_of(10) {
            s.push_str("|WCO:");
            let wco: Vec<String> = wco[..n].iter().map(|v| format!("{v:.3}")).collect();
            s.push_str(&wco.join(","));
        } else if self.reports % 10 == 1 {
            let [f, r, sp] = self.overrides;
            s.push_str(&format!("|Ov:{f},{r},{sp}"));
            let mut a = String::new();
            match self.gc.modal.spindle {
                Spindle::Cw => a.push('S'),
                Spindle::Ccw => a.push('C'),
                Spindle::Off => {}
            }
            if self.gc.modal.flood {
                a.push('F');
            }
            if self.gc.modal.mist {
                a.push('M');
            }
            if !a.is_empty() {
                s.push_str(&format!("|A:{a}"));
            }
        }
        self.reports += 1;
        s.push('>');
        s
    }
}
