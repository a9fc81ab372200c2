//! Process presets: named values with units, as data (`stdlib/presets/*.toml` or a file next
//! to the recipe). `use stdlib::presets::cam_hardening` binds each value as a recipe
//! variable; a later `let` overrides it.
//!
//! ```toml
//! doc = "Laser hardening of a steel cam"
//! [values]
//! power = "1200 W"
//! spot = "4 mm"
//! ```

use crate::value::Value;
use lase_lang::units::{self, Dim, QuantityError};

/// A parsed preset: its doc line and its values, in file order.
#[derive(Debug, Clone, Default)]
pub struct Preset {
    pub doc: String,
    pub values: Vec<(String, Value)>,
}

/// Why a preset could not be read: a message and the byte range in the file.
pub(crate) type PresetError = (String, std::ops::Range<usize>);

pub(crate) fn parse(text: &str) -> Result<Preset, PresetError> {
    let doc: toml::Table = toml::from_str(text).map_err(|e: toml::de::Error| {
        (
            e.message().to_string(),
            e.span().unwrap_or(0..text.len().min(1)),
        )
    })?;
    let whole = 0..text.len().min(1);
    let values = match doc.get("values") {
        Some(toml::Value::Table(t)) => t,
        _ => return Err(("a preset needs a [values] table".into(), whole)),
    };
    let mut out = Vec::new();
    for (k, v) in values {
        let at = key_span(text, k);
        let value = match v {
            toml::Value::String(s) => quantity(s).map_err(|m| (format!("`{k}`: {m}"), at))?,
            toml::Value::Float(x) => Value::Num(*x, Dim::NONE),
            toml::Value::Integer(i) => Value::Num(*i as f64, Dim::NONE),
            toml::Value::Boolean(b) => Value::Bool(*b),
            _ => {
                return Err((
                    format!("`{k}` must be a quantity string (\"1200 W\"), a number or a bool"),
                    at,
                ));
            }
        };
        out.push((k.clone(), value));
    }
    // toml's table is sorted; keep the file's order for docs.
    out.sort_by_key(|(k, _)| key_span(text, k).start);
    Ok(Preset {
        doc: doc
            .get("doc")
            .and_then(|d| d.as_str())
            .unwrap_or("")
            .to_string(),
        values: out,
    })
}

/// `"1200 W"` → 1200 W in internal units; a bare `"3"` is a plain number.
fn quantity(s: &str) -> Result<Value, String> {
    match units::parse_quantity(s) {
        Ok(q) => Ok(Value::Num(q.value, q.dim)),
        Err(QuantityError::NotANumber(t)) => Err(format!("\"{t}\" is not a number with a unit")),
        Err(e) => Err(e.to_string()),
    }
}

fn key_span(text: &str, key: &str) -> std::ops::Range<usize> {
    text.lines()
        .scan(0, |off, l| {
            let start = *off;
            *off += l.len() + 1;
            Some((start, l))
        })
        .find(|(_, l)| {
            l.trim_start()
                .strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with('='))
        })
        .map(|(s, l)| s..s + l.len())
        .unwrap_or(0..0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_read_quantities_in_internal_units() {
        let p = parse("doc = \"d\"\n[values]\nspeed = \"0.6 m/min\"\npower = \"1.2 kW\"\nn = 3\n")
            .unwrap();
        assert_eq!(p.doc, "d");
        let names: Vec<&str> = p.values.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(names, ["speed", "power", "n"]);
        match p.values[0].1 {
            Value::Num(x, d) => assert!((x - 10.0).abs() < 1e-12 && d == Dim::SPEED),
            _ => panic!(),
        }
        match p.values[1].1 {
            Value::Num(x, d) => assert!((x - 1200.0).abs() < 1e-9 && d == Dim::POWER),
            _ => panic!(),
        }
        let e = parse("[values]\npower = \"12 Wt\"\n").unwrap_err();
        assert!(e.0.contains("Wt"), "{}", e.0);
        assert_eq!(e.1.start, 9);
    }
}
