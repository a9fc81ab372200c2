//! The code map's invariants, checked on the sources so that ARCHITECTURE.md cannot drift
//! from the code:
//! - the runtime's modules use only modules of their own stage or an earlier one, in the
//!   pipeline order that ARCHITECTURE.md states (its `**Pipeline order:**` line);
//! - no source file is longer than 1 000 lines;
//! - NC text is written only by `emit` (no NC block literal elsewhere in the runtime but the
//!   simulator, which reads NC, match patterns that read a post's words, and tests);
//! - the language crate does no IO.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The source of a file without its `#[cfg(test)]` module (the last item, by convention).
fn without_tests(text: &str) -> &str {
    match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    }
}

/// The stages of the runtime, in order, from ARCHITECTURE.md: the line that starts with
/// `**Pipeline order:**` names each stage's modules in backticks, stages separated by `→`.
fn stages() -> Vec<Vec<String>> {
    let doc = std::fs::read_to_string(common::root().join("ARCHITECTURE.md")).unwrap();
    let line = doc
        .lines()
        .find(|l| l.starts_with("**Pipeline order:**"))
        .expect("ARCHITECTURE.md states the pipeline order on a `**Pipeline order:**` line");
    line.trim_start_matches("**Pipeline order:**")
        .split('→')
        .map(|stage| {
            stage
                .split('`')
                .skip(1)
                .step_by(2)
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .filter(|s| !s.is_empty())
        .collect()
}

/// The runtime module a file belongs to (`emit/writer.rs` → `emit`, `lib.rs` → none).
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel
        .components()
        .next()?
        .as_os_str()
        .to_string_lossy()
        .into_owned();
    let name = first.trim_end_matches(".rs").to_string();
    (name != "lib").then_some(name)
}

#[test]
fn runtime_modules_use_only_earlier_stages() {
    let stages = stages();
    let stage_of: BTreeMap<&str, usize> = stages
        .iter()
        .enumerate()
        .flat_map(|(i, s)| s.iter().map(move |m| (m.as_str(), i)))
        .collect();
    let src = common::root().join("runtime/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut wrong = Vec::new();
    for f in &files {
        let Some(module) = module_of(&src, f) else {
            continue;
        };
        let Some(&own) = stage_of.get(module.as_str()) else {
            wrong.push(format!(
                "{}: module `{module}` is not in ARCHITECTURE.md's pipeline order",
                common::relative(f)
            ));
            continue;
        };
        let text = std::fs::read_to_string(f).unwrap();
        for (n, line) in without_tests(&text).lines().enumerate() {
            for (i, _) in line.match_indices("crate::") {
                let used: String = line[i + 7..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if used == module || used.is_empty() {
                    continue;
                }
                match stage_of.get(used.as_str()) {
                    Some(&s) if s <= own => {}
                    Some(_) => wrong.push(format!(
                        "{}:{}: `{module}` uses `{used}`, a later stage",
                        common::relative(f),
                        n + 1
                    )),
                    None => {}
                }
            }
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn no_source_file_is_longer_than_1000_lines() {
    let mut files = Vec::new();
    for dir in ["lang/src", "runtime/src", "stdlib/src", "src"] {
        rust_files(&common::root().join(dir), &mut files);
    }
    let long: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let n = std::fs::read_to_string(f).unwrap().lines().count();
            (n > 1000).then(|| format!("{}: {n} lines", common::relative(f)))
        })
        .collect();
    assert!(
        long.is_empty(),
        "split these along their seams:\n{}",
        long.join("\n")
    );
}

/// One NC word, or a format placeholder standing for a value: `G1`, `X-1.5`, `F{}`, `{}`.
fn nc_word(w: &str) -> bool {
    let placeholder = |t: &str| t.starts_with('{') && t.ends_with('}');
    if placeholder(w) {
        return true;
    }
    let mut c = w.chars();
    let Some(letter) = c.next() else {
        return false;
    };
    let value = c.as_str();
    "GMXYZABCIJKFSPQRTLN".contains(letter)
        && !value.is_empty()
        && (placeholder(value)
            || value
                .chars()
                .all(|c| c.is_ascii_digit() || c == '.' || c == '-'))
}

/// A string literal that is an NC block: a G or M word first, then only NC words (an error
/// message that names a G-code is prose, not a block).
fn nc_literal(line: &str) -> Option<&str> {
    let mut rest = line;
    while let Some(i) = rest.find('"') {
        let lit = &rest[i + 1..];
        let end = lit.find('"').unwrap_or(lit.len());
        let body = &lit[..end];
        let b = body.as_bytes();
        // A literal in a match pattern (`"M3" | "M03" => …`) reads a word; it writes none.
        let after = lit[(end + 1).min(lit.len())..].trim_start();
        let pattern = after.starts_with('|') || after.starts_with("=>");
        if b.len() >= 2
            && matches!(b[0], b'G' | b'M')
            && b[1].is_ascii_digit()
            && body.split_whitespace().all(nc_word)
            && !pattern
        {
            return Some(body);
        }
        rest = &lit[(end + 1).min(lit.len())..];
    }
    None
}

#[test]
fn the_nc_text_heuristic_tells_blocks_from_prose() {
    assert!(nc_literal(r#"out.push("M5".to_string())"#).is_some());
    assert!(nc_literal(r#"format!("G0 {}", axes)"#).is_some());
    assert!(nc_literal(r#"let s = "G21 G90 G94";"#).is_some());
    assert!(nc_literal(r#"30 => "G53 is only allowed with G0 and G1 motion modes","#).is_none());
    assert!(nc_literal(r#"code(lase::io) "Grbl 1.1h""#).is_none());
    assert!(nc_literal(r#""M3" | "M03" => Some(false),"#).is_none());
    assert!(nc_literal(r#""M4" => Some(true),"#).is_none());
}

#[test]
fn only_emit_writes_nc_text() {
    let src = common::root().join("runtime/src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut wrong = Vec::new();
    for f in &files {
        let rel = common::relative(f);
        // emit writes NC; the simulator reads it.
        if rel.starts_with("runtime/src/emit") || rel.starts_with("runtime/src/link/sim") {
            continue;
        }
        let text = std::fs::read_to_string(f).unwrap();
        for (n, line) in without_tests(&text).lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if let Some(lit) = nc_literal(code) {
                wrong.push(format!(
                    "{rel}:{}: NC text `{}`",
                    n + 1,
                    &lit[..lit.len().min(20)]
                ));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "NC text outside emit:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn the_language_crate_does_no_io() {
    let mut files = Vec::new();
    rust_files(&common::root().join("lang/src"), &mut files);
    let mut wrong = Vec::new();
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        for (n, line) in without_tests(&text).lines().enumerate() {
            if ["std::fs", "std::net", "std::process", "File::"]
                .iter()
                .any(|io| line.contains(io))
            {
                wrong.push(format!(
                    "{}:{}: {}",
                    common::relative(f),
                    n + 1,
                    line.trim()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "IO in lang:\n{}", wrong.join("\n"));
}
