//! Import of profiles from drawing text: DXF (LINE, ARC, CIRCLE, LWPOLYLINE with bulges,
//! SPLINE) through the `dxf` crate, and SVG path data (M L H V C S Q T A Z, absolute and
//! relative) through `svgtypes`. The caller reads the file; this module only parses text.
//!
//! Lines and circular arcs are kept exact. Curves that are neither (Béziers, NURBS, elliptical
//! arcs) become tangent-continuous biarcs within `ImportOptions::tol_mm`. DXF entities are
//! chained into profiles by matching end points within `ImportOptions::join_tol_mm`; a chain
//! that comes back to its start is closed.

use super::biarc::fit_biarcs;
use super::{Profile, Seg, V2};
use std::f64::consts::{PI, TAU};

/// Why a drawing could not be imported; `line` (1-based) and `offset` (bytes) point at the
/// bad entity or character when they are known.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportError {
    pub message: String,
    pub line: Option<usize>,
    pub offset: Option<usize>,
}

impl ImportError {
    pub fn new(message: String) -> ImportError {
        ImportError {
            message,
            line: None,
            offset: None,
        }
    }

    pub fn at(message: String, line: usize, offset: usize) -> ImportError {
        ImportError {
            message,
            line: Some(line),
            offset: Some(offset),
        }
    }
}

impl std::fmt::Display for ImportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.message)?;
        if let Some(l) = self.line {
            write!(f, " (line {l})")?;
        }
        Ok(())
    }
}

impl std::error::Error for ImportError {}

/// Import settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImportOptions {
    /// Largest distance, mm, between a curve and its line/arc approximation.
    pub tol_mm: f64,
    /// End points closer than this, mm, are joined.
    pub join_tol_mm: f64,
    /// SVG only: mirror y (SVG's y axis points down).
    pub flip_y: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            tol_mm: 1e-3,
            join_tol_mm: 1e-3,
            flip_y: false,
        }
    }
}

fn check_opts(o: &ImportOptions) -> Result<(), ImportError> {
    if !(o.tol_mm > 0.0
        && o.tol_mm.is_finite()
        && o.join_tol_mm >= 0.0
        && o.join_tol_mm.is_finite())
    {
        return Err(ImportError::new(
            "import tolerances must be positive finite numbers".into(),
        ));
    }
    Ok(())
}

fn finite(p: V2) -> bool {
    p.x.is_finite() && p.y.is_finite()
}

/// Byte offset of the start of 1-based line `line` in `text`.
fn line_offset(text: &str, line: usize) -> usize {
    if line <= 1 {
        return 0;
    }
    text.match_indices('\n')
        .nth(line - 2)
        .map(|(i, _)| i + 1)
        .unwrap_or(text.len())
}

// ---------------------------------------------------------------------------------------------
// Chaining

/// One open piece, or a profile that is closed on its own.
enum Piece {
    Open(Vec<Seg>),
    Closed(Profile),
}

fn seq_start(s: &[Seg]) -> V2 {
    s[0].start()
}

fn seq_end(s: &[Seg]) -> V2 {
    s[s.len() - 1].end()
}

fn reversed_seq(s: &[Seg]) -> Vec<Seg> {
    s.iter().rev().map(Seg::reversed).collect()
}

/// Moves a line's end onto `p` (arcs stay exact and keep the gap, which is within tolerance).
fn snap_start(seg: &mut Seg, p: V2) {
    if let Seg::Line { a, .. } = seg {
        *a = p;
    }
}

/// Chains open pieces end to end (in entity order, reversing pieces as needed).
fn chain(pieces: Vec<Piece>, tol: f64) -> Vec<Profile> {
    let mut out = Vec::new();
    let mut open: Vec<Option<Vec<Seg>>> = Vec::new();
    let mut order: Vec<(bool, usize)> = Vec::new();
    let mut closed = Vec::new();
    for p in pieces {
        match p {
            Piece::Open(s) if !s.is_empty() => {
                order.push((true, open.len()));
                open.push(Some(s));
            }
            Piece::Open(_) => {}
            Piece::Closed(pr) => {
                order.push((false, closed.len()));
                closed.push(Some(pr));
            }
        }
    }
    for (is_open, idx) in order {
        if !is_open {
            if let Some(p) = closed[idx].take() {
                out.push(p);
            }
            continue;
        }
        let Some(mut segs) = open[idx].take() else {
            continue;
        };
        // Grow forward, then backward.
        loop {
            let end = seq_end(&segs);
            let found = open.iter().enumerate().find_map(|(k, o)| {
                let o = o.as_ref()?;
                if (seq_start(o) - end).norm() <= tol {
                    Some((k, false))
                } else if (seq_end(o) - end).norm() <= tol {
                    Some((k, true))
                } else {
                    None
                }
            });
            let Some((k, rev)) = found else { break };
            let Some(o) = open[k].take() else { break };
            let mut next = if rev { reversed_seq(&o) } else { o };
            snap_start(&mut next[0], end);
            segs.extend(next);
        }
        loop {
            let start = seq_start(&segs);
            let found = open.iter().enumerate().find_map(|(k, o)| {
                let o = o.as_ref()?;
                if (seq_end(o) - start).norm() <= tol {
                    Some((k, false))
                } else if (seq_start(o) - start).norm() <= tol {
                    Some((k, true))
                } else {
                    None
                }
            });
            let Some((k, rev)) = found else { break };
            let Some(o) = open[k].take() else { break };
            let mut prev = if rev { reversed_seq(&o) } else { o };
            snap_start(&mut segs[0], seq_end(&prev));
            prev.extend(segs);
            segs = prev;
        }
        let closes = (seq_end(&segs) - seq_start(&segs)).norm() <= tol
            && (segs.len() > 1 || matches!(segs[0], Seg::Arc { .. }));
        if closes {
            let s0 = seq_start(&segs);
            let last = segs.len() - 1;
            if let Seg::Line { b, .. } = &mut segs[last] {
                *b = s0;
            }
        }
        out.push(Profile::from_segs(segs, closes));
    }
    out
}

// ---------------------------------------------------------------------------------------------
// DXF

/// Line numbers of the entities in the ENTITIES section, by type name, in file order.
fn dxf_entity_lines(text: &str) -> Vec<(String, usize)> {
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let mut out = Vec::new();
    let mut in_entities = false;
    let mut i = 0;
    while i + 1 < lines.len() {
        let (code, value) = (lines[i], lines[i + 1]);
        if code == "2" && value == "ENTITIES" {
            in_entities = true;
        } else if code == "0" && value == "ENDSEC" {
            in_entities = false;
        } else if in_entities && code == "0" {
            out.push((value.to_string(), i + 1));
        }
        i += 2;
    }
    out
}

/// The entity types this module reads.
const DXF_TYPES: [&str; 5] = ["LINE", "ARC", "CIRCLE", "LWPOLYLINE", "SPLINE"];

/// Checks the numbers of the entities this module reads, before the `dxf` crate sees them: the
/// crate drops an entity with an unreadable number silently, and a shape that vanishes without
/// a word is worse than an error naming its line.
fn dxf_check_numbers(text: &str) -> Result<(), ImportError> {
    let lines: Vec<&str> = text.lines().map(str::trim).collect();
    let mut in_entities = false;
    let mut current: Option<&str> = None;
    let mut i = 0;
    while i + 1 < lines.len() {
        let (code, value) = (lines[i], lines[i + 1]);
        if code == "2" && value == "ENTITIES" {
            in_entities = true;
        } else if code == "0" {
            if value == "ENDSEC" {
                in_entities = false;
            }
            current = DXF_TYPES.iter().copied().find(|t| *t == value);
        } else if in_entities && let Some(name) = current {
            let Ok(c) = code.parse::<i32>() else {
                // The crate reports malformed group codes itself, with their line.
                i += 2;
                continue;
            };
            let float = matches!(c, 10..=59 | 110..=149 | 210..=239 | 1010..=1059);
            let int = matches!(c, 60..=99 | 170..=179 | 270..=289 | 370..=389 | 1060..=1071);
            let bad = (float && !value.parse::<f64>().is_ok_and(f64::is_finite))
                || (int && value.parse::<i64>().is_err());
            if bad {
                return Err(ImportError::at(
                    format!("DXF {name}: group {c} has `{value}`, which is not a valid number"),
                    i + 2,
                    line_offset(text, i + 2),
                ));
            }
        }
        i += 2;
    }
    Ok(())
}

/// Finds the line of the `k`-th entity of type `name`.
fn entity_line(index: &[(String, usize)], name: &str, k: usize) -> Option<usize> {
    index
        .iter()
        .filter(|(n, _)| n == name)
        .nth(k)
        .map(|(_, l)| *l)
}

/// Maps object coordinates to world XY: identity for normal +Z, a mirror of x for −Z (the
/// arbitrary-axis rule gives Ax = −X there); anything tilted is not a planar XY drawing.
fn ocs_mirror(nx: f64, ny: f64, nz: f64) -> Option<bool> {
    if nx.abs() < 1e-9 && ny.abs() < 1e-9 {
        if nz > 0.0 {
            return Some(false);
        }
        if nz < 0.0 {
            return Some(true);
        }
    }
    None
}

fn mirror_seg(s: Seg) -> Seg {
    match s {
        Seg::Line { a, b } => Seg::Line {
            a: V2::new(-a.x, a.y),
            b: V2::new(-b.x, b.y),
        },
        Seg::Arc {
            center,
            r,
            a0,
            sweep,
        } => Seg::Arc {
            center: V2::new(-center.x, center.y),
            r,
            a0: PI - a0,
            sweep: -sweep,
        },
    }
}

/// Profiles from DXF text: LINE, ARC, CIRCLE, LWPOLYLINE (with bulges), SPLINE; other
/// entities are ignored. Open pieces are chained by end points.
pub fn dxf_profiles(text: &str, opts: &ImportOptions) -> Result<Vec<Profile>, ImportError> {
    use dxf::entities::EntityType;
    check_opts(opts)?;
    dxf_check_numbers(text)?;
    let loaded = std::panic::catch_unwind(|| dxf::Drawing::load(&mut text.as_bytes()));
    let drawing = match loaded {
        Ok(Ok(d)) => d,
        Ok(Err(e)) => {
            use dxf::DxfError as E;
            let line = match &e {
                E::ParseFloatError(_, o)
                | E::ParseIntError(_, o)
                | E::ParseError(o)
                | E::UnexpectedCode(_, o)
                | E::UnexpectedByte(_, o)
                | E::UnexpectedEnumValue(o)
                | E::ExpectedTableType(o)
                | E::WrongValueType(o) => Some(*o),
                E::UnexpectedCodePair(cp, _) => Some(cp.offset),
                _ => None,
            };
            return Err(ImportError {
                message: format!("the DXF text could not be read: {e}"),
                line,
                offset: line.map(|l| line_offset(text, l)),
            });
        }
        Err(_) => {
            return Err(ImportError::new(
                "the DXF text could not be read (the parser failed)".into(),
            ));
        }
    };
    let index = dxf_entity_lines(text);
    let mut counts: std::collections::HashMap<&'static str, usize> = Default::default();
    let mut pieces = Vec::new();
    for ent in drawing.entities() {
        let name: &'static str = match &ent.specific {
            EntityType::Line(_) => "LINE",
            EntityType::Arc(_) => "ARC",
            EntityType::Circle(_) => "CIRCLE",
            EntityType::LwPolyline(_) => "LWPOLYLINE",
            EntityType::Spline(_) => "SPLINE",
            _ => continue,
        };
        let k = counts.entry(name).or_insert(0);
        let nth = *k;
        *k += 1;
        let fail = |why: String| {
            let line = entity_line(&index, name, nth);
            ImportError {
                message: format!("DXF {name} #{}: {why}", nth + 1),
                line,
                offset: line.map(|l| line_offset(text, l)),
            }
        };
        let piece = dxf_entity(&ent.specific, opts).map_err(fail)?;
        if let Some(p) = piece {
            pieces.push(p);
        }
    }
    for name in DXF_TYPES {
        let in_text = index.iter().filter(|(n, _)| n == name).count();
        let read = counts.get(name).copied().unwrap_or(0);
        if read < in_text {
            return Err(ImportError::new(format!(
                "{} of the {in_text} DXF {name} entities could not be read",
                in_text - read
            )));
        }
    }
    Ok(chain(pieces, opts.join_tol_mm))
}

fn dxf_entity(
    e: &dxf::entities::EntityType,
    opts: &ImportOptions,
) -> Result<Option<Piece>, String> {
    use dxf::entities::EntityType;
    let plane = |n: &dxf::Vector| {
        ocs_mirror(n.x, n.y, n.z)
            .ok_or_else(|| "the entity does not lie in the XY plane".to_string())
    };
    match e {
        EntityType::Line(l) => {
            let a = V2::new(l.p1.x, l.p1.y);
            let b = V2::new(l.p2.x, l.p2.y);
            if !(finite(a) && finite(b)) {
                return Err("a coordinate is not a finite number".into());
            }
            if (b - a).norm() <= 1e-12 {
                return Ok(None);
            }
            Ok(Some(Piece::Open(vec![Seg::Line { a, b }])))
        }
        EntityType::Arc(a) => {
            let mirror = plane(&a.normal)?;
            let c = V2::new(a.center.x, a.center.y);
            if !(finite(c) && a.radius > 0.0 && a.radius.is_finite()) {
                return Err(format!("radius {} is not positive", a.radius));
            }
            if !(a.start_angle.is_finite() && a.end_angle.is_finite()) {
                return Err("an angle is not a finite number".into());
            }
            let mut sweep = (a.end_angle - a.start_angle).rem_euclid(360.0);
            if sweep <= 1e-12 {
                sweep = 360.0;
            }
            let seg = Seg::Arc {
                center: c,
                r: a.radius,
                a0: a.start_angle.to_radians(),
                sweep: sweep.to_radians(),
            };
            Ok(Some(Piece::Open(vec![if mirror {
                mirror_seg(seg)
            } else {
                seg
            }])))
        }
        EntityType::Circle(c) => {
            let mirror = plane(&c.normal)?;
            let mut center = V2::new(c.center.x, c.center.y);
            if mirror {
                center.x = -center.x;
            }
            let p = Profile::circle(center, c.radius, 0.0, !mirror).map_err(|e| e.to_string())?;
            Ok(Some(Piece::Closed(p)))
        }
        EntityType::LwPolyline(pl) => {
            let mirror = plane(&pl.extrusion_direction)?;
            let mut verts: Vec<(V2, f64)> = Vec::new();
            for v in &pl.vertices {
                let p = V2::new(v.x, v.y);
                if !(finite(p) && v.bulge.is_finite()) {
                    return Err("a vertex is not a finite number".into());
                }
                match verts.last_mut() {
                    // A repeated vertex: the zero-length piece between them has no shape.
                    Some(last) if (last.0 - p).norm() <= 1e-12 => last.1 = v.bulge,
                    _ => verts.push((p, v.bulge)),
                }
            }
            let closed = pl.is_closed();
            if closed && verts.len() > 2 && (verts[0].0 - verts[verts.len() - 1].0).norm() <= 1e-12
            {
                verts.pop();
            }
            if verts.len() < 2 {
                return Err("a polyline needs at least 2 distinct vertices".into());
            }
            let mut cp = if closed {
                cavalier_contours::polyline::Polyline::new_closed()
            } else {
                cavalier_contours::polyline::Polyline::new()
            };
            use cavalier_contours::polyline::PlineSourceMut;
            for (p, b) in &verts {
                cp.add(p.x, p.y, *b);
            }
            let mut prof = Profile::from_pline(&cp);
            if mirror {
                prof.segs = prof.segs.into_iter().map(mirror_seg).collect();
            }
            Ok(Some(if closed {
                Piece::Closed(prof)
            } else {
                Piece::Open(prof.segs)
            }))
        }
        EntityType::Spline(s) => dxf_spline(s, opts).map(Some),
        _ => Ok(None),
    }
}

/// A DXF SPLINE: a (rational) B-spline of any degree from control points and knots, or, with
/// only fit points, the seed-2 cubic interpolation through them.
fn dxf_spline(s: &dxf::entities::Spline, opts: &ImportOptions) -> Result<Piece, String> {
    if ocs_mirror(s.normal.x, s.normal.y, s.normal.z).is_none()
        && !(s.normal.x == 0.0 && s.normal.y == 0.0 && s.normal.z == 0.0)
    {
        return Err("the spline does not lie in the XY plane".into());
    }
    if s.control_points.is_empty() {
        let fit: Vec<V2> = s.fit_points.iter().map(|p| V2::new(p.x, p.y)).collect();
        let p = Profile::interpolate(&fit, s.is_closed())
            .and_then(|p| p.to_line_arc(opts.tol_mm))
            .map_err(|e| e.to_string())?;
        return Ok(if p.closed {
            Piece::Closed(p)
        } else {
            Piece::Open(p.segs)
        });
    }
    let p = s.degree_of_curve;
    let n = s.control_points.len();
    let knots = &s.knot_values;
    if !(1..=25).contains(&p) || n < (p as usize) + 1 {
        return Err(format!(
            "degree {p} with {n} control points is not a valid B-spline"
        ));
    }
    let p = p as usize;
    if knots.len() != n + p + 1 {
        return Err(format!(
            "{} knots for {n} control points of degree {p}; expected {}",
            knots.len(),
            n + p + 1
        ));
    }
    if knots.iter().any(|k| !k.is_finite()) || knots.windows(2).any(|w| w[1] < w[0]) {
        return Err("the knots must be finite and non-decreasing".into());
    }
    let weights: Vec<f64> = if s.weight_values.len() == n {
        s.weight_values.clone()
    } else {
        vec![1.0; n]
    };
    if weights.iter().any(|w| !(*w > 0.0 && w.is_finite())) {
        return Err("the weights must be positive".into());
    }
    let ctrl: Vec<[f64; 3]> = s
        .control_points
        .iter()
        .zip(&weights)
        .map(|(c, w)| [c.x * w, c.y * w, *w])
        .collect();
    if ctrl.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err("a control point is not a finite number".into());
    }
    let nurbs = Nurbs::new(p, knots.clone(), ctrl);
    let curve = |u: f64| nurbs.point_and_derivative(u);
    let mut segs = Vec::new();
    let (lo, hi) = (knots[p], knots[n]);
    if !(hi > lo) {
        return Err("the knot vector has an empty domain".into());
    }
    // Fit knot interval by knot interval: the curve may lose smoothness at knots.
    for w in knots[p..=n].windows(2) {
        if w[1] > w[0] {
            fit_biarcs(&curve, w[0], w[1], opts.tol_mm, &mut segs);
        }
    }
    segs.retain(|s| s.length() > 1e-12);
    if segs.is_empty() {
        return Err("the spline has no length".into());
    }
    let closes = (seq_end(&segs) - seq_start(&segs)).norm() <= opts.join_tol_mm;
    Ok(if closes && s.is_closed() {
        Piece::Closed(Profile::from_segs(segs, true))
    } else {
        Piece::Open(segs)
    })
}

/// A rational B-spline in homogeneous coordinates, evaluated with de Boor's algorithm.
struct Nurbs {
    p: usize,
    knots: Vec<f64>,
    ctrl: Vec<[f64; 3]>,
    /// The derivative curve (degree p − 1, knots without the first and last).
    dknots: Vec<f64>,
    dctrl: Vec<[f64; 3]>,
}

impl Nurbs {
    fn new(p: usize, knots: Vec<f64>, ctrl: Vec<[f64; 3]>) -> Nurbs {
        let n = ctrl.len();
        let mut dctrl = Vec::with_capacity(n.saturating_sub(1));
        for i in 0..n - 1 {
            let den = knots[i + p + 1] - knots[i + 1];
            let f = if den > 0.0 { p as f64 / den } else { 0.0 };
            dctrl.push([
                f * (ctrl[i + 1][0] - ctrl[i][0]),
                f * (ctrl[i + 1][1] - ctrl[i][1]),
                f * (ctrl[i + 1][2] - ctrl[i][2]),
            ]);
        }
        let dknots = knots[1..knots.len() - 1].to_vec();
        Nurbs {
            p,
            knots,
            ctrl,
            dknots,
            dctrl,
        }
    }

    fn de_boor(p: usize, knots: &[f64], ctrl: &[[f64; 3]], u: f64) -> [f64; 3] {
        let n = ctrl.len();
        if p == 0 {
            // Piecewise constant: the span's control point.
            let k = (0..n)
                .rev()
                .find(|&k| knots[k] <= u && knots[k] < knots[k + 1])
                .unwrap_or(0);
            return ctrl[k.min(n - 1)];
        }
        // Span k with knots[k] ≤ u < knots[k + 1], p ≤ k ≤ n − 1.
        let mut k = p;
        while k + 1 < n && knots[k + 1] <= u {
            k += 1;
        }
        while k > p && knots[k] == knots[k + 1] {
            k -= 1;
        }
        let mut d: Vec<[f64; 3]> = (0..=p).map(|j| ctrl[j + k - p]).collect();
        for r in 1..=p {
            for j in (r..=p).rev() {
                let i = j + k - p;
                let den = knots[i + p + 1 - r] - knots[i];
                let a = if den > 0.0 { (u - knots[i]) / den } else { 0.0 };
                let prev = d[j - 1];
                for (x, q) in d[j].iter_mut().zip(prev) {
                    *x = (1.0 - a) * q + a * *x;
                }
            }
        }
        d[p]
    }

    fn point_and_derivative(&self, u: f64) -> (V2, V2) {
        let a = Self::de_boor(self.p, &self.knots, &self.ctrl, u);
        let da = Self::de_boor(self.p - 1, &self.dknots, &self.dctrl, u);
        let w = a[2];
        let c = V2::new(a[0] / w, a[1] / w);
        let d = (V2::new(da[0], da[1]) - c * da[2]) / w;
        (c, d)
    }
}

// ---------------------------------------------------------------------------------------------
// SVG

/// Cubic Bézier point and derivative.
fn bezier3(p: [V2; 4], t: f64) -> (V2, V2) {
    let m = 1.0 - t;
    let pt = p[0] * (m * m * m)
        + p[1] * (3.0 * m * m * t)
        + p[2] * (3.0 * m * t * t)
        + p[3] * (t * t * t);
    let d = (p[1] - p[0]) * (3.0 * m * m)
        + (p[2] - p[1]) * (6.0 * m * t)
        + (p[3] - p[2]) * (3.0 * t * t);
    (pt, d)
}

/// SVG arc from `p0` to `p1` (SVG 1.1 implementation notes F.6.5: endpoint to center form,
/// radii scaled up when too small). Circular arcs are exact; elliptical ones are biarcs.
/// The arguments are the SVG `A` command's own.
#[allow(clippy::too_many_arguments)]
fn svg_arc(
    p0: V2,
    p1: V2,
    rx: f64,
    ry: f64,
    rot_deg: f64,
    large: bool,
    sweep: bool,
    tol: f64,
    out: &mut Vec<Seg>,
) {
    if (p1 - p0).norm() <= 1e-12 {
        return;
    }
    let (mut rx, mut ry) = (rx.abs(), ry.abs());
    if rx <= 1e-12 || ry <= 1e-12 {
        out.push(Seg::Line { a: p0, b: p1 });
        return;
    }
    let phi = rot_deg.to_radians();
    let (cs, sn) = (phi.cos(), phi.sin());
    let h = (p0 - p1) / 2.0;
    let x1 = cs * h.x + sn * h.y;
    let y1 = -sn * h.x + cs * h.y;
    let lambda = (x1 * x1) / (rx * rx) + (y1 * y1) / (ry * ry);
    if lambda > 1.0 {
        let s = lambda.sqrt();
        rx *= s;
        ry *= s;
    }
    let num = (rx * rx * ry * ry - rx * rx * y1 * y1 - ry * ry * x1 * x1).max(0.0);
    let den = rx * rx * y1 * y1 + ry * ry * x1 * x1;
    let mut coef = if den > 0.0 { (num / den).sqrt() } else { 0.0 };
    if large == sweep {
        coef = -coef;
    }
    let cx1 = coef * rx * y1 / ry;
    let cy1 = -coef * ry * x1 / rx;
    let mid = (p0 + p1) / 2.0;
    let center = V2::new(cs * cx1 - sn * cy1 + mid.x, sn * cx1 + cs * cy1 + mid.y);
    let ang = |ux: f64, uy: f64| uy.atan2(ux);
    let th1 = ang((x1 - cx1) / rx, (y1 - cy1) / ry);
    let th2 = ang((-x1 - cx1) / rx, (-y1 - cy1) / ry);
    let mut dth = th2 - th1;
    if sweep && dth < 0.0 {
        dth += TAU;
    } else if !sweep && dth > 0.0 {
        dth -= TAU;
    }
    if (rx - ry).abs() <= 1e-12 * rx.max(1.0) {
        // A circle: the rotation does not matter; the start angle is measured in world axes.
        let a0 = (p0.y - center.y).atan2(p0.x - center.x);
        out.push(Seg::Arc {
            center,
            r: rx,
            a0,
            sweep: dth,
        });
        return;
    }
    let f = |t: f64| {
        let th = th1 + dth * t;
        let (c, s) = (th.cos(), th.sin());
        let p = V2::new(cs * rx * c - sn * ry * s, sn * rx * c + cs * ry * s) + center;
        let d = V2::new(-cs * rx * s - sn * ry * c, -sn * rx * s + cs * ry * c) * dth;
        (p, d)
    };
    fit_biarcs(&f, 0.0, 1.0, tol, out);
}

fn svg_error(d: &str, e: &svgtypes::Error) -> ImportError {
    use svgtypes::Error as E;
    let pos = match e {
        E::UnexpectedData(p) | E::InvalidNumber(p) => Some(*p),
        E::InvalidChar(_, p) | E::InvalidString(_, p) => Some(*p),
        _ => None,
    };
    // svgtypes counts characters from 1.
    let offset = pos.map(|p| {
        d.char_indices()
            .nth(p.saturating_sub(1))
            .map(|(i, _)| i)
            .unwrap_or(d.len())
    });
    let line = offset.map(|o| d[..o].matches('\n').count() + 1);
    ImportError {
        message: format!("the SVG path data could not be read: {e}"),
        line,
        offset,
    }
}

/// Profiles from SVG path data (the `d` attribute): one per subpath, closed where it ends
/// with Z. Coordinates are taken as mm.
pub fn svg_path_profiles(d: &str, opts: &ImportOptions) -> Result<Vec<Profile>, ImportError> {
    use svgtypes::PathSegment as P;
    check_opts(opts)?;
    let tol = opts.tol_mm;
    let mut out: Vec<Profile> = Vec::new();
    let mut segs: Vec<Seg> = Vec::new();
    let mut cur = V2::zeros();
    let mut start = V2::zeros();
    // The last control point of a cubic / quadratic, for S and T reflection.
    let mut last_c3: Option<V2> = None;
    let mut last_q: Option<V2> = None;
    let finish = |segs: &mut Vec<Seg>, closed: bool, out: &mut Vec<Profile>| {
        if !segs.is_empty() {
            out.push(Profile::from_segs(std::mem::take(segs), closed));
        }
    };
    for item in svgtypes::PathParser::from(d) {
        let seg = item.map_err(|e| svg_error(d, &e))?;
        let abs = seg.is_abs();
        let at = |x: f64, y: f64, cur: V2| {
            if abs {
                V2::new(x, y)
            } else {
                cur + V2::new(x, y)
            }
        };
        let (mut c3, mut q) = (None, None);
        match seg {
            P::MoveTo { x, y, .. } => {
                finish(&mut segs, false, &mut out);
                cur = at(x, y, cur);
                start = cur;
            }
            P::LineTo { x, y, .. } => {
                let p = at(x, y, cur);
                push_line(&mut segs, cur, p);
                cur = p;
            }
            P::HorizontalLineTo { x, .. } => {
                let p = if abs {
                    V2::new(x, cur.y)
                } else {
                    cur + V2::new(x, 0.0)
                };
                push_line(&mut segs, cur, p);
                cur = p;
            }
            P::VerticalLineTo { y, .. } => {
                let p = if abs {
                    V2::new(cur.x, y)
                } else {
                    cur + V2::new(0.0, y)
                };
                push_line(&mut segs, cur, p);
                cur = p;
            }
            P::CurveTo {
                x1,
                y1,
                x2,
                y2,
                x,
                y,
                ..
            } => {
                let pts = [cur, at(x1, y1, cur), at(x2, y2, cur), at(x, y, cur)];
                push_cubic(&mut segs, pts, tol);
                c3 = Some(pts[2]);
                cur = pts[3];
            }
            P::SmoothCurveTo { x2, y2, x, y, .. } => {
                let c1 = last_c3.map_or(cur, |c| cur * 2.0 - c);
                let pts = [cur, c1, at(x2, y2, cur), at(x, y, cur)];
                push_cubic(&mut segs, pts, tol);
                c3 = Some(pts[2]);
                cur = pts[3];
            }
            P::Quadratic { x1, y1, x, y, .. } => {
                let c = at(x1, y1, cur);
                let e = at(x, y, cur);
                push_quadratic(&mut segs, cur, c, e, tol);
                q = Some(c);
                cur = e;
            }
            P::SmoothQuadratic { x, y, .. } => {
                let c = last_q.map_or(cur, |c| cur * 2.0 - c);
                let e = at(x, y, cur);
                push_quadratic(&mut segs, cur, c, e, tol);
                q = Some(c);
                cur = e;
            }
            P::EllipticalArc {
                rx,
                ry,
                x_axis_rotation,
                large_arc,
                sweep,
                x,
                y,
                ..
            } => {
                let e = at(x, y, cur);
                if !(finite(e) && rx.is_finite() && ry.is_finite() && x_axis_rotation.is_finite()) {
                    return Err(ImportError::new(
                        "an SVG arc has a coordinate that is not a finite number".into(),
                    ));
                }
                svg_arc(
                    cur,
                    e,
                    rx,
                    ry,
                    x_axis_rotation,
                    large_arc,
                    sweep,
                    tol,
                    &mut segs,
                );
                cur = e;
            }
            P::ClosePath { .. } => {
                push_line(&mut segs, cur, start);
                if let Some(last) = segs.len().checked_sub(1)
                    && let Seg::Line { b, .. } = &mut segs[last]
                {
                    *b = start;
                }
                cur = start;
                finish(&mut segs, true, &mut out);
            }
        }
        if !finite(cur) {
            return Err(ImportError::new(
                "an SVG path coordinate is not a finite number".into(),
            ));
        }
        last_c3 = c3;
        last_q = q;
    }
    finish(&mut segs, false, &mut out);
    // A closed subpath needs at least two pieces (or one full arc) to enclose anything.
    out.retain(|p| !p.segs.is_empty());
    for p in &mut out {
        if p.closed && p.segs.len() == 1 && matches!(p.segs[0], Seg::Line { .. }) {
            p.closed = false;
        }
        if opts.flip_y {
            p.segs = p.segs.iter().cloned().map(mirror_seg_y).collect();
        }
    }
    Ok(out)
}

fn mirror_seg_y(s: Seg) -> Seg {
    match s {
        Seg::Line { a, b } => Seg::Line {
            a: V2::new(a.x, -a.y),
            b: V2::new(b.x, -b.y),
        },
        Seg::Arc {
            center,
            r,
            a0,
            sweep,
        } => Seg::Arc {
            center: V2::new(center.x, -center.y),
            r,
            a0: -a0,
            sweep: -sweep,
        },
    }
}

fn push_line(segs: &mut Vec<Seg>, a: V2, b: V2) {
    if (b - a).norm() > 1e-12 {
        segs.push(Seg::Line { a, b });
    }
}

fn push_cubic(segs: &mut Vec<Seg>, p: [V2; 4], tol: f64) {
    if p.iter().all(|q| (q - p[0]).norm() <= 1e-12) {
        return;
    }
    let f = |t: f64| bezier3(p, t);
    let before = segs.len();
    fit_biarcs(&f, 0.0, 1.0, tol, segs);
    let mut kept: Vec<Seg> = segs
        .drain(before..)
        .filter(|s| s.length() > 1e-12)
        .collect();
    segs.append(&mut kept);
}

fn push_quadratic(segs: &mut Vec<Seg>, a: V2, c: V2, b: V2, tol: f64) {
    // Degree elevation: the same curve as a cubic.
    push_cubic(
        segs,
        [a, a + (c - a) * (2.0 / 3.0), b + (c - b) * (2.0 / 3.0), b],
        tol,
    );
}
