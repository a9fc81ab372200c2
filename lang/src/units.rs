//! Physical dimensions and unit literals.
//!
//! lase computes in one internal unit system — mm, s, rad, W — and converts only at the
//! edges: unit literals in the recipe are scaled to it here, and NC dialects convert on the
//! way out. A [`Dim`] is a vector of exponents over the base quantities length, time, angle
//! and power; energy is power·time and frequency is time⁻¹.

use serde::{Deserialize, Serialize};
use std::fmt;

/// Exponents of the base quantities (length, time, angle, power).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct Dim {
    pub length: i8,
    pub time: i8,
    pub angle: i8,
    pub power: i8,
}

impl Dim {
    pub const NONE: Dim = Dim::new(0, 0, 0, 0);
    pub const LENGTH: Dim = Dim::new(1, 0, 0, 0);
    pub const TIME: Dim = Dim::new(0, 1, 0, 0);
    pub const ANGLE: Dim = Dim::new(0, 0, 1, 0);
    pub const POWER: Dim = Dim::new(0, 0, 0, 1);
    pub const SPEED: Dim = Dim::new(1, -1, 0, 0);
    pub const ACCEL: Dim = Dim::new(1, -2, 0, 0);
    pub const JERK: Dim = Dim::new(1, -3, 0, 0);
    pub const ANGULAR_SPEED: Dim = Dim::new(0, -1, 1, 0);
    pub const ANGULAR_ACCEL: Dim = Dim::new(0, -2, 1, 0);
    pub const ANGULAR_JERK: Dim = Dim::new(0, -3, 1, 0);
    pub const FREQUENCY: Dim = Dim::new(0, -1, 0, 0);
    pub const ENERGY: Dim = Dim::new(0, 1, 0, 1);

    pub const fn new(length: i8, time: i8, angle: i8, power: i8) -> Dim {
        Dim {
            length,
            time,
            angle,
            power,
        }
    }

    pub fn powi(self, n: i8) -> Dim {
        Dim::new(
            self.length * n,
            self.time * n,
            self.angle * n,
            self.power * n,
        )
    }

    pub fn is_none(self) -> bool {
        self == Dim::NONE
    }

    /// The everyday name of a dimension ("speed"), or its base-unit form ("mm·s⁻²") if it has
    /// none.
    pub fn name(self) -> String {
        for (d, n) in NAMED_DIMS {
            if *d == self {
                return (*n).to_string();
            }
        }
        format!("[{}]", self.base_unit())
    }

    /// The dimension with its article, as diagnostics and the reference name a value's type:
    /// "a length", "an angular speed", "a quantity in mm^2", "a plain number".
    pub fn describe(self) -> String {
        if self.is_none() {
            return "a plain number".into();
        }
        let n = self.name();
        if n.starts_with('[') {
            return format!("a quantity in {}", self.base_unit());
        }
        let article = if n.starts_with(['a', 'e', 'i', 'o', 'u']) {
            "an"
        } else {
            "a"
        };
        format!("{article} {n}")
    }

    /// The internal unit of this dimension, e.g. `mm/s^2`.
    pub fn base_unit(self) -> String {
        let parts = [
            ("mm", self.length),
            ("rad", self.angle),
            ("W", self.power),
            ("s", self.time),
        ];
        let num: Vec<String> = parts
            .iter()
            .filter(|(_, e)| *e > 0)
            .map(|(u, e)| {
                if *e == 1 {
                    u.to_string()
                } else {
                    format!("{u}^{e}")
                }
            })
            .collect();
        let den: Vec<String> = parts
            .iter()
            .filter(|(_, e)| *e < 0)
            .map(|(u, e)| {
                if *e == -1 {
                    u.to_string()
                } else {
                    format!("{u}^{}", -e)
                }
            })
            .collect();
        let mut s = if num.is_empty() {
            "1".to_string()
        } else {
            num.join("*")
        };
        for d in den {
            s.push('/');
            s.push_str(&d);
        }
        s
    }
}

const NAMED_DIMS: &[(Dim, &str)] = &[
    (Dim::NONE, "number"),
    (Dim::LENGTH, "length"),
    (Dim::TIME, "time"),
    (Dim::ANGLE, "angle"),
    (Dim::POWER, "power"),
    (Dim::SPEED, "speed"),
    (Dim::ACCEL, "acceleration"),
    (Dim::JERK, "jerk"),
    (Dim::ANGULAR_SPEED, "angular speed"),
    (Dim::ANGULAR_ACCEL, "angular acceleration"),
    (Dim::ANGULAR_JERK, "angular jerk"),
    (Dim::FREQUENCY, "frequency"),
    (Dim::ENERGY, "energy"),
];

impl std::ops::Mul for Dim {
    type Output = Dim;
    fn mul(self, o: Dim) -> Dim {
        Dim::new(
            self.length + o.length,
            self.time + o.time,
            self.angle + o.angle,
            self.power + o.power,
        )
    }
}

impl std::ops::Div for Dim {
    type Output = Dim;
    fn div(self, o: Dim) -> Dim {
        self * o.powi(-1)
    }
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

/// The dimension named by a type annotation (`length`, `speed`, ...).
pub fn dim_by_name(name: &str) -> Option<Dim> {
    let alias = match name {
        "accel" => "acceleration",
        "angular_speed" => "angular speed",
        "angular_accel" => "angular acceleration",
        "angular_jerk" => "angular jerk",
        other => other,
    };
    NAMED_DIMS
        .iter()
        .find(|(_, n)| *n == alias)
        .map(|(d, _)| *d)
}

/// Atomic units: name, dimension, factor to the internal unit.
const ATOMS: &[(&str, Dim, f64)] = &[
    ("mm", Dim::LENGTH, 1.0),
    ("um", Dim::LENGTH, 1e-3),
    ("µm", Dim::LENGTH, 1e-3),
    ("cm", Dim::LENGTH, 10.0),
    ("m", Dim::LENGTH, 1000.0),
    ("in", Dim::LENGTH, 25.4),
    ("s", Dim::TIME, 1.0),
    ("ms", Dim::TIME, 1e-3),
    ("us", Dim::TIME, 1e-6),
    ("µs", Dim::TIME, 1e-6),
    ("ns", Dim::TIME, 1e-9),
    ("min", Dim::TIME, 60.0),
    ("rad", Dim::ANGLE, 1.0),
    ("deg", Dim::ANGLE, std::f64::consts::PI / 180.0),
    ("°", Dim::ANGLE, std::f64::consts::PI / 180.0),
    ("rev", Dim::ANGLE, std::f64::consts::TAU),
    ("W", Dim::POWER, 1.0),
    ("mW", Dim::POWER, 1e-3),
    ("kW", Dim::POWER, 1e3),
    ("Hz", Dim::FREQUENCY, 1.0),
    ("kHz", Dim::FREQUENCY, 1e3),
    ("MHz", Dim::FREQUENCY, 1e6),
    ("rpm", Dim::ANGULAR_SPEED, std::f64::consts::TAU / 60.0),
    ("J", Dim::ENERGY, 1.0),
    ("mJ", Dim::ENERGY, 1e-3),
    ("uJ", Dim::ENERGY, 1e-6),
    ("µJ", Dim::ENERGY, 1e-6),
];

/// Every atomic unit name, for completion and "did you mean".
pub fn unit_names() -> impl Iterator<Item = &'static str> {
    ATOMS.iter().map(|(n, _, _)| *n)
}

/// A resolved unit: its dimension and the factor that scales a value in it to the internal
/// unit of that dimension.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unit {
    pub dim: Dim,
    pub factor: f64,
}

/// Why a unit literal could not be resolved.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownUnit {
    /// The atom that is not a unit.
    pub atom: String,
    /// The closest known unit name, if any is close.
    pub suggestion: Option<&'static str>,
}

/// Resolves a unit literal such as `mm/s^2`, `m/min`, `kW`, `mm^2` or `s^-1`.
pub fn parse_unit(text: &str) -> Result<Unit, UnknownUnit> {
    let mut dim = Dim::NONE;
    let mut factor = 1.0;
    let mut sign = 1i8;
    let mut rest = text;
    loop {
        let end = rest.find(['/', '*']).unwrap_or(rest.len());
        let (term, tail) = rest.split_at(end);
        let (name, pow) = match term.split_once('^') {
            Some((n, p)) => (n, p.parse::<i8>().unwrap_or(1)),
            None => (term, 1),
        };
        let (_, d, f) = ATOMS
            .iter()
            .find(|(n, _, _)| *n == name)
            .ok_or_else(|| UnknownUnit {
                atom: name.to_string(),
                suggestion: suggest(name, unit_names()),
            })?;
        let p = pow * sign;
        dim = dim * d.powi(p);
        factor *= f.powi(p as i32);
        if tail.is_empty() {
            break;
        }
        sign = if tail.starts_with('/') { -1 } else { 1 };
        rest = &tail[1..];
    }
    Ok(Unit { dim, factor })
}

/// A number with its unit, as written outside recipes: in machine files (`v_max = "200
/// mm/s"`), process presets (`power = "1.2 kW"`), REPL commands (`:set power 1.1kW`) and
/// command-line options (`--period 0.5ms`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quantity {
    /// The value in internal units (mm, s, rad, W).
    pub value: f64,
    /// Its dimension; [`Dim::NONE`] for a bare number.
    pub dim: Dim,
    /// No unit was written. Callers that need a unit say so; a dimensionless unit such as
    /// `mm/mm` is not bare.
    pub bare: bool,
}

/// Why a text is not a [`Quantity`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QuantityError {
    /// It does not start with a number.
    #[error("`{0}` is not a number with a unit")]
    NotANumber(String),
    /// The number is followed by something that is not a unit.
    #[error("unknown unit `{}`", .0.atom)]
    UnknownUnit(UnknownUnit),
    /// The value overflows (`1e999 mm`) once scaled to internal units.
    #[error("`{0}` is not a finite number")]
    NotFinite(String),
}

/// Parses a number with an optional unit: `12 mm/s`, `900 deg/s^2`, `1.5kW`, `-5 mm`,
/// `1e-3 s`, `2E3 Hz`, `90°`, or a bare `3`. The one parser for quantities written outside
/// recipes (recipe literals go through the grammar).
///
/// The syntax, the union of what machine files, presets, the REPL and the command line
/// accepted before they shared this parser: surrounding whitespace is ignored; the number is
/// the longest prefix of digits, `.`, `+`, `-`, `e` and `E` and must parse as a Rust `f64`
/// (so `inf` and `nan` are not numbers); a space between number and unit is optional; the
/// unit is anything [`parse_unit`] resolves. A percentage is not a quantity: the REPL reads
/// `80%` as an override factor itself.
pub fn parse_quantity(text: &str) -> Result<Quantity, QuantityError> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '+' | '-' | 'e' | 'E')))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let number: f64 = number
        .parse()
        .map_err(|_| QuantityError::NotANumber(t.to_string()))?;
    let unit = unit.trim();
    let q = if unit.is_empty() {
        Quantity {
            value: number,
            dim: Dim::NONE,
            bare: true,
        }
    } else {
        let u = parse_unit(unit).map_err(QuantityError::UnknownUnit)?;
        Quantity {
            value: number * u.factor,
            dim: u.dim,
            bare: false,
        }
    };
    if !q.value.is_finite() {
        return Err(QuantityError::NotFinite(t.to_string()));
    }
    Ok(q)
}

/// The candidate closest to `name` by edit distance, if it is close enough to be a likely typo.
pub fn suggest<'a>(name: &str, candidates: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let mut best: Option<(f64, &str)> = None;
    for c in candidates {
        let score = strsim::jaro_winkler(name, c);
        if score > 0.8 && best.is_none_or(|(b, _)| score > b) {
            best = Some((score, c));
        }
    }
    best.map(|(_, c)| c)
}

/// Formats a value given in internal units with a readable unit of its dimension.
pub fn format_quantity(value: f64, dim: Dim) -> String {
    let (v, u) = match dim {
        d if d == Dim::LENGTH => (value, "mm"),
        d if d == Dim::TIME => (value, "s"),
        d if d == Dim::ANGLE => (value.to_degrees(), "deg"),
        d if d == Dim::POWER => (value, "W"),
        d if d == Dim::SPEED => (value, "mm/s"),
        d if d == Dim::ACCEL => (value, "mm/s^2"),
        d if d == Dim::JERK => (value, "mm/s^3"),
        d if d == Dim::ANGULAR_SPEED => (value.to_degrees(), "deg/s"),
        d if d == Dim::ANGULAR_ACCEL => (value.to_degrees(), "deg/s^2"),
        d if d == Dim::ANGULAR_JERK => (value.to_degrees(), "deg/s^3"),
        d if d == Dim::FREQUENCY => (value, "Hz"),
        d if d == Dim::ENERGY => (value, "J"),
        d if d == Dim::NONE => return format_number(value),
        d => return format!("{} {}", format_number(value), d.base_unit()),
    };
    format!("{} {u}", format_number(v))
}

/// A number with at most 6 decimals and no trailing zeros.
pub fn format_number(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compound_units_scale_to_internal() {
        let u = parse_unit("m/s^2").unwrap();
        assert_eq!(u.dim, Dim::ACCEL);
        assert_eq!(u.factor, 1000.0);
        let u = parse_unit("mm/min").unwrap();
        assert_eq!(u.dim, Dim::SPEED);
        assert!((u.factor - 1.0 / 60.0).abs() < 1e-15);
        let u = parse_unit("m/min").unwrap();
        assert!((u.factor - 1000.0 / 60.0).abs() < 1e-12);
        let u = parse_unit("deg/s").unwrap();
        assert_eq!(u.dim, Dim::ANGULAR_SPEED);
        let u = parse_unit("mm^2").unwrap();
        assert_eq!(u.dim, Dim::new(2, 0, 0, 0));
        let u = parse_unit("s^-1").unwrap();
        assert_eq!(u.dim, Dim::FREQUENCY);
        let u = parse_unit("W*s").unwrap();
        assert_eq!(u.dim, Dim::ENERGY);
        let u = parse_unit("m/s^3").unwrap();
        assert_eq!((u.dim, u.factor), (Dim::JERK, 1000.0));
        assert_eq!(parse_unit("in").unwrap().factor, 25.4);
    }

    #[test]
    fn unknown_units_suggest_the_closest() {
        let e = parse_unit("mmm").unwrap_err();
        assert_eq!(e.atom, "mmm");
        assert_eq!(e.suggestion, Some("mm"));
        let e = parse_unit("mm/sec").unwrap_err();
        assert_eq!(e.atom, "sec");
    }

    #[test]
    fn dims_have_names() {
        assert_eq!(Dim::SPEED.name(), "speed");
        assert_eq!(Dim::new(2, 0, 0, 0).name(), "[mm^2]");
        assert_eq!(Dim::new(1, -4, 0, 0).base_unit(), "mm/s^4");
        assert_eq!(format_quantity(std::f64::consts::PI, Dim::ANGLE), "180 deg");
    }

    #[test]
    fn quantities_accept_every_written_form() {
        let q = |t: &str| parse_quantity(t).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
        // Machine files and presets: a space before the unit.
        let v = q("12 mm/s");
        assert_eq!((v.value, v.dim, v.bare), (12.0, Dim::SPEED, false));
        let v = q("900 deg/s^2");
        assert!(close(v.value, 900f64.to_radians()) && v.dim == Dim::ANGULAR_ACCEL);
        let v = q("0.6 m/min");
        assert!(close(v.value, 10.0) && v.dim == Dim::SPEED);
        // The REPL and the command line: no space, signs, exponents.
        let v = q("1.5kW");
        assert_eq!((v.value, v.dim), (1500.0, Dim::POWER));
        assert_eq!(q("-5 mm").value, -5.0);
        assert_eq!(q("+5mm").value, 5.0);
        assert!(close(q("1e-3 s").value, 1e-3));
        assert_eq!(q("2E3 Hz").value, 2000.0);
        assert!(close(q("0.5ms").value, 5e-4));
        assert!(close(q("90°").value, std::f64::consts::FRAC_PI_2));
        assert_eq!(q(" .5 mm ").value, 0.5);
        // A bare number is dimensionless and says so; a unit that cancels is not bare.
        let v = q("3");
        assert_eq!((v.value, v.dim, v.bare), (3.0, Dim::NONE, true));
        let v = q("3 mm/mm");
        assert_eq!((v.dim, v.bare), (Dim::NONE, false));
    }

    #[test]
    fn malformed_quantities_say_why() {
        let e = |t: &str| parse_quantity(t).unwrap_err();
        assert_eq!(e("mm"), QuantityError::NotANumber("mm".into()));
        assert_eq!(e("  "), QuantityError::NotANumber("".into()));
        assert_eq!(e("inf mm"), QuantityError::NotANumber("inf mm".into()));
        assert_eq!(e("1-2 mm"), QuantityError::NotANumber("1-2 mm".into()));
        match e("100 mm/ss") {
            QuantityError::UnknownUnit(u) => assert_eq!(u.atom, "ss"),
            other => panic!("{other:?}"),
        }
        assert_eq!(e("12 Wt").to_string(), "unknown unit `Wt`");
        assert_eq!(e("1e999 mm"), QuantityError::NotFinite("1e999 mm".into()));
        assert_eq!(e("1e308 m"), QuantityError::NotFinite("1e308 m".into()));
    }
}
