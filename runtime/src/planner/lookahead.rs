//! Look-ahead: the entry and exit speed of every move, offline or through a bounded window.
//!
//! Method (GRBL `planner_recalculate`, Klipper `lookahead`): a backward pass computes for each
//! move the highest entry speed from which it can still slow to what the following moves
//! allow (ending at rest at every stop and at the end), capped by the junction speed; a forward
//! pass then accelerates as hard as the limits allow without exceeding those caps. Both passes
//! use the exact jerk-aware reachable-speed relations of `profile` (`entry_limit`,
//! `exit_speed`), so an S-curve plan never asks a move for a speed change its jerk limit cannot
//! deliver.
//!
//! Streaming (`lookahead: Some(n)`): a controller that receives moves one by one must commit
//! move k's exit speed while it only knows moves k+1..=k+n, and it must assume the last known
//! move k+n ends at rest (more moves may never come). [`streaming`] reproduces exactly that: the
//! backward pass runs over the window with a stop at its end. Growing the window by one move
//! can only raise entry caps (`entry_limit` is monotone in the exit cap, which is why it is not
//! plain `reach` for S-curves), so a speed committed under a shorter window stays feasible;
//! and once one recomputed cap is unchanged all earlier ones are too,
//! so each window shift re-runs the backward pass only until it stops changing (GRBL's
//! "planned" pointer idea).

use super::profile::{entry_limit, exit_speed};

/// What the passes need to know about one move: 40 bytes, read in order by every pass.
///
/// Stops have no flag: the move after a stop point has `cap = 0`, and a backward pass that
/// hands a move the next one's entry limit as its exit cap hands it 0 there.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Kin {
    /// Path length.
    pub len: f64,
    /// Speed limit of the move (feed, path and axis limits, centripetal cap on curves).
    pub v: f64,
    /// Path acceleration limit.
    pub a: f64,
    /// Path jerk limit (infinite for the trapezoid profile).
    pub j: f64,
    /// Highest entry speed the junction allows (0 at program start and after a stop). The
    /// offline backward pass overwrites it with the highest entry speed that still lets the
    /// rest of the program stop where it must (`entry_max`).
    pub cap: f64,
}

// The tests' tables and `Segment::kin` count on it.
const _: () = assert!(std::mem::size_of::<Kin>() == 40);

/// Where the passes read each move's [`Kin`] and keep its entry cap. The plan's own segments
/// are one (`plan::Segment::kin`: until the look-ahead times a segment, its timing fields hold
/// its `Kin`), so planning needs no scratch table of 40 bytes a move (issue 18); a plain
/// `[Kin]` is another (the tests). A pass never reads a move after committing it.
pub(crate) trait KinTable {
    fn count(&self) -> usize;
    fn kin(&self, i: usize) -> Kin;
    fn set_cap(&mut self, i: usize, cap: f64);
}

impl KinTable for [Kin] {
    #[inline]
    fn count(&self) -> usize {
        self.len()
    }

    #[inline]
    fn kin(&self, i: usize) -> Kin {
        self[i]
    }

    #[inline]
    fn set_cap(&mut self, i: usize, cap: f64) {
        self[i].cap = cap;
    }
}

/// Offline look-ahead over the whole program. `commit(table, k, move, v_in, v_out)` receives
/// each move's entry and exit speed, in order, and may overwrite move k in the table.
pub(crate) fn offline<T: KinTable + ?Sized>(
    kin: &mut T,
    mut commit: impl FnMut(&mut T, usize, &Kin, f64, f64),
) {
    let n = kin.count();
    let mut next_entry = 0.0;
    for i in (0..n).rev() {
        let m = kin.kin(i);
        let cap = m.cap.min(entry_limit(next_entry, m.len, m.a, m.j));
        kin.set_cap(i, cap);
        next_entry = cap;
    }
    // Forward pass: from rest, each move accelerates as far as its length allows, capped by
    // the exit cap the backward pass left (the next move's entry limit, 0 at the end).
    let mut v = 0.0f64;
    for k in 0..n {
        let exit_cap = if k + 1 == n { 0.0 } else { kin.kin(k + 1).cap };
        let m = kin.kin(k);
        let v_in = v.min(m.cap);
        let v_out = exit_speed(v_in, exit_cap.min(m.v), m.len, m.a, m.j);
        commit(kin, k, &m, v_in, v_out);
        v = v_out;
    }
}

/// Streaming look-ahead: move k's exit speed is decided knowing only moves k+1..=k+window,
/// the last of which must be able to stop. `commit` as for [`offline`].
///
/// The entry limits of the moves in the window live in a ring of `window + 1` slots: at move k
/// only k..=k+window are ever read or written.
pub(crate) fn streaming<T: KinTable + ?Sized>(
    kin: &mut T,
    window: usize,
    mut commit: impl FnMut(&mut T, usize, &Kin, f64, f64),
) {
    let n = kin.count();
    if n == 0 {
        return;
    }
    let slots = window.saturating_add(1).min(n);
    let mut entry_max = vec![0.0f64; slots];
    // `end` is the last move the controller has received; entry_max[j] for j in k+1..=end is
    // valid for the window ending at `end`.
    let mut end: Option<usize> = None;
    let mut v = 0.0f64;
    for k in 0..n {
        let want = k.saturating_add(window).min(n - 1);
        while end.is_none_or(|e| e < want) {
            let m = end.map_or(0, |e| e + 1);
            end = Some(m);
            // The new last move must stop at its end; re-run the backward pass from it until a
            // cap no longer changes. Moves before k+1 are committed and need no caps.
            let lowest = (k + 1).min(m);
            let mut i = m;
            let mut exit_cap = 0.0;
            loop {
                let mi = kin.kin(i);
                let new = mi.cap.min(entry_limit(exit_cap, mi.len, mi.a, mi.j));
                let slot = &mut entry_max[i % slots];
                if i < m && new == *slot {
                    break;
                }
                *slot = new;
                if i == lowest || i == 0 {
                    break;
                }
                exit_cap = new;
                i -= 1;
            }
        }
        let end_k = end.unwrap_or(k);
        let exit_cap = if k == end_k {
            0.0
        } else {
            entry_max[(k + 1) % slots]
        };
        let m = kin.kin(k);
        let v_in = v.min(m.cap);
        let v_out = exit_speed(v_in, exit_cap.min(m.v), m.len, m.a, m.j);
        commit(kin, k, &m, v_in, v_out);
        v = v_out;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(n: usize, len: f64) -> Vec<Kin> {
        (0..n)
            .map(|k| Kin {
                len,
                v: 100.0,
                a: 1000.0,
                j: f64::INFINITY,
                cap: if k == 0 { 0.0 } else { 100.0 },
            })
            .collect()
    }

    /// (v_in, v_out) of every move.
    fn speeds(
        kin: &mut [Kin],
        pass: impl FnOnce(&mut [Kin], &mut dyn FnMut(&mut [Kin], usize, &Kin, f64, f64)),
    ) -> Vec<(f64, f64)> {
        let mut out = vec![(f64::NAN, f64::NAN); kin.len()];
        pass(kin, &mut |_, k, _, v_in, v_out| out[k] = (v_in, v_out));
        out
    }

    #[test]
    fn offline_straight_line_accelerates_then_stops() {
        let mut kin = straight(10, 1.0);
        let v = speeds(&mut kin, |k, c| offline(k, c));
        // Trapezoid: v² = 2 a s until the limit, symmetric at the end.
        assert!((v[0].1 - (2.0 * 1000.0 * 1.0f64).sqrt()).abs() < 1e-9);
        assert!((v[4].1 - 100.0).abs() < 1e-9);
        assert!((v[8].1 - (2.0 * 1000.0 * 1.0f64).sqrt()).abs() < 1e-9);
        assert_eq!(v[9].1, 0.0);
        for w in v.windows(2) {
            assert_eq!(w[0].1, w[1].0);
        }
    }

    #[test]
    fn streaming_with_large_window_equals_offline() {
        for j in [f64::INFINITY, 5000.0] {
            let mut a = straight(50, 0.3);
            for (k, m) in a.iter_mut().enumerate() {
                m.j = j;
                m.len = 0.05 + 0.1 * (k % 7) as f64;
            }
            // A stop after move 20: the next move may not be entered at speed.
            a[21].cap = 0.0;
            let mut b = a.clone();
            let off = speeds(&mut a, |k, c| offline(k, c));
            let st = speeds(&mut b, |k, c| streaming(k, 100, c));
            assert_eq!(off, st);
            assert_eq!(off[20].1, 0.0);
        }
    }

    #[test]
    fn streaming_window_of_one_must_stop_after_the_next_move() {
        let mut kin = straight(6, 1.0);
        let v = speeds(&mut kin, |k, c| streaming(k, 1, c));
        // Each exit must allow a stop within the one following move: v² ≤ 2 a L.
        for &(_, v_out) in &v[..5] {
            assert!(v_out <= (2.0 * 1000.0f64).sqrt() + 1e-9);
        }
        let mut zero = straight(4, 1.0);
        let v = speeds(&mut zero, |k, c| streaming(k, 0, c));
        assert!(v.iter().all(|&(_, v_out)| v_out == 0.0));
    }
}
