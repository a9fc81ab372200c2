//! `scan image`'s settings (issue 19): a PNG or JPEG file engraved row by row. Its own file
//! because the table is long; it shares `scan`'s common settings.

use super::{L, NUM, PTy, SCAN_COMMON, ScanKind, set};
use crate::units::Dim;

pub const IMAGE_MODES: &[&str] = &["grayscale", "dither", "threshold"];
pub const IMAGE_DITHERS: &[&str] = &["floyd", "jarvis", "stucki", "atkinson", "bayer"];

/// `scan image "file.png" { ... }`: image engraving (`runtime/src/raster/image.rs`).
pub(super) const IMAGE_SCAN: ScanKind = ScanKind {
    name: "image",
    region: "a string: the path of a PNG or JPEG file, relative to the recipe",
    settings: &[
        SCAN_COMMON[0],
        SCAN_COMMON[1],
        SCAN_COMMON[2],
        SCAN_COMMON[3],
        set(
            "overscan",
            L,
            "Extension of every row before its first and after its last lit pixel, so every pixel is passed at the programmed speed. Default: computed from the planner's ramps (the lead-in length for the speed, the axes' limits and the ramp kind).",
        ),
        set(
            "origin",
            PTy::Point,
            "Where the image's lower-left corner goes (default (0, 0)); rows run along `angle`.",
        ),
        SCAN_COMMON[7],
        set(
            "width",
            L,
            "Width of the image on the part; the pixel size is `width` / pixels across. With `height` too, pixels may be non-square.",
        ),
        set(
            "height",
            L,
            "Height of the image on the part (rows are `height` / pixels down apart).",
        ),
        set(
            "dpi",
            NUM,
            "Pixels per inch (25.4 mm / dpi per pixel), when neither `width` nor `height` is given.",
        ),
        set(
            "power",
            PTy::Dim(Dim::POWER),
            "Power of the darkest shade (black pixels; every lit pixel in `dither` and `threshold` modes). Default: the laser's power in force.",
        ),
        set(
            "min_power",
            PTy::Dim(Dim::POWER),
            "Power of the lightest lit shade in `grayscale` mode (default 0 W): shade s of 1..255 burns at min_power + (power − min_power)·s/255; white pixels stay dark.",
        ),
        set(
            "mode",
            PTy::Word(IMAGE_MODES),
            "`grayscale` (default): power per pixel from its shade; `dither`: every pixel full power or dark, their density following the tone (see `dither`); `threshold`: full power where the tone reaches `threshold`.",
        ),
        set(
            "dither",
            PTy::Word(IMAGE_DITHERS),
            "The dither of `mode dither`: error diffusion by `floyd` (Floyd–Steinberg, default), `jarvis` (Jarvis–Judice–Ninke), `stucki` or `atkinson`, or `bayer` (ordered, 8 × 8 matrix).",
        ),
        set(
            "gamma",
            NUM,
            "Tone curve: a pixel's darkness (0 white .. 1 black) is raised to this power before the mode applies (default 1; above 1 lightens mid-tones, below 1 darkens them).",
        ),
        set(
            "threshold",
            NUM,
            "The tone (0..1, after `gamma`) from which `mode threshold` lights a pixel (default 0.5).",
        ),
        set(
            "invert",
            PTy::Flag,
            "Engrave the light pixels instead of the dark ones (a negative).",
        ),
        set(
            "line_offset",
            L,
            "Bidirectional scan-line offset: rows scanned backwards (serpentine order) are shifted this far along +u, to cancel the lag between the two directions (measure the gap between a forward and a backward row and give it here; default 0).",
        ),
    ],
    doc: "Image engraving: a PNG or JPEG file's pixels as a raster, row by row at `speed`, each run of equal pixels one block at its power. White pixels at a row's ends are skipped and white rows are left out; inside a row a white run is a block at 0 W, so the row runs through at speed. Power follows the speed (GRBL/grblHAL `M4` with an `S` word per block; LinuxCNC `M67` per block, synchronized with motion). The image may have at most 4096 × 4096 pixels.",
};
