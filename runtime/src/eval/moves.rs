//! Motion statements: `move` (rapid or at a feed, keeping the beam orientation on machines
//! that orient it) and `follow` (a profile as lines and arcs on a flat bed, or as an oriented
//! toolpath of poses on machines that orient the beam).

use super::{Cx, EvalError, Evaluator, Kind, LaserSet, R, Value, bad, geom_error, type_err};
use crate::geometry::Profile;
use crate::geometry::toolpath::{HeadSide, Normals, Station, ToolpathError, oriented_stations};
use crate::program::*;
use lase_lang::Span;
use lase_lang::ast::*;
use lase_lang::units::{Dim, format_quantity};
use std::rc::Rc;
use std::sync::Arc;

impl Evaluator {
    pub(super) fn move_stmt(
        &mut self,
        kind: MoveKind,
        target: &Expr,
        speed: &MoveSpeed,
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        let v = self.expr(target, cx)?;
        let (p, n) = self.as_point(&v, target.span, "the target of `move`")?;
        self.need_machine(span)?;
        let mut to = self.pos;
        for k in 0..n as usize {
            to[k] = match kind {
                MoveKind::To => p[k],
                MoveKind::By => self.pos[k] + p[k],
            };
        }
        let orient = self.move_orient(span)?.map(Box::new);
        match speed {
            MoveSpeed::Rapid => self.push(OpKind::Rapid { to, orient }, span),
            MoveSpeed::At(e) => {
                let v = self.expr(e, cx)?;
                let feed = self.feed(&v, e.span)?;
                let laser = if self.laser.on {
                    let l = self.current_laser(span, &LaserSet::default())?;
                    self.check_pulse_rate(&l, feed, e.span)?;
                    Some(self.share_laser(l))
                } else {
                    None
                };
                self.push(
                    OpKind::Line {
                        to,
                        feed_mm_s: feed,
                        laser,
                        orient,
                        row: None,
                    },
                    span,
                );
            }
        }
        Ok(())
    }

    /// Whether the selected machine orients the beam (cam X-ω-B, arm).
    pub(super) fn oriented(&self) -> bool {
        self.machine.is_some() && self.orients_beam
    }

    /// The orientation a `move` keeps: the last one on an oriented machine (a move there
    /// needs one), none on a flat bed.
    pub(super) fn move_orient(&self, span: Span) -> R<Option<Orient>> {
        if !self.oriented() {
            return Ok(None);
        }
        match self.orient {
            Some(o) => Ok(Some(o)),
            None => Err(bad(
                Kind::NoOrientation,
                span,
                "this machine orients the beam, and no path has set its direction yet",
                "which way does the beam point here?",
                Some(
                    "`follow` a profile first (it sets the beam along the surface normal); a \
                     `move` keeps the beam direction and standoff of the move before it",
                ),
            )),
        }
    }

    pub(super) fn feed(&self, v: &Value, span: Span) -> R<f64> {
        let f = self.as_dim(v, Dim::SPEED, span, "a speed")?;
        if !(f > 0.0) {
            return Err(bad(
                Kind::NotPositive,
                span,
                "a speed must be greater than zero",
                "not positive",
                None,
            ));
        }
        self.in_range(f, &super::bounds::FEED, "the speed", span)
    }

    pub(super) fn follow(
        &mut self,
        path: &Expr,
        speed: &Expr,
        settings: &[Setting],
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        let v = self.expr(path, cx)?;
        // One profile, or the lit pieces of one (`tabs`), cut in turn with the beam off
        // across the gaps between them.
        let pieces: Vec<Rc<Profile>> = match &v {
            Value::Profile(p) => vec![p.clone()],
            Value::List(items) if !items.is_empty() => items
                .iter()
                .map(|it| match it {
                    Value::Profile(p) => Ok(p.clone()),
                    other => Err(type_err(
                        "a profile",
                        other,
                        path.span,
                        "each piece of the path of `follow`",
                    )),
                })
                .collect::<R<_>>()?,
            _ => {
                return Err(type_err(
                    "a profile or a list of profiles",
                    &v,
                    path.span,
                    "the path of `follow`",
                ));
            }
        };
        let sv = self.expr(speed, cx)?;
        let feed = self.feed(&sv, speed.span)?;
        let set = self.laser_settings(settings, cx)?;
        self.need_machine(span)?;
        let laser = self.current_laser(span, &set)?;
        self.check_pulse_rate(&laser, feed, speed.span)?;
        let laser = self.share_laser(laser);
        if self.oriented() {
            for profile in &pieces {
                self.follow_oriented(profile, feed, laser.clone(), &set, span)?;
            }
            return Ok(());
        }
        if let Some((_, side_span)) = set.side {
            return Err(bad(
                Kind::Conflict,
                side_span,
                "`side` only applies to machines that orient the beam",
                "the beam of this machine always points down",
                Some("remove `side`, or choose a machine such as cam_xwb or arm_3r"),
            ));
        }
        self.room_for_ops(
            pieces.iter().map(|p| p.segs.len() as f64 + 1.0).sum(),
            "this path",
            "use fewer points (a path this fine is finer than the machine resolves)",
            span,
        )?;
        let z = self.pos[2];
        for (k, profile) in pieces.iter().enumerate() {
            let start = profile.start();
            if (start.x - self.pos[0]).hypot(start.y - self.pos[1]) > 1e-9 {
                let to = [start.x, start.y, z];
                let kind = if k == 0 {
                    // Going to the start of a path is part of following it: a rapid, laser off.
                    OpKind::Rapid { to, orient: None }
                } else {
                    // A tab: crossed at the cutting speed with the beam off, so the path stays
                    // one cut (ordered, entered and given its kerf as one).
                    OpKind::Line {
                        to,
                        feed_mm_s: feed,
                        laser: None,
                        orient: None,
                        row: None,
                    }
                };
                self.push(kind, span);
            }
            for kind in super::order::profile_ops(profile, z, feed, &laser) {
                self.push(kind, span);
            }
        }
        Ok(())
    }

    /// The stations with steps shortened where the controller's joint-linear block between
    /// two poses would take the spot off the surface by more than the tolerance or ripple its
    /// speed by more than 0.1 % (`kinematics::chords`, issue 13 item 4). New stations are
    /// exact: spot on the profile, beam along its normal.
    fn chord_true(
        &self,
        profile: &Profile,
        stations: Vec<Station>,
        z: f64,
        standoff: f64,
        head_on_left: bool,
        tol: f64,
    ) -> Vec<Station> {
        use crate::kinematics::chords::{ChordBudget, Surface, refine};
        let Some(machine) = self.machine.as_ref() else {
            return stations;
        };
        let kin = crate::kinematics::for_machine(machine);
        let surface = Surface {
            profile,
            z,
            standoff,
            head_on_left,
        };
        let s: Vec<f64> = stations.iter().map(|st| st.s).collect();
        let room = super::MAX_OPS.saturating_sub(self.ops.len()) + 1;
        let refined = refine(&*kin, &surface, &s, ChordBudget::for_tolerance(tol), room);
        if refined.len() == s.len() {
            return stations;
        }
        // The caller's stations are kept as they were (a closed path's last repeats its first
        // exactly); only the new ones come from the profile's frames.
        let mut old = stations.into_iter().peekable();
        refined
            .into_iter()
            .map(|si| {
                old.next_if(|st| st.s == si).unwrap_or_else(|| {
                    let (pose, _) = surface.pose(si);
                    Station {
                        s: si,
                        point: crate::geometry::V2::new(pose.spot.x, pose.spot.y),
                        beam: crate::geometry::V2::new(pose.beam.x, pose.beam.y),
                    }
                })
            })
            .collect()
    }

    /// `follow` on a machine that orients the beam (PROCESS.md §1 and §2): the profile becomes
    /// an oriented toolpath (`geometry::toolpath`: equal arc-length steps, the beam back along
    /// the exact normal on the head's side, or seed 1's chord normals with `normals chord`, and
    /// the fold-over rule), and every station a pose with the lens at the standoff. Equal steps
    /// at one feed give constant surface speed.
    pub(super) fn follow_oriented(
        &mut self,
        profile: &Profile,
        feed: f64,
        laser: Arc<Laser>,
        set: &LaserSet,
        span: Span,
    ) -> R<()> {
        let machine = self.need_machine(span)?.name.clone();
        let standoff = set.standoff.or(self.laser.standoff_mm).ok_or_else(|| {
            bad(
                Kind::MissingSetting,
                span,
                &format!("machine `{machine}` orients the beam: it needs a standoff"),
                "no standoff in force",
                Some("write `laser { standoff 12 mm }`, or `follow ... { standoff 12 mm }`"),
            )
        })?;
        let side = match set.side {
            Some((s @ (HeadSide::Outside | HeadSide::Inside), sp)) if !profile.closed => {
                let word = if s == HeadSide::Outside {
                    "outside"
                } else {
                    "inside"
                };
                return Err(bad(
                    Kind::Conflict,
                    sp,
                    &format!("`side {word}` needs a closed profile"),
                    "this path is open",
                    Some(
                        "say which side of the direction of travel the head stands on: `side left` or `side right`",
                    ),
                ));
            }
            Some((s, _)) => s,
            None if profile.closed => HeadSide::Outside,
            None => HeadSide::Left,
        };
        let step = set.step.or(self.scan_step_mm).unwrap_or(1.0);
        let tol = self.planner_settings_now().arc_tolerance_mm;
        let normals = if set.chord_normals {
            Normals::Chord
        } else {
            Normals::Exact
        };
        // A station per step at least (the step only ever shortens), counted before resampling.
        self.room_for_ops(
            profile.length() / step,
            "this path at this step",
            "use a coarser `step`",
            span,
        )?;
        let stations =
            oriented_stations(profile, step, tol, standoff, side.on_left(profile), normals)
                .map_err(|e| match e {
                    ToolpathError::Geometry(g) => geom_error(g, span, None),
                    ToolpathError::FoldOver {
                        r_min,
                        s_start,
                        s_end,
                    } => EvalError::Geometry {
                        message: format!(
                            "the surface is concave with a radius down to {} toward the head, \
                             less than the standoff {}: the lens path folds over between s = {} \
                             and {}",
                            format_quantity(r_min, Dim::LENGTH),
                            format_quantity(standoff, Dim::LENGTH),
                            format_quantity(s_start, Dim::LENGTH),
                            format_quantity(s_end, Dim::LENGTH)
                        ),
                        span,
                        label: "this path".into(),
                        help: Some(format!(
                            "use a standoff below {}, or round the concave region of the profile",
                            format_quantity(r_min, Dim::LENGTH)
                        )),
                    },
                })?;
        let z = self.pos[2];
        let stations = if normals == Normals::Exact {
            self.chord_true(profile, stations, z, standoff, side.on_left(profile), tol)
        } else {
            // Seed 1's chord normals stay as the paper steps them: they are kept to be
            // compared with, not to be run true.
            stations
        };
        self.room_for_ops(
            stations.len() as f64,
            "this path at the steps its tolerance needs",
            "use a coarser `planner { tolerance }`",
            span,
        )?;
        let pose = |st: &Station| {
            (
                [st.point.x, st.point.y, z],
                Orient {
                    beam: [st.beam.x, st.beam.y, 0.0],
                    standoff_mm: standoff,
                },
            )
        };
        let Some(first) = stations.first() else {
            return Ok(());
        };
        let (p0, o0) = pose(first);
        if crate::program::dist(p0, self.pos) > 1e-9 || self.orient != Some(o0) {
            // Going to the start of a path, beam already along its normal: a rapid, laser off.
            self.push(
                OpKind::Rapid {
                    to: p0,
                    orient: Some(Box::new(o0)),
                },
                span,
            );
        }
        for st in &stations[1..] {
            let (p, o) = pose(st);
            if crate::program::dist(p, self.pos) <= 1e-12 {
                continue;
            }
            self.push(
                OpKind::Line {
                    to: p,
                    feed_mm_s: feed,
                    laser: Some(laser.clone()),
                    orient: Some(Box::new(o)),
                    row: None,
                },
                span,
            );
        }
        Ok(())
    }
}
