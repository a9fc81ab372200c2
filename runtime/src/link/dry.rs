//! A dry-run line checker for the REPL's `:run`: parses each NC line of any dialect (words,
//! comments, modal groups), tracks absolute position, feed, motion mode and the laser output,
//! and refuses what a controller would refuse (unknown letters, malformed numbers, a feed
//! move without a feed, travel beyond the machine's soft limits). It answers at once and
//! speaks no protocol: live jobs go through [`super::Link`] and the GRBL simulator
//! ([`super::sim`]).

use super::{DryLink, LinkError, Reply};
use crate::machine::Machine;

#[derive(Debug, Clone)]
pub struct SimController {
    letters: Vec<char>,
    travel: Vec<(f64, f64)>,
    pub pos: Vec<f64>,
    pub feed_mm_min: f64,
    pub motion: u8,
    pub inverse_time: bool,
    pub laser_on: bool,
    pub lines: usize,
    pub motion_blocks: usize,
}

impl SimController {
    pub fn new(m: &Machine) -> SimController {
        SimController {
            letters: m
                .axes
                .iter()
                .map(|a| a.name.chars().next().unwrap_or('X'))
                .collect(),
            // NC words are mm and degrees; the machine file's limits are mm and radians.
            travel: m
                .axes
                .iter()
                .map(|a| {
                    let scale = super::controller_scale(a.kind);
                    (a.min * scale, a.max * scale)
                })
                .collect(),
            pos: vec![0.0; m.axes.len()],
            feed_mm_min: 0.0,
            motion: 0,
            inverse_time: false,
            laser_on: false,
            lines: 0,
            motion_blocks: 0,
        }
    }

    fn reject(code: u32, message: impl Into<String>) -> Result<Reply, LinkError> {
        Ok(Reply::Error {
            code,
            message: message.into(),
        })
    }
}

/// Splits a line into (letter, number) words, dropping comments and block numbers' spaces.
pub fn words(line: &str) -> Result<Vec<(char, f64)>, String> {
    let mut out = Vec::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            ' ' | '\t' | '%' => {}
            '(' => {
                for c in chars.by_ref() {
                    if c == ')' {
                        break;
                    }
                }
            }
            ';' => break,
            c if c.is_ascii_alphabetic() => {
                let mut num = String::new();
                while let Some(&d) = chars.peek() {
                    if d.is_ascii_digit() || d == '.' || d == '-' || d == '+' || d == ' ' {
                        if d != ' ' {
                            num.push(d);
                        }
                        chars.next();
                        if d == ' ' && !num.is_empty() {
                            break;
                        }
                    } else {
                        break;
                    }
                }
                let v: f64 = num
                    .parse()
                    .map_err(|_| format!("bad number after `{c}`: `{num}`"))?;
                out.push((c.to_ascii_uppercase(), v));
            }
            other => return Err(format!("unexpected character `{other}`")),
        }
    }
    Ok(out)
}

impl DryLink for SimController {
    fn send(&mut self, line: &str) -> Result<Reply, LinkError> {
        self.lines += 1;
        let ws = match words(line) {
            Ok(w) => w,
            Err(e) => return Self::reject(1, e),
        };
        let mut target = self.pos.clone();
        let mut moved = false;
        let mut has_feed_word = false;
        for (c, v) in &ws {
            match c {
                'G' => match (*v * 10.0).round() as i64 {
                    0 => self.motion = 0,
                    10 => self.motion = 1,
                    20 => self.motion = 2,
                    30 => self.motion = 3,
                    930 => self.inverse_time = true,
                    940 => self.inverse_time = false,
                    40 | 170 | 210 | 900 | 640 | 610 => {}
                    g => {
                        return Self::reject(
                            20,
                            format!("unsupported G-code G{}", g as f64 / 10.0),
                        );
                    }
                },
                'M' => match *v as i64 {
                    3 | 4 => self.laser_on = true,
                    5 => self.laser_on = false,
                    62 | 64 if ws.iter().any(|(c, p)| *c == 'P' && *p == 0.0) => {
                        self.laser_on = true
                    }
                    63 | 65 if ws.iter().any(|(c, p)| *c == 'P' && *p == 0.0) => {
                        self.laser_on = false
                    }
                    _ => {}
                },
                'F' => {
                    if *v <= 0.0 {
                        return Self::reject(22, "feed must be positive");
                    }
                    self.feed_mm_min = *v;
                    has_feed_word = true;
                }
                'N' | 'S' | 'P' | 'Q' | 'E' | 'I' | 'J' | 'K' | 'O' => {}
                c => match self.letters.iter().position(|l| l == c) {
                    Some(i) => {
                        target[i] = *v;
                        moved = true;
                    }
                    None => return Self::reject(20, format!("unknown word `{c}`")),
                },
            }
        }
        if moved {
            if self.motion != 0 && self.feed_mm_min <= 0.0 {
                return Self::reject(22, "feed move without a feed rate");
            }
            if self.inverse_time && self.motion != 0 && !has_feed_word {
                return Self::reject(22, "inverse-time move without F");
            }
            for (i, v) in target.iter().enumerate() {
                let (lo, hi) = self.travel[i];
                if *v < lo - 1e-6 || *v > hi + 1e-6 {
                    return Self::reject(15, format!("travel exceeded: {} = {v}", self.letters[i]));
                }
            }
            self.pos = target;
            self.motion_blocks += 1;
        }
        Ok(Reply::Ok)
    }

    fn status(&self) -> String {
        let pos: Vec<String> = self
            .letters
            .iter()
            .zip(&self.pos)
            .map(|(l, v)| format!("{l}{}", lase_lang::units::format_number(*v)))
            .collect();
        format!(
            "Idle | {} | laser {} | {} lines, {} motion blocks",
            pos.join(" "),
            if self.laser_on { "on" } else { "off" },
            self.lines,
            self.motion_blocks
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_skip_comments_and_parse_numbers() {
        let w = words("N10 G1 X-1.5 (go) Y2 F1200").unwrap();
        assert_eq!(
            w,
            vec![
                ('N', 10.0),
                ('G', 1.0),
                ('X', -1.5),
                ('Y', 2.0),
                ('F', 1200.0)
            ]
        );
        assert!(words("G1 X1.2.3").is_err());
        assert!(words("G1 #5").is_err());
    }

    #[test]
    fn rotary_travel_is_checked_in_degrees() {
        let m = crate::machine::parse_machine(lase_stdlib::machine("cam_xwb").unwrap(), 0).unwrap();
        let mut c = SimController::new(&m);
        // B travels ±100°: 30° is inside (it was refused when the limits stayed in radians).
        assert_eq!(c.send("G0 X10 B30 C720").unwrap(), Reply::Ok);
        assert!(matches!(
            c.send("G0 B120").unwrap(),
            Reply::Error { code: 15, .. }
        ));
    }
}
