//! Marking: text and 2D codes as plain geometry (issue 19). Text becomes profiles — the
//! built-in single-stroke font's open strokes (`hershey`) or an outline font's closed contours
//! (`outline`) — laid out along a line or an arc; QR and Data Matrix symbols become the
//! rectangles of their dark modules or the modules' centres (`codes`). The recipe side is
//! `eval/marking.rs`; what is lit, and how, stays with `follow`, `scan raster` and `scan dots`.
//!
//! Everything here is plain math on plain data: no AST, no IO (a font file arrives as bytes).

pub mod codes;
pub mod hershey;
pub mod outline;

use crate::geometry::{GeomError, Profile, V2};

/// One glyph in font units scaled so that a capital letter is 1 high: polylines (open strokes
/// or closed contours) with the baseline at y = 0 and the pen starting at x = 0, and the
/// advance to the next glyph.
#[derive(Debug, Clone, PartialEq)]
pub struct Glyph {
    pub paths: Vec<Vec<V2>>,
    pub advance: f64,
}

/// Where the anchor sits on the text's baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    Left,
    Center,
    Right,
}

impl Align {
    pub const NAMES: &'static [&'static str] = &["left", "center", "right"];

    pub fn parse(s: &str) -> Option<Align> {
        match s {
            "left" => Some(Align::Left),
            "center" => Some(Align::Center),
            "right" => Some(Align::Right),
            _ => None,
        }
    }
}

/// How a line of glyphs is placed, all in mm and rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    /// Height of a capital letter.
    pub height: f64,
    pub at: V2,
    pub align: Align,
    /// Added between letters, beyond each glyph's own advance.
    pub spacing: f64,
    /// The baseline's direction (on a line) or the anchor's polar angle (on an arc).
    pub angle: f64,
    /// The baseline is an arc of this radius about `at`: positive outside, reading clockwise;
    /// negative inside, reading counter-clockwise.
    pub radius: Option<f64>,
    /// Longest straight piece a path keeps before it is bent onto an arc, mm.
    pub bend_step: f64,
}

/// The text's width along its baseline, mm: the glyphs' advances and the spacing between them.
pub fn width(glyphs: &[Glyph], layout: &Layout) -> f64 {
    let adv: f64 = glyphs.iter().map(|g| g.advance * layout.height).sum();
    adv + layout.spacing * glyphs.len().saturating_sub(1) as f64
}

/// The glyphs placed one after the other and mapped onto the baseline: one profile per path
/// (`closed` for outline contours). Paths that shrink to a point are dropped.
pub fn place(glyphs: &[Glyph], layout: &Layout, closed: bool) -> Result<Vec<Profile>, GeomError> {
    let w = width(glyphs, layout);
    let mut x = match layout.align {
        Align::Left => 0.0,
        Align::Center => -w / 2.0,
        Align::Right => -w,
    };
    let mut out = Vec::new();
    for g in glyphs {
        for path in &g.paths {
            let local: Vec<V2> = path
                .iter()
                .map(|p| V2::new(x + p.x * layout.height, p.y * layout.height))
                .collect();
            let pts = match layout.radius {
                None => {
                    let (s, c) = layout.angle.sin_cos();
                    local
                        .iter()
                        .map(|p| layout.at + V2::new(c * p.x - s * p.y, s * p.x + c * p.y))
                        .collect::<Vec<_>>()
                }
                Some(r) => bend(&local, closed, layout.bend_step)
                    .into_iter()
                    .map(|p| on_arc(p, r, layout))
                    .collect(),
            };
            match Profile::polyline(&pts, closed) {
                Ok(p) => out.push(p),
                // A dot of a stroke font or a sliver of an outline: nothing to trace.
                Err(GeomError::TooFewPoints(_)) => {}
                Err(e) => return Err(e),
            }
        }
        x += g.advance * layout.height + layout.spacing;
    }
    Ok(out)
}

/// A point of the flat layout (u along the baseline, v up) on the arc baseline. Outside
/// (r > 0) the letters read clockwise, their up pointing away from the centre; inside, they
/// read counter-clockwise with up towards the centre. Either way a letter is not mirrored.
fn on_arc(p: V2, r: f64, layout: &Layout) -> V2 {
    let (theta, dist) = if r > 0.0 {
        (layout.angle - p.x / r, r + p.y)
    } else {
        (layout.angle + p.x / -r, -r - p.y)
    };
    layout.at + V2::new(theta.cos(), theta.sin()) * dist
}

/// Splits every piece of a path longer than `step`, so that bending it onto an arc keeps it
/// close to the bent shape.
fn bend(pts: &[V2], closed: bool, step: f64) -> Vec<V2> {
    let mut out = Vec::with_capacity(pts.len());
    let n = pts.len();
    let pieces = if closed { n } else { n.saturating_sub(1) };
    for i in 0..pieces {
        let (a, b) = (pts[i], pts[(i + 1) % n]);
        let k = ((b - a).norm() / step).ceil().clamp(1.0, 10_000.0) as usize;
        for j in 0..k {
            out.push(a + (b - a) * (j as f64 / k as f64));
        }
    }
    if !closed && let Some(last) = pts.last() {
        out.push(*last);
    }
    if n == 1 {
        out.push(pts[0]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bar() -> Glyph {
        Glyph {
            paths: vec![vec![V2::new(0.0, 0.0), V2::new(0.0, 1.0)]],
            advance: 0.5,
        }
    }

    fn layout() -> Layout {
        Layout {
            height: 2.0,
            at: V2::new(10.0, 5.0),
            align: Align::Left,
            spacing: 0.5,
            angle: 0.0,
            radius: None,
            bend_step: 0.1,
        }
    }

    #[test]
    fn glyphs_advance_by_width_and_spacing_and_align_about_the_anchor() {
        let g = [bar(), bar(), bar()];
        let l = layout();
        // Three advances of 0.5 × 2 mm and two gaps of 0.5 mm.
        assert!((width(&g, &l) - 4.0).abs() < 1e-12);
        let p = place(&g, &l, false).unwrap();
        let xs: Vec<f64> = p.iter().map(|p| p.start().x).collect();
        assert_eq!(xs, vec![10.0, 11.5, 13.0]);
        assert!((p[0].end().y - 7.0).abs() < 1e-12);
        let c = place(
            &g,
            &Layout {
                align: Align::Center,
                ..l
            },
            false,
        )
        .unwrap();
        assert!((c[0].start().x - 8.0).abs() < 1e-12);
        let r = place(
            &g,
            &Layout {
                align: Align::Right,
                ..l
            },
            false,
        )
        .unwrap();
        assert!((r[2].start().x - 9.0).abs() < 1e-12);
    }

    #[test]
    fn on_an_arc_letters_stand_upright_outside_and_inside() {
        let l = Layout {
            at: V2::zeros(),
            radius: Some(20.0),
            angle: std::f64::consts::FRAC_PI_2,
            ..layout()
        };
        let p = place(&[bar()], &l, false).unwrap();
        // The bar's foot is on the circle at the top, its head 2 mm further out.
        assert!((p[0].start() - V2::new(0.0, 20.0)).norm() < 1e-9);
        assert!((p[0].end() - V2::new(0.0, 22.0)).norm() < 1e-9);
        let inside = Layout {
            radius: Some(-20.0),
            angle: -std::f64::consts::FRAC_PI_2,
            ..l
        };
        let q = place(&[bar(), bar()], &inside, false).unwrap();
        assert!((q[0].start() - V2::new(0.0, -20.0)).norm() < 1e-9);
        assert!((q[0].end() - V2::new(0.0, -18.0)).norm() < 1e-9);
        // Reading counter-clockwise at the bottom: the second letter is to the right.
        assert!(q[1].start().x > 0.0);
        for s in &q {
            let d = s.start().norm();
            assert!((d - 20.0).abs() < 1e-9, "feet on the circle: {d}");
        }
    }
}
