//! Statements: blocks and their scopes, where each statement may stand, functions (declared
//! before the block runs so they may be called early), `import`/`use`, and the settings of
//! process statements against the schema's tables.

use super::{Checker, FnSig, Place, Ty};
use crate::Resolved;
use crate::ast::*;
use crate::diag::{CheckError, did_you_mean};
use crate::schema::{self, PTy, SettingSpec};
use crate::span::Span;
use crate::units::Dim;
use std::collections::HashMap;
use std::rc::Rc;

impl Checker {
    pub(super) fn block(&mut self, stmts: &[Stmt], place: Place, new_scope: bool) {
        if new_scope {
            self.scopes.push(HashMap::new());
        }
        // Functions are visible in their whole block, so they may be called before (and from
        // within) their definition.
        for s in stmts {
            if let StmtKind::Fn(f) = &s.kind {
                self.declare_fn(f);
            }
        }
        for s in stmts {
            self.stmt(s, place);
        }
        if new_scope {
            self.scopes.pop();
        }
    }

    fn annotation(&mut self, ty: &Ident) -> Ty {
        Ty::from_name(&ty.name).unwrap_or_else(|| {
            self.err(CheckError::UnknownType {
                name: ty.name.clone(),
                span: ty.span,
                help: did_you_mean(&ty.name, schema::TYPE_NAMES.iter().copied())
                    .or_else(|| Some(format!("types are: {}", schema::TYPE_NAMES.join(", ")))),
            });
            Ty::Unknown
        })
    }

    fn declare_fn(&mut self, f: &FnDef) {
        if let Some(prev) = self.fns.get(&f.name.name)
            && prev.span != f.name.span
        {
            let first = prev.span;
            self.err(CheckError::Duplicate {
                name: f.name.name.clone(),
                span: f.name.span,
                first,
            });
            return;
        }
        let params = f
            .params
            .iter()
            .map(|p| {
                let ty = p.ty.as_ref().map_or(Ty::Unknown, |t| self.annotation(t));
                (p.name.name.clone(), ty)
            })
            .collect();
        let ret = f.ret.as_ref().map_or(Ty::Unknown, |t| self.annotation(t));
        self.fns.insert(
            f.name.name.clone(),
            FnSig {
                params,
                ret,
                span: f.name.span,
            },
        );
    }

    fn misplaced(&mut self, what: &str, place: &str, span: Span, help: &str) {
        self.err(CheckError::Misplaced {
            what: what.into(),
            place: place.into(),
            span,
            help: Some(help.into()),
        });
    }

    fn stmt(&mut self, s: &Stmt, place: Place) {
        stacker::maybe_grow(crate::STACK_RED_ZONE, crate::STACK_SEGMENT, || {
            self.stmt_here(s, place)
        })
    }

    fn stmt_here(&mut self, s: &Stmt, place: Place) {
        let in_import = place == Place::Import;
        let process_stmt = !matches!(
            s.kind,
            StmtKind::Let { .. }
                | StmtKind::Fn(_)
                | StmtKind::Import(_)
                | StmtKind::Use(_)
                | StmtKind::Return(_)
        );
        if in_import && process_stmt {
            self.misplaced(
                "a process statement",
                "in an imported file",
                s.span,
                "imported files hold definitions (`let`, `fn`) only; move this into the recipe \
                 or into a function the recipe calls",
            );
            return;
        }
        match &s.kind {
            StmtKind::Machine(_) => {
                if place != Place::Main {
                    self.misplaced(
                        "`machine`",
                        "here",
                        s.span,
                        "select the machine once, at the top level of the recipe",
                    );
                }
            }
            StmtKind::Limits(groups) => {
                for g in groups {
                    self.settings("limits", &g.settings, schema::LIMIT_SETTINGS);
                }
            }
            StmtKind::Let { name, ty, value } => {
                let t = self.expr(value);
                let t = match ty {
                    Some(ann) => {
                        let want = self.annotation(ann);
                        self.expect_ty(&t, &want, value, &format!("`{}`", name.name));
                        want
                    }
                    None => t,
                };
                let t = if t == Ty::Zero { Ty::Unknown } else { t };
                self.bind(&name.name, t);
            }
            StmtKind::Fn(f) => self.fn_body(f),
            StmtKind::Import(path) => self.import(path),
            StmtKind::Use(path) => self.use_module(path, s.span),
            StmtKind::If { cond, then, els } => {
                let t = self.expr(cond);
                self.expect_ty(&t, &Ty::Bool, cond, "the condition of `if`");
                let inner = if place == Place::Main {
                    Place::Nested
                } else {
                    place
                };
                self.block(then, inner, true);
                if let Some(e) = els {
                    self.block(e, inner, true);
                }
            }
            StmtKind::For { var, iter, body } => {
                let var_ty = self.for_iter(iter, "`for`");
                let inner = if place == Place::Main {
                    Place::Nested
                } else {
                    place
                };
                self.scopes.push(HashMap::new());
                self.bind(&var.name, var_ty);
                self.block(body, inner, false);
                self.scopes.pop();
            }
            StmtKind::Return(e) => {
                let t = e.as_ref().map_or(Ty::Nothing, |e| self.expr(e));
                match self.returns.last_mut() {
                    Some(r) => r.push(t),
                    None => self.misplaced(
                        "`return`",
                        "outside a function",
                        s.span,
                        "`return` ends a function; a recipe simply ends at its last line",
                    ),
                }
            }
            StmtKind::Laser(LaserStmt::Settings(set)) => {
                self.settings("laser", set, schema::LASER_SETTINGS)
            }
            StmtKind::Laser(_) => {}
            StmtKind::Pulse(PulseStmt::Settings(set)) => {
                self.settings("pulse", set, schema::PULSE_SETTINGS)
            }
            StmtKind::Pulse(PulseStmt::Off) => {}
            StmtKind::Planner(set) => self.settings("planner", set, schema::PLANNER_SETTINGS),
            StmtKind::Rotary(set) => self.settings("rotary", set, schema::ROTARY_SETTINGS),
            StmtKind::Move { target, speed, .. } => {
                let t = self.expr(target);
                self.expect_ty(&t, &Ty::Point, target, "the target of `move`");
                if let MoveSpeed::At(v) = speed {
                    let t = self.expr(v);
                    self.expect_dim(&t, Dim::SPEED, v, "the speed of `move`");
                }
            }
            StmtKind::Follow {
                path,
                speed,
                settings,
            } => {
                let t = self.expr(path);
                // A list of profiles is the lit pieces of one path (`tabs`).
                if t != Ty::List(Box::new(Ty::Profile)) {
                    self.expect_ty(&t, &Ty::Profile, path, "the path of `follow`");
                }
                let t = self.expr(speed);
                self.expect_dim(&t, Dim::SPEED, speed, "the speed of `follow`");
                self.settings("follow", settings, schema::FOLLOW_SETTINGS);
            }
            StmtKind::Dwell(e) => {
                let t = self.expr(e);
                self.expect_dim(&t, Dim::TIME, e, "`dwell`");
            }
            StmtKind::MCode { code, .. } => {
                let t = self.expr(code);
                self.expect_count(&t, code, "an M-code number");
            }
            StmtKind::Event(_) | StmtKind::Output { .. } => {}
            StmtKind::Scan {
                kind,
                region,
                settings,
            } => {
                let t = self.expr(region);
                let Some(sk) = schema::scan_kind(&kind.name) else {
                    self.err(CheckError::UnknownName {
                        name: kind.name.clone(),
                        span: kind.span,
                        help: did_you_mean(&kind.name, schema::SCAN_KINDS.iter().map(|k| k.name))
                            .or_else(|| {
                                Some("scan kinds: `scan dots`, `scan raster`, `scan image`".into())
                            }),
                    });
                    return;
                };
                let ok = match &t {
                    _ if sk.name == "image" => matches!(t, Ty::Str | Ty::Unknown),
                    Ty::Profile | Ty::Unknown => true,
                    Ty::Point => sk.name == "dots",
                    Ty::List(inner) => match **inner {
                        Ty::Profile | Ty::Unknown => true,
                        Ty::Point => sk.name == "dots",
                        _ => false,
                    },
                    _ => false,
                };
                if !ok {
                    self.err(CheckError::TypeMismatch {
                        expected: sk.region.into(),
                        found: t.describe(),
                        context: format!("the region of `scan {}`", sk.name),
                        span: region.span,
                        help: Some(if sk.name == "image" {
                            "e.g. `scan image \"logo.png\" { width 40 mm, speed 100 mm/s, power \
                             20 W }`"
                                .into()
                        } else if sk.name == "dots" {
                            "e.g. `scan dots (0, 0) { rows 20, cols 30, pitch 0.2 mm, speed \
                             20 mm/s }` or `scan dots profile rect((0, 0), 4 mm, 2 mm) { ... }`"
                                .into()
                        } else {
                            "e.g. `scan raster profile rect((0, 0), 10 mm, 5 mm) { pitch \
                             0.1 mm, speed 100 mm/s }`"
                                .into()
                        }),
                    });
                }
                self.settings(&format!("scan {}", sk.name), settings, sk.settings);
            }
            StmtKind::Expr(e) => {
                self.expr(e);
            }
        }
    }

    fn fn_body(&mut self, f: &Rc<FnDef>) {
        let Some(sig) = self.fns.get(&f.name.name).cloned() else {
            return;
        };
        if sig.span != f.name.span {
            return; // a duplicate, already reported
        }
        let mut scope = HashMap::new();
        for (n, t) in &sig.params {
            scope.insert(n.clone(), t.clone());
        }
        self.scopes.push(scope);
        self.returns.push(Vec::new());
        self.block(&f.body, Place::Function, false);
        let rets = self.returns.pop().unwrap_or_default();
        self.scopes.pop();
        if sig.ret == Ty::Unknown {
            // Infer the result from the first return that says something definite.
            let inferred = rets
                .into_iter()
                .find(|t| !matches!(t, Ty::Unknown | Ty::Zero))
                .unwrap_or(Ty::Unknown);
            if let Some(s) = self.fns.get_mut(&f.name.name) {
                s.ret = inferred;
            }
        }
    }

    /// `use`: the declarations the caller resolved (see [`crate::Program::uses`]) come into
    /// scope; extension functions are typed by their declared signatures.
    fn use_module(&mut self, path: &StrLit, span: Span) {
        let Some(ex) = self.program.uses.get(&path.span.start).cloned() else {
            self.err(CheckError::Unsupported {
                what: format!("`use {}` here", path.value),
                span,
                help: Some(
                    "extension modules and presets are loaded by `lase` before checking; \
                     this tool did not load them"
                        .into(),
                ),
            });
            return;
        };
        for f in ex.fns {
            if let Some(prev) = self.fns.get(&f.name)
                && prev.span != path.span
            {
                let first = prev.span;
                self.err(CheckError::Duplicate {
                    name: f.name.clone(),
                    span: path.span,
                    first,
                });
                continue;
            }
            self.fns.insert(
                f.name,
                FnSig {
                    params: f.params,
                    ret: f.ret,
                    span: path.span,
                },
            );
        }
        for (name, ty) in ex.vars {
            self.bind(&name, ty);
        }
    }

    fn import(&mut self, path: &StrLit) {
        let Some(Resolved::Module(idx)) = self.program.imports.get(&path.span.start).cloned()
        else {
            return; // the loader has reported why it could not be loaded
        };
        if !self.checked_modules.contains_key(&idx) {
            let stmts = self.program.modules[idx].stmts.clone();
            let globals = vec![self.scopes[0].clone()];
            let saved_scopes = std::mem::replace(&mut self.scopes, globals);
            let saved_fns = std::mem::take(&mut self.fns);
            self.scopes.push(HashMap::new());
            self.block(&stmts, Place::Import, false);
            let vars = self.scopes.pop().unwrap_or_default();
            let fns = std::mem::replace(&mut self.fns, saved_fns);
            self.scopes = saved_scopes;
            self.checked_modules.insert(idx, (vars, fns));
        }
        let (vars, fns) = self.checked_modules[&idx].clone();
        for (n, t) in vars {
            self.bind(&n, t);
        }
        for (n, sig) in fns {
            self.fns.entry(n).or_insert(sig);
        }
    }

    fn settings(&mut self, stmt: &str, set: &[Setting], specs: &[SettingSpec]) {
        for s in set {
            let Some(spec) = specs.iter().find(|sp| sp.key == s.key.name) else {
                self.err(CheckError::UnknownSetting {
                    stmt: stmt.into(),
                    key: s.key.name.clone(),
                    span: s.key.span,
                    help: did_you_mean(&s.key.name, specs.iter().map(|sp| sp.key)).or_else(|| {
                        Some(format!(
                            "`{stmt}` takes: {}",
                            specs.iter().map(|sp| sp.key).collect::<Vec<_>>().join(", ")
                        ))
                    }),
                });
                if let Some(v) = &s.value {
                    self.expr(v);
                }
                continue;
            };
            self.setting_value(spec.key, spec.ty, s);
        }
    }

    fn setting_value(&mut self, key: &str, ty: PTy, s: &Setting) {
        let Some(v) = &s.value else {
            if ty != PTy::Flag {
                self.err(CheckError::MissingValue {
                    key: key.into(),
                    span: s.span,
                    help: Some(format!("`{key}` takes {}", ty.describe())),
                });
            }
            return;
        };
        if let PTy::Word(words) = ty {
            match &v.kind {
                ExprKind::Var(w) if words.contains(&w.as_str()) => {}
                _ => self.err(CheckError::TypeMismatch {
                    expected: ty.describe(),
                    found: format!("`{}`", self.snippet_of(v)),
                    context: format!("`{key}`"),
                    span: v.span,
                    help: did_you_mean(&self.snippet_of(v), words.iter().copied())
                        .or_else(|| Some(format!("write one of: {}", words.join(", ")))),
                }),
            }
            return;
        }
        let t = self.expr(v);
        self.expect_param(&t, ty, v, &format!("`{key}`"));
    }

    fn snippet_of(&self, e: &Expr) -> String {
        match &e.kind {
            ExprKind::Var(n) => n.clone(),
            _ => "this".into(),
        }
    }
}
