//! Run-time values of the recipe language.

use crate::geometry::Profile;
use lase_lang::units::{self, Dim};
use std::fmt;
use std::rc::Rc;

#[derive(Debug, Clone)]
pub enum Value {
    /// A number in internal units with its dimension.
    Num(f64, Dim),
    /// The literal `0`, which fits any dimension.
    Zero,
    Bool(bool),
    Str(Rc<str>),
    /// A point in mm; `dims` is 2 or 3 (a 2-D point keeps the current z when moved to).
    Point([f64; 3], u8),
    List(Rc<Vec<Value>>),
    Profile(Rc<Profile>),
    Nothing,
}

impl Value {
    pub fn type_name(&self) -> String {
        match self {
            Value::Num(_, d) => lase_lang::Ty::Num(*d).describe(),
            Value::Zero => "zero".into(),
            Value::Bool(_) => "a bool".into(),
            Value::Str(_) => "a string".into(),
            Value::Point(..) => "a point".into(),
            Value::List(_) => "a list".into(),
            Value::Profile(_) => "a profile".into(),
            Value::Nothing => "nothing".into(),
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Num(v, d) => f.write_str(&units::format_quantity(*v, *d)),
            Value::Zero => f.write_str("0"),
            Value::Bool(b) => write!(f, "{b}"),
            Value::Str(s) => write!(f, "\"{s}\""),
            Value::Point(p, n) => {
                let c: Vec<String> = p[..*n as usize]
                    .iter()
                    .map(|v| units::format_quantity(*v, Dim::LENGTH))
                    .collect();
                write!(f, "({})", c.join(", "))
            }
            Value::List(items) => {
                f.write_str("[")?;
                for (i, v) in items.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    if i == 8 && items.len() > 10 {
                        write!(f, "… {} more", items.len() - 8)?;
                        break;
                    }
                    write!(f, "{v}")?;
                }
                f.write_str("]")
            }
            Value::Profile(p) => write!(
                f,
                "profile ({} segment{}, {}, {})",
                p.segs.len(),
                if p.segs.len() == 1 { "" } else { "s" },
                if p.closed { "closed" } else { "open" },
                units::format_quantity(p.length(), Dim::LENGTH)
            ),
            Value::Nothing => f.write_str("()"),
        }
    }
}
