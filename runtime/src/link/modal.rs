//! Predicts a controller's modal state and position line by line, from the NC text a job
//! sends (RS274 words as GRBL reads them). The resume logic compares these predictions with
//! what the controller reports to find the last line it executed, and the re-approach
//! restores the predicted state.

use super::{AxisPos, MAX_AXES, ModalState, MotionMode, Plane, Spindle, axis_index};

/// What a line does, as far as resuming cares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineKind {
    /// Comments, empty lines, lines that repeat the modal state.
    Nothing,
    /// Changes modal state only (units, feed, laser power, …).
    Modal,
    /// Moves; `lit` when the laser fires during the move.
    Motion { lit: bool },
    /// Waits (G4) or pauses (M0/M1).
    Dwell,
}

/// The words of a line (letter upper-cased, value), comments and spaces dropped.
pub fn words(line: &str) -> Result<Vec<(char, f64)>, String> {
    let mut out = Vec::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            c if c.is_whitespace() => {}
            '(' => {
                for c in chars.by_ref() {
                    if c == ')' {
                        break;
                    }
                }
            }
            ';' => break,
            '%' | '/' => {}
            c if c.is_ascii_alphabetic() => {
                let mut num = String::new();
                while let Some(&d) = chars.peek() {
                    if d.is_ascii_digit() || d == '.' || d == '-' || d == '+' {
                        num.push(d);
                        chars.next();
                    } else if d == ' ' {
                        chars.next();
                    } else {
                        break;
                    }
                }
                let v: f64 = num
                    .parse()
                    .ok()
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| format!("bad number after `{c}`: `{num}`"))?;
                out.push((c.to_ascii_uppercase(), v));
            }
            other => return Err(format!("unexpected character `{other}`")),
        }
    }
    Ok(out)
}

/// The interpreter state of a controller and its position (work coordinates: X Y Z in mm,
/// A B C in degrees).
#[derive(Debug, Clone, PartialEq)]
pub struct Tracker {
    pub state: ModalState,
    pub pos: AxisPos,
}

impl Tracker {
    pub fn new(pos: AxisPos) -> Tracker {
        Tracker {
            state: ModalState::default(),
            pos,
        }
    }

    /// Whether the laser fires during a move in the current state (GRBL laser mode: M3/M4
    /// with S > 0, in G1/G2/G3).
    pub fn lit(&self) -> bool {
        self.state.spindle != Spindle::Off
            && self.state.s > 0.0
            && matches!(
                self.state.motion,
                MotionMode::Linear | MotionMode::ArcCw | MotionMode::ArcCcw
            )
    }

    /// Applies one line.
    pub fn apply(&mut self, line: &str) -> Result<LineKind, String> {
        let ws = words(line)?;
        let before = self.clone();
        let mut dwell = false;
        let mut target: [Option<f64>; MAX_AXES] = [None; MAX_AXES];
        let mut machine_coords = false;
        let scale = |inches: bool| if inches { 25.4 } else { 1.0 };
        // Modal words first, in GRBL's order of execution, then the motion.
        for &(c, v) in &ws {
            let code = (v * 10.0).round() as i64;
            match (c, code) {
                ('G', 0) => self.state.motion = MotionMode::Rapid,
                ('G', 10) => self.state.motion = MotionMode::Linear,
                ('G', 20) => self.state.motion = MotionMode::ArcCw,
                ('G', 30) => self.state.motion = MotionMode::ArcCcw,
                ('G', 800) => self.state.motion = MotionMode::None,
                ('G', 40) => dwell = true,
                ('G', 170) => self.state.plane = Plane::Xy,
                ('G', 180) => self.state.plane = Plane::Zx,
                ('G', 190) => self.state.plane = Plane::Yz,
                ('G', 200) => self.state.inches = true,
                ('G', 210) => self.state.inches = false,
                ('G', 530) => machine_coords = true,
                ('G', 900) => self.state.incremental = false,
                ('G', 910) => self.state.incremental = true,
                ('G', 930) => self.state.inverse_time = true,
                ('G', 940) => self.state.inverse_time = false,
                ('M', 0) | ('M', 10) => dwell = true,
                ('M', 30) => self.state.spindle = Spindle::Cw,
                ('M', 40) => self.state.spindle = Spindle::Ccw,
                ('M', 50) => self.state.spindle = Spindle::Off,
                ('M', 70) => self.state.mist = true,
                ('M', 80) => self.state.flood = true,
                ('M', 90) => {
                    self.state.flood = false;
                    self.state.mist = false;
                }
                ('S', _) => self.state.s = v,
                (c @ ('X' | 'Y' | 'Z' | 'A' | 'B' | 'C'), _) => {
                    if let Some(i) = axis_index(c) {
                        target[i] = Some(v);
                    }
                }
                _ => {}
            }
        }
        // Units apply to the whole block, whatever the order of its words.
        let k = scale(self.state.inches);
        // GRBL's feed: the block's F; without one, the last feed only in G94 after G94 (in
        // G93 every feed move carries its own, and leaving G93 leaves the feed undefined).
        if let Some(&(_, f)) = ws.iter().find(|(c, _)| *c == 'F') {
            self.state.feed = if self.state.inverse_time { f } else { f * k };
        } else if self.state.inverse_time || before.state.inverse_time {
            self.state.feed = 0.0;
        }
        let has_axes = target.iter().any(Option::is_some);
        let mut kind = LineKind::Nothing;
        if has_axes && !dwell {
            for (i, t) in target.iter().enumerate() {
                if let Some(v) = t {
                    // Inches scale the linear axes; rotary axes stay in degrees.
                    let v = if i < 3 { v * k } else { *v };
                    self.pos[i] = if self.state.incremental && !machine_coords {
                        self.pos[i] + v
                    } else {
                        v
                    };
                }
            }
            kind = LineKind::Motion { lit: self.lit() };
        }
        // Program end (M2/M30), after the block's motion: GRBL's reset of modal state.
        if ws.iter().any(|&(c, v)| c == 'M' && (v == 2.0 || v == 30.0)) {
            self.state.motion = MotionMode::Linear;
            self.state.plane = Plane::Xy;
            self.state.incremental = false;
            self.state.inverse_time = false;
            self.state.spindle = Spindle::Off;
            self.state.flood = false;
            self.state.mist = false;
        }
        if dwell {
            return Ok(LineKind::Dwell);
        }
        if kind == LineKind::Nothing && self.state != before.state {
            kind = LineKind::Modal;
        }
        Ok(kind)
    }
}

/// The predicted state after each prefix of `lines`: element `c` is the state once the first
/// `c` lines have run (element 0 is `start`), with the kind of line `c - 1`.
pub fn predict(start: &Tracker, lines: &[String]) -> Vec<(Tracker, LineKind)> {
    let mut out = Vec::with_capacity(lines.len() + 1);
    let mut t = start.clone();
    out.push((t.clone(), LineKind::Nothing));
    for l in lines {
        // A line the controller would refuse changes nothing.
        let kind = t.apply(l).unwrap_or(LineKind::Nothing);
        out.push((t.clone(), kind));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracks_position_units_and_laser() {
        let mut t = Tracker::new([0.0; MAX_AXES]);
        assert_eq!(t.apply("(comment)").unwrap(), LineKind::Nothing);
        assert_eq!(t.apply("G21 G90 G17 G94").unwrap(), LineKind::Nothing);
        assert_eq!(
            t.apply("G0 X-1.5 Y0").unwrap(),
            LineKind::Motion { lit: false }
        );
        assert_eq!(t.apply("M3 S400").unwrap(), LineKind::Modal);
        assert_eq!(
            t.apply("G3 X0 Y-1.5 I1.5 J0 F1200").unwrap(),
            LineKind::Motion { lit: true }
        );
        assert_eq!(t.pos, [0.0, -1.5, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(t.state.feed, 1200.0);
        assert_eq!(t.apply("G91 X1").unwrap(), LineKind::Motion { lit: true });
        assert_eq!(t.pos[0], 1.0);
        assert_eq!(t.apply("G4 P0.5").unwrap(), LineKind::Dwell);
        t.apply("M2").unwrap();
        assert_eq!(t.state.spindle, Spindle::Off);
        assert!(!t.state.incremental);
        assert!(t.apply("G1 X1.2.3").is_err());
    }

    #[test]
    fn rotary_words_move_a_b_c_in_degrees_whatever_the_units() {
        let mut t = Tracker::new([0.0; MAX_AXES]);
        t.apply("G20 G93").unwrap();
        assert_eq!(
            t.apply("G1 X1 C90.5 B-12 F60").unwrap(),
            LineKind::Motion { lit: false }
        );
        assert_eq!(t.pos, [25.4, 0.0, 0.0, 0.0, -12.0, 90.5]);
        assert!(t.state.inverse_time);
        assert_eq!(t.state.feed, 60.0);
        t.apply("G91 A2").unwrap();
        assert_eq!(t.pos[3], 2.0);
    }
}
