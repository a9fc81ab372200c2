//! Expressions: literals and their units, names, fields, lists, and the dimensional
//! analysis of operators (`+` wants equal dimensions, `*` multiplies them).

use super::{Checker, Ty, same_kind};
use crate::ast::*;
use crate::diag::{CheckError, did_you_mean};
use crate::schema;
use crate::units::{self, Dim};
use std::collections::HashMap;

impl Checker {
    pub(super) fn expr(&mut self, e: &Expr) -> Ty {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.expr_here(e)
        })
    }

    fn expr_here(&mut self, e: &Expr) -> Ty {
        match &e.kind {
            ExprKind::Number { value, unit } => {
                if !value.is_finite() {
                    self.err(CheckError::WrongDimension {
                        expected: "a finite number".into(),
                        found: "a number too large to represent".into(),
                        context: "a literal".into(),
                        span: e.span,
                        help: Some("use a unit instead of a huge exponent".into()),
                    });
                    return Ty::Unknown;
                }
                match unit {
                    None if *value == 0.0 => Ty::Zero,
                    None => Ty::Num(Dim::NONE),
                    Some((u, span)) => match units::parse_unit(u) {
                        Ok(unit) => Ty::Num(unit.dim),
                        Err(bad) => {
                            self.err(CheckError::UnknownUnit {
                                unit: bad.atom.clone(),
                                span: *span,
                                help: bad
                                    .suggestion
                                    .map(|s| format!("did you mean `{s}`?"))
                                    .or_else(|| Some(units_help())),
                            });
                            Ty::Unknown
                        }
                    },
                }
            }
            ExprKind::Bool(_) => Ty::Bool,
            ExprKind::Str(_) => Ty::Str,
            ExprKind::Var(name) => match self.lookup(name) {
                Some(t) => t.clone(),
                None => {
                    let help = if self.fns.contains_key(name) || schema::builtin(name).is_some() {
                        Some(format!("`{name}` is a function; call it: `{name}(...)`"))
                    } else if units::parse_unit(name).is_ok() {
                        Some(format!(
                            "`{name}` is a unit; it goes right after a number on the same line: `1 {name}`"
                        ))
                    } else {
                        did_you_mean(name, self.all_names().into_iter())
                    };
                    self.err(CheckError::UnknownName {
                        name: name.clone(),
                        span: e.span,
                        help,
                    });
                    Ty::Unknown
                }
            },
            ExprKind::Point(items) => {
                if !(2..=3).contains(&items.len()) {
                    self.err(CheckError::TypeMismatch {
                        expected: "a point with 2 or 3 coordinates".into(),
                        found: format!("{} coordinates", items.len()),
                        context: "a point".into(),
                        span: e.span,
                        help: None,
                    });
                }
                for it in items {
                    let t = self.expr(it);
                    self.expect_dim(&t, Dim::LENGTH, it, "a point coordinate");
                }
                Ty::Point
            }
            ExprKind::List(items) => {
                let mut elem = Ty::Unknown;
                for it in items {
                    let t = self.expr(it);
                    match (&elem, &t) {
                        (Ty::Unknown, _) => elem = t,
                        (a, b) if same_kind(a, b) => {
                            if *a == Ty::Zero {
                                elem = t
                            }
                        }
                        (_, Ty::Unknown) => {}
                        (a, b) => self.err(CheckError::TypeMismatch {
                            expected: a.describe(),
                            found: b.describe(),
                            context: "a list item".into(),
                            span: it.span,
                            help: Some("all items of a list have one type".into()),
                        }),
                    }
                }
                if elem == Ty::Zero {
                    elem = Ty::Unknown;
                }
                Ty::List(Box::new(elem))
            }
            ExprKind::Binary { op, lhs, rhs } => {
                let l = self.expr(lhs);
                let r = self.expr(rhs);
                self.binary(*op, l, r, lhs, rhs)
            }
            ExprKind::Unary { op, expr } => {
                let t = self.expr(expr);
                match (op, &t) {
                    (UnOp::Neg, Ty::Num(_) | Ty::Zero | Ty::Point | Ty::Unknown) => t,
                    (UnOp::Not, Ty::Bool | Ty::Unknown) => Ty::Bool,
                    (UnOp::Neg, _) => {
                        self.type_err("a number or a point", &t, expr, "`-`");
                        Ty::Unknown
                    }
                    (UnOp::Not, _) => {
                        self.type_err("a bool", &t, expr, "`not`");
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Field { expr, field } => {
                let t = self.expr(expr);
                match (&t, field.name.as_str()) {
                    (Ty::Point | Ty::Unknown, "x" | "y" | "z") => Ty::Num(Dim::LENGTH),
                    (Ty::Profile, "length") => Ty::Num(Dim::LENGTH),
                    (Ty::Profile, "start" | "end") => Ty::Point,
                    (Ty::Unknown, _) => Ty::Unknown,
                    _ => {
                        let fields: &[&str] = match t {
                            Ty::Point => &["x", "y", "z"],
                            Ty::Profile => &["length", "start", "end"],
                            _ => &[],
                        };
                        self.err(CheckError::UnknownName {
                            name: format!(".{}", field.name),
                            span: field.span,
                            help: if fields.is_empty() {
                                Some(format!("{} has no fields", t.describe()))
                            } else {
                                did_you_mean(&field.name, fields.iter().copied()).or_else(|| {
                                    Some(format!("{} has: {}", t.describe(), fields.join(", ")))
                                })
                            },
                        });
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Index { expr, index } => {
                let t = self.expr(expr);
                let i = self.expr(index);
                self.expect_count(&i, index, "an index");
                match t {
                    Ty::List(elem) => *elem,
                    // A string's item is its character at the index, itself a string.
                    Ty::Str => Ty::Str,
                    Ty::Unknown => Ty::Unknown,
                    other => {
                        self.type_err("a list or a string", &other, expr, "indexing");
                        Ty::Unknown
                    }
                }
            }
            ExprKind::Call { callee, args } => self.call(callee, args, e.span),
            ExprKind::Comprehension {
                item,
                var,
                iter,
                cond,
            } => {
                let var_ty = self.for_iter(iter, "a list comprehension");
                self.scopes.push(HashMap::new());
                self.bind(&var.name, var_ty);
                if let Some(c) = cond {
                    let t = self.expr(c);
                    self.expect_ty(&t, &Ty::Bool, c, "the condition of a list comprehension");
                }
                let t = self.expr(item);
                self.scopes.pop();
                Ty::List(Box::new(t))
            }
            ExprKind::Profile { kind, args, flags } => {
                let Some(pk) = schema::profile_kind(&kind.name) else {
                    self.err(CheckError::UnknownName {
                        name: kind.name.clone(),
                        span: kind.span,
                        help: did_you_mean(
                            &kind.name,
                            schema::PROFILE_KINDS.iter().map(|k| k.name),
                        )
                        .or_else(|| {
                            Some(format!(
                                "profiles are: {}",
                                schema::PROFILE_KINDS
                                    .iter()
                                    .filter(|k| !k.unsupported)
                                    .map(|k| k.name)
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            ))
                        }),
                    });
                    for a in args {
                        self.expr(&a.value);
                    }
                    return Ty::Profile;
                };
                if pk.unsupported {
                    self.err(CheckError::Unsupported {
                        what: format!("`profile {}`", pk.name),
                        span: kind.span,
                        help: Some(format!(
                            "{} — not available in this version; use polyline, line, arc, \
                             circle or rect",
                            pk.doc
                        )),
                    });
                    return Ty::Profile;
                }
                let name = format!("profile {}", pk.name);
                self.bind_args(&name, pk.params, args, e.span);
                for f in flags {
                    if !pk.flags.contains(&f.name.as_str()) {
                        self.err(CheckError::UnknownSetting {
                            stmt: name.clone(),
                            key: f.name.clone(),
                            span: f.span,
                            help: Some(if pk.flags.is_empty() {
                                format!("`{name}` takes no flags")
                            } else {
                                format!("`{name}` takes: {}", pk.flags.join(", "))
                            }),
                        });
                    }
                }
                let dir = |n: &str| flags.iter().find(|f| f.name == n);
                if let (Some(cw), Some(ccw)) = (dir("cw"), dir("ccw")) {
                    let (a, b) = if cw.span.start <= ccw.span.start {
                        (cw, ccw)
                    } else {
                        (ccw, cw)
                    };
                    self.err(CheckError::ConflictingFlags {
                        first: a.name.clone(),
                        second: b.name.clone(),
                        first_span: a.span,
                        second_span: b.span,
                    });
                }
                // Text is many strokes or outlines: a list of profiles.
                if pk.name == "text" {
                    Ty::List(Box::new(Ty::Profile))
                } else {
                    Ty::Profile
                }
            }
        }
    }

    /// The type a loop variable takes from what it runs over: a count from a range, an item
    /// from a list (`for` statements and list comprehensions alike).
    pub(super) fn for_iter(&mut self, iter: &ForIter, context: &str) -> Ty {
        match iter {
            ForIter::Range { start, end, .. } => {
                for e in [start, end] {
                    let t = self.expr(e);
                    self.expect_count(&t, e, "a range bound");
                }
                Ty::Num(Dim::NONE)
            }
            ForIter::Expr(e) => match self.expr(e) {
                Ty::List(t) => *t,
                Ty::Unknown => Ty::Unknown,
                other => {
                    self.err(CheckError::TypeMismatch {
                        expected: "a list or a range".into(),
                        found: other.describe(),
                        context: context.into(),
                        span: e.span,
                        help: Some("loop over a list `[a, b]` or a range `0..n`".into()),
                    });
                    Ty::Unknown
                }
            },
        }
    }

    fn type_err(&mut self, expected: &str, found: &Ty, e: &Expr, context: &str) {
        self.err(CheckError::TypeMismatch {
            expected: expected.into(),
            found: found.describe(),
            context: context.into(),
            span: e.span,
            help: None,
        });
    }

    fn binary(&mut self, op: BinOp, l: Ty, r: Ty, lhs: &Expr, rhs: &Expr) -> Ty {
        use Ty::*;
        if l == Unknown || r == Unknown {
            return match op {
                BinOp::Eq
                | BinOp::Ne
                | BinOp::Lt
                | BinOp::Le
                | BinOp::Gt
                | BinOp::Ge
                | BinOp::And
                | BinOp::Or => Bool,
                _ => match (&l, &r) {
                    (Point, _) | (_, Point) if matches!(op, BinOp::Add | BinOp::Sub) => Point,
                    _ => Unknown,
                },
            };
        }
        let mismatch = |s: &mut Self, verb: &'static str| {
            s.err(CheckError::UnitMismatch {
                verb,
                op: op.symbol(),
                left: l.describe(),
                right: r.describe(),
                lhs: lhs.span,
                rhs: rhs.span,
            });
            Unknown
        };
        match op {
            BinOp::Add | BinOp::Sub | BinOp::Rem => {
                let verb = match op {
                    BinOp::Add => "add",
                    BinOp::Sub => "subtract",
                    _ => "take the remainder of",
                };
                match (&l, &r) {
                    (Num(a), Num(b)) if a == b => l.clone(),
                    (Zero, Num(_)) => r.clone(),
                    (Num(_), Zero) | (Zero, Zero) => l.clone(),
                    (Point, Point) if op != BinOp::Rem => Point,
                    (Str, Str) if op == BinOp::Add => Str,
                    // `+` on two lists concatenates them; their items must be of one kind.
                    (List(a), List(b)) if op == BinOp::Add => match (&**a, &**b) {
                        (Unknown, _) => r.clone(),
                        (_, Unknown) => l.clone(),
                        (a, b) if same_kind(a, b) => l.clone(),
                        _ => mismatch(self, "concatenate"),
                    },
                    _ => mismatch(self, verb),
                }
            }
            BinOp::Mul => match (&l, &r) {
                (Num(a), Num(b)) => Num(*a * *b),
                (Zero, Num(_)) => r.clone(),
                (Num(_), Zero) | (Zero, Zero) => l.clone(),
                (Point, Num(d)) | (Num(d), Point) if d.is_none() => Point,
                (Point, Zero) | (Zero, Point) => Point,
                _ => mismatch(self, "multiply"),
            },
            BinOp::Div => match (&l, &r) {
                (Num(a), Num(b)) => Num(*a / *b),
                (Zero, Num(b)) => Num(Dim::NONE / *b),
                (_, Zero) => {
                    self.err(CheckError::WrongDimension {
                        expected: "a non-zero divisor".into(),
                        found: "zero".into(),
                        context: "`/`".into(),
                        span: rhs.span,
                        help: Some("division by zero".into()),
                    });
                    Unknown
                }
                (Point, Num(d)) if d.is_none() => Point,
                _ => mismatch(self, "divide"),
            },
            BinOp::Eq | BinOp::Ne => {
                if !same_kind(&l, &r) {
                    mismatch(self, "compare");
                }
                Bool
            }
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                match (&l, &r) {
                    (Num(a), Num(b)) if a == b => {}
                    (Zero, Num(_)) | (Num(_), Zero) | (Zero, Zero) => {}
                    _ => {
                        mismatch(self, "compare");
                    }
                }
                Bool
            }
            BinOp::And | BinOp::Or => {
                if l != Bool {
                    self.type_err("a bool", &l, lhs, &format!("`{}`", op.symbol()));
                }
                if r != Bool {
                    self.type_err("a bool", &r, rhs, &format!("`{}`", op.symbol()));
                }
                Bool
            }
        }
    }
}

fn units_help() -> String {
    "units: mm um cm m in · s ms us ns min · deg rad rev · W kW · Hz kHz MHz · J mJ uJ, \
     combined with / and ^ (mm/s, m/s^2)"
        .into()
}
