//! Pieces of a profile by arc length: `segment(p, from, to)` and the lit pieces between tabs
//! (`tabs(p, count | spacing, width)`).
//!
//! A tab is a short gap left uncut so the part stays held in the sheet: the profile minus the
//! gaps is what the beam cuts. Cuts are exact on lines and arcs (an arc piece is the same
//! circle over a shorter sweep); a spline profile is cut on its line/arc rendition, which
//! stays within `SPLINE_RENDER_TOL_MM` of the curve.

use super::{GeomError, Profile, Seg};

/// Below this an arc-length range is empty (mm): a piece shorter than a micrometre's
/// thousandth is no cut.
const EPS_MM: f64 = 1e-9;

/// Where the tabs of a profile go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TabLayout {
    /// This many tabs, evenly spaced.
    Count(usize),
    /// Tabs about this far apart (mm): the count is the length over the spacing, rounded, at
    /// least one; they are then evenly spaced.
    Spacing(f64),
}

/// The part of `seg` between arc lengths `s0 < s1` measured from its start.
fn sub_seg(seg: &Seg, s0: f64, s1: f64) -> Seg {
    match seg {
        Seg::Line { .. } => Seg::Line {
            a: seg.point_at(s0),
            b: seg.point_at(s1),
        },
        Seg::Arc {
            center,
            r,
            a0,
            sweep,
        } => {
            let len = seg.length();
            let (f0, f1) = (s0 / len, s1 / len);
            Seg::Arc {
                center: *center,
                r: *r,
                a0: a0 + sweep * f0,
                sweep: sweep * (f1 - f0),
            }
        }
    }
}

impl Profile {
    /// The open profile along this one from arc length `from` to `to` (mm). On a closed
    /// profile `from > to` runs across the seam (the start), so a piece may straddle it.
    pub fn segment(&self, from: f64, to: f64) -> Result<Profile, GeomError> {
        let total: f64 = self.segs.iter().map(Seg::length).sum();
        let slack = 1e-9 * total.max(1.0);
        let inside = |s: f64| s >= -slack && s <= total + slack;
        if !(inside(from) && inside(to)) {
            return Err(GeomError::Degenerate(format!(
                "the piece {} mm to {} mm is outside the profile, which runs from 0 to {} mm",
                lase_lang::units::format_number(from),
                lase_lang::units::format_number(to),
                lase_lang::units::format_number(total)
            )));
        }
        let (from, to) = (from.clamp(0.0, total), to.clamp(0.0, total));
        if from > to + EPS_MM {
            if !self.closed {
                return Err(GeomError::Degenerate(
                    "on an open profile a piece runs forward: `from` must not be past `to`".into(),
                ));
            }
            // Across the seam: the tail after `from`, then the head up to `to`.
            let mut segs = self.cut(from, total);
            segs.extend(self.cut(0.0, to));
            return piece(segs);
        }
        piece(self.cut(from, to))
    }

    /// The line/arc pieces between arc lengths `from <= to`.
    fn cut(&self, from: f64, to: f64) -> Vec<Seg> {
        let mut out = Vec::new();
        let mut at = 0.0;
        for seg in &self.segs {
            let l = seg.length();
            let (s0, s1) = ((from - at).max(0.0), (to - at).min(l));
            if s1 - s0 > EPS_MM {
                out.push(if s0 <= 0.0 && s1 >= l {
                    seg.clone()
                } else {
                    sub_seg(seg, s0, s1)
                });
            }
            at += l;
        }
        out
    }

    /// The lit pieces of this profile with tabs (uncut gaps of `width` mm, centred on evenly
    /// spaced places): on a closed profile the tabs sit at (k + ½)·L/n, so none falls on the
    /// seam, and piece k runs from tab k to tab k + 1 (the last across the seam); on an open
    /// profile the n tabs sit at k·L/(n + 1) for k = 1…n, leaving both ends cut.
    pub fn tabs(&self, layout: TabLayout, width: f64) -> Result<Vec<Profile>, GeomError> {
        let total: f64 = self.segs.iter().map(Seg::length).sum();
        let n = match layout {
            TabLayout::Count(n) => n,
            TabLayout::Spacing(d) => ((total / d).round() as usize).max(1),
        };
        if n == 0 {
            return Err(GeomError::Degenerate("at least one tab is needed".into()));
        }
        let pitch = if self.closed {
            total / n as f64
        } else {
            total / (n + 1) as f64
        };
        if !(width > 0.0) || width >= pitch - EPS_MM {
            return Err(GeomError::Degenerate(format!(
                "tabs {} mm wide leave nothing to cut between tabs {} mm apart",
                lase_lang::units::format_number(width),
                lase_lang::units::format_number(pitch)
            )));
        }
        let h = width / 2.0;
        if self.closed {
            let centre = |k: usize| (k as f64 + 0.5) * pitch;
            (0..n)
                .map(|k| {
                    let to = if k + 1 == n {
                        centre(0) - h
                    } else {
                        centre(k + 1) - h
                    };
                    self.segment(centre(k) + h, to)
                })
                .collect()
        } else {
            let centre = |k: usize| k as f64 * pitch;
            (0..=n)
                .map(|k| {
                    let from = if k == 0 { 0.0 } else { centre(k) + h };
                    let to = if k == n { total } else { centre(k + 1) - h };
                    self.segment(from, to)
                })
                .collect()
        }
    }
}

fn piece(segs: Vec<Seg>) -> Result<Profile, GeomError> {
    if segs.is_empty() {
        return Err(GeomError::Degenerate(
            "the piece is empty: `from` and `to` are the same place".into(),
        ));
    }
    Ok(Profile::from_segs(segs, false))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::V2;

    fn rect() -> Profile {
        Profile::polyline(
            &[
                V2::new(0.0, 0.0),
                V2::new(40.0, 0.0),
                V2::new(40.0, 20.0),
                V2::new(0.0, 20.0),
            ],
            true,
        )
        .unwrap()
    }

    #[test]
    fn a_segment_is_the_profile_between_two_arc_lengths() {
        let s = rect().segment(30.0, 50.0).unwrap();
        assert!((s.length() - 20.0).abs() < 1e-12);
        assert!((s.start() - V2::new(30.0, 0.0)).norm() < 1e-12);
        assert!((s.end() - V2::new(40.0, 10.0)).norm() < 1e-12);
        // Across the seam of a closed profile.
        let w = rect().segment(115.0, 5.0).unwrap();
        assert!((w.length() - 10.0).abs() < 1e-12);
        assert!((w.start() - V2::new(0.0, 5.0)).norm() < 1e-12);
        assert!((w.end() - V2::new(5.0, 0.0)).norm() < 1e-12);
        assert!(rect().segment(0.0, 121.0).is_err());
    }

    #[test]
    fn an_arc_piece_keeps_its_circle() {
        let c = Profile::circle(V2::new(0.0, 0.0), 10.0, 0.0, true).unwrap();
        let q = c.segment(0.0, 5.0 * std::f64::consts::PI).unwrap();
        assert!((q.end() - V2::new(0.0, 10.0)).norm() < 1e-12);
        assert!((q.length() - 5.0 * std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn tabs_leave_gaps_of_their_width_at_their_places() {
        let pieces = rect().tabs(TabLayout::Count(4), 2.0).unwrap();
        assert_eq!(pieces.len(), 4);
        // Tabs centred at 15, 45, 75, 105 mm along the rectangle.
        let cut: f64 = pieces.iter().map(Profile::length).sum();
        assert!((cut - (120.0 - 4.0 * 2.0)).abs() < 1e-9);
        assert!((pieces[0].start() - V2::new(16.0, 0.0)).norm() < 1e-12);
        assert!((pieces[0].end() - V2::new(40.0, 4.0)).norm() < 1e-12);
        assert!((pieces[3].end() - V2::new(14.0, 0.0)).norm() < 1e-12);
        let by_spacing = rect().tabs(TabLayout::Spacing(50.0), 2.0).unwrap();
        assert_eq!(by_spacing.len(), 2);
        assert!(rect().tabs(TabLayout::Count(4), 30.0).is_err());
        let open = rect().segment(0.0, 40.0).unwrap();
        let p = open.tabs(TabLayout::Count(1), 2.0).unwrap();
        assert_eq!(p.len(), 2);
        assert!((p[0].end() - V2::new(19.0, 0.0)).norm() < 1e-12);
    }
}
