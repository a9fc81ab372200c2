//! The junction after a move, judged from the moves around it (`Splitter` splits each move at
//! it): its blend's shape, the curvature it shares with its neighbours on a run of chords, and
//! its limits. It reads the moves through [`MoveSource`], the whole program's (`split`) or the
//! planner's buffer in windows (`window`), so both judge every corner from the same moves.

use super::super::lookahead::Kin;
use super::super::{Axes, AxisLimits, Prepared};
use super::{
    ABUT, Blend, Junction, LEVELS, MIN_RUN, MoveInfo, MoveInfos, Side, Unrounded, curve_like,
    part_turn, shape, shared_at, shared_curvature, with_limits,
};

/// What [`junction_at`] reads of the moves `prepare` made: each move's look-ahead data, start
/// point and flags, by its index among them; `count` once every move is known (`usize::MAX`
/// before: the planner in windows judges a junction only once both its moves and the one after
/// them are in).
pub(in crate::planner) trait MoveSource {
    fn count(&self) -> usize;
    fn kin(&self, i: usize) -> Kin;
    /// Start point of move `i`; the end of the last move for `i == count`.
    fn point(&self, i: usize) -> Axes;
    fn info(&self, i: usize) -> MoveInfo;
}

/// The whole program `prepare` made.
pub(super) struct Whole<'a> {
    pub(super) p: &'a Prepared,
    pub(super) info: &'a MoveInfos,
    pub(super) start: Axes,
    pub(super) n: usize,
}

impl MoveSource for Whole<'_> {
    fn count(&self) -> usize {
        self.p.segments.len()
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self.p.segments[i].kin()
    }

    #[inline]
    fn point(&self, i: usize) -> Axes {
        if i >= self.count() {
            return self.p.end;
        }
        let mut q = self.start;
        q[..self.n].copy_from_slice(&self.p.points[i * self.n..(i + 1) * self.n]);
        q
    }

    #[inline]
    fn info(&self, i: usize) -> MoveInfo {
        self.info.get(i)
    }
}

/// How many moves past `i + 1` [`junction_at`] may read: the shared curvature at the far end
/// of the blend after `i` looks along the run of chords for [`MIN_RUN`] midpoints, each of
/// which reads the blends at both ends of its move (the planner in windows splits move `i`
/// once this many more moves are in).
pub(in crate::planner) const READS_AHEAD: usize = MIN_RUN + 4;

/// How many moves before `i` [`junction_at`] may read (the run looked along backwards).
pub(in crate::planner) const READS_BEHIND: usize = MIN_RUN + 3;

/// The blend's geometry at the junction after move `i` (or what the junction is instead). It
/// reads moves `i` and `i + 1` and the start of `i + 2`.
#[allow(clippy::needless_range_loop)] // one index over parallel axis arrays
pub(super) fn shape_at(
    src: &impl MoveSource,
    i: usize,
    delta: f64,
    n: usize,
) -> Result<Blend, Unrounded> {
    let count = src.count();
    if i.saturating_add(1) >= count || src.kin(i).len == 0.0 || src.kin(i + 1).len == 0.0 {
        return Err(Unrounded::Stop);
    }
    let (info_i, info_next) = (src.info(i), src.info(i + 1));
    if info_next.stop_before {
        return Err(Unrounded::Stop);
    }
    if info_next.stepped_before {
        return Err(Unrounded::Stepped);
    }
    // `Δq / length` of move k, from the points (as `prepare` computed it: not kept, it would
    // be 48 bytes a move).
    let rate = |k: usize| -> Axes {
        let (a, b) = (src.point(k), src.point(k + 1));
        let len = src.kin(k).len;
        let mut r = Axes::ZERO;
        for axis in 0..n {
            r[axis] = (b[axis] - a[axis]) / len;
        }
        r
    };
    let (rate_i, rate_next) = (rate(i), rate(i + 1));
    let (kin_i, kin_next) = (src.kin(i), src.kin(i + 1));
    let turn = part_turn(&info_i.part_dir, &info_next.part_dir);
    shape(
        &src.point(i + 1),
        &Side {
            dir: &rate_i,
            kin: &kin_i,
            euclidean: info_i.euclidean,
        },
        &Side {
            dir: &rate_next,
            kin: &kin_next,
            euclidean: info_next.euclidean,
        },
        delta,
        turn,
        info_next.lit_before,
        n,
    )
}

/// Where the deviation of the blends around move `m` is measured (`raw_g`, `shared_g`).
#[derive(Clone, Copy, PartialEq)]
enum Space {
    /// Every length is the axis-space length: the axis-space deviation is the spot's.
    Axes,
    /// Some length is a part-space chord of mm and rad axes (an oriented machine): the spot's,
    /// to first order, from the moves' part-space directions (`part_blend`).
    Part,
}

/// How the deviation of the blends around move `m` is measured, if it can be: every length is
/// the axis-space length, or the spot's part-space direction is known on all three moves.
fn space_of(src: &impl MoveSource, m: usize) -> Option<Space> {
    let infos = [src.info(m - 1), src.info(m), src.info(m + 1)];
    if infos.iter().all(|i| i.euclidean) {
        return Some(Space::Axes);
    }
    let known = |d: &[f64; 3]| d.iter().any(|&x| x != 0.0);
    infos
        .iter()
        .all(|i| known(&i.part_dir))
        .then_some(Space::Part)
}

/// The blend `b` at the junction after move `i` as the spot sees it, to first order: the same
/// corner and reach, with the spot's part-space unit directions of moves `i` and `i + 1` for
/// its rates. Where a length is the spot's part-space chord, `J·Δq/length` is the spot's unit
/// direction (J the kinematics' Jacobian), so `J` maps the blend's axis-space offset from its
/// corner (`3/16·ℓ·Δu + ℓ²/16·(g0 + g1)`, `Blend::deviation`) to this blend's in part space,
/// and the curvature the axes share (`shared_curvature`, a difference of rates) to the one the
/// part-space rates share: the part-space turn `plan_along` bounds the smoothstep's reach by
/// (`shape`), extended to the shared curvature's term.
fn part_blend(src: &impl MoveSource, b: &Blend, i: usize) -> Blend {
    let dir = |k: usize| {
        let d = src.info(k).part_dir;
        Axes::from_fn(|k| if k < 3 { d[k] } else { 0.0 })
    };
    Blend {
        u: dir(i),
        w: dir(i + 1),
        ..*b
    }
}

/// The curvature the blends at both ends of move `m` would share at its midpoint: where they
/// abut (the move is a chord wholly inside them) and their deviation can be measured as the
/// spot's (`space_of`).
fn raw_g(src: &impl MoveSource, m: usize, delta: f64, n: usize) -> Option<Axes> {
    if m == 0 || m.saturating_add(1) >= src.count() {
        return None;
    }
    space_of(src, m)?;
    let (a, b) = (
        shape_at(src, m - 1, delta, n).ok()?,
        shape_at(src, m, delta, n).ok()?,
    );
    let abut = a.reach + b.reach >= src.kin(m).len * (1.0 - ABUT);
    (abut && curve_like(&a, &b, n)).then(|| shared_curvature(&a, &b))
}

/// The level of curvature shared at the midpoint of move `m` (`Blend::shared`), ramped in at a
/// run's ends: the blend that leaves a straight piece into a run of chords bends from zero, and
/// one that bent to the full curvature within one chord would need more jerk than the
/// smoothstep; so the k-th midpoint from the nearer end of the run gets k/LEVELS of its
/// curvature.
fn level_at(src: &impl MoveSource, m: usize, delta: f64, n: usize) -> Option<(u8, Axes)> {
    raw_g(src, m, delta, n)?;
    // Midpoints of the run on either side, as far as it takes to see a run of MIN_RUN.
    let mut back = 0;
    while back < MIN_RUN && m > back + 1 && raw_g(src, m - 1 - back, delta, n).is_some() {
        back += 1;
    }
    let mut fwd = 0;
    while fwd < MIN_RUN && raw_g(src, m + 1 + fwd, delta, n).is_some() {
        fwd += 1;
    }
    if back + fwd + 1 < MIN_RUN {
        return None;
    }
    let level = 1 + back.min(fwd).min(usize::from(LEVELS - 1)) as u8;
    let (a, b) = (
        shape_at(src, m - 1, delta, n).ok()?,
        shape_at(src, m, delta, n).ok()?,
    );
    Some((level, shared_at(&a, &b, level)))
}

/// The curvature the blends at both ends of move `m` share at its midpoint: where they sample
/// one curve (`raw_g`) and stay within the corner tolerance with it, whatever their other ends
/// share (so each end is decided on its own). The deviation is the spot's: in axis space on a
/// Cartesian path, else in part space to first order (`part_blend`), with the part-space rates'
/// shared curvature at the same levels.
fn shared_g(src: &impl MoveSource, m: usize, delta: f64, n: usize) -> Option<(u8, Axes)> {
    let (level, g) = level_at(src, m, delta, n)?;
    let (a, b) = (
        shape_at(src, m - 1, delta, n).ok()?,
        shape_at(src, m, delta, n).ok()?,
    );
    let z = Axes::ZERO;
    let within = |b: &Blend, g0: &[Axes], g1: &[Axes], n: usize| {
        g0.iter().all(|g0| {
            g1.iter()
                .all(|g1| b.deviation(g0, g1, n) <= delta * (1.0 + 1e-9))
        })
    };
    if space_of(src, m)? == Space::Axes {
        let scaled_g = |k: usize| level_at(src, k, delta, n).map(|(_, g)| g);
        let before = [z, scaled_g(m - 1).unwrap_or(z)];
        let after = [z, scaled_g(m + 1).unwrap_or(z)];
        return (within(&a, &before, &[g], n) && within(&b, &[g], &after, n)).then_some((level, g));
    }
    // The part-space blends around midpoint k (moves k − 1, k, k + 1 have known directions
    // where it shares a curvature: `space_of`).
    let part = |k: usize| -> Option<(Blend, Blend)> {
        Some((
            part_blend(src, &shape_at(src, k - 1, delta, n).ok()?, k - 1),
            part_blend(src, &shape_at(src, k, delta, n).ok()?, k),
        ))
    };
    let part_g = |k: usize| -> Option<Axes> {
        let (level, _) = level_at(src, k, delta, n)?;
        let (pa, pb) = part(k)?;
        Some(shared_at(&pa, &pb, level))
    };
    let (pa, pb) = part(m)?;
    let gp = shared_at(&pa, &pb, level);
    let before = [z, part_g(m - 1).unwrap_or(z)];
    let after = [z, part_g(m + 1).unwrap_or(z)];
    (within(&pa, &before, &[gp], 3) && within(&pb, &[gp], &after, 3)).then_some((level, g))
}

/// The junction after move `i`: its blend with the curvatures it shares with its neighbours on
/// a run of chords, and its limits. Computed where it is needed instead of kept in a table: a
/// `Junction` with its blend is about 220 bytes, more than the plan's own segment, kin and
/// point of a move together (issue 18's memory per move). It reads from [`READS_BEHIND`] moves
/// before `i` to [`READS_AHEAD`] after `i + 1`.
pub(in crate::planner) fn junction_at(
    src: &impl MoveSource,
    i: usize,
    delta: f64,
    limits: &AxisLimits,
    n: usize,
) -> Junction {
    let mut blend = match shape_at(src, i, delta, n) {
        Ok(b) => b,
        Err(other) => return other.into(),
    };
    let (l0, g0) = shared_g(src, i, delta, n).unwrap_or((0, Axes::ZERO));
    let (l1, g1) = shared_g(src, i + 1, delta, n).unwrap_or((0, Axes::ZERO));
    blend.shared = l0 | (l1 << 4);
    let (kin_i, kin_next) = (src.kin(i), src.kin(i + 1));
    with_limits(blend, &g0, &g1, &kin_i, &kin_next, limits, n)
}
