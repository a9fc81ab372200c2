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
        trial(
            "an_immediate_linuxcnc_output_where_the_plan_flies_points_at_its_post_line",
            an_immediate_linuxcnc_output_where_the_plan_flies_points_at_its_post_line,
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

/// LinuxCNC's M64/M65/M68 drain the motion queue: a post line with one where lase plans a
/// flying beam switch (lead-ins of style b) is refused at `lase emit`, pointing at the line of
/// the machine file; the same line where the plan stops there (`laser_switch_stops`) is fine.
fn an_immediate_linuxcnc_output_where_the_plan_flies_points_at_its_post_line() {
    let dir = tempfile::tempdir().unwrap();
    let stock = std::fs::read_to_string(root().join("stdlib/machines/xy_table.toml")).unwrap();
    let flying = stock.replace(
        "laser_on = [\"M67 E0 Q{pct}\", \"M62 P0\"]",
        "laser_on = [\"M67 E0 Q{pct}\", \"M64 P0\"]",
    );
    assert_ne!(flying, stock, "xy_table's LinuxCNC laser_on is M67 + M62");
    let line = flying.lines().position(|l| l.contains("M64 P0")).unwrap() + 1;
    let at_rest = flying.replace(
        "[post.linuxcnc]\n",
        "[post.linuxcnc]\nlaser_switch_stops = true\n",
    );
    for (name, toml) in [("flying", &flying), ("at_rest", &at_rest)] {
        std::fs::write(dir.path().join(format!("{name}.toml")), toml).unwrap();
        std::fs::write(
            dir.path().join(format!("{name}.lase")),
            format!(
                "machine \"{name}.toml\"\nlaser {{ power 10 W }}\n\
                 follow profile polyline [(0, 0), (20 mm, 0)] at 20 mm/s\n"
            ),
        )
        .unwrap();
    }
    let recipe = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let (code, _, err) = lase(&["emit", "--dialect", "linuxcnc", &recipe("flying.lase")]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::emit::immediate_output"), "{err}");
    assert!(err.contains(&format!("flying.toml:{line}:")), "{err}");
    assert!(
        err.contains("at 20 mm/") && err.contains("write M62 for M64"),
        "{err}"
    );
    let (code, _, err) = lase(&["emit", "--dialect", "linuxcnc", &recipe("at_rest.lase")]);
    assert_eq!(code, 0, "{err}");
}

fn a_missing_file_is_a_clean_error() {
    let (code, _, err) = lase(&["check", "tests/err/does_not_exist.lase"]);
    assert_eq!(code, 1);
    assert!(err.contains("cannot read"), "{err}");
}
