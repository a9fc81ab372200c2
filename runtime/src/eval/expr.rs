//! Expressions: literals with units, variables, points and lists, fields and indexing, unary
//! and binary operators (`binary`, with dimension arithmetic), and the conversions from a
//! `Value` to what a statement needs (`as_dim`, `as_count`, `as_point`, ...).

use super::{Cx, EvalError, Evaluator, Kind, R, Value, bad, point2, type_err};
use crate::geometry::Profile;
use lase_lang::ast::*;
use lase_lang::units::{self, Dim};
use lase_lang::{STACK_RED_ZONE, STACK_SEGMENT, Span};
use std::rc::Rc;

impl Evaluator {
    pub(super) fn as_bool(&self, v: &Value, span: Span, ctx: &str) -> R<bool> {
        match v {
            Value::Bool(b) => Ok(*b),
            other => Err(type_err("a bool", other, span, ctx)),
        }
    }

    pub(super) fn as_dim(&self, v: &Value, want: Dim, span: Span, ctx: &str) -> R<f64> {
        match v {
            Value::Zero => Ok(0.0),
            Value::Num(x, d) if *d == want => Ok(*x),
            Value::Num(_, d) => Err(EvalError::Type {
                expected: lase_lang::Ty::Num(want).describe(),
                found: lase_lang::Ty::Num(*d).describe(),
                context: ctx.into(),
                span,
                help: Some(format!(
                    "{} is measured in {}",
                    lase_lang::Ty::Num(want).describe(),
                    want.base_unit()
                )),
            }),
            other => Err(type_err(
                &lase_lang::Ty::Num(want).describe(),
                other,
                span,
                ctx,
            )),
        }
    }

    pub(super) fn as_count(&self, v: &Value, span: Span, ctx: &str) -> R<i64> {
        let x = self.as_dim(v, Dim::NONE, span, ctx)?;
        if x.fract() != 0.0 || !x.is_finite() || x.abs() > 1e15 {
            return Err(bad(
                Kind::NotWhole,
                span,
                &format!("{ctx} must be a whole number"),
                "not a whole number",
                None,
            ));
        }
        Ok(x as i64)
    }

    pub(super) fn as_point(&self, v: &Value, span: Span, ctx: &str) -> R<([f64; 3], u8)> {
        match v {
            Value::Point(p, n) => Ok((*p, *n)),
            other => Err(type_err("a point", other, span, ctx)),
        }
    }

    pub(super) fn as_profile(&self, v: &Value, span: Span, ctx: &str) -> R<Rc<Profile>> {
        match v {
            Value::Profile(p) => Ok(p.clone()),
            other => Err(type_err("a profile", other, span, ctx)),
        }
    }

    pub(super) fn expr(&mut self, e: &Expr, cx: &mut Cx) -> R<Value> {
        stacker::maybe_grow(STACK_RED_ZONE, STACK_SEGMENT, || self.expr_here(e, cx))
    }

    pub(super) fn expr_here(&mut self, e: &Expr, cx: &mut Cx) -> R<Value> {
        // Every expression node is a step, so a runaway (an exponential recursion inside one
        // statement) meets the budget as surely as a long loop does.
        self.step(self.at)?;
        match &e.kind {
            ExprKind::Number { value, unit } => match unit {
                None if *value == 0.0 => Ok(Value::Zero),
                None => Ok(Value::Num(*value, Dim::NONE)),
                Some((u, uspan)) => {
                    let unit = units::parse_unit(u).map_err(|_| {
                        bad(
                            Kind::UnknownName,
                            *uspan,
                            "unknown unit",
                            "not a unit",
                            None,
                        )
                    })?;
                    Ok(Value::Num(value * unit.factor, unit.dim))
                }
            },
            ExprKind::Bool(b) => Ok(Value::Bool(*b)),
            ExprKind::Str(s) => Ok(Value::Str(s.as_str().into())),
            ExprKind::Var(name) => self
                .scopes
                .iter()
                .rev()
                .find_map(|s| s.get(name))
                .cloned()
                .ok_or_else(|| {
                    bad(
                        Kind::Undefined,
                        e.span,
                        &format!("`{name}` is not defined here"),
                        "undefined",
                        None,
                    )
                }),
            ExprKind::Point(items) => {
                let mut p = [0.0; 3];
                for (k, it) in items.iter().enumerate().take(3) {
                    let v = self.expr(it, cx)?;
                    p[k] = self.as_dim(&v, Dim::LENGTH, it.span, "a point coordinate")?;
                }
                if items.len() == 2 {
                    p[2] = 0.0;
                }
                super::bounds::point_in_range(Value::Point(p, items.len().min(3) as u8), e.span)
            }
            ExprKind::List(items) => {
                let mut out = Vec::with_capacity(items.len());
                for it in items {
                    out.push(self.expr(it, cx)?);
                }
                Ok(Value::List(Rc::new(out)))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                if matches!(op, BinOp::And | BinOp::Or) {
                    let l = self.expr(lhs, cx)?;
                    let l = self.as_bool(&l, lhs.span, op.symbol())?;
                    if (*op == BinOp::And && !l) || (*op == BinOp::Or && l) {
                        return Ok(Value::Bool(l));
                    }
                    let r = self.expr(rhs, cx)?;
                    return Ok(Value::Bool(self.as_bool(&r, rhs.span, op.symbol())?));
                }
                let l = self.expr(lhs, cx)?;
                let r = self.expr(rhs, cx)?;
                super::bounds::point_in_range(binary(*op, l, r, lhs.span, rhs.span)?, e.span)
            }
            ExprKind::Unary { op, expr } => {
                let v = self.expr(expr, cx)?;
                match (op, v) {
                    (UnOp::Neg, Value::Num(x, d)) => Ok(Value::Num(-x, d)),
                    (UnOp::Neg, Value::Zero) => Ok(Value::Zero),
                    (UnOp::Neg, Value::Point(p, n)) => Ok(Value::Point([-p[0], -p[1], -p[2]], n)),
                    (UnOp::Not, Value::Bool(b)) => Ok(Value::Bool(!b)),
                    (_, other) => Err(type_err(
                        "a number, point or bool",
                        &other,
                        expr.span,
                        "a unary operator",
                    )),
                }
            }
            ExprKind::Field { expr, field } => {
                let v = self.expr(expr, cx)?;
                match (&v, field.name.as_str()) {
                    (Value::Point(p, _), "x") => Ok(Value::Num(p[0], Dim::LENGTH)),
                    (Value::Point(p, _), "y") => Ok(Value::Num(p[1], Dim::LENGTH)),
                    (Value::Point(p, _), "z") => Ok(Value::Num(p[2], Dim::LENGTH)),
                    (Value::Profile(p), "length") => Ok(Value::Num(p.length(), Dim::LENGTH)),
                    (Value::Profile(p), "start") => Ok(point2(p.start())),
                    (Value::Profile(p), "end") => Ok(point2(p.end())),
                    _ => Err(bad(
                        Kind::UnknownName,
                        field.span,
                        &format!("{} has no field `{}`", v.type_name(), field.name),
                        "no such field",
                        None,
                    )),
                }
            }
            ExprKind::Index { expr, index } => {
                let v = self.expr(expr, cx)?;
                let i = self.expr(index, cx)?;
                let i = self.as_count(&i, index.span, "an index")?;
                match v {
                    Value::List(items) => {
                        let len = items.len() as i64;
                        let k = if i < 0 { len + i } else { i };
                        items
                            .get(k as usize)
                            .filter(|_| k >= 0)
                            .cloned()
                            .ok_or_else(|| {
                                bad(
                                    Kind::OutOfRange,
                                    index.span,
                                    &format!("index {i} is out of range for a list of {len}"),
                                    "out of range",
                                    Some("indices run from 0; negative ones count from the end"),
                                )
                            })
                    }
                    // A string's items are its characters (Unicode scalar values), so a
                    // serial number's digits can be taken one by one.
                    Value::Str(text) => {
                        let len = text.chars().count() as i64;
                        let k = if i < 0 { len + i } else { i };
                        text.chars()
                            .nth(k as usize)
                            .filter(|_| k >= 0)
                            .map(|c| Value::Str(c.to_string().into()))
                            .ok_or_else(|| {
                                bad(
                                    Kind::OutOfRange,
                                    index.span,
                                    &format!(
                                        "index {i} is out of range for a string of {len} characters"
                                    ),
                                    "out of range",
                                    Some("indices run from 0; negative ones count from the end"),
                                )
                            })
                    }
                    other => Err(type_err(
                        "a list or a string",
                        &other,
                        expr.span,
                        "indexing",
                    )),
                }
            }
            ExprKind::Call { callee, args } => self.call(callee, args, e.span, cx),
            ExprKind::Comprehension {
                item,
                var,
                iter,
                cond,
            } => {
                let items = self.for_items(iter, "a list comprehension", cx)?;
                let mut out = Vec::new();
                for v in items {
                    self.step(var.span)?;
                    // Each item is a value held at once: the list is bounded before it can
                    // grow past what memory holds (the step budget alone would allow 20 M).
                    if out.len() >= MAX_LIST_ITEMS {
                        return Err(bad(
                            Kind::TooLarge,
                            e.span,
                            &format!("this list would hold more than {MAX_LIST_ITEMS} items"),
                            "too many items",
                            Some("filter earlier, or loop with `for` instead of building a list"),
                        ));
                    }
                    self.scopes.push(std::collections::HashMap::new());
                    self.bind(&var.name, v);
                    let r = self.comprehension_item(item, cond.as_deref(), cx);
                    self.scopes.pop();
                    if let Some(v) = r? {
                        out.push(v);
                    }
                }
                Ok(Value::List(Rc::new(out)))
            }
            ExprKind::Profile { kind, args, flags } => self.profile(kind, args, flags, e.span, cx),
        }
    }
}

impl Evaluator {
    /// One turn of a list comprehension: the item, unless the condition drops it.
    fn comprehension_item(
        &mut self,
        item: &Expr,
        cond: Option<&Expr>,
        cx: &mut Cx,
    ) -> R<Option<Value>> {
        if let Some(c) = cond {
            let keep = self.expr(c, cx)?;
            if !self.as_bool(&keep, c.span, "the condition of a list comprehension")? {
                return Ok(None);
            }
        }
        self.expr(item, cx).map(Some)
    }
}

fn binary(op: BinOp, l: Value, r: Value, ls: Span, rs: Span) -> R<Value> {
    use Value::*;
    let mismatch = |l: &Value, r: &Value| EvalError::Type {
        expected: format!("operands that `{}` accepts", op.symbol()),
        found: format!("{} and {}", l.type_name(), r.type_name()),
        context: format!("`{}`", op.symbol()),
        span: ls.to(rs),
        help: Some("both sides of + and - need one dimension".into()),
    };
    let num = |v: &Value| match v {
        Num(x, d) => Some((*x, Some(*d))),
        Zero => Some((0.0, None)),
        _ => None,
    };
    if let (Some((a, da)), Some((b, db))) = (num(&l), num(&r)) {
        let same = |da: Option<Dim>, db: Option<Dim>| -> Option<Option<Dim>> {
            match (da, db) {
                (Some(x), Some(y)) if x == y => Some(Some(x)),
                (Some(x), None) | (None, Some(x)) => Some(Some(x)),
                (None, None) => Some(None),
                _ => None,
            }
        };
        let mk = |x: f64, d: Option<Dim>| match d {
            Some(d) => Num(x, d),
            None => Zero,
        };
        return match op {
            BinOp::Add | BinOp::Sub | BinOp::Rem => {
                let d = same(da, db).ok_or_else(|| mismatch(&l, &r))?;
                Ok(match op {
                    BinOp::Add => mk(a + b, d),
                    BinOp::Sub => mk(a - b, d),
                    _ => {
                        if b == 0.0 {
                            return Err(bad(
                                Kind::DivisionByZero,
                                rs,
                                "remainder by zero",
                                "zero",
                                None,
                            ));
                        }
                        mk(a % b, d)
                    }
                })
            }
            BinOp::Mul => Ok(match (da, db) {
                (Some(x), Some(y)) => Num(a * b, x * y),
                (Some(x), None) | (None, Some(x)) => Num(0.0, x),
                (None, None) => Zero,
            }),
            BinOp::Div => {
                if b == 0.0 {
                    return Err(division_by_zero(rs));
                }
                Ok(Num(
                    a / b,
                    da.unwrap_or(Dim::NONE) / db.unwrap_or(Dim::NONE),
                ))
            }
            _ => {
                same(da, db).ok_or_else(|| mismatch(&l, &r))?;
                Ok(Bool(match op {
                    BinOp::Eq => a == b,
                    BinOp::Ne => a != b,
                    BinOp::Lt => a < b,
                    BinOp::Le => a <= b,
                    BinOp::Gt => a > b,
                    _ => a >= b,
                }))
            }
        };
    }
    match (op, &l, &r) {
        (BinOp::Add, Point(a, n), Point(b, m)) => {
            Ok(Point([a[0] + b[0], a[1] + b[1], a[2] + b[2]], (*n).max(*m)))
        }
        (BinOp::Sub, Point(a, n), Point(b, m)) => {
            Ok(Point([a[0] - b[0], a[1] - b[1], a[2] - b[2]], (*n).max(*m)))
        }
        (BinOp::Mul, Point(a, n), Num(k, d)) | (BinOp::Mul, Num(k, d), Point(a, n))
            if d.is_none() =>
        {
            Ok(Point([a[0] * k, a[1] * k, a[2] * k], *n))
        }
        (BinOp::Div, Point(a, n), Num(k, d)) if d.is_none() => {
            if *k == 0.0 {
                return Err(division_by_zero(rs));
            }
            Ok(Point([a[0] / k, a[1] / k, a[2] / k], *n))
        }
        (BinOp::Add, Str(a), Str(b)) => Ok(Str(format!("{a}{b}").into())),
        // List concatenation, capped so doubling a list in a loop or recursion cannot exhaust
        // memory before the step budget notices.
        (BinOp::Add, List(a), List(b)) => {
            let n = a.len() + b.len();
            if n > MAX_LIST_ITEMS {
                return Err(EvalError::TooLarge {
                    message: format!(
                        "the concatenated list would hold {} items, above the {} lase handles",
                        lase_lang::units::format_number(n as f64),
                        lase_lang::units::format_number(MAX_LIST_ITEMS as f64)
                    ),
                    span: ls.to(rs),
                    label: "too many items".into(),
                    help: Some("build smaller lists, or split the job into several recipes".into()),
                });
            }
            let mut out = Vec::with_capacity(n);
            out.extend(a.iter().cloned());
            out.extend(b.iter().cloned());
            Ok(List(Rc::new(out)))
        }
        (BinOp::Eq, Bool(a), Bool(b)) => Ok(Bool(a == b)),
        (BinOp::Ne, Bool(a), Bool(b)) => Ok(Bool(a != b)),
        (BinOp::Eq, Str(a), Str(b)) => Ok(Bool(a == b)),
        (BinOp::Ne, Str(a), Str(b)) => Ok(Bool(a != b)),
        _ => Err(mismatch(&l, &r)),
    }
}

/// Items a list made by `+` or by a comprehension may hold (as many as an extension's arrays).
pub(crate) const MAX_LIST_ITEMS: usize = 1_000_000;

/// `x / 0`: the error at the divisor.
fn division_by_zero(divisor: Span) -> EvalError {
    bad(
        Kind::DivisionByZero,
        divisor,
        "division by zero",
        "this is zero",
        None,
    )
}
