//! Expectations: a found type compared with the one a context wants, and diagnostics that
//! say how to fix a mismatch (a bare number gets the unit it most likely lacks).

use super::{Checker, Ty};
use crate::ast::*;
use crate::diag::CheckError;
use crate::schema::PTy;
use crate::units::{self, Dim};

impl Checker {
    fn bare_number_help(e: &Expr, want: Dim) -> Option<String> {
        let unit = match want {
            d if d == Dim::LENGTH => "mm",
            d if d == Dim::SPEED => "mm/s",
            d if d == Dim::TIME => "s",
            d if d == Dim::ANGLE => "deg",
            d if d == Dim::POWER => "W",
            d if d == Dim::ACCEL => "mm/s^2",
            d if d == Dim::JERK => "mm/s^3",
            d if d == Dim::FREQUENCY => "kHz",
            d if d == Dim::ENERGY => "mJ",
            _ => return None,
        };
        match &e.kind {
            ExprKind::Number { value, unit: None } => Some(format!(
                "a bare number has no unit; write `{} {unit}`",
                units::format_number(*value)
            )),
            _ => Some(format!("give it a unit, e.g. multiply by `1 {unit}`")),
        }
    }

    pub(super) fn expect_dim(&mut self, t: &Ty, want: Dim, e: &Expr, context: &str) {
        match t {
            Ty::Num(d) if *d == want => {}
            Ty::Zero | Ty::Unknown => {}
            Ty::Num(d) => self.err(CheckError::WrongDimension {
                expected: Ty::Num(want).describe(),
                found: t.describe(),
                context: context.into(),
                span: e.span,
                help: if d.is_none() {
                    Self::bare_number_help(e, want)
                } else {
                    Some(format!(
                        "{} is measured in {}; this is in {}",
                        Ty::Num(want).describe(),
                        want.base_unit(),
                        d.base_unit()
                    ))
                },
            }),
            other => self.err(CheckError::TypeMismatch {
                expected: Ty::Num(want).describe(),
                found: other.describe(),
                context: context.into(),
                span: e.span,
                help: None,
            }),
        }
    }

    pub(super) fn expect_count(&mut self, t: &Ty, e: &Expr, context: &str) {
        self.expect_dim(t, Dim::NONE, e, context);
    }

    pub(super) fn expect_ty(&mut self, t: &Ty, want: &Ty, e: &Expr, context: &str) {
        match (t, want) {
            (_, Ty::Unknown) | (Ty::Unknown, _) => {}
            (_, Ty::Num(d)) => self.expect_dim(t, *d, e, context),
            (Ty::List(_), Ty::List(w)) if **w == Ty::Unknown => {}
            (a, b) if a == b => {}
            (a, b) => {
                let help = match (a, b) {
                    (Ty::Point, Ty::Profile) => Some(
                        "a point is not a path; make one with `profile line(a, b)` or \
                         `profile polyline [...]`"
                            .to_string(),
                    ),
                    (Ty::List(_), Ty::Point) => {
                        Some("a point is written with parentheses: `(x, y)`".to_string())
                    }
                    _ => None,
                };
                self.err(CheckError::TypeMismatch {
                    expected: b.describe(),
                    found: a.describe(),
                    context: context.into(),
                    span: e.span,
                    help,
                })
            }
        }
    }

    pub(super) fn expect_param(&mut self, t: &Ty, ty: PTy, e: &Expr, context: &str) {
        match ty {
            PTy::Dim(d) => self.expect_dim(t, d, e, context),
            PTy::Either(a, b) => match t {
                Ty::Num(d) if *d == a || *d == b => {}
                Ty::Zero | Ty::Unknown => {}
                _ => self.err(CheckError::WrongDimension {
                    expected: ty.describe(),
                    found: t.describe(),
                    context: context.into(),
                    span: e.span,
                    help: match t {
                        Ty::Num(d) if d.is_none() => Self::bare_number_help(e, a),
                        _ => None,
                    },
                }),
            },
            PTy::AnyNum => {
                if !t.is_numeric() {
                    self.err(CheckError::TypeMismatch {
                        expected: "a number".into(),
                        found: t.describe(),
                        context: context.into(),
                        span: e.span,
                        help: None,
                    })
                }
            }
            PTy::Point => self.expect_ty(t, &Ty::Point, e, context),
            PTy::Profile => self.expect_ty(t, &Ty::Profile, e, context),
            PTy::Points => self.expect_ty(t, &Ty::List(Box::new(Ty::Point)), e, context),
            PTy::List => self.expect_ty(t, &Ty::List(Box::new(Ty::Unknown)), e, context),
            PTy::ListOrStr => {
                if !matches!(t, Ty::List(_) | Ty::Str | Ty::Unknown) {
                    self.err(CheckError::TypeMismatch {
                        expected: ty.describe(),
                        found: t.describe(),
                        context: context.into(),
                        span: e.span,
                        help: None,
                    })
                }
            }
            PTy::Any => {}
            PTy::Bool => self.expect_ty(t, &Ty::Bool, e, context),
            PTy::Str => self.expect_ty(t, &Ty::Str, e, context),
            PTy::Word(_) | PTy::Flag => {}
        }
    }
}
