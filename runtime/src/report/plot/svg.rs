//! SVG writing helpers shared by the plot's panels: frames, ticks, axis labels, polylines,
//! round tick values, number formatting and the speed colour ramp.

use std::fmt::{self, Write};

/// Speed colour ramp for lit moves, slow → fast: green, olive, amber, orange, red. Legible on
/// white and distinct from the blue of unlit feeds and the grey of rapids.
const RAMP: [(u8, u8, u8); 5] = [
    (0x2e, 0x7d, 0x32),
    (0x9e, 0x9d, 0x24),
    (0xf9, 0xa8, 0x25),
    (0xef, 0x6c, 0x00),
    (0xc6, 0x28, 0x28),
];

pub(super) fn frame(s: &mut String, x: f64, y: f64, w: f64, h: f64) -> fmt::Result {
    writeln!(
        s,
        r##"<rect x="{x}" y="{y:.2}" width="{w}" height="{h:.2}" fill="none" stroke="#333" stroke-width="0.8"/>"##
    )
}

pub(super) fn tick_x(s: &mut String, x: f64, top: f64, h: f64, label: &str) -> fmt::Result {
    let bottom = top + h;
    writeln!(
        s,
        r##"<line x1="{x:.2}" y1="{top:.2}" x2="{x:.2}" y2="{bottom:.2}" stroke="#e4e4e4" stroke-width="0.6"/><line x1="{x:.2}" y1="{bottom:.2}" x2="{x:.2}" y2="{:.2}" stroke="#333" stroke-width="0.8"/><text x="{x:.2}" y="{:.2}" text-anchor="middle">{label}</text>"##,
        bottom + 5.0,
        bottom + 17.0
    )
}

pub(super) fn tick_y(s: &mut String, y: f64, left: f64, w: f64, label: &str) -> fmt::Result {
    let right = left + w;
    writeln!(
        s,
        r##"<line x1="{left:.2}" y1="{y:.2}" x2="{right:.2}" y2="{y:.2}" stroke="#e4e4e4" stroke-width="0.6"/><line x1="{:.2}" y1="{y:.2}" x2="{left:.2}" y2="{y:.2}" stroke="#333" stroke-width="0.8"/><text x="{:.2}" y="{:.2}" text-anchor="end">{label}</text>"##,
        left - 5.0,
        left - 8.0,
        y + 4.0
    )
}

/// A tick on the right-hand edge at `x` (the power axis), no grid line.
pub(super) fn tick_right(s: &mut String, y: f64, x: f64, label: &str, color: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<line x1="{x:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}" stroke="{color}" stroke-width="0.8"/><text x="{:.2}" y="{:.2}" fill="{color}">{label}</text>"#,
        x + 5.0,
        x + 8.0,
        y + 4.0
    )
}

pub(super) fn axis_label_x(s: &mut String, x: f64, y: f64, text: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<text x="{x:.2}" y="{y:.2}" text-anchor="middle">{text}</text>"#
    )
}

pub(super) fn axis_label_y(s: &mut String, x: f64, y: f64, text: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<text x="{x:.2}" y="{y:.2}" text-anchor="middle" transform="rotate(-90 {x:.2} {y:.2})">{text}</text>"#
    )
}

/// A polyline; `attrs` carries its style (and id or class).
pub(super) fn polyline(s: &mut String, attrs: &str, pts: &[(f64, f64)]) -> fmt::Result {
    write!(s, r#"<polyline {attrs} points=""#)?;
    for (i, (x, y)) in pts.iter().enumerate() {
        if i > 0 {
            s.push(' ');
        }
        write!(s, "{x:.2},{y:.2}")?;
    }
    writeln!(s, r#""/>"#)
}

/// A legend entry: a short line in style `attrs`, then its label.
pub(super) fn legend_line(s: &mut String, x: f64, y: f64, attrs: &str, label: &str) -> fmt::Result {
    writeln!(
        s,
        r#"<line x1="{x}" y1="{y:.2}" x2="{}" y2="{y:.2}" {attrs}/><text x="{}" y="{:.2}">{label}</text>"#,
        x + 22.0,
        x + 26.0,
        y + 4.0
    )
}

/// Round tick values covering [lo, hi]: steps of 1, 2 or 5 times a power of ten.
pub(super) fn ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
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
pub(super) fn num(x: f64) -> String {
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

pub(super) fn ramp(f: f64) -> String {
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

pub(super) fn xml(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
