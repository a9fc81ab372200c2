//! Marking (issue 19) measured from lase's real outputs: QR codes decoded back from the lit
//! moves of the emitted GRBL program, Data Matrix symbols from the pulse list, single-stroke
//! text against the Hershey table's own coordinates, and outline text against the font's own
//! glyph outlines (read here with ttf-parser, independently of lase's flattening).

mod common;

use common::*;
use std::path::Path;

/// The lit feed moves of a GRBL-family program: (from, to) in mm, S > 0.
/// The lit feed moves of a GRBL program, (from, to).
fn lit_moves(nc: &str) -> Vec<([f64; 2], [f64; 2])> {
    lit_moves_with_power(nc)
        .into_iter()
        .map(|(a, b, _, _)| (a, b))
        .collect()
}

const HEADER: &str = "machine xy_table\nlimits { x: v 200 mm/s, a 2 m/s^2; y: v 200 mm/s, a 2 m/s^2 }\nlaser { power 10 W, spot 50 um }\n";

#[test]
fn the_qr_code_of_the_example_decodes_from_the_emitted_grbl_program() {
    for dialect in ["grbl", "grblhal"] {
        let nc = emit_ok(&root().join("examples/codes.lase"), dialect);
        // Paint every lit hatch line of the QR (left of x = 14 mm) as a band one hatch pitch
        // (0.1 mm) wide into a 0.05 mm bitmap with a white margin, as a camera would see it.
        let px = 0.05;
        let (w, h) = (360usize, 360usize);
        let margin = 40.0;
        let mut img = vec![255u8; w * h];
        for (a, b) in lit_moves(&nc).into_iter().filter(|(a, _)| a[0] < 14.0) {
            assert!((a[1] - b[1]).abs() < 1e-9, "hatch lines run along x");
            let row_lo = ((a[1] - 0.05) / px + margin).round() as usize;
            let row_hi = ((a[1] + 0.05) / px + margin).round() as usize;
            let (x0, x1) = (a[0].min(b[0]), a[0].max(b[0]));
            for r in row_lo..row_hi {
                for c in
                    ((x0 / px + margin).round() as usize)..((x1 / px + margin).round() as usize)
                {
                    // y up in the part, rows down in the image.
                    img[(h - 1 - r) * w + c] = 0;
                }
            }
        }
        let mut prepared = rqrr::PreparedImage::prepare_from_greyscale(w, h, |x, y| img[y * w + x]);
        let grids = prepared.detect_grids();
        assert_eq!(grids.len(), 1, "{dialect}: one QR code in the plot");
        let (_, text) = grids[0].decode().unwrap();
        assert_eq!(text, "LASE-01234", "{dialect}");
    }
}

#[test]
fn the_data_matrix_of_the_example_decodes_from_the_pulse_list() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("pulses.csv");
    let recipe = root().join("examples/codes.lase");
    let (code, _, err) = lase(&[
        "plan",
        recipe.to_str().unwrap(),
        "--pulses",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(csv).unwrap();
    let pulses: Vec<[f64; 2]> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [f[1], f[2]]
        })
        .filter(|p| p[0] > 14.0)
        .collect();
    // The module grid from the pulses alone: the L finder fills the left column and the
    // bottom row, so the extreme pulses span the symbol.
    let module = 0.3;
    let (x0, y0) = pulses
        .iter()
        .fold((f64::MAX, f64::MAX), |m, p| (m.0.min(p[0]), m.1.min(p[1])));
    let (x1, y1) = pulses
        .iter()
        .fold((f64::MIN, f64::MIN), |m, p| (m.0.max(p[0]), m.1.max(p[1])));
    let cols = ((x1 - x0) / module).round() as usize + 1;
    let rows = ((y1 - y0) / module).round() as usize + 1;
    assert_eq!(cols, rows, "a square symbol");
    let mut dark = vec![false; cols * rows];
    for p in &pulses {
        let c = (p[0] - x0) / module;
        let r = (y1 - p[1]) / module;
        // Every pulse sits on a module centre, within a micrometre.
        assert!((c - c.round()).abs() * module < 1e-3 && (r - r.round()).abs() * module < 1e-3);
        dark[r.round() as usize * cols + c.round() as usize] = true;
    }
    // The quiet zone: the symbol starts one 0.3 mm module in from `origin: (15 mm, 0)`.
    assert!((x0 - (15.0 + 1.5 * module)).abs() < 1e-6, "{x0}");
    assert!((y0 - 1.5 * module).abs() < 1e-6, "{y0}");
    let decoded = datamatrix::DataMatrix::decode(&dark, cols).expect("a readable Data Matrix");
    assert_eq!(decoded, b"LASE-01234");
}

#[test]
fn single_stroke_text_is_the_hershey_glyph_scaled_to_its_cap_height() {
    let dir = tempfile::tempdir().unwrap();
    // 21 mm capitals: one Hershey unit is one millimetre.
    let r = write_file(
        dir.path(),
        "h.lase",
        &format!(
            "{HEADER}for s in profile text(\"H\", height: 21 mm, origin: (5 mm, 2 mm)) {{ follow s at 20 mm/s }}\n"
        ),
    );
    let lit = lit_moves(&emit_ok(&r, "grbl"));
    // Hershey Simplex 'H': left edge -11; strokes (-7,-12)-(-7,9), (7,-12)-(7,9),
    // (-7,-2)-(7,-2) with y down and the baseline at 9.
    let want = [
        ([4.0, 21.0], [4.0, 0.0]),
        ([18.0, 21.0], [18.0, 0.0]),
        ([4.0, 11.0], [18.0, 11.0]),
    ];
    assert_eq!(lit.len(), want.len(), "{lit:?}");
    for ((a, b), (wa, wb)) in lit.iter().zip(want) {
        for (p, q) in [(a, wa), (b, wb)] {
            assert!(
                (p[0] - (q[0] + 5.0)).abs() < 1e-3 && (p[1] - (q[1] + 2.0)).abs() < 1e-3,
                "{p:?} vs {q:?}"
            );
        }
    }
}

/// The font's own outline of a glyph, flattened finely here (in font units).
struct Outline(Vec<Vec<[f64; 2]>>);

impl ttf_parser::OutlineBuilder for Outline {
    fn move_to(&mut self, x: f32, y: f32) {
        self.0.push(vec![[x as f64, y as f64]]);
    }
    fn line_to(&mut self, x: f32, y: f32) {
        self.0.last_mut().unwrap().push([x as f64, y as f64]);
    }
    fn quad_to(&mut self, x1: f32, y1: f32, x: f32, y: f32) {
        let c = self.0.last_mut().unwrap();
        let p0 = *c.last().unwrap();
        for i in 1..=200 {
            let t = i as f64 / 200.0;
            let u = 1.0 - t;
            c.push([
                u * u * p0[0] + 2.0 * u * t * x1 as f64 + t * t * x as f64,
                u * u * p0[1] + 2.0 * u * t * y1 as f64 + t * t * y as f64,
            ]);
        }
    }
    fn curve_to(&mut self, x1: f32, y1: f32, x2: f32, y2: f32, x: f32, y: f32) {
        let c = self.0.last_mut().unwrap();
        let p0 = *c.last().unwrap();
        for i in 1..=200 {
            let t = i as f64 / 200.0;
            let u = 1.0 - t;
            let b = [u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t];
            c.push([
                b[0] * p0[0] + b[1] * x1 as f64 + b[2] * x2 as f64 + b[3] * x as f64,
                b[0] * p0[1] + b[1] * y1 as f64 + b[2] * y2 as f64 + b[3] * y as f64,
            ]);
        }
    }
    fn close(&mut self) {}
}

fn seg_dist(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let l2 = dx * dx + dy * dy;
    let t = if l2 == 0.0 {
        0.0
    } else {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2).clamp(0.0, 1.0)
    };
    ((p[0] - a[0] - t * dx).powi(2) + (p[1] - a[1] - t * dy).powi(2)).sqrt()
}

#[test]
fn outline_text_fills_the_fonts_own_glyph() {
    let font = Path::new("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf");
    let data = std::fs::read(font).expect("fonts-dejavu-core is installed (.ci/run installs it)");
    let face = ttf_parser::Face::parse(&data, 0).unwrap();
    // DejaVu's OS/2 table states no cap height: a capital is as high as its 'H'.
    let cap = face.capital_height().map(f64::from).unwrap_or_else(|| {
        face.glyph_bounding_box(face.glyph_index('H').unwrap())
            .unwrap()
            .y_max as f64
    });
    let height = 10.0;
    let k = height / cap;
    let mut o = Outline(Vec::new());
    face.outline_glyph(face.glyph_index('B').unwrap(), &mut o)
        .unwrap();
    let outline: Vec<Vec<[f64; 2]>> =
        o.0.iter()
            .map(|c| c.iter().map(|p| [p[0] * k, p[1] * k]).collect())
            .collect();
    let dir = tempfile::tempdir().unwrap();
    let r = write_file(
        dir.path(),
        "b.lase",
        &format!(
            "{HEADER}scan raster profile text(\"B\", height: {height} mm, font: \"{}\") {{ pitch 0.1 mm, speed 20 mm/s }}\n",
            font.display()
        ),
    );
    let lit = lit_moves(&emit_ok(&r, "grbl"));
    assert!(
        lit.len() > 90,
        "about 100 hatch rows over a 10 mm capital: {}",
        lit.len()
    );
    let dist = |p: [f64; 2]| {
        outline
            .iter()
            .flat_map(|c| {
                c.windows(2)
                    .map(move |w| seg_dist(p, w[0], w[1]))
                    .chain([seg_dist(p, c[c.len() - 1], c[0])])
            })
            .fold(f64::MAX, f64::min)
    };
    let inside = |p: [f64; 2]| {
        let mut n = 0;
        for c in &outline {
            for i in 0..c.len() {
                let (a, b) = (c[i], c[(i + 1) % c.len()]);
                if (a[1] > p[1]) != (b[1] > p[1])
                    && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
                {
                    n += 1;
                }
            }
        }
        n % 2 == 1
    };
    for (a, b) in &lit {
        // Each hatch line starts and ends on the font's outline (within the planner's default
        // chord tolerance and the NC's 4 decimals) and runs inside the glyph.
        for p in [*a, *b] {
            assert!(dist(p) < 0.02, "{p:?} is {} mm off the outline", dist(p));
        }
        assert!(
            inside([(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]),
            "{a:?}-{b:?}"
        );
    }
}

#[test]
fn string_parts_and_format_run_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let r = write_file(
        dir.path(),
        "s.lase",
        &format!(
            "{HEADER}let sn = format(\"SN {{:04}}\", 7)\nlet n = len(sn)\nlet last = sn[-1]\nfor s in profile text(format(\"{{}}{{}}\", last, n), height: 2 mm) {{ follow s at 20 mm/s }}\n"
        ),
    );
    let (code, out, err) = lase(&["check", r.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}{err}");
}

#[test]
fn the_marking_examples_run_on_the_simulated_controller() {
    for ex in ["serial_number", "codes", "material_test"] {
        let recipe = root().join(format!("examples/{ex}.lase"));
        let (code, out, err) = lase(&[
            "run",
            recipe.to_str().unwrap(),
            "--link",
            "sim://?time-scale=max",
        ]);
        assert_eq!(code, 0, "{ex}: {out}{err}");
        assert!(
            format!("{out}{err}").contains("controller Idle"),
            "{ex}: {out}{err}"
        );
    }
}

/// Lit feed moves of a GRBL program with their S word and feed (mm/min).
fn lit_moves_with_power(nc: &str) -> Vec<([f64; 2], [f64; 2], f64, f64)> {
    let (mut x, mut y, mut s, mut g, mut f) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut out = Vec::new();
    for line in nc.lines() {
        let (x0, y0) = (x, y);
        let mut moved = false;
        for (c, v) in nc_words(line) {
            match c {
                'G' if v == 0.0 || v == 1.0 => g = v,
                'X' => (x, moved) = (v, true),
                'Y' => (y, moved) = (v, true),
                'S' => s = v,
                'F' => f = v,
                _ => {}
            }
        }
        if moved && g == 1.0 && s > 0.0 {
            out.push(([x0, y0], [x, y], s, f));
        }
    }
    out
}

#[test]
fn the_material_test_grid_steps_power_by_row_and_speed_by_column() {
    // The preset's numbers: 4..20 W over 5 rows, 20..100 mm/s over 5 columns, 5 mm cells
    // 2 mm apart after a 6 mm label margin, hatched every 0.2 mm; labels at 6 W.
    let nc = emit_ok(&root().join("examples/material_test.lase"), "grbl");
    let lit = lit_moves_with_power(&nc);
    let (cell, step, margin, hatch) = (5.0, 7.0, 6.0, 0.2);
    let mut s_of_row = Vec::new();
    for r in 0..5 {
        let power = 4.0 + 16.0 * r as f64 / 4.0;
        for c in 0..5 {
            let speed = 20.0 + 80.0 * c as f64 / 4.0;
            let (x0, y0) = (margin + c as f64 * step, r as f64 * step);
            let inside = |p: [f64; 2]| {
                p[0] >= x0 - 1e-6
                    && p[0] <= x0 + cell + 1e-6
                    && p[1] >= y0 - 1e-6
                    && p[1] <= y0 + cell + 1e-6
            };
            let lines: Vec<_> = lit.iter().filter(|m| inside(m.0) && inside(m.1)).collect();
            assert_eq!(lines.len(), (cell / hatch) as usize, "cell ({r}, {c})");
            for (a, b, s, f) in &lines {
                assert!(
                    (a[1] - b[1]).abs() < 1e-9 && ((a[0] - b[0]).abs() - cell).abs() < 1e-3,
                    "a full-width hatch line"
                );
                assert!((f - speed * 60.0).abs() < 1e-6, "cell ({r}, {c}): F{f}");
                assert_eq!(*s, lines[0].2, "one power per cell");
            }
            if c == 0 {
                s_of_row.push((power, lines[0].2));
            } else {
                assert_eq!(lines[0].2, s_of_row[r].1, "one power per row");
            }
        }
    }
    // The S word is proportional to the row's power.
    for (p, s) in &s_of_row {
        assert!(
            (s / s_of_row[0].1 - p / s_of_row[0].0).abs() < 1e-3,
            "{p} W: S{s}"
        );
    }
    // Everything else lit is a label stroke at the label power: 6 W is 1.5 × the first row's.
    let grid = |p: [f64; 2]| {
        p[0] >= margin - 1e-6 && p[1] <= 5.0 * step - 2.0 + 1e-6 && p[0] <= margin + 5.0 * step
    };
    let labels: Vec<_> = lit
        .iter()
        .filter(|m| {
            !(grid(m.0)
                && grid(m.1)
                && (m.0[1] - m.1[1]).abs() < 1e-9
                && ((m.0[0] - m.1[0]).abs() - cell).abs() < 1e-3)
        })
        .collect();
    assert!(labels.len() > 50, "{}", labels.len());
    for (_, _, s, f) in labels {
        assert!((s / s_of_row[0].1 - 1.5).abs() < 1e-3, "label S{s}");
        assert!((f - 30.0 * 60.0).abs() < 1e-6);
    }
}

#[test]
fn the_material_test_labels_read_the_grids_numbers() {
    // The labels' glyph strokes: "4" … "20" beside the rows and "20" … "100" above the
    // columns are what `format` made of the preset's ranges, laid out in the Hershey font.
    let (code, out, err) = lase(&[
        "check",
        root().join("examples/material_test.lase").to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{out}{err}");
    let dir = tempfile::tempdir().unwrap();
    let r = write_file(
        dir.path(),
        "l.lase",
        &format!(
            "{HEADER}use stdlib::presets::material_test\nlet powers = [format(\"{{:.0}}\", (power_min + (power_max - power_min) * r / (rows - 1)) / 1 W) for r in 0..rows]\nlet speeds = [format(\"{{:.0}}\", (speed_min + (speed_max - speed_min) * c / (cols - 1)) / 1 mm/s) for c in 0..cols]\nif powers[4] == \"20\" and powers[1] == \"8\" and speeds[2] == \"60\" and speeds[4] == \"100\" {{ dwell 1 s }}\n"
        ),
    );
    let (code, out, err) = lase(&["plan", r.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("lase's plan     1.0000 s"),
        "the labels' numbers: {out}"
    );
}

/// The trigger (`M62 P1` / `M63 P1`) as LinuxCNC's motion switches it: the synchronized
/// switches queued before a move take effect when that move starts, and only the last one per
/// output counts (tp.c `tpSetDout` keeps one slot per output for the next segment). `calls`
/// are the program's events in the interpreter's order: `Some(high)` a switch of the trigger,
/// `None` a move. Returns (rising edges, falling edges, moves that had more than one trigger
/// switch queued).
fn trigger_edges_per_move(calls: impl IntoIterator<Item = Option<bool>>) -> (usize, usize, usize) {
    let (mut up, mut down, mut crowded) = (0, 0, 0);
    let mut level = false;
    let mut queued: Vec<bool> = Vec::new();
    for call in calls {
        match call {
            Some(high) => queued.push(high),
            None => {
                crowded += usize::from(queued.len() > 1);
                if let Some(&high) = queued.last() {
                    up += usize::from(high && !level);
                    down += usize::from(!high && level);
                    level = high;
                }
                queued.clear();
            }
        }
    }
    (up, down, crowded)
}

#[test]
fn every_data_matrix_pulse_has_its_own_trigger_edges_on_linuxcnc() {
    // codes' Data Matrix dots touch where runs of different pitch meet (x = 16.35 on row
    // y = 1.05): lase once lowered and raised the trigger before the same move there, and on
    // the real LinuxCNC 5 of its 105 pulses merged into their neighbours.
    let recipe = root().join("examples/codes.lase");
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let (code, _, err) = lase(&[
        "plan",
        recipe.to_str().unwrap(),
        "--summary",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    let planned = summary["pulses"].as_u64().unwrap() as usize;
    assert_eq!(planned, 105);

    let ngc = emit_ok(&recipe, "linuxcnc");
    // From the NC text: a block's outputs come before its motion (rs274ngc's order).
    let calls = ngc.lines().flat_map(|line| {
        let w = nc_words(line);
        let trigger = w.contains(&('P', 1.0));
        let switches: Vec<Option<bool>> = w
            .iter()
            .filter(|&&(c, v)| trigger && c == 'M' && (v == 62.0 || v == 63.0))
            .map(|&(_, v)| Some(v == 62.0))
            .collect();
        let moves = w.iter().any(|(c, _)| "XYZABC".contains(*c));
        switches.into_iter().chain(moves.then_some(None))
    });
    assert_eq!(trigger_edges_per_move(calls), (planned, planned, 0));

    // The same from LinuxCNC's own interpreter, where it is installed.
    let f = dir.path().join("codes.ngc");
    std::fs::write(&f, &ngc).unwrap();
    if let Ok(out) = rs274_g(&f) {
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && text.contains("PROGRAM_END"),
            "{text}"
        );
        let calls = text.lines().filter_map(|l| {
            if l.contains("SET_MOTION_OUTPUT_BIT(1)") {
                Some(Some(true))
            } else if l.contains("CLEAR_MOTION_OUTPUT_BIT(1)") {
                Some(Some(false))
            } else if ["STRAIGHT_FEED", "STRAIGHT_TRAVERSE", "ARC_FEED"]
                .iter()
                .any(|m| l.contains(m))
            {
                Some(None)
            } else {
                None
            }
        });
        assert_eq!(trigger_edges_per_move(calls), (planned, planned, 0));
    }
}
