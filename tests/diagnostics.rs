//! Diagnostics tests: every `tests/err/*.lase` fails `lase check` with exit code 1, reports
//! exactly the errors written inline in it (`// error: CODE` on the line where the error
//! points), and renders as in its golden `tests/err/NAME.txt` (no colour, width 80).
//!
//! One trial per bad recipe (`err::fold_over`), so `cargo test --test diagnostics fold_over`
//! runs one; see `common::cases`.

mod common;

use common::cases::{per_file, run, trial};
use common::*;
use std::path::Path;

fn main() {
    let files = lase_files(&root().join("tests/err"));
    let mut trials = vec![
        trial("ten_bad_recipes_or_more", || {
            assert!(lase_files(&root().join("tests/err")).len() >= 10)
        }),
        trial(
            "three_independent_mistakes_are_all_reported",
            three_independent_mistakes_are_all_reported,
        ),
        trial(
            "machine_file_errors_point_into_the_toml",
            machine_file_errors_point_into_the_toml,
        ),
        trial(
            "a_missing_file_is_a_clean_error",
            a_missing_file_is_a_clean_error,
        ),
    ];
    trials.extend(per_file(
        "err",
        &files,
        bad_recipe_reports_exactly_its_errors,
    ));
    run(trials)
}

/// (code, line) pairs from miette's graphical output: the code heads each report and the
/// first `╭─[file:line:col]` after it gives the line.
fn reported(stderr: &str) -> Vec<(String, usize)> {
    let mut out = Vec::new();
    let mut code: Option<String> = None;
    for l in stderr.lines() {
        let t = l.trim();
        if t.starts_with("lase::") {
            if let Some(c) = code.take() {
                out.push((c, 0));
            }
            code = Some(t.split_whitespace().next().unwrap().to_string());
        } else if let Some(rest) = t.split("╭─[").nth(1)
            && let Some(c) = code.take()
        {
            let loc = rest.trim_end_matches(']');
            let line: usize = loc
                .rsplit(':')
                .nth(1)
                .and_then(|n| n.parse().ok())
                .unwrap_or(0);
            out.push((c, line));
        }
    }
    if let Some(c) = code {
        out.push((c, 0));
    }
    out.sort();
    out
}

fn expected(src: &str) -> Vec<(String, usize)> {
    let mut v: Vec<(String, usize)> = src
        .lines()
        .enumerate()
        .filter_map(|(i, l)| {
            l.split("// error: ")
                .nth(1)
                .map(|c| (c.trim().to_string(), i + 1))
        })
        .collect();
    v.sort();
    v
}

/// The bad recipe fails `lase check` with exit code 1, reports exactly the errors written
/// inline in it, and renders as its golden `NAME.txt`.
fn bad_recipe_reports_exactly_its_errors(f: &Path) {
    let rel = relative(f);
    let (code, _out, err) = lase(&["check", &rel]);
    assert_eq!(code, 1, "{rel} must fail with exit code 1:\n{err}");
    assert!(!err.contains("panicked"), "{rel} panicked:\n{err}");
    let src = std::fs::read_to_string(f).unwrap();
    let want = expected(&src);
    if !want.is_empty() {
        assert_eq!(reported(&err), want, "{rel}: reported errors differ\n{err}");
    }
    golden(&f.with_extension("txt"), &err);
}

fn three_independent_mistakes_are_all_reported() {
    let (code, _, err) = lase(&["check", "tests/err/three_mistakes.lase"]);
    assert_eq!(code, 1);
    assert_eq!(reported(&err).len(), 3, "{err}");
    assert!(err.contains("3 errors"));
    // Both sides of the mismatch are labelled.
    assert!(
        err.contains("this is a length") && err.contains("this is a speed"),
        "{err}"
    );
    assert!(err.contains("did you mean `spot`?"), "{err}");
    assert!(err.contains("write `5 mm`"), "{err}");
}

fn machine_file_errors_point_into_the_toml() {
    let (code, _, err) = lase(&["check", "tests/err/bad_machine_file.lase"]);
    assert_eq!(code, 1);
    assert!(err.contains("bad_machine.toml:9"), "{err}");
    assert!(err.contains("unknown unit `ss`"), "{err}");
}

fn a_missing_file_is_a_clean_error() {
    let (code, _, err) = lase(&["check", "tests/err/does_not_exist.lase"]);
    assert_eq!(code, 1);
    assert!(err.contains("cannot read"), "{err}");
}
