//! Image engraving (`scan image`, issue 19) measured from lase's real outputs: test images are
//! written as PNG files by a small encoder here, engraved by the `lase` binary, and the emitted
//! NC programs are read back — the power of every block along every row — to rebuild each
//! pixel's power, which is compared with the source pixels after the mapping computed here
//! independently of lase's code.

mod common;

use common::*;
use std::path::PathBuf;

// ------------------------------------------------------------------ a PNG encoder

/// An 8-bit grayscale PNG (zlib stored blocks: no compressor needed, still a valid file).
fn png_gray(w: u32, h: u32, luma: &[u8]) -> Vec<u8> {
    assert_eq!(luma.len(), (w * h) as usize);
    png_claiming(w, h, luma)
}

/// A PNG whose header says `w × h` around the given pixel bytes (rows of `luma.len() / h`
/// when that divides, else one row): a valid file when they agree, a bomb's header when not.
fn png_claiming(w: u32, h: u32, luma: &[u8]) -> Vec<u8> {
    let (dw, dh) = if luma.len() == (w as usize) * (h as usize) {
        (w, h)
    } else {
        (luma.len() as u32, 1)
    };
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = 0xffff_ffffu32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8], data: &[u8]) {
        out.extend((data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend(data);
        out.extend(&body);
        out.extend(crc32(&body).to_be_bytes());
    }
    let mut raw = Vec::new();
    for r in 0..dh as usize {
        raw.push(0); // filter: none
        raw.extend(&luma[r * dw as usize..(r + 1) * dw as usize]);
    }
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
    for (i, b) in blocks.iter().enumerate() {
        z.push(u8::from(i + 1 == blocks.len()));
        z.extend((b.len() as u16).to_le_bytes());
        z.extend((!(b.len() as u16)).to_le_bytes());
        z.extend(*b);
    }
    let (mut a, mut b) = (1u32, 0u32);
    for &x in &raw {
        a = (a + u32::from(x)) % 65_521;
        b = (b + a) % 65_521;
    }
    z.extend(((b << 16) | a).to_be_bytes());
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 0, 0, 0, 0]);
    chunk(&mut out, b"IHDR", &ihdr);
    chunk(&mut out, b"IDAT", &z);
    chunk(&mut out, b"IEND", &[]);
    out
}

/// A horizontal ramp from white (left) to black (right), with a white margin of 3 pixels
/// left and right and one white row (dropped from the scan) at the top.
fn ramp(w: u32, h: u32) -> Vec<u8> {
    (0..h)
        .flat_map(|r| {
            (0..w).map(move |c| {
                if r == 0 || c < 3 || c >= w - 3 {
                    255
                } else {
                    255 - ((c - 3) * 255 / (w - 7)) as u8
                }
            })
        })
        .collect()
}

struct Job {
    _dir: tempfile::TempDir,
    recipe: PathBuf,
}

/// A recipe `scan image "img.png" { SETTINGS }` on the xy_table, next to the image.
fn job(w: u32, h: u32, luma: &[u8], settings: &str) -> Job {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("img.png"), png_gray(w, h, luma)).unwrap();
    let recipe = dir.path().join("img.lase");
    std::fs::write(
        &recipe,
        format!(
            "machine xy_table\nlaser {{ power 50 W, spot 0.1 mm }}\n\
             scan image \"img.png\" {{ {settings} }}\nmove to (0, 0) rapid\n"
        ),
    )
    .unwrap();
    Job { _dir: dir, recipe }
}

// ------------------------------------------------------------------ reading the NC back

/// A feed block along a row: from x0 to x1 at y, with the power the NC gives it, % of full.
#[derive(Debug, Clone, Copy)]
struct Block {
    y: f64,
    x0: f64,
    x1: f64,
    pct: f64,
}

/// The feed blocks of a GRBL program (power = S / 1000 · 100 %, `s_max` 1000 on xy_table;
/// `G0` runs dark in laser mode), an ISO one (the same S, lit between `M3` and `M5`, a power
/// change as an `S` block of its own before the run's move) or a LinuxCNC one (`M67 E0 Q` is the power, `M62 P0`/`M63 P0`
/// the gate, both taking effect with the next motion block).
///
/// LinuxCNC's programs carry each beam switch passed on the fly 1.5 servo periods (1 ms) of
/// the row's speed along the row, where the controller's joints are when the output switches
/// (`emit::writer::lead`, measured in `runtime/tests/switch_lead.rs` and on the real
/// LinuxCNC): the beam is read here where it lights, that far back from the switch.
fn blocks(nc: &str) -> Vec<Block> {
    let (mut x, mut y, mut s, mut q, mut gate, mut g) = (0.0, 0.0, 0.0, 0.0, false, 0);
    let mut f = 0.0;
    let mut out: Vec<Block> = Vec::new();
    let linuxcnc = nc.contains("for linuxcnc");
    for line in nc.lines() {
        let w = nc_words(line);
        let get = |c: char| w.iter().find(|(k, _)| *k == c).map(|(_, v)| *v);
        // LinuxCNC carries a row's power steps and its beam-off the lead (1.5 servo periods,
        // `emit::writer::lead`) past the run's end: the block before ends that much later, so
        // the step stands where the run ends.
        let carried_back = |out: &mut Vec<Block>, x: &mut f64| {
            let lead = 1.5e-3 * f;
            if let Some(b) = out.last_mut()
                && linuxcnc
                && b.y == y
                && b.x1 == *x
                && b.pct > 0.0
                && (b.x1 - b.x0).abs() > lead + 1e-9
            {
                b.x1 -= lead * (b.x1 - b.x0).signum();
                *x = b.x1;
            }
        };
        if get('M') == Some(67.0) {
            carried_back(&mut out, &mut x);
            q = get('Q').unwrap();
            continue;
        }
        if linuxcnc && matches!((get('M'), get('P')), (Some(m), Some(p)) if m == 63.0 && p == 0.0) {
            carried_back(&mut out, &mut x);
        }
        if let Some(v) = get('F') {
            f = v / 60.0;
        }
        let switch = matches!((get('M'), get('P')), (Some(m), Some(p)) if (m == 62.0 || m == 63.0) && p == 0.0);
        // Where the beam switches: a switch carried by the lead ends a piece cut exactly that
        // long from the row's block (elsewhere it stands where the block starts).
        let lead = 1.5e-3 * f;
        if linuxcnc
            && switch
            && out
                .last()
                .is_some_and(|b| b.y == y && b.x1 == x && ((b.x1 - b.x0).abs() - lead).abs() < 2e-4)
        {
            x = out.pop().unwrap().x0;
        }
        match (get('M'), get('P')) {
            (Some(m), Some(p)) if m == 62.0 && p == 0.0 => gate = true,
            (Some(m), Some(p)) if m == 63.0 && p == 0.0 => gate = false,
            // ISO: M3 (with its S) lights, M5 darkens; the S words between are the power.
            (Some(3.0), None) => gate = true,
            (Some(5.0), None) => gate = false,
            _ => {}
        }
        if let Some(v) = get('G')
            && (v == 0.0 || v == 1.0)
        {
            g = v as i32;
        }
        if let Some(v) = get('S') {
            s = v;
        }
        let (nx, ny) = (get('X').unwrap_or(x), get('Y').unwrap_or(y));
        if (nx, ny) != (x, y) && g == 1 {
            let pct = if nc.contains("for grbl") {
                s / 10.0
            } else if nc.contains("for iso") {
                if gate { s / 10.0 } else { 0.0 }
            } else if gate {
                q
            } else {
                0.0
            };
            if ny == y {
                out.push(Block {
                    y,
                    x0: x,
                    x1: nx,
                    pct,
                });
            }
        }
        (x, y) = (nx, ny);
    }
    out
}

/// The power (%) at each pixel centre of a `w × h` image with pixels `p` mm square and its
/// lower-left corner at the origin: row r (top first) at y = (h − 1 − r + ½)·p. Rows run
/// backwards are read `offset` mm further along +x. Pixels no block covers are `None`.
fn pixels(bl: &[Block], w: u32, h: u32, p: f64, offset: f64) -> Vec<Option<f64>> {
    let mut out = vec![None; (w * h) as usize];
    for b in bl {
        let r = (f64::from(h) - 0.5 - b.y / p).round();
        if !(0.0..f64::from(h)).contains(&r) || (b.y - (f64::from(h) - 0.5 - r) * p).abs() > 1e-4 {
            continue;
        }
        let shift = if b.x1 < b.x0 { offset } else { 0.0 };
        let (lo, hi) = (b.x0.min(b.x1) - shift, b.x0.max(b.x1) - shift);
        for c in 0..w {
            let xc = (f64::from(c) + 0.5) * p;
            if xc > lo && xc < hi {
                out[(r as u32 * w + c) as usize] = Some(b.pct);
            }
        }
    }
    out
}

/// Darkness after the tone curve, as the reference documents it.
fn tone(l: u8, gamma: f64, invert: bool) -> f64 {
    let d = f64::from(l) / 255.0;
    (if invert { d } else { 1.0 - d }).powf(gamma)
}

// ------------------------------------------------------------------ tests

/// Grayscale: every pixel's power in the NC is min + (max − min)·round(255·tone)/255, exactly
/// up to the S word's 4 decimals, in both dialects; white pixels are dark (0 or not covered).
#[test]
fn grayscale_power_per_pixel_is_the_mapped_shade() {
    let (w, h) = (40, 6);
    let luma = ramp(w, h);
    for gamma in [1.0, 2.2] {
        let j = job(
            w,
            h,
            &luma,
            &format!("width 4 mm, speed 50 mm/s, power 40 W, min_power 10 W, gamma {gamma}"),
        );
        for dialect in ["grbl", "linuxcnc", "iso"] {
            let nc = emit_ok(&j.recipe, dialect);
            let px = pixels(&blocks(&nc), w, h, 0.1, 0.0);
            let mut lit = 0;
            for (i, &l) in luma.iter().enumerate() {
                let shade = (255.0 * tone(l, gamma, false)).round();
                let want = if shade == 0.0 {
                    0.0
                } else {
                    // % of the machine's 100 W.
                    10.0 + 30.0 * shade / 255.0
                };
                let got = px[i].unwrap_or(0.0);
                // GRBL and ISO: S (0..1000) to 4 decimals = 5e-6 %; LinuxCNC: Q % to 4 decimals.
                assert!(
                    (got - want).abs() <= 5e-5 + 1e-9,
                    "{dialect} gamma {gamma} pixel {i}: {got} %, expected {want} %"
                );
                lit += usize::from(want > 0.0);
            }
            assert!(lit > 150, "{lit} lit pixels");
        }
    }
}

/// Runs of equal pixels are one block each: a 2-level image of 4 equal stripes per row gives
/// exactly 4 blocks a row (plus the lead-ins and lead-outs, which are dark).
#[test]
fn runs_of_equal_pixels_are_merged_into_one_block() {
    let (w, h) = (40, 5);
    let luma: Vec<u8> = (0..h)
        .flat_map(|_| (0..w).map(|c| if (c / 10) % 2 == 0 { 0 } else { 128 }))
        .collect();
    let j = job(w, h, &luma, "width 4 mm, speed 50 mm/s");
    let nc = emit_ok(&j.recipe, "grbl");
    let lit: Vec<Block> = blocks(&nc).into_iter().filter(|b| b.pct > 0.0).collect();
    assert_eq!(lit.len(), 4 * h as usize, "{lit:?}");
    for b in &lit {
        assert!(((b.x1 - b.x0).abs() - 1.0).abs() < 1e-9, "{b:?}");
    }
}

/// Threshold and invert: a pixel is at full power exactly where its (inverted) tone reaches
/// the threshold.
#[test]
fn threshold_and_invert_light_the_pixels_past_the_threshold() {
    let (w, h) = (40, 4);
    let luma = ramp(w, h);
    let j = job(
        w,
        h,
        &luma,
        "width 4 mm, speed 50 mm/s, mode threshold, threshold 0.3, invert",
    );
    let px = pixels(&blocks(&emit_ok(&j.recipe, "grbl")), w, h, 0.1, 0.0);
    for (i, &l) in luma.iter().enumerate() {
        let on = tone(l, 1.0, true) >= 0.3;
        let got = px[i].unwrap_or(0.0);
        assert_eq!(got, if on { 50.0 } else { 0.0 }, "pixel {i} (luma {l})");
    }
}

/// Dithering: over 16 × 16 patches of a ramp, the share of pixels the NC lights at full power
/// matches the patch's mean tone within 0.03 (Atkinson, which drops a quarter of the error by
/// design, within 0.08 over mid-tone patches 0.2 to 0.8); every lit pixel is at full power.
#[test]
fn dithered_dot_density_follows_the_gray_level() {
    let (w, h) = (134, 34);
    let luma = ramp(w, h);
    for kernel in ["floyd", "jarvis", "stucki", "atkinson", "bayer"] {
        let j = job(
            w,
            h,
            &luma,
            &format!("width 13.4 mm, speed 50 mm/s, mode dither, dither {kernel}"),
        );
        let px = pixels(&blocks(&emit_ok(&j.recipe, "grbl")), w, h, 0.1, 0.0);
        assert!(px.iter().flatten().all(|&p| p == 0.0 || p == 50.0));
        for pr in 0..2 {
            for pc in 0..8 {
                let (mut on, mut t) = (0.0, 0.0);
                for r in 1 + pr * 16..1 + (pr + 1) * 16 {
                    for c in 3 + pc * 16..3 + (pc + 1) * 16 {
                        let i = (r * w + c) as usize;
                        on += f64::from(u8::from(px[i] == Some(50.0)));
                        t += tone(luma[i], 1.0, false);
                    }
                }
                let (on, t) = (on / 256.0, t / 256.0);
                if kernel == "atkinson" && !(0.2..=0.8).contains(&t) {
                    continue;
                }
                let tol = if kernel == "atkinson" { 0.08 } else { 0.03 };
                assert!(
                    (on - t).abs() <= tol,
                    "{kernel} patch ({pr}, {pc}): density {on:.3}, tone {t:.3}"
                );
            }
        }
    }
}

/// Bidirectional offset: on a vertical black bar, the bar's edges in the NC's backward rows
/// stand `line_offset` further along +x than in the forward rows.
#[test]
fn backward_rows_are_shifted_by_the_line_offset_in_the_nc() {
    let (w, h) = (20, 6);
    let luma: Vec<u8> = (0..h)
        .flat_map(|_| (0..w).map(|c| if (5..15).contains(&c) { 0 } else { 255 }))
        .collect();
    for dialect in ["grbl", "linuxcnc"] {
        let j = job(
            w,
            h,
            &luma,
            "width 2 mm, speed 50 mm/s, line_offset 0.035 mm",
        );
        let lit: Vec<Block> = blocks(&emit_ok(&j.recipe, dialect))
            .into_iter()
            .filter(|b| b.pct > 0.0)
            .collect();
        assert_eq!(lit.len(), h as usize);
        for b in &lit {
            let (lo, hi) = (b.x0.min(b.x1), b.x0.max(b.x1));
            let shift = if b.x1 < b.x0 { 0.035 } else { 0.0 };
            assert!((lo - (0.5 + shift)).abs() < 1e-9, "{dialect} {b:?}");
            assert!((hi - (1.5 + shift)).abs() < 1e-9, "{dialect} {b:?}");
        }
        // Both directions are there: serpentine rows.
        assert_eq!(lit.iter().filter(|b| b.x1 < b.x0).count(), h as usize / 2);
    }
}

/// Every lit pixel is passed at the programmed speed: the plan's overscan (lead-ins) stands
/// before every row, GRBL arms `M4` (power follows speed) once, and the job runs on the
/// simulator line by line.
#[test]
fn image_scans_check_plan_emit_and_run_in_every_flat_bed_dialect() {
    let (w, h) = (30, 5);
    let j = job(w, h, &ramp(w, h), "dpi 254, speed 80 mm/s");
    let r = j.recipe.to_str().unwrap();
    let (code, _, err) = lase(&["check", r]);
    assert_eq!(code, 0, "{err}");
    let (code, out, err) = lase(&["plan", r]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("laser on"), "{out}");
    for d in ["linuxcnc", "grbl", "grblhal", "iso"] {
        let nc = emit_ok(&j.recipe, d);
        if d.starts_with("grbl") {
            assert_eq!(nc.matches("M4 S0").count(), 1, "{nc}");
            assert!(!nc.contains("M3"), "{nc}");
        }
        // The first lit block starts after a dark run-up along the row.
        let bl = blocks(&nc);
        if let Some(k) = bl.iter().position(|b| b.pct > 0.0) {
            assert!(
                k > 0 && bl[k - 1].pct == 0.0 && bl[k - 1].y == bl[k].y,
                "{d}"
            );
            assert!(
                (bl[k - 1].x1 - bl[k - 1].x0).abs() > 0.5,
                "{d}: run-up {:?}",
                bl[k - 1]
            );
        }
    }
    let (code, out, err) = lase(&["run", r, "--time-scale", "max"]);
    assert_eq!(code, 0, "{err}");
    let lines = emit_ok(&j.recipe, "grbl").lines().count();
    assert!(out.contains(&format!("{lines} lines")), "{out}");
}

/// Bad images end in a diagnostic pointing at the file name, never a panic: not an image, a
/// canvas above the pixel limit (the header alone is read), a truncated file.
#[test]
fn bad_images_are_diagnostics() {
    let dir = tempfile::tempdir().unwrap();
    // A valid header claiming 20000 × 20000 pixels, and 16 bytes of data.
    let big = png_claiming(20_000, 20_000, &[0; 16]);
    let full = png_gray(8, 8, &[0; 64]);
    let cases: [(&str, Vec<u8>, &str); 3] = [
        ("text.png", b"not an image".to_vec(), "not a PNG or JPEG"),
        ("bomb.png", big, "20000 × 20000"),
        (
            "cut.png",
            full[..full.len() - 30].to_vec(),
            "cannot be decoded",
        ),
    ];
    for (name, bytes, says) in cases {
        std::fs::write(dir.path().join(name), bytes).unwrap();
        let recipe = dir.path().join("r.lase");
        std::fs::write(
            &recipe,
            format!(
                "machine xy_table\nlaser {{ power 5 W }}\n\
                 scan image \"{name}\" {{ width 4 mm, speed 50 mm/s }}\n"
            ),
        )
        .unwrap();
        let (code, _, err) = lase(&["check", recipe.to_str().unwrap()]);
        assert_eq!(code, 1, "{name}: {err}");
        assert!(err.contains("lase::eval::image"), "{name}: {err}");
        assert!(err.contains(says), "{name}: {err}");
        assert!(err.contains("r.lase:3:12"), "{name}: {err}");
        assert!(err.contains("help:"), "{name}: {err}");
        assert!(!err.contains("panicked"), "{name}: {err}");
    }
}

/// `angle`: the rows turned 30° about the image's corner at (5, 5). The NC's lit blocks,
/// turned back into the image frame, give every pixel its shade's power exactly as an
/// unturned scan does: the runs' ends are the turned pixel edges (within the NC's 3 decimals).
#[test]
fn a_turned_image_puts_every_pixel_at_its_power_in_the_turned_frame() {
    let (w, h) = (24, 5);
    let luma = ramp(w, h);
    let j = job(
        w,
        h,
        &luma,
        "width 2.4 mm, speed 50 mm/s, power 40 W, angle 30 deg, origin (5 mm, 5 mm)",
    );
    let nc = emit_ok(&j.recipe, "grbl");
    let (sin, cos) = 30f64.to_radians().sin_cos();
    let local = |x: f64, y: f64| {
        let (dx, dy) = (x - 5.0, y - 5.0);
        (dx * cos + dy * sin, -dx * sin + dy * cos)
    };
    let (mut x, mut y, mut s, mut g) = (0.0, 0.0, 0.0, 0);
    let mut bl = Vec::new();
    for line in nc.lines() {
        let wd = nc_words(line);
        let get = |c: char| wd.iter().find(|(k, _)| *k == c).map(|(_, v)| *v);
        if let Some(v) = get('G')
            && (v == 0.0 || v == 1.0)
        {
            g = v as i32;
        }
        if let Some(v) = get('S') {
            s = v;
        }
        let (nx, ny) = (get('X').unwrap_or(x), get('Y').unwrap_or(y));
        if (nx, ny) != (x, y) && g == 1 && s > 0.0 {
            let ((u0, v0), (u1, v1)) = (local(x, y), local(nx, ny));
            // Along a row: the same v at both ends, up to the NC's rounding.
            assert!((v0 - v1).abs() < 2e-3, "{line}: not along a turned row");
            // Snap v to its row's centre line for `pixels`, after checking it is on it.
            let r = (f64::from(h) - 0.5 - v0 / 0.1).round();
            let vr = (f64::from(h) - 0.5 - r) * 0.1;
            assert!((v0 - vr).abs() < 2e-3, "{line}: v {v0} off row {r}");
            bl.push(Block {
                y: vr,
                x0: u0,
                x1: u1,
                pct: s / 10.0,
            });
        }
        (x, y) = (nx, ny);
    }
    let px = pixels(&bl, w, h, 0.1, 0.0);
    let mut lit = 0;
    for (i, &l) in luma.iter().enumerate() {
        let shade = (255.0 * tone(l, 1.0, false)).round();
        let want = 40.0 * shade / 255.0;
        let got = px[i].unwrap_or(0.0);
        assert!(
            (got - want).abs() <= 5e-5,
            "pixel {i}: {got} %, expected {want} %"
        );
        lit += usize::from(want > 0.0);
    }
    assert!(lit >= 4 * 17, "{lit} lit pixels");
}

/// `lase plot`: a ramp image's pixel runs are drawn grey by power — each run's line has the
/// opacity power / the scan's power, so the strokes darken left to right as the ramp does.
#[test]
fn the_plot_shades_image_runs_by_power() {
    let (w, h) = (40, 6);
    let luma = ramp(w, h);
    let j = job(w, h, &luma, "width 4 mm, speed 50 mm/s, power 40 W");
    let svg_path = j.recipe.with_extension("svg");
    let (code, _, err) = lase(&[
        "plot",
        j.recipe.to_str().unwrap(),
        "-o",
        svg_path.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let attr = |l: &str, k: &str| -> f64 {
        let at = l.find(&format!(" {k}=\"")).unwrap() + k.len() + 3;
        l[at..at + l[at..].find('"').unwrap()].parse().unwrap()
    };
    // (x centre on the page, opacity, power) of every drawn run, row by row.
    let runs: Vec<(f64, f64, f64)> = svg
        .lines()
        .filter(|l| l.contains(r#"class="pixel""#))
        .map(|l| {
            (
                0.5 * (attr(l, "x1") + attr(l, "x2")),
                attr(l, "stroke-opacity"),
                attr(l, "data-power"),
            )
        })
        .collect();
    // One line per lit pixel of the 5 scanned rows: every ramp pixel is its own shade.
    assert_eq!(runs.len(), 5 * (w as usize - 7), "{}", runs.len());
    for &(_, op, p) in &runs {
        assert!((op - p / 40.0).abs() <= 5e-4, "opacity {op} for {p} W");
    }
    // Darker where the power is higher: sorted by x, opacity never falls, and it spans the
    // ramp from near white to black.
    let mut by_x = runs.clone();
    by_x.sort_by(|a, b| a.0.total_cmp(&b.0));
    for pair in by_x.windows(2) {
        if pair[1].0 - pair[0].0 > 1e-6 {
            assert!(pair[1].1 >= pair[0].1, "{pair:?}");
        }
    }
    assert!(
        by_x[0].1 < 0.05 && by_x[by_x.len() - 1].1 > 0.99,
        "{by_x:?}"
    );
}
