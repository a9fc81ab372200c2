//! Calls: user functions bound by position or name against their annotated parameters, and
//! builtins and profile constructors bound against the schema's parameter tables.

use super::{Checker, Ty, same_kind};
use crate::ast::*;
use crate::diag::{CheckError, did_you_mean};
use crate::schema::{self, ParamSpec, Ret};
use crate::span::Span;
use crate::units::Dim;

impl Checker {
    pub(super) fn call(&mut self, callee: &Ident, args: &[Arg], span: Span) -> Ty {
        if let Some(sig) = self.fns.get(&callee.name).cloned() {
            // User functions: bind by position or name, check annotated parameters.
            let mut bound: Vec<Option<Ty>> = vec![None; sig.params.len()];
            let mut positional = 0;
            for a in args {
                let t = self.expr(&a.value);
                let idx = match &a.name {
                    Some(n) => match sig.params.iter().position(|(p, _)| *p == n.name) {
                        Some(i) => i,
                        None => {
                            self.err(CheckError::UnknownArg {
                                name: callee.name.clone(),
                                arg: n.name.clone(),
                                span: n.span,
                                help: did_you_mean(
                                    &n.name,
                                    sig.params.iter().map(|(p, _)| p.as_str()),
                                ),
                            });
                            continue;
                        }
                    },
                    None => {
                        positional += 1;
                        positional - 1
                    }
                };
                if idx >= sig.params.len() {
                    continue;
                }
                let want = sig.params[idx].1.clone();
                self.expect_ty(
                    &t,
                    &want,
                    &a.value,
                    &format!("parameter `{}` of `{}`", sig.params[idx].0, callee.name),
                );
                bound[idx] = Some(t);
            }
            let missing: Vec<&str> = sig
                .params
                .iter()
                .zip(&bound)
                .filter(|(_, b)| b.is_none())
                .map(|((n, _), _)| n.as_str())
                .collect();
            if args.len() > sig.params.len() || !missing.is_empty() {
                self.err(CheckError::ArgCount {
                    name: callee.name.clone(),
                    expected: sig.params.len().to_string(),
                    found: args.len(),
                    span,
                    help: Some(format!(
                        "`{}({})`",
                        callee.name,
                        sig.params
                            .iter()
                            .map(|(n, _)| n.as_str())
                            .collect::<Vec<_>>()
                            .join(", ")
                    )),
                });
            }
            return sig.ret.clone();
        }
        let Some(b) = schema::builtin(&callee.name) else {
            self.err(CheckError::UnknownName {
                name: callee.name.clone(),
                span: callee.span,
                help: did_you_mean(&callee.name, self.all_names().into_iter()),
            });
            for a in args {
                self.expr(&a.value);
            }
            return Ty::Unknown;
        };
        let tys = self.bind_args(b.name, b.params, args, span);
        let first = tys.first().cloned().flatten().unwrap_or(Ty::Unknown);
        // Two-operand numeric builtins need operands of one dimension.
        if matches!(b.name, "min" | "max" | "atan2")
            && let (Some(Some(x)), Some(Some(y))) = (tys.first(), tys.get(1))
            && !same_kind(x, y)
        {
            self.err(CheckError::UnitMismatch {
                verb: "compare",
                op: ",",
                left: x.describe(),
                right: y.describe(),
                lhs: args[0].value.span,
                rhs: args[1].value.span,
            });
        }
        match b.ret {
            Ret::Dim(d) => Ty::Num(d),
            Ret::Point => Ty::Point,
            Ret::Profile => Ty::Profile,
            Ret::Points => Ty::List(Box::new(Ty::Point)),
            Ret::Str => Ty::Str,
            Ret::Profiles => Ty::List(Box::new(Ty::Profile)),
            Ret::SameAsFirst => match (first, tys.get(1).cloned().flatten()) {
                (Ty::Zero, Some(t)) => t,
                (t, _) => t,
            },
            Ret::SqrtOfFirst => match first {
                Ty::Num(d) => {
                    let even = d.length % 2 == 0
                        && d.time % 2 == 0
                        && d.angle % 2 == 0
                        && d.power % 2 == 0;
                    if even {
                        Ty::Num(Dim::new(d.length / 2, d.time / 2, d.angle / 2, d.power / 2))
                    } else {
                        self.err(CheckError::WrongDimension {
                            expected: "a quantity with even unit powers".into(),
                            found: Ty::Num(d).describe(),
                            context: "`sqrt`".into(),
                            span: args[0].value.span,
                            help: Some("sqrt of mm^2 is mm; sqrt of mm has no unit".into()),
                        });
                        Ty::Unknown
                    }
                }
                t => t,
            },
        }
    }

    /// Binds call arguments to a builtin's parameters by position or name, checks each, and
    /// returns the bound argument types in parameter order.
    pub(super) fn bind_args(
        &mut self,
        name: &str,
        params: &[ParamSpec],
        args: &[Arg],
        span: Span,
    ) -> Vec<Option<Ty>> {
        let mut bound: Vec<Option<Ty>> = vec![None; params.len()];
        let mut positional = 0;
        let mut too_many = false;
        for a in args {
            let t = self.expr(&a.value);
            let idx = match &a.name {
                Some(n) => match params.iter().position(|p| p.name == n.name) {
                    Some(i) => i,
                    None => {
                        self.err(CheckError::UnknownArg {
                            name: name.into(),
                            arg: n.name.clone(),
                            span: n.span,
                            help: did_you_mean(&n.name, params.iter().map(|p| p.name)).or_else(
                                || {
                                    Some(format!(
                                        "`{name}` takes: {}",
                                        params
                                            .iter()
                                            .map(|p| p.name)
                                            .collect::<Vec<_>>()
                                            .join(", ")
                                    ))
                                },
                            ),
                        });
                        continue;
                    }
                },
                None => {
                    positional += 1;
                    positional - 1
                }
            };
            // A variadic builtin's last parameter takes the rest of the positional arguments.
            let idx = if idx >= params.len() && a.name.is_none() && schema::VARIADIC.contains(&name)
            {
                params.len() - 1
            } else {
                idx
            };
            if idx >= params.len() {
                too_many = true;
                continue;
            }
            let p = params[idx];
            self.expect_param(&t, p.ty, &a.value, &format!("`{}` of `{name}`", p.name));
            bound[idx] = Some(t);
        }
        let signature = || {
            format!(
                "`{name}({})`",
                params
                    .iter()
                    .map(|p| if p.required {
                        format!("{}: {}", p.name, p.ty.describe())
                    } else {
                        format!("{}: {} (optional)", p.name, p.ty.describe())
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        if too_many {
            let req = params.iter().filter(|p| p.required).count();
            self.err(CheckError::ArgCount {
                name: name.into(),
                expected: if req == params.len() {
                    req.to_string()
                } else {
                    format!("{req} to {}", params.len())
                },
                found: args.len(),
                span,
                help: Some(signature()),
            });
        } else {
            for (p, b) in params.iter().zip(&bound) {
                if p.required && b.is_none() {
                    self.err(CheckError::MissingArg {
                        name: name.into(),
                        arg: p.name.into(),
                        span,
                        help: Some(signature()),
                    });
                }
            }
        }
        bound
    }
}
