//! The recipe side of marking (issue 19): `profile text(...)`, the 2D-code builtins (`qr`,
//! `qr_dots`, `datamatrix`, `datamatrix_dots`) and `format`. The geometry is `crate::marking`;
//! here arguments are checked, fonts read through the `Host`, and diagnostics point at the
//! argument that is wrong.

use super::{Cx, EvalError, Evaluator, Kind, R, Value, bad, type_err};
use crate::geometry::V2;
use crate::marking::{self, Align, Glyph, Layout, codes, hershey, outline};
use lase_lang::Span;
use lase_lang::ast::{Arg, ExprKind};
use lase_lang::diag::did_you_mean;
use lase_lang::units::{self, Dim};
use std::rc::Rc;

/// Characters one text or code may hold: far above a label, far below what would exhaust
/// memory before the op budget could refuse it.
const MAX_CHARS: usize = 10_000;

type Bound = [Option<(Value, Span)>];

impl Evaluator {
    fn str_arg(&self, a: &Bound, i: usize, what: &str, span: Span) -> R<(Rc<str>, Span)> {
        match a.get(i).cloned().flatten() {
            Some((Value::Str(s), sp)) => {
                if s.chars().count() > MAX_CHARS {
                    return Err(bad(
                        Kind::TooLarge,
                        sp,
                        &format!("{what} holds more than {MAX_CHARS} characters"),
                        "too long",
                        None,
                    ));
                }
                Ok((s, sp))
            }
            Some((v, sp)) => Err(type_err("a string", &v, sp, what)),
            None => Err(bad(
                Kind::MissingArgument,
                span,
                &format!("missing {what}"),
                "in this call",
                None,
            )),
        }
    }

    fn positive_len(&self, a: &Bound, i: usize, what: &str, span: Span) -> R<f64> {
        let (v, sp) = a.get(i).cloned().flatten().ok_or_else(|| {
            bad(
                Kind::MissingArgument,
                span,
                &format!("missing {what}"),
                "in this call",
                None,
            )
        })?;
        let x = self.as_dim(&v, Dim::LENGTH, sp, what)?;
        if !(x > 0.0) {
            return Err(bad(
                Kind::NotPositive,
                sp,
                &format!("{what} must be greater than zero"),
                "not positive",
                None,
            ));
        }
        self.in_range(x, &super::bounds::FINE_LENGTH, what, sp)?;
        Ok(x)
    }

    fn point_or_origin(&self, a: &Bound, i: usize) -> R<V2> {
        match a.get(i).cloned().flatten() {
            Some((v, sp)) => {
                let (p, _) = self.as_point(&v, sp, "`origin`")?;
                Ok(V2::new(p[0], p[1]))
            }
            None => Ok(V2::zeros()),
        }
    }

    /// `profile text(text, height, at, align, spacing, angle, radius, font)`.
    pub(super) fn text_profile(&mut self, a: &Bound, span: Span, cx: &mut Cx) -> R<Value> {
        let (text, text_span) = self.str_arg(a, 0, "the text", span)?;
        let height = self.positive_len(a, 1, "the text height", span)?;
        let at = self.point_or_origin(a, 2)?;
        let align = match a.get(3).cloned().flatten() {
            None => Align::Left,
            Some((Value::Str(s), sp)) => Align::parse(&s).ok_or_else(|| {
                let help = did_you_mean(&s, Align::NAMES.iter().copied())
                    .unwrap_or_else(|| "write \"left\", \"center\" or \"right\"".into());
                bad(
                    Kind::UnknownName,
                    sp,
                    &format!("unknown alignment \"{s}\""),
                    "not an alignment",
                    Some(&help),
                )
            })?,
            Some((v, sp)) => return Err(type_err("a string", &v, sp, "`align`")),
        };
        let spacing = match a.get(4).cloned().flatten() {
            Some((v, sp)) => self.as_dim(&v, Dim::LENGTH, sp, "`spacing`")?,
            None => 0.0,
        };
        let radius = match a.get(6).cloned().flatten() {
            Some((v, sp)) => {
                let r = self.as_dim(&v, Dim::LENGTH, sp, "`radius`")?;
                if r == 0.0 || !r.is_finite() {
                    return Err(bad(
                        Kind::OutOfRange,
                        sp,
                        "a text arc needs a radius other than zero",
                        "zero radius",
                        Some(
                            "a positive radius sets the text outside the arc, a negative one inside",
                        ),
                    ));
                }
                self.in_range(r.abs(), &super::bounds::FINE_LENGTH, "the radius", sp)?;
                Some(r)
            }
            None => None,
        };
        let angle = match a.get(5).cloned().flatten() {
            Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`angle`")?,
            None if radius.is_some() => std::f64::consts::FRAC_PI_2,
            None => 0.0,
        };
        let tol = self.planner_settings_now().arc_tolerance_mm;
        let bend_step = radius.map_or(height, |r| (8.0 * tol * r.abs()).sqrt().min(height / 4.0));
        let layout = Layout {
            height,
            at,
            align,
            spacing,
            angle,
            radius,
            bend_step,
        };
        let missing = |c: char, what: &str| {
            bad(
                Kind::Marking,
                text_span,
                &format!("{what} has no glyph for {c:?}"),
                "this text",
                Some(
                    "the built-in font holds printable ASCII (space to `~`); give a `font:` \
                     file that has the character, or leave it out",
                ),
            )
        };
        let (glyphs, closed): (Vec<Glyph>, bool) = match a.get(7).cloned().flatten() {
            None => {
                let g = text
                    .chars()
                    .map(|c| {
                        hershey::glyph(c)
                            .cloned()
                            .ok_or_else(|| missing(c, "the built-in font"))
                    })
                    .collect::<R<_>>()?;
                (g, false)
            }
            Some((Value::Str(path), sp)) => {
                let importer = cx
                    .map
                    .file_of(sp.start as usize)
                    .map(|f| cx.map.name(f).to_string())
                    .unwrap_or_default();
                let fail = |reason: String| {
                    bad(
                        Kind::Marking,
                        sp,
                        &format!("cannot read the font \"{path}\": {reason}"),
                        "this font",
                        Some("give a TrueType or OpenType file, relative to the recipe's folder"),
                    )
                };
                let (_, bytes) = cx.host.binary_file(&importer, &path).map_err(fail)?;
                let font = outline::Font::parse(&bytes).map_err(fail)?;
                let g = text
                    .chars()
                    .map(|c| {
                        font.glyph(c, tol / height)
                            .ok_or_else(|| missing(c, &format!("the font \"{path}\"")))
                    })
                    .collect::<R<_>>()?;
                (g, true)
            }
            Some((v, sp)) => return Err(type_err("a string", &v, sp, "`font`")),
        };
        let profiles =
            marking::place(&glyphs, &layout, closed).map_err(|g| EvalError::Geometry {
                message: format!("the text cannot be laid out: {g}"),
                span,
                label: "this text".into(),
                help: None,
            })?;
        Ok(Value::List(Rc::new(
            profiles
                .into_iter()
                .map(|p| Value::Profile(Rc::new(p)))
                .collect(),
        )))
    }

    /// `qr(text, module, at, quiet)` and its kin: the symbol's dark modules as rectangles to
    /// fill, or their centres to fire at.
    pub(super) fn code_call(&mut self, name: &str, a: &Bound, span: Span) -> R<Value> {
        let sym = if name.starts_with("qr") {
            codes::Symbology::Qr
        } else {
            codes::Symbology::DataMatrix
        };
        let (text, text_span) = self.str_arg(a, 0, "the text", span)?;
        let module = self.positive_len(a, 1, "the module size", span)?;
        let at = self.point_or_origin(a, 2)?;
        let quiet = match a.get(3).cloned().flatten() {
            Some((v, sp)) => {
                let q = self.as_count(&v, sp, "`quiet`")?;
                if !(0..=100).contains(&q) {
                    return Err(bad(
                        Kind::OutOfRange,
                        sp,
                        &format!("a quiet zone of {q} modules is outside 0 to 100"),
                        "out of range",
                        Some("the standards ask for 4 modules (QR) or 1 (Data Matrix)"),
                    ));
                }
                q as u32
            }
            None => sym.default_quiet(),
        };
        let m = codes::encode(sym, &text).map_err(|reason| {
            bad(
                Kind::Marking,
                text_span,
                &format!(
                    "cannot encode this text as a {}: {reason}",
                    symbology_name(sym)
                ),
                "this text",
                Some("shorten the text, or split it over several codes"),
            )
        })?;
        let p = codes::Placement { at, module, quiet };
        Ok(Value::List(Rc::new(if name.ends_with("_dots") {
            m.centres(&p)
                .into_iter()
                .map(|c| Value::Point([c.x, c.y, 0.0], 2))
                .collect()
        } else {
            m.runs(&p)
                .into_iter()
                .map(|r| Value::Profile(Rc::new(r)))
                .collect()
        })))
    }

    /// `format(template, values…)`: see the builtin's documentation in the schema.
    pub(super) fn format_call(&mut self, args: &[Arg], span: Span, cx: &mut Cx) -> R<Value> {
        let Some(first) = args.first() else {
            return Err(bad(
                Kind::MissingArgument,
                span,
                "missing argument `template`",
                "in this call",
                Some("`format(\"SN {:04}\", n)`"),
            ));
        };
        let tv = self.expr(&first.value, cx)?;
        let Value::Str(template) = &tv else {
            return Err(type_err("a string", &tv, first.value.span, "the template"));
        };
        let mut values = Vec::with_capacity(args.len() - 1);
        for a in &args[1..] {
            values.push((self.expr(&a.value, cx)?, a.value.span));
        }
        // A literal template written without escapes maps byte for byte onto the recipe, so a
        // mistake can be pointed at exactly; otherwise at the whole template.
        let t_span = first.value.span;
        let exact = matches!(&first.value.kind, ExprKind::Str(s) if s.len() + 2 == (t_span.end - t_span.start) as usize);
        let at = |from: usize, to: usize| {
            if exact {
                Span::new(
                    t_span.start as usize + 1 + from,
                    t_span.start as usize + 1 + to,
                )
            } else {
                t_span
            }
        };
        format_template(template, &values, at, span).map(|s| Value::Str(s.into()))
    }
}

fn symbology_name(s: codes::Symbology) -> &'static str {
    match s {
        codes::Symbology::Qr => "QR code",
        codes::Symbology::DataMatrix => "Data Matrix",
    }
}

/// One `{…}` placeholder's spec: `[<^>][0][width][.precision]`.
#[derive(Debug, Default, PartialEq)]
struct Spec {
    align: Option<char>,
    zero: bool,
    width: usize,
    precision: Option<usize>,
}

fn parse_spec(s: &str) -> Option<Spec> {
    let mut spec = Spec::default();
    let mut rest = s;
    if let Some(c) = rest.chars().next().filter(|c| matches!(c, '<' | '^' | '>')) {
        spec.align = Some(c);
        rest = &rest[1..];
    }
    if let Some(r) = rest.strip_prefix('0') {
        spec.zero = true;
        rest = r;
    }
    let (w, p) = match rest.split_once('.') {
        Some((w, p)) => (w, Some(p)),
        None => (rest, None),
    };
    let digits = |d: &str| d.chars().all(|c| c.is_ascii_digit()) && d.len() <= 3;
    if !digits(w) || p.is_some_and(|p| p.is_empty() || !digits(p)) {
        return None;
    }
    spec.width = if w.is_empty() { 0 } else { w.parse().ok()? };
    spec.precision = match p {
        Some(p) => Some(p.parse().ok()?),
        None => None,
    };
    Some(spec)
}

fn format_template(
    template: &str,
    values: &[(Value, Span)],
    at: impl Fn(usize, usize) -> Span,
    call: Span,
) -> R<String> {
    let err = |sp: Span, msg: &str, label: &str, help: &str| {
        bad(Kind::Format, sp, msg, label, Some(help))
    };
    let mut out = String::new();
    let mut next = 0;
    let mut chars = template.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        match c {
            '{' if chars.peek().map(|x| x.1) == Some('{') => {
                chars.next();
                out.push('{');
            }
            '}' if chars.peek().map(|x| x.1) == Some('}') => {
                chars.next();
                out.push('}');
            }
            '}' => {
                return Err(err(
                    at(i, i + 1),
                    "a `}` without its `{`",
                    "unmatched",
                    "write `}}` for a literal brace",
                ));
            }
            '{' => {
                let Some(close) = template[i..].find('}').map(|k| i + k) else {
                    return Err(err(
                        at(i, i + 1),
                        "a `{` without its `}`",
                        "unmatched",
                        "close the placeholder (`{}`), or write `{{` for a literal brace",
                    ));
                };
                let inner = &template[i + 1..close];
                while chars.peek().is_some_and(|x| x.0 <= close) {
                    chars.next();
                }
                let here = at(i, close + 1);
                let spec = match inner.strip_prefix(':') {
                    Some(s) => parse_spec(s),
                    None if inner.is_empty() => Some(Spec::default()),
                    None => None,
                }
                .ok_or_else(|| {
                    err(
                        here,
                        &format!("`{{{inner}}}` is not a placeholder lase knows"),
                        "unknown spec",
                        "placeholders take the values in order: `{}`, `{:04}` (zero-padded to 4), \
                         `{:>6}` (right-aligned in 6), `{:.2}` (2 decimals)",
                    )
                })?;
                let Some((v, vspan)) = values.get(next) else {
                    return Err(err(
                        here,
                        &format!(
                            "the template has more placeholders than the {} value(s) given",
                            values.len()
                        ),
                        "no value for this",
                        "give one value per `{}`",
                    ));
                };
                next += 1;
                out.push_str(&render(v, &spec, *vspan)?);
            }
            c => out.push(c),
        }
    }
    if let Some((_, sp)) = values.get(next) {
        let _ = call;
        return Err(err(
            *sp,
            &format!(
                "{} value(s) given for {} placeholder(s)",
                values.len(),
                next
            ),
            "no placeholder for this",
            "add a `{}` to the template for it, or leave it out",
        ));
    }
    Ok(out)
}

/// One value under its spec.
fn render(v: &Value, spec: &Spec, span: Span) -> R<String> {
    let number = match v {
        Value::Num(x, d) if d.is_none() => Some(*x),
        Value::Zero => Some(0.0),
        _ => None,
    };
    if number.is_none() && (spec.zero || spec.precision.is_some()) {
        let help = match v {
            Value::Num(..) => {
                "a quantity prints with its unit; for digits of your own divide by \
                               a unit first: `format(\"{:.2}\", d / 1 mm)`"
            }
            _ => "`0` and `.N` apply to plain numbers",
        };
        return Err(bad(
            Kind::Format,
            span,
            &format!("`0` and `.N` need a plain number, not {}", v.type_name()),
            "not a plain number",
            Some(help),
        ));
    }
    let body = match (number, v) {
        (Some(x), _) => match spec.precision {
            Some(p) => format!("{x:.p$}"),
            None if x.fract() == 0.0 && x.abs() < 1e15 => format!("{}", x as i64),
            None => units::format_number(x),
        },
        (None, Value::Str(s)) => s.to_string(),
        (None, other) => other.to_string(),
    };
    let len = body.chars().count();
    if len >= spec.width {
        return Ok(body);
    }
    let pad = spec.width - len;
    if spec.zero {
        // Zeros go after the sign: -0042, as printf and Rust do.
        let (sign, digits) = match body.strip_prefix('-') {
            Some(d) => ("-", d),
            None => ("", body.as_str()),
        };
        return Ok(format!("{sign}{}{digits}", "0".repeat(pad)));
    }
    let align = spec
        .align
        .unwrap_or(if number.is_some() { '>' } else { '<' });
    Ok(match align {
        '<' => format!("{body}{}", " ".repeat(pad)),
        '>' => format!("{}{body}", " ".repeat(pad)),
        _ => format!("{}{body}{}", " ".repeat(pad / 2), " ".repeat(pad - pad / 2)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fmt(t: &str, vals: &[Value]) -> Result<String, String> {
        let v: Vec<(Value, Span)> = vals.iter().map(|v| (v.clone(), Span::new(0, 1))).collect();
        format_template(t, &v, |_, _| Span::new(0, 1), Span::new(0, 1)).map_err(|e| e.to_string())
    }

    fn n(x: f64) -> Value {
        Value::Num(x, Dim::NONE)
    }

    #[test]
    fn placeholders_fill_in_order_with_their_specs() {
        assert_eq!(fmt("SN {:04}", &[n(42.0)]).unwrap(), "SN 0042");
        assert_eq!(fmt("{:04}", &[n(-7.0)]).unwrap(), "-007");
        assert_eq!(fmt("{}/{}", &[n(3.0), n(12.0)]).unwrap(), "3/12");
        assert_eq!(fmt("{:.2} W", &[n(12.345)]).unwrap(), "12.35 W");
        assert_eq!(fmt("[{:>5}]", &[n(1.5)]).unwrap(), "[  1.5]");
        assert_eq!(
            fmt("[{:<4}]", &[Value::Str("ab".into())]).unwrap(),
            "[ab  ]"
        );
        assert_eq!(
            fmt("[{:^6}]", &[Value::Str("ab".into())]).unwrap(),
            "[  ab  ]"
        );
        assert_eq!(fmt("[{:4}]", &[Value::Str("ab".into())]).unwrap(), "[ab  ]");
        assert_eq!(fmt("{{{}}}", &[n(1.0)]).unwrap(), "{1}");
        assert_eq!(
            fmt("{}", &[Value::Num(2.5, Dim::LENGTH)]).unwrap(),
            "2.5 mm"
        );
        assert_eq!(fmt("{}", &[Value::Bool(true)]).unwrap(), "true");
        assert_eq!(fmt("no values", &[]).unwrap(), "no values");
    }

    #[test]
    fn mismatches_are_refused_with_what_went_wrong() {
        assert!(
            fmt("{} {}", &[n(1.0)])
                .unwrap_err()
                .contains("more placeholders")
        );
        assert!(
            fmt("{}", &[n(1.0), n(2.0)])
                .unwrap_err()
                .contains("2 value(s) given for 1")
        );
        assert!(fmt("{", &[n(1.0)]).unwrap_err().contains("without its `}`"));
        assert!(fmt("}", &[]).unwrap_err().contains("without its `{`"));
        assert!(
            fmt("{0}", &[n(1.0)])
                .unwrap_err()
                .contains("not a placeholder")
        );
        assert!(
            fmt("{:x}", &[n(1.0)])
                .unwrap_err()
                .contains("not a placeholder")
        );
        assert!(
            fmt("{:04}", &[Value::Num(1.0, Dim::LENGTH)])
                .unwrap_err()
                .contains("plain number")
        );
    }
}
