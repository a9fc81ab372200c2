//! `lase plot`: what the picture contains, read back from the SVG and the PNG — one mark per
//! pulse at the pulse's position with its pass, the view fitted to the lit work, limit lines at
//! the programmed feed, the power trace, events at standstills, beam arrows along the beam, a
//! colour bar that does not degenerate, and a PNG with text and the path in it.

mod common;

use common::{lase, root};
use lase_runtime::compile::{FsFiles, compile};
use lase_runtime::motion::Job;
use lase_runtime::program::OpKind;
use lase_runtime::report::{PlotOptions, SpeedUnit, beam_at, plot_svg, pulse_events, summarize};
use std::path::Path;

// ------------------------------------------------------------------ helpers

fn job_of(path: &Path) -> (String, Job) {
    let (recipe, job) = compile(&mut FsFiles, path.to_str().unwrap()).expect("compiles");
    (recipe.map.text(recipe.main).to_string(), job)
}

fn example(name: &str) -> (String, Job) {
    job_of(&root().join("examples").join(format!("{name}.lase")))
}

/// The plot as `lase plot` draws it (speed unit from the recipe).
fn plot(source: &str, job: &Job, full: bool) -> String {
    let opts = PlotOptions {
        full_extent: full,
        speed_unit: SpeedUnit::of_source(source),
    };
    plot_svg(job, &opts).unwrap()
}

/// The lines of the SVG (one element per line) that contain `pat`.
fn elements<'a>(svg: &'a str, pat: &str) -> Vec<&'a str> {
    svg.lines().filter(|l| l.contains(pat)).collect()
}

fn attr<'a>(el: &'a str, name: &str) -> &'a str {
    let key = format!(" {name}=\"");
    let at = el.find(&key).unwrap_or_else(|| panic!("no {name} in {el}")) + key.len();
    &el[at..at + el[at..].find('"').unwrap()]
}

fn num(el: &str, name: &str) -> f64 {
    attr(el, name).parse().unwrap()
}

fn nums(el: &str, name: &str) -> Vec<f64> {
    attr(el, name)
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect()
}

fn points(el: &str) -> Vec<(f64, f64)> {
    attr(el, "points")
        .split(' ')
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// Maps part-plane coordinates to the page as the toolpath panel does: its view
/// (`data-view`) onto its frame (the clip rectangle).
struct View {
    view: [f64; 4],
    frame: [f64; 4],
}

impl View {
    fn of(svg: &str) -> View {
        let g = elements(svg, r#"<g id="toolpath""#)[0];
        let v = nums(g, "data-view");
        let clip = elements(svg, r#"<clipPath id="toolpath-clip""#)[0];
        View {
            view: [v[0], v[1], v[2], v[3]],
            frame: [
                num(clip, "x"),
                num(clip, "y"),
                num(clip, "width"),
                num(clip, "height"),
            ],
        }
    }

    fn page(&self, h: f64, w: f64) -> (f64, f64) {
        let [h0, w0, h1, w1] = self.view;
        let [x, y, fw, fh] = self.frame;
        (
            x + (h - h0) / (h1 - h0) * fw,
            y + fh - (w - w0) / (w1 - w0) * fh,
        )
    }
}

// ------------------------------------------------------------------ pulses

/// Every pulse is a mark where it fires, in time order, with its pass: `texture_array`'s 72
/// spots five times over, each spot with five rings.
#[test]
fn texture_array_draws_every_pulse_per_pass() {
    let (src, job) = example("texture_array");
    let svg = plot(&src, &job, false);
    let marks = elements(&svg, r#"class="pulse""#);
    let pulses: Vec<_> = pulse_events(&job).collect();
    assert_eq!(marks.len() as u64, summarize(&job).pulses);
    assert_eq!(marks.len(), 360);
    for pass in 1..=5 {
        let n = marks
            .iter()
            .filter(|m| attr(m, "data-pass") == pass.to_string())
            .count();
        assert_eq!(n, 72, "pass {pass}");
    }
    let view = View::of(&svg);
    for (m, p) in marks.iter().zip(&pulses) {
        let (x, y) = view.page(p.pos[0], p.pos[1]);
        assert!(
            (num(m, "cx") - x).abs() <= 0.006 && (num(m, "cy") - y).abs() <= 0.006,
            "{m} vs pulse at {:?}",
            p.pos
        );
    }
    // The rows are travel between pulses, drawn thin and light, not as lit lines.
    assert!(elements(&svg, r#"class="lit""#).is_empty());
    assert!(!elements(&svg, r#"class="pulsed""#).is_empty());
    assert!(svg.contains("pass 5: 72 pulses"));
}

/// `dial_marks`'s dotted arc is dots: 139 pulses, one pass, each a filled mark.
#[test]
fn dial_marks_dotted_arc_is_dots() {
    let (src, job) = example("dial_marks");
    let svg = plot(&src, &job, false);
    let marks = elements(&svg, r#"class="pulse""#);
    assert_eq!(marks.len(), 139);
    assert!(marks.iter().all(|m| attr(m, "data-pass") == "1"));
    // On the dotted arc's radius, 33 mm, as drawn.
    let view = View::of(&svg);
    let (cx, cy) = view.page(0.0, 0.0);
    let (ex, _) = view.page(33.0, 0.0);
    for m in &marks {
        let r = (num(m, "cx") - cx).hypot(num(m, "cy") - cy);
        assert!((r - (ex - cx)).abs() < 0.02, "{m}: r {r} px");
    }
}

/// A dot-mode job (pulses at rest): every pulse is marked, the beam-on band and the power
/// trace show the windows, and `lase plan` says the pulses fire at rest.
#[test]
fn dot_mode_pulses_at_rest_are_marked_and_summarized() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dots.lase");
    std::fs::write(
        &path,
        "machine xy_table\nlaser { power 20 W, spot 40 um }\npulse { rate 5 kHz }\n\
         scan dots (1 mm, 2 mm) { rows 3, cols 4, pitch 0.5 mm, pulses 3, speed 10 mm/s }\n",
    )
    .unwrap();
    let (src, job) = job_of(&path);
    let s = summarize(&job);
    assert_eq!(
        (s.pulses, s.pulses_standstill, s.pulses_moving),
        (36, 36, 0)
    );
    // Twelve windows of 3 pulses at 5 kHz: 0.6 ms each.
    assert!(
        (s.standstill_fire_time_s - 12.0 * 6e-4).abs() < 1e-9,
        "{s:?}"
    );
    let svg = plot(&src, &job, false);
    assert_eq!(elements(&svg, r#"class="pulse""#).len(), 36);
    assert!(elements(&svg, r#"class="laser-band""#).len() >= 12);
    // The power trace reaches the set power (20 W) in the windows.
    let panel = elements(&svg, r#"<g id="speed-panel""#)[0];
    let (top, h, p_top) = (
        num(panel, "data-top"),
        num(panel, "data-height"),
        num(panel, "data-p-top"),
    );
    let power = points(elements(&svg, r#"id="power""#)[0]);
    let y20 = top + h - 20.0 / p_top * h;
    assert!(power.iter().any(|p| (p.1 - y20).abs() < 0.01), "{power:?}");

    let (code, out, err) = lase(&["plan", path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("laser at rest   0.0072 s in dot-mode windows"),
        "{out}"
    );
    assert!(
        out.contains("pulses          36 (36 at rest, 0 along lit moves)"),
        "{out}"
    );
}

// ------------------------------------------------------------------ view

/// The view fits the lit work plus a 5 % margin (the arm's 600 mm approach from home does not
/// shrink it); `--full` fits everything, the start included.
#[test]
fn the_view_fits_the_lit_work_and_full_shows_all() {
    for name in ["surface_hardening_arm", "frame_marking", "cam_hardening"] {
        let (src, job) = example(name);
        let svg = plot(&src, &job, false);
        let g = elements(&svg, r#"<g id="toolpath""#)[0];
        assert_eq!(attr(g, "data-fit"), "lit", "{name}");
        let lit = nums(g, "data-lit");
        let view = View::of(&svg);
        // The lit extent, from the trace's lit rows (1 ms apart) in the drawing plane.
        let plane_w = 1;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        let mut t = 0.0;
        while t <= job.cycle_time() {
            let (sample, on, _) = beam_at(&job, t);
            if on {
                let spot = job.spot(&sample.pos, sample.tag);
                for (k, c) in [spot[0], spot[plane_w]].into_iter().enumerate() {
                    lo[k] = lo[k].min(c);
                    hi[k] = hi[k].max(c);
                }
            }
            t += 1e-3;
        }
        for k in 0..2 {
            // A millionth of the lit extent's larger side (0.12 µm on the arm's 120 mm; the
            // plot keeps one scale for both, and a pixel of its 690 is 1.4e-3 of that side): the plot's samples (a fixed budget spread over
            // the job's time) and the trace's 1 ms ones are different points of the same path,
            // and neither need sit on a curve's crest (the arm at 3.5 mm/s, 221 s: a 1 ms
            // sample at the section's crest 12 nm above the plot's highest).
            let slack = 1e-6 * (lit[2] - lit[0]).max(lit[3] - lit[1]).max(1.0);
            assert!(
                lit[k] <= lo[k] + slack && lit[k + 2] >= hi[k] - slack,
                "{name}: {lit:?} vs the trace's {lo:?} {hi:?}"
            );
            // Sampled at 1 ms, the trace misses at most a millisecond of travel at each end.
            assert!(
                lo[k] - lit[k] < 1.0 && lit[k + 2] - hi[k] < 1.0,
                "{name}: {lit:?}"
            );
        }
        let pad = 0.05 * (lit[2] - lit[0]).max(lit[3] - lit[1]);
        let (dh, dw) = (view.view[2] - view.view[0], view.view[3] - view.view[1]);
        let (need_h, need_w) = (lit[2] - lit[0] + 2.0 * pad, lit[3] - lit[1] + 2.0 * pad);
        assert!(dh >= need_h - 1e-9 && dw >= need_w - 1e-9, "{name}");
        // Equal aspect: one side is exactly the lit extent plus the margin.
        assert!(
            (dh - need_h).abs() < 1e-6 || (dw - need_w).abs() < 1e-6,
            "{name}: view {dh} x {dw}, lit + margin {need_h} x {need_w}"
        );

        let full = plot(&src, &job, true);
        let g = elements(&full, r#"<g id="toolpath""#)[0];
        assert_eq!(attr(g, "data-fit"), "full");
        let v = View::of(&full).view;
        let start = job.spot(&job.plan.start(), 0);
        assert!(v[0] <= start[0] && start[0] <= v[2]);
        assert!(v[1] <= start[plane_w] && start[plane_w] <= v[3]);
    }
    // The arm's lit section is a small part of its motion: the fitted view is far closer.
    let (src, job) = example("surface_hardening_arm");
    let fit = View::of(&plot(&src, &job, false)).view;
    let all = View::of(&plot(&src, &job, true)).view;
    assert!(
        (all[2] - all[0]) > 2.0 * (fit[2] - fit[0]),
        "{fit:?} vs {all:?}"
    );
}

// ------------------------------------------------------------------ speed panel

fn speed_y(svg: &str, v: f64) -> f64 {
    let panel = elements(svg, r#"<g id="speed-panel""#)[0];
    num(panel, "data-top") + num(panel, "data-height")
        - v / num(panel, "data-v-top") * num(panel, "data-height")
}

/// `conrod_notch` speaks mm/min: the axis is in mm/min and the feed limit runs at 950 mm/min
/// where it cuts; the axis limit is drawn; the events (M-functions, swings) are marked where
/// the machine stands still, and the laser switches are marked.
#[test]
fn the_speed_panel_has_limits_power_and_events_in_the_recipes_unit() {
    let (src, job) = example("conrod_notch");
    let svg = plot(&src, &job, false);
    assert_eq!(SpeedUnit::of_source(&src), SpeedUnit::MmPerMin);
    assert!(svg.contains(">v [mm/min]<") && svg.contains(r#"data-unit="mm/min""#));
    let feed = points(elements(&svg, r#"id="feed-limit""#)[0]);
    let y950 = speed_y(&svg, 950.0);
    assert!(
        feed.windows(2)
            .any(|p| (p[0].1 - y950).abs() < 0.006 && (p[1].1 - y950).abs() < 0.006),
        "no 950 mm/min step in {feed:?}"
    );
    assert_eq!(elements(&svg, r#"id="axis-limit""#).len(), 1);
    assert_eq!(elements(&svg, r#"id="power""#).len(), 1);
    let events = elements(&svg, r#"class="event""#);
    let standstill_ops = job
        .program
        .ops
        .iter()
        .filter(|o| {
            matches!(
                o.kind,
                OpKind::MCode { .. } | OpKind::Event { .. } | OpKind::Dwell { .. }
            )
        })
        .count();
    assert_eq!(events.len(), standstill_ops);
    assert!(svg.contains(">swing_right<") && svg.contains(">swing_left<"));
    for e in &events {
        // "NAME at T s": the machine stands still at T.
        let title = &e[e.find("<title>").unwrap() + 7..e.find("</title>").unwrap()];
        let t: f64 = title
            .rsplit(" at ")
            .next()
            .unwrap()
            .trim_end_matches(" s")
            .parse()
            .unwrap();
        assert!(beam_at(&job, t).0.v.abs() < 1e-6, "{title}: moving");
    }
    let on = elements(&svg, r#"class="laser-on""#).len();
    assert!(on >= 1 && on == elements(&svg, r#"class="laser-off""#).len());
}

/// A constant lit speed shows one swatch labelled with the speed, not a bar from 20 to 20;
/// a varying one a bar between two different numbers.
#[test]
fn the_colour_bar_does_not_degenerate_at_constant_speed() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("line.lase");
    std::fs::write(
        &path,
        "machine xy_table\nlaser { power 20 W, spot 0.1 mm }\n\
         follow profile line((0, 0), (50 mm, 0)) at 20 mm/s\n",
    )
    .unwrap();
    let (src, job) = job_of(&path);
    let svg = plot(&src, &job, false);
    assert_eq!(elements(&svg, r#"class="speed-swatch""#).len(), 1);
    assert!(svg.contains(">20 (constant)<"), "{svg}");
    assert!(elements(&svg, r#"class="speed-bar""#).is_empty());

    // The dial's circle at 40 mm/s and ticks at 50 mm/s.
    let (src, job) = example("dial_marks");
    let svg = plot(&src, &job, false);
    assert_eq!(elements(&svg, r#"class="speed-bar""#).len(), 1);
    assert!(svg.contains(">50</text>") && svg.contains(">40</text>"));
    assert!(elements(&svg, r#"class="speed-swatch""#).is_empty());
}

/// On oriented machines arrows show the beam at lit poses, each along the beam's projection
/// onto the drawing plane; a flat bed has none.
#[test]
fn oriented_machines_show_the_beam_direction() {
    // Both draw the xy plane (the cam's profile, the arm's surface from above).
    for (name, plane_w) in [("cam_hardening", 1), ("surface_hardening_arm", 1)] {
        let (src, job) = example(name);
        let svg = plot(&src, &job, false);
        let arrows = elements(&svg, r#"class="beam-arrow""#);
        // Up to 24, spread so that none stands on another (40 px apart at the spot).
        assert!((8..=24).contains(&arrows.len()), "{name}: {}", arrows.len());
        let tips: Vec<(f64, f64)> = arrows
            .iter()
            .filter(|a| a.starts_with("<line"))
            .map(|a| (num(a, "x2"), num(a, "y2")))
            .collect();
        for (i, a) in tips.iter().enumerate() {
            for b in &tips[..i] {
                assert!(
                    (a.0 - b.0).hypot(a.1 - b.1) >= 40.0 - 0.01,
                    "{name}: {a:?} {b:?}"
                );
            }
        }
        for a in arrows.iter().filter(|a| a.starts_with("<line")) {
            let title = &a[a.find("beam (").unwrap() + 6..a.find(") at").unwrap()];
            let b: Vec<f64> = title.split(", ").map(|v| v.parse().unwrap()).collect();
            let (dx, dy) = (num(a, "x2") - num(a, "x1"), num(a, "y2") - num(a, "y1"));
            let len = b[0].hypot(b[plane_w]);
            // Page y grows downward.
            let (ex, ey) = (b[0] / len, -b[plane_w] / len);
            let n = dx.hypot(dy);
            assert!(
                (dx / n - ex).abs() < 0.01 && (dy / n - ey).abs() < 0.01,
                "{name}: {a}"
            );
        }
    }
    let (src, job) = example("frame_marking");
    assert!(!plot(&src, &job, false).contains("beam-arrow"));
}

// ------------------------------------------------------------------ files

/// `-o f.png` writes a PNG twice the SVG's size, with text (the embedded font) and the path
/// drawn where the SVG puts it; `-o f.svg` writes the SVG `plot_svg` draws.
#[test]
fn lase_plot_writes_png_and_svg() {
    let dir = tempfile::tempdir().unwrap();
    let (png, svg_path) = (dir.path().join("f.png"), dir.path().join("f.svg"));
    for out in [&png, &svg_path] {
        let (code, stdout, err) = lase(&[
            "plot",
            "examples/frame_marking.lase",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        assert!(stdout.contains("wrote"), "{stdout}");
    }
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let (src, job) = example("frame_marking");
    assert_eq!(svg, plot(&src, &job, false));
    let head = svg.lines().next().unwrap();
    let (w, h) = (num(head, "width"), num(head, "height"));

    let pixmap = resvg::tiny_skia::Pixmap::load_png(&png).expect("a PNG");
    assert_eq!(
        (pixmap.width(), pixmap.height()),
        ((2.0 * w) as u32, (2.0 * h) as u32)
    );
    let dark = |x: f64, y: f64, r: i64| {
        let (cx, cy) = ((2.0 * x) as i64, (2.0 * y) as i64);
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                let p = pixmap.pixel((cx + dx) as u32, (cy + dy) as u32).unwrap();
                u32::from(p.red()) + u32::from(p.green()) + u32::from(p.blue()) < 3 * 200
            })
        })
    };
    // Every vertex of the lit path is inked.
    for line in elements(&svg, r#"class="lit""#) {
        for (x, y) in points(line) {
            assert!(dark(x, y, 2), "no ink at ({x}, {y})");
        }
    }
    // The title is text: ink along its baseline.
    let inked = (0..300).filter(|&x| dark(72.0 + x as f64, 16.0, 0)).count();
    assert!(inked > 30, "title not drawn ({inked} dark pixels)");
    // A blank corner stays white.
    assert!(!dark(5.0, h - 5.0, 2));
}

#[test]
fn a_bad_speed_unit_is_refused() {
    let (code, _, err) = lase(&[
        "plot",
        "examples/frame_marking.lase",
        "--speed-unit",
        "furlongs",
        "-o",
        "/dev/null",
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("mm/s or mm/min"), "{err}");
}
