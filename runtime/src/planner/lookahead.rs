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

/// What the passes need to know about one move.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Kin {
    /// Path length.
    pub len: f64,
    /// Speed limit of the move (feed, path and axis limits).
    pub v: f64,
    /// Path acceleration limit.
    pub a: f64,
    /// Path jerk limit (infinite for the trapezoid profile).
    pub j: f64,
    /// Highest entry speed the junction allows (0 at program start and after a stop).
    pub entry_cap: f64,
    /// The exit speed must be 0 (stop point, dwell).
    pub stop: bool,
    /// Backward-pass result: highest entry speed that still lets the rest of the (known)
    /// program stop where it must.
    pub entry_max: f64,
    /// Chosen entry speed.
    pub v_in: f64,
    /// Chosen exit speed.
    pub v_out: f64,
}

/// Offline look-ahead over the whole program.
pub(crate) fn offline(kin: &mut [Kin]) {
    let n = kin.len();
    let mut next_entry = 0.0;
    for k in (0..n).rev() {
        let m = &mut kin[k];
        let exit_cap = if m.stop || k + 1 == n {
            0.0
        } else {
            next_entry
        };
        m.entry_max = m.entry_cap.min(entry_limit(exit_cap, m.len, m.a, m.j));
        next_entry = m.entry_max;
    }
    forward(kin, |kin, k| {
        if kin[k].stop || k + 1 == kin.len() {
            0.0
        } else {
            kin[k + 1].entry_max
        }
    });
}

/// Forward pass: from rest, each move accelerates as far as its length allows, capped by the
/// exit cap the backward pass left.
#[inline]
fn forward(kin: &mut [Kin], exit_cap: impl Fn(&[Kin], usize) -> f64) {
    let mut v = 0.0f64;
    for k in 0..kin.len() {
        let cap = exit_cap(kin, k);
        let m = &mut kin[k];
        let v_in = v.min(m.entry_cap);
        m.v_in = v_in;
        m.v_out = exit_speed(v_in, cap.min(m.v), m.len, m.a, m.j);
        v = m.v_out;
    }
}

/// Streaming look-ahead: move k's exit speed is decided knowing only moves k+1..=k+window,
/// the last of which must be able to stop.
pub(crate) fn streaming(kin: &mut [Kin], window: usize) {
    let n = kin.len();
    if n == 0 {
        return;
    }
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
                let mi = &mut kin[i];
                let new = mi.entry_cap.min(entry_limit(exit_cap, mi.len, mi.a, mi.j));
                if i < m && new == mi.entry_max {
                    break;
                }
                mi.entry_max = new;
                if i == lowest || i == 0 || kin[i - 1].stop {
                    break;
                }
                exit_cap = new;
                i -= 1;
            }
        }
        let end_k = end.unwrap_or(k);
        let cap = if kin[k].stop || k == end_k {
            0.0
        } else {
            kin[k + 1].entry_max
        };
        let m = &mut kin[k];
        let v_in = v.min(m.entry_cap);
        m.v_in = v_in;
        m.v_out = exit_speed(v_in, cap.min(m.v), m.len, m.a, m.j);
        v = m.v_out;
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
                entry_cap: if k == 0 { 0.0 } else { 100.0 },
                ..Kin::default()
            })
            .collect()
    }

    #[test]
    fn offline_straight_line_accelerates_then_stops() {
        let mut kin = straight(10, 1.0);
        offline(&mut kin);
        // Trapezoid: v² = 2 a s until the limit, symmetric at the end.
        assert!((kin[0].v_out - (2.0 * 1000.0 * 1.0f64).sqrt()).abs() < 1e-9);
        assert!((kin[4].v_out - 100.0).abs() < 1e-9);
        assert!((kin[8].v_out - (2.0 * 1000.0 * 1.0f64).sqrt()).abs() < 1e-9);
        assert_eq!(kin[9].v_out, 0.0);
        for w in kin.windows(2) {
            assert_eq!(w[0].v_out, w[1].v_in);
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
            a[20].stop = true;
            let mut b = a.clone();
            offline(&mut a);
            streaming(&mut b, 100);
            for (x, y) in a.iter().zip(&b) {
                assert_eq!((x.v_in, x.v_out), (y.v_in, y.v_out));
            }
        }
    }

    #[test]
    fn streaming_window_of_one_must_stop_after_the_next_move() {
        let mut kin = straight(6, 1.0);
        streaming(&mut kin, 1);
        // Each exit must allow a stop within the one following move: v² ≤ 2 a L.
        for m in &kin[..5] {
            assert!(m.v_out <= (2.0 * 1000.0f64).sqrt() + 1e-9);
        }
        let mut zero = straight(4, 1.0);
        streaming(&mut zero, 0);
        assert!(zero.iter().all(|m| m.v_out == 0.0));
    }
}
