//! Profile constructors (`profile polyline(...)`, `line`, `arc`, `circle`, `rect`,
//! `spline`), cams from a motion program or a lift table, profiles imported from DXF files
//! and SVG path data, and the data files they read through the `Host`.

use super::{Cx, EvalError, Evaluator, Kind, R, Value, bad, geom_error, type_err};
use crate::geometry::{Profile, V2};
use lase_lang::ast::*;
use lase_lang::diag::did_you_mean;
use lase_lang::units::{self, Dim};
use lase_lang::{Span, schema};
use std::rc::Rc;

impl Evaluator {
    pub(super) fn profile(
        &mut self,
        kind: &Ident,
        args: &[Arg],
        flags: &[Ident],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        let Some(pk) = schema::profile_kind(&kind.name) else {
            return Err(bad(
                Kind::UnknownName,
                kind.span,
                "unknown profile",
                "unknown",
                None,
            ));
        };
        let names: Vec<&str> = pk.params.iter().map(|p| p.name).collect();
        let a = self.bind_args(&names, args, cx)?;
        let has = |f: &str| flags.iter().any(|x| x.name == f);
        let get = |i: usize| {
            a.get(i).cloned().flatten().ok_or_else(|| {
                bad(
                    Kind::MissingArgument,
                    span,
                    &format!("missing `{}`", names[i]),
                    "in this profile",
                    None,
                )
            })
        };
        let pt = |s: &Self, i: usize| -> R<V2> {
            let (v, sp) = get(i)?;
            let (p, _) = s.as_point(&v, sp, &format!("`{}`", names[i]))?;
            Ok(V2::new(p[0], p[1]))
        };
        let len = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = get(i)?;
            s.as_dim(&v, Dim::LENGTH, sp, &format!("`{}`", names[i]))
        };
        let ang = |s: &Self, i: usize| -> R<f64> {
            let (v, sp) = get(i)?;
            s.as_dim(&v, Dim::ANGLE, sp, &format!("`{}`", names[i]))
        };
        // A radius below what the NC text resolves draws a point (a circle of 1e-300 mm is
        // emitted as arcs about the spot itself); a negative one is the geometry's to refuse.
        let radius = |s: &Self| -> R<f64> {
            let (v, sp) = get(1)?;
            let r = s.as_dim(&v, Dim::LENGTH, sp, "`radius`")?;
            if r > 0.0 {
                s.in_range(r, &super::bounds::FINE_LENGTH, "the radius", sp)?;
            }
            Ok(r)
        };
        if pk.name == "text" {
            return self.text_profile(&a, span, cx);
        }
        let r = match pk.name {
            "polyline" => {
                let (v, sp) = get(0)?;
                let Value::List(items) = v else {
                    return Err(type_err("a list of points", &v, sp, "`points`"));
                };
                let mut pts = Vec::with_capacity(items.len());
                for it in items.iter() {
                    let (p, _) = self.as_point(it, sp, "a polyline point")?;
                    pts.push(V2::new(p[0], p[1]));
                }
                Profile::polyline(&pts, has("closed"))
            }
            "line" => Profile::polyline(&[pt(self, 0)?, pt(self, 1)?], false),
            "arc" => {
                let (a0, a1) = (ang(self, 2)?, ang(self, 3)?);
                // An end on the start (mod one turn) would otherwise be read as a whole turn:
                // a lit full circle where the recipe meant nothing, or a typo.
                let turns = (a1 - a0) / std::f64::consts::TAU;
                if a0.is_finite() && a1.is_finite() && (turns - turns.round()).abs() < 1e-9 {
                    let at = get(3)?.1;
                    return Err(bad(
                        Kind::OutOfRange,
                        at,
                        &format!(
                            "this arc ends where it starts (start {}, end {}): it sweeps nothing",
                            units::format_quantity(a0, Dim::ANGLE),
                            units::format_quantity(a1, Dim::ANGLE)
                        ),
                        "zero sweep",
                        Some(
                            "give `end` a different angle from `start`; for a full circle write \
                             `profile circle(center, radius, start: ...)`",
                        ),
                    ));
                }
                Profile::arc(pt(self, 0)?, radius(self)?, a0, a1, !has("cw"))
            }
            "circle" => {
                let a0 = match a.get(2).cloned().flatten() {
                    Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`start`")?,
                    None => 0.0,
                };
                Profile::circle(pt(self, 0)?, radius(self)?, a0, !has("cw"))
            }
            "rect" => {
                let c = pt(self, 0)?;
                let w = len(self, 1)?;
                let h = len(self, 2)?;
                if !(w > 0.0 && h > 0.0) {
                    return Err(bad(
                        Kind::NotPositive,
                        span,
                        "a rectangle needs a positive width and height",
                        "empty rectangle",
                        None,
                    ));
                }
                Profile::polyline(
                    &[
                        c,
                        c + V2::new(w, 0.0),
                        c + V2::new(w, h),
                        c + V2::new(0.0, h),
                    ],
                    true,
                )
            }
            "spline" => {
                let (v, sp) = get(0)?;
                let Value::List(items) = v else {
                    return Err(type_err("a list of points", &v, sp, "`points`"));
                };
                let mut pts = Vec::with_capacity(items.len());
                for it in items.iter() {
                    let (p, _) = self.as_point(it, sp, "a spline point")?;
                    pts.push(V2::new(p[0], p[1]));
                }
                Profile::interpolate(&pts, has("closed"))
            }
            "cam" => return self.cam_profile(&a, span, cx),
            "dxf" | "svg" => return self.imported_profile(pk.name, &a, span, cx),
            other => {
                return Err(bad(
                    Kind::UnknownName,
                    kind.span,
                    &format!("`profile {other}` is not supported yet"),
                    "not supported",
                    None,
                ));
            }
        };
        r.map(|p| Value::Profile(Rc::new(p)))
            .map_err(|g| geom_error(g, span, None))
    }

    /// `profile cam(...)`: a motion program (rise, top dwell, fall, base dwell) or a lift table.
    pub(super) fn cam_profile(
        &mut self,
        a: &[Option<(Value, Span)>],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        use crate::geometry::cam::{CamLaw, CamSegment, CamSegmentKind};
        let arg = |i: usize| a.get(i).cloned().flatten();
        let (bv, bs) = arg(0).ok_or_else(|| {
            bad(
                Kind::MissingArgument,
                span,
                "missing `base`",
                "in this cam",
                None,
            )
        })?;
        let base = self.positive_length(&bv, bs, "`base`")?;
        if let Some((tv, ts)) = arg(6) {
            let Value::Str(path) = &tv else {
                return Err(type_err("a file name", &tv, ts, "`table`"));
            };
            if let Some((_, ls)) = arg(1) {
                return Err(bad(
                    Kind::Conflict,
                    ls,
                    "a cam takes its lift from a motion program or from a table, not both",
                    "remove this",
                    Some("with `table`, the lift of every angle is in the file"),
                ));
            }
            let text = self.data_file(path, ts, cx)?;
            let prof =
                Profile::cam_from_lift_csv(base, &text).map_err(|e| EvalError::Geometry {
                    message: format!("lift table \"{path}\": {e}"),
                    span: ts,
                    label: "this table".into(),
                    help: Some(
                        "one `angle_deg, lift_mm` row a line, angles increasing within one turn"
                            .into(),
                    ),
                })?;
            return Ok(Value::Profile(Rc::new(prof)));
        }
        let need = |i: usize, name: &str| {
            arg(i).ok_or_else(|| {
                bad(
                    Kind::MissingArgument,
                    span,
                    &format!("a cam motion program needs `{name}`"),
                    "in this cam",
                    Some("give `lift`, `rise` (and optionally `top`, `fall`, `law`), or a lift `table`"),
                )
            })
        };
        let (lv, ls) = need(1, "lift")?;
        let lift = self.positive_length(&lv, ls, "`lift`")?;
        let (rv, rs) = need(2, "rise")?;
        let rise = self.as_dim(&rv, Dim::ANGLE, rs, "`rise`")?.to_degrees();
        let dwell = match arg(3) {
            Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`top`")?.to_degrees(),
            None => 0.0,
        };
        let fall = match arg(4) {
            Some((v, sp)) => self.as_dim(&v, Dim::ANGLE, sp, "`fall`")?.to_degrees(),
            None => rise,
        };
        let law = match arg(5) {
            None => CamLaw::Cycloidal,
            Some((Value::Str(w), sp)) => match &*w {
                "harmonic" => CamLaw::Harmonic,
                "cycloidal" => CamLaw::Cycloidal,
                "345" | "3-4-5" | "poly345" => CamLaw::Poly345,
                "modified_trapezoid" => CamLaw::ModifiedTrapezoid,
                other => {
                    let help = did_you_mean(
                        other,
                        ["harmonic", "cycloidal", "345", "modified_trapezoid"].into_iter(),
                    )
                    .unwrap_or_else(|| {
                        "the laws are \"harmonic\", \"cycloidal\", \"345\" and \"modified_trapezoid\"".into()
                    });
                    return Err(bad(
                        Kind::UnknownName,
                        sp,
                        &format!("unknown cam law \"{other}\""),
                        "not a cam law",
                        Some(&help),
                    ));
                }
            },
            Some((v, sp)) => return Err(type_err("a law name", &v, sp, "`law`")),
        };
        for (name, deg, i) in [("rise", rise, 2), ("top", dwell, 3), ("fall", fall, 4)] {
            let neg = if name == "top" { deg < 0.0 } else { deg <= 0.0 };
            if neg || !deg.is_finite() {
                let sp = arg(i).map_or(span, |x| x.1);
                return Err(bad(
                    Kind::NotPositive,
                    sp,
                    &format!("`{name}` must be a positive angle"),
                    "out of range",
                    None,
                ));
            }
        }
        let rest = 360.0 - rise - dwell - fall;
        if rest < -1e-9 {
            return Err(bad(
                Kind::OutOfRange,
                span,
                &format!(
                    "rise, top and fall add up to {}°, more than a turn",
                    units::format_number(rise + dwell + fall)
                ),
                "this cam",
                Some("the base dwell takes what is left of 360°"),
            ));
        }
        let seg = |kind, duration_deg| CamSegment {
            kind,
            law,
            duration_deg,
            lift_mm: lift,
        };
        let mut segs = vec![seg(CamSegmentKind::Rise, rise)];
        if dwell > 0.0 {
            segs.push(seg(CamSegmentKind::Dwell, dwell));
        }
        segs.push(seg(CamSegmentKind::Return, fall));
        if rest > 1e-9 {
            segs.push(seg(CamSegmentKind::Dwell, rest));
        }
        // 0.25° samples: the spline through them follows the law's lift to well under a µm.
        let prof = Profile::cam(base, &segs, 1440).map_err(|g| geom_error(g, span, None))?;
        Ok(Value::Profile(Rc::new(prof)))
    }

    /// `profile dxf(file)` and `profile svg(path data)`.
    pub(super) fn imported_profile(
        &mut self,
        kind: &str,
        a: &[Option<(Value, Span)>],
        span: Span,
        cx: &mut Cx,
    ) -> R<Value> {
        use crate::geometry::import::{ImportOptions, dxf_profiles, svg_path_profiles};
        let (v, sp) = a.first().cloned().flatten().ok_or_else(|| {
            bad(
                Kind::MissingArgument,
                span,
                "missing the source",
                "in this profile",
                None,
            )
        })?;
        let Value::Str(src) = &v else {
            return Err(type_err("a string", &v, sp, "the source"));
        };
        let tol = self.planner_settings_now().arc_tolerance_mm;
        let opts = ImportOptions {
            tol_mm: tol,
            flip_y: kind == "svg",
            ..ImportOptions::default()
        };
        let id = match a.get(2).cloned().flatten() {
            Some((Value::Str(id), isp)) => Some((id.to_string(), isp)),
            Some((other, isp)) => return Err(type_err("a string", &other, isp, "`id`")),
            None => None,
        };
        let (profiles, what) = if kind == "dxf" {
            let text = self.data_file(src, sp, cx)?;
            (dxf_profiles(&text, &opts), format!("DXF file \"{src}\""))
        } else if src.to_ascii_lowercase().ends_with(".svg") {
            let text = self.data_file(src, sp, cx)?;
            let what = format!("SVG file \"{src}\"");
            let paths = crate::geometry::svg_file::svg_document_paths(&text).map_err(|e| {
                EvalError::Geometry {
                    message: format!("{what}: {e}"),
                    span: sp,
                    label: "cannot be read".into(),
                    help: None,
                }
            })?;
            (svg_file_profiles(&paths, id.as_ref(), &what, &opts)?, what)
        } else {
            if let Some((_, isp)) = &id {
                return Err(bad(
                    Kind::Conflict,
                    *isp,
                    "`id` picks a path of an SVG file, and this is path data",
                    "no ids here",
                    Some("name a file (`svg(\"part.svg\", id: \"outline\")`), or drop `id`"),
                ));
            }
            (svg_path_profiles(src, &opts), "SVG path data".to_string())
        };
        let profiles = profiles.map_err(|e| EvalError::Geometry {
            message: format!("{what}: {e}"),
            span: sp,
            label: "cannot be read".into(),
            help: None,
        })?;
        let index = match a.get(1).cloned().flatten() {
            Some((v, isp)) => Some((self.as_count(&v, isp, "`index`")?, isp)),
            None => None,
        };
        let n = profiles.len();
        let pick = match index {
            Some((i, isp)) if i < 0 || i as usize >= n => {
                return Err(bad(
                    Kind::OutOfRange,
                    isp,
                    &format!("{what} holds {n} contour(s)"),
                    "no such contour",
                    Some(&format!("`index` runs from 0 to {}", n.saturating_sub(1))),
                ));
            }
            Some((i, _)) => i as usize,
            None if n == 1 => 0,
            None => {
                return Err(bad(
                    Kind::MissingArgument,
                    sp,
                    &format!("{what} holds {n} contours"),
                    "which one?",
                    Some(&format!(
                        "pick one with `index: 0` … `index: {}`",
                        n.saturating_sub(1)
                    )),
                ));
            }
        };
        Ok(Value::Profile(Rc::new(
            profiles.into_iter().nth(pick).expect("checked"),
        )))
    }

    /// The text of a data file named in the recipe, relative to the file that names it.
    pub(super) fn data_file(&self, path: &str, span: Span, cx: &mut Cx) -> R<String> {
        let importer = cx
            .map
            .file_of(span.start as usize)
            .map(|f| cx.map.name(f).to_string())
            .unwrap_or_default();
        cx.host
            .data_file(&importer, path)
            .map(|(_, text)| text)
            .map_err(|reason| EvalError::Geometry {
                message: format!("cannot read \"{path}\": {reason}"),
                span,
                label: "this file".into(),
                help: Some("paths are relative to the recipe's folder".into()),
            })
    }
}

/// The contours of an SVG file's paths: the one `id` names (an error listing the ids there
/// are when none has it), else every path's, in document order.
fn svg_file_profiles(
    paths: &[crate::geometry::svg_file::SvgPath],
    id: Option<&(String, Span)>,
    what: &str,
    opts: &crate::geometry::import::ImportOptions,
) -> R<Result<Vec<Profile>, crate::geometry::import::ImportError>> {
    use crate::geometry::import::svg_path_profiles;
    let chosen: Vec<&crate::geometry::svg_file::SvgPath> = match id {
        Some((want, isp)) => {
            let found: Vec<_> = paths
                .iter()
                .filter(|p| p.id.as_deref() == Some(want.as_str()))
                .collect();
            if found.is_empty() {
                let ids: Vec<&str> = paths.iter().filter_map(|p| p.id.as_deref()).collect();
                return Err(bad(
                    Kind::OutOfRange,
                    *isp,
                    &format!("{what} has no path with id \"{want}\""),
                    "no such path",
                    Some(&if ids.is_empty() {
                        "its paths have no ids: pick one with `index`".to_string()
                    } else {
                        format!("its path ids: {}", ids.join(", "))
                    }),
                ));
            }
            found
        }
        None => paths.iter().collect(),
    };
    let mut out = Vec::new();
    for p in chosen {
        match svg_path_profiles(&p.d, opts) {
            Ok(v) => out.extend(v),
            Err(e) => return Ok(Err(e)),
        }
    }
    Ok(Ok(out))
}
