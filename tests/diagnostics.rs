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
            "long_operator_chains_are_refused_at_the_operator_too_deep",
            long_operator_chains_are_refused_at_the_operator_too_deep,
        ),
        trial(
            "a_recipe_over_the_size_limit_is_refused_before_parsing",
            a_recipe_over_the_size_limit_is_refused_before_parsing,
        ),
        trial(
            "a_byte_order_mark_is_accepted_in_recipes_imports_and_machine_files",
            a_byte_order_mark_is_accepted_in_recipes_imports_and_machine_files,
        ),
        trial(
            "thousands_of_errors_show_the_first_fifty_and_count_the_rest",
            thousands_of_errors_show_the_first_fifty_and_count_the_rest,
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

/// A scratch file for generated recipes, under cargo's per-test-target directory.
fn scratch(name: &str, bytes: &[u8]) -> String {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("diagnostics");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path.to_string_lossy().into_owned()
}

/// `[file:line:col]` of the first report.
fn first_location(stderr: &str) -> String {
    let rest = stderr
        .split("╭─[")
        .nth(1)
        .unwrap_or_else(|| panic!("{stderr}"));
    let loc = &rest[..rest.find(']').unwrap()];
    let mut parts = loc.rsplitn(3, ':');
    let col = parts.next().unwrap();
    let line = parts.next().unwrap();
    format!("{line}:{col}")
}

/// A million-point polyline written out in a recipe (27 MB) took 50 s and 2.9 GB to parse
/// before anything could refuse it; a recipe over `MAX_SOURCE_BYTES` (4 MiB) is refused from
/// its length, pointing at where it passes the limit, and so is an import of one.
fn a_recipe_over_the_size_limit_is_refused_before_parsing() {
    let limit = lase_lang::parser::MAX_SOURCE_BYTES;
    let point = "(12.3456 mm, 65.4321 mm), ";
    let n = limit / point.len() + 10;
    let text = format!(
        "machine xy_table\nlet p = profile polyline [{}(0, 0)]\n",
        point.repeat(n)
    );
    assert!(text.len() > limit);
    let path = scratch("huge.lase", text.as_bytes());
    let (code, _, err) = lase(&["check", &path]);
    assert_eq!(code, 1, "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("lase::parse::too_large"), "{err}");
    assert!(err.contains("more than the 4 MiB a recipe may be"), "{err}");
    // The label sits on the first byte past the limit: line 2 (all on one line), its column.
    let col = limit - "machine xy_table\n".len() + 1;
    assert_eq!(first_location(&err), format!("2:{col}"), "{err}");
    assert!(err.lines().all(|l| l.chars().count() < 200), "{err}");
    // An import of such a file is refused the same way, at the file's own span.
    let dir = std::path::Path::new(&path).parent().unwrap();
    std::fs::write(
        dir.join("imports_huge.lase"),
        "machine xy_table\nimport \"huge.lase\"\n",
    )
    .unwrap();
    let (code, _, err) = lase(&["check", &dir.join("imports_huge.lase").to_string_lossy()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::parse::too_large"), "{err}");
}

/// 30 000 chained `+`, unary `-` or `not` once overflowed the stack (exit 134) while the tree
/// was cloned or dropped; now the parser refuses the operator that makes the expression deeper
/// than `MAX_EXPR_DEPTH` (500), on one long line as on many short ones.
fn long_operator_chains_are_refused_at_the_operator_too_deep() {
    let limit = lase_lang::parser::MAX_EXPR_DEPTH;
    let prefix = "machine xy_table\nlet a = ";
    let cases = [
        // The 500th `+` builds the 501st level (the first operand is level one).
        (" + 1 mm".repeat(30_000), "1 mm", 4 + (limit - 1) * 7 + 2),
        ("-".repeat(30_000), "1 mm", 30_000 - limit + 1),
        ("not ".repeat(30_000), "true", (30_000 - limit) * 4 + 1),
    ];
    for (i, (chain, leaf, col)) in cases.into_iter().enumerate() {
        let text = if i == 0 {
            format!("{prefix}{leaf}{chain}\n")
        } else {
            format!("{prefix}{chain}{leaf}\n")
        };
        let path = scratch(&format!("chain{i}.lase"), text.as_bytes());
        let (code, _, err) = lase(&["check", &path]);
        assert_eq!(code, 1, "{err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(err.contains("lase::parse::too_deep"), "{err}");
        assert!(err.contains("nests more than 500 operators deep"), "{err}");
        // The column of the operator (plus `let a = `), and the long line shown only in part.
        assert_eq!(first_location(&err), format!("2:{}", col + 8), "{err}");
        assert!(err.lines().all(|l| l.chars().count() < 200), "{err}");
    }
    // One level less is a valid recipe.
    let ok = format!("{prefix}1 mm{}\n", " + 1 mm".repeat(limit - 1));
    let (code, out, err) = lase(&["check", &scratch("chain_ok.lase", ok.as_bytes())]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("ok"), "{out}");
}

/// Windows editors start files with a UTF-8 byte-order mark; it once was a syntax error at 1:1.
fn a_byte_order_mark_is_accepted_in_recipes_imports_and_machine_files() {
    const BOM: &str = "\u{feff}";
    let machine = std::fs::read_to_string(root().join("stdlib/machines/xy_table.toml")).unwrap();
    scratch("bom_machine.toml", format!("{BOM}{machine}").as_bytes());
    scratch("bom_lib.lase", format!("{BOM}let q = 2 mm\n").as_bytes());
    let main = scratch(
        "bom_main.lase",
        format!(
            "{BOM}machine \"bom_machine.toml\"\nimport \"bom_lib.lase\"\nmove to (q, q) rapid\n"
        )
        .as_bytes(),
    );
    let (code, out, err) = lase(&["check", &main]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("ok — 1 ops"), "{out}");
    // An error after a mark still points at its line and column.
    let bad = scratch(
        "bom_bad.lase",
        format!("{BOM}machine xy_table\nlet = 3\n").as_bytes(),
    );
    let (code, _, err) = lase(&["check", &bad]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("lase::parse::syntax"), "{err}");
    assert_eq!(first_location(&err), "2:5", "{err}");
}

/// 20 000 unit errors: all are found and counted, the first 50 rendered (rendering all took
/// quadratic time: each locates its line from the start of the file).
fn thousands_of_errors_show_the_first_fifty_and_count_the_rest() {
    let mut text = String::from("machine xy_table\n");
    for i in 0..20_000 {
        text.push_str(&format!("let a{i} = 1 mm + 1 s\n"));
    }
    let (code, _, err) = lase(&["check", &scratch("many_errors.lase", text.as_bytes())]);
    assert_eq!(code, 1);
    assert!(!err.contains("panicked"), "{err}");
    let rendered = err
        .lines()
        .filter(|l| l.trim() == "lase::check::unit_mismatch")
        .count();
    assert_eq!(rendered, 50);
    assert_eq!(first_location(&err), "2:10");
    assert!(
        err.contains("… and 19950 more errors not shown (only the first 50 are)"),
        "{err}"
    );
    assert!(err.trim_end().ends_with("20000 errors"), "{err}");
}
