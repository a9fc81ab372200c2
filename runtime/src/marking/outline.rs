//! Outline fonts (TrueType and OpenType, through `ttf-parser`): each glyph's contours as
//! closed polylines, quadratic and cubic curves flattened within a tolerance, scaled so that a
//! capital letter is 1 high. Contours keep the font's own nesting (a letter's counter is a
//! contour inside its outline), which is how `scan raster` fills them: even-odd.

use super::Glyph;
use crate::geometry::V2;
use ttf_parser::OutlineBuilder;

/// A parsed font face and the factor from its units to cap heights.
#[derive(Debug)]
pub struct Font<'a> {
    face: ttf_parser::Face<'a>,
    scale: f64,
}

impl<'a> Font<'a> {
    /// The font in `data` (the first face of a collection), or why it cannot be read.
    pub fn parse(data: &'a [u8]) -> Result<Font<'a>, String> {
        let face = ttf_parser::Face::parse(data, 0).map_err(|e| format!("{e}"))?;
        // The font's own cap height (OS/2) when it states one; else the height of 'H'.
        let cap = face
            .capital_height()
            .filter(|h| *h > 0)
            .map(f64::from)
            .or_else(|| {
                let id = face.glyph_index('H')?;
                face.glyph_bounding_box(id).map(|b| f64::from(b.y_max))
            })
            .filter(|h| *h > 0.0)
            .unwrap_or(0.7 * f64::from(face.units_per_em()));
        Ok(Font {
            face,
            scale: 1.0 / cap,
        })
    }

    /// The glyph of `c` with its curves flattened so that no chord strays more than `tol`
    /// (in cap heights) from the curve, or `None` when the font lacks the character.
    pub fn glyph(&self, c: char, tol: f64) -> Option<Glyph> {
        let id = self.face.glyph_index(c)?;
        let advance = f64::from(self.face.glyph_hor_advance(id).unwrap_or(0)) * self.scale;
        let mut b = Builder {
            scale: self.scale,
            tol: tol.max(1e-6),
            paths: Vec::new(),
            cur: Vec::new(),
        };
        // A glyph without an outline (a space) still advances.
        self.face.outline_glyph(id, &mut b);
        b.close();
        Some(Glyph {
            paths: b.paths,
            advance,
        })
    }
}

struct Builder {
    scale: f64,
    tol: f64,
    paths: Vec<Vec<V2>>,
    cur: Vec<V2>,
}

impl Builder {
    fn pt(&self, x: f32, y: f32) -> V2 {
        V2::new(f64::from(x), f64::from(y)) * self.scale
    }

    fn last(&self) -> V2 {
        *self.cur.last().unwrap_or(&V2::zeros())
    }

    /// Uniform steps along a curve whose second derivative is at most `bend`: the chord error
    /// of a step h is at most bend·h²/8.
    fn steps(&self, bend: f64) -> usize {
        (bend / (8.0 * self.tol)).sqrt().ceil().clamp(1.0, 1000.0) as usize
    }
}

impl ttf_parser::OutlineBuilder for Builder {
    fn move_to(&mut self, x: f32, y: f32) {
        self.close();
        let p = self.pt(x, y);
        self.cur.push(p);
    }

    fn line_to(&mut self, x: f32, y: f32) {
        let p = self.pt(x, y);
        self.cur.push(p);
    }

    fn quad_to(&mut self, x1: f32, y1: f32, x: f32, y: f32) {
        let (p0, p1, p2) = (self.last(), self.pt(x1, y1), self.pt(x, y));
        let n = self.steps(2.0 * (p0 - 2.0 * p1 + p2).norm());
        for i in 1..=n {
            let t = i as f64 / n as f64;
            let u = 1.0 - t;
            self.cur
                .push(p0 * (u * u) + p1 * (2.0 * u * t) + p2 * (t * t));
        }
    }

    fn curve_to(&mut self, x1: f32, y1: f32, x2: f32, y2: f32, x: f32, y: f32) {
        let (p0, p1, p2, p3) = (self.last(), self.pt(x1, y1), self.pt(x2, y2), self.pt(x, y));
        let bend = 6.0 * (p0 - 2.0 * p1 + p2).norm().max((p1 - 2.0 * p2 + p3).norm());
        let n = self.steps(bend);
        for i in 1..=n {
            let t = i as f64 / n as f64;
            let u = 1.0 - t;
            self.cur.push(
                p0 * (u * u * u)
                    + p1 * (3.0 * u * u * t)
                    + p2 * (3.0 * u * t * t)
                    + p3 * (t * t * t),
            );
        }
    }

    fn close(&mut self) {
        let mut c = std::mem::take(&mut self.cur);
        if c.len() > 1 && (c[0] - c[c.len() - 1]).norm() < 1e-12 {
            c.pop();
        }
        if c.len() >= 3 {
            self.paths.push(c);
        }
    }
}
