//! Planning in windows (issue 18): the same plan as [`plan_along_iter`](super::plan_along_iter),
//! bit for bit, handed on a window of segments at a time, so that a job of millions of moves
//! never holds its whole plan (120 bytes of segment and `8 · n_axes` of point a move).
//!
//! The stages run as the moves come in, each on a small buffer:
//! 1. `Preparer` makes each move's segment skeleton; its last one stays open until the next move
//!    comes (a stop or dwell after it, a chord's curve limits).
//! 2. Under `Corners::Blend`, `Splitter` splits move `i` once the moves its end junction reads
//!    are in: both moves and the start of the one after, and on a run of chords the moves whose
//!    blends share their curvature, up to `blend::READS_AHEAD` past `i + 1` and
//!    `blend::READS_BEHIND` before `i` (`junction_at`); so each corner is judged from the same
//!    neighbours as in the whole plan.
//! 3. The look-ahead commits a prefix of the split segments once it is final. The whole plan's
//!    backward pass sets each entry cap to `min(cap_i, entry_limit(cap_{i+1}))` from a stop at the
//!    program's end. Run over the buffer with a stop at its end instead, it gives each cap a lower
//!    bound (`entry_limit` only grows with the exit cap). Where the bound already reaches
//!    segment `i`'s own junction cap (`entry_limit(…) ≥ cap_i`, with a margin for rounding: the
//!    path from `i` to the buffer's end is longer than the braking distance from `cap_i`), the
//!    true cap is `cap_i` too, whatever follows; caps before `i` follow from it exactly, so the
//!    forward pass can time every segment before `i` as the whole plan does. A stop (`cap_i = 0`)
//!    cuts there always.
//!
//! A pass over the buffer runs when it has doubled since the last one (and holds at least
//! [`MIN_WINDOW`] segments), so the passes cost linear time whatever the buffer's length; the
//! buffer holds the segments within braking distance of its end, and no more than twice that.
//!
//! Unlike the whole plan, windows are handed on as they are made: a move the planner refuses
//! after some windows ends the stream with its error, so a consumer that must not act on a
//! refused program (emit) runs a first pass to the end before it writes anything.
//!
//! A streaming controller's bounded look-ahead (`PlannerConfig::lookahead`) plans whole and hands
//! the plan on as one window.

use super::blend::{self, MoveSource, Splitter};
use super::lookahead::Kin;
use super::profile::{entry_limit, exit_speed};
use super::{
    Along, Axes, AxisLimits, Blends, Move, Plan, PlanError, PlannerConfig, Prepared, Preparer, Raw,
    Segment, Timeline,
    plan::{NO_BLEND, half_ranks, half_start},
};

/// Fewest segments a look-ahead pass runs over (about 600 kB with their points): fewer passes,
/// longer windows.
pub const MIN_WINDOW: usize = 4096;

/// Relative margin on "the cap bound reaches the junction cap": `entry_limit` is monotone in
/// its exit cap, but a jerk-limited one is a chain of roots whose rounding might not be, by a
/// few ulps.
const FINAL_MARGIN: f64 = 1e-9;

/// What the windows of a plan add up to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Planned {
    /// How many segments the windows held.
    pub segments: usize,
    /// Total duration in s, dwells included ([`Plan::duration`] of the whole plan).
    pub duration: f64,
    /// Path length ([`Plan::length`]).
    pub length: f64,
    /// Axis positions at the end.
    pub end: Axes,
}

/// [`plan_along_iter`](super::plan_along_iter) in windows: the plan's segments in order, a
/// window at a time, each a [`Plan`] of its own segments (their times, path distances, move
/// indices and blend numbers those of the whole plan; [`Plan::start`] is where the window starts,
/// [`Plan::duration`] the time its last segment ends, [`Plan::blends`] the blends its segments
/// follow). `each` may drop a window once it has read it.
pub fn plan_along_windows(
    start: impl Into<Axes>,
    moves: impl IntoIterator<Item = (Move, Along)>,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
    each: impl FnMut(Plan),
) -> Result<Planned, PlanError> {
    plan_along_windows_sized(start, moves, limits, cfg, MIN_WINDOW, each)
}

/// [`plan_along_windows`] with look-ahead passes from `min_window` segments on: the tests cut
/// small programs into many windows with it.
#[doc(hidden)]
pub fn plan_along_windows_sized(
    start: impl Into<Axes>,
    moves: impl IntoIterator<Item = (Move, Along)>,
    limits: &AxisLimits,
    cfg: &PlannerConfig,
    min_window: usize,
    mut each: impl FnMut(Plan),
) -> Result<Planned, PlanError> {
    let start = start.into();
    super::validate(start, limits, cfg)?;
    if cfg.lookahead.is_some() {
        let plan = super::plan_along_iter(start, moves, 0, limits, cfg)?;
        let planned = Planned {
            segments: plan.segments.len(),
            duration: plan.duration,
            length: plan.length(),
            end: plan.end,
        };
        if !plan.segments.is_empty() {
            each(plan);
        }
        return Ok(planned);
    }
    let mut s = Stream::new(start, limits, cfg, min_window.max(1));
    for (index, (mv, here)) in moves.into_iter().enumerate() {
        s.prep.push(index, &mv, here, &mut s.raw)?;
        s.advance(false, &mut each);
    }
    s.advance(true, &mut each);
    Ok(Planned {
        segments: s.committed,
        duration: s.timeline.t,
        length: s.timeline.s,
        end: s.prep.q,
    })
}

/// The buffers between the stages.
struct Stream<'a> {
    cfg: &'a PlannerConfig,
    limits: &'a AxisLimits,
    start: Axes,
    prep: Preparer<'a>,
    /// Prepared moves not yet split (or, without blends, not yet handed to the look-ahead).
    raw: Raw,
    /// The index of the move `raw.segments[0]` is.
    raw_first: usize,
    /// The next move to split.
    split_next: usize,
    splitter: Splitter,
    /// Split segments not yet timed (their look-ahead data inside), their points, and the
    /// blends they or the segments handed on last refer to.
    ahead: Prepared,
    /// The number of the blend `ahead.blends[0]` is.
    blends_first: u32,
    /// The backward pass's caps over `ahead`.
    caps: Vec<f64>,
    /// Run the next pass once `ahead` holds this many segments.
    next_pass: usize,
    min_window: usize,
    /// Exit speed of the last segment timed.
    v: f64,
    timeline: Timeline,
    /// Segments handed on.
    committed: usize,
}

/// The prepared moves still in `Stream::raw`, by their index in the program.
struct Buffered<'s> {
    raw: &'s Raw,
    first: usize,
    count: usize,
    start: Axes,
    end: Axes,
    n: usize,
}

impl MoveSource for Buffered<'_> {
    fn count(&self) -> usize {
        self.count
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self.raw.segments[i - self.first].kin()
    }

    #[inline]
    fn point(&self, i: usize) -> Axes {
        if i >= self.count {
            return self.end;
        }
        let k = i - self.first;
        let mut q = self.start;
        q[..self.n].copy_from_slice(&self.raw.points[k * self.n..(k + 1) * self.n]);
        q
    }

    #[inline]
    fn info(&self, i: usize) -> blend::MoveInfo {
        self.raw.info.get(i)
    }
}

impl<'a> Stream<'a> {
    fn new(
        start: Axes,
        limits: &'a AxisLimits,
        cfg: &'a PlannerConfig,
        min_window: usize,
    ) -> Stream<'a> {
        let empty = || Prepared {
            segments: Vec::new(),
            points: Vec::new(),
            end: start,
            blends: Blends::new(cfg.n_axes, start),
        };
        let ahead = empty();
        Stream {
            cfg,
            limits,
            start,
            prep: Preparer::new(start, limits, cfg),
            raw: Raw {
                segments: Vec::new(),
                points: Vec::new(),
                info: blend::MoveInfos::default(),
            },
            raw_first: 0,
            split_next: 0,
            splitter: Splitter::default(),
            ahead,
            blends_first: 0,
            caps: Vec::new(),
            next_pass: min_window,
            min_window,
            v: 0.0,
            timeline: Timeline { t: 0.0, s: 0.0 },
            committed: 0,
        }
    }

    /// Moves what is final from stage to stage; `done`: every move is in.
    fn advance(&mut self, done: bool, each: &mut impl FnMut(Plan)) {
        let n = self.cfg.n_axes;
        let made = self.raw_first + self.raw.segments.len();
        if self.prep.blending {
            // Move i is split once the moves its end junction reads are in (`junction_at`: the
            // shared curvature of a run of chords looks `READS_AHEAD` moves past i + 1, whose
            // start it reads; the last move made is still open).
            let ready = if done {
                made
            } else {
                made.saturating_sub(blend::READS_AHEAD)
            };
            while self.split_next < ready {
                let src = Buffered {
                    raw: &self.raw,
                    first: self.raw_first,
                    count: if done { made } else { usize::MAX },
                    start: self.start,
                    end: self.prep.q,
                    n,
                };
                let i = self.split_next;
                let after =
                    blend::junction_at(&src, i, self.cfg.junction_deviation, self.limits, n);
                let at = src.point(i);
                let seg = self.raw.segments[i - self.raw_first];
                self.splitter
                    .split_move(seg, &at, after, &mut self.ahead, n);
                self.split_next += 1;
            }
            // The junction after `split_next` reads it, the moves after it and `READS_BEHIND`
            // before it.
            let keep = self.split_next.saturating_sub(blend::READS_BEHIND);
            self.forget_raw(keep.max(self.raw_first), done);
        } else {
            // Without blends a segment is final once the next move is in.
            let ready = if done { made } else { made.saturating_sub(1) };
            let k = ready - self.raw_first;
            if done || k >= 256 {
                self.ahead
                    .segments
                    .extend_from_slice(&self.raw.segments[..k]);
                self.ahead
                    .points
                    .extend_from_slice(&self.raw.points[..k * n]);
                self.forget_raw(ready, true);
            }
        }
        if done || self.ahead.segments.len() >= self.next_pass {
            self.commit(done, each);
        }
    }

    /// Drops the prepared moves before `i` (in batches unless `now`).
    fn forget_raw(&mut self, i: usize, now: bool) {
        let k = i - self.raw_first;
        if k == 0 || !(now || k >= 256) {
            return;
        }
        let n = self.cfg.n_axes;
        self.raw.segments.drain(..k);
        self.raw.points.drain(..k * n);
        self.raw.info.forget_before(i);
        self.raw_first = i;
    }

    /// Times the final prefix of `ahead` (all of it when `done`) and hands it on.
    fn commit(&mut self, done: bool, each: &mut impl FnMut(Plan)) {
        let count = self.ahead.segments.len();
        if count == 0 {
            return;
        }
        // Backward pass from a stop at the buffer's end (the program's end when `done`).
        self.caps.clear();
        self.caps.resize(count, 0.0);
        let mut cut = if done { count } else { 0 };
        let mut next = 0.0;
        for i in (0..count).rev() {
            let m = self.ahead.segments[i].kin();
            let limit = entry_limit(next, m.len, m.a, m.j);
            let cap = m.cap.min(limit);
            self.caps[i] = cap;
            next = cap;
            if cut == 0 && i > 0 && limit >= m.cap * (1.0 + FINAL_MARGIN) {
                cut = i;
            }
        }
        // Forward pass over the final prefix, as `lookahead::offline`'s.
        for k in 0..cut {
            let exit_cap = if k + 1 == count {
                0.0
            } else {
                self.caps[k + 1]
            };
            let m = Kin {
                cap: self.caps[k],
                ..self.ahead.segments[k].kin()
            };
            let v_in = self.v.min(m.cap);
            let v_out = exit_speed(v_in, exit_cap.min(m.v), m.len, m.a, m.j);
            self.timeline
                .commit(&mut self.ahead.segments[k], &m, v_in, v_out);
            self.v = v_out;
        }
        self.next_pass = self.min_window.max(2 * (count - cut));
        if cut > 0 {
            let window = self.take(cut);
            self.committed += cut;
            each(window);
        }
    }

    /// The first `cut` segments of `ahead`, timed, as a window.
    fn take(&mut self, cut: usize) -> Plan {
        let n = self.cfg.n_axes;
        let segments: Vec<Segment> = self.ahead.segments.drain(..cut).collect();
        // The halves of blends keep no point (`Plan::segment_start`).
        let with_points = segments.iter().filter(|s| s.blend == NO_BLEND).count();
        let points: Vec<f64> = self.ahead.points.drain(..with_points * n).collect();
        // The blends this window's segments follow; the last of them stays for the next
        // window too, whose first segment may be its half after the corner.
        let refs = |s: &[Segment]| {
            s.iter()
                .filter(|s| s.blend != NO_BLEND)
                .map(|s| s.blend / 2)
                .fold(None, |r: Option<(u32, u32)>, b| {
                    Some(r.map_or((b, b), |(lo, hi)| (lo.min(b), hi.max(b))))
                })
        };
        let (base, blends) = match refs(&segments) {
            Some((lo, hi)) => {
                // The blend before the first, where still held: its curvature may be shared
                // with the first's (`Plan::blend_curvatures`).
                let lo = lo.saturating_sub(1).max(self.blends_first);
                let from = (lo - self.blends_first) as usize;
                let to = (hi - self.blends_first) as usize;
                (lo, self.ahead.blends.slice(from, to))
            }
            None => (self.blends_first, Blends::new(n, self.start)),
        };
        let keep = match (refs(&segments), refs(&self.ahead.segments)) {
            (Some((_, hi)), Some((lo, _))) => Some(hi.min(lo)),
            (Some((_, hi)), None) => Some(hi),
            (None, Some((lo, _))) => Some(lo),
            (None, None) => None,
        };
        if let Some(keep) = keep {
            // One blend more, for the curvature the next window's first may share with it.
            let keep = keep.saturating_sub(1).max(self.blends_first);
            let drop = (keep - self.blends_first) as usize;
            self.ahead.blends.drain_front(drop);
            self.blends_first = keep;
        }
        // Where the window starts and ends: where its first segment and the next one start
        // (`Plan::segment_start`).
        let halves = half_ranks(&segments);
        let mut window = Plan {
            segments,
            points,
            start: self.start,
            end: self.prep.q,
            duration: self.timeline.t,
            n_axes: n,
            blends,
            blend_base: base,
            halves,
        };
        window.start = window.segment_start(0);
        if let Some(next) = self.ahead.segments.first() {
            window.end = if next.blend == NO_BLEND {
                let mut q = self.start;
                q[..n].copy_from_slice(&self.ahead.points[..n]);
                q
            } else {
                // Held: the window's blends were kept from the first `ahead` refers to on.
                let k = (next.blend / 2 - self.blends_first) as usize;
                let b = self.ahead.blends.get(k).expect("the blend ahead is held");
                half_start(&b, next.blend % 2 == 1, &self.start, n)
            };
        }
        window
    }
}
