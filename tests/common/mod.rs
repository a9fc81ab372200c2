//! Shared helpers for the integration tests: golden files and running the binary.

#![allow(dead_code)]

#[path = "rs274.rs"]
mod rs274;

pub mod cases;
pub mod linuxcnc;

use std::path::{Path, PathBuf};
use std::process::Command;

pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Compares `actual` with the golden file at `path`. A missing golden is written (and the test
/// passes); `UPDATE_GOLDEN=1` rewrites them all; a difference fails with both texts' first
/// differing line.
pub fn golden(path: &Path, actual: &str) {
    let update = std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v == "1");
    match std::fs::read_to_string(path) {
        Ok(expected) if !update => {
            if expected != actual {
                let (n, (e, a)) = expected
                    .lines()
                    .chain(std::iter::repeat("<end>"))
                    .zip(actual.lines().chain(std::iter::repeat("<end>")))
                    .enumerate()
                    .find(|(_, (e, a))| e != a)
                    .unwrap_or((0, ("", "")));
                panic!(
                    "golden file {} differs at line {}:\n  expected: {e}\n  actual:   {a}\n\
                     (run with UPDATE_GOLDEN=1 to accept the new output)\n--- actual ---\n{actual}",
                    path.display(),
                    n + 1
                );
            }
        }
        _ => {
            std::fs::create_dir_all(path.parent().unwrap()).unwrap();
            std::fs::write(path, actual).unwrap();
        }
    }
}

/// Runs `lase ARGS` from the repository root; returns (exit code, stdout, stderr).
pub fn lase(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lase"))
        .args(args)
        .current_dir(root())
        .env("NO_COLOR", "1")
        .output()
        .expect("the lase binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The `.lase` files of a folder, sorted.
/// A path below the repository root, relative to it (as `lase` is run from the root).
/// `lase emit RECIPE --dialect DIALECT`, which must succeed: the NC text.
pub fn emit_ok(recipe: &Path, dialect: &str) -> String {
    let (code, out, err) = lase(&["emit", recipe.to_str().unwrap(), "--dialect", dialect]);
    assert_eq!(code, 0, "{err}");
    out
}

/// Writes `text` to `dir/name` and returns the path (recipes and data files for a test).
pub fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

pub fn relative(p: &Path) -> String {
    p.strip_prefix(root())
        .unwrap_or(p)
        .to_string_lossy()
        .into_owned()
}

pub fn lase_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "lase"))
        .collect();
    v.sort();
    v
}

/// Parses an NC file's words per line, ignoring comments: [(letter, value)].
pub fn nc_words(line: &str) -> Vec<(char, f64)> {
    let mut out = Vec::new();
    let mut s = String::new();
    let mut in_comment = false;
    for c in line.chars() {
        match c {
            '(' => in_comment = true,
            ')' => in_comment = false,
            c if !in_comment => s.push(c),
            _ => {}
        }
    }
    let s = s.split(';').next().unwrap_or("").replace(' ', "");
    let mut chars = s.chars().peekable();
    while let Some(c) = chars.next() {
        if c.is_ascii_alphabetic() {
            let mut num = String::new();
            while let Some(&d) = chars.peek() {
                if d.is_ascii_digit() || d == '.' || d == '-' || d == '+' {
                    num.push(d);
                    chars.next();
                } else {
                    break;
                }
            }
            if let Ok(v) = num.parse() {
                out.push((c, v));
            }
        }
    }
    out
}

#[allow(unused_imports)]
pub use rs274::rs274_g;

/// A LinuxCNC program's lines (text, op tag) with each beam switch the writer carried along
/// the path (`emit::writer::lead`: LinuxCNC's synchronized outputs lead its joints by 1.5
/// servo periods, so the switch is written that far past the beam's edge, cutting a straight
/// block there) put back where the beam lights: before the cut block, whose two parts are one
/// block again. Tests of what the beam marks read the program through this; the lead itself
/// is measured in `runtime/tests/switch_lead.rs` and on the real LinuxCNC.
pub fn uncarried(lines: Vec<(String, Option<u32>)>) -> Vec<(String, Option<u32>)> {
    let is_switch = |t: &str| {
        let t = t.trim();
        t == "M62 P0" || t == "M63 P0" || t.starts_with("M67 ")
    };
    let words = |t: &str| -> Vec<String> {
        t.split(['(', ';'])
            .next()
            .unwrap_or("")
            .split_whitespace()
            .map(str::to_string)
            .collect()
    };
    let axis = |w: &[String], c: char| {
        w.iter()
            .find(|x| x.starts_with(c))
            .and_then(|x| x[1..].parse::<f64>().ok())
    };
    let is_motion = |w: &[String]| {
        w.iter().any(|x| x.starts_with(['X', 'Y', 'Z']))
            && !w.iter().any(|x| {
                x.starts_with('M') || x == "G4" || x.starts_with("G2") || x.starts_with("G3")
            })
    };
    let mut out: Vec<(String, Option<u32>)> = Vec::with_capacity(lines.len());
    // Where each line of `out` leaves the spot (x, y, z), and whether the last is G0/G1 linear.
    let mut pos = [0.0f64; 3];
    let mut before_last = [0.0f64; 3];
    let mut last_motion: Option<usize> = None;
    // The feed in force, mm/min: a cut's first part lasts at most 2.2 servo periods (1 ms) of
    // it (`lead::cut_at`), which tells it from a block that just runs on in line.
    let mut feed = 0.0f64;
    let mut i = 0;
    while i < lines.len() {
        let (t, tag) = &lines[i];
        let w = words(t);
        if let Some(f) = axis(&w, 'F') {
            feed = f;
        }
        if is_switch(t) && last_motion == Some(out.len() - 1) {
            // The switch group and the motion line after it.
            let mut j = i;
            while j < lines.len() && is_switch(&lines[j].0) {
                j += 1;
            }
            // A beam switch among them (a power step alone is not carried).
            let beam = lines[i..j]
                .iter()
                .any(|(s, _)| matches!(s.trim(), "M62 P0" | "M63 P0"));
            if let Some((bt, btag)) = lines.get(j).filter(|_| beam) {
                let bw = words(bt);
                let end = [
                    axis(&bw, 'X').unwrap_or(pos[0]),
                    axis(&bw, 'Y').unwrap_or(pos[1]),
                    axis(&bw, 'Z').unwrap_or(pos[2]),
                ];
                let (a, b) = (
                    [
                        pos[0] - before_last[0],
                        pos[1] - before_last[1],
                        pos[2] - before_last[2],
                    ],
                    [end[0] - pos[0], end[1] - pos[1], end[2] - pos[2]],
                );
                let cross = (a[1] * b[2] - a[2] * b[1]).abs()
                    + (a[2] * b[0] - a[0] * b[2]).abs()
                    + (a[0] * b[1] - a[1] * b[0]).abs();
                let (la, lb) = (
                    a.iter().map(|v| v * v).sum::<f64>().sqrt(),
                    b.iter().map(|v| v * v).sum::<f64>().sqrt(),
                );
                let g_change = bw.iter().any(|x| x.starts_with('G'));
                let short = la <= 2.2e-3 * feed.max(axis(&bw, 'F').unwrap_or(0.0)) / 60.0 + 2e-4;
                // With tags: both parts of a cut block carry the same op's.
                let a_tag = out[out.len() - 1].1;
                let same_op = a_tag.is_none() || a_tag == *btag;
                if is_motion(&bw)
                    && !g_change
                    && short
                    && same_op
                    && la > 0.0
                    && lb > 0.0
                    && cross < 2e-4 * (la + lb)
                    && a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() > 0.0
                {
                    // Cut: the switches go before the first part, the parts join again.
                    let (at, atag) = out.pop().unwrap();
                    let mut merged = words(&at);
                    for x in &bw {
                        let c = x.chars().next().unwrap();
                        match merged.iter_mut().find(|m| m.starts_with(c)) {
                            Some(m) => *m = x.clone(),
                            None => merged.push(x.clone()),
                        }
                    }
                    for s in &lines[i..j] {
                        out.push(s.clone());
                    }
                    out.push((merged.join(" "), btag.or(atag)));
                    let _ = tag;
                    pos = end;
                    last_motion = Some(out.len() - 1);
                    i = j + 1;
                    continue;
                }
            }
        }
        out.push((t.clone(), *tag));
        if is_motion(&w) {
            before_last = pos;
            pos = [
                axis(&w, 'X').unwrap_or(pos[0]),
                axis(&w, 'Y').unwrap_or(pos[1]),
                axis(&w, 'Z').unwrap_or(pos[2]),
            ];
            last_motion = Some(out.len() - 1);
        } else if !is_switch(t) {
            last_motion = None;
            if w.iter().any(|x| x.starts_with(['X', 'Y', 'Z'])) {
                // An arc or other move: where it ends.
                pos = [
                    axis(&w, 'X').unwrap_or(pos[0]),
                    axis(&w, 'Y').unwrap_or(pos[1]),
                    axis(&w, 'Z').unwrap_or(pos[2]),
                ];
            }
        }
        i += 1;
    }
    out
}

/// [`uncarried`] of a program's text.
pub fn uncarried_text(nc: &str) -> String {
    let lines = uncarried(nc.lines().map(|l| (l.to_string(), None)).collect());
    let mut s: String = lines.into_iter().map(|(t, _)| t + "\n").collect();
    if !nc.ends_with('\n') {
        s.pop();
    }
    s
}
