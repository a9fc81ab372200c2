//! Image engraving (`scan image`): an image file's pixels to shades, and shades to rows of
//! merged runs, as plain data — no recipe syntax, no NC text.
//!
//! * **Decoding** goes through the `image` crate (PNG and JPEG only). The header is read first
//!   and an image of more than [`MAX_IMAGE_PIXELS`] pixels is refused before anything is
//!   decoded, so a small file that claims a huge canvas (a decompression bomb) costs nothing;
//!   the decoder also runs under an allocation limit. Transparent pixels are composited over
//!   white (paper: nothing to engrave).
//! * **Tone.** A pixel's darkness is `1 − luma/255` (`invert`: `luma/255`), raised to `gamma`
//!   (above 1 lightens the mid-tones, below 1 darkens them). The result is a **shade** 0..=255,
//!   0 meaning the beam stays dark there. Grayscale rounds the tone to a shade; threshold lights
//!   a pixel at full shade when its tone reaches the threshold; dithering spreads each pixel's
//!   quantisation error to neighbours not yet visited by an error-diffusion kernel
//!   (Floyd–Steinberg, Jarvis–Judice–Ninke, Stucki, Atkinson) or compares the tone with an 8 × 8
//!   Bayer matrix (ordered), so the density of lit pixels over an area follows its tone.
//! * **Runs.** Along an image row, neighbouring pixels of equal shade are one run (one NC block
//!   whatever its length); leading and trailing dark pixels are dropped and a row without a lit
//!   pixel is no row at all.
//! * **Path.** Rows are laid out in a [`Frame`] whose origin is the image's lower-left corner:
//!   pixel column `c` spans `[c·px, (c+1)·px]` along `u`, image row `r` (top first, as stored)
//!   is scanned at `v = (h − 1 − r + ½)·py`, so rows are visited bottom up, each approached in
//!   `+v` like every scan raster (`super::scan_path`'s rules: serpentine or unidirectional,
//!   overscan or the motion layer's lead-ins, passes from A'). Rows run backwards (`−u`) are
//!   shifted by `line_offset` along `+u`, which cancels the lag between the two directions (a
//!   beam that answers late burns a forward row late in `+u` and a backward row late in `−u`:
//!   shifting the backward rows by the measured gap lands both on the same pixels).

use super::{Frame, Order};
use crate::geometry::V2;

/// The most pixels an image may have (a 4096 × 4096 photo): far above what a scan can engrave
/// within the op budget, far below what would exhaust memory while decoding.
pub const MAX_IMAGE_PIXELS: u64 = 4096 * 4096;
/// What the decoder may allocate, bytes (an RGBA16 frame of the largest image allowed).
const MAX_DECODE_BYTES: u64 = MAX_IMAGE_PIXELS * 8;

/// A decoded image: `w × h` luma bytes, top row first, transparency already over white.
#[derive(Debug, Clone, PartialEq)]
pub struct Gray {
    pub w: u32,
    pub h: u32,
    pub luma: Vec<u8>,
}

impl Gray {
    pub fn new(w: u32, h: u32, luma: Vec<u8>) -> Gray {
        assert_eq!(luma.len() as u64, u64::from(w) * u64::from(h));
        Gray { w, h, luma }
    }

    fn at(&self, c: u32, r: u32) -> u8 {
        self.luma[(r as usize) * (self.w as usize) + c as usize]
    }
}

/// Why an image cannot be used.
#[derive(Debug, Clone, PartialEq)]
pub enum ImageError {
    /// Neither PNG nor JPEG (by its first bytes).
    Format,
    /// More than [`MAX_IMAGE_PIXELS`].
    TooLarge { w: u32, h: u32 },
    /// No pixels.
    Empty,
    /// The decoder's own message (truncated data, bad checksum, …).
    Decode(String),
}

impl std::fmt::Display for ImageError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ImageError::Format => write!(f, "not a PNG or JPEG image"),
            ImageError::TooLarge { w, h } => write!(
                f,
                "the image is {w} × {h} pixels, more than the 4096 × 4096 lase engraves"
            ),
            ImageError::Empty => write!(f, "the image has no pixels"),
            ImageError::Decode(m) => write!(f, "the image cannot be decoded: {m}"),
        }
    }
}

/// Decodes a PNG or JPEG file's bytes into luma (see the module header for the limits).
pub fn decode(bytes: &[u8]) -> Result<Gray, ImageError> {
    use image::{ImageFormat, ImageReader, Limits};
    let reader = || -> Result<ImageReader<std::io::Cursor<&[u8]>>, ImageError> {
        let r = ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ImageError::Decode(e.to_string()))?;
        match r.format() {
            Some(ImageFormat::Png | ImageFormat::Jpeg) => Ok(r),
            _ => Err(ImageError::Format),
        }
    };
    // The header alone first: a canvas too large is refused before a pixel is decoded.
    let (w, h) = reader()?
        .into_dimensions()
        .map_err(|e| ImageError::Decode(e.to_string()))?;
    if u64::from(w) * u64::from(h) > MAX_IMAGE_PIXELS {
        return Err(ImageError::TooLarge { w, h });
    }
    if w == 0 || h == 0 {
        return Err(ImageError::Empty);
    }
    let mut r = reader()?;
    let mut limits = Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    limits.max_alloc = Some(MAX_DECODE_BYTES);
    r.limits(limits);
    let img = r.decode().map_err(|e| ImageError::Decode(e.to_string()))?;
    let la = img.to_luma_alpha8();
    let luma = la
        .pixels()
        .map(|p| {
            let [l, a] = p.0;
            // Over white: 255 − (255 − l)·a/255, rounded.
            255 - ((u32::from(255 - l) * u32::from(a) + 127) / 255) as u8
        })
        .collect();
    Ok(Gray::new(la.width(), la.height(), luma))
}

/// An error-diffusion kernel: `(dx, dy, weight)` to the pixels not yet visited.
type Kernel = &'static [(i32, i32, f32)];

/// An error-diffusion or ordered dither.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dither {
    FloydSteinberg,
    Jarvis,
    Stucki,
    Atkinson,
    /// Ordered, against an 8 × 8 Bayer matrix.
    Bayer,
}

impl Dither {
    /// The recipe's word for each (`schema::IMAGE_DITHERS`).
    pub fn from_word(w: &str) -> Option<Dither> {
        Some(match w {
            "floyd" => Dither::FloydSteinberg,
            "jarvis" => Dither::Jarvis,
            "stucki" => Dither::Stucki,
            "atkinson" => Dither::Atkinson,
            "bayer" => Dither::Bayer,
            _ => return None,
        })
    }

    /// Error-diffusion weights `(dx, dy, weight)` and their divisor; `None` for ordered.
    /// Atkinson's six eighths spread only 3/4 of the error on purpose (its crisper look).
    fn kernel(self) -> Option<(Kernel, f32)> {
        const FS: &[(i32, i32, f32)] = &[(1, 0, 7.0), (-1, 1, 3.0), (0, 1, 5.0), (1, 1, 1.0)];
        const JJN: &[(i32, i32, f32)] = &[
            (1, 0, 7.0),
            (2, 0, 5.0),
            (-2, 1, 3.0),
            (-1, 1, 5.0),
            (0, 1, 7.0),
            (1, 1, 5.0),
            (2, 1, 3.0),
            (-2, 2, 1.0),
            (-1, 2, 3.0),
            (0, 2, 5.0),
            (1, 2, 3.0),
            (2, 2, 1.0),
        ];
        const STUCKI: &[(i32, i32, f32)] = &[
            (1, 0, 8.0),
            (2, 0, 4.0),
            (-2, 1, 2.0),
            (-1, 1, 4.0),
            (0, 1, 8.0),
            (1, 1, 4.0),
            (2, 1, 2.0),
            (-2, 2, 1.0),
            (-1, 2, 2.0),
            (0, 2, 4.0),
            (1, 2, 2.0),
            (2, 2, 1.0),
        ];
        const ATKINSON: &[(i32, i32, f32)] = &[
            (1, 0, 1.0),
            (2, 0, 1.0),
            (-1, 1, 1.0),
            (0, 1, 1.0),
            (1, 1, 1.0),
            (0, 2, 1.0),
        ];
        match self {
            Dither::FloydSteinberg => Some((FS, 16.0)),
            Dither::Jarvis => Some((JJN, 48.0)),
            Dither::Stucki => Some((STUCKI, 42.0)),
            Dither::Atkinson => Some((ATKINSON, 8.0)),
            Dither::Bayer => None,
        }
    }
}

/// How tones become shades.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// Shade = tone, rounded to 1/255: power between the minimum and the maximum.
    Grayscale,
    /// Full shade where the tone reaches this fraction (0, 1], dark elsewhere.
    Threshold(f64),
    Dither(Dither),
}

/// The mapping of pixels to shades.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mapping {
    pub mode: Mode,
    /// Exponent of the tone curve (> 0; 1 is linear).
    pub gamma: f64,
    /// Engrave the light pixels instead of the dark ones.
    pub invert: bool,
}

impl Mapping {
    /// A luma byte's tone in [0, 1].
    pub fn tone(&self, luma: u8) -> f64 {
        let l = f64::from(luma) / 255.0;
        let d = if self.invert { l } else { 1.0 - l };
        d.powf(self.gamma)
    }
}

/// The 8 × 8 Bayer index matrix (0..64).
const BAYER8: [[u8; 8]; 8] = [
    [0, 32, 8, 40, 2, 34, 10, 42],
    [48, 16, 56, 24, 50, 18, 58, 26],
    [12, 44, 4, 36, 14, 46, 6, 38],
    [60, 28, 52, 20, 62, 30, 54, 22],
    [3, 35, 11, 43, 1, 33, 9, 41],
    [51, 19, 59, 27, 49, 17, 57, 25],
    [15, 47, 7, 39, 13, 45, 5, 37],
    [63, 31, 55, 23, 61, 29, 53, 21],
];

/// Every pixel's shade (0 = dark, 255 = full), row-major, top row first.
pub fn shades(img: &Gray, m: &Mapping) -> Vec<u8> {
    let (w, h) = (img.w as usize, img.h as usize);
    // Tones once per luma byte: a photo has millions of pixels and 256 values.
    let lut: Vec<f64> = (0..=255u8).map(|l| m.tone(l)).collect();
    match m.mode {
        Mode::Grayscale => img
            .luma
            .iter()
            .map(|&l| (lut[l as usize] * 255.0).round() as u8)
            .collect(),
        Mode::Threshold(t) => img
            .luma
            .iter()
            .map(|&l| {
                let x = lut[l as usize];
                if x > 0.0 && x >= t - 1e-12 { 255 } else { 0 }
            })
            .collect(),
        Mode::Dither(d) => match d.kernel() {
            None => (0..h)
                .flat_map(|r| (0..w).map(move |c| (r, c)))
                .map(|(r, c)| {
                    let x = lut[img.at(c as u32, r as u32) as usize];
                    let limit = (f64::from(BAYER8[r % 8][c % 8]) + 0.5) / 64.0;
                    if x > limit { 255 } else { 0 }
                })
                .collect(),
            Some((kernel, div)) => {
                let mut buf: Vec<f32> = img.luma.iter().map(|&l| lut[l as usize] as f32).collect();
                let mut out = vec![0u8; w * h];
                for r in 0..h {
                    for c in 0..w {
                        let x = buf[r * w + c];
                        let on = x >= 0.5;
                        out[r * w + c] = if on { 255 } else { 0 };
                        let err = x - if on { 1.0 } else { 0.0 };
                        for &(dx, dy, wt) in kernel {
                            let (cc, rr) = (c as i64 + i64::from(dx), r + dy as usize);
                            if cc >= 0 && (cc as usize) < w && rr < h {
                                buf[rr * w + cc as usize] += err * wt / div;
                            }
                        }
                    }
                }
                out
            }
        },
    }
}

/// Neighbouring pixels of one shade along a row: columns `c0..c1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRun {
    pub c0: u32,
    pub c1: u32,
    pub shade: u8,
}

/// The runs of image row `r` (see the module header), in `+u` order.
pub fn row_runs(shades: &[u8], w: u32, r: u32) -> Vec<PixelRun> {
    let row = &shades[(r as usize) * (w as usize)..(r as usize + 1) * (w as usize)];
    let Some(first) = row.iter().position(|&s| s > 0) else {
        return Vec::new();
    };
    let last = row.iter().rposition(|&s| s > 0).expect("a lit pixel") + 1;
    let mut runs: Vec<PixelRun> = Vec::new();
    for (c, &s) in row.iter().enumerate().take(last).skip(first) {
        match runs.last_mut() {
            Some(run) if run.shade == s => run.c1 = c as u32 + 1,
            _ => runs.push(PixelRun {
                c0: c as u32,
                c1: c as u32 + 1,
                shade: s,
            }),
        }
    }
    runs
}

/// Where the image lies and how its rows are visited.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageLayout {
    /// Origin: the image's lower-left corner; `u` along its rows.
    pub frame: Frame,
    /// Pixel size along `u` and `v`, mm.
    pub px: f64,
    pub py: f64,
    pub order: Order,
    pub passes: u32,
    /// As [`super::Family::overscan`] and [`super::Family::lead`].
    pub overscan: Option<f64>,
    pub lead: f64,
    /// Shift of the rows run in `−u`, along `+u`, mm.
    pub line_offset: f64,
}

/// One step of an image scan, part coordinates.
#[derive(Debug, Clone, PartialEq)]
pub enum ImageStep {
    /// Positioning with the beam off.
    Travel(V2),
    /// A move at the scan speed with the beam off (overscan).
    Idle(V2),
    /// A move at the scan speed across a row's runs to `to`, each run at its shade (0: a dark
    /// gap inside the row, which stays in the lit section so the row runs through at speed):
    /// `v` and `shift` place the row in the frame, `runs` are `(end column, shade)` in scan
    /// order (one op for the whole row: `crate::program::PixelRow`).
    Row {
        to: V2,
        v: f64,
        shift: f64,
        runs: Vec<(u32, u8)>,
    },
}

/// The rows of an image: `(v, runs)` bottom up, empty rows left out.
pub fn image_rows(shades: &[u8], w: u32, h: u32, py: f64) -> Vec<(f64, Vec<PixelRun>)> {
    (0..h)
        .rev()
        .filter_map(|r| {
            let runs = row_runs(shades, w, r);
            let v = (f64::from(h - 1 - r) + 0.5) * py;
            (!runs.is_empty()).then_some((v, runs))
        })
        .collect()
}

/// The steps of the scan (see the module header).
pub fn image_path(rows: &[(f64, Vec<PixelRun>)], lay: &ImageLayout) -> Vec<ImageStep> {
    let f = &lay.frame;
    let o = lay.overscan.unwrap_or(0.0);
    let mut out = Vec::new();
    for _ in 0..lay.passes {
        for (k, (y, runs)) in rows.iter().enumerate() {
            let backward = lay.order == Order::Serpentine && k % 2 == 1;
            let (d, shift) = if backward {
                (-1.0, lay.line_offset)
            } else {
                (1.0, 0.0)
            };
            let x = |c: u32| f64::from(c) * lay.px + shift;
            let (first, last) = if backward {
                (x(runs[runs.len() - 1].c1), x(runs[0].c0))
            } else {
                (x(runs[0].c0), x(runs[runs.len() - 1].c1))
            };
            let approach = first - d * lay.overscan.unwrap_or(lay.lead);
            let enter = if lay.overscan.is_none() {
                first
            } else {
                approach
            };
            if k == 0 {
                out.push(ImageStep::Travel(f.to_part(approach, y - lay.py)));
            }
            out.push(ImageStep::Travel(f.to_part(enter, *y)));
            if o > 0.0 {
                out.push(ImageStep::Idle(f.to_part(first, *y)));
            }
            let burn = |run: &PixelRun| (if backward { run.c0 } else { run.c1 }, run.shade);
            out.push(ImageStep::Row {
                to: f.to_part(last, *y),
                v: *y,
                shift,
                runs: if backward {
                    runs.iter().rev().map(burn).collect()
                } else {
                    runs.iter().map(burn).collect()
                },
            });
            if o > 0.0 {
                out.push(ImageStep::Idle(f.to_part(last + d * o, *y)));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> Gray {
        // Left to right from white to black, every row alike.
        let luma = (0..h)
            .flat_map(|_| (0..w).map(move |c| 255 - (c * 255 / (w - 1)) as u8))
            .collect();
        Gray::new(w, h, luma)
    }

    fn map(mode: Mode) -> Mapping {
        Mapping {
            mode,
            gamma: 1.0,
            invert: false,
        }
    }

    #[test]
    fn grayscale_shades_are_the_darkness_and_invert_flips_them() {
        let img = Gray::new(3, 1, vec![255, 128, 0]);
        assert_eq!(shades(&img, &map(Mode::Grayscale)), [0, 127, 255]);
        let inv = Mapping {
            invert: true,
            ..map(Mode::Grayscale)
        };
        assert_eq!(shades(&img, &inv), [255, 128, 0]);
        let g2 = Mapping {
            gamma: 2.0,
            ..map(Mode::Grayscale)
        };
        // (127/255)² · 255 = 63.25
        assert_eq!(shades(&img, &g2), [0, 63, 255]);
    }

    /// Encodes `img` with the `image` crate's own encoders (PNG or JPEG).
    fn encode(img: image::DynamicImage, fmt: image::ImageFormat) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, fmt).unwrap();
        out.into_inner()
    }

    #[test]
    fn jpeg_and_png_decode_to_luma_with_transparency_over_white() {
        // JPEG: a flat gray and a ramp come back within the codec's loss.
        let gray = image::GrayImage::from_fn(32, 16, |c, _| image::Luma([(c * 8) as u8]));
        let jpg = encode(gray.clone().into(), image::ImageFormat::Jpeg);
        let g = decode(&jpg).unwrap();
        assert_eq!((g.w, g.h), (32, 16));
        for (a, b) in g.luma.iter().zip(gray.as_raw()) {
            assert!((i32::from(*a) - i32::from(*b)).abs() <= 6, "{a} vs {b}");
        }
        // PNG with alpha: black at alpha 0 is white, at 255 black, at 128 mid-gray.
        let rgba = image::RgbaImage::from_fn(3, 1, |c, _| {
            image::Rgba([0, 0, 0, [0, 255, 128][c as usize]])
        });
        let png = encode(rgba.into(), image::ImageFormat::Png);
        assert_eq!(decode(&png).unwrap().luma, [255, 0, 127]);
        assert_eq!(decode(b"GIF89a...."), Err(ImageError::Format));
    }

    #[test]
    fn equal_pixels_merge_and_dark_ends_are_dropped() {
        let s = [0, 0, 5, 5, 5, 0, 9, 0];
        assert_eq!(
            row_runs(&s, 8, 0),
            [
                PixelRun {
                    c0: 2,
                    c1: 5,
                    shade: 5
                },
                PixelRun {
                    c0: 5,
                    c1: 6,
                    shade: 0
                },
                PixelRun {
                    c0: 6,
                    c1: 7,
                    shade: 9
                },
            ]
        );
        assert!(row_runs(&[0, 0], 2, 0).is_empty());
    }

    /// Lit density over 16 × 16 patches of a ramp follows the patch's mean tone, for every
    /// dither, within 0.02 (Atkinson: 0.08, in the mid-tones).
    #[test]
    fn dithered_density_follows_the_tone() {
        let img = ramp(256, 64);
        for d in [
            Dither::FloydSteinberg,
            Dither::Jarvis,
            Dither::Stucki,
            Dither::Atkinson,
            Dither::Bayer,
        ] {
            let m = map(Mode::Dither(d));
            let s = shades(&img, &m);
            let mut worst: f64 = 0.0;
            for pc in 0..16u32 {
                let (mut lit, mut tone) = (0.0, 0.0);
                for r in 16..32u32 {
                    for c in pc * 16..pc * 16 + 16 {
                        lit += f64::from(s[(r * 256 + c) as usize] / 255);
                        tone += m.tone(img.at(c, r));
                    }
                }
                let (lit, tone) = (lit / 256.0, tone / 256.0);
                // Atkinson spreads only 3/4 of the error: by design it loses the lightest and
                // darkest tones, so it is held to the mid-tones.
                if d == Dither::Atkinson && !(0.2..=0.8).contains(&tone) {
                    continue;
                }
                let tol = if d == Dither::Atkinson { 0.08 } else { 0.02 };
                worst = worst.max((lit - tone).abs());
                assert!(
                    (lit - tone).abs() <= tol,
                    "{d:?} patch {pc}: density {lit:.3}, tone {tone:.3}"
                );
            }
            eprintln!("{d:?}: worst density error {worst:.3}");
        }
    }

    #[test]
    fn backward_rows_are_shifted_by_the_line_offset() {
        let rows = vec![
            (
                0.05,
                vec![PixelRun {
                    c0: 1,
                    c1: 3,
                    shade: 9,
                }],
            ),
            (
                0.15,
                vec![PixelRun {
                    c0: 1,
                    c1: 3,
                    shade: 9,
                }],
            ),
        ];
        let lay = ImageLayout {
            frame: Frame::new(V2::zeros(), 0.0),
            px: 0.1,
            py: 0.1,
            order: Order::Serpentine,
            passes: 1,
            overscan: Some(1.0),
            lead: 0.0,
            line_offset: 0.02,
        };
        let steps = image_path(&rows, &lay);
        // Each row's first run end.
        let burns: Vec<V2> = steps
            .iter()
            .filter_map(|s| match s {
                ImageStep::Row { v, shift, runs, .. } => {
                    Some(V2::new(f64::from(runs[0].0) * 0.1 + shift, *v))
                }
                _ => None,
            })
            .collect();
        assert!((burns[0] - V2::new(0.3, 0.05)).norm() < 1e-12);
        assert!((burns[1] - V2::new(0.12, 0.15)).norm() < 1e-12);
        // The pass starts one row pitch below the first row's approach.
        assert_eq!(steps[0], ImageStep::Travel(V2::new(-0.9, -0.05)));
    }
}
