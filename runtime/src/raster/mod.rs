//! Scan rasters: the geometry of texturing dot arrays and hatch fills (PROCESS.md §3), as plain
//! math on plain data — no recipe syntax, no NC text.
//!
//! A raster lives in a [`Frame`]: rows run along `u` (the frame's angle), successive rows step
//! along `v` (`u` turned +90°). Work on a row is a list of [`Run`]s, ordered along `+u`: a run
//! of equally spaced spots (a dot array) or one continuous hatch interval. [`scan_path`] turns
//! the rows into [`Step`]s (positioning, idle moves at the scan speed, lit moves, dots) for a
//! number of passes in a visit order:
//!
//! * **Rows** are visited by increasing `v`, so every row start is approached by a move with a
//!   `+v` component (the row step), never `−v`: the cross-row axis always takes up its backlash
//!   the same way. Along a row the spots are passed in the row's traversal direction after an
//!   overscan in that direction.
//! * **Order.** `Unidirectional` (the paper's old method): every row in `+u`, with an idle
//!   return stroke to the next row's start. `Serpentine` (boustrophedon, the optimized one):
//!   rows alternate `+u`, `−u`; the k-th row *visited* (empty rows are skipped) runs `+u` when
//!   k is even. Within a row, runs are visited in the traversal direction; a gap between runs
//!   is crossed by an idle move at the scan speed.
//! * **Passes** (seed 3: one pulse per spot per pass, the whole array N times). Every pass
//!   starts at the approach point A of its first row, reached from A' = A − L2·v (one row pitch
//!   before it), so A too is approached in `+v`. The pass ending follows from the row count:
//!   with serpentine order an even number of rows ends at B on the start side (B → A' → A),
//!   an odd number on the far side (B → A' → A, A' standing in for the paper's C and D: the
//!   shortest return that keeps the approach direction). Unidirectional passes always end on
//!   the far side.
//! * **Overscan.** Each row is lengthened before its first and after its last run by the
//!   overscan, so every spot is passed at the programmed speed; the caller computes it from the
//!   planner's ramps unless the recipe gives one (`None` leaves the extension to the motion
//!   layer's lead-ins, which compute the same length).
//! * **Positions** are counted from the lattice origin by integer indices (`origin + c·L1·u +
//!   r·L2·v`), never accumulated from previous moves, so passes hit the same spots exactly.

pub mod image;

use crate::geometry::{GeomError, Profile, Seg, V2};

/// Chord tolerance of the polygons that stand in for arcs in region tests, mm (0.1 µm).
pub const FLATTEN_TOL_MM: f64 = 1e-4;
/// Spots this close outside a region's border still count as inside, mm (1 nm): a spot placed
/// on the border by construction is kept whatever the rounding.
pub const BORDER_TOL_MM: f64 = 1e-6;

/// The raster's coordinate frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// Lattice origin, part coordinates.
    pub origin: V2,
    /// Row direction, rad from +x.
    pub angle: f64,
}

impl Frame {
    pub fn new(origin: V2, angle: f64) -> Frame {
        Frame { origin, angle }
    }

    /// Unit vector along the rows.
    pub fn u(&self) -> V2 {
        V2::new(self.angle.cos(), self.angle.sin())
    }

    /// Unit vector from one row to the next (u turned +90°).
    pub fn v(&self) -> V2 {
        V2::new(-self.angle.sin(), self.angle.cos())
    }

    /// Local coordinates (along u, along v) of a part point.
    pub fn to_local(self, p: V2) -> V2 {
        let d = p - self.origin;
        V2::new(d.dot(&self.u()), d.dot(&self.v()))
    }

    /// The part point at local coordinates (x along u, y along v).
    pub fn to_part(self, x: f64, y: f64) -> V2 {
        self.origin + self.u() * x + self.v() * y
    }
}

/// How the spots of successive rows stand to each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Columns aligned.
    Grid,
    /// Odd rows shifted by half a pitch along the row (with row pitch L1·√3/2: hexagonal).
    Stagger,
}

/// A dot lattice: spot (r, c) at `origin + (c·L1 + shift(r))·u + r·L2·v`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    pub frame: Frame,
    /// L1: spot spacing along a row, mm.
    pub pitch: f64,
    /// L2: row spacing, mm.
    pub row_pitch: f64,
    pub layout: Layout,
}

impl Lattice {
    /// Along-row position of column `c` in row `r`.
    pub fn x(&self, r: i64, c: i64) -> f64 {
        let shift = match self.layout {
            Layout::Stagger if r.rem_euclid(2) == 1 => 0.5 * self.pitch,
            _ => 0.0,
        };
        c as f64 * self.pitch + shift
    }

    pub fn y(&self, r: i64) -> f64 {
        r as f64 * self.row_pitch
    }
}

/// Work along one row, in the row's local coordinates: `count` spots from `x0` every `pitch`
/// (a dot run), or, with `count == 0`, the continuous interval `x0..x1` (a hatch line).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run {
    pub x0: f64,
    pub x1: f64,
    pub pitch: f64,
    pub count: u32,
}

impl Run {
    fn dots(x0: f64, pitch: f64, count: u32) -> Run {
        Run {
            x0,
            x1: x0 + (count.saturating_sub(1)) as f64 * pitch,
            pitch,
            count,
        }
    }

    fn line(x0: f64, x1: f64) -> Run {
        Run {
            x0,
            x1,
            pitch: 0.0,
            count: 0,
        }
    }

    /// Along-row position of spot k (from the run's first index, not accumulated).
    pub fn spot(&self, k: u32) -> f64 {
        self.x0 + k as f64 * self.pitch
    }
}

/// One row: its local y and its runs, ordered along +u.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    pub y: f64,
    pub runs: Vec<Run>,
}

impl Row {
    /// Spots on the row.
    pub fn spots(&self) -> u64 {
        self.runs.iter().map(|r| u64::from(r.count)).sum()
    }
}

/// What can go wrong building a raster.
#[derive(Debug, Clone, PartialEq)]
pub enum RasterError {
    /// A region profile is not closed.
    OpenRegion { index: usize },
    /// Insetting a region failed (it vanishes or folds over).
    Inset { index: usize, error: GeomError },
}

impl std::fmt::Display for RasterError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RasterError::OpenRegion { index } => {
                write!(
                    f,
                    "region profile {index} is open; a region needs closed profiles"
                )
            }
            RasterError::Inset { index, error } => {
                write!(f, "cannot inset region profile {index}: {error}")
            }
        }
    }
}

impl std::error::Error for RasterError {}

/// An area bounded by closed profiles; a point is inside when it lies inside an odd number of
/// them (even-odd rule), so a profile inside another is a hole (a seal ring face is the outer
/// circle and the inner one).
#[derive(Debug, Clone)]
pub struct Region {
    profiles: Vec<Profile>,
    /// The profiles as polygons within [`FLATTEN_TOL_MM`].
    polys: Vec<Vec<V2>>,
}

impl Region {
    /// The region of `profiles`, shrunk by `inset` from every border (outer borders move in,
    /// holes grow) with the offset machinery; `inset` may be 0.
    pub fn new(profiles: &[Profile], inset: f64) -> Result<Region, RasterError> {
        for (i, p) in profiles.iter().enumerate() {
            if !p.closed {
                return Err(RasterError::OpenRegion { index: i });
            }
        }
        let flat: Vec<Vec<V2>> = profiles.iter().map(flatten).collect();
        let mut out = Vec::with_capacity(profiles.len());
        for (i, p) in profiles.iter().enumerate() {
            if inset == 0.0 {
                out.push(p.clone());
                continue;
            }
            // A border inside an odd number of others bounds a hole: it grows.
            let probe = flat[i][0];
            let depth = flat
                .iter()
                .enumerate()
                .filter(|(j, poly)| *j != i && inside_poly(poly, probe))
                .count();
            let d = if depth % 2 == 0 { -inset } else { inset };
            let o = p
                .offset(d)
                .map_err(|error| RasterError::Inset { index: i, error })?;
            out.push(o);
        }
        let polys = out.iter().map(flatten).collect();
        Ok(Region {
            profiles: out,
            polys,
        })
    }

    /// The exact bounding box in `frame`'s local coordinates: (min, max).
    pub fn bounds(&self, frame: &Frame) -> (V2, V2) {
        let mut lo = V2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = V2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut add = |p: V2| {
            let q = frame.to_local(p);
            lo = lo.inf(&q);
            hi = hi.sup(&q);
        };
        for p in &self.profiles {
            for s in &p.segs {
                add(s.start());
                add(s.end());
                if let Seg::Arc {
                    center,
                    r,
                    a0,
                    sweep,
                } = s
                {
                    // The arc's extremes along u and v: where its tangent is parallel to them.
                    for k in 0..4 {
                        let a = frame.angle + k as f64 * std::f64::consts::FRAC_PI_2;
                        if angle_in_sweep(a, *a0, *sweep) {
                            add(center + V2::new(a.cos(), a.sin()) * *r);
                        }
                    }
                }
            }
        }
        (lo, hi)
    }

    /// The intervals of the line `y = const` (local coordinates of `frame`) inside the region,
    /// ordered along u. A line along a border counts as inside: the intervals are the union
    /// of those just below and just above it.
    pub fn intervals(&self, frame: &Frame, y: f64) -> Vec<(f64, f64)> {
        let mut all = self.crossings(frame, y - BORDER_TOL_MM);
        all.extend(self.crossings(frame, y + BORDER_TOL_MM));
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut out: Vec<(f64, f64)> = Vec::with_capacity(all.len());
        for (a, b) in all {
            match out.last_mut() {
                Some(last) if a <= last.1 => last.1 = last.1.max(b),
                _ => out.push((a, b)),
            }
        }
        out
    }

    /// Even-odd intervals of one scan line.
    fn crossings(&self, frame: &Frame, y: f64) -> Vec<(f64, f64)> {
        let mut xs = Vec::new();
        for poly in &self.polys {
            let n = poly.len();
            for i in 0..n {
                let a = frame.to_local(poly[i]);
                let b = frame.to_local(poly[(i + 1) % n]);
                if (a.y > y) != (b.y > y) {
                    xs.push(a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y));
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        xs.chunks_exact(2).map(|c| (c[0], c[1])).collect()
    }
}

fn angle_in_sweep(a: f64, a0: f64, sweep: f64) -> bool {
    use std::f64::consts::TAU;
    let d = if sweep >= 0.0 { a - a0 } else { a0 - a };
    d.rem_euclid(TAU) <= sweep.abs() + 1e-12
}

/// A closed profile as a polygon (arcs as chords within [`FLATTEN_TOL_MM`]).
fn flatten(p: &Profile) -> Vec<V2> {
    let mut out = Vec::new();
    for s in &p.segs {
        out.push(s.start());
        if let Seg::Arc { r, sweep, .. } = s {
            let step = if *r > FLATTEN_TOL_MM {
                2.0 * (1.0 - FLATTEN_TOL_MM / r).acos()
            } else {
                std::f64::consts::FRAC_PI_2
            };
            let n = ((sweep.abs() / step).ceil() as usize).clamp(1, 100_000);
            let len = s.length();
            for k in 1..n {
                out.push(s.point_at(len * k as f64 / n as f64));
            }
        }
    }
    out
}

fn inside_poly(poly: &[V2], p: V2) -> bool {
    let n = poly.len();
    let mut inside = false;
    for i in 0..n {
        let a = poly[i];
        let b = poly[(i + 1) % n];
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            inside = !inside;
        }
    }
    inside
}

// ------------------------------------------------------------------ rows

/// A rows × cols array from the lattice origin (row 0 at the origin, rows stepping +v).
pub fn grid_rows(lat: &Lattice, rows: u32, cols: u32) -> Vec<Row> {
    (0..i64::from(rows))
        .map(|r| Row {
            y: lat.y(r),
            runs: if cols == 0 {
                Vec::new()
            } else {
                vec![Run::dots(lat.x(r, 0), lat.pitch, cols)]
            },
        })
        .collect()
}

/// The lattice spots inside a region, row by row; each stretch of consecutive columns inside
/// one interval of the row is a run.
pub fn region_rows(lat: &Lattice, region: &Region) -> Vec<Row> {
    let (lo, hi) = region.bounds(&lat.frame);
    let tol = BORDER_TOL_MM;
    let r0 = ((lo.y - tol) / lat.row_pitch).ceil() as i64;
    let r1 = ((hi.y + tol) / lat.row_pitch).floor() as i64;
    let mut out = Vec::new();
    for r in r0..=r1 {
        let y = lat.y(r);
        let shift = lat.x(r, 0);
        let mut runs = Vec::new();
        for (a, b) in region.intervals(&lat.frame, y) {
            let c0 = ((a - tol - shift) / lat.pitch).ceil() as i64;
            let c1 = ((b + tol - shift) / lat.pitch).floor() as i64;
            if c1 >= c0 {
                runs.push(Run::dots(lat.x(r, c0), lat.pitch, (c1 - c0 + 1) as u32));
            }
        }
        if !runs.is_empty() {
            out.push(Row { y, runs });
        }
    }
    out
}

/// Explicit spots: grouped into rows by their local y (within 1 nm), ordered along u; a run is
/// a stretch of equal spacing. A lone spot gets `pitch` as its spacing (for the lit move's
/// length on the fly).
pub fn point_rows(frame: &Frame, points: &[V2], pitch: f64) -> Vec<Row> {
    let mut local: Vec<V2> = points.iter().map(|p| frame.to_local(*p)).collect();
    local.sort_by(|a, b| a.y.total_cmp(&b.y).then(a.x.total_cmp(&b.x)));
    let mut rows: Vec<Row> = Vec::new();
    let mut i = 0;
    while i < local.len() {
        let y = local[i].y;
        let mut j = i;
        while j < local.len() && (local[j].y - y).abs() <= BORDER_TOL_MM {
            j += 1;
        }
        let xs: Vec<f64> = local[i..j].iter().map(|p| p.x).collect();
        let mut runs: Vec<Run> = Vec::new();
        let mut k = 0;
        while k < xs.len() {
            if k + 1 == xs.len() {
                runs.push(Run::dots(xs[k], pitch, 1));
                break;
            }
            let gap = xs[k + 1] - xs[k];
            if gap <= BORDER_TOL_MM {
                k += 1; // a repeated spot is one spot
                continue;
            }
            let mut n = 2;
            while k + n < xs.len() && ((xs[k + n] - xs[k]) - n as f64 * gap).abs() <= BORDER_TOL_MM
            {
                n += 1;
            }
            runs.push(Run::dots(xs[k], gap, n as u32));
            k += n;
        }
        rows.push(Row { y, runs });
        i = j;
    }
    rows
}

/// Hatch lines `pitch` apart from the frame origin (line k at local y = k·pitch), clipped to
/// the region; one run per interval.
pub fn hatch_rows(frame: &Frame, pitch: f64, region: &Region) -> Vec<Row> {
    let (lo, hi) = region.bounds(frame);
    let k0 = (lo.y / pitch).ceil() as i64;
    let k1 = (hi.y / pitch).floor() as i64;
    (k0..=k1)
        .filter_map(|k| {
            let y = k as f64 * pitch;
            let runs: Vec<Run> = region
                .intervals(frame, y)
                .into_iter()
                .filter(|(a, b)| b - a > BORDER_TOL_MM * 4.0)
                .map(|(a, b)| Run::line(a, b))
                .collect();
            (!runs.is_empty()).then_some(Row { y, runs })
        })
        .collect()
}

// ------------------------------------------------------------------ path

/// The visit order of rows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Every row in +u, an idle return stroke between rows (the paper's old method).
    Unidirectional,
    /// Rows alternate +u, −u (boustrophedon).
    Serpentine,
}

/// How spots are fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Firing {
    /// Lit moves through the spots at the scan speed, one pulse per spot on the fly (the
    /// position-synchronized output of seed 3). Hatch lines are always lit moves.
    Fly,
    /// Move to each spot, stop, fire.
    Dot,
}

/// One family of rows (a cross-hatch has two) with its frame and row pitch.
#[derive(Debug, Clone)]
pub struct Family {
    pub frame: Frame,
    pub row_pitch: f64,
    pub rows: Vec<Row>,
    /// Extension before the first and after the last run of each row, mm; `None`: the motion
    /// layer's lead-ins extend the rows.
    pub overscan: Option<f64>,
    /// With `overscan: None`, the lead-in length the motion layer will add: row approach
    /// points stand that far before the first spot, so the row step stays a pure `+v` move.
    pub lead: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathOptions {
    pub order: Order,
    pub firing: Firing,
    pub passes: u32,
}

/// One step of a scan path, part coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Step {
    /// Positioning with the beam off at the machine's top speed.
    Travel(V2),
    /// A move at the scan speed with the beam off (overscan, a gap, dot positioning).
    Idle(V2),
    /// A lit move at the scan speed. `pitch`: spots every `pitch` from the move's start (a dot
    /// run on the fly; the move ends half a pitch past its last spot, so the count never
    /// hangs on rounding); `None`: a hatch line.
    Lit { to: V2, pitch: Option<f64> },
    /// Stop here and fire (dot mode).
    Fire(V2),
    /// The move before was the entry to a row (its start, at rest): a row start to settle
    /// (`scan … { settle }`). `dir` is the row's direction of travel (a unit vector).
    RowStart { dir: V2 },
}

/// The steps of `passes` passes over the families, in the documented order.
pub fn scan_path(families: &[Family], opts: &PathOptions) -> Vec<Step> {
    let mut out = Vec::new();
    for _ in 0..opts.passes {
        for fam in families {
            family_pass(fam, opts, &mut out);
        }
    }
    out
}

fn family_pass(fam: &Family, opts: &PathOptions, out: &mut Vec<Step>) {
    let f = &fam.frame;
    let o = fam.overscan.unwrap_or(0.0);
    for (k, row) in fam.rows.iter().filter(|r| !r.runs.is_empty()).enumerate() {
        let d = match opts.order {
            Order::Serpentine if k % 2 == 1 => -1.0,
            _ => 1.0,
        };
        let runs: Vec<&Run> = if d > 0.0 {
            row.runs.iter().collect()
        } else {
            row.runs.iter().rev().collect()
        };
        // Entry and exit of a run in the traversal direction.
        let ends = |r: &Run| if d > 0.0 { (r.x0, r.x1) } else { (r.x1, r.x0) };
        let first = ends(runs[0]).0;
        let approach = match opts.firing {
            Firing::Fly => first - d * fam.overscan.unwrap_or(fam.lead),
            Firing::Dot => first,
        };
        // Without an overscan of its own the row is entered at its first spot: the motion
        // layer moves that positioning back to the lead-in start (`approach`).
        let enter = if fam.overscan.is_none() && opts.firing == Firing::Fly {
            first
        } else {
            approach
        };
        if k == 0 {
            // A' one row pitch before A, then A: the pass starts in +v like every row.
            out.push(Step::Travel(f.to_part(approach, row.y - fam.row_pitch)));
        }
        out.push(match opts.firing {
            // Dot mode reaches rows at the scan speed: a feed move leaves GRBL's laser mode
            // able to fire at rest (it keeps the beam dark after a rapid).
            Firing::Dot => Step::Idle(f.to_part(enter, row.y)),
            Firing::Fly => Step::Travel(f.to_part(enter, row.y)),
        });
        out.push(Step::RowStart { dir: f.u() * d });
        for (j, run) in runs.iter().enumerate() {
            let (a, b) = ends(run);
            match opts.firing {
                Firing::Fly => {
                    if j > 0 || o > 0.0 {
                        out.push(Step::Idle(f.to_part(a, row.y)));
                    }
                    let (to, pitch) = if run.count > 0 {
                        (b + d * 0.5 * run.pitch, Some(run.pitch))
                    } else {
                        (b, None)
                    };
                    out.push(Step::Lit {
                        to: f.to_part(to, row.y),
                        pitch,
                    });
                }
                Firing::Dot => {
                    for i in 0..run.count {
                        let i = if d > 0.0 { i } else { run.count - 1 - i };
                        let p = f.to_part(run.spot(i), row.y);
                        out.push(Step::Idle(p));
                        out.push(Step::Fire(p));
                    }
                }
            }
        }
        if opts.firing == Firing::Fly && o > 0.0 {
            let last = ends(runs[runs.len() - 1]).1;
            let tail = if runs[runs.len() - 1].count > 0 {
                0.5 * runs[runs.len() - 1].pitch
            } else {
                0.0
            };
            out.push(Step::Idle(f.to_part(last + d * (tail + o), row.y)));
        }
    }
}

/// Length of the moves with the beam off (travel and idle) from `start` along `steps`, mm.
#[cfg(test)]
pub fn idle_length(start: V2, steps: &[Step]) -> f64 {
    let mut pos = start;
    let mut idle = 0.0;
    for s in steps {
        match s {
            Step::Travel(p) | Step::Idle(p) => {
                idle += (p - pos).norm();
                pos = *p;
            }
            Step::Lit { to, .. } => pos = *to,
            Step::Fire(_) | Step::RowStart { .. } => {}
        }
    }
    idle
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lat(pitch: f64) -> Lattice {
        Lattice {
            frame: Frame::new(V2::zeros(), 0.0),
            pitch,
            row_pitch: pitch,
            layout: Layout::Grid,
        }
    }

    #[test]
    fn rectangle_region_keeps_border_spots() {
        let rect = Profile::polyline(
            &[
                V2::new(0.0, 0.0),
                V2::new(4.0, 0.0),
                V2::new(4.0, 2.0),
                V2::new(0.0, 2.0),
            ],
            true,
        )
        .unwrap();
        let region = Region::new(&[rect], 0.0).unwrap();
        let rows = region_rows(&lat(0.2), &region);
        assert_eq!(rows.len(), 11);
        assert!(rows.iter().all(|r| r.spots() == 21));
    }

    #[test]
    fn annulus_has_two_runs_through_the_hole() {
        let outer = Profile::circle(V2::zeros(), 5.0, 0.0, true).unwrap();
        let inner = Profile::circle(V2::zeros(), 3.0, 0.0, true).unwrap();
        let region = Region::new(&[outer, inner], 0.0).unwrap();
        let rows = region_rows(&lat(0.5), &region);
        let mid = rows.iter().find(|r| r.y.abs() < 1e-9).unwrap();
        assert_eq!(mid.runs.len(), 2);
        // x = -5..-3 and 3..5 at 0.5 mm: 5 spots each.
        assert_eq!(mid.spots(), 10);
        for row in &rows {
            for run in &row.runs {
                for k in 0..run.count {
                    let r = V2::new(run.spot(k), row.y).norm();
                    assert!((3.0 - 1e-6..=5.0 + 1e-6).contains(&r), "spot at radius {r}");
                }
            }
        }
    }

    #[test]
    fn serpentine_alternates_and_unidirectional_returns() {
        let rows = grid_rows(&lat(1.0), 3, 4);
        let fam = [Family {
            frame: Frame::new(V2::zeros(), 0.0),
            row_pitch: 1.0,
            rows,
            overscan: Some(0.5),
            lead: 0.0,
        }];
        let opts = PathOptions {
            order: Order::Serpentine,
            firing: Firing::Fly,
            passes: 1,
        };
        let s = scan_path(&fam, &opts);
        let lits: Vec<V2> = s
            .iter()
            .filter_map(|s| match s {
                Step::Lit { to, .. } => Some(*to),
                _ => None,
            })
            .collect();
        assert_eq!(
            lits,
            vec![V2::new(3.5, 0.0), V2::new(-0.5, 1.0), V2::new(3.5, 2.0)]
        );
        let serp = idle_length(V2::new(-0.5, -1.0), &s);
        let uni = idle_length(
            V2::new(-0.5, -1.0),
            &scan_path(
                &fam,
                &PathOptions {
                    order: Order::Unidirectional,
                    ..opts
                },
            ),
        );
        assert!(uni > serp);
    }
}
