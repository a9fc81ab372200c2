//! The process sheet: the machine (`machine`), the limits a recipe may tighten (`limits`),
//! the laser (`laser { ... }`, also the settings of one `follow`), pulses (`pulse { ... }`)
//! and the planner settings (`planner { ... }`), each checked against the machine, and the
//! pulse rate a feed implies.

use super::{Cx, EvalError, Evaluator, Kind, LaserSet, R, Value, bad, bounds, type_err};
use crate::geometry::toolpath::HeadSide;
use crate::machine::{AxisKind, parse_machine};
use crate::program::*;
use lase_lang::Span;
use lase_lang::ast::*;
use lase_lang::diag::did_you_mean;
use lase_lang::units::{Dim, format_quantity};
use std::sync::Arc;

impl Evaluator {
    pub(super) fn select_machine(&mut self, m: &MachineRef, span: Span, cx: &mut Cx) -> R<()> {
        let (name, text, at) = match m {
            MachineRef::Named(id) => match lase_stdlib::machine(&id.name) {
                Some(t) => (
                    format!("<stdlib>/machines/{}.toml", id.name),
                    t.to_string(),
                    id.span,
                ),
                None => {
                    return Err(EvalError::UnknownMachine {
                        name: id.name.clone(),
                        span: id.span,
                        help: did_you_mean(&id.name, lase_stdlib::machine_names()).or_else(|| {
                            Some(format!(
                                "stock machines: {}; or give a file: `machine \"my_machine.toml\"`",
                                lase_stdlib::machine_names().collect::<Vec<_>>().join(", ")
                            ))
                        }),
                    });
                }
            },
            MachineRef::Path(p) => {
                let importer = cx
                    .map
                    .file_of(p.span.start as usize)
                    .map(|f| cx.map.name(f).to_string())
                    .unwrap_or_default();
                let (name, text) = cx
                    .host
                    .machine_file(&importer, &p.value)
                    .map_err(|reason| EvalError::MachineFile {
                        path: p.value.clone(),
                        reason,
                        span: p.span,
                    })?;
                (name, text, p.span)
            }
        };
        let _ = at;
        if !self.ops.is_empty() {
            return Err(EvalError::MachineChanged { span });
        }
        let id = match cx.map.find(&name) {
            Some(id) => id,
            None => cx.map.add(name, text),
        };
        let machine = parse_machine(cx.map.text(id), cx.map.base(id))?;
        self.limits = AxisLimit::of_machine(&machine);
        self.orients_beam = crate::kinematics::for_machine(&machine).oriented();
        self.machine = Some(machine);
        Ok(())
    }

    pub(super) fn set_limits(&mut self, groups: &[LimitGroup], cx: &mut Cx) -> R<()> {
        let span = groups.first().map(|g| g.axis.span).unwrap_or_default();
        let machine = self.need_machine(span)?.clone();
        for g in groups {
            let path = g.axis.name == "path";
            let axis =
                if path {
                    None
                } else {
                    Some(machine.axis_index(&g.axis.name).ok_or_else(|| {
                        EvalError::UnknownAxis {
                            machine: machine.name.clone(),
                            axis: g.axis.name.clone(),
                            span: g.axis.span,
                            help: Some(format!(
                                "`{}` has axes {}; `path:` limits the motion along the path",
                                machine.name,
                                machine
                                    .axes
                                    .iter()
                                    .map(|a| a.name.to_ascii_lowercase())
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            )),
                        }
                    })?)
                };
            let rotary = axis.is_some_and(|i| machine.axes[i].kind == AxisKind::Rotary);
            for s in &g.settings {
                let Some(e) = &s.value else { continue };
                let v = self.expr(e, cx)?;
                let (want, name) = match (s.key.name.as_str(), rotary) {
                    ("v", false) => (Dim::SPEED, "speed"),
                    ("v", true) => (Dim::ANGULAR_SPEED, "speed"),
                    ("a", false) => (Dim::ACCEL, "acceleration"),
                    ("a", true) => (Dim::ANGULAR_ACCEL, "acceleration"),
                    ("j", false) => (Dim::JERK, "jerk"),
                    _ => (Dim::ANGULAR_JERK, "jerk"),
                };
                let x = self.as_dim(&v, want, e.span, &format!("limit `{}`", s.key.name))?;
                if !(x > 0.0) {
                    return Err(bad(
                        Kind::NotPositive,
                        e.span,
                        "limits must be greater than zero",
                        "not positive",
                        None,
                    ));
                }
                if !rotary {
                    let r = match s.key.name.as_str() {
                        "v" => &bounds::FEED,
                        "a" => &bounds::ACCEL,
                        _ => &bounds::JERK,
                    };
                    self.in_range(x, r, &format!("the {name} limit"), e.span)?;
                }
                match axis {
                    None => match s.key.name.as_str() {
                        "v" => self.path_limits.v = x,
                        "a" => self.path_limits.a = x,
                        _ => self.path_limits.j = x,
                    },
                    Some(i) => {
                        let a = &machine.axes[i];
                        let cap = match s.key.name.as_str() {
                            "v" => a.v_max,
                            "a" => a.a_max,
                            _ => a.j_max,
                        };
                        if x > cap * (1.0 + 1e-12) {
                            return Err(EvalError::AboveMachine {
                                what: format!("{} {name} limit", a.name),
                                value: format_quantity(x, want),
                                limit: format_quantity(cap, want),
                                span: e.span,
                                help: Some(
                                    "a recipe can only tighten the machine's limits; raise them in the machine file if the machine allows it"
                                        .into(),
                                ),
                            });
                        }
                        let l = &mut self.limits[i];
                        match s.key.name.as_str() {
                            "v" => l.v = x,
                            "a" => l.a = x,
                            _ => l.j = x,
                        }
                    }
                }
            }
        }
        Ok(())
    }

    pub(super) fn laser_settings(&mut self, set: &[Setting], cx: &mut Cx) -> R<LaserSet> {
        let mut power = None;
        let mut spot = None;
        let mut couple = None;
        let mut standoff = None;
        let mut kerf = None;
        let mut side = None;
        let mut step = None;
        let mut chord_normals = false;
        for s in set {
            let Some(e) = &s.value else { continue };
            if s.key.name == "normals" {
                chord_normals = matches!(&e.kind, ExprKind::Var(w) if w == "chord");
                continue;
            }
            if s.key.name == "side" {
                // A word, checked against the schema's list by the checker.
                side = Some((
                    match &e.kind {
                        ExprKind::Var(w) if w == "inside" => HeadSide::Inside,
                        ExprKind::Var(w) if w == "left" => HeadSide::Left,
                        ExprKind::Var(w) if w == "right" => HeadSide::Right,
                        _ => HeadSide::Outside,
                    },
                    e.span,
                ));
                continue;
            }
            if s.key.name == "couple" {
                // A word, checked against the schema's list: anything but `speed` is `none`.
                couple = Some(match &e.kind {
                    ExprKind::Var(w) if w == "speed" => Coupling::Speed,
                    _ => Coupling::None,
                });
                continue;
            }
            let v = self.expr(e, cx)?;
            match s.key.name.as_str() {
                "power" => {
                    let p = self.as_dim(&v, Dim::POWER, e.span, "`power`")?;
                    if p < 0.0 {
                        return Err(bad(
                            Kind::Negative,
                            e.span,
                            "laser power cannot be negative",
                            "negative",
                            None,
                        ));
                    }
                    check_power(p, self.need_machine(e.span)?, e.span)?;
                    power = Some(p);
                }
                "standoff" => {
                    let d = self.as_dim(&v, Dim::LENGTH, e.span, "`standoff`")?;
                    if !(d >= 0.0 && d.is_finite()) {
                        return Err(bad(
                            Kind::Negative,
                            e.span,
                            "the standoff cannot be negative",
                            "negative",
                            None,
                        ));
                    }
                    standoff = Some(d);
                }
                "step" => step = Some(self.positive_length(&v, e.span, "`step`")?),
                "kerf" => {
                    let k = self.as_dim(&v, Dim::LENGTH, e.span, "`kerf`")?;
                    if !(k >= 0.0) {
                        return Err(bad(
                            Kind::Negative,
                            e.span,
                            "the kerf cannot be negative",
                            "negative",
                            Some("the kerf is the width the beam cuts away, e.g. `kerf 0.15 mm`"),
                        ));
                    }
                    // 0 turns the kerf off; anything else is a width a beam can cut.
                    kerf = Some(if k == 0.0 {
                        0.0
                    } else {
                        self.in_range(k, &bounds::FINE_LENGTH, "the kerf", e.span)?
                    });
                }
                _ => {
                    let d = self.as_dim(&v, Dim::LENGTH, e.span, "`spot`")?;
                    if !(d > 0.0) {
                        return Err(bad(
                            Kind::NotPositive,
                            e.span,
                            "the spot diameter must be greater than zero",
                            "not positive",
                            None,
                        ));
                    }
                    spot = Some(self.in_range(d, &bounds::FINE_LENGTH, "the spot", e.span)?);
                }
            }
        }
        Ok(LaserSet {
            power,
            spot,
            couple,
            standoff,
            kerf,
            side,
            step,
            chord_normals,
        })
    }

    pub(super) fn positive_length(&self, v: &Value, span: Span, ctx: &str) -> R<f64> {
        let x = self.as_dim(v, Dim::LENGTH, span, ctx)?;
        if !(x > 0.0 && x.is_finite()) {
            return Err(bad(
                Kind::NotPositive,
                span,
                "must be greater than zero",
                "not positive",
                None,
            ));
        }
        self.in_range(x, &bounds::FINE_LENGTH, ctx, span)
    }

    pub(super) fn pulse_settings(&mut self, set: &[Setting], cx: &mut Cx) -> R<()> {
        let mut pulse = self.pulse.clone().unwrap_or(Pulse {
            mode: PulseMode::Time {
                period_s: f64::INFINITY,
            },
            width_s: None,
            energy_j: None,
        });
        let mut mode_set = self.pulse.is_some();
        for s in set {
            let Some(e) = &s.value else { continue };
            let v = self.expr(e, cx)?;
            let positive = |x: f64| {
                if x > 0.0 {
                    Ok(x)
                } else {
                    Err(bad(
                        Kind::NotPositive,
                        e.span,
                        "pulse settings must be greater than zero",
                        "not positive",
                        None,
                    ))
                }
            };
            match s.key.name.as_str() {
                "interval" => {
                    mode_set = true;
                    pulse.mode = match &v {
                        Value::Num(x, d) if *d == Dim::LENGTH => PulseMode::Distance {
                            pitch_mm: positive(*x)?,
                        },
                        Value::Num(x, d) if *d == Dim::TIME => PulseMode::Time {
                            period_s: positive(*x)?,
                        },
                        other => {
                            return Err(type_err(
                                "a length or a time",
                                other,
                                e.span,
                                "`interval`",
                            ));
                        }
                    }
                }
                "rate" => {
                    mode_set = true;
                    let f = positive(self.as_dim(&v, Dim::FREQUENCY, e.span, "`rate`")?)?;
                    check_pulse_rate(f, None, self.need_machine(e.span)?, e.span)?;
                    pulse.mode = PulseMode::Time { period_s: 1.0 / f };
                }
                "width" => {
                    pulse.width_s =
                        Some(positive(self.as_dim(&v, Dim::TIME, e.span, "`width`")?)?)
                }
                _ => {
                    pulse.energy_j = Some(positive(self.as_dim(
                        &v,
                        Dim::ENERGY,
                        e.span,
                        "`energy`",
                    )?)?)
                }
            }
        }
        self.pulse_in_range(&pulse, set)?;
        // The setting that makes energy and rate meet: the energy if written, else the rate.
        let at = |k: &str| {
            set.iter()
                .find(|s| s.key.name == k)?
                .value
                .as_ref()
                .map(|e| e.span)
        };
        if let (Some(power), Some(span)) = (
            self.laser.power_w,
            at("energy")
                .or_else(|| at("rate"))
                .or_else(|| at("interval")),
        ) {
            pulse_energy_agrees(power, &pulse, span, "this pulse setting")?;
        }
        if !mode_set {
            let span = set.first().map(|s| s.span).unwrap_or_default();
            return Err(bad(
                Kind::MissingSetting,
                span,
                "pulses need an interval or a rate",
                "no interval",
                Some(
                    "add `interval 0.2 mm` (by distance), `interval 50 us` or `rate 20 kHz` (by time)",
                ),
            ));
        }
        self.pulse = Some(pulse);
        Ok(())
    }

    /// `rotary { diameter D }` (issue 20): the object's diameter on a rotary attachment,
    /// written into the program's machine, whose kinematics maps the surface with it. Before
    /// any move: the moves already made were mapped with the diameter they were made under.
    pub(super) fn rotary_settings(&mut self, set: &[Setting], span: Span, cx: &mut Cx) -> R<()> {
        let machine = self.need_machine(span)?;
        if machine.rotary.is_none() {
            let help = format!(
                "machine `{}` has no rotary attachment; use one whose kinematics is `rotary` \
                 (the stock `xy_rotary`)",
                machine.name
            );
            return Err(bad(
                Kind::Conflict,
                span,
                "`rotary` sets the object on a rotary attachment",
                "no rotary attachment",
                Some(help.as_str()),
            ));
        }
        if !self.ops.is_empty() {
            return Err(bad(
                Kind::Conflict,
                span,
                "the object's diameter cannot change once the recipe has moved",
                "after a move",
                Some("set `rotary { diameter ... }` before the first move"),
            ));
        }
        for s in set {
            let Some(e) = &s.value else { continue };
            if s.key.name == "diameter" {
                let v = self.expr(e, cx)?;
                let d = self.positive_length(&v, e.span, "`diameter`")?;
                if let Some(r) = self.machine.as_mut().and_then(|m| m.rotary.as_mut()) {
                    r.diameter_mm = d;
                }
            }
        }
        Ok(())
    }

    pub(super) fn planner_settings(&mut self, set: &[Setting], span: Span, cx: &mut Cx) -> R<()> {
        self.need_machine(span)?;
        let mut p = self.planner_settings_now();
        for s in set {
            let Some(e) = &s.value else { continue };
            match s.key.name.as_str() {
                "ramp" => {
                    p.ramp = match &e.kind {
                        ExprKind::Var(w) if w == "trapezoid" => Ramp::Trapezoid,
                        _ => Ramp::Scurve,
                    }
                }
                "step" => {
                    let v = self.expr(e, cx)?;
                    self.scan_step_mm = Some(self.positive_length(&v, e.span, "`step`")?);
                }
                "order" => {
                    p.order = match &e.kind {
                        ExprKind::Var(w) if w == "nearest" => CutOrder::Nearest,
                        ExprKind::Var(w) if w == "inner_first" => CutOrder::InnerFirst,
                        _ => CutOrder::Source,
                    }
                }
                "origin" => {
                    p.origin = match &e.kind {
                        ExprKind::Var(w) if w == "current" => JobOrigin::Current,
                        ExprKind::Var(w) => w
                            .strip_prefix('g')
                            .and_then(|n| n.parse::<u8>().ok())
                            .filter(|n| (54..=59).contains(n))
                            .map_or(JobOrigin::Absolute, JobOrigin::Work),
                        _ => JobOrigin::Absolute,
                    }
                }
                "leadin" => {
                    p.leadin = match &e.kind {
                        ExprKind::Var(w) if w == "none" => LeadIn::Off,
                        _ => LeadIn::Auto,
                    }
                }
                "corner" | "tolerance" => {
                    let v = self.expr(e, cx)?;
                    let x = self.as_dim(&v, Dim::LENGTH, e.span, &format!("`{}`", s.key.name))?;
                    if !(x > 0.0) {
                        return Err(bad(
                            Kind::NotPositive,
                            e.span,
                            "must be greater than zero",
                            "not positive",
                            None,
                        ));
                    }
                    let what = format!("the {}", s.key.name);
                    let x = self.in_range(x, &bounds::TOLERANCE, &what, e.span)?;
                    if s.key.name == "corner" {
                        p.junction_deviation_mm = x;
                    } else {
                        p.arc_tolerance_mm = x;
                    }
                }
                _ => {
                    let v = self.expr(e, cx)?;
                    let n = self.as_count(&v, e.span, "`lookahead`")?;
                    if n < 1 {
                        return Err(bad(
                            Kind::OutOfRange,
                            e.span,
                            "look-ahead needs at least 1 move",
                            "too small",
                            None,
                        ));
                    }
                    p.lookahead = Some(n as usize);
                }
            }
        }
        self.planner = Some(p);
        Ok(())
    }

    pub(super) fn current_laser(&self, span: Span, set: &LaserSet) -> R<Laser> {
        let power_w = set
            .power
            .or(self.laser.power_w)
            .ok_or(EvalError::NoPower { span })?;
        Ok(Laser {
            power_w,
            spot_mm: set.spot.unwrap_or(self.laser.spot_mm),
            pulse: self.pulse.clone(),
            couple: set.couple.unwrap_or(self.laser.couple),
            kerf_mm: self.laser.kerf_mm,
        })
    }

    /// `laser` as an op carries it: the one `Arc` of the lit ops before, if it is the same
    /// laser. A loop of a million lit moves then holds one laser, not a million (80 bytes an
    /// op; issue 18).
    pub(super) fn share_laser(&mut self, laser: Laser) -> Arc<Laser> {
        match &self.shared_laser {
            Some(l) if **l == laser => Arc::clone(l),
            _ => {
                let l = Arc::new(laser);
                self.shared_laser = Some(Arc::clone(&l));
                l
            }
        }
    }

    /// Pulses by distance at `feed`, held to the laser's maximum rate at the speed's span
    /// (pulses by time are held by `ProcessProgram::validate`, at the move).
    pub(super) fn check_pulse_rate(&self, laser: &Laser, feed: f64, span: Span) -> R<()> {
        let Some(Pulse {
            mode: PulseMode::Distance { .. },
            ..
        }) = &laser.pulse
        else {
            return Ok(());
        };
        Ok(laser.check_pulse_rate(feed, self.need_machine(span)?, span)?)
    }

    /// The planner settings in force (machine defaults, overridden by `planner`).
    pub(super) fn planner_settings_now(&self) -> PlannerSettings {
        self.planner.clone().unwrap_or_else(|| {
            let m = self.machine.as_ref();
            PlannerSettings {
                ramp: m.map_or(Ramp::Trapezoid, |m| m.ramp),
                junction_deviation_mm: m.map_or(0.01, |m| m.junction_deviation_mm),
                arc_tolerance_mm: m.map_or(0.001, |m| m.arc_tolerance_mm),
                lookahead: None,
                leadin: LeadIn::Auto,
                order: CutOrder::Source,
                origin: JobOrigin::Absolute,
            }
        })
    }
}

/// Pulses by time at a rate `f` with energy `E` each deliver `E·f` of average power: a laser
/// `power` that differs (by more than 1 %) contradicts them, and one of the three is a slip
/// (`rate 20 kHz, energy 1 mJ` is 20 W, not the 50 W set). An error, not a warning: lase sends
/// the power, so the energy written beside it would silently not be what the part gets.
/// Pulses by distance have no fixed rate (it follows the speed) and are not checked.
pub(super) fn pulse_energy_agrees(power_w: f64, pulse: &Pulse, span: Span, what: &str) -> R<()> {
    let (PulseMode::Time { period_s }, Some(energy)) = (pulse.mode, pulse.energy_j) else {
        return Ok(());
    };
    if !period_s.is_finite() || power_w <= 0.0 {
        return Ok(());
    }
    let rate = 1.0 / period_s;
    let average = energy * rate;
    if (average - power_w).abs() <= 0.01 * power_w {
        return Ok(());
    }
    // In the units a laser's data sheet uses: mJ, kHz.
    let q = |v: f64, d: Dim| {
        let n = lase_lang::units::format_number;
        if d == Dim::ENERGY && v < 1.0 {
            format!("{} mJ", n(v * 1e3))
        } else if d == Dim::FREQUENCY && v >= 1e3 {
            format!("{} kHz", n(v / 1e3))
        } else {
            format_quantity(v, d)
        }
    };
    Err(EvalError::Conflict {
        message: format!(
            "pulses of {} at {} deliver {} on average, but the laser power is {}",
            q(energy, Dim::ENERGY),
            q(rate, Dim::FREQUENCY),
            q(average, Dim::POWER),
            q(power_w, Dim::POWER),
        ),
        span,
        label: format!(
            "{what}: {} × {} = {}",
            q(energy, Dim::ENERGY),
            q(rate, Dim::FREQUENCY),
            q(average, Dim::POWER)
        ),
        help: Some(format!(
            "power = energy × rate: set `energy {}`, `rate {}`, or `laser {{ power {} }}`",
            q(power_w / rate, Dim::ENERGY),
            q(power_w / energy, Dim::FREQUENCY),
            q(average, Dim::POWER),
        )),
    })
}
