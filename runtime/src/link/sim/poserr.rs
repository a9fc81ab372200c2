//! The simulated table's positioning error (issue 15, PROCESS.md §3): where the table really
//! is, as a 1 µm linear scale reads it, when the controller's own position is exact.
//!
//! Three effects, each settable (`lase sim --position-error`, `sim://?position_error=…`):
//! * **backlash** — a dead band of `backlash` per axis: after a reversal the table does not
//!   move until the command has taken up the play (the classic play operator, exact along a
//!   straight block because each axis moves one way within it);
//! * **random** — an error drawn uniformly in ±`random` per axis whenever the table comes to
//!   rest after a positioning move (more than [`SMALL_MOVE_MM`] of travel since the last
//!   rest), from a seeded generator, so a run repeats; the table carries it through the moves
//!   that follow until the next rest (a row runs with the error its start had, as on the
//!   seed's table, whose scale counts the spots from the row start), and corrective steps
//!   smaller than that keep the error they found, as a servo's final increments do;
//! * **drift** — a slow linear drift of `drift` per second on every axis (thermal growth).
//!
//! The reading is the table's position rounded to the scale's resolution (`scale`, 1 µm),
//! and is what the status report shows as `MPos` when the model is on.

use crate::link::{AxisPos, MAX_AXES};
use std::fmt;
use std::str::FromStr;

/// More travel than this between two rests is a positioning move and draws a new random
/// error; less is a corrective step. mm.
pub const SMALL_MOVE_MM: f64 = 0.01;

/// The settable model, mm and mm/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionErrorConfig {
    pub backlash_mm: f64,
    pub random_mm: f64,
    pub drift_mm_s: f64,
    /// The scale's resolution, mm (default 1 µm).
    pub scale_mm: f64,
    pub seed: u64,
}

impl Default for PositionErrorConfig {
    fn default() -> Self {
        PositionErrorConfig {
            backlash_mm: 0.0,
            random_mm: 0.0,
            drift_mm_s: 0.0,
            scale_mm: 0.001,
            seed: 1,
        }
    }
}

impl FromStr for PositionErrorConfig {
    type Err = String;

    /// `backlash=3um,random=5um,drift=0.1um/s,scale=1um,seed=7` (any subset, any order; the
    /// values are lase quantities with units).
    fn from_str(s: &str) -> Result<Self, String> {
        use lase_lang::units::{Dim, parse_quantity};
        let mut c = PositionErrorConfig::default();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').ok_or_else(|| {
                format!("position error `{part}`: write key=value, e.g. backlash=3um")
            })?;
            if k == "seed" {
                c.seed = v
                    .parse()
                    .map_err(|_| format!("position error seed `{v}`: give a whole number"))?;
                continue;
            }
            let q = parse_quantity(v).map_err(|e| format!("position error `{part}`: {e}"))?;
            let want = if k == "drift" {
                Dim::SPEED
            } else {
                Dim::LENGTH
            };
            if q.dim != want || !q.value.is_finite() || q.value < 0.0 || q.value > 1.0 {
                return Err(format!(
                    "position error `{part}`: give {} from 0 to 1 mm{}",
                    if k == "drift" { "a speed" } else { "a length" },
                    if k == "drift" {
                        "/s, e.g. drift=0.1um/s"
                    } else {
                        ", e.g. 3um"
                    }
                ));
            }
            match k {
                "backlash" => c.backlash_mm = q.value,
                "random" => c.random_mm = q.value,
                "drift" => c.drift_mm_s = q.value,
                "scale" if q.value > 0.0 => c.scale_mm = q.value,
                _ => {
                    return Err(format!(
                        "position error `{k}`: known keys are backlash, random, drift, scale, seed"
                    ));
                }
            }
        }
        Ok(c)
    }
}

impl fmt::Display for PositionErrorConfig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "backlash={}um,random={}um,drift={}um/s,scale={}um,seed={}",
            self.backlash_mm * 1e3,
            self.random_mm * 1e3,
            self.drift_mm_s * 1e3,
            self.scale_mm * 1e3,
            self.seed
        )
    }
}

/// The model's state: the play operator's output per axis, the random error, the generator.
#[derive(Debug, Clone)]
pub struct PositionError {
    pub cfg: PositionErrorConfig,
    /// The table's position before the random error and drift (the play operator's output).
    played: AxisPos,
    random: AxisPos,
    /// Travel since the table last came to rest, mm.
    travelled: f64,
    rng: u64,
}

impl PositionError {
    pub fn new(cfg: PositionErrorConfig, start: AxisPos) -> PositionError {
        PositionError {
            cfg,
            played: start,
            random: [0.0; MAX_AXES],
            travelled: 0.0,
            // splitmix64 needs any non-zero state.
            rng: cfg.seed ^ 0x9E37_79B9_7F4A_7C15,
        }
    }

    /// The commanded position is now `cmd`: the play takes up what the command moved.
    pub fn follow(&mut self, cmd: &AxisPos) {
        let h = 0.5 * self.cfg.backlash_mm;
        for (p, c) in self.played.iter_mut().zip(cmd) {
            if c - *p > h {
                *p = c - h;
            } else if *p - c > h {
                *p = c + h;
            }
        }
    }

    /// A block from `from` to `to` ended (`at_rest`: at zero speed): the table follows, and
    /// coming to rest after a positioning move draws a new random error.
    pub fn block_done(&mut self, from: &AxisPos, to: &AxisPos, at_rest: bool) {
        self.follow(to);
        let len = from
            .iter()
            .zip(to)
            .map(|(a, b)| (b - a) * (b - a))
            .sum::<f64>()
            .sqrt();
        self.travelled += len;
        if !at_rest {
            return;
        }
        if self.travelled > SMALL_MOVE_MM && self.cfg.random_mm > 0.0 {
            for k in 0..MAX_AXES {
                self.random[k] = self.cfg.random_mm * (2.0 * self.uniform() - 1.0);
            }
        }
        self.travelled = 0.0;
    }

    /// Where the table really is at time `t` s (after [`follow`](Self::follow)ing the command).
    pub fn actual(&self, t: f64) -> AxisPos {
        std::array::from_fn(|k| self.played[k] + self.random[k] + self.cfg.drift_mm_s * t)
    }

    /// What the scale reads at time `t`: the actual position to its resolution.
    pub fn reading(&self, t: f64) -> AxisPos {
        let s = self.cfg.scale_mm;
        self.actual(t).map(|x| (x / s).round() * s)
    }

    /// Uniform in [0, 1) (splitmix64).
    fn uniform(&mut self) -> f64 {
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Where the table was when a row's first pulse fired: the first lit feed block since the
/// table stood still or ran a rapid (a row of pulses by distance runs up from rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowStartRecord {
    /// Simulated s.
    pub t: f64,
    /// The controller's (exact) position.
    pub commanded: AxisPos,
    /// The table's, from the error model.
    pub actual: AxisPos,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: f64) -> AxisPos {
        let mut p = [0.0; MAX_AXES];
        p[0] = x;
        p
    }

    #[test]
    fn backlash_is_a_dead_band_taken_up_after_a_reversal() {
        let cfg: PositionErrorConfig = "backlash=3um".parse().unwrap();
        let mut m = PositionError::new(cfg, at(0.0));
        m.follow(&at(1.0));
        // Moving +x, the table lags 1.5 µm behind.
        assert!((m.actual(0.0)[0] - (1.0 - 0.0015)).abs() < 1e-12);
        // Reversing by 2 µm moves nothing yet (3 µm of play to take up).
        m.follow(&at(0.998));
        assert!((m.actual(0.0)[0] - (1.0 - 0.0015)).abs() < 1e-12);
        // 4 µm back: the last 1 µm moves the table, now leading by 1.5 µm.
        m.follow(&at(0.996));
        assert!((m.actual(0.0)[0] - (0.996 + 0.0015)).abs() < 1e-12);
    }

    #[test]
    fn random_errors_are_seeded_bounded_and_kept_by_small_steps() {
        let cfg: PositionErrorConfig = "random=5um,seed=3".parse().unwrap();
        let mut a = PositionError::new(cfg, at(0.0));
        let mut b = PositionError::new(cfg, at(0.0));
        let mut seen = Vec::new();
        let mut x = 0.0;
        for _ in 0..200 {
            a.block_done(&at(x), &at(x + 1.0), true);
            b.block_done(&at(x), &at(x + 1.0), true);
            x += 1.0;
            let e = a.actual(0.0)[0] - x;
            assert!(e.abs() <= 0.005 + 1e-12);
            assert_eq!(a.actual(0.0), b.actual(0.0));
            seen.push(e);
        }
        assert!(seen.iter().any(|e| *e > 0.004) && seen.iter().any(|e| *e < -0.004));
        // A 0.5 µm step keeps the error and moves the table by the step.
        let before = a.actual(0.0)[0];
        a.block_done(&at(x), &at(x + 0.0005), true);
        assert!((a.actual(0.0)[0] - before - 0.0005).abs() < 1e-12);
        // A long move that does not stop (a row's run-up into its first spot) keeps it too.
        let before = a.actual(0.0)[0] - x - 0.0005;
        a.block_done(&at(x), &at(x + 1.0), false);
        assert!((a.actual(0.0)[0] - (x + 1.0) - before).abs() < 1e-12);
    }

    #[test]
    fn the_reading_is_the_scale_count_and_drift_grows_with_time() {
        let cfg: PositionErrorConfig = "drift=0.1um/s".parse().unwrap();
        let m = PositionError::new(cfg, at(1.0));
        assert_eq!(m.reading(0.0)[0], 1.0);
        assert!((m.reading(10.0)[0] - 1.001).abs() < 1e-12);
        assert!((m.reading(4.0)[0] - 1.0).abs() < 1e-12, "0.4 µm reads as 0");
        assert!("backlash=3".parse::<PositionErrorConfig>().is_err());
        assert!("wobble=3um".parse::<PositionErrorConfig>().is_err());
        assert!("backlash=2mm".parse::<PositionErrorConfig>().is_err());
    }
}
