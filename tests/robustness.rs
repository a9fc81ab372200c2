//! No input, however malformed, makes lase panic: random text and mutated example recipes
//! go through parse, check, evaluation and planning, and each phase either succeeds or
//! returns diagnostics.

mod common;

use lase_runtime::compile::{self, MemFiles};
use proptest::prelude::*;
use std::sync::OnceLock;

/// The files the corpus imports and uses, beside the recipe under test (`fuzz.lase`).
fn files() -> MemFiles {
    static FILES: OnceLock<MemFiles> = OnceLock::new();
    FILES
        .get_or_init(|| {
            let read = |p: &str| std::fs::read_to_string(common::root().join(p)).unwrap();
            let mut files = MemFiles::new([
                ("lib/shapes.lase", read("tests/ok/lib/shapes.lase")),
                ("lib/plate.svg", read("tests/ok/lib/plate.svg")),
                ("rhai_cam_law.rhai", read("examples/rhai_cam_law.rhai")),
            ]);
            files.insert_bytes(
                "image_engrave.png",
                std::fs::read(common::root().join("examples/image_engrave.png")).unwrap(),
            );
            files
        })
        .clone()
}

/// Runs every phase, through the pipeline `lase` runs; returns how far it got (for the corpus
/// test's own sanity): 0 load, 1 check, 2 evaluate, 3 plan, 4 all the way.
fn pipeline(text: &str) -> usize {
    let mut files = files();
    files.insert("fuzz.lase", text);
    let mut recipe = match compile::load(&mut files, "fuzz.lase") {
        Ok(r) => r,
        Err((map, f)) => {
            // Every diagnostic's span lies inside the source map (the end of a file included).
            for d in &f.diagnostics {
                for l in d.labels().into_iter().flatten() {
                    assert!(
                        map.files().any(|id| {
                            let base = map.base(id);
                            (base..=base + map.text(id).len()).contains(&l.offset())
                        }),
                        "{d}"
                    );
                }
            }
            return 0;
        }
    };
    if compile::check(&recipe).is_err() {
        return 1;
    }
    let Ok(p) = compile::evaluate(&mut recipe, &mut files) else {
        return 2;
    };
    let Ok(job) = compile::plan(p) else {
        return 3;
    };
    let _ = lase_runtime::emit::emit_to_string(&job, lase_runtime::emit::Dialect::LinuxCnc);
    let _ = lase_runtime::report::summarize(&job);
    4
}

fn corpus() -> Vec<String> {
    let mut v: Vec<String> = common::lase_files(&common::root().join("examples"))
        .into_iter()
        .chain(common::lase_files(&common::root().join("tests/ok")))
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    v.push("machine xy_table\nlaser { power 5 W }\nfollow profile circle(center: (1 mm, 2 mm), radius: 3 mm) at 9 mm/s".into());
    v
}

/// The recipes mutated by the proptest: the corpus without the production-sized jobs (a cam
/// track, six arm sections, texture arrays). A mutated digit turns those into jobs of millions
/// of poses or spots that are valid, just slow in a debug build; their parsing and checking
/// paths are the same as the small recipes'.
fn mutation_corpus() -> Vec<String> {
    corpus()
        .into_iter()
        .filter(|s| !["cam_xwb", "arm_3r", "scan "].iter().any(|k| s.contains(k)))
        .collect()
}

#[test]
fn the_unmutated_corpus_runs_all_the_way() {
    // Imports and extension files come from `files()`.
    for (i, src) in corpus().iter().enumerate() {
        assert_eq!(
            pipeline(src),
            4,
            "corpus entry {i} did not get through:\n{src}"
        );
    }
}

/// A function that calls itself without end, and expressions nested a hundred deep, end in a
/// diagnostic (or a result) on a small thread stack too: the evaluator's depth limit is reached
/// long before the stack, however large a debug build's frames are. (Found by the mutation
/// test below: a mutated recipe overflowed the test thread's stack.)
#[test]
fn deep_recursion_is_a_diagnostic_on_a_small_stack() {
    let recursive = "machine xy_table\nfn f(x: length) {\n  f(x)\n}\nf(1 mm)\n".to_string();
    let nested = |n: usize| {
        format!(
            "machine xy_table\nlet y = {}1 mm{}\nmove to (y, y) at 5 mm/s\n",
            "(".repeat(n),
            ")".repeat(n)
        )
    };
    // 120 levels parse, check, evaluate and plan; 300 are refused by the parser's nesting
    // limit (a diagnostic, not pest running out of stack).
    // Operator chains build trees as deep as they are long, with no bracket: at the parser's
    // expression depth limit they still get all the way (the tree is cloned, checked,
    // evaluated and dropped); past it they are refused. Once 30 000 overflowed the stack.
    let depth = lase_lang::parser::MAX_EXPR_DEPTH;
    let chain = |n: usize, op: &str, leaf: &str| {
        format!(
            "machine xy_table\nlet y = {}{leaf}\nmove to (y, y) at 5 mm/s\n",
            op.repeat(n)
        )
    };
    let sum = |n: usize| {
        format!(
            "machine xy_table\nlet y = 0 mm{}\nmove to (y, y) at 5 mm/s\n",
            " + 0.01 mm".repeat(n)
        )
    };
    let cases = [
        (recursive, 2),
        (nested(120), 4),
        (nested(300), 0),
        (sum(depth - 1), 4),
        (chain(depth - 1, "-", "1 mm"), 4),
        (sum(30_000), 0),
        (chain(30_000, "-", "1 mm"), 0),
        (chain(30_000, "not ", "true"), 0),
    ];
    for (src, want) in cases {
        let got = std::thread::Builder::new()
            .stack_size(512 * 1024)
            .spawn(move || pipeline(&src))
            .unwrap()
            .join()
            .expect("no stack overflow, no panic");
        assert_eq!(got, want);
    }
}

const TOKENS: &[&str] = &[
    "(", ")", "[", "]", "{", "}", ",", ";", ":", "..", "=", "==", "+", "-", "*", "/", "%", "mm",
    "mm/s", "deg", "0", "1", "-1", "1e308", "\"", "let", "fn", "for", "in", "if", "else", "follow",
    "move", "to", "rapid", "at", "profile", "circle", "offset", "laser", "pulse", "limits",
    "machine", "xy_table", "return", "\n", " ", "µ", "°", "1e-300",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn random_text_never_panics(s in "\\PC{0,120}") {
        pipeline(&s);
    }

    #[test]
    fn random_token_soup_never_panics(toks in proptest::collection::vec(0..TOKENS.len(), 0..60)) {
        let s: Vec<&str> = toks.iter().map(|&i| TOKENS[i]).collect();
        pipeline(&s.join(" "));
    }

    #[test]
    fn mutated_recipes_never_panic(
        which in 0usize..16,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), 0usize..3, 0..TOKENS.len()), 1..5),
    ) {
        let corpus = mutation_corpus();
        let mut src = corpus[which % corpus.len()].clone();
        for (at, kind, tok) in edits {
            let len = src.len();
            let mut pos = at.index(len + 1);
            while !src.is_char_boundary(pos) {
                pos -= 1;
            }
            match kind {
                0 => src.insert_str(pos, TOKENS[tok]),
                1 => {
                    let mut end = (pos + 1 + tok % 8).min(len);
                    while !src.is_char_boundary(end) {
                        end += 1;
                    }
                    src.replace_range(pos..end, "");
                }
                _ => {
                    let mut end = (pos + 3).min(len);
                    while !src.is_char_boundary(end) {
                        end += 1;
                    }
                    src.replace_range(pos..end, TOKENS[tok]);
                }
            }
        }
        pipeline(&src);
    }
}
