//! Calls: argument binding (positional, then by name), recipe functions (their own scope,
//! the call-depth limit, type annotations checked), Rhai extension functions, and the
//! builtins of `schema::BUILTINS` (profile transforms, queries, math).

use super::{
    Cx, EvalError, Evaluator, Flow, Kind, MAX_DEPTH, R, Value, bad, geom_error, point2, type_err,
};
use crate::geometry::{GeomError, Profile, V2};
use lase_lang::ast::*;
use lase_lang::units::{self, Dim};
use lase_lang::{Span, schema};
use std::collections::HashMap;
use std::rc::Rc;

impl Evaluator {
    /// Binds arguments to named parameters (positional first, then by name).
    pub(super) fn bind_args(
        &mut self,
        names: &[&str],
        args: &[Arg],
        cx: &mut Cx,
    ) -> R<Vec<Option<(Value, Span)>>> {
        let mut out: Vec<Option<(Value, Span)>> = vec![None; names.len()];
        let mut pos = 0;
        for a in args {
            let v = self.expr(&a.value, cx)?;
            let idx = match &a.name {
                Some(n) => names.iter().position(|p| *p == n.name),
                None => {
                    pos += 1;
                    Some(pos - 1)
                }
            };
            if let Some(i) = idx.filter(|i| *i < names.len()) {
                out[i] = Some((v, a.value.span));
            }
        }
        Ok(out)
    }

    pub(super) fn call(
        &mut self,
        callee: &Ident,
        args: &[Arg],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        if let Some(f) = self.fns.get(&callee.name).cloned() {
            let names: Vec<&str> = f.params.iter().map(|p| p.name.name.as_str()).collect();
            let bound = self.bind_args(&names, args, cx)?;
            if self.depth >= MAX_DEPTH {
                return Err(EvalError::Budget {
                    message: format!("functions nest more than {MAX_DEPTH} calls deep"),
                    span,
                    help: Some("a recursive function never reaches its base case".into()),
                });
            }
            let mut scope = HashMap::new();
            for (p, b) in f.params.iter().zip(bound) {
                let (v, vspan) = b.ok_or_else(|| {
                    bad(
                        Kind::MissingArgument,
                        span,
                        &format!("missing argument `{}`", p.name.name),
                        "in this call",
                        None,
                    )
                })?;
                if let Some(ty) = &p.ty {
                    self.check_annotation(
                        &v,
                        &ty.name,
                        vspan,
                        &format!("parameter `{}`", p.name.name),
                    )?;
                }
                scope.insert(p.name.name.clone(), v);
            }
            // A function sees the recipe's globals and its parameters, not its caller's locals.
            let saved = self.scopes.split_off(1);
            self.scopes.push(scope);
            self.depth += 1;
            let r = self.block(&f.body, cx);
            self.depth -= 1;
            self.scopes.truncate(1);
            self.scopes.extend(saved);
            let v = match r? {
                Flow::Return(v) => v,
                Flow::Normal => Value::Nothing,
            };
            if let Some(ty) = &f.ret {
                self.check_annotation(
                    &v,
                    &ty.name,
                    span,
                    &format!("the result of `{}`", callee.name),
                )?;
            }
            return Ok(v);
        }
        if let Some(sig) = self.ext.lookup(&callee.name) {
            // A Rhai extension function: bound like a recipe `fn`, converted and run by `ext`.
            let names: Vec<String> = sig.params.iter().map(|(n, _)| n.clone()).collect();
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let bound = self.bind_args(&names, args, cx)?;
            let mut values = Vec::with_capacity(bound.len());
            for (n, b) in names.iter().zip(bound) {
                values.push(b.ok_or_else(|| {
                    bad(
                        Kind::MissingArgument,
                        span,
                        &format!("missing argument `{n}`"),
                        "in this call",
                        None,
                    )
                })?);
            }
            return Ok(self.ext.call(&callee.name, &values, span)?);
        }
        let Some(b) = schema::builtin(&callee.name) else {
            return Err(bad(
                Kind::Undefined,
                callee.span,
                &format!("unknown function `{}`", callee.name),
                "unknown",
                None,
            ));
        };
        if b.name == "format" {
            return self.format_call(args, span, cx);
        }
        let names: Vec<&str> = b.params.iter().map(|p| p.name).collect();
        let a = self.bind_args(&names, args, cx)?;
        if matches!(b.name, "qr" | "qr_dots" | "datamatrix" | "datamatrix_dots") {
            return self.code_call(b.name, &a, span);
        }
        let arg = |i: usize| {
            a.get(i).cloned().flatten().ok_or_else(|| {
                bad(
                    Kind::MissingArgument,
                    span,
                    &format!("missing argument `{}`", names[i]),
                    "in this call",
                    None,
                )
            })
        };
        let num = |_: &Self, i: usize| -> R<(f64, Dim, Span)> {
            let (v, sp) = arg(i)?;
            match v {
                Value::Num(x, d) => Ok((x, d, sp)),
                Value::Zero => Ok((0.0, Dim::NONE, sp)),
                other => Err(type_err(
                    "a number",
                    &other,
                    sp,
                    &format!("`{}`", callee.name),
                )),
            }
        };
        let prof = |s: &Self, i: usize| -> R<Rc<Profile>> {
            let (v, sp) = arg(i)?;
            s.as_profile(&v, sp, &format!("`{}`", callee.name))
        };
        let len = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = arg(i)?;
            s.as_dim(&v, Dim::LENGTH, sp, &format!("`{}`", names[i]))
        };
        let ang = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = arg(i)?;
            s.as_dim(&v, Dim::ANGLE, sp, &format!("`{}`", names[i]))
        };
        let pt = |s: &Self, i: usize| -> R<[f64; 3]> {
            let (v, sp) = arg(i)?;
            Ok(s.as_point(&v, sp, &format!("`{}`", names[i]))?.0)
        };
        Ok(match b.name {
            "offset" => {
                let p = prof(self, 0)?;
                let d = len(self, 1)?;
                let trim = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_bool(&v, sp, "`trim`")?,
                    None => false,
                };
                let opts = crate::geometry::offset::OffsetOptions {
                    trim,
                    tol_mm: self.planner_settings_now().arc_tolerance_mm,
                };
                let o = p.offset_with(d, &opts).map_err(|g| {
                    // A fold-over is a property of the profile: point at it.
                    let at = match g {
                        GeomError::FoldOver { .. } | GeomError::Crosses { .. } => {
                            a.first().cloned().flatten().map_or(span, |x| x.1)
                        }
                        _ => span,
                    };
                    geom_error(g, at, Some(d))
                })?;
                Value::Profile(Rc::new(o))
            }
            "reverse" => Value::Profile(Rc::new(prof(self, 0)?.reversed())),
            "translate" => {
                let p = prof(self, 0)?;
                let v = pt(self, 1)?;
                Value::Profile(Rc::new(p.transformed(0.0, V2::new(v[0], v[1]))))
            }
            "rotate" => {
                let p = prof(self, 0)?;
                let angle = ang(self, 1)?;
                let c = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_point(&v, sp, "`about`")?.0,
                    None => [0.0; 3],
                };
                // Turning about c is turning about the origin, then shifting c back onto itself.
                let cv = V2::new(c[0], c[1]);
                let rot = nalgebra::Rotation2::new(angle);
                Value::Profile(Rc::new(p.transformed(angle, cv - rot * cv)))
            }
            "length" => Value::Num(prof(self, 0)?.length(), Dim::LENGTH),
            "start" => point2(prof(self, 0)?.start()),
            "end" => point2(prof(self, 0)?.end()),
            "point_at" => {
                let p = prof(self, 0)?;
                let s = len(self, 1)?;
                // Beyond either end there is no point on the profile; clamping to the end would
                // hand back a point the recipe did not ask for. The slack forgives rounding in
                // an `s` computed as `length(p)` or a sum of pieces.
                let total = p.length();
                let slack = 1e-9 * total.max(1.0);
                if !(s >= -slack && s <= total + slack) {
                    let at = a.get(1).cloned().flatten().map_or(span, |x| x.1);
                    return Err(bad(
                        Kind::OutOfRange,
                        at,
                        &format!(
                            "s = {} is outside the profile, which runs from 0 to {}",
                            units::format_quantity(s, Dim::LENGTH),
                            units::format_quantity(total, Dim::LENGTH)
                        ),
                        "beyond the profile",
                        Some("`point_at(p, s)` takes s from 0 to `length(p)`"),
                    ));
                }
                point2(p.point_at(s.clamp(0.0, total)))
            }
            "polar" => {
                let r = len(self, 0)?;
                let a = ang(self, 1)?;
                Value::Point([r * a.cos(), r * a.sin(), 0.0], 2)
            }
            "distance" => {
                let p = pt(self, 0)?;
                let q = pt(self, 1)?;
                Value::Num(
                    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt(),
                    Dim::LENGTH,
                )
            }
            "sqrt" => {
                let (x, d, sp) = num(self, 0)?;
                if x < 0.0 {
                    return Err(bad(
                        Kind::Negative,
                        sp,
                        "square root of a negative number",
                        "negative",
                        None,
                    ));
                }
                if [d.length, d.time, d.angle, d.power]
                    .iter()
                    .any(|e| e % 2 != 0)
                {
                    return Err(bad(
                        Kind::Dimension,
                        sp,
                        "sqrt needs even unit powers",
                        "odd unit power",
                        None,
                    ));
                }
                Value::Num(
                    x.sqrt(),
                    Dim::new(d.length / 2, d.time / 2, d.angle / 2, d.power / 2),
                )
            }
            "abs" => {
                let (x, d, _) = num(self, 0)?;
                Value::Num(x.abs(), d)
            }
            "min" | "max" => {
                let (x, dx, _) = num(self, 0)?;
                let (y, dy, sy) = num(self, 1)?;
                let d = if a_is_zero(&a, 0) { dy } else { dx };
                if dx != dy && !a_is_zero(&a, 0) && !a_is_zero(&a, 1) {
                    return Err(bad(
                        Kind::Dimension,
                        sy,
                        "both operands need one dimension",
                        "different dimension",
                        None,
                    ));
                }
                Value::Num(if b.name == "min" { x.min(y) } else { x.max(y) }, d)
            }
            "sin" => Value::Num(ang(self, 0)?.sin(), Dim::NONE),
            "cos" => Value::Num(ang(self, 0)?.cos(), Dim::NONE),
            "tan" => Value::Num(ang(self, 0)?.tan(), Dim::NONE),
            "atan2" => {
                let (y, _, _) = num(self, 0)?;
                let (x, _, _) = num(self, 1)?;
                Value::Num(y.atan2(x), Dim::ANGLE)
            }
            "floor" | "ceil" | "round" => {
                let (x, d, sp) = num(self, 0)?;
                if !d.is_none() {
                    return Err(bad(
                        Kind::Dimension,
                        sp,
                        "rounding needs a plain number",
                        "has a unit",
                        Some("divide by a unit first: `round(x / 1 mm)`"),
                    ));
                }
                Value::Num(
                    match b.name {
                        "floor" => x.floor(),
                        "ceil" => x.ceil(),
                        _ => x.round(),
                    },
                    Dim::NONE,
                )
            }
            "len" => {
                let (v, sp) = arg(0)?;
                match v {
                    Value::List(items) => Value::Num(items.len() as f64, Dim::NONE),
                    Value::Str(s) => Value::Num(s.chars().count() as f64, Dim::NONE),
                    other => return Err(type_err("a list or a string", &other, sp, "`len`")),
                }
            }
            other => {
                return Err(bad(
                    Kind::Undefined,
                    callee.span,
                    &format!("`{other}` is not available"),
                    "not available",
                    None,
                ));
            }
        })
    }

    pub(super) fn check_annotation(&self, v: &Value, ty: &str, span: Span, ctx: &str) -> R<()> {
        let ok = match (ty, v) {
            ("bool", Value::Bool(_))
            | ("string", Value::Str(_))
            | ("point", Value::Point(..))
            | ("profile", Value::Profile(_))
            | ("list", Value::List(_)) => true,
            (_, Value::Zero) => units::dim_by_name(ty).is_some(),
            (t, Value::Num(_, d)) => units::dim_by_name(t) == Some(*d),
            _ => false,
        };
        if ok {
            Ok(())
        } else {
            Err(EvalError::Type {
                expected: ty.to_string(),
                found: v.type_name(),
                context: ctx.into(),
                span,
                help: None,
            })
        }
    }
}

fn a_is_zero(a: &[Option<(Value, Span)>], i: usize) -> bool {
    matches!(a.get(i), Some(Some((Value::Zero, _))))
}
