//! lase's built-in single-stroke font: Hershey Simplex, read from the public-domain glyph data
//! in `hershey_simplex.jhf` (ASCII 32–126, one glyph per line). Single strokes are what a
//! laser engraves as lines: each stroke is followed once, never outlined.

use super::Glyph;
use crate::geometry::V2;
use std::sync::OnceLock;

const DATA: &str = include_str!("hershey_simplex.jhf");
/// Hershey's cap line and baseline (y grows downwards): a capital letter is 21 units high.
const CAP_Y: f64 = -12.0;
const BASE_Y: f64 = 9.0;

/// The first and last character the font holds.
pub const FIRST: char = ' ';
pub const LAST: char = '~';

/// The glyph of a character, scaled so that a capital letter is 1 high, or `None` for a
/// character the font lacks.
pub fn glyph(c: char) -> Option<&'static Glyph> {
    static FONT: OnceLock<Vec<Glyph>> = OnceLock::new();
    let font = FONT.get_or_init(|| {
        DATA.lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .take((LAST as usize) - (FIRST as usize) + 1)
            .map(parse)
            .collect()
    });
    if !(FIRST..=LAST).contains(&c) {
        return None;
    }
    font.get(c as usize - FIRST as usize)
}

/// One line of Hershey data: 5 columns of glyph number, 3 of vertex count, then coordinate
/// pairs as characters offset from 'R'; the first pair is the left and right edge, and " R"
/// lifts the pen.
fn parse(line: &str) -> Glyph {
    let b = line.as_bytes();
    let coord = |c: u8| f64::from(c) - f64::from(b'R');
    let body = &b[8..];
    let (left, right) = (coord(body[0]), coord(body[1]));
    let scale = 1.0 / (BASE_Y - CAP_Y);
    let mut paths = Vec::new();
    let mut cur: Vec<V2> = Vec::new();
    for pair in body[2..].chunks_exact(2) {
        if pair == b" R" {
            paths.push(std::mem::take(&mut cur));
            continue;
        }
        cur.push(V2::new(
            (coord(pair[0]) - left) * scale,
            (BASE_Y - coord(pair[1])) * scale,
        ));
    }
    paths.push(cur);
    paths.retain(|p| !p.is_empty());
    Glyph {
        paths,
        advance: (right - left) * scale,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_holds_every_printable_ascii_character() {
        for c in FIRST..=LAST {
            let g = glyph(c).unwrap_or_else(|| panic!("{c:?}"));
            assert!(g.advance > 0.0, "{c:?}");
            assert_eq!(g.paths.is_empty(), c == ' ', "{c:?}");
        }
        assert!(glyph('é').is_none());
        assert!(glyph('\n').is_none());
    }

    #[test]
    fn capitals_stand_on_the_baseline_and_are_one_high() {
        // 'H' is two uprights from the cap line to the baseline and a bar: Hershey's own data,
        // "H 22: left -11, right 11; (-7,-12)-(-7,9), (7,-12)-(7,9), (-7,-2)-(7,-2)".
        let h = glyph('H').unwrap();
        assert_eq!(h.paths.len(), 3);
        let u = 1.0 / 21.0;
        assert!((h.advance - 22.0 * u).abs() < 1e-12);
        let first = &h.paths[0];
        assert!((first[0] - V2::new(4.0 * u, 1.0)).norm() < 1e-12);
        assert!((first[1] - V2::new(4.0 * u, 0.0)).norm() < 1e-12);
        let bar = &h.paths[2];
        assert!((bar[0].y - 11.0 * u).abs() < 1e-12);
        for c in 'A'..='Z' {
            let g = glyph(c).unwrap();
            let top = g
                .paths
                .iter()
                .flatten()
                .map(|p| p.y)
                .fold(f64::MIN, f64::max);
            let bottom = g
                .paths
                .iter()
                .flatten()
                .map(|p| p.y)
                .fold(f64::MAX, f64::min);
            // Round capitals overshoot the cap line and baseline by a unit at most; Q's tail
            // reaches two units below the baseline.
            let below = if c == 'Q' { 2.0 * u } else { u };
            assert!((top - 1.0).abs() <= u + 1e-12, "{c}: top {top}");
            assert!(bottom.abs() <= below + 1e-12, "{c}: bottom {bottom}");
        }
    }
}
