//! Parser tests: statements, precedence and spans, and the limits on input depth.

use super::*;

fn parse(src: &str) -> Module {
    parse_recipe(src, crate::FileId(0), 0).unwrap_or_else(|e| panic!("{e:?}"))
}

#[test]
fn sketch_from_the_brief_parses() {
    let m = parse(
        "machine xy_table
         limits { x: v 200 mm/s, a 2 m/s^2; y: v 200 mm/s, a 2 m/s^2 }
         let pitch = 0.2 mm
         let part = profile polyline [(0, 0), (40 mm, 0), (40 mm, 20 mm), (0, 20 mm)] closed
         let path = offset(part, 1.5 mm)
         laser { power 40 W, spot 50 um }
         follow path at 20 mm/s
         for i in 0..3 { move to (0, i * pitch) rapid }",
    );
    assert_eq!(m.stmts.len(), 8);
    match &m.stmts[1].kind {
        StmtKind::Limits(g) => {
            assert_eq!(g.len(), 2);
            assert_eq!(g[0].axis.name, "x");
            assert_eq!(g[0].settings[1].key.name, "a");
        }
        k => panic!("{k:?}"),
    }
    match &m.stmts[3].kind {
        StmtKind::Let { value, .. } => match &value.kind {
            ExprKind::Profile { kind, args, flags } => {
                assert_eq!(kind.name, "polyline");
                assert_eq!(args.len(), 1);
                assert_eq!(flags[0].name, "closed");
            }
            k => panic!("{k:?}"),
        },
        k => panic!("{k:?}"),
    }
}

#[test]
fn a_unit_must_share_the_line_with_its_number() {
    let m = parse("let n = 3\nlaser { power 40 W }");
    assert_eq!(m.stmts.len(), 2);
    match &m.stmts[0].kind {
        StmtKind::Let { value, .. } => {
            assert_eq!(
                value.kind,
                ExprKind::Number {
                    value: 3.0,
                    unit: None
                }
            )
        }
        k => panic!("{k:?}"),
    }
}

#[test]
fn precedence_and_spans() {
    let m = parse("let x = 1 mm + 2 mm * 3");
    let StmtKind::Let { value, .. } = &m.stmts[0].kind else {
        panic!()
    };
    let ExprKind::Binary { op, rhs, .. } = &value.kind else {
        panic!()
    };
    assert_eq!(*op, BinOp::Add);
    assert_eq!((rhs.span.start, rhs.span.end), (15, 23));
}

#[test]
fn brackets_nested_too_deep_are_refused_at_the_first_one() {
    let n = MAX_NESTING as usize;
    let ok = format!("let y = {}1{}", "(".repeat(n), ")".repeat(n));
    assert!(parse_recipe(&ok, crate::FileId(0), 0).is_ok());
    let deep = format!("let y = {}1{}", "(".repeat(n + 5), ")".repeat(n + 5));
    let e = parse_recipe(&deep, crate::FileId(0), 10).unwrap_err();
    let ParseError::Syntax { message, span, .. } = e else {
        panic!()
    };
    assert!(message.contains("nest more than 128"), "{message}");
    assert_eq!(span.start as usize, 10 + 8 + n);
    // Brackets in strings and comments do not count.
    let quoted = format!("let s = \"{}\" // {}", "(".repeat(n + 1), "[".repeat(n + 1));
    assert!(brackets(&quoted).too_deep.is_none());
}

#[test]
fn syntax_errors_name_what_was_expected() {
    let e = parse_recipe("let = 3", crate::FileId(0), 0).unwrap_err();
    let ParseError::Syntax { message, span, .. } = e else {
        panic!()
    };
    assert!(message.contains("expected a name"), "{message}");
    assert_eq!(span.start, 4);
}

#[test]
fn the_pulse_block_takes_interval_as_a_key() {
    let m = parse("pulse { interval 50 us, width 100 ns, energy 1 mJ }\npulse interval 2 mm");
    let keys = |s: &Stmt| match &s.kind {
        StmtKind::Pulse(PulseStmt::Settings(set)) => {
            set.iter().map(|s| s.key.name.clone()).collect::<Vec<_>>()
        }
        k => panic!("{k:?}"),
    };
    assert_eq!(keys(&m.stmts[0]), ["interval", "width", "energy"]);
    assert_eq!(keys(&m.stmts[1]), ["interval"]);
}

#[test]
fn a_byte_order_mark_is_skipped_and_spans_stay_true() {
    let e = parse_recipe("\u{feff}let = 3", crate::FileId(0), 0).unwrap_err();
    assert_eq!(e.span().start, 3 + 4);
    assert_eq!(parse("\u{feff}machine xy_table").stmts.len(), 1);
}

#[test]
fn expressions_deeper_than_the_limit_are_refused_at_the_operator() {
    let ok = format!("let a = 1{}", " + 1".repeat(MAX_EXPR_DEPTH - 1));
    assert!(parse_recipe(&ok, crate::FileId(0), 0).is_ok());
    let deep = format!("let a = 1{}", " + 1".repeat(MAX_EXPR_DEPTH));
    let e = parse_recipe(&deep, crate::FileId(0), 0).unwrap_err();
    assert!(matches!(e, ParseError::TooDeep { limit: 500, .. }), "{e:?}");
    // The last `+`: `let a = 1` then 4 bytes per ` + 1`.
    assert_eq!(e.span().start as usize, 9 + (MAX_EXPR_DEPTH - 1) * 4 + 1);
    // Field and index suffixes count too, brackets or not.
    for suffix in [".x", "[0]"] {
        let chain = format!("let a = p{}", suffix.repeat(MAX_EXPR_DEPTH + 5));
        let e = parse_recipe(&chain, crate::FileId(0), 0).unwrap_err();
        assert!(matches!(e, ParseError::TooDeep { .. }), "{e:?}");
    }
}

#[test]
fn incomplete_input_is_detected() {
    assert!(is_incomplete("fn f() {"));
    assert!(is_incomplete("let a = [1,"));
    assert!(!is_incomplete("let a = [1, 2] // [ "));
}

#[test]
fn a_list_comprehension_parses_into_item_variable_source_and_condition() {
    let m = parse(
        "let xs = [x * 2 mm for x in 0..=4 if x % 2 == 0]\nlet ys = [y for y in xs]\nlet zs = [1, 2,]",
    );
    let StmtKind::Let { value, .. } = &m.stmts[0].kind else {
        panic!()
    };
    let ExprKind::Comprehension {
        item,
        var,
        iter,
        cond,
    } = &value.kind
    else {
        panic!("{:?}", value.kind)
    };
    assert_eq!(var.name, "x");
    assert!(matches!(item.kind, ExprKind::Binary { op: BinOp::Mul, .. }));
    assert!(matches!(
        **iter,
        ForIter::Range {
            inclusive: true,
            ..
        }
    ));
    assert!(matches!(
        cond.as_deref().map(|c| &c.kind),
        Some(ExprKind::Binary { op: BinOp::Eq, .. })
    ));
    let StmtKind::Let { value, .. } = &m.stmts[1].kind else {
        panic!()
    };
    assert!(matches!(
        &value.kind,
        ExprKind::Comprehension { cond: None, .. }
    ));
    let StmtKind::Let { value, .. } = &m.stmts[2].kind else {
        panic!()
    };
    assert!(matches!(&value.kind, ExprKind::List(items) if items.len() == 2));
}

#[test]
fn deeply_nested_lists_parse_without_backtracking() {
    // The first item is parsed once whether a comprehension's `for` or a `,` follows: 100
    // nested lists would take 2^100 attempts (a hang) if either alternative re-parsed it.
    let src = format!("let x = {}1{}", "[".repeat(100), "]".repeat(100));
    let m = parse(&src);
    let StmtKind::Let { value, .. } = &m.stmts[0].kind else {
        panic!()
    };
    let mut depth = 0;
    let mut e = value;
    while let ExprKind::List(items) = &e.kind {
        depth += 1;
        e = &items[0];
    }
    assert_eq!(depth, 100);
}
