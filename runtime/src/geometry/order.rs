//! Cut order: which of a job's paths to cut first, where to enter each and which way round.
//!
//! Two rules, as a shop cuts parts out of a sheet:
//! - *Inner before outer*: a path lying inside a closed path is cut before it, so a hole is cut
//!   while the part is still held by the sheet (a part cut free first drops or shifts, and its
//!   holes land in the wrong place).
//! - *Nearest next*: among the paths whose insides are done, the one whose entry is nearest the
//!   spot goes next (greedy nearest neighbour), entering a closed path at its vertex nearest
//!   the spot and an open path at its nearer end.
//!
//! Plain math on plain data: a path is its vertices (the ends of its pieces, plus midpoints of
//! arcs so a polygon through them follows the curve), whether it is closed, and whether it may
//! be entered elsewhere than its start.

use super::V2;

/// One path as the ordering sees it.
#[derive(Debug, Clone)]
pub struct PathShape {
    /// The path's start, then the end of each of its pieces (mm, part coordinates).
    pub ends: Vec<[f64; 3]>,
    /// Extra points on the path (arc midpoints) that only shape its polygon.
    pub shape: Vec<V2>,
    /// The path ends where it starts.
    pub closed: bool,
    /// The path bounds a region other paths can lie in: closed, or nearly closed (a profile
    /// cut in pieces between tabs, whose last gap is left open).
    pub encloses: bool,
    /// The path may be entered at another vertex (closed) or from its end (open).
    pub movable: bool,
}

/// Where and how one path is cut.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Visit {
    /// Index of the path in the input.
    pub path: usize,
    /// Closed paths: the vertex (index into `ends`) where the cut starts.
    pub entry: usize,
    /// Open paths: cut from the end back to the start.
    pub reversed: bool,
}

impl PathShape {
    fn bbox(&self) -> (V2, V2) {
        let mut lo = V2::new(f64::INFINITY, f64::INFINITY);
        let mut hi = -lo;
        for p in self.points() {
            lo = lo.inf(&p);
            hi = hi.sup(&p);
        }
        (lo, hi)
    }

    fn points(&self) -> impl Iterator<Item = V2> + '_ {
        self.ends
            .iter()
            .map(|p| V2::new(p[0], p[1]))
            .chain(self.shape.iter().copied())
    }
}

/// Even-odd test of `p` against the closed polygon `poly` (vertices in order).
fn inside(poly: &[V2], p: V2) -> bool {
    let mut c = false;
    let n = poly.len();
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + n - 1) % n]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            c = !c;
        }
    }
    c
}

/// `inner[i]` lists the enclosing paths that path `i` lies inside (every point of it inside
/// their polygon).
pub fn containment(paths: &[PathShape], rings: &[Vec<V2>]) -> Vec<Vec<usize>> {
    let boxes: Vec<(V2, V2)> = paths.iter().map(PathShape::bbox).collect();
    (0..paths.len())
        .map(|i| {
            (0..paths.len())
                .filter(|&j| {
                    j != i
                        && paths[j].encloses
                        && boxes[j].0.x <= boxes[i].0.x
                        && boxes[j].0.y <= boxes[i].0.y
                        && boxes[j].1.x >= boxes[i].1.x
                        && boxes[j].1.y >= boxes[i].1.y
                        && paths[i].points().all(|p| inside(&rings[j], p))
                })
                .collect()
        })
        .collect()
}

/// The ring of a closed path: its ends with each piece's shape point after it, so the polygon
/// follows arcs. `mids[k]` is the shape point of piece k, if any.
pub fn ring(ends: &[[f64; 3]], mids: &[Option<V2>]) -> Vec<V2> {
    let mut out = Vec::with_capacity(ends.len() * 2);
    for (k, e) in ends.iter().enumerate() {
        out.push(V2::new(e[0], e[1]));
        if let Some(Some(m)) = mids.get(k) {
            out.push(*m);
        }
    }
    out
}

fn d3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// The cut order from `from`: every path once; with `inner_first`, no closed path before a
/// path inside it; nearest entry next among the paths allowed.
pub fn order(
    paths: &[PathShape],
    rings: &[Vec<V2>],
    from: [f64; 3],
    inner_first: bool,
) -> Vec<Visit> {
    let inner = if inner_first {
        containment(paths, rings)
    } else {
        vec![Vec::new(); paths.len()]
    };
    // waiting[j]: paths inside j not yet cut.
    let mut waiting = vec![0usize; paths.len()];
    for outs in &inner {
        for &j in outs {
            waiting[j] += 1;
        }
    }
    let mut done = vec![false; paths.len()];
    let mut at = from;
    let mut out = Vec::with_capacity(paths.len());
    for _ in 0..paths.len() {
        let mut best: Option<(f64, Visit)> = None;
        for (i, p) in paths.iter().enumerate() {
            if done[i] || waiting[i] > 0 {
                continue;
            }
            let n = p.ends.len();
            let mut consider = |d: f64, v: Visit| {
                if best.is_none_or(|(b, _)| d < b - 1e-9) {
                    best = Some((d, v));
                }
            };
            let plain = Visit {
                path: i,
                entry: 0,
                reversed: false,
            };
            consider(d3(at, p.ends[0]), plain);
            if p.movable && p.closed {
                // The last end is the start again.
                for k in 1..n.saturating_sub(1) {
                    consider(d3(at, p.ends[k]), Visit { entry: k, ..plain });
                }
            } else if p.movable {
                consider(
                    d3(at, p.ends[n - 1]),
                    Visit {
                        reversed: true,
                        ..plain
                    },
                );
            }
        }
        // Containment is acyclic (a path inside another is smaller), so one is always ready.
        let Some((_, v)) = best else { break };
        done[v.path] = true;
        for &j in &inner[v.path] {
            waiting[j] -= 1;
        }
        let p = &paths[v.path];
        at = if p.closed {
            p.ends[v.entry]
        } else if v.reversed {
            p.ends[0]
        } else {
            p.ends[p.ends.len() - 1]
        };
        out.push(v);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(x: f64, y: f64, s: f64) -> PathShape {
        PathShape {
            ends: vec![
                [x, y, 0.0],
                [x + s, y, 0.0],
                [x + s, y + s, 0.0],
                [x, y + s, 0.0],
                [x, y, 0.0],
            ],
            shape: vec![],
            closed: true,
            encloses: true,
            movable: true,
        }
    }

    #[test]
    fn holes_go_before_their_outline_and_travel_is_nearest() {
        // Outline first in source order, then a hole in it, then a far part.
        let paths = vec![
            square(0.0, 0.0, 50.0),
            square(100.0, 0.0, 10.0),
            square(20.0, 20.0, 5.0),
        ];
        let rings: Vec<Vec<V2>> = paths.iter().map(|p| ring(&p.ends, &[])).collect();
        let v = order(&paths, &rings, [0.0; 3], true);
        let seq: Vec<usize> = v.iter().map(|v| v.path).collect();
        assert_eq!(seq, vec![2, 0, 1]);
        // The outline is entered at the corner nearest the hole's start (20, 20): (0, 0)... the
        // nearest of (0,0), (50,0), (50,50), (0,50) to (20,20) is (0,0).
        assert_eq!(v[1].entry, 0);
        // Without the rule the outline, whose corner is where the spot stands, goes first.
        let free: Vec<usize> = order(&paths, &rings, [0.0; 3], false)
            .iter()
            .map(|v| v.path)
            .collect();
        assert_eq!(free[0], 0);
    }
}
