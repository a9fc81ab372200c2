//! The plot as a PNG, for machines without an SVG viewer: the SVG rasterized in-process by
//! resvg. Text needs a font, and a plot must not depend on what fonts a machine has: the
//! module embeds DejaVu Sans (Bitstream Vera licence, which allows redistribution with its
//! notice: `DejaVuSans.LICENSE` beside this file) and uses it for every family.

use super::{PlotOptions, plot_svg};
use crate::motion::Job;
use resvg::{tiny_skia, usvg};

/// DejaVu Sans 2.37 (Debian's fonts-dejavu-core).
static FONT: &[u8] = include_bytes!("DejaVuSans.ttf");

/// Pixels per SVG unit in `lase plot -o f.png`: a 1040-unit-wide plot becomes 2080 px, legible
/// on a high-density screen and when zoomed.
pub const PNG_SCALE: f32 = 2.0;

/// The plot of `job` as PNG bytes, [`PNG_SCALE`] pixels per SVG unit.
pub fn plot_png(job: &Job, opts: &PlotOptions) -> Result<Vec<u8>, String> {
    let svg = plot_svg(job, opts).map_err(|e| e.to_string())?;
    svg_to_png(&svg, PNG_SCALE)
}

/// Rasterizes an SVG document at `scale` pixels per unit, on its own white background.
pub fn svg_to_png(svg: &str, scale: f32) -> Result<Vec<u8>, String> {
    let mut opt = usvg::Options {
        font_family: "DejaVu Sans".into(),
        ..usvg::Options::default()
    };
    let db = opt.fontdb_mut();
    db.load_font_data(FONT.to_vec());
    db.set_sans_serif_family("DejaVu Sans");
    db.set_serif_family("DejaVu Sans");
    db.set_monospace_family("DejaVu Sans");
    let tree = usvg::Tree::from_str(svg, &opt).map_err(|e| format!("the plot's SVG: {e}"))?;
    let size = tree
        .size()
        .to_int_size()
        .scale_by(scale)
        .ok_or("the plot is too large to rasterize")?;
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or("the plot is too large to rasterize")?;
    resvg::render(
        &tree,
        tiny_skia::Transform::from_scale(scale, scale),
        &mut pixmap.as_mut(),
    );
    pixmap.encode_png().map_err(|e| e.to_string())
}
