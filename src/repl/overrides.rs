//! The REPL's overrides (`:set power 80%`, `:set speed 20 mm/s`): applied to each job before
//! it is planned, and held to the machine's laser again.

use super::Amount;
use super::Session;
use super::commands::{Typed, parse_typed};
use lase_lang::SourceMap;
use lase_lang::units::{self, Dim};
use lase_runtime::compile;
use lase_runtime::program::{OpKind, ProcessProgram};

impl Session {
    /// Applies the overrides, then holds the program to the machine's laser again: a power
    /// override can exceed its power, a speed override its pulse rate with pulses by distance.
    /// Reports what fails (against `map`, the program's sources).
    pub(super) fn apply_overrides(&self, map: &SourceMap, program: &mut ProcessProgram) -> bool {
        for op in &mut program.ops {
            let (feed, laser) = match &mut op.kind {
                OpKind::Line {
                    feed_mm_s, laser, ..
                }
                | OpKind::Arc {
                    feed_mm_s, laser, ..
                } => (feed_mm_s, laser),
                _ => continue,
            };
            match self.overrides.speed {
                Some(Amount::Value(v)) => *feed = v,
                Some(Amount::Factor(k)) => *feed *= k,
                None => {}
            }
            if let (Some(l), Some(power)) = (laser, &self.overrides.power) {
                // Ops share their laser (issue 18): this op's becomes its own.
                let l = std::sync::Arc::make_mut(l);
                match power {
                    Amount::Value(v) => l.power_w = *v,
                    Amount::Factor(k) => l.power_w *= *k,
                }
            }
        }
        match compile::validate(program) {
            Ok(()) => true,
            Err(f) => {
                self.report_in(map, &f);
                let list = self.overrides_list();
                if !list.is_empty() {
                    self.say_error(&format!(
                        "with the overrides ({list}) the job asks more than the laser can give: `:set` them lower"
                    ));
                }
                false
            }
        }
    }

    /// The overrides in force, `power 30 W, speed 50%`, or nothing.
    pub(super) fn overrides_list(&self) -> String {
        let fmt = |a: Amount, dim: Dim| match a {
            Amount::Value(v) => units::format_quantity(v, dim),
            Amount::Factor(k) => format!("{}%", units::format_number(k * 100.0)),
        };
        let mut v = Vec::new();
        if let Some(p) = self.overrides.power {
            v.push(format!("power {}", fmt(p, Dim::POWER)));
        }
        if let Some(s) = self.overrides.speed {
            v.push(format!("speed {}", fmt(s, Dim::SPEED)));
        }
        v.join(", ")
    }

    pub(super) fn overrides_note(&self) -> String {
        let list = self.overrides_list();
        if list.is_empty() {
            list
        } else {
            format!("overrides: {list}")
        }
    }

    /// `:set`, `:set KEY VALUE`, `:set KEY off`.
    pub(super) fn set(&mut self, rest: &str) {
        let mut words = rest.splitn(2, char::is_whitespace);
        let key = words.next().unwrap_or("").trim();
        let value = words.next().unwrap_or("").trim();
        if key.is_empty() {
            let note = self.overrides_note();
            println!(
                "{}",
                if note.is_empty() {
                    "no overrides".into()
                } else {
                    note
                }
            );
            return;
        }
        let (slot, dim) = match key {
            "power" => (&mut self.overrides.power, Dim::POWER),
            "speed" | "feed" => (&mut self.overrides.speed, Dim::SPEED),
            other => {
                self.say_error(&format!(
                    "`:set {other}`: overrides are `power` and `speed`"
                ));
                return;
            }
        };
        if matches!(value, "off" | "-" | "none" | "clear" | "100%") {
            *slot = None;
            println!("{key}: as programmed");
            return;
        }
        let amount = match parse_typed(value) {
            Ok(Typed::Quantity(v, d)) if d == dim && v > 0.0 => Amount::Value(v),
            Ok(Typed::Percent(k)) if k > 0.0 => Amount::Factor(k),
            Ok(_) => {
                let what = if dim == Dim::POWER {
                    "a power (W, kW)"
                } else {
                    "a speed (mm/s, m/min)"
                };
                self.say_error(&format!(
                    "`:set {key}` takes {what} or a percentage, e.g. 80%"
                ));
                return;
            }
            Err(e) => {
                self.say_error(&e);
                return;
            }
        };
        if let (Amount::Value(v), Some(m)) = (amount, self.eval.machine())
            && dim == Dim::POWER
            && v > m.laser.max_power_w
        {
            self.say_error(&format!(
                "{} is above the {} the laser of `{}` can give",
                units::format_quantity(v, Dim::POWER),
                units::format_quantity(m.laser.max_power_w, Dim::POWER),
                m.name
            ));
            return;
        }
        *slot = Some(amount);
        println!("{} for the next runs", self.overrides_note());
    }
}
