//! The speed panel: the path speed over time in the recipe's speed unit, the limits it runs
//! under (the programmed feed and the axis limits along each move's direction), the laser
//! power on a second axis, the beam-on intervals shaded, and the events marked: laser on/off
//! edges, M-functions, machine events and dwells.

use super::svg::{
    axis_label_x, axis_label_y, frame, legend_line, num, polyline, tick_right, tick_x, tick_y,
    ticks, xml,
};
use super::{Ctx, LEFT, PLOT_W, SPEED_H};
use crate::program::OpKind;
use crate::report::{dwell_lit, fixed6, segment_is_rapid, segment_laser, standstills};
use std::fmt::{self, Write};

const POWER_COLOR: &str = "#7b1fa2";
const FEED_LIMIT_COLOR: &str = "#1f5fbf";
const AXIS_LIMIT_COLOR: &str = "#d32f2f";
const EVENT_COLOR: &str = "#00695c";
/// Most event and laser on/off markers drawn; past it they would fill the panel, and the
/// shading still shows the beam-on intervals.
const MAX_MARKERS: usize = 400;

pub(super) fn draw(s: &mut String, ctx: &Ctx, top: f64) -> fmt::Result {
    let job = ctx.job;
    let segs = job.plan.segments();
    let t0 = job.initial_dwell_s;
    let total = job.cycle_time();
    let per = ctx.opts.speed_unit.per_mm_s();
    let unit = ctx.opts.speed_unit.label();
    let t_span = total.max(1e-9);

    // The programmed feed and the axis limit along each move, as step lines over its motion.
    let limits = &job.program.limits;
    let axis_limit = |i: usize| {
        let u = job.plan.direction(i);
        let mut lim = job.program.path_limits.v;
        for (k, l) in limits.iter().enumerate() {
            let uk = u[k].abs();
            if uk > 1e-12 {
                lim = lim.min(l.v / uk);
            }
        }
        lim
    };
    let v_max = ctx.pts.iter().map(|p| p.v).fold(0.0, f64::max);
    let feed_max = segs
        .iter()
        .enumerate()
        .filter(|(i, _)| !segment_is_rapid(job, *i))
        .map(|(_, s)| s.feed)
        .filter(|f| f.is_finite())
        .fold(0.0, f64::max);
    let v_top = if v_max.max(feed_max) > 0.0 {
        v_max.max(feed_max) * 1.08 * per
    } else {
        1.0
    };
    let p_max = ctx.pts.iter().map(|p| p.power).fold(0.0, f64::max);
    let fires: Vec<(f64, f64, f64)> = standstills(job)
        .into_iter()
        .filter_map(|st| match &job.program.ops[st.op].kind {
            OpKind::Fire { laser, .. } => Some((st.t, st.t + st.duration, laser.power_w)),
            _ => None,
        })
        .collect();
    let p_max = fires.iter().map(|f| f.2).fold(p_max, f64::max);
    let p_top = if p_max > 0.0 { p_max * 1.08 } else { 1.0 };
    let sx = |t: f64| LEFT + t / t_span * PLOT_W;
    let sy = |v: f64| top + SPEED_H - (v * per / v_top).min(1.2) * SPEED_H;
    // (Values above the scale sit 20 % above the panel, where the clip hides them.)
    let spy = |p: f64| top + SPEED_H - p / p_top * SPEED_H;

    writeln!(
        s,
        r#"<g id="speed-panel" data-unit="{unit}" data-top="{top}" data-height="{SPEED_H}" data-v-top="{v_top}" data-p-top="{p_top}"><clipPath id="speed-clip"><rect x="{LEFT}" y="{top:.2}" width="{PLOT_W}" height="{SPEED_H}"/></clipPath>"#
    )?;
    // Beam-on intervals (lit motion, lit dwells, dot-mode windows), merged below half a pixel.
    let min_gap = 0.5 * t_span / PLOT_W;
    let mut on: Vec<(f64, f64)> = Vec::new();
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
        on.push((a, b));
    }
    on.extend(fires.iter().map(|f| (f.0, f.1)));
    on.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut lit: Vec<(f64, f64)> = Vec::new();
    for (a, b) in on {
        match lit.last_mut() {
            Some(last) if a - last.1 <= min_gap => last.1 = last.1.max(b),
            _ => lit.push((a, b)),
        }
    }
    for (a, b) in &lit {
        writeln!(
            s,
            r##"<rect class="laser-band" x="{:.2}" y="{top:.2}" width="{:.2}" height="{SPEED_H}" fill="#f9a825" fill-opacity="0.22"/>"##,
            sx(*a),
            (sx(*b) - sx(*a)).max(0.5)
        )?;
    }
    frame(s, LEFT, top, PLOT_W, SPEED_H)?;
    for v in ticks(0.0, total, 8) {
        tick_x(s, sx(v), top, SPEED_H, &num(v))?;
    }
    for v in ticks(0.0, v_top, 5) {
        tick_y(
            s,
            top + SPEED_H - v / v_top * SPEED_H,
            LEFT,
            PLOT_W,
            &num(v),
        )?;
    }
    axis_label_x(s, LEFT + PLOT_W / 2.0, top + SPEED_H + 32.0, "t [s]")?;
    axis_label_y(s, LEFT - 52.0, top + SPEED_H / 2.0, &format!("v [{unit}]"))?;

    // Limit step lines, clipped to the panel (an axis limit far above the feeds runs off it).
    let mut feed_line: Vec<(f64, f64)> = Vec::new();
    let mut axis_line: Vec<(f64, f64)> = Vec::new();
    let step = |line: &mut Vec<(f64, f64)>, a: f64, v: f64| {
        let y = sy(v);
        if let Some(&(_, last_y)) = line.last() {
            if (last_y - y).abs() > 1e-6 {
                line.push((sx(a), last_y));
                line.push((sx(a), y));
            }
        } else {
            line.push((sx(a), y));
        }
    };
    for (i, seg) in segs.iter().enumerate() {
        let a = t0 + seg.t_start;
        if seg.feed.is_finite() && !segment_is_rapid(job, i) {
            step(&mut feed_line, a, seg.feed);
        }
        let lim = axis_limit(i);
        if lim.is_finite() {
            step(&mut axis_line, a, lim);
        }
    }
    for line in [&mut feed_line, &mut axis_line] {
        if let Some(&(_, y)) = line.last() {
            line.push((sx(total), y));
        }
    }
    writeln!(s, r#"<g clip-path="url(#speed-clip)" fill="none">"#)?;
    if !axis_line.is_empty() {
        polyline(
            s,
            &format!(
                r#"id="axis-limit" class="limit" stroke="{AXIS_LIMIT_COLOR}" stroke-width="1" stroke-dasharray="6 3""#
            ),
            &axis_line,
        )?;
    }
    if !feed_line.is_empty() {
        polyline(
            s,
            &format!(
                r#"id="feed-limit" class="limit" stroke="{FEED_LIMIT_COLOR}" stroke-width="1" stroke-dasharray="2 2""#
            ),
            &feed_line,
        )?;
    }

    // Power, on its own axis at the right.
    if p_max > 0.0 {
        // Power is piecewise constant unless coupled to speed: a run of equal values is drawn
        // by its two ends, so the trace costs points only where the power changes.
        let mut power: Vec<(f64, f64)> = Vec::new();
        let mut held: Option<(f64, f64)> = None;
        let mut add = |power: &mut Vec<(f64, f64)>, t: f64, w: f64| {
            let pt = (sx(t), spy(w));
            match power.last() {
                Some(last) if (last.1 - pt.1).abs() < 1e-9 => held = Some(pt),
                _ => {
                    if let Some(h) = held.take() {
                        power.push(h);
                    }
                    power.push(pt);
                }
            }
        };
        add(&mut power, 0.0, 0.0);
        let mut windows = fires.iter().peekable();
        for p in &ctx.pts {
            while let Some(f) = windows.next_if(|f| f.0 <= p.t) {
                for (t, w) in [(f.0, 0.0), (f.0, f.2), (f.1, f.2), (f.1, 0.0)] {
                    add(&mut power, t, w);
                }
            }
            add(&mut power, p.t, p.power);
        }
        for f in windows {
            for (t, w) in [(f.0, 0.0), (f.0, f.2), (f.1, f.2), (f.1, 0.0)] {
                add(&mut power, t, w);
            }
        }
        if let Some(h) = held {
            power.push(h);
        }
        polyline(
            s,
            &format!(r#"id="power" stroke="{POWER_COLOR}" stroke-width="1" stroke-opacity="0.85""#),
            &power,
        )?;
    }
    // The speed curve.
    let mut curve: Vec<(f64, f64)> = vec![(sx(0.0), sy(0.0))];
    if t0 > 0.0 {
        curve.push((sx(t0), sy(0.0)));
    }
    curve.extend(ctx.pts.iter().map(|p| (sx(p.t), sy(p.v))));
    polyline(
        s,
        r##"id="speed" stroke="#222" stroke-width="1.2""##,
        &curve,
    )?;
    writeln!(s, "</g>")?;
    if p_max > 0.0 {
        let right = LEFT + PLOT_W;
        for p in ticks(0.0, p_top, 5) {
            tick_right(s, spy(p), right, &num(p), POWER_COLOR)?;
        }
        writeln!(
            s,
            r#"<text x="{:.2}" y="{:.2}" fill="{POWER_COLOR}" text-anchor="middle" transform="rotate(90 {:.2} {:.2})">P [W]</text>"#,
            right + 44.0,
            top + SPEED_H / 2.0,
            right + 44.0,
            top + SPEED_H / 2.0
        )?;
    }

    markers(s, ctx, top, &lit, &sx)?;
    // The axis limit, when every bit of it lies above the scale, is named in the legend.
    let axis_label = if axis_line.is_empty() {
        None
    } else if axis_line.iter().all(|p| p.1 < top) {
        let lowest = (0..segs.len())
            .map(axis_limit)
            .fold(f64::INFINITY, f64::min);
        Some(format!("axis limit ≥ {} (off scale)", num(lowest * per)))
    } else {
        Some("axis limit".to_string())
    };
    legend(s, top, p_max > 0.0, axis_label.as_deref())?;
    writeln!(s, "</g>")
}

/// Laser on/off edges (triangles on the panel's top edge) and standstill events (a vertical
/// line each, labelled while the labels do not collide).
fn markers(
    s: &mut String,
    ctx: &Ctx,
    top: f64,
    lit: &[(f64, f64)],
    sx: &dyn Fn(f64) -> f64,
) -> fmt::Result {
    let job = ctx.job;
    writeln!(s, r#"<g id="events">"#)?;
    if lit.len() * 2 <= MAX_MARKERS {
        for (a, b) in lit {
            let (xa, xb) = (sx(*a), sx(*b));
            writeln!(
                s,
                r##"<path class="laser-on" d="M{:.2},{:.2} l4,-7 l-8,0 z" fill="#e65100"><title>laser on at {} s</title></path>"##,
                xa,
                top,
                fixed6(*a)
            )?;
            writeln!(
                s,
                r##"<path class="laser-off" d="M{:.2},{:.2} l4,-7 l-8,0 z" fill="#616161"><title>laser off at {} s</title></path>"##,
                xb,
                top,
                fixed6(*b)
            )?;
        }
    }
    let events: Vec<(f64, String)> = standstills(job)
        .into_iter()
        .filter_map(|st| {
            let label = match &job.program.ops[st.op].kind {
                OpKind::MCode { code, comment } => match comment {
                    Some(c) => format!("M{code} {c}"),
                    None => format!("M{code}"),
                },
                OpKind::Event { name } => name.clone(),
                OpKind::Dwell { seconds } => format!("dwell {} s", num(*seconds)),
                _ => return None,
            };
            Some((st.t, label))
        })
        .collect();
    let mut last_label = f64::NEG_INFINITY;
    for (t, label) in events.iter().take(MAX_MARKERS) {
        let x = sx(*t);
        writeln!(
            s,
            r#"<line class="event" x1="{x:.2}" y1="{top:.2}" x2="{x:.2}" y2="{:.2}" stroke="{EVENT_COLOR}" stroke-width="0.9" stroke-dasharray="3 2"><title>{} at {} s</title></line>"#,
            top + SPEED_H,
            xml(label),
            fixed6(*t)
        )?;
        if x - last_label >= 13.0 {
            last_label = x;
            let y = top + 10.0;
            writeln!(
                s,
                r#"<text class="event-label" x="{:.2}" y="{y:.2}" fill="{EVENT_COLOR}" font-size="9" transform="rotate(90 {:.2} {y:.2})">{}</text>"#,
                x + 3.0,
                x + 3.0,
                xml(label)
            )?;
        }
    }
    if events.len() > MAX_MARKERS {
        writeln!(
            s,
            r#"<text x="{LEFT}" y="{:.2}" fill="{EVENT_COLOR}">{} events; the first {MAX_MARKERS} are marked</text>"#,
            top - 10.0,
            events.len()
        )?;
    }
    writeln!(s, "</g>")
}

fn legend(s: &mut String, top: f64, power: bool, axis: Option<&str>) -> fmt::Result {
    let lx = LEFT + PLOT_W + 64.0;
    let mut ly = top + 8.0;
    writeln!(s, r#"<g id="speed-legend">"#)?;
    writeln!(
        s,
        r##"<rect x="{lx}" y="{:.2}" width="22" height="10" fill="#f9a825" fill-opacity="0.35"/><text x="{}" y="{:.2}">laser on</text>"##,
        ly - 5.0,
        lx + 26.0,
        ly + 4.0
    )?;
    ly += 16.0;
    legend_line(
        s,
        lx,
        ly,
        r##"stroke="#222" stroke-width="1.2""##,
        "path speed",
    )?;
    ly += 16.0;
    legend_line(
        s,
        lx,
        ly,
        &format!(r#"stroke="{FEED_LIMIT_COLOR}" stroke-dasharray="2 2""#),
        "programmed feed",
    )?;
    ly += 16.0;
    if let Some(label) = axis {
        legend_line(
            s,
            lx,
            ly,
            &format!(r#"stroke="{AXIS_LIMIT_COLOR}" stroke-dasharray="6 3""#),
            label,
        )?;
        ly += 16.0;
    }
    if power {
        legend_line(
            s,
            lx,
            ly,
            &format!(r#"stroke="{POWER_COLOR}""#),
            "power [W]",
        )?;
        ly += 16.0;
    }
    legend_line(
        s,
        lx,
        ly,
        &format!(r#"stroke="{EVENT_COLOR}" stroke-dasharray="3 2""#),
        "event, dwell",
    )?;
    writeln!(s, "</g>")
}
