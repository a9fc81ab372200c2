//! Cut order and kerf over a finished list of ops (`planner { order nearest | inner_first }`,
//! `laser { kerf }`): the job's paths are found in the ops, moved out or in by half the kerf
//! (in any order, `source` included), and put in the order `geometry::order` chooses.
//!
//! A *path* is a rapid followed by the feed moves after it (lit, or unlit across a tab's gap)
//! up to the next op that is not a feed move. Paths only trade places with paths next to them:
//! a dwell, an M-code, an event, a dot-mode stop or a rapid with no cut after it stays where it
//! is, and the paths on either side of it are ordered apart, since the recipe put that op
//! between them for a reason. Oriented programs (cam_xwb, arm_3r) are left as written: their
//! poses chain continuously and a reorder would break the chain.

use super::{EvalError, R, geom_error};
use crate::geometry::offset::OffsetOptions;
use crate::geometry::order::{PathShape, Visit, containment, order, ring};
use crate::geometry::{Profile, Seg, V2};
use crate::program::{CutOrder, Laser, Op, OpKind, OrderReport, P3, dist};
use lase_lang::Span;
use std::sync::Arc;

/// A path whose end is nearer its start than this share of its length still bounds a region
/// (a closed profile cut in pieces between tabs leaves its last gap open); a gap this size is
/// wider than any tab and far narrower than the opening of an open shape such as an arc.
const TAB_GAP_SHARE: f64 = 0.1;

/// Paths one run may order or give a kerf: containment and the nearest-next search compare
/// every path with every other (some seconds for 10 000 paths in a debug build), so a job of
/// more paths is refused before it is worked on rather than left to run for minutes. Real
/// sheets hold hundreds of paths.
const MAX_ORDERED_PATHS: usize = 10_000;

/// One path: its leading rapid and its feed moves.
struct Path {
    span: Span,
    from_rapid: Op,
    feeds: Vec<Op>,
}

impl Path {
    fn ends(&self) -> Vec<P3> {
        let mut e = vec![self.from_rapid.target().unwrap_or([0.0; 3])];
        e.extend(self.feeds.iter().filter_map(Op::target));
        e
    }

    /// Each feed's arc midpoint (for the polygon of the path), `None` for lines.
    fn mids(&self, ends: &[P3]) -> Vec<Option<V2>> {
        self.feeds
            .iter()
            .zip(ends)
            .map(|(op, &from)| {
                let (r, a0, sweep) = op.arc_from(from)?;
                let OpKind::Arc { center, .. } = op.kind else {
                    return None;
                };
                let a = a0 + sweep / 2.0;
                Some(V2::new(center[0] + r * a.cos(), center[1] + r * a.sin()))
            })
            .collect()
    }

    fn shape(&self) -> (PathShape, Vec<V2>) {
        let ends = self.ends();
        let mids = self.mids(&ends);
        let gap = dist(ends[0], ends[ends.len() - 1]);
        let closed = gap < 1e-6;
        let length: f64 = self
            .feeds
            .iter()
            .zip(&ends)
            .map(|(op, &from)| op.length_from(from))
            .sum();
        let ring = ring(&ends[..ends.len() - usize::from(closed)], &mids);
        let shape = PathShape {
            shape: mids.iter().flatten().copied().collect(),
            ends,
            closed,
            // A tabbed outline ends one tab short of its start: still the border of its part.
            encloses: closed || gap < TAB_GAP_SHARE * length,
            movable: true,
        };
        (shape, ring)
    }
}

enum Item {
    Keep(Op),
    Path(Path),
}

/// `ops` (starting at `start`) with the paths ordered and kerf applied, and what the order
/// saved; the ops unchanged when there is nothing to do.
pub(super) fn order_ops(
    ops: Vec<Op>,
    start: P3,
    how: CutOrder,
    tol_mm: f64,
) -> R<(Vec<Op>, Option<OrderReport>)> {
    // A kerf is applied whatever the order; in source order the paths keep their places.
    let kerfed = ops
        .iter()
        .any(|o| o.laser().is_some_and(|l| l.kerf_mm > 0.0));
    if (how == CutOrder::Source && !kerfed) || ops.iter().any(|o| o.orient().is_some()) {
        return Ok((ops, None));
    }
    let ops = &ops[..];
    let items = split(ops, start);
    let mut out = Vec::with_capacity(ops.len());
    let mut run: Vec<Path> = Vec::new();
    let mut paths = 0;
    for item in items {
        match item {
            Item::Path(p) => run.push(p),
            Item::Keep(op) => {
                paths += run.len();
                flush(&mut run, &mut out, start, how, tol_mm)?;
                out.push(op);
            }
        }
    }
    paths += run.len();
    flush(&mut run, &mut out, start, how, tol_mm)?;
    let report = (how != CutOrder::Source).then(|| OrderReport {
        paths,
        source_travel_mm: travel(ops, start),
        travel_mm: travel(&out, start),
    });
    Ok((out, report))
}

/// Length of the rapids, mm.
fn travel(ops: &[Op], start: P3) -> f64 {
    let mut at = start;
    let mut sum = 0.0;
    for op in ops {
        if let OpKind::Rapid { to, .. } = &op.kind {
            sum += dist(at, *to);
        }
        if let Some(t) = op.target() {
            at = t;
        }
    }
    sum
}

fn is_feed(op: &Op) -> bool {
    matches!(op.kind, OpKind::Line { .. } | OpKind::Arc { .. })
}

/// Whether a path carries an image row (`scan image`): its pixel runs are laid out in the
/// direction it was scanned, so it is never reversed or moved; it stays where it is, like a
/// dwell.
fn has_row(feeds: &[Op]) -> bool {
    feeds
        .iter()
        .any(|o| matches!(o.kind, OpKind::Line { row: Some(_), .. }))
}

fn split(ops: &[Op], start: P3) -> Vec<Item> {
    let mut items = Vec::new();
    let mut i = 0;
    let mut moved = false;
    while i < ops.len() {
        let op = &ops[i];
        if !moved && is_feed(op) && op.laser().is_some() {
            // The job's first path starts where the machine stands, so `follow` wrote no rapid
            // to it; it is a path all the same (ordered, and given its kerf by containment),
            // reached by a rapid from the start that is empty unless it is reordered.
            let n = ops[i..].iter().take_while(|o| is_feed(o)).count();
            if has_row(&ops[i..i + n]) {
                items.extend(ops[i..i + n].iter().cloned().map(Item::Keep));
                moved = true;
                i += n;
                continue;
            }
            items.push(Item::Path(Path {
                span: op.span,
                from_rapid: Op {
                    kind: OpKind::Rapid {
                        to: start,
                        orient: None,
                    },
                    span: op.span,
                },
                feeds: ops[i..i + n].to_vec(),
            }));
            moved = true;
            i += n;
            continue;
        }
        moved |= op.target().is_some();
        if matches!(op.kind, OpKind::Rapid { .. }) && ops.get(i + 1).is_some_and(is_feed) {
            let n = ops[i + 1..].iter().take_while(|o| is_feed(o)).count();
            if has_row(&ops[i + 1..i + 1 + n]) {
                items.extend(ops[i..i + 1 + n].iter().cloned().map(Item::Keep));
                i += 1 + n;
                continue;
            }
            items.push(Item::Path(Path {
                span: op.span,
                from_rapid: op.clone(),
                feeds: ops[i + 1..i + 1 + n].to_vec(),
            }));
            i += 1 + n;
        } else {
            items.push(Item::Keep(op.clone()));
            i += 1;
        }
    }
    items
}

/// Orders the paths of one run (kerf first, so each is entered on the line it is cut on) and
/// appends them to `out`.
fn flush(run: &mut Vec<Path>, out: &mut Vec<Op>, start: P3, how: CutOrder, tol_mm: f64) -> R<()> {
    if run.is_empty() {
        return Ok(());
    }
    if run.len() > MAX_ORDERED_PATHS {
        return Err(EvalError::TooLarge {
            message: format!(
                "{} paths in a row: lase orders (or gives a kerf to) at most {MAX_ORDERED_PATHS}",
                run.len()
            ),
            span: run[MAX_ORDERED_PATHS].span,
            label: "this path is one too many".into(),
            help: Some(
                "write `planner { order source }` and `laser { kerf 0 }` and order the paths in \
                 the recipe, or split the job into several recipes"
                    .into(),
            ),
        });
    }
    let from = out.iter().rev().find_map(Op::target).unwrap_or(start);
    let (shapes, rings): (Vec<_>, Vec<_>) = run.iter().map(Path::shape).unzip();
    let inside = containment(&shapes, &rings);
    for (k, path) in run.iter_mut().enumerate() {
        kerf(path, &shapes[k], inside[k].len(), tol_mm)?;
    }
    let (shapes, rings): (Vec<_>, Vec<_>) = run.iter().map(Path::shape).unzip();
    let visits = if how == CutOrder::Source {
        (0..run.len())
            .map(|path| Visit {
                path,
                entry: 0,
                reversed: false,
            })
            .collect()
    } else {
        order(&shapes, &rings, from, how == CutOrder::InnerFirst)
    };
    for v in visits {
        let p = &run[v.path];
        let ends = &shapes[v.path].ends;
        let entry = if p.feeds.is_empty() {
            ends[0]
        } else if shapes[v.path].closed {
            ends[v.entry]
        } else if v.reversed {
            ends[ends.len() - 1]
        } else {
            ends[0]
        };
        out.push(Op {
            kind: OpKind::Rapid {
                to: entry,
                orient: None,
            },
            span: p.from_rapid.span,
        });
        if shapes[v.path].closed {
            out.extend(p.feeds[v.entry..].iter().cloned());
            out.extend(p.feeds[..v.entry].iter().cloned());
        } else if v.reversed {
            for k in (0..p.feeds.len()).rev() {
                out.push(reversed(&p.feeds[k], ends[k]));
            }
        } else {
            out.extend(p.feeds.iter().cloned());
        }
    }
    run.clear();
    Ok(())
}

/// The feed move `op` run backwards, ending at `to` (its start).
fn reversed(op: &Op, to: P3) -> Op {
    let kind = match &op.kind {
        OpKind::Line {
            feed_mm_s,
            laser,
            orient,
            ..
        } => OpKind::Line {
            to,
            feed_mm_s: *feed_mm_s,
            laser: laser.clone(),
            orient: orient.clone(),
            // Paths with image rows are kept as scanned (`has_row`), never reversed.
            row: None,
        },
        OpKind::Arc {
            center,
            ccw,
            feed_mm_s,
            laser,
            ..
        } => OpKind::Arc {
            to,
            center: *center,
            ccw: !ccw,
            feed_mm_s: *feed_mm_s,
            laser: laser.clone(),
        },
        other => other.clone(),
    };
    Op {
        kind,
        span: op.span,
    }
}

/// Moves a closed path half its kerf outward (an outline: inside an even number of closed
/// paths) or inward (a hole), so the part comes out at its drawn size.
fn kerf(path: &mut Path, shape: &PathShape, depth: usize, tol_mm: f64) -> R<()> {
    let Some(laser) = path.feeds.iter().find_map(Op::shared_laser).cloned() else {
        return Ok(());
    };
    // An open path has no inside or outside to move toward: a kerf leaves it as drawn.
    if laser.kerf_mm == 0.0 || !shape.encloses {
        return Ok(());
    }
    let feed = path
        .feeds
        .iter()
        .find_map(Op::lit_feed)
        .map_or(0.0, |f| f.0);
    let z = shape.ends[0][2];
    let uniform = shape.closed
        && path.feeds.iter().all(|o| {
            o.lit_feed().is_some_and(|(f, l)| f == feed && *l == *laser)
                && o.target().is_some_and(|t| t[2] == z)
        });
    if !uniform {
        return Err(EvalError::Geometry {
            message: "a kerf needs the closed path cut whole, at one speed and power, in one plane"
                .into(),
            span: path.span,
            label: "this path has tabs, unlit gaps or several settings".into(),
            help: Some(
                "offset the profile yourself before cutting it in pieces, e.g. \
                 `tabs(offset(p, kerf / 2), count: 4, width: 2 mm)`, and set `laser { kerf 0 }` \
                 for it"
                    .into(),
            ),
        });
    }
    let segs: Vec<Seg> = path
        .feeds
        .iter()
        .zip(&shape.ends)
        .map(|(op, &from)| {
            let to = op.target().unwrap_or(from);
            match (op.arc_from(from), &op.kind) {
                (Some((r, a0, sweep)), OpKind::Arc { center, .. }) => Seg::Arc {
                    center: V2::new(center[0], center[1]),
                    r,
                    a0,
                    sweep,
                },
                _ => Seg::Line {
                    a: V2::new(from[0], from[1]),
                    b: V2::new(to[0], to[1]),
                },
            }
        })
        .collect();
    let profile = Profile::from_segs(segs, true);
    let d = if depth.is_multiple_of(2) { 1.0 } else { -1.0 } * laser.kerf_mm / 2.0;
    let opts = OffsetOptions {
        trim: false,
        tol_mm,
    };
    let moved = profile
        .offset_with(d, &opts)
        .map_err(|g| geom_error(g, path.span, Some(d)))?;
    let s = moved.start();
    path.from_rapid = Op {
        kind: OpKind::Rapid {
            to: [s.x, s.y, z],
            orient: None,
        },
        span: path.from_rapid.span,
    };
    path.feeds = profile_ops(&moved, z, feed, &laser)
        .into_iter()
        .map(|kind| Op {
            kind,
            span: path.span,
        })
        .collect();
    Ok(())
}

/// The feed moves that cut `profile` at height `z`: one per line, arcs longer than a half turn
/// split so every dialect reads them unambiguously.
pub(super) fn profile_ops(profile: &Profile, z: f64, feed: f64, laser: &Arc<Laser>) -> Vec<OpKind> {
    let mut out = Vec::with_capacity(profile.segs.len());
    for seg in &profile.segs {
        match seg {
            Seg::Line { b, .. } => out.push(OpKind::Line {
                to: [b.x, b.y, z],
                feed_mm_s: feed,
                laser: Some(laser.clone()),
                orient: None,
                row: None,
            }),
            Seg::Arc {
                center,
                r,
                a0,
                sweep,
            } => {
                let pieces = (sweep.abs() / std::f64::consts::PI - 1e-9).ceil().max(1.0) as usize;
                for k in 1..=pieces {
                    let a = a0 + sweep * k as f64 / pieces as f64;
                    let to = if k == pieces {
                        seg.end()
                    } else {
                        center + V2::new(a.cos(), a.sin()) * *r
                    };
                    out.push(OpKind::Arc {
                        to: [to.x, to.y, z],
                        center: [center.x, center.y],
                        ccw: *sweep > 0.0,
                        feed_mm_s: feed,
                        laser: Some(laser.clone()),
                    });
                }
            }
        }
    }
    out
}
