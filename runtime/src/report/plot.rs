//! The job as a picture: the toolpath in the part plane (top) and the path speed over time
//! (bottom), one hand-written SVG. Written by hand rather than through plotters because the
//! workspace's plotters has no font support, and an SVG's `<text>` needs none.
//!
//! The plan is sampled adaptively: every segment boundary, plus interior points shared out by
//! duration, within a budget of [`MAX_POINTS`]; a job with more segments than that is sampled
//! uniformly in time instead.

use super::{dwell_lit, segment_is_rapid, segment_laser};
use crate::motion::Job;
use std::fmt::{self, Write};

/// Budget of sample points for the whole plot.
const MAX_POINTS: usize = 20_000;
/// Most interior points one segment gets (its geometry is a straight line in axis space).
const MAX_PER_SEGMENT: usize = 200;

const WIDTH: f64 = 900.0;
const LEFT: f64 = 72.0;
const PLOT_W: f64 = 690.0;
const TOP: f64 = 34.0;
const SPEED_H: f64 = 200.0;
const GAP: f64 = 70.0;

/// Speed color ramp for lit moves, slow → fast: green, olive, amber, orange, red. Legible on
/// white and distinct from the blue of unlit feeds and the grey of rapids.
const RAMP: [(u8, u8, u8); 5] = [
    (0x2e, 0x7d, 0x32),
    (0x9e, 0x9d, 0x24),
    (0xf9, 0xa8, 0x25),
    (0xef, 0x6c, 0x00),
    (0xc6, 0x28, 0x28),
];
/// Distinct colors of the ramp used for lit polylines.
const BINS: usize = 24;
const FEED_COLOR: &str = "#1f5fbf";
const RAPID_COLOR: &str = "#9a9a9a";

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Rapid,
    Feed,
    Lit,
}

#[derive(Debug, Clone, Copy)]
struct Pt {
    /// Job time.
    t: f64,
    /// Part-plane coordinates (x and y, or x and z).
    h: f64,
    w: f64,
    v: f64,
    kind: Kind,
}

/// The toolpath and the speed profile of `job` as an SVG document.
pub fn plot_svg(job: &Job) -> Result<String, fmt::Error> {
    let machine = &job.program.machine;
    let has_y = machine
        .axes
        .iter()
        .any(|a| a.part_axis.as_deref() == Some("y"))
        || machine.axes.iter().all(|a| a.part_axis.is_none());
    let plane_w = if has_y { 1 } else { 2 };
    let plan = &job.plan;
    let segs = plan.segments();
    let t0 = job.initial_dwell_s;
    let total = job.cycle_time();

    let kind_of = |i: usize| {
        if segment_is_rapid(job, i) {
            Kind::Rapid
        } else if segment_laser(job, i).is_some() {
            Kind::Lit
        } else {
            Kind::Feed
        }
    };
    let point = |i: usize, t_local: f64| {
        let s = plan.sample_segment(i, t_local);
        let spot = job.spot(&s.pos, s.tag);
        Pt {
            t: t0 + s.t,
            h: spot[0],
            w: spot[plane_w],
            v: s.v,
            kind: kind_of(i),
        }
    };

    // Samples: per segment when the budget allows, uniform in time otherwise.
    let mut pts: Vec<Pt> = Vec::new();
    if segs.len() * 2 <= MAX_POINTS {
        let motion_total: f64 = segs.iter().map(|s| s.motion_duration()).sum();
        let spare = (MAX_POINTS - segs.len() * 2) as f64;
        for (i, seg) in segs.iter().enumerate() {
            let motion = seg.motion_duration();
            let share = if motion_total > 0.0 {
                motion / motion_total
            } else {
                0.0
            };
            let n = ((spare * share) as usize).min(MAX_PER_SEGMENT);
            for k in 0..=n + 1 {
                pts.push(point(i, motion * k as f64 / (n + 1) as f64));
            }
            if seg.dwell > 0.0 {
                pts.push(point(i, seg.duration()));
            }
        }
    } else {
        let duration = plan.duration();
        for k in 0..MAX_POINTS {
            let s = plan.sample(duration * k as f64 / (MAX_POINTS - 1) as f64);
            pts.push(point(s.segment, s.t - segs[s.segment].t_start));
        }
    }

    let lit_v: Vec<f64> = pts
        .iter()
        .filter(|p| p.kind == Kind::Lit)
        .map(|p| p.v)
        .collect();
    let v_lo = lit_v.iter().copied().fold(f64::INFINITY, f64::min);
    let v_hi = lit_v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let v_max = pts.iter().map(|p| p.v).fold(0.0, f64::max);

    // Top panel geometry: equal aspect, the window grown around the path to fit the panel.
    let start = job.spot(&plan.start(), 0);
    let (mut h0, mut h1, mut w0, mut w1) = (start[0], start[0], start[plane_w], start[plane_w]);
    for p in &pts {
        h0 = h0.min(p.h);
        h1 = h1.max(p.h);
        w0 = w0.min(p.w);
        w1 = w1.max(p.w);
    }
    let span = (h1 - h0).max(w1 - w0).max(1e-3);
    let pad = 0.04 * span;
    let (dh, dw) = (h1 - h0 + 2.0 * pad, w1 - w0 + 2.0 * pad);
    let path_h = (PLOT_W * dw / dh).clamp(160.0, 460.0);
    let scale = (PLOT_W / dh).min(path_h / dw);
    let (hc, wc) = (0.5 * (h0 + h1), 0.5 * (w0 + w1));
    let (hmin, hmax) = (hc - 0.5 * PLOT_W / scale, hc + 0.5 * PLOT_W / scale);
    let (wmin, wmax) = (wc - 0.5 * path_h / scale, wc + 0.5 * path_h / scale);
    let px = |h: f64| LEFT + (h - hmin) * scale;
    let py = |w: f64| TOP + path_h - (w - wmin) * scale;

    let speed_top = TOP + path_h + GAP;
    let t_span = total.max(1e-9);
    let v_span = if v_max > 0.0 { v_max * 1.08 } else { 1.0 };
    let sx = |t: f64| LEFT + t / t_span * PLOT_W;
    let sy = |v: f64| speed_top + SPEED_H - v / v_span * SPEED_H;
    let height = speed_top + SPEED_H + 58.0;

    let mut svg = String::with_capacity(64 * pts.len() + 8192);
    let s = &mut svg;
    writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height:.0}" viewBox="0 0 {WIDTH} {height:.0}" font-family="sans-serif" font-size="11">"#
    )?;
    writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#)?;
    writeln!(
        s,
        r#"<text x="{LEFT}" y="20" font-size="13" font-weight="bold">{} on {} — cycle {} s</text>"#,
        xml(&job.program.recipe),
        xml(&machine.name),
        num(total)
    )?;

    // Toolpath frame, grid and ticks.
    let (hn, wn) = ("x", if has_y { "y" } else { "z" });
    frame(s, LEFT, TOP, PLOT_W, path_h)?;
    for v in ticks(hmin, hmax, 8) {
        let x = px(v);
        tick_x(s, x, TOP, path_h, &num(v))?;
    }
    for v in ticks(wmin, wmax, 6) {
        let y = py(v);
        tick_y(s, y, LEFT, PLOT_W, &num(v))?;
    }
    axis_label_x(
        s,
        LEFT + PLOT_W / 2.0,
        TOP + path_h + 32.0,
        &format!("{hn} [mm]"),
    )?;
    axis_label_y(s, LEFT - 48.0, TOP + path_h / 2.0, &format!("{wn} [mm]"))?;

    // Toolpath pieces, merged into polylines of one style.
    writeln!(
        s,
        r#"<g fill="none" stroke-linecap="round" stroke-linejoin="round">"#
    )?;
    let style = |a: &Pt, b: &Pt| match b.kind {
        Kind::Rapid => format!(r#"stroke="{RAPID_COLOR}" stroke-width="1" stroke-dasharray="4 3""#),
        Kind::Feed => format!(r#"stroke="{FEED_COLOR}" stroke-width="1.3""#),
        Kind::Lit => {
            let f = if v_hi > v_lo {
                (0.5 * (a.v + b.v) - v_lo) / (v_hi - v_lo)
            } else {
                1.0
            };
            let bin = (f.clamp(0.0, 1.0) * (BINS - 1) as f64).round() / (BINS - 1) as f64;
            format!(r#"stroke="{}" stroke-width="1.8""#, ramp(bin))
        }
    };
    let mut current: Option<(String, Vec<(f64, f64)>)> = None;
    for pair in pts.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        // Consecutive segments meet at a shared point: a pair without extent draws nothing.
        if (a.h - b.h).abs() + (a.w - b.w).abs() == 0.0 {
            continue;
        }
        let st = style(a, b);
        let (pa, pb) = ((px(a.h), py(a.w)), (px(b.h), py(b.w)));
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
    writeln!(s, "</g>")?;
    // Start marker.
    writeln!(
        s,
        r#"<circle cx="{:.2}" cy="{:.2}" r="3" fill="none" stroke="black"><title>start</title></circle>"#,
        px(start[0]),
        py(start[plane_w])
    )?;

    // Legend and color bar, right of the toolpath.
    let lx = LEFT + PLOT_W + 16.0;
    let mut ly = TOP + 6.0;
    for (label, st) in [
        (
            "rapid",
            format!(r#"stroke="{RAPID_COLOR}" stroke-dasharray="4 3""#),
        ),
        (
            "feed, laser off",
            format!(r#"stroke="{FEED_COLOR}" stroke-width="1.3""#),
        ),
    ] {
        writeln!(
            s,
            r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" {st}/>"#,
            lx + 22.0
        )?;
        writeln!(
            s,
            r#"<text x="{}" y="{}">{label}</text>"#,
            lx + 26.0,
            ly + 4.0
        )?;
        ly += 16.0;
    }
    if !lit_v.is_empty() {
        ly += 8.0;
        writeln!(s, r#"<text x="{lx}" y="{ly}">laser on, speed</text>"#)?;
        writeln!(s, r#"<text x="{lx}" y="{}">[mm/s]</text>"#, ly + 13.0)?;
        let (bar_top, bar_h, bar_w) = (ly + 22.0, 120.0, 14.0);
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
            r##"<rect x="{lx}" y="{bar_top}" width="{bar_w}" height="{bar_h}" fill="none" stroke="#444" stroke-width="0.6"/>"##
        )?;
        writeln!(
            s,
            r#"<text x="{}" y="{}">{}</text>"#,
            lx + bar_w + 4.0,
            bar_top + 4.0,
            num(v_hi)
        )?;
        writeln!(
            s,
            r#"<text x="{}" y="{}">{}</text>"#,
            lx + bar_w + 4.0,
            bar_top + bar_h + 4.0,
            num(v_lo)
        )?;
    }

    // Speed panel: laser-on shading first, then frame, ticks and the speed curve.
    let min_gap = 0.5 * t_span / PLOT_W;
    let mut lit: Vec<(f64, f64)> = Vec::new();
    for (i, seg) in segs.iter().enumerate() {
        if segment_laser(job, i).is_none() {
            continue;
        }
        let a = t0 + seg.t_start;
        let b = a + if dwell_lit(job, i) {
            seg.duration()
        } else {
            seg.motion_duration()
        };
        match lit.last_mut() {
            Some(last) if a - last.1 <= min_gap => last.1 = b,
            _ => lit.push((a, b)),
        }
    }
    for (a, b) in &lit {
        writeln!(
            s,
            r##"<rect x="{:.2}" y="{speed_top}" width="{:.2}" height="{SPEED_H}" fill="#f9a825" fill-opacity="0.22"/>"##,
            sx(*a),
            (sx(*b) - sx(*a)).max(0.5)
        )?;
    }
    frame(s, LEFT, speed_top, PLOT_W, SPEED_H)?;
    for v in ticks(0.0, total, 8) {
        tick_x(s, sx(v), speed_top, SPEED_H, &num(v))?;
    }
    for v in ticks(0.0, v_span, 5) {
        tick_y(s, sy(v), LEFT, PLOT_W, &num(v))?;
    }
    axis_label_x(s, LEFT + PLOT_W / 2.0, speed_top + SPEED_H + 32.0, "t [s]")?;
    axis_label_y(s, LEFT - 48.0, speed_top + SPEED_H / 2.0, "v [mm/s]")?;
    let mut curve: Vec<(f64, f64)> = vec![(sx(0.0), sy(0.0))];
    if t0 > 0.0 {
        curve.push((sx(t0), sy(0.0)));
    }
    curve.extend(pts.iter().map(|p| (sx(p.t), sy(p.v))));
    polyline(
        s,
        r##"fill="none" stroke="#222" stroke-width="1.2""##,
        &curve,
    )?;
    let ly = speed_top + 8.0;
    writeln!(
        s,
        r##"<rect x="{lx}" y="{ly}" width="22" height="10" fill="#f9a825" fill-opacity="0.35"/>"##
    )?;
    writeln!(
        s,
        r#"<text x="{}" y="{}">laser on</text>"#,
        lx + 26.0,
        ly + 9.0
    )?;
    writeln!(
        s,
        r##"<line x1="{lx}" y1="{}" x2="{}" y2="{}" stroke="#222" stroke-width="1.2"/>"##,
        ly + 24.0,
        lx + 22.0,
        ly + 24.0
    )?;
    writeln!(
        s,
        r#"<text x="{}" y="{}">path speed</text>"#,
        lx + 26.0,
        ly + 28.0
    )?;
    if segs.is_empty() {
        writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">no motion</text>"#,
            LEFT + PLOT_W / 2.0,
            TOP + path_h / 2.0
        )?;
    }
    writeln!(s, "</svg>")?;
    Ok(svg)
}

fn frame(s: &mut String, x: f64, y: f64, w: f64, h: f64) -> fmt::Result {
    writeln!(
        s,
        r##"<rect x="{x}" y="{y:.2}" width="{w}" height="{h:.2}" fill="none" stroke="#333" stroke-width="0.8"/>"##
    )
}

fn tick_x(s: &mut String, x: f64, top: f64, h: f64, label: &str) -> fmt::Result {
    let bottom = top + h;
    writeln!(
        s,
        r##"<line x1="{x:.2}" y1="{top:.2}" x2="{x:.2}" y2="{bottom:.2}" stroke="#e4e4e4" stroke-width="0.6"/><line x1="{x:.2}" y1="{bottom:.2}" x2="{x:.2}" y2="{:.2}" stroke="#333" stroke-width="0.8"/><text x="{x:.2}" y="{:.2}" text-anchor="middle">{label}</text>"##,
        bottom + 5.0,
        bottom + 17.0
    )
}

fn tick_y(s: &mut String, y: f64, left: f64, w: f64, label: &str) -> fmt::Result {
    let right = left + w;
    writeln!(
        s,
        r##"<line x1="{left:.2}" y1="{y:.2}" x2="{right:.2}" y2="{y:.2}" stroke="#e4e4e4" stroke-width="0.6"/><line x1="{:.2}" y1="{y:.2}" x2="{left:.2}" y2="{y:.2}" stroke="#333" stroke-width="0.8"/><text x="{:.2}" y="{:.2}" text-anchor="end">{label}</text>"##,
        left - 5.0,
        left - 8.0,
        y + 4.0
    )
}

fn axis_label_x(s: &mut String, x: f64, y: f64, text: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<text x="{x:.2}" y="{y:.2}" text-anchor="middle">{text}</text>"#
    )
}

fn axis_label_y(s: &mut String, x: f64, y: f64, text: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<text x="{x:.2}" y="{y:.2}" text-anchor="middle" transform="rotate(-90 {x:.2} {y:.2})">{text}</text>"#
    )
}

fn polyline(s: &mut String, style: &str, pts: &[(f64, f64)]) -> fmt::Result {
    write!(s, r#"<polyline {style} points=""#)?;
    for (i, (x, y)) in pts.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        write!(s, "{x:.2},{y:.2}")?;
    }
    writeln!(s, r#""/>"#)
}

/// Round tick values covering [lo, hi]: steps of 1, 2 or 5 times a power of ten.
fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(hi > lo) || !lo.is_finite() || !hi.is_finite() {
        return vec![lo];
    }
    let raw = (hi - lo) / target.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * mag)
        .find(|st| *st >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

/// A tick or legend number: up to 4 significant decimals, no `-0`.
fn num(x: f64) -> String {
    let digits = if x.abs() >= 100.0 {
        0
    } else if x.abs() >= 10.0 {
        1
    } else if x.abs() >= 1.0 {
        2
    } else {
        4
    };
    let mut s = format!("{x:.digits$}");
    if s.contains('.') {
        let t = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(t);
    }
    if s == "-0" { "0".into() } else { s }
}

fn ramp(f: f64) -> String {
    let f = f.clamp(0.0, 1.0) * (RAMP.len() - 1) as f64;
    let i = (f.floor() as usize).min(RAMP.len() - 2);
    let u = f - i as f64;
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * u).round() as u8;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    format!(
        "#{:02x}{:02x}{:02x}",
        mix(a.0, b.0),
        mix(a.1, b.1),
        mix(a.2, b.2)
    )
}

fn xml(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
