//! Image rows in the toolpath panel: each pixel run of a `scan image` row (a `Line` with a
//! `PixelRow`) as a line whose grey is its power, so the plot shows the picture being
//! engraved — darker where the beam burns harder. The speed colours of the other lit moves
//! say nothing here: a row runs at one speed, only its power changes.
//!
//! Grey is `stroke-opacity` of black, the run's power over the largest row power of the job
//! (the scan's `power`), three decimals; a white run (0 W) is not drawn. Past
//! [`MAX_RUN_LINES`] runs (a photo has a million) each row is one line at its mean power
//! along its length instead, so the SVG stays a few MB: the picture's rows, without their
//! pixels.

use super::Ctx;
use crate::program::{OpKind, PixelRow, dist};
use std::fmt::{self, Write};

/// Most runs drawn one line each.
pub const MAX_RUN_LINES: usize = 100_000;

/// The image rows of the job, with the part point each starts at.
fn rows<'a>(ctx: &Ctx<'a>) -> Vec<([f64; 3], [f64; 3], &'a PixelRow)> {
    let mut pos = ctx.job.program.start;
    let mut out = Vec::new();
    for op in &ctx.job.program.ops {
        if let OpKind::Line {
            to, row: Some(row), ..
        } = &op.kind
        {
            out.push((pos, *to, &**row));
        }
        pos = op.target().unwrap_or(pos);
    }
    out
}

/// Whether the job has image rows (the legend names them).
pub fn any(ctx: &Ctx) -> bool {
    ctx.job
        .program
        .ops
        .iter()
        .any(|o| matches!(o.kind, OpKind::Line { row: Some(_), .. }))
}

/// Draws the rows' runs; `at` maps a part point to the page, `width` is a pixel's size on the
/// page per mm of pixel.
pub fn draw(
    s: &mut String,
    ctx: &Ctx,
    at: &dyn Fn([f64; 3]) -> (f64, f64),
    scale: f64,
) -> fmt::Result {
    let rows = rows(ctx);
    if rows.is_empty() {
        return Ok(());
    }
    let top = rows.iter().map(|r| r.2.max_w).fold(0.0, f64::max);
    if top <= 0.0 {
        return Ok(());
    }
    let runs: usize = rows.iter().map(|r| r.2.runs.len()).sum();
    let per_run = runs <= MAX_RUN_LINES;
    writeln!(
        s,
        r#"<g id="image-rows" stroke="black" stroke-linecap="butt" clip-path="url(#toolpath-clip)" data-per-run="{per_run}">"#
    )?;
    let line = |s: &mut String, a: [f64; 3], b: [f64; 3], w: f64, px: f64| {
        if w <= 0.0 {
            return Ok(());
        }
        let ((x1, y1), (x2, y2)) = (at(a), at(b));
        writeln!(
            s,
            r#"<line class="pixel" x1="{x1:.2}" y1="{y1:.2}" x2="{x2:.2}" y2="{y2:.2}" stroke-width="{:.2}" stroke-opacity="{:.3}" data-power="{w}"/>"#,
            (px * scale).max(0.5),
            (w / top).min(1.0)
        )
    };
    for (from, to, row) in rows {
        let end = |c: u32| {
            let [x, y] = row.end_of(c);
            [x, y, to[2]]
        };
        if per_run {
            let mut a = from;
            for (k, &(c, shade)) in row.runs.iter().enumerate() {
                let b = if k + 1 == row.runs.len() { to } else { end(c) };
                line(s, a, b, row.power_w(shade), row.px)?;
                a = b;
            }
        } else {
            // The row's mean power along its length.
            let (mut a, mut energy) = (from, 0.0);
            for &(c, shade) in &row.runs {
                let b = end(c);
                energy += row.power_w(shade) * dist(a, b);
                a = b;
            }
            let len = dist(from, to);
            line(
                s,
                from,
                to,
                if len > 0.0 { energy / len } else { 0.0 },
                row.px,
            )?;
        }
    }
    writeln!(s, "</g>")
}
