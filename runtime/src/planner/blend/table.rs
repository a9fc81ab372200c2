//! The blends of a plan, stored compactly (issue 13 item 3 with issue 18's memory per move): a
//! [`Blend`] is 160 bytes (three six-axis vectors), and a lit zigzag blends every corner.
//!
//! What a blend holds that the table need not: the axes a plan does not use (`u`, `w` are zero
//! there and the corner keeps the plan's start, `judge`'s points), and its `w`, which is the
//! `u` of the next blend wherever both round the two ends of one move (`w` and the next `u`
//! are that move's `Δq / length`, computed alike: the same bits). So a blend keeps its corner,
//! its `u` and its reach, `2·n + 1` numbers, and a byte: its shared levels and whether its `w`
//! is its own (kept in a side table, for the last blend and wherever the next blend does not
//! continue it). Two axes: 41 bytes a blend, not 160. Every blend read back is the one pushed,
//! bit for bit.

use super::{Blend, LEVELS};
use crate::axes::Axes;

/// The flag of a blend whose `w` is in the side table (the shared levels use two bits of each
/// half of the byte, `LEVELS` ≤ 3).
const OWN_W: u8 = 0x08;
const _: () = assert!(LEVELS < 4);

/// Corner blends in order (`Plan::blends`), numbered from 0.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Blends {
    /// Axes in use.
    n: usize,
    /// The corners' values on the axes not in use.
    rest: Axes,
    /// Per blend: its corner and `u` on the axes in use, and its reach.
    vals: Vec<f64>,
    /// Per blend: `Blend::shared`, and [`OWN_W`].
    flags: Vec<u8>,
    /// The blends whose `w` is their own, in order, and those `w`s (`n` values each).
    own_at: Vec<u32>,
    own_w: Vec<f64>,
}

impl Blends {
    /// No blends yet, of a plan of `n` axes starting at `start`.
    pub(crate) fn new(n: usize, start: Axes) -> Blends {
        Blends {
            n,
            rest: start,
            ..Blends::default()
        }
    }

    /// [`Blends::new`] with room for `count` blends.
    pub(crate) fn with_capacity(n: usize, start: Axes, count: usize) -> Blends {
        Blends {
            vals: Vec::with_capacity(count * (2 * n + 1)),
            flags: Vec::with_capacity(count),
            ..Blends::new(n, start)
        }
    }

    /// How many blends.
    pub fn len(&self) -> usize {
        self.flags.len()
    }

    pub fn is_empty(&self) -> bool {
        self.flags.is_empty()
    }

    fn stride(&self) -> usize {
        2 * self.n + 1
    }

    /// Appends `b`.
    pub(crate) fn push(&mut self, b: Blend) {
        let n = self.n;
        if let Some(last) = self.flags.last_mut() {
            // The previous blend's `w` is the last own one: dropped where `b` continues it.
            let w = &self.own_w[self.own_w.len() - n..];
            if w.iter()
                .zip(&b.u[..n])
                .all(|(a, b)| a.to_bits() == b.to_bits())
            {
                *last &= !OWN_W;
                self.own_at.pop();
                self.own_w.truncate(self.own_w.len() - n);
            }
        }
        self.own_at.push(self.flags.len() as u32);
        self.own_w.extend_from_slice(&b.w[..n]);
        self.flags.push(b.shared | OWN_W);
        self.vals.extend_from_slice(&b.corner[..n]);
        self.vals.extend_from_slice(&b.u[..n]);
        self.vals.push(b.reach);
    }

    /// Blend `k`, as pushed.
    pub fn get(&self, k: usize) -> Option<Blend> {
        let (n, stride) = (self.n, self.stride());
        let flags = *self.flags.get(k)?;
        let v = &self.vals[k * stride..(k + 1) * stride];
        let mut b = Blend {
            corner: self.rest,
            reach: v[2 * n],
            u: Axes::ZERO,
            w: Axes::ZERO,
            shared: flags & !OWN_W,
        };
        b.corner[..n].copy_from_slice(&v[..n]);
        b.u[..n].copy_from_slice(&v[n..2 * n]);
        let w = if flags & OWN_W != 0 {
            let j = self.own_at.binary_search(&(k as u32)).ok()?;
            &self.own_w[j * n..(j + 1) * n]
        } else {
            // The next blend's `u`.
            &self.vals[(k + 1) * stride + n..(k + 1) * stride + 2 * n]
        };
        b.w[..n].copy_from_slice(w);
        Some(b)
    }

    /// Every blend, in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = Blend> + '_ {
        (0..self.len()).map(|k| self.get(k).expect("a blend of the table"))
    }

    /// Blends `from..=to`, numbered from 0.
    pub(crate) fn slice(&self, from: usize, to: usize) -> Blends {
        let mut out = Blends::with_capacity(self.n, self.rest, to + 1 - from);
        for k in from..=to {
            out.push(self.get(k).expect("a blend of the table"));
        }
        out
    }

    /// Drops the first `count` blends (the next one becomes number 0).
    pub(crate) fn drain_front(&mut self, count: usize) {
        let count = count.min(self.len());
        self.vals.drain(..count * self.stride());
        self.flags.drain(..count);
        let own = self.own_at.partition_point(|&k| (k as usize) < count);
        self.own_at.drain(..own);
        self.own_w.drain(..own * self.n);
        for k in &mut self.own_at {
            *k -= count as u32;
        }
    }

    /// Gives back what was reserved beyond the blends pushed.
    pub(crate) fn shrink_to_fit(&mut self) {
        self.vals.shrink_to_fit();
        self.flags.shrink_to_fit();
        self.own_at.shrink_to_fit();
        self.own_w.shrink_to_fit();
    }

    /// Bytes the table holds on the heap.
    pub fn heap_bytes(&self) -> usize {
        8 * (self.vals.capacity() + self.own_w.capacity())
            + self.flags.capacity()
            + 4 * self.own_at.capacity()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blend(corner: [f64; 2], u: [f64; 2], w: [f64; 2], shared: u8) -> Blend {
        let ax = |v: [f64; 2]| Axes::from([v[0], v[1], 0.0, 0.0, 0.0, 0.0]);
        let mut corner = ax(corner);
        corner[4] = 7.5;
        Blend {
            corner,
            reach: 0.025 + corner[0] * 1e-3,
            u: ax(u),
            w: ax(w),
            shared,
        }
    }

    /// Each blend reads back bit for bit, whether its `w` continues into the next blend's `u`
    /// (kept once) or not (a side table), in the whole table, a slice of it and what is left
    /// once its front is dropped; a continued `w` costs nothing.
    #[test]
    fn every_blend_reads_back_as_pushed() {
        let d = [0.1f64.sqrt(), -0.3];
        let all = [
            blend([1.0, 0.0], [1.0, 0.0], d, 0x30),
            blend([2.0, 0.5], d, [0.0, 1.0], 0x13),
            // Not continued: its `u` is not the `w` before it.
            blend([3.0, 1.0], [0.0, -1.0], [-0.0, 1.0], 0x02),
            blend([3.0, 2.0], [-0.0, 1.0], [0.6, 0.8], 0),
            blend([4.0, 2.0], [0.6, 0.8], [1.0, 0.0], 0x33),
        ];
        let mut t = Blends::new(2, Axes::from([0.0, 0.0, 0.0, 0.0, 7.5, 0.0]));
        for b in all {
            t.push(b);
        }
        let bits = |b: &Blend| {
            let v: Vec<u64> = [b.corner, b.u, b.w]
                .iter()
                .flat_map(|a| a.iter().map(|x| x.to_bits()))
                .chain([b.reach.to_bits(), u64::from(b.shared)])
                .collect();
            v
        };
        let got: Vec<Blend> = t.iter().collect();
        assert_eq!(got.len(), all.len());
        for (g, w) in got.iter().zip(&all) {
            assert_eq!(bits(g), bits(w));
        }
        // The own `w`s: the one before the break and the last.
        assert_eq!(t.own_at, [1, 4]);
        t.shrink_to_fit();
        assert_eq!(t.heap_bytes(), 8 * (5 * 5 + 2 * 2) + 5 + 4 * 2);
        let s = t.slice(1, 3);
        for k in 0..3 {
            assert_eq!(bits(&s.get(k).unwrap()), bits(&all[k + 1]));
        }
        assert!(s.get(3).is_none());
        t.drain_front(2);
        assert_eq!(t.len(), 3);
        for k in 0..3 {
            assert_eq!(bits(&t.get(k).unwrap()), bits(&all[k + 2]));
        }
    }
}
