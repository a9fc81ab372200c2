//! Statements: blocks and scopes, control flow (`if`, `for`, `return`), `let` and `fn`,
//! `import`, the step budget, and `push`, the one place an op is appended (it moves the spot
//! and keeps the beam orientation). Each statement kind that sets the process sheet or moves
//! the head hands over to `sheet.rs` or `moves.rs`.

use super::{
    Cx, EvalError, Evaluator, Flow, Kind, MAX_OPS, R, STEP_BUDGET, Value, bad, no_machine, type_err,
};
use crate::machine::Machine;
use crate::program::*;
use lase_lang::ast::*;
use lase_lang::diag::did_you_mean;
use lase_lang::units::{self, Dim};
use lase_lang::{Resolved, STACK_RED_ZONE, STACK_SEGMENT, Span};
use std::collections::HashMap;

impl Evaluator {
    pub(super) fn hoist(&mut self, stmts: &[Stmt]) {
        for s in stmts {
            if let StmtKind::Fn(f) = &s.kind {
                self.fns.insert(f.name.name.clone(), f.clone());
            }
        }
    }

    /// One statement: a step, and the op count held to its budget (a statement is where ops
    /// are made, so an overrun points at the one that made too many).
    pub(super) fn tick(&mut self, span: Span) -> R<()> {
        self.step(span)?;
        if self.ops.len() > MAX_OPS {
            return Err(EvalError::Budget {
                message: format!(
                    "the program holds more than {} moves and machine events",
                    units::format_number(MAX_OPS as f64)
                ),
                span,
                help: Some(
                    "a loop produces far more motion than a job needs; check its range (a job \
                     this size, if meant, belongs in several recipes)"
                        .into(),
                ),
            });
        }
        Ok(())
    }

    /// One evaluation step (a statement, an expression node, a loop turn), held to the budget.
    pub(super) fn step(&mut self, span: Span) -> R<()> {
        self.steps += 1;
        if self.steps > STEP_BUDGET {
            return Err(EvalError::Budget {
                message: format!(
                    "the recipe ran more than {} evaluation steps",
                    units::format_number(STEP_BUDGET as f64)
                ),
                span,
                help: Some(
                    "a loop runs far longer than intended, or a function calls itself more \
                     than once per call (its work doubles with each level); check the range or \
                     the recursion"
                        .into(),
                ),
            });
        }
        Ok(())
    }

    pub(super) fn block(&mut self, stmts: &[Stmt], cx: &mut Cx) -> R<Flow> {
        self.scopes.push(HashMap::new());
        self.hoist(stmts);
        let mut flow = Flow::Normal;
        for s in stmts {
            match self.stmt(s, cx) {
                Ok(Flow::Normal) => {}
                Ok(f @ Flow::Return(_)) => {
                    flow = f;
                    break;
                }
                Err(e) => {
                    self.scopes.pop();
                    return Err(e);
                }
            }
        }
        self.scopes.pop();
        Ok(flow)
    }

    pub(super) fn bind(&mut self, name: &str, v: Value) {
        self.scopes
            .last_mut()
            .expect("there is always a scope")
            .insert(name.to_string(), v);
    }

    pub(super) fn need_machine(&self, span: Span) -> R<&Machine> {
        self.machine.as_ref().ok_or_else(|| no_machine(span))
    }

    /// Statements and expressions recurse (a function calling itself up to `MAX_DEPTH`,
    /// nested blocks and expressions): near the end of the stack, it continues on a new
    /// segment, so no recipe overflows it, however its frames are sized (a debug build's are
    /// large).
    pub(super) fn stmt(&mut self, s: &Stmt, cx: &mut Cx) -> R<Flow> {
        // An expression's steps are charged to the innermost statement running it, the one a
        // budget overrun points at; a call returns to its caller's statement.
        let outer = std::mem::replace(&mut self.at, s.span);
        let r = stacker::maybe_grow(STACK_RED_ZONE, STACK_SEGMENT, || self.stmt_here(s, cx));
        self.at = outer;
        r
    }

    pub(super) fn stmt_here(&mut self, s: &Stmt, cx: &mut Cx) -> R<Flow> {
        self.tick(s.span)?;
        match &s.kind {
            StmtKind::Machine(m) => self.select_machine(m, s.span, cx)?,
            StmtKind::Limits(groups) => self.set_limits(groups, cx)?,
            StmtKind::Let { name, value, .. } => {
                let v = self.expr(value, cx)?;
                self.bind(&name.name, v);
            }
            StmtKind::Fn(f) => {
                self.fns.insert(f.name.name.clone(), f.clone());
            }
            StmtKind::Import(path) => self.import(path, cx)?,
            StmtKind::Use(path) => {
                for (name, v) in self.ext.activate(path)? {
                    self.bind(&name, v);
                }
            }
            StmtKind::Scan {
                kind,
                region,
                settings,
            } => self.scan(kind, region, settings, s.span, cx)?,
            StmtKind::If { cond, then, els } => {
                let c = self.expr(cond, cx)?;
                let c = self.as_bool(&c, cond.span, "the condition of `if`")?;
                if c {
                    return self.block(then, cx);
                } else if let Some(e) = els {
                    return self.block(e, cx);
                }
            }
            StmtKind::For { var, iter, body } => return self.for_loop(var, iter, body, cx),
            StmtKind::Return(e) => {
                let v = match e {
                    Some(e) => self.expr(e, cx)?,
                    None => Value::Nothing,
                };
                return Ok(Flow::Return(v));
            }
            StmtKind::Laser(l) => match l {
                LaserStmt::On => self.laser.on = true,
                LaserStmt::Off => self.laser.on = false,
                LaserStmt::Settings(set) => {
                    let ls = self.laser_settings(set, cx)?;
                    if let Some(p) = ls.power {
                        if let (Some(pulse), Some(e)) = (
                            &self.pulse,
                            set.iter()
                                .find(|s| s.key.name == "power")
                                .and_then(|s| s.value.as_ref()),
                        ) {
                            super::sheet::pulse_energy_agrees(p, pulse, e.span, "this power")?;
                        }
                        self.laser.power_w = Some(p);
                    }
                    if let Some(d) = ls.spot {
                        self.laser.spot_mm = d;
                    }
                    if let Some(c) = ls.couple {
                        self.laser.couple = c;
                    }
                    if let Some(d) = ls.standoff {
                        self.laser.standoff_mm = Some(d);
                    }
                    if let Some(k) = ls.kerf {
                        self.laser.kerf_mm = k;
                    }
                }
            },
            StmtKind::Pulse(PulseStmt::Off) => self.pulse = None,
            StmtKind::Pulse(PulseStmt::Settings(set)) => self.pulse_settings(set, cx)?,
            StmtKind::Planner(set) => self.planner_settings(set, s.span, cx)?,
            StmtKind::Rotary(set) => self.rotary_settings(set, s.span, cx)?,
            StmtKind::Move {
                kind,
                target,
                speed,
            } => self.move_stmt(*kind, target, speed, s.span, cx)?,
            StmtKind::Follow {
                path,
                speed,
                settings,
            } => self.follow(path, speed, settings, s.span, cx)?,
            StmtKind::Dwell(e) => {
                let v = self.expr(e, cx)?;
                let t = self.as_dim(&v, Dim::TIME, e.span, "`dwell`")?;
                if t < 0.0 {
                    return Err(bad(
                        Kind::Negative,
                        e.span,
                        "a dwell cannot be negative",
                        "negative",
                        None,
                    ));
                }
                if t > 0.0 {
                    self.in_range(t, &super::bounds::DWELL, "the dwell", e.span)?;
                }
                self.need_machine(s.span)?;
                self.push(OpKind::Dwell { seconds: t }, s.span);
            }
            StmtKind::MCode { code, comment } => {
                let v = self.expr(code, cx)?;
                let c = self.as_count(&v, code.span, "an M-code")?;
                if !(0..1000).contains(&c) {
                    return Err(bad(
                        Kind::OutOfRange,
                        code.span,
                        "M-codes run from 0 to 999",
                        "out of range",
                        None,
                    ));
                }
                self.need_machine(s.span)?;
                self.push(
                    OpKind::MCode {
                        code: c as u32,
                        comment: comment.as_ref().map(|c| c.value.clone()),
                    },
                    s.span,
                );
            }
            StmtKind::Event(name) => {
                let m = self.need_machine(s.span)?;
                if !m.events.contains_key(&name.name) {
                    let machine = m.name.clone();
                    let help = did_you_mean(&name.name, m.events.keys().map(String::as_str))
                        .or_else(|| {
                            Some(if m.events.is_empty() {
                                format!("machine `{machine}` defines no events")
                            } else {
                                format!(
                                    "`{machine}` has: {}",
                                    m.events.keys().cloned().collect::<Vec<_>>().join(", ")
                                )
                            })
                        });
                    return Err(EvalError::UnknownEvent {
                        machine,
                        name: name.name.clone(),
                        span: name.span,
                        help,
                    });
                }
                self.push(
                    OpKind::Event {
                        name: name.name.clone(),
                    },
                    s.span,
                );
            }
            StmtKind::Output { name, on } => {
                let m = self.need_machine(s.span)?;
                let Some(out) = m.outputs.get(&name.name) else {
                    let machine = m.name.clone();
                    let help = did_you_mean(&name.name, m.outputs.keys().map(String::as_str))
                        .unwrap_or_else(|| {
                            if m.outputs.is_empty() {
                                format!(
                                    "machine `{machine}` declares no outputs; add \
                                     `[outputs.{}]` to its file",
                                    name.name
                                )
                            } else {
                                format!(
                                    "`{machine}` has: {}",
                                    m.outputs.keys().cloned().collect::<Vec<_>>().join(", ")
                                )
                            }
                        });
                    return Err(EvalError::UnknownOutput {
                        machine,
                        name: name.name.clone(),
                        span: name.span,
                        help,
                    });
                };
                let stops = out.stops();
                self.push(
                    OpKind::Output {
                        name: name.name.clone(),
                        on: *on,
                        stops,
                    },
                    s.span,
                );
            }
            StmtKind::Expr(e) => {
                self.expr(e, cx)?;
            }
        }
        Ok(Flow::Normal)
    }

    pub(super) fn push(&mut self, kind: OpKind, span: Span) {
        if let Some(t) = match &kind {
            OpKind::Rapid { to, .. } | OpKind::Line { to, .. } | OpKind::Arc { to, .. } => {
                Some(*to)
            }
            _ => None,
        } {
            self.pos = t;
        }
        if let OpKind::Rapid {
            orient: Some(o), ..
        }
        | OpKind::Line {
            orient: Some(o), ..
        } = &kind
        {
            self.orient = Some(**o);
        }
        self.ops.push(Op { kind, span });
    }

    pub(super) fn for_loop(
        &mut self,
        var: &Ident,
        iter: &ForIter,
        body: &[Stmt],
        cx: &mut Cx,
    ) -> R<Flow> {
        let items = self.for_items(iter, "`for`", cx)?;
        for item in items {
            self.step(var.span)?;
            self.scopes.push(HashMap::new());
            self.bind(&var.name, item);
            let r = self.block(body, cx);
            self.scopes.pop();
            if let Flow::Return(v) = r? {
                return Ok(Flow::Return(v));
            }
        }
        Ok(Flow::Normal)
    }

    /// What a `for` statement or a list comprehension runs over: the counts of a range,
    /// produced as they are needed, or a list's items.
    pub(super) fn for_items(
        &mut self,
        iter: &ForIter,
        context: &str,
        cx: &mut Cx,
    ) -> R<Box<dyn Iterator<Item = Value>>> {
        Ok(match iter {
            ForIter::Range {
                start,
                end,
                inclusive,
            } => {
                let a = self.expr(start, cx)?;
                let a = self.as_count(&a, start.span, "a range bound")?;
                let b = self.expr(end, cx)?;
                let b = self.as_count(&b, end.span, "a range bound")?;
                let b = if *inclusive { b + 1 } else { b };
                Box::new((a..b).map(|i| Value::Num(i as f64, Dim::NONE)))
            }
            ForIter::Expr(e) => match self.expr(e, cx)? {
                Value::List(items) => Box::new((*items).clone().into_iter()),
                other => return Err(type_err("a list or a range", &other, e.span, context)),
            },
        })
    }

    pub(super) fn import(&mut self, path: &StrLit, cx: &mut Cx) -> R<()> {
        let Some(Resolved::Module(idx)) = cx.program.imports.get(&path.span.start).cloned() else {
            return Err(bad(
                Kind::NotLoaded,
                path.span,
                "this import could not be loaded",
                "not loaded",
                None,
            ));
        };
        if !self.imported.insert(idx) {
            return Ok(());
        }
        let stmts = cx.program.modules[idx].stmts.clone();
        // An imported file's definitions land in the importer's scope.
        self.hoist(&stmts);
        for s in &stmts {
            self.stmt(s, cx)?;
        }
        Ok(())
    }
}
