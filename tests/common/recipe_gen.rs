//! A structured generator of recipes for fuzzing: from any byte string (through `arbitrary`'s
//! `Unstructured`) it writes a recipe that parses most of the time and reaches the evaluator,
//! the planner and the emitter, instead of dying at the first syntax error as random text does.
//!
//! It is driven by the language's own schema (`lase_lang::schema`): every statement kind, every
//! setting of every statement, every builtin, every profile constructor and every scan kind is
//! drawn from the tables the checker uses, so a statement or setting added to the language is
//! fuzzed without touching this file. Values are drawn to hurt: zero, denormals, 1e±300,
//! negative lengths, wrong dimensions, long lists, deep brackets, long operator chains, loops
//! with huge ranges and recursive functions.

#![allow(dead_code)]

use arbitrary::{Result, Unstructured};
use lase_lang::schema::{self, PTy, ParamSpec, SettingSpec};
use lase_lang::units::Dim;
use std::fmt::Write;

/// The stock machines a recipe may name (stdlib/machines).
const MACHINES: &[&str] = &["xy_table", "xyz", "cam_xwb", "arm_3r", "notcher"];

/// Sizes the generator may reach. `smoke` keeps each input small enough for a debug build;
/// `campaign` lets inputs grow to the hostile sizes issue 16 lists.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    pub max_stmts: usize,
    pub max_list: usize,
    pub max_chain: usize,
    pub max_nesting: usize,
    /// The argument of the doubly recursive function (2^n calls without a step budget).
    pub max_recursion: u32,
    /// The largest `for` range.
    pub max_loop: i64,
}

impl Limits {
    pub const SMOKE: Limits = Limits {
        max_stmts: 24,
        max_list: 40,
        max_chain: 200,
        max_nesting: 40,
        max_recursion: 12,
        max_loop: 1000,
    };
    pub const CAMPAIGN: Limits = Limits {
        max_stmts: 80,
        max_list: 20_000,
        max_chain: 40_000,
        max_nesting: 700,
        max_recursion: 70,
        max_loop: 1_000_000_000,
    };
}

/// Writes one recipe from `u`. Never fails for lack of bytes: `Unstructured` answers zeros and
/// the first choices once it runs dry, which still makes a recipe.
pub fn recipe(u: &mut Unstructured<'_>, limits: Limits) -> Result<String> {
    let mut g = Gen {
        u,
        limits,
        out: String::new(),
        names: Vec::new(),
        depth: 0,
        fns: 0,
        clean: false,
    };
    // Half the recipes are hostile (extreme values, type errors, huge inputs), half clean.
    g.clean = g.u.ratio(1, 2)?;
    g.recipe()?;
    Ok(g.out)
}

struct Gen<'a, 'b> {
    u: &'a mut Unstructured<'b>,
    limits: Limits,
    out: String,
    /// Names bound by `let` so far, with what they hold, so later statements can use them.
    names: Vec<(String, PTy)>,
    depth: usize,
    /// Functions defined so far (each gets a new name).
    fns: usize,
    /// A clean recipe: no injected errors, no extreme values.
    clean: bool,
}

impl Gen<'_, '_> {
    fn recipe(&mut self) -> Result<()> {
        // Most recipes name a machine first, as real ones do; some do not (a diagnostic).
        let mut machine = "";
        if self.clean || !self.u.ratio(1, 12)? {
            // Clean recipes mostly run on flat beds, where any move is reachable.
            let m = if self.clean && !self.u.ratio(1, 5)? {
                *self.u.choose(&["xy_table", "xyz"])?
            } else {
                *self.u.choose(MACHINES)?
            };
            machine = m;
            if self.spice(20)? {
                let _ = writeln!(self.out, "machine \"{m}.toml\"");
            } else {
                let _ = writeln!(self.out, "machine {m}");
            }
        }
        // A laser power up front, as real recipes set one; sometimes none (a diagnostic).
        if self.clean || !self.u.ratio(1, 10)? {
            let w: u16 = self.u.int_in_range(1..=200)?;
            let _ = write!(self.out, "laser {{ power {w} W");
            if matches!(machine, "cam_xwb" | "arm_3r") {
                let _ = write!(self.out, ", standoff {} mm", self.u.int_in_range(2..=40)?);
            }
            self.out.push_str(" }\n");
        }
        let n = self.u.int_in_range(1..=self.limits.max_stmts)?;
        for _ in 0..n {
            if self.u.is_empty() {
                break;
            }
            self.stmt()?;
            self.out.push('\n');
        }
        Ok(())
    }

    fn stmt(&mut self) -> Result<()> {
        self.depth += 1;
        let r = self.stmt_inner();
        self.depth -= 1;
        r
    }

    fn stmt_inner(&mut self) -> Result<()> {
        let nested = self.depth > 3;
        match self.u.int_in_range(0..=19)? {
            0 | 13 if self.clean => self.move_stmt(),
            0 => self.limits_stmt(),
            1 | 2 => self.let_stmt(),
            3 => self.settings_stmt("laser", schema::LASER_SETTINGS),
            4 => {
                if self.u.ratio(1, 2)? {
                    self.out.push_str("pulse interval ");
                    self.quantity_of(PTy::Either(Dim::LENGTH, Dim::TIME))
                } else {
                    self.settings_stmt("pulse", schema::PULSE_SETTINGS)
                }
            }
            5 => self.settings_stmt("planner", schema::PLANNER_SETTINGS),
            6 | 7 => self.move_stmt(),
            8..=10 => self.follow_stmt(),
            11 => {
                self.out.push_str("dwell ");
                self.quantity_of(PTy::Dim(Dim::TIME))
            }
            12 => {
                self.out.push_str("mcode ");
                let m: u16 = self.u.int_in_range(0..=200)?;
                let _ = write!(self.out, "{m}");
                if self.u.ratio(1, 2)? {
                    self.out.push_str(" \"");
                    self.text()?;
                    self.out.push('"');
                }
                Ok(())
            }
            13 => {
                let name = self.ident()?;
                let _ = write!(self.out, "event {name}");
                Ok(())
            }
            14 | 15 => self.scan_stmt(),
            16 if !nested => self.for_stmt(),
            17 if !nested => self.if_stmt(),
            18 if !nested => self.fn_stmt(),
            19 => {
                self.out.push_str(if self.u.ratio(1, 2)? {
                    "laser on"
                } else {
                    "laser off"
                });
                Ok(())
            }
            _ => self.let_stmt(),
        }
    }

    fn limits_stmt(&mut self) -> Result<()> {
        self.out.push_str("limits { ");
        let axes = ["x", "y", "z", "a", "b", "c", "w", "q"];
        let n = self.u.int_in_range(1..=3)?;
        for i in 0..n {
            if i > 0 {
                self.out.push_str("; ");
            }
            let axis = *self.u.choose(&axes)?;
            let _ = write!(self.out, "{axis}: ");
            let spec = *self.u.choose(schema::LIMIT_SETTINGS)?;
            let _ = write!(self.out, "{} ", spec.key);
            self.value(spec.ty)?;
            if self.u.ratio(1, 2)? {
                self.out.push_str(", ");
                self.settings_list(schema::LIMIT_SETTINGS)?;
            }
        }
        self.out.push_str(" }");
        Ok(())
    }

    fn let_stmt(&mut self) -> Result<()> {
        let name = format!("v{}", self.names.len());
        let ty = self.any_type()?;
        let _ = write!(self.out, "let {name} = ");
        self.value(ty)?;
        self.names.push((name, ty));
        Ok(())
    }

    fn settings_stmt(&mut self, kw: &str, specs: &[SettingSpec]) -> Result<()> {
        let _ = write!(self.out, "{kw} {{ ");
        self.settings_list(specs)?;
        self.out.push_str(" }");
        Ok(())
    }

    /// `key value, key value` from the schema, now and then a misspelt or repeated key.
    fn settings_list(&mut self, specs: &[SettingSpec]) -> Result<()> {
        let n = self.u.int_in_range(0..=specs.len().min(6))?;
        for i in 0..n {
            if i > 0 {
                self.out.push_str(", ");
            }
            let spec = *self.u.choose(specs)?;
            if self.spice(300)? {
                let _ = write!(self.out, "{}x ", spec.key);
            } else {
                let _ = write!(self.out, "{} ", spec.key);
            }
            self.value(spec.ty)?;
        }
        Ok(())
    }

    fn move_stmt(&mut self) -> Result<()> {
        let kind = if self.u.ratio(1, 2)? { "to" } else { "by" };
        let _ = write!(self.out, "move {kind} ");
        self.value(PTy::Point)?;
        match self.u.int_in_range(0..=2)? {
            0 => self.out.push_str(" rapid"),
            1 => {
                self.out.push_str(" at ");
                self.quantity_of(PTy::Dim(Dim::SPEED))?;
            }
            _ => {}
        }
        Ok(())
    }

    fn follow_stmt(&mut self) -> Result<()> {
        self.out.push_str("follow ");
        self.value(PTy::Profile)?;
        self.out.push_str(" at ");
        if self.spice(50)? {
            self.quantity_of(PTy::Dim(Dim::ANGULAR_SPEED))?;
        } else {
            self.quantity_of(PTy::Dim(Dim::SPEED))?;
        }
        if self.u.ratio(1, 2)? {
            self.out.push(' ');
            self.settings_stmt_body(schema::FOLLOW_SETTINGS)?;
        }
        Ok(())
    }

    fn settings_stmt_body(&mut self, specs: &[SettingSpec]) -> Result<()> {
        self.out.push_str("{ ");
        self.settings_list(specs)?;
        self.out.push_str(" }");
        Ok(())
    }

    fn scan_stmt(&mut self) -> Result<()> {
        let kind = *self.u.choose(schema::SCAN_KINDS)?;
        let _ = write!(self.out, "scan {} ", kind.name);
        let dots = kind.name == "dots";
        if kind.name == "image" {
            // An image file: the stored test image or a name that is not there.
            self.out.push_str(if self.u.ratio(1, 2)? {
                "\"image_engrave.png\""
            } else {
                "\"nope.png\""
            });
            self.out.push(' ');
            return self.settings_stmt_body(kind.settings);
        }
        match self.u.int_in_range(0..=5)? {
            0 if dots => self.value(PTy::Point)?,
            1 if dots => self.value(PTy::Points)?,
            0..=2 => {
                self.out.push_str("profile polyline ");
                let n = self.u.int_in_range(3..=8)?;
                self.points(n)?;
                self.out.push_str(" closed");
            }
            3 => {
                self.out.push_str("profile circle(center: ");
                self.leaf(PTy::Point)?;
                self.out.push_str(", radius: ");
                self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                self.out.push(')');
            }
            _ => {
                self.out.push_str("profile rect(");
                self.leaf(PTy::Point)?;
                self.out.push_str(", ");
                self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                self.out.push_str(", ");
                self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                self.out.push(')');
            }
        }
        self.out.push(' ');
        if self.clean {
            // A scan needs its speed; the rest is drawn from the schema.
            let v: u16 = self.u.int_in_range(1..=200)?;
            let _ = write!(self.out, "{{ speed {v} mm/s, ");
            self.settings_list(kind.settings)?;
            self.out.push_str(" }");
            return Ok(());
        }
        self.settings_stmt_body(kind.settings)
    }

    fn for_stmt(&mut self) -> Result<()> {
        let var = format!("i{}", self.depth);
        let _ = write!(self.out, "for {var} in ");
        // Mostly small loops; sometimes one that only a budget can stop.
        let hi: i64 = match self.u.int_in_range(0..=9)? {
            0 if !self.clean => self.limits.max_loop,
            1 if !self.clean => self.limits.max_loop.min(100_000),
            _ => self.u.int_in_range(0..=4)?,
        };
        let lo: i64 = self.u.int_in_range(-2..=2)?;
        let op = if self.u.ratio(1, 2)? { ".." } else { "..=" };
        let _ = writeln!(self.out, "{lo}{op}{hi} {{");
        let scope = self.names.len();
        self.names.push((var, PTy::AnyNum));
        let n = self.u.int_in_range(1..=3)?;
        for _ in 0..n {
            self.stmt()?;
            self.out.push('\n');
        }
        self.names.truncate(scope);
        self.out.push('}');
        Ok(())
    }

    fn if_stmt(&mut self) -> Result<()> {
        self.out.push_str("if ");
        self.value(PTy::Bool)?;
        let scope = self.names.len();
        self.out.push_str(" {\n");
        self.stmt()?;
        self.out.push_str("\n}");
        self.names.truncate(scope);
        if self.u.ratio(1, 2)? {
            self.out.push_str(" else {\n");
            self.stmt()?;
            self.out.push_str("\n}");
            self.names.truncate(scope);
        }
        Ok(())
    }

    /// A function, sometimes recursive (twice per call: exponential without a step budget).
    fn fn_stmt(&mut self) -> Result<()> {
        self.fns += 1;
        let name = format!("f{}", self.fns);
        if self.u.ratio(1, 3)? {
            let n: u32 = self.u.int_in_range(0..=self.limits.max_recursion)?;
            let _ = write!(
                self.out,
                "fn {name}(n) -> number {{ if n <= 0 {{ return 1 }} return {name}(n - 1) + {name}(n - 1) }}\nlet r{name} = {name}({n})"
            );
            return Ok(());
        }
        let _ = writeln!(self.out, "fn {name}(p: length) -> length {{");
        let scope = self.names.len();
        self.names.push(("p".into(), PTy::Dim(Dim::LENGTH)));
        if self.u.ratio(1, 2)? {
            self.stmt()?;
            self.out.push('\n');
        }
        self.out.push_str("return ");
        self.value(PTy::Dim(Dim::LENGTH))?;
        self.names.truncate(scope);
        let _ = write!(self.out, "\n}}\nlet r{name} = {name}(");
        self.quantity_of(PTy::Dim(Dim::LENGTH))?;
        self.out.push(')');
        Ok(())
    }

    fn any_type(&mut self) -> Result<PTy> {
        Ok(*self.u.choose(&[
            PTy::Dim(Dim::LENGTH),
            PTy::Dim(Dim::SPEED),
            PTy::Dim(Dim::ANGLE),
            PTy::Dim(Dim::TIME),
            PTy::Dim(Dim::POWER),
            PTy::Dim(Dim::NONE),
            PTy::Point,
            PTy::Points,
            PTy::Profile,
            PTy::Profile,
            PTy::List,
            PTy::Bool,
            PTy::Str,
        ])?)
    }

    /// An expression meant to have type `ty`; one in twenty has another type on purpose.
    fn value(&mut self, ty: PTy) -> Result<()> {
        self.depth += 1;
        let r = self.value_inner(ty);
        self.depth -= 1;
        r
    }

    fn value_inner(&mut self, ty: PTy) -> Result<()> {
        // One dimension of an either-or for the whole expression, so its terms agree.
        let ty = match ty {
            PTy::Either(a, b) => PTy::Dim(if self.u.ratio(1, 2)? { a } else { b }),
            t => t,
        };
        if self.depth > 8 {
            return self.leaf(ty);
        }
        // A bound name of the right type, now and then.
        if self.u.ratio(1, 5)? {
            let fits: Vec<String> = self
                .names
                .iter()
                .filter(|(_, t)| same_kind(*t, ty))
                .map(|(n, _)| n.clone())
                .collect();
            if !fits.is_empty() {
                let n = self.u.choose(&fits)?.clone();
                self.out.push_str(&n);
                return Ok(());
            }
        }
        if self.spice(1000)? {
            let other = self.any_type()?;
            return self.leaf(other);
        }
        if self.spice(600)? {
            return self.hostile(ty);
        }
        match ty {
            PTy::Profile => self.profile(),
            PTy::Dim(d) if self.clean && d.is_none() => self.leaf(ty),
            PTy::Dim(_) | PTy::Either(..) | PTy::AnyNum => {
                if self.u.ratio(1, 4)? {
                    return self.arith(ty);
                }
                if self.u.ratio(1, 6)? {
                    return self.builtin_call(ty);
                }
                self.leaf(ty)
            }
            _ => self.leaf(ty),
        }
    }

    /// The sizes issue 16 found: long chains, deep brackets, long lists, huge strings.
    fn hostile(&mut self, ty: PTy) -> Result<()> {
        match self.u.int_in_range(0..=3)? {
            0 => {
                let n = self.u.int_in_range(1..=self.limits.max_chain)?;
                self.out.push('(');
                self.leaf(ty)?;
                for _ in 0..n {
                    self.out.push_str(" + ");
                    self.leaf(ty)?;
                }
                self.out.push(')');
            }
            1 => {
                let n = self.u.int_in_range(1..=self.limits.max_nesting)?;
                self.out.push_str(&"(".repeat(n));
                self.leaf(ty)?;
                self.out.push_str(&")".repeat(n));
            }
            2 => {
                let n = self.u.int_in_range(1..=self.limits.max_chain)?;
                let op = if self.u.ratio(1, 2)? { "-" } else { "not " };
                self.out.push_str(&op.repeat(n));
                self.leaf(ty)?;
            }
            _ => {
                let n = self.u.int_in_range(0..=self.limits.max_list)?;
                self.points(n)?;
            }
        }
        Ok(())
    }

    fn arith(&mut self, ty: PTy) -> Result<()> {
        self.out.push('(');
        self.value(ty)?;
        let op = *self.u.choose(&[" + ", " - ", " * ", " / "])?;
        self.out.push_str(op);
        if op == " * " || op == " / " {
            self.value(PTy::Dim(Dim::NONE))?;
        } else {
            self.value(ty)?;
        }
        self.out.push(')');
        Ok(())
    }

    /// A builtin whose result has the wanted dimension (most of the time).
    fn builtin_call(&mut self, ty: PTy) -> Result<()> {
        let fits: Vec<&schema::Builtin> = schema::BUILTINS
            .iter()
            .filter(|b| match (b.ret, ty) {
                (schema::Ret::Dim(d), PTy::Dim(w)) => d == w,
                (schema::Ret::Dim(d), PTy::Either(a, c)) => d == a || d == c,
                _ => false,
            })
            .collect();
        if fits.is_empty() {
            return self.leaf(ty);
        }
        if self.u.ratio(1, 400)? {
            let b = *self.u.choose(schema::BUILTINS)?;
            return self.call(b.name, b.params);
        }
        let b = *self.u.choose(&fits)?;
        self.call(b.name, b.params)
    }

    /// `name(args)`: positional or named, now and then one missing or one too many.
    fn call(&mut self, name: &str, params: &[ParamSpec]) -> Result<()> {
        let _ = write!(self.out, "{name}(");
        let named = self.u.ratio(1, 3)?;
        let mut first = true;
        for p in params {
            if !p.required && self.u.ratio(1, 2)? {
                continue;
            }
            if p.required && self.spice(300)? {
                continue;
            }
            if !first {
                self.out.push_str(", ");
            }
            first = false;
            // Keyword parameter names (`to`, `profile`) are written by name too: the grammar
            // takes any word before `:`.
            if named || !p.required {
                let _ = write!(self.out, "{}: ", p.name);
            }
            self.param(p.ty)?;
        }
        if self.spice(300)? {
            if !first {
                self.out.push_str(", ");
            }
            self.number()?;
        }
        self.out.push(')');
        Ok(())
    }

    fn param(&mut self, ty: PTy) -> Result<()> {
        match ty {
            PTy::Word(words) => {
                let w = *self.u.choose(words)?;
                self.out.push_str(w);
                Ok(())
            }
            PTy::Flag => Ok(()),
            t => self.value(t),
        }
    }

    fn profile(&mut self) -> Result<()> {
        if self.depth < 6 && self.u.ratio(1, 4)? {
            // A builtin that takes and returns a profile.
            let b = *self.u.choose(schema::BUILTINS)?;
            if b.ret == schema::Ret::Profile {
                return self.call(b.name, b.params);
            }
        }
        let kinds: Vec<&schema::ProfileKind> = schema::PROFILE_KINDS
            .iter()
            .filter(|k| !self.clean || !matches!(k.name, "dxf" | "svg"))
            .collect();
        let kind = *self.u.choose(&kinds)?;
        let _ = write!(self.out, "profile {}", kind.name);
        if kind.params.len() == 1
            && matches!(kind.params[0].ty, PTy::Points)
            && self.u.ratio(1, 2)?
        {
            self.out.push(' ');
            let n = self.u.int_in_range(0..=self.limits.max_list.min(12))?;
            self.points(n)?;
        } else {
            self.call("", kind.params)?;
        }
        if !kind.flags.is_empty() && self.u.ratio(1, 3)? {
            let f = *self.u.choose(kind.flags)?;
            let _ = write!(self.out, " {f}");
        }
        Ok(())
    }

    /// A literal of type `ty` (no further nesting).
    fn leaf(&mut self, ty: PTy) -> Result<()> {
        match ty {
            PTy::Dim(_) | PTy::Either(..) | PTy::AnyNum => self.quantity_of(ty),
            PTy::Point => {
                self.out.push('(');
                self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                self.out.push_str(", ");
                self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                if self.u.ratio(1, 8)? {
                    self.out.push_str(", ");
                    self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                }
                self.out.push(')');
                Ok(())
            }
            // `len`'s list-or-string and `format`'s any value take a list as well as the rest.
            PTy::Points | PTy::List | PTy::ListOrStr | PTy::Any => {
                let n = self.u.int_in_range(2..=self.limits.max_list.clamp(2, 8))?;
                self.points(n)
            }
            PTy::Profile => {
                let n = self.u.int_in_range(0..=6)?;
                self.out.push_str("profile polyline ");
                self.points(n)?;
                if self.u.ratio(1, 2)? {
                    self.out.push_str(" closed");
                }
                Ok(())
            }
            PTy::Bool => {
                match self.u.int_in_range(0..=2)? {
                    0 => self.out.push_str("true"),
                    1 => self.out.push_str("false"),
                    _ => {
                        self.out.push('(');
                        self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                        let op = *self.u.choose(&[" < ", " <= ", " == ", " != ", " > "])?;
                        self.out.push_str(op);
                        self.quantity_of(PTy::Dim(Dim::LENGTH))?;
                        self.out.push(')');
                    }
                }
                Ok(())
            }
            PTy::Str => {
                self.out.push('"');
                self.text()?;
                self.out.push('"');
                Ok(())
            }
            PTy::Word(words) => {
                let w = *self.u.choose(words)?;
                self.out.push_str(w);
                Ok(())
            }
            PTy::Flag => Ok(()),
        }
    }

    fn points(&mut self, n: usize) -> Result<()> {
        self.out.push('[');
        // Long lists are drawn cheaply (a line of points, a circle's worth, a random walk) so
        // that 20 000 points do not use up the input's bytes.
        let style = self.u.int_in_range(0..=3)?;
        let scale = self.magnitude()?;
        for i in 0..n {
            if i > 0 {
                self.out.push_str(", ");
            }
            if n > 16 || style == 0 {
                let t = i as f64 / n.max(1) as f64 * std::f64::consts::TAU;
                let (x, y) = match style {
                    0 => (i as f64 * scale, 0.0),
                    1 => (scale * t.cos(), scale * t.sin()),
                    2 => (scale * (i % 2) as f64, scale * (i / 2) as f64),
                    _ => (scale * (3.0 * t).sin(), scale * (2.0 * t).sin()),
                };
                let _ = write!(self.out, "({} mm, {} mm)", num(x), num(y));
            } else {
                self.leaf(PTy::Point)?;
            }
        }
        self.out.push(']');
        Ok(())
    }

    /// A number in a unit of the wanted dimension; sometimes bare, sometimes a wrong unit.
    fn quantity_of(&mut self, ty: PTy) -> Result<()> {
        let dim = match ty {
            PTy::Dim(d) => d,
            PTy::Either(a, b) => {
                if self.u.ratio(1, 2)? {
                    a
                } else {
                    b
                }
            }
            _ => Dim::NONE,
        };
        if self.spice(40)? {
            self.out.push('-');
        }
        if dim.is_none() && self.clean {
            // Counts (`passes`, `rows`, `pulses`) are whole numbers.
            let n: u8 = self.u.int_in_range(1..=5)?;
            let _ = write!(self.out, "{n}");
            return Ok(());
        }
        self.number()?;
        if dim.is_none() {
            return Ok(());
        }
        let unit = if self.spice(500)? {
            let all: Vec<&str> = lase_lang::units::unit_names().collect();
            (*self.u.choose(&all)?).to_string()
        } else {
            unit_for(dim)
        };
        let _ = write!(self.out, " {unit}");
        Ok(())
    }

    /// True once in `n` draws, in hostile recipes only: a wrong type, a wrong unit, a
    /// misspelt key, a missing argument. Clean recipes leave them out so that they get past
    /// the checker and into the evaluator, the planner and the emitter.
    fn spice(&mut self, n: u32) -> Result<bool> {
        if self.clean {
            return Ok(false);
        }
        self.u.ratio(1, n)
    }

    fn magnitude(&mut self) -> Result<f64> {
        if self.clean {
            return Ok(*self.u.choose(&[0.05, 0.5, 1.0, 2.5, 10.0, 40.0])?);
        }
        Ok(*self.u.choose(&[
            0.0, 1e-300, 1e-12, 1e-6, 0.001, 0.05, 0.5, 1.0, 2.5, 10.0, 40.0, 120.0, 1e4, 1e9,
            1e300,
        ])?)
    }

    fn number(&mut self) -> Result<()> {
        let v = if self.u.ratio(1, 8)? {
            self.magnitude()?
        } else {
            f64::from(self.u.int_in_range(0u16..=2000)?) / 10.0
        };
        self.out.push_str(&num(v));
        Ok(())
    }

    fn ident(&mut self) -> Result<String> {
        let n = self.u.int_in_range(1..=8)?;
        let mut s = String::from("e");
        for _ in 0..n {
            s.push(*self.u.choose(&['a', 'b', 'z', '_', '1'])?);
        }
        Ok(s)
    }

    fn text(&mut self) -> Result<()> {
        let n = self.u.int_in_range(0..=12)?;
        for _ in 0..n {
            let c = *self
                .u
                .choose(&['a', 'Z', ' ', '(', ')', ';', '%', 'é', '\\', '/', '.'])?;
            self.out.push(c);
        }
        Ok(())
    }
}

/// Whether a bound value of type `have` may stand where `want` is expected.
fn same_kind(have: PTy, want: PTy) -> bool {
    match (have, want) {
        (PTy::Dim(a), PTy::Dim(b)) => a == b,
        (PTy::Dim(a), PTy::Either(b, c)) => a == b || a == c,
        (PTy::AnyNum, PTy::AnyNum) => true,
        (PTy::AnyNum, PTy::Dim(d)) | (PTy::Dim(d), PTy::AnyNum) => d.is_none(),
        (PTy::Point, PTy::Point) | (PTy::Profile, PTy::Profile) => true,
        (PTy::Points | PTy::List, PTy::Points | PTy::List) => true,
        (PTy::Bool, PTy::Bool) | (PTy::Str, PTy::Str) => true,
        _ => false,
    }
}

/// A unit the language knows for a dimension: its base unit, or a common one.
fn unit_for(dim: Dim) -> String {
    match dim {
        d if d == Dim::ANGLE => "deg".into(),
        d if d == Dim::ANGULAR_SPEED => "deg/s".into(),
        d if d == Dim::ANGULAR_ACCEL => "deg/s^2".into(),
        d if d == Dim::ANGULAR_JERK => "deg/s^3".into(),
        d if d == Dim::FREQUENCY => "Hz".into(),
        d if d == Dim::ENERGY => "mJ".into(),
        d => d.base_unit(),
    }
}

/// A number as the grammar writes it: digits, an optional fraction and exponent, no sign.
fn num(v: f64) -> String {
    let v = v.abs();
    if v == 0.0 {
        return "0".into();
    }
    if (1e-4..1e7).contains(&v) {
        let s = format!("{v:.6}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s.is_empty() { "0".into() } else { s.into() }
    } else {
        format!("{v:e}")
    }
}
