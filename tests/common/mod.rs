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

#[path = "../../runtime/tests/common/uncarried.rs"]
mod uncarried;
#[allow(unused_imports)]
pub use uncarried::{uncarried, uncarried_text};
