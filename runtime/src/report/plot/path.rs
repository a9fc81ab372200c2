//! The toolpath panel: the path in the part plane, every pulse as a mark (a ring per pass
//! where passes repeat a spot) or a density view past [`DOT_LIMIT`], the beam direction at
//! lit poses on oriented machines, and the legend.
//!
//! The view fits the lit work (lit moves and pulses) plus a margin, so approach moves, travel
//! and overscan, drawn light, do not shrink the part; `PlotOptions::full_extent` fits all.

use super::svg::{
    axis_label_x, axis_label_y, frame, legend_line, num, polyline, ramp, tick_x, tick_y, ticks,
};
use super::{Ctx, DOT_LIMIT, Kind, LEFT, PLOT_W, Pt, TOP};
use crate::report::{pulse_events, summarize};
use std::collections::HashMap;
use std::fmt::{self, Write};

/// Distinct colors of the speed ramp used for lit polylines.
const BINS: usize = 24;
const FEED_COLOR: &str = "#1f5fbf";
const RAPID_COLOR: &str = "#9a9a9a";
/// Pass colours, cycled: blue, red, green, purple, orange, teal, brown, pink.
const PASS_COLORS: [&str; 8] = [
    "#1565c0", "#c62828", "#2e7d32", "#6a1b9a", "#ef6c00", "#00838f", "#6d4c41", "#ad1457",
];
/// Most beam arrows drawn along the lit work on an oriented machine …
const BEAM_ARROWS: usize = 24;
/// … each at least this far (px) from the others: passes that retrace a path in the drawing
/// plane (the arm's slide steps) would otherwise stack their arrows on one spot.
const BEAM_SPACING: f64 = 40.0;
/// Side of a density cell, px.
const CELL: f64 = 4.0;
/// Pulses on the same spot to this grid (mm) are one spot, when counting passes.
const SPOT_GRID_MM: f64 = 1e-4;

/// One pulse mark: part-plane position and the pass (1 = first visit of its spot).
#[derive(Debug, Clone, Copy)]
struct Dot {
    h: f64,
    w: f64,
    pass: u32,
}

/// The panel's window onto the part plane and its size on the page.
pub(super) struct Panel {
    pub height: f64,
    scale: f64,
    hmin: f64,
    wmin: f64,
    hmax: f64,
    wmax: f64,
    /// Lit extent (h0, w0, h1, w1), when anything is lit.
    lit: Option<[f64; 4]>,
    /// The pulses, when there are at most `DOT_LIMIT`; their count otherwise.
    dots: Vec<Dot>,
    pulses: u64,
    /// Spot diameter, mm, for the size of a pulse mark.
    spot_mm: f64,
}

impl Panel {
    pub fn new(ctx: &Ctx) -> Panel {
        let job = ctx.job;
        let pulses = summarize(job).pulses;
        let dots = if pulses <= DOT_LIMIT {
            dots(ctx)
        } else {
            Vec::new()
        };
        let spot_mm = job
            .program
            .ops
            .iter()
            .filter_map(|o| match &o.kind {
                crate::program::OpKind::Fire { laser, .. } => Some(laser.spot_mm),
                _ => o.laser().map(|l| l.spot_mm),
            })
            .fold(0.0, f64::max);
        let grow = |b: &mut Option<[f64; 4]>, h: f64, w: f64| {
            let e = b.get_or_insert([h, w, h, w]);
            *e = [e[0].min(h), e[1].min(w), e[2].max(h), e[3].max(w)];
        };
        let mut lit = None;
        for p in ctx.pts.iter().filter(|p| p.kind.lit()) {
            grow(&mut lit, p.h, p.w);
        }
        for d in &dots {
            grow(&mut lit, d.h, d.w);
        }
        if pulses > DOT_LIMIT {
            // Pulses past the limit are not stored: the lit moves bound them, and dot-mode
            // windows (which stand still) are stored by the pulse stream anyway.
            for p in crate::report::pulses::fire_events(job) {
                grow(&mut lit, p.pos[0], p.pos[ctx.plane_w]);
            }
        }
        let mut all = None;
        let start = job.spot(&job.plan.start(), 0);
        grow(&mut all, start[0], start[ctx.plane_w]);
        for p in &ctx.pts {
            grow(&mut all, p.h, p.w);
        }
        for d in &dots {
            grow(&mut all, d.h, d.w);
        }
        let [h0, w0, h1, w1] = match (ctx.opts.full_extent, lit) {
            (false, Some(l)) => l,
            _ => all.unwrap_or([0.0; 4]),
        };
        // Margin: 5 % of the larger side, at least 0.1 mm (a single spot has no extent).
        let pad = (0.05 * (h1 - h0).max(w1 - w0)).max(0.1);
        let (dh, dw) = (h1 - h0 + 2.0 * pad, w1 - w0 + 2.0 * pad);
        let height = (PLOT_W * dw / dh).clamp(160.0, 460.0);
        let scale = (PLOT_W / dh).min(height / dw);
        let (hc, wc) = (0.5 * (h0 + h1), 0.5 * (w0 + w1));
        Panel {
            height,
            scale,
            hmin: hc - 0.5 * PLOT_W / scale,
            hmax: hc + 0.5 * PLOT_W / scale,
            wmin: wc - 0.5 * height / scale,
            wmax: wc + 0.5 * height / scale,
            lit,
            dots,
            pulses,
            spot_mm,
        }
    }

    fn px(&self, h: f64) -> f64 {
        LEFT + (h - self.hmin) * self.scale
    }

    fn py(&self, w: f64) -> f64 {
        TOP + self.height - (w - self.wmin) * self.scale
    }

    pub fn draw(&self, s: &mut String, ctx: &Ctx) -> fmt::Result {
        let job = ctx.job;
        let unit = ctx.opts.speed_unit;
        let fitted = !ctx.opts.full_extent && self.lit.is_some();
        let outside = ctx.pts.iter().any(|p| {
            p.h < self.hmin - 1e-9
                || p.h > self.hmax + 1e-9
                || p.w < self.wmin - 1e-9
                || p.w > self.wmax + 1e-9
        });
        if fitted && outside {
            writeln!(
                s,
                r##"<text x="{LEFT}" y="36" fill="#555">view fitted to the lit work; travel outside it is cut off (lase plot --full shows everything)</text>"##
            )?;
        }

        // Frame, grid and ticks.
        let (hn, wn) = ("x", if ctx.has_y { "y" } else { "z" });
        let lit = self.lit.map_or(String::new(), |l| {
            format!(r#" data-lit="{} {} {} {}""#, l[0], l[1], l[2], l[3])
        });
        writeln!(
            s,
            r#"<g id="toolpath" data-view="{} {} {} {}" data-fit="{}"{lit}>"#,
            self.hmin,
            self.wmin,
            self.hmax,
            self.wmax,
            if fitted { "lit" } else { "full" }
        )?;
        writeln!(
            s,
            r#"<clipPath id="toolpath-clip"><rect x="{LEFT}" y="{TOP}" width="{PLOT_W}" height="{:.2}"/></clipPath>"#,
            self.height
        )?;
        frame(s, LEFT, TOP, PLOT_W, self.height)?;
        for v in ticks(self.hmin, self.hmax, 8) {
            tick_x(s, self.px(v), TOP, self.height, &num(v))?;
        }
        for v in ticks(self.wmin, self.wmax, 6) {
            tick_y(s, self.py(v), LEFT, PLOT_W, &num(v))?;
        }
        axis_label_x(
            s,
            LEFT + PLOT_W / 2.0,
            TOP + self.height + 32.0,
            &format!("{hn} [mm]"),
        )?;
        axis_label_y(
            s,
            LEFT - 48.0,
            TOP + self.height / 2.0,
            &format!("{wn} [mm]"),
        )?;

        let (v_lo, v_hi) = ctx
            .pts
            .iter()
            .filter(|p| p.kind == Kind::Lit)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.v), hi.max(p.v))
            });
        // A speed range below 0.1 % of the speed is constant speed: one colour, no bar.
        let constant = v_hi - v_lo <= 1e-3 * v_hi.abs();
        self.draw_path(s, ctx, v_lo, v_hi, constant)?;
        let plane_w = ctx.plane_w;
        let at = |p: [f64; 3]| (self.px(p[0]), self.py(p[plane_w]));
        super::shade::draw(s, ctx, &at, self.scale)?;
        self.draw_pulses(s, ctx)?;
        if job.kin.oriented() {
            self.draw_beams(s, ctx)?;
        }
        let start = job.spot(&job.plan.start(), 0);
        writeln!(
            s,
            r#"<rect class="start" x="{:.2}" y="{:.2}" width="6" height="6" fill="none" stroke="black"><title>start</title></rect>"#,
            self.px(start[0]) - 3.0,
            self.py(start[ctx.plane_w]) - 3.0
        )?;
        writeln!(s, "</g>")?;

        // Legend and color bar, right of the toolpath.
        let lx = LEFT + PLOT_W + 16.0;
        let mut ly = TOP + 6.0;
        writeln!(s, r#"<g id="path-legend">"#)?;
        legend_line(
            s,
            lx,
            ly,
            &format!(r#"stroke="{RAPID_COLOR}" stroke-dasharray="4 3""#),
            "rapid",
        )?;
        ly += 16.0;
        legend_line(
            s,
            lx,
            ly,
            &format!(r#"stroke="{FEED_COLOR}" stroke-opacity="0.4" stroke-width="1.3""#),
            "feed, laser off",
        )?;
        ly += 16.0;
        if ctx.pts.iter().any(|p| p.kind == Kind::Pulsed) {
            legend_line(
                s,
                lx,
                ly,
                r##"stroke="#777" stroke-opacity="0.5" stroke-width="0.8""##,
                "travel between pulses",
            )?;
            ly += 16.0;
        }
        if super::shade::any(ctx) {
            legend_line(
                s,
                lx,
                ly,
                r#"stroke="black" stroke-opacity="0.5" stroke-width="4""#,
                "image: grey = power",
            )?;
            ly += 16.0;
        }
        if job.kin.oriented() {
            legend_line(
                s,
                lx,
                ly,
                r##"stroke="#5e35b1" stroke-width="1.2" marker-end="url(#arrow)""##,
                "beam direction",
            )?;
            ly += 16.0;
        }
        ly = self.pulse_legend(s, lx, ly)?;
        if v_hi.is_finite() {
            ly += 8.0;
            let per = unit.per_mm_s();
            writeln!(s, r#"<text x="{lx}" y="{ly}">laser on, speed</text>"#)?;
            writeln!(
                s,
                r#"<text x="{lx}" y="{}">[{}]</text>"#,
                ly + 13.0,
                unit.label()
            )?;
            let (bar_top, bar_w) = (ly + 22.0, 14.0);
            if constant {
                writeln!(
                    s,
                    r#"<rect class="speed-swatch" x="{lx}" y="{bar_top}" width="{bar_w}" height="14" fill="{}"/><text x="{}" y="{}">{} (constant)</text>"#,
                    ramp(1.0),
                    lx + bar_w + 4.0,
                    bar_top + 11.0,
                    num(v_hi * per)
                )?;
            } else {
                let bar_h = 120.0;
                for k in 0..BINS {
                    let f = k as f64 / (BINS - 1) as f64;
                    let y = bar_top + bar_h * (1.0 - (k + 1) as f64 / BINS as f64);
                    writeln!(
                        s,
                        r#"<rect x="{lx}" y="{y:.2}" width="{bar_w}" height="{:.2}" fill="{}"/>"#,
                        bar_h / BINS as f64 + 0.3,
                        ramp(f)
                    )?;
                }
                writeln!(
                    s,
                    r##"<rect class="speed-bar" x="{lx}" y="{bar_top}" width="{bar_w}" height="{bar_h}" fill="none" stroke="#444" stroke-width="0.6"/>"##
                )?;
                for (y, v) in [(bar_top + 4.0, v_hi), (bar_top + bar_h + 4.0, v_lo)] {
                    writeln!(
                        s,
                        r#"<text x="{}" y="{y}">{}</text>"#,
                        lx + bar_w + 4.0,
                        num(v * per)
                    )?;
                }
            }
        }
        writeln!(s, "</g>")
    }

    /// Path pieces, merged into polylines of one style; everything but lit moves light.
    fn draw_path(
        &self,
        s: &mut String,
        ctx: &Ctx,
        v_lo: f64,
        v_hi: f64,
        constant: bool,
    ) -> fmt::Result {
        writeln!(
            s,
            r#"<g fill="none" stroke-linecap="round" stroke-linejoin="round" clip-path="url(#toolpath-clip)">"#
        )?;
        let style = |a: &Pt, b: &Pt| match b.kind {
            // Drawn by `shade`, run by run.
            Kind::Shaded => String::new(),
            Kind::Rapid => format!(
                r#"class="rapid" stroke="{RAPID_COLOR}" stroke-opacity="0.6" stroke-width="1" stroke-dasharray="4 3""#
            ),
            Kind::Feed => format!(
                r#"class="feed" stroke="{FEED_COLOR}" stroke-opacity="0.4" stroke-width="1.3""#
            ),
            Kind::Pulsed => {
                r##"class="pulsed" stroke="#777" stroke-opacity="0.5" stroke-width="0.8""##.into()
            }
            Kind::Lit => {
                let f = if constant {
                    1.0
                } else {
                    (0.5 * (a.v + b.v) - v_lo) / (v_hi - v_lo)
                };
                let bin = (f.clamp(0.0, 1.0) * (BINS - 1) as f64).round() / (BINS - 1) as f64;
                format!(r#"class="lit" stroke="{}" stroke-width="1.8""#, ramp(bin))
            }
        };
        let mut current: Option<(String, Vec<(f64, f64)>)> = None;
        for pair in ctx.pts.windows(2) {
            let (a, b) = (&pair[0], &pair[1]);
            // Consecutive segments meet at a shared point: a pair without extent draws nothing.
            if (a.h - b.h).abs() + (a.w - b.w).abs() == 0.0 {
                continue;
            }
            let st = style(a, b);
            let (pa, pb) = ((self.px(a.h), self.py(a.w)), (self.px(b.h), self.py(b.w)));
            if st.is_empty() {
                if let Some((cs, line)) = current.take() {
                    polyline(s, &cs, &line)?;
                }
                continue;
            }
            match &mut current {
                Some((cs, line)) if *cs == st && line.last() == Some(&pa) => line.push(pb),
                _ => {
                    if let Some((cs, line)) = current.take() {
                        polyline(s, &cs, &line)?;
                    }
                    current = Some((st, vec![pa, pb]));
                }
            }
        }
        if let Some((cs, line)) = current.take() {
            polyline(s, &cs, &line)?;
        }
        writeln!(s, "</g>")
    }

    /// One mark per pulse: a filled dot for a single pass; with several passes a ring per
    /// pass, the later ones smaller, so five visits of one spot show five rings. Past
    /// `DOT_LIMIT` pulses, a density view: pulses per cell, shaded by count.
    fn draw_pulses(&self, s: &mut String, ctx: &Ctx) -> fmt::Result {
        if self.pulses == 0 {
            return Ok(());
        }
        writeln!(
            s,
            r#"<g id="pulses" data-pulses="{}" clip-path="url(#toolpath-clip)">"#,
            self.pulses
        )?;
        if self.pulses > DOT_LIMIT {
            self.draw_density(s, ctx)?;
            return writeln!(s, "</g>");
        }
        let passes = self.passes();
        let r0 = (0.5 * self.spot_mm * self.scale).clamp(1.5, 7.0);
        for d in &self.dots {
            let color = PASS_COLORS[(d.pass as usize - 1) % PASS_COLORS.len()];
            let (x, y) = (self.px(d.h), self.py(d.w));
            if passes == 1 {
                writeln!(
                    s,
                    r#"<circle class="pulse" data-pass="1" cx="{x:.2}" cy="{y:.2}" r="{r0:.2}" fill="{color}" fill-opacity="0.8"/>"#
                )?;
            } else {
                let r = r0 * (1.0 - 0.55 * f64::from(d.pass - 1) / f64::from(passes - 1));
                writeln!(
                    s,
                    r#"<circle class="pulse" data-pass="{}" cx="{x:.2}" cy="{y:.2}" r="{r:.2}" fill="none" stroke="{color}" stroke-width="1"/>"#,
                    d.pass
                )?;
            }
        }
        writeln!(s, "</g>")
    }

    fn draw_density(&self, s: &mut String, ctx: &Ctx) -> fmt::Result {
        // The pulses are streamed again (past the limit they are not stored). A pulse outside
        // the view (`--full` off) counts in the edge cell nearest to it, so the cells add up
        // to every pulse.
        let (cols, rows) = (
            (PLOT_W / CELL).ceil() as i64,
            (self.height / CELL).ceil() as i64,
        );
        let mut cells: HashMap<(i64, i64), u64> = HashMap::new();
        for p in pulse_events(ctx.job) {
            let c = ((self.px(p.pos[0]) - LEFT) / CELL).floor() as i64;
            let r = ((self.py(p.pos[ctx.plane_w]) - TOP) / CELL).floor() as i64;
            *cells
                .entry((c.clamp(0, cols - 1), r.clamp(0, rows - 1)))
                .or_insert(0) += 1;
        }
        let most = cells.values().copied().max().unwrap_or(1).max(1) as f64;
        let mut keys: Vec<_> = cells.keys().copied().collect();
        keys.sort_unstable();
        for (c, r) in keys {
            let n = cells[&(c, r)];
            // Log shading: one pulse in a cell still shows next to thousands in another.
            let f = 0.15 + 0.85 * (1.0 + n as f64).ln() / (1.0 + most).ln();
            writeln!(
                s,
                r##"<rect class="density" data-n="{n}" x="{:.2}" y="{:.2}" width="{CELL}" height="{CELL}" fill="#4a148c" fill-opacity="{f:.3}"/>"##,
                LEFT + c as f64 * CELL,
                TOP + r as f64 * CELL
            )?;
        }
        Ok(())
    }

    /// The most passes any spot gets.
    fn passes(&self) -> u32 {
        self.dots.iter().map(|d| d.pass).max().unwrap_or(0)
    }

    fn pulse_legend(&self, s: &mut String, lx: f64, mut ly: f64) -> Result<f64, fmt::Error> {
        if self.pulses == 0 {
            return Ok(ly);
        }
        if self.pulses > DOT_LIMIT {
            writeln!(
                s,
                r##"<rect x="{lx}" y="{:.2}" width="22" height="10" fill="#4a148c" fill-opacity="0.6"/><text x="{}" y="{:.2}">{} pulses: density</text>"##,
                ly - 5.0,
                lx + 26.0,
                ly + 4.0,
                self.pulses
            )?;
            writeln!(
                s,
                r##"<text x="{lx}" y="{:.2}" fill="#555">(more than {DOT_LIMIT}; darker = more)</text>"##,
                ly + 18.0
            )?;
            return Ok(ly + 32.0);
        }
        let passes = self.passes();
        for pass in 1..=passes {
            let n = self.dots.iter().filter(|d| d.pass == pass).count();
            let color = PASS_COLORS[(pass as usize - 1) % PASS_COLORS.len()];
            let label = if passes == 1 {
                format!("{n} pulses")
            } else {
                format!("pass {pass}: {n} pulses")
            };
            writeln!(
                s,
                r#"<circle cx="{}" cy="{ly:.2}" r="4" fill="{color}"/><text x="{}" y="{:.2}">{label}</text>"#,
                lx + 11.0,
                lx + 26.0,
                ly + 4.0
            )?;
            ly += 16.0;
        }
        Ok(ly)
    }

    /// Arrows along the beam, from the lens side to the spot, at up to `BEAM_ARROWS` lit poses
    /// spread over the lit samples and at least `BEAM_SPACING` apart on the page. A beam square to the drawing plane shows as a ring around the spot.
    fn draw_beams(&self, s: &mut String, ctx: &Ctx) -> fmt::Result {
        let job = ctx.job;
        let lit: Vec<&Pt> = ctx.pts.iter().filter(|p| p.kind.lit()).collect();
        if lit.is_empty() {
            return Ok(());
        }
        writeln!(s, r#"<g id="beams">"#)?;
        // Candidates spread evenly over the lit samples, kept while they stand clear of the
        // arrows already placed.
        let candidates = (BEAM_ARROWS * 8).min(lit.len());
        let mut placed: Vec<(f64, f64)> = Vec::new();
        for k in 0..candidates {
            if placed.len() == BEAM_ARROWS {
                break;
            }
            let p = lit[k * lit.len() / candidates];
            let here = (self.px(p.h), self.py(p.w));
            if placed
                .iter()
                .any(|q| (q.0 - here.0).hypot(q.1 - here.1) < BEAM_SPACING)
            {
                continue;
            }
            placed.push(here);
            let sample = job.plan.sample_segment(p.seg, p.t_local);
            let pose = job.kin.forward_at(&sample.pos, job.standoff_of(sample.tag));
            let (bh, bw) = (pose.beam[0], pose.beam[ctx.plane_w]);
            let len = bh.hypot(bw);
            let (x, y) = (self.px(p.h), self.py(p.w));
            let title = format!(
                "beam ({:.3}, {:.3}, {:.3}) at t = {} s",
                pose.beam[0],
                pose.beam[1],
                pose.beam[2],
                num(p.t)
            );
            if len < 0.15 {
                // Nearly square to the page: the beam seen end-on, a circled cross.
                writeln!(
                    s,
                    r##"<path class="beam-arrow" d="M{:.2},{:.2} m-3.5,0 a3.5,3.5 0 1,0 7,0 a3.5,3.5 0 1,0 -7,0 m1,-2.5 l5,5 m0,-5 l-5,5" fill="white" fill-opacity="0.7" stroke="#5e35b1" stroke-width="1.1"><title>{title}</title></path>"##,
                    x, y
                )?;
            } else {
                // Screen y grows downward: the plane's w runs up.
                let (dx, dy) = (bh / len * 22.0, -bw / len * 22.0);
                writeln!(
                    s,
                    r##"<line class="beam-arrow" x1="{:.2}" y1="{:.2}" x2="{x:.2}" y2="{y:.2}" stroke="#5e35b1" stroke-width="1.2" marker-end="url(#arrow)"><title>{title}</title></line>"##,
                    x - dx,
                    y - dy
                )?;
            }
        }
        writeln!(s, "</g>")
    }
}

/// The job's pulses in the drawing plane, each with its pass: the n-th run of consecutive
/// pulses on one spot is pass n (a dot-mode window's pulses on its spot are one visit).
fn dots(ctx: &Ctx) -> Vec<Dot> {
    let mut visits: HashMap<(i64, i64, i64), u32> = HashMap::new();
    let mut last: Option<(i64, i64, i64)> = None;
    let mut out = Vec::new();
    for p in pulse_events(ctx.job) {
        let key = (
            (p.pos[0] / SPOT_GRID_MM).round() as i64,
            (p.pos[1] / SPOT_GRID_MM).round() as i64,
            (p.pos[2] / SPOT_GRID_MM).round() as i64,
        );
        let n = visits.entry(key).or_insert(0);
        if last != Some(key) {
            *n += 1;
        }
        last = Some(key);
        out.push(Dot {
            h: p.pos[0],
            w: p.pos[ctx.plane_w],
            pass: *n,
        });
    }
    out
}
