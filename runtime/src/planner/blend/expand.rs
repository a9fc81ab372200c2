//! The whole plan's split (`split`) made in the table it splits, so that a job holds its
//! expanded plan once, not beside the prepared one (issue 13 item 3 with issue 18's memory per
//! move: a lit zigzag whose every corner is blended has 2.5 segments a move, and building them
//! beside the prepared moves held 137 bytes a move more at the peak, plus 20 % spare capacity).
//!
//! **How.** First an upper bound of the segments the split makes is counted from each corner's
//! shape (`shape_at`, cheap: no limits): a move gets the half-blend after its start corner, its
//! straight middle (unless the blends leave none of it) and the half-blend before its end
//! corner. A corner whose limits then turn it into a stop (`with_limits`) loses its halves and
//! may give its moves the middle they lacked, never more, so the count bounds the split. The
//! table is grown to that many segments (plus [`SLACK`]) and the prepared moves moved to its
//! end; the split then reads them there and writes its segments from the front. It writes
//! segment `o` only once every move it still reads lies past `o`: after move `i` it has written
//! at most `bound − (moves after i)` segments, and the moves it reads from there on start at
//! `i + 1 − READS_BEHIND`, which lie at `shift + i + 1 − READS_BEHIND` with `shift = bound +
//! SLACK − count` — past what it wrote when `SLACK ≥ READS_BEHIND`. Should the bound ever fail,
//! the moves still to read are moved further on first (`make_room`), so the split never reads a
//! move it overwrote. The points need no such room: a move splits into one straight segment at
//! most (the halves of blends keep no point, `Plan::segment_start`), so they are written over
//! the moves' own from the front, [`SLACK`] behind the first one still read. What is left
//! unused is given back (`shrink_to_fit`: the allocator shrinks the block in place) and the
//! blends' table is sized to the blends made.

use super::super::lookahead::Kin;
use super::super::{Axes, AxisLimits, Prepared};
use super::judge::{MoveSource, READS_BEHIND, shape_at};
use super::{Blends, MoveInfo, MoveInfos, Splitter, junction_at};

/// Room kept between what the split has written and the first move it may still read: the
/// moves a junction reads before its own (`READS_BEHIND`), and two more for safety.
const SLACK: usize = READS_BEHIND + 2;

/// The prepared moves, `shift` segments into the table the split writes into and [`SLACK`]
/// points into the points (`n` values each).
struct Shifted<'a> {
    p: &'a Prepared,
    info: &'a MoveInfos,
    start: Axes,
    n: usize,
    shift: usize,
    count: usize,
}

impl MoveSource for Shifted<'_> {
    fn count(&self) -> usize {
        self.count
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self.p.segments[self.shift + i].kin()
    }

    #[inline]
    fn point(&self, i: usize) -> Axes {
        if i >= self.count {
            return self.p.end;
        }
        let k = (SLACK + i) * self.n;
        let mut q = self.start;
        q[..self.n].copy_from_slice(&self.p.points[k..k + self.n]);
        q
    }

    #[inline]
    fn info(&self, i: usize) -> MoveInfo {
        self.info.get(i)
    }
}

/// An upper bound of the segments `split` makes of `src`'s moves, and of its blends: per move,
/// what `Splitter::split_move` would push if every corner `shape_at` can round kept its blend.
pub(super) fn bound(src: &impl MoveSource, delta: f64, n: usize) -> (usize, usize) {
    let count = src.count();
    let (mut segments, mut blends) = (0usize, 0usize);
    let mut reach_in: Option<f64> = None;
    for i in 0..count {
        let reach_out = shape_at(src, i, delta, n).ok().map(|b| b.reach);
        let k = src.kin(i);
        if k.len == 0.0 {
            segments += 1;
            reach_in = None;
            continue;
        }
        let (l_in, l_out) = (reach_in.unwrap_or(0.0), reach_out.unwrap_or(0.0));
        let mid = k.len - l_in - l_out;
        segments += usize::from(reach_in.is_some())
            + usize::from(mid > 1e-9 * k.len)
            + usize::from(reach_out.is_some());
        blends += usize::from(reach_out.is_some());
        reach_in = reach_out;
    }
    (segments, blends)
}

/// `split` of `p` (which has `bound` segments at most and `blends` blends at most, [`bound`]),
/// in `p`'s own tables.
pub(super) fn split_in_place(
    mut p: Prepared,
    info: &MoveInfos,
    start: Axes,
    delta: f64,
    limits: &AxisLimits,
    n: usize,
    (bound, blends): (usize, usize),
) -> Prepared {
    let count = p.segments.len();
    let len = bound.max(count) + SLACK;
    let mut shift = len - count;
    // The moves go to the end of the grown table (the filler is overwritten before it is read).
    // A move splits into one straight segment at most, the others are the halves of blends,
    // which keep no point (`Plan::segment_start`): the points need room for what is read
    // behind only.
    let filler = p.segments.first().copied();
    if let Some(filler) = filler {
        p.segments.reserve_exact(len - count);
        p.segments.resize(len, filler);
        p.segments.copy_within(0..count, shift);
        p.points.reserve_exact(SLACK * n);
        p.points.resize((count + SLACK) * n, 0.0);
        p.points.copy_within(0..count * n, SLACK * n);
    }
    p.blends = Blends::with_capacity(n, start, blends);
    // What one move splits into, before it is copied to its place.
    let mut piece = Prepared {
        segments: Vec::with_capacity(3),
        points: Vec::with_capacity(3 * n),
        end: p.end,
        blends: Blends::new(n, start),
    };
    let mut splitter = Splitter::default();
    let (mut written, mut written_points) = (0usize, 0usize);
    for i in 0..count {
        let src = Shifted {
            p: &p,
            info,
            start,
            n,
            shift,
            count,
        };
        let after = junction_at(&src, i, delta, limits, n);
        let at = src.point(i);
        let seg = p.segments[shift + i];
        piece.segments.clear();
        piece.points.clear();
        splitter.split_move(seg, &at, after, &mut piece, n);
        let k = piece.segments.len();
        // The first move read from here on: what the junction after `i + 1` reads.
        let keep = (i + 1).saturating_sub(READS_BEHIND);
        if written + k > shift + keep {
            shift = make_room(&mut p, shift, keep, count, written + k);
        }
        p.segments[written..written + k].copy_from_slice(&piece.segments);
        let kp = piece.points.len();
        debug_assert!(written_points + kp <= (SLACK + keep) * n);
        p.points[written_points..written_points + kp].copy_from_slice(&piece.points);
        written_points += kp;
        if let Some(b) = piece.blends.get(0) {
            p.blends.push(b);
            piece.blends = Blends::new(n, start);
        }
        written += k;
    }
    p.segments.truncate(written);
    p.segments.shrink_to_fit();
    p.points.truncate(written_points);
    p.points.shrink_to_fit();
    p.blends.shrink_to_fit();
    p
}

/// Moves the prepared moves' segments from `keep` on further into the table, so that `upto`
/// segments can be written before them; returns the new shift. Only where [`bound`] failed
/// (module doc).
#[cold]
fn make_room(p: &mut Prepared, shift: usize, keep: usize, count: usize, upto: usize) -> usize {
    let grow = (upto - (shift + keep)).max(count - keep);
    let (from, to) = (shift + keep, shift + count);
    let filler = p.segments[from];
    p.segments.resize(p.segments.len() + grow, filler);
    p.segments.copy_within(from..to, from + grow);
    shift + grow
}

#[cfg(test)]
mod tests {
    use super::super::judge::Whole;
    use super::*;
    use crate::planner::{
        Along, Corners, MAX_AXES, Move, PlannerConfig, Preparer, ProfileKind, Raw,
    };

    /// A bound too small for the split (every move as one segment, no slack) moves the moves
    /// still to read on as often as it needs, and the split is the one a true bound gives, bit
    /// for bit: the lit chords of a circle sharing their curvature (junctions reading
    /// `READS_BEHIND` moves back), then a lit zigzag, then a stop and a dark corner.
    #[test]
    fn a_bound_that_fails_moves_the_moves_on_and_splits_the_same() {
        let cfg = PlannerConfig {
            profile: ProfileKind::SCurve,
            junction_deviation: 0.01,
            n_axes: 2,
            corners: Corners::Blend,
            ..PlannerConfig::default()
        };
        let limits = AxisLimits {
            v: [200.0; MAX_AXES],
            a: [2000.0; MAX_AXES],
            j: [50_000.0; MAX_AXES],
        };
        let mut points: Vec<([f64; 2], bool)> = (0..=40)
            .map(|i| {
                let t = 0.1 * f64::from(i);
                ([4.0 * t.cos(), 4.0 * t.sin()], true)
            })
            .collect();
        let (x0, y0) = (points[40].0[0], points[40].0[1]);
        points.extend((1..=30).map(|i| {
            let y = if i % 2 == 1 { 0.005 } else { 0.0 };
            ([x0 + 0.05 * f64::from(i), y0 + y], true)
        }));
        points.extend([([0.0, 0.0], false), ([0.0, 3.0], false)]);
        let start = Axes::from([4.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let prepared = || {
            let mut raw = Raw {
                segments: Vec::new(),
                points: Vec::new(),
                info: MoveInfos::default(),
            };
            let mut prep = Preparer::new(start, &limits, &cfg);
            let mut from = start;
            for (index, &([x, y], lit)) in points.iter().enumerate().skip(1) {
                let to = Axes::from([x, y, 0.0, 0.0, 0.0, 0.0]);
                let mv = Move::linear(from, to, 30.0);
                let here = Along {
                    lit,
                    ..Along::default()
                };
                prep.push(index, &mv, here, &mut raw)
                    .expect("the move is valid");
                from = to;
            }
            let p = Prepared {
                segments: raw.segments,
                points: raw.points,
                end: prep.q,
                blends: Blends::new(2, start),
            };
            (p, raw.info)
        };
        let (p, info) = prepared();
        let count = p.segments.len();
        let src = Whole {
            p: &p,
            info: &info,
            start,
            n: 2,
        };
        let bound = bound(&src, cfg.junction_deviation, 2);
        let want = split_in_place(p, &info, start, 0.01, &limits, 2, bound);
        assert!(want.segments.len() <= bound.0 && want.blends.len() <= bound.1);
        assert!(
            want.segments.len() > 2 * count,
            "{} segments",
            want.segments.len()
        );
        assert!(
            want.blends.iter().any(|b| b.shared != 0),
            "a run shares its curvature"
        );
        let (p, info) = prepared();
        let got = split_in_place(p, &info, start, 0.01, &limits, 2, (0, 0));
        assert_eq!(got.segments, want.segments);
        assert_eq!(got.points, want.points);
        assert_eq!(got.blends, want.blends);
    }
}
