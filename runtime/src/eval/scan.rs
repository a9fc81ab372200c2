//! `scan dots` and `scan raster` (`scan image` is `image.rs`): the recipe side of scan rasters (the geometry is in
//! `crate::raster`). Binds the settings (`schema::SCAN_KINDS`), builds the region and the
//! rows, takes the overscan from the planner's ramps unless the recipe gives one, checks the
//! pulse rate against the laser before anything runs, and appends the ops:
//!
//! * on the fly, each run of spots is one lit `Line` with pulses by distance every L1 from its
//!   first spot, ending half a pitch past its last (so the count never hangs on rounding);
//! * in dot mode, an unlit `Line` to each spot and a `Fire` op there;
//! * hatch lines are lit `Line`s with the pulse setting in force;
//! * positioning between rows is a `Rapid`, overscan and gaps unlit `Line`s at the speed.

use super::{Cx, Evaluator, Kind, R, Value, bad, geom_error, type_err};
use crate::geometry::{GeomError, Profile, V2};
use crate::kinematics::{self, ToolPose};
use crate::planner::{self, AxisLimits, MAX_AXES, PlannerConfig, ProfileKind};
use crate::program::*;
use crate::raster::{
    self, Family, Firing, Frame, Lattice, Layout, Order, PathOptions, Region, Step,
};
use lase_lang::Span;
use lase_lang::ast::*;
use lase_lang::units::{Dim, format_quantity};
use std::sync::Arc;

/// Dot mode needs two ops per spot and pass, so the op budget allows half as many stops (on
/// the fly needs a few ops per row).
const MAX_DOT_WINDOWS: u64 = (super::MAX_OPS / 2) as u64;
/// Rows a raster may have.
const MAX_ROWS: f64 = 2_000_000.0;
/// NC dwell resolution (`G4 P` with 4 decimals), s.
const NC_TIME_STEP_S: f64 = 1e-4;

/// The settings of one `scan` statement, bound and converted.
#[derive(Default)]
struct ScanSet {
    speed: Option<(f64, Span)>,
    angle: f64,
    order: Option<Order>,
    passes: Option<(u32, Span)>,
    overscan: Option<(f64, Span)>,
    origin: Option<V2>,
    pitch: Option<(f64, Span)>,
    row_pitch: Option<(f64, Span)>,
    rows: Option<(u32, Span)>,
    cols: Option<(u32, Span)>,
    layout: Option<&'static str>,
    pulses: Option<(u32, Span)>,
    mode: Option<(Firing, Span)>,
    inset: f64,
    cross: bool,
    settle: SettleSet,
}

/// Row-start settling as the recipe wrote it (`settle`, `settle_*`), in mm and s.
#[derive(Default)]
struct SettleSet {
    /// Where settling was turned on (`settle`, else the first `settle_*`).
    on: Option<Span>,
    window: Option<((f64, f64), Span)>,
    across: Option<(f64, Span)>,
    step: Option<(f64, Span)>,
    max_steps: Option<u32>,
    timeout: Option<(f64, Span)>,
}

impl Evaluator {
    pub(super) fn scan(
        &mut self,
        kind: &Ident,
        region: &Expr,
        settings: &[Setting],
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        let dots = match kind.name.as_str() {
            "image" => return self.scan_image(region, settings, span, cx),
            "dots" => true,
            "raster" => false,
            _ => {
                return Err(bad(
                    Kind::UnknownName,
                    kind.span,
                    &format!("unknown scan kind `{}`", kind.name),
                    "not a scan kind",
                    Some("write `scan dots` (a dot array) or `scan raster` (a hatch fill)"),
                ));
            }
        };
        self.need_machine(span)?;
        let set = self.scan_settings(settings, cx)?;
        let laser_keys: Vec<Setting> = settings
            .iter()
            .filter(|s| matches!(s.key.name.as_str(), "power" | "spot"))
            .cloned()
            .collect();
        let ls = self.laser_settings(&laser_keys, cx)?;
        let laser = self.current_laser(span, &ls)?;
        let (speed, speed_span) = set.speed.ok_or_else(|| {
            bad(
                Kind::MissingSetting,
                span,
                "`scan` needs a `speed`",
                "no speed",
                Some("add the table speed along the rows, e.g. `speed 20 mm/s`"),
            )
        })?;
        let positive = |v: Option<(f64, Span)>, what: &str| -> R<Option<(f64, Span)>> {
            match v {
                Some((x, sp)) if !(x > 0.0 && x.is_finite()) => Err(bad(
                    Kind::NotPositive,
                    sp,
                    &format!("{what} must be greater than zero"),
                    "not positive",
                    None,
                )),
                v => Ok(v),
            }
        };
        positive(Some((speed, speed_span)), "the scan speed")?;
        self.in_range(speed, &super::bounds::FEED, "the scan speed", speed_span)?;
        let pitch = positive(set.pitch, "the pitch")?;
        let row_pitch = positive(set.row_pitch, "the row pitch")?;
        for (x, sp) in [set.pitch, set.row_pitch].into_iter().flatten() {
            self.in_range(x, &super::bounds::FINE_LENGTH, "the pitch", sp)?;
        }
        if let Some((o, sp)) = set.overscan
            && !(o >= 0.0 && o.is_finite())
        {
            return Err(bad(
                Kind::Negative,
                sp,
                "the overscan cannot be negative",
                "negative",
                None,
            ));
        }
        let passes = set.passes.map_or(1, |p| p.0);
        let pulses = set.pulses.map_or(1, |p| p.0);
        let firing = match (dots, set.mode, pulses) {
            (false, _, _) => Firing::Fly,
            (true, Some((Firing::Fly, sp)), n) if n > 1 => {
                return Err(bad(
                    Kind::Conflict,
                    sp,
                    &format!("{n} pulses per spot cannot be fired on the fly"),
                    "needs the spot at rest",
                    Some(
                        "several pulses on one spot need it at rest: write `mode dot`, or fire \
                         one pulse per spot per pass and repeat with `passes` (seed 3)",
                    ),
                ));
            }
            (true, Some((m, _)), _) => m,
            (true, None, 1) => Firing::Fly,
            (true, None, _) => Firing::Dot,
        };
        let order = set.order.unwrap_or(Order::Serpentine);

        // The region: what the expression is decides the kind of array.
        let rv = self.expr(region, cx)?;
        let angle = set.angle;
        let mut families = Vec::new();
        let default_pitch = pitch.map_or(laser.spot_mm, |p| p.0);
        let need_pitch = || {
            pitch.map(|p| p.0).ok_or_else(|| {
                bad(
                    Kind::MissingSetting,
                    span,
                    &format!("`scan {}` needs a `pitch`", kind.name),
                    "no pitch",
                    Some(if dots {
                        "add the spot spacing along a row, e.g. `pitch 0.2 mm`"
                    } else {
                        "add the spacing of the hatch lines, e.g. `pitch 0.1 mm`"
                    }),
                )
            })
        };
        let layout = match set.layout {
            Some("stagger") | Some("hex") => Layout::Stagger,
            _ => Layout::Grid,
        };
        let lattice = |p: f64, origin: V2| Lattice {
            frame: Frame::new(origin, angle),
            pitch: p,
            row_pitch: row_pitch.map_or(
                if set.layout == Some("hex") {
                    p * 3f64.sqrt() / 2.0
                } else {
                    p
                },
                |r| r.0,
            ),
            layout,
        };
        match (&rv, dots) {
            (Value::Point(p, _), true) => {
                let (Some((rows, _)), Some((cols, _))) = (set.rows, set.cols) else {
                    return Err(bad(
                        Kind::MissingSetting,
                        region.span,
                        "an array given by its origin needs `rows` and `cols`",
                        "array origin",
                        Some("add e.g. `rows 20, cols 30`, or give a region profile instead"),
                    ));
                };
                let lat = lattice(need_pitch()?, V2::new(p[0], p[1]));
                self.rows_fit(f64::from(rows), span)?;
                families.push(Family {
                    frame: lat.frame,
                    row_pitch: lat.row_pitch,
                    rows: raster::grid_rows(&lat, rows, cols),
                    overscan: None,
                    lead: 0.0,
                });
            }
            (Value::List(items), true) if items.iter().all(|v| matches!(v, Value::Point(..))) => {
                let pts: Vec<V2> = items
                    .iter()
                    .filter_map(|v| match v {
                        Value::Point(p, _) => Some(V2::new(p[0], p[1])),
                        _ => None,
                    })
                    .collect();
                if pts.is_empty() {
                    return Err(bad(
                        Kind::Empty,
                        region.span,
                        "no spots to scan",
                        "empty list",
                        None,
                    ));
                }
                let frame = Frame::new(set.origin.unwrap_or(V2::zeros()), angle);
                let rows = raster::point_rows(&frame, &pts, default_pitch);
                families.push(Family {
                    frame,
                    row_pitch: row_pitch.map_or(default_pitch, |r| r.0),
                    rows,
                    overscan: None,
                    lead: 0.0,
                });
            }
            _ => {
                let profiles = self.region_profiles(&rv, region.span, dots)?;
                // A crossing outline has no one inside: the raster would fill part of it.
                if let Some(near) = profiles
                    .iter()
                    .filter(|p| p.closed)
                    .find_map(|p| p.crossing())
                {
                    return Err(geom_error(GeomError::Crosses { near }, region.span, None));
                }
                let reg = Region::new(&profiles, set.inset).map_err(|e| {
                    bad(
                        Kind::Geometry,
                        region.span,
                        &e.to_string(),
                        "this region",
                        Some(match e {
                            raster::RasterError::OpenRegion { .. } => {
                                "close the profile (`closed`), or use `circle`/`rect`"
                            }
                            _ => "use a smaller `inset`",
                        }),
                    )
                })?;
                let p = need_pitch()?;
                let angles: &[f64] = if set.cross {
                    &[0.0, std::f64::consts::FRAC_PI_2]
                } else {
                    &[0.0]
                };
                for extra in angles {
                    let a = angle + extra;
                    let (lo, hi) = reg.bounds(&Frame::new(V2::zeros(), a));
                    let lat0 = lattice(p, V2::zeros());
                    self.rows_fit((hi.y - lo.y) / lat0.row_pitch, span)?;
                    let local0 = Frame::new(V2::zeros(), a);
                    if dots {
                        let origin = set.origin.unwrap_or(local0.to_part(lo.x, lo.y));
                        let lat = Lattice {
                            frame: Frame::new(origin, a),
                            ..lat0
                        };
                        families.push(Family {
                            frame: lat.frame,
                            row_pitch: lat.row_pitch,
                            rows: raster::region_rows(&lat, &reg),
                            overscan: None,
                            lead: 0.0,
                        });
                    } else {
                        let origin = set.origin.unwrap_or(local0.to_part(lo.x, lo.y + 0.5 * p));
                        let frame = Frame::new(origin, a);
                        families.push(Family {
                            frame,
                            row_pitch: p,
                            rows: raster::hatch_rows(&frame, p, &reg),
                            overscan: None,
                            lead: 0.0,
                        });
                    }
                }
            }
        }
        let spots: u64 = families
            .iter()
            .flat_map(|f| f.rows.iter())
            .map(|r| r.spots())
            .sum();
        if families.iter().all(|f| f.rows.is_empty()) {
            return Err(bad(
                Kind::Empty,
                region.span,
                "the region holds no spot or line to scan",
                "nothing to scan",
                Some("check the pitch against the region's size, the `inset` and the `origin`"),
            ));
        }
        if firing == Firing::Dot && spots * u64::from(passes) > MAX_DOT_WINDOWS {
            return Err(bad(
                Kind::TooLarge,
                span,
                &format!(
                    "dot mode would stop at {} spots; lase handles at most {MAX_DOT_WINDOWS}",
                    spots * u64::from(passes)
                ),
                "too many stops",
                Some("fire on the fly (`mode fly`, one pulse per spot per pass)"),
            ));
        }

        // Pulses: on the fly every run's pitch; its rate at the scan speed must suit the laser.
        let base_pulse = self.pulse.clone();
        let pulse_for = |pitch_mm: f64| Pulse {
            mode: PulseMode::Distance { pitch_mm },
            width_s: base_pulse.as_ref().and_then(|p| p.width_s),
            energy_j: base_pulse.as_ref().and_then(|p| p.energy_j),
        };
        if firing == Firing::Fly {
            let mut seen: Vec<f64> = Vec::new();
            for run in families
                .iter()
                .flat_map(|f| f.rows.iter().flat_map(|r| &r.runs))
            {
                if run.count > 0 && !seen.contains(&run.pitch) {
                    seen.push(run.pitch);
                    let l = Laser {
                        pulse: Some(pulse_for(run.pitch)),
                        ..laser.clone()
                    };
                    self.check_pulse_rate(&l, speed, speed_span)?;
                }
            }
            if !dots {
                self.check_pulse_rate(&laser, speed, speed_span)?;
            }
        }

        // Overscan: the recipe's, else the planner's ramp length along each family's rows
        // (left to the lead-ins when they are on: they compute the same length).
        if firing == Firing::Fly {
            let leadin = self.planner_settings_now().leadin;
            for fam in &mut families {
                let needed = self.row_run_up(&fam.frame, speed, speed_span)?;
                // Dot rows on the fly run up `PULSE_CRUISE_MARGIN_S` longer than the ramp needs
                // (the lead-ins do the same), so they are at cruise that long before the first
                // spot: approach points stand that far back.
                let margin = if dots {
                    speed * crate::program::PULSE_CRUISE_MARGIN_S
                } else {
                    0.0
                };
                fam.lead = needed + margin;
                // No lead-ins: the overscan is the run-up, one move from the approach.
                fam.overscan =
                    overscan(set.overscan, leadin, needed, needed + margin, speed, "fire")?;
            }
        }

        // Dot mode: the fire window, each half period a whole number of NC time steps.
        let machine_rate = self.need_machine(span)?.laser.max_pulse_rate_hz;
        let period = match self.pulse.as_ref().map(|p| p.mode) {
            Some(PulseMode::Time { period_s }) if period_s.is_finite() => period_s,
            _ => 1.0 / machine_rate,
        };
        let half = (0.5 * period / NC_TIME_STEP_S - 1e-9).ceil().max(1.0) * NC_TIME_STEP_S;
        let period_nc = 2.0 * half;

        // Every row is at least a move per pass, and every dot-mode spot a stop: held to the op
        // budget before the path is laid out.
        let rows: usize = families.iter().map(|f| f.rows.len()).sum();
        let stops = if firing == Firing::Dot { 2 * spots } else { 0 };
        self.room_for_ops(
            (rows as f64 + stops as f64) * f64::from(passes),
            "this scan",
            "use a coarser pitch or fewer passes",
            span,
        )?;
        let steps = raster::scan_path(
            &families,
            &PathOptions {
                order,
                firing,
                passes,
            },
        );
        let settle = self.settle_template(&set.settle)?;
        let rows_per_pass = rows.max(1) as u32;
        let mut row_starts = 0u32;
        let z = self.pos[2];
        // One laser per kind of op, shared by all of them (issue 18: an op's size).
        let hatch_laser = self.share_laser(laser.clone());
        let fire_laser = Arc::new(Laser {
            pulse: None,
            ..laser.clone()
        });
        let mut dot_laser: Option<(f64, Arc<Laser>)> = None;
        // A row ends where the scan leaves it: at a travel, or at the entry move of the next
        // row (the move just before its `RowStart`); its settle then learns its end op.
        let close_row = |settles: &mut Vec<Settle>, open: &mut Option<usize>, end: usize| {
            if let Some(k) = open.take() {
                settles[k].end = end;
            }
        };
        let mut open_row: Option<usize> = None;
        for (i, &st) in steps.iter().enumerate() {
            if matches!(st, Step::Travel(_))
                || matches!(steps.get(i + 1), Some(Step::RowStart { .. }))
            {
                close_row(&mut self.settles, &mut open_row, self.ops.len());
            }
            let at = |p: V2| [p.x, p.y, z];
            match st {
                Step::Travel(p) => self.push_motion(
                    OpKind::Rapid {
                        to: at(p),
                        orient: None,
                    },
                    span,
                ),
                Step::Idle(p) => self.push_motion(
                    OpKind::Line {
                        to: at(p),
                        feed_mm_s: speed,
                        laser: None,
                        orient: None,
                        row: None,
                    },
                    span,
                ),
                Step::Lit { to, pitch } => {
                    let l = match pitch {
                        Some(p) => match &dot_laser {
                            Some((q, l)) if *q == p => Arc::clone(l),
                            _ => {
                                let l = Arc::new(Laser {
                                    pulse: Some(pulse_for(p)),
                                    ..laser.clone()
                                });
                                dot_laser = Some((p, Arc::clone(&l)));
                                l
                            }
                        },
                        None => hatch_laser.clone(),
                    };
                    self.push_motion(
                        OpKind::Line {
                            to: at(to),
                            feed_mm_s: speed,
                            laser: Some(l),
                            orient: None,
                            row: None,
                        },
                        span,
                    );
                }
                Step::RowStart { dir } => {
                    if let Some(t) = &settle {
                        open_row = Some(self.settles.len());
                        self.settles.push(Settle {
                            op: self.ops.len().saturating_sub(1),
                            end: self.ops.len(),
                            dir: [dir.x, dir.y],
                            pass: row_starts / rows_per_pass,
                            row: row_starts % rows_per_pass,
                            ..t.clone()
                        });
                    }
                    row_starts += 1;
                }
                Step::Fire(_) => self.push(
                    OpKind::Fire {
                        count: pulses,
                        period_s: period_nc,
                        window_s: f64::from(pulses) * period_nc,
                        laser: Arc::clone(&fire_laser),
                    },
                    span,
                ),
            }
        }
        close_row(&mut self.settles, &mut open_row, self.ops.len());
        Ok(())
    }

    /// A motion op, unless it goes nowhere.
    pub(super) fn push_motion(&mut self, kind: OpKind, span: Span) {
        if let Some(to) = match &kind {
            OpKind::Rapid { to, .. } | OpKind::Line { to, .. } => Some(*to),
            _ => None,
        } && (0..3).all(|k| (to[k] - self.pos[k]).abs() <= 1e-12)
        {
            return;
        }
        self.push(kind, span);
    }

    /// The settle parameters every row start of this scan shares (`None`: settling off),
    /// with the seed's defaults (`schema::SETTLE_*`). A window narrower than one step could
    /// never be reached: the loop would step across it forever.
    fn settle_template(&self, s: &SettleSet) -> R<Option<Settle>> {
        use lase_lang::schema::*;
        let Some(on) = s.on else { return Ok(None) };
        let um = 1e-3;
        let window = s
            .window
            .map_or((SETTLE_WINDOW_UM.0 * um, SETTLE_WINDOW_UM.1 * um), |w| w.0);
        let step = s.step.map_or(SETTLE_STEP_UM * um, |x| x.0);
        let across = s.across.map_or(SETTLE_ACROSS_UM * um, |x| x.0);
        if window.1 - window.0 + 1e-12 < step {
            let sp = s.step.or(s.window.map(|w| (0.0, w.1))).map_or(on, |x| x.1);
            return Err(bad(
                Kind::Conflict,
                sp,
                &format!(
                    "a settle window {} wide is narrower than the {} step",
                    format_quantity(window.1 - window.0, Dim::LENGTH),
                    format_quantity(step, Dim::LENGTH)
                ),
                "can never settle",
                Some(
                    "the loop steps across a window narrower than one step: widen `settle_window` or take a smaller `settle_step`",
                ),
            ));
        }
        if 2.0 * across + 1e-12 < step {
            let sp = s.across.map_or(on, |x| x.1);
            return Err(bad(
                Kind::Conflict,
                sp,
                &format!(
                    "a settle window of ±{} across the row is narrower than the {} step",
                    format_quantity(across, Dim::LENGTH),
                    format_quantity(step, Dim::LENGTH)
                ),
                "can never settle",
                Some("`settle_across` must be at least half a `settle_step`"),
            ));
        }
        Ok(Some(Settle {
            op: 0,
            end: 0,
            dir: [1.0, 0.0],
            window_mm: window,
            across_mm: across,
            step_mm: step,
            max_steps: s.max_steps.unwrap_or(SETTLE_MAX_STEPS),
            timeout_s: s.timeout.map_or(SETTLE_TIMEOUT_S, |t| t.0),
            pass: 0,
            row: 0,
            span: on,
        }))
    }

    /// `settle_window [low, high]`: two lengths, low ≤ 0 ≤ high, each within ±1 mm.
    fn settle_window(&self, v: &Value, span: Span) -> R<(f64, f64)> {
        let ctx = "`settle_window`";
        let help = Some(
            "write the accepted error along the row as `[low, high]`, e.g. `[-0.5 um, 1.5 um]`",
        );
        let Value::List(items) = v else {
            return Err(type_err("a list of two lengths", v, span, ctx));
        };
        if items.len() != 2 {
            return Err(bad(
                Kind::OutOfRange,
                span,
                &format!(
                    "{ctx} needs two lengths, [low, high]; this list has {}",
                    items.len()
                ),
                "not [low, high]",
                help,
            ));
        }
        let lo = self.as_dim(&items[0], Dim::LENGTH, span, ctx)?;
        let hi = self.as_dim(&items[1], Dim::LENGTH, span, ctx)?;
        if !(lo <= 0.0 && hi >= 0.0 && lo >= -1.0 && hi <= 1.0) {
            return Err(bad(
                Kind::OutOfRange,
                span,
                &format!(
                    "{ctx} must contain zero and lie within ±1 mm (it is {} … {})",
                    format_quantity(lo, Dim::LENGTH),
                    format_quantity(hi, Dim::LENGTH)
                ),
                "out of range",
                help,
            ));
        }
        Ok((lo, hi))
    }

    fn rows_fit(&self, rows: f64, span: Span) -> R<()> {
        if rows > MAX_ROWS || !rows.is_finite() {
            return Err(bad(
                Kind::TooLarge,
                span,
                &format!("the raster would have {rows:.0} rows"),
                "too many rows",
                Some("check the pitch: it is tiny for the size of the region"),
            ));
        }
        Ok(())
    }

    fn region_profiles(&self, v: &Value, span: Span, dots: bool) -> R<Vec<Profile>> {
        let expected = if dots {
            "a closed profile, a list of them, a list of points or an array origin"
        } else {
            "a closed profile or a list of them"
        };
        match v {
            Value::Profile(p) => Ok(vec![(**p).clone()]),
            Value::List(items) => items
                .iter()
                .map(|it| match it {
                    Value::Profile(p) => Ok((**p).clone()),
                    other => Err(type_err(expected, other, span, "the region of `scan`")),
                })
                .collect(),
            other => Err(type_err(expected, other, span, "the region of `scan`")),
        }
    }

    /// How far a row of `frame` must run to reach `speed` from rest (the planner's ramp along
    /// it), refusing a speed the axes cannot hold along the rows.
    pub(super) fn row_run_up(&self, frame: &Frame, speed: f64, speed_span: Span) -> R<f64> {
        let (v, a, j) = self.row_limits(frame, speed);
        if v < speed * (1.0 - 1e-9) {
            return Err(bad(
                Kind::OutOfRange,
                speed_span,
                &format!(
                    "the scan speed {} is above what the axes allow along the rows ({})",
                    format_quantity(speed, Dim::SPEED),
                    format_quantity(v, Dim::SPEED)
                ),
                "too fast for the axes",
                Some("lower `speed`, or turn the rows (`angle`) along a faster axis"),
            ));
        }
        // Entered at speed, like a lead-in: room for the blends at its ends (`motion::leadin`).
        let room = planner::lead_blend_room(self.planner_settings_now().junction_deviation_mm);
        Ok(planner::lead_distance(v, v, a, j) + room)
    }

    /// Path limits (v, a, j) of a row of `frame` at `speed`, as the planner will derive them
    /// (`planner::move_limits`, the tightest axis along the row).
    pub(super) fn row_limits(&self, frame: &Frame, speed: f64) -> (f64, f64, f64) {
        let Some(machine) = self.machine.as_ref() else {
            return (speed, f64::INFINITY, f64::INFINITY);
        };
        let kin = kinematics::for_machine(machine);
        let z = self.pos[2];
        let a = frame.origin;
        let b = frame.origin + frame.u() * 10.0;
        let q = |p: V2| kin.inverse(&ToolPose::down([p.x, p.y, z]), None).ok();
        let (Some(qa), Some(qb)) = (q(a), q(b)) else {
            return (speed, f64::INFINITY, f64::INFINITY);
        };
        let dq: [f64; MAX_AXES] = std::array::from_fn(|k| qb[k] - qa[k]);
        let mut limits = AxisLimits {
            v: [f64::INFINITY; MAX_AXES],
            a: [f64::INFINITY; MAX_AXES],
            j: [f64::INFINITY; MAX_AXES],
        };
        for (i, l) in self.limits.iter().enumerate().take(MAX_AXES) {
            limits.v[i] = l.v;
            limits.a[i] = l.a;
            limits.j[i] = l.j;
        }
        let p = self.planner_settings_now();
        let cfg = PlannerConfig {
            profile: match p.ramp {
                Ramp::Trapezoid => ProfileKind::Trapezoid,
                Ramp::Scurve => ProfileKind::SCurve,
            },
            junction_deviation: p.junction_deviation_mm,
            path_v: self.path_limits.v,
            path_a: self.path_limits.a,
            path_j: self.path_limits.j,
            lookahead: p.lookahead,
            n_axes: kin.axis_count(),
            corners: planner::Corners::Blend,
        };
        planner::move_limits(&dq, 10.0, speed, &limits, &cfg)
    }

    fn scan_settings(&mut self, settings: &[Setting], cx: &mut Cx) -> R<ScanSet> {
        let mut set = ScanSet::default();
        for s in settings {
            let key = s.key.name.as_str();
            if key == "cross" {
                set.cross = true;
                continue;
            }
            if key == "settle" {
                set.settle.on = Some(s.key.span);
                continue;
            }
            if key.starts_with("settle_") {
                set.settle.on.get_or_insert(s.key.span);
            }
            let Some(e) = &s.value else { continue };
            let word = match &e.kind {
                ExprKind::Var(w) => Some(w.as_str()),
                _ => None,
            };
            match key {
                "order" => {
                    set.order = Some(if word == Some("unidirectional") {
                        Order::Unidirectional
                    } else {
                        Order::Serpentine
                    })
                }
                "layout" => {
                    set.layout = Some(match word {
                        Some("stagger") => "stagger",
                        Some("hex") => "hex",
                        _ => "grid",
                    })
                }
                "mode" => {
                    set.mode = Some((
                        if word == Some("dot") {
                            Firing::Dot
                        } else {
                            Firing::Fly
                        },
                        e.span,
                    ))
                }
                "power" | "spot" => {}
                _ => {
                    let v = self.expr(e, cx)?;
                    let ctx = format!("`{key}`");
                    match key {
                        "speed" => {
                            set.speed = Some((self.as_dim(&v, Dim::SPEED, e.span, &ctx)?, e.span))
                        }
                        "angle" => set.angle = self.as_dim(&v, Dim::ANGLE, e.span, &ctx)?,
                        "overscan" => {
                            set.overscan =
                                Some((self.as_dim(&v, Dim::LENGTH, e.span, &ctx)?, e.span))
                        }
                        "pitch" => {
                            set.pitch = Some((self.as_dim(&v, Dim::LENGTH, e.span, &ctx)?, e.span))
                        }
                        "row_pitch" => {
                            set.row_pitch =
                                Some((self.as_dim(&v, Dim::LENGTH, e.span, &ctx)?, e.span))
                        }
                        "inset" => {
                            let x = self.as_dim(&v, Dim::LENGTH, e.span, &ctx)?;
                            if !(x >= 0.0 && x.is_finite()) {
                                return Err(bad(
                                    Kind::Negative,
                                    e.span,
                                    "an inset cannot be negative",
                                    "negative",
                                    None,
                                ));
                            }
                            set.inset = x;
                        }
                        "settle_window" => {
                            set.settle.window = Some((self.settle_window(&v, e.span)?, e.span))
                        }
                        "settle_across" | "settle_step" => {
                            let x = self.as_dim(&v, Dim::LENGTH, e.span, &ctx)?;
                            let ok = if key == "settle_step" {
                                x > 0.0
                            } else {
                                x >= 0.0
                            };
                            if !(ok && x <= 1.0) {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    &format!(
                                        "{ctx} must be {} and at most 1 mm",
                                        if key == "settle_step" {
                                            "greater than zero"
                                        } else {
                                            "zero or more"
                                        }
                                    ),
                                    "out of range",
                                    Some(
                                        "settling corrects micrometres: e.g. `0.5 um` (the seed's servo increment)",
                                    ),
                                ));
                            }
                            if key == "settle_step" {
                                set.settle.step = Some((x, e.span));
                            } else {
                                set.settle.across = Some((x, e.span));
                            }
                        }
                        "settle_steps" => {
                            let n = self.as_count(&v, e.span, &ctx)?;
                            if !(1..=10_000).contains(&n) {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    &format!("{ctx} must be 1 … 10000"),
                                    "out of range",
                                    None,
                                ));
                            }
                            set.settle.max_steps = Some(n as u32);
                        }
                        "settle_timeout" => {
                            let t = self.as_dim(&v, Dim::TIME, e.span, &ctx)?;
                            if !(t > 0.0 && t <= 3600.0) {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    &format!("{ctx} must be greater than zero and at most 1 h"),
                                    "out of range",
                                    None,
                                ));
                            }
                            set.settle.timeout = Some((t, e.span));
                        }
                        "origin" => {
                            let (p, _) = self.as_point(&v, e.span, &ctx)?;
                            set.origin = Some(V2::new(p[0], p[1]));
                        }
                        "passes" | "pulses" | "rows" | "cols" => {
                            let n = self.as_count(&v, e.span, &ctx)?;
                            if !(1..=i64::from(u32::MAX)).contains(&n) {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    &format!("{ctx} must be at least 1"),
                                    "out of range",
                                    None,
                                ));
                            }
                            let n = Some((n as u32, e.span));
                            match key {
                                "passes" => set.passes = n,
                                "pulses" => set.pulses = n,
                                "rows" => set.rows = n,
                                _ => set.cols = n,
                            }
                        }
                        _ => {}
                    }
                }
            }
        }
        Ok(set)
    }
}

/// A scan's overscan: the recipe's (`given`, at least the `needed` run-up while the lead-ins
/// are on, since they start from its end), none when the lead-ins make it, or `run_up` when
/// there are no lead-ins. `verb` says what the rows do while the speed ramps (the help).
pub(super) fn overscan(
    given: Option<(f64, Span)>,
    leadin: LeadIn,
    needed: f64,
    run_up: f64,
    speed: f64,
    verb: &str,
) -> R<Option<f64>> {
    Ok(match (given, leadin) {
        (Some((o, sp)), LeadIn::Auto) if o + 1e-9 < needed => {
            return Err(bad(
                Kind::OutOfRange,
                sp,
                &format!(
                    "an overscan of {} is shorter than the {} the table needs to reach {}",
                    format_quantity(o, Dim::LENGTH),
                    format_quantity(needed, Dim::LENGTH),
                    format_quantity(speed, Dim::SPEED)
                ),
                "too short to reach the speed",
                Some(&format!(
                    "leave `overscan` out (lase computes it from the planner's ramps), give at \
                     least that much, or write `planner {{ leadin none }}` to {verb} while the \
                     speed ramps"
                )),
            ));
        }
        (Some((o, _)), _) => Some(o),
        (None, LeadIn::Auto) => None,
        (None, LeadIn::Off) => Some(run_up),
    })
}
