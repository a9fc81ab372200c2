//! Rhai extensions: values crossing with their units, the standard library modules against
//! closed forms, and the sandbox — every runaway or forbidden extension ends in a clear
//! diagnostic, deterministically (operation and size limits, no timing).

use lase_lang::units::Dim;
use lase_lang::{CheckError, SourceMap};
use lase_runtime::compile::{self, Failure, MemFiles};
use lase_runtime::eval::{EvalError, Evaluator, Value};
use lase_runtime::ext::ExtError;
use std::f64::consts::{PI, TAU};

#[derive(Debug)]
enum Fail {
    /// Loading the recipe, its imports and its `use`s (the extension errors: `of::<ExtError>`).
    Load(Failure),
    Check(Failure),
    Eval(EvalError),
}

/// Loads, checks and evaluates `recipe` with `files` beside it, through the pipeline `lase`
/// runs; returns the evaluator (its variables hold the results) and the source map.
#[allow(clippy::result_large_err)]
fn run(recipe: &str, files: &[(&str, &str)]) -> Result<(Evaluator, SourceMap), (Fail, SourceMap)> {
    let mut files = MemFiles::new(files.iter().copied().chain([("test.lase", recipe)]));
    let mut r = compile::load(&mut files, "test.lase").map_err(|(map, f)| (Fail::Load(f), map))?;
    if let Err(f) = compile::check(&r) {
        return Err((Fail::Check(f), r.map));
    }
    match compile::run(&mut r, &mut files) {
        Ok(ev) => Ok((ev, r.map)),
        Err(e) => Err((Fail::Eval(e), r.map)),
    }
}

fn ok(recipe: &str, files: &[(&str, &str)]) -> Evaluator {
    match run(recipe, files) {
        Ok((ev, _)) => ev,
        Err((f, _)) => panic!("{f:#?}"),
    }
}

/// The value of a recipe expression after running `recipe`.
fn value(ev: &mut Evaluator, expr: &str) -> Value {
    let mut map = SourceMap::new();
    let id = map.add("expr.lase", format!("let __v = {expr}"));
    let (program, perr) = lase_lang::load(&mut map, id, &mut lase_lang::NoImports);
    assert!(perr.is_empty(), "{perr:?}");
    let lase_lang::ast::StmtKind::Let { value, .. } = &program.modules[0].stmts[0].kind else {
        unreachable!()
    };
    ev.eval_expr(value, &program, &mut map, &mut MemFiles::default())
        .unwrap_or_else(|e| panic!("{e:?}"))
}

fn num(v: &Value, dim: Dim) -> f64 {
    match v {
        Value::Num(x, d) if *d == dim => *x,
        other => panic!("expected a {dim}, got {other:?}"),
    }
}

fn points(v: &Value) -> Vec<[f64; 3]> {
    lase_runtime::ext::spots(v).unwrap_or_else(|| panic!("not a list of points: {v:?}"))
}

fn close(a: f64, b: f64, tol: f64) {
    assert!((a - b).abs() <= tol, "{a} vs {b}");
}

const LAW: &str = r#"
/// A harmonic rise as a user law.
/// lase: (theta: angle, rise: length, beta: angle) -> length
fn my_lift(theta, rise, beta) {
    if theta >= beta { return rise; }
    rise * (1.0 - cos(PI() * theta / beta)) / 2.0
}

/// lase: (base: length, rise: length) -> profile
fn my_cam(base, rise) {
    polar_profile(|th| base + rise * (1.0 - cos(th)) / 2.0, 360)
}

/// lase: (p: point, k: number) -> point
fn scaled(p, k) { p * k }

/// lase: (n: number) -> number
fn spin(n) { let i = 0; loop { i += 1; } }

/// lase: (n: number) -> number
fn deep(n) { deep(n + 1.0) }

/// lase: (n: number) -> [number]
fn giant(n) { let a = []; a.pad(50000000, n); a.len() }

/// lase: (n: number) -> string
fn long_string(n) { let s = "x"; loop { s += s; } }

/// lase: (n: number) -> number
fn nested_pushes(n) { let a = []; for i in 0..1000000 { a.push([i, [i]]); } a.len() }

/// lase: (n: number) -> number
fn reads_file(n) { open_file("/etc/passwd"); n }

/// lase: (n: number) -> number
fn wrong_result(n) { "ten" }

/// lase: (n: number) -> number
fn fails(n) { helper(n) }

fn helper(n) { throw "the input " + n + " is out of range"; }
"#;

#[test]
fn numbers_cross_in_internal_units_and_come_back_with_their_declared_dimension() {
    let mut ev = ok(
        "use \"law.rhai\"\nlet h = my_lift(90 deg, 6 mm, 180 deg)\nlet q = scaled((1 mm, 2 mm), 3)",
        &[("law.rhai", LAW)],
    );
    // 90° of a 180° harmonic rise of 6 mm: half the lift; the angle arrived in radians.
    close(num(&value(&mut ev, "h"), Dim::LENGTH), 3.0, 1e-12);
    match value(&mut ev, "q") {
        Value::Point(p, 2) => assert_eq!([p[0], p[1]], [3.0, 6.0]),
        other => panic!("{other:?}"),
    }
    // An angle in degrees or revolutions arrives as the same radians.
    close(
        num(
            &value(&mut ev, "my_lift(0.25 rev, 6 mm, 0.5 rev)"),
            Dim::LENGTH,
        ),
        3.0,
        1e-12,
    );
}

#[test]
fn the_checker_types_extension_calls_by_their_declared_signature() {
    let Err((Fail::Check(f), _)) = run(
        "use \"law.rhai\"\nlet h = my_lift(90 deg, 6 mm/s, 180 deg)\nlet s: speed = my_lift(1 deg, 1 mm, 2 deg)\nlet n = nope(1)",
        &[("law.rhai", LAW)],
    ) else {
        panic!("expected check errors")
    };
    let errs = f.of::<CheckError>();
    let text: Vec<String> = errs.iter().map(|e| e.to_string()).collect();
    assert_eq!(errs.len(), 3, "{text:#?}");
    assert!(
        text[0].contains("length") && text[0].contains("rise"),
        "{}",
        text[0]
    );
    assert!(text[1].contains("speed"), "{}", text[1]);
    assert!(text[2].contains("nope"), "{}", text[2]);
    // Without `use`, the function is unknown.
    let Err((Fail::Check(f), _)) = run("let h = my_lift(1 deg, 1 mm, 2 deg)", &[]) else {
        panic!()
    };
    let errs = f.of::<CheckError>();
    assert!(errs[0].to_string().contains("my_lift"));
}

#[test]
fn profile_generators_return_profiles_with_methods() {
    let mut ev = ok(
        "use \"law.rhai\"\nlet cam = my_cam(20 mm, 5 mm)",
        &[("law.rhai", LAW)],
    );
    let Value::Profile(p) = value(&mut ev, "cam") else {
        panic!()
    };
    assert!(p.closed);
    // Every point of the contour lies at r(θ) = 20 + 5 (1 − cos θ)/2 from the center.
    let len = p.length();
    for i in 0..2000 {
        let q = p.point_at(len * i as f64 / 2000.0);
        let th = q.y.atan2(q.x);
        close(q.norm(), 20.0 + 5.0 * (1.0 - th.cos()) / 2.0, 1e-6);
    }
}

#[test]
fn profiles_cross_into_rhai_with_their_methods() {
    let module = r#"
/// lase: (p: profile) -> [number]
fn facts(p) {
    let q = p.point_at(p.length() / 4.0);
    let n = p.normal_at(0.0);
    let o = p.offset(1.0);
    [p.length(), q.x, q.y, n.x, n.y, o.length(), p.sample(4).len(), p.curvature_at(0.0)]
}
"#;
    let mut ev = ok(
        "use \"m.rhai\"\nlet f = facts(profile circle(center: (0, 0), radius: 10 mm))",
        &[("m.rhai", module)],
    );
    let Value::List(items) = value(&mut ev, "f") else {
        panic!()
    };
    let f: Vec<f64> = items.iter().map(|v| num(v, Dim::NONE)).collect();
    close(f[0], TAU * 10.0, 1e-9);
    // A quarter turn counter-clockwise from (10, 0).
    close(f[1], 0.0, 1e-9);
    close(f[2], 10.0, 1e-9);
    // The normal points to the concave side: the center.
    close(f[3], -1.0, 1e-9);
    close(f[4], 0.0, 1e-9);
    close(f[5], TAU * 11.0, 1e-6);
    assert_eq!(f[6], 4.0);
    close(f[7].abs(), 0.1, 1e-9);
}

// ---------------------------------------------------------------- stdlib::patterns

#[test]
fn patterns_match_their_closed_forms() {
    let mut ev = ok("use stdlib::patterns", &[]);
    let g = points(&value(&mut ev, "grid((1 mm, 2 mm), 3, 2, 0.5 mm, 0.25 mm)"));
    assert_eq!(g.len(), 6);
    for (k, p) in g.iter().enumerate() {
        let (i, j) = (k % 3, k / 3);
        close(p[0], 1.0 + 0.5 * i as f64, 1e-12);
        close(p[1], 2.0 + 0.25 * j as f64, 1e-12);
    }
    let s = points(&value(&mut ev, "serpentine((0, 0), 4, 3, 1 mm, -2 mm)"));
    assert_eq!(s.len(), 12);
    for (k, p) in s.iter().enumerate() {
        let (j, c) = (k / 4, k % 4);
        let i = if j % 2 == 0 { c } else { 3 - c };
        assert_eq!([p[0], p[1]], [i as f64, -2.0 * j as f64], "spot {k}");
    }
    let st = points(&value(&mut ev, "staggered((0, 0), 3, 3, 2 mm, 1 mm)"));
    for (k, p) in st.iter().enumerate() {
        let (i, j) = (k % 3, k / 3);
        close(
            p[0],
            2.0 * i as f64 + if j % 2 == 1 { 1.0 } else { 0.0 },
            1e-12,
        );
        close(p[1], j as f64, 1e-12);
    }
    // Hexagonal: every spot's nearest neighbours are exactly `pitch` away.
    let h = points(&value(&mut ev, "hex((0, 0), 5, 5, 0.1 mm)"));
    assert_eq!(h.len(), 25);
    for (a, p) in h.iter().enumerate() {
        let nearest = h
            .iter()
            .enumerate()
            .filter(|(b, _)| *b != a)
            .map(|(_, q)| ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt())
            .fold(f64::MAX, f64::min);
        close(nearest, 0.1, 1e-12);
    }
    let r = points(&value(&mut ev, "ring((5 mm, 0), 2 mm, 8, 45 deg)"));
    assert_eq!(r.len(), 8);
    for (k, p) in r.iter().enumerate() {
        let a = PI / 4.0 + TAU * k as f64 / 8.0;
        close(p[0], 5.0 + 2.0 * a.cos(), 1e-12);
        close(p[1], 2.0 * a.sin(), 1e-12);
    }
    // Reordering a row-by-row grid serpentine gives the serpentine array.
    let o = points(&value(
        &mut ev,
        "serpentine_order(grid((0, 0), 4, 3, 1 mm, 2 mm))",
    ));
    let want = points(&value(&mut ev, "serpentine((0, 0), 4, 3, 1 mm, 2 mm)"));
    assert_eq!(o, want);
    // A count that is not whole is an error inside the module, pointed at the call.
    let Err((Fail::Eval(EvalError::Extension(e)), _)) = run(
        "use stdlib::patterns\nlet g = grid((0, 0), 2.5, 2, 1 mm, 1 mm)",
        &[],
    ) else {
        panic!()
    };
    assert!(e.to_string().contains("nx must be a whole number"), "{e}");
}

// ---------------------------------------------------------------- stdlib::cams

#[test]
fn cam_laws_match_their_closed_forms() {
    let mut ev = ok("use stdlib::cams", &[]);
    for u in [0.0, 0.1, 0.25, 0.5, 0.8, 1.0] {
        let get = |ev: &mut Evaluator, f: &str, law: &str| {
            num(&value(ev, &format!("{f}(\"{law}\", {u})")), Dim::NONE)
        };
        close(
            get(&mut ev, "law_lift", "harmonic"),
            (1.0 - (PI * u).cos()) / 2.0,
            1e-12,
        );
        close(
            get(&mut ev, "law_velocity", "harmonic"),
            PI / 2.0 * (PI * u).sin(),
            1e-12,
        );
        close(
            get(&mut ev, "law_accel", "harmonic"),
            PI * PI / 2.0 * (PI * u).cos(),
            1e-12,
        );
        close(
            get(&mut ev, "law_lift", "cycloidal"),
            u - (TAU * u).sin() / TAU,
            1e-12,
        );
        close(
            get(&mut ev, "law_velocity", "cycloidal"),
            1.0 - (TAU * u).cos(),
            1e-12,
        );
        close(
            get(&mut ev, "law_accel", "cycloidal"),
            TAU * (TAU * u).sin(),
            1e-12,
        );
        close(
            get(&mut ev, "law_lift", "poly345"),
            10.0 * u.powi(3) - 15.0 * u.powi(4) + 6.0 * u.powi(5),
            1e-12,
        );
        close(
            get(&mut ev, "law_velocity", "poly345"),
            30.0 * u * u - 60.0 * u.powi(3) + 30.0 * u.powi(4),
            1e-12,
        );
        close(
            get(&mut ev, "law_accel", "poly345"),
            60.0 * u - 180.0 * u * u + 120.0 * u.powi(3),
            1e-12,
        );
    }
    // Modified trapezoid: constant peak acceleration 8π/(2+π) between u = 1/8 and 3/8,
    // s(1/2) = 1/2 by symmetry, s(1) = 1.
    let a = 8.0 * PI / (2.0 + PI);
    for (u, want) in [(0.2, a), (0.3, a), (0.7, -a)] {
        close(
            num(
                &value(&mut ev, &format!("law_accel(\"modified_trapezoid\", {u})")),
                Dim::NONE,
            ),
            want,
            1e-9,
        );
    }
    close(
        num(
            &value(&mut ev, "law_lift(\"modified_trapezoid\", 0.5)"),
            Dim::NONE,
        ),
        0.5,
        1e-12,
    );
    // A rise–dwell–return cam: lift at the middle of a cycloidal 120° rise of 6 mm is 3 mm;
    // on the high dwell 6 mm; a quarter into the return 6·(1 − s(1/4)).
    let lift = |ev: &mut Evaluator, th: &str| {
        num(
            &value(
                ev,
                &format!("lift({th}, 6 mm, 120 deg, 40 deg, 120 deg, \"cycloidal\")"),
            ),
            Dim::LENGTH,
        )
    };
    close(lift(&mut ev, "60 deg"), 3.0, 1e-12);
    close(lift(&mut ev, "140 deg"), 6.0, 1e-12);
    let s = 0.25 - (TAU * 0.25).sin() / TAU;
    close(lift(&mut ev, "190 deg"), 6.0 * (1.0 - s), 1e-12);
    close(lift(&mut ev, "300 deg"), 0.0, 1e-12);
    // The disc cam's contour is r = base + lift along rays from the center.
    let Value::Profile(cam) = value(
        &mut ev,
        "disc_cam(20 mm, 6 mm, 120 deg, 40 deg, 120 deg, \"harmonic\")",
    ) else {
        panic!()
    };
    let n = 3000;
    for i in 0..n {
        let q = cam.point_at(cam.length() * i as f64 / n as f64);
        let th = q.y.atan2(q.x).rem_euclid(TAU);
        let deg = th.to_degrees();
        let l = if deg < 120.0 {
            6.0 * (1.0 - (PI * deg / 120.0).cos()) / 2.0
        } else if deg < 160.0 {
            6.0
        } else if deg < 280.0 {
            6.0 * (1.0 + (PI * (deg - 160.0) / 120.0).cos()) / 2.0
        } else {
            0.0
        };
        close(q.norm(), 20.0 + l, 2e-3);
    }
}

// ---------------------------------------------------------------- presets

#[test]
fn presets_bind_values_with_units_and_can_be_overridden() {
    let mut ev = ok(
        "use stdlib::presets::cam_hardening\nlet base_power = power\nlet power = 1.1 kW\nuse \"mine.toml\"",
        &[("mine.toml", "[values]\nstep = \"0.5 mm\"\n")],
    );
    close(num(&value(&mut ev, "base_power"), Dim::POWER), 1200.0, 1e-9);
    close(num(&value(&mut ev, "power"), Dim::POWER), 1100.0, 1e-9);
    close(num(&value(&mut ev, "speed"), Dim::SPEED), 8.0, 1e-12);
    close(num(&value(&mut ev, "spot"), Dim::LENGTH), 4.0, 1e-12);
    close(num(&value(&mut ev, "step"), Dim::LENGTH), 0.5, 1e-12);
    // The checker knows their dimensions.
    let Err((Fail::Check(f), _)) = run(
        "use stdlib::presets::cam_hardening\nlet x: length = speed",
        &[],
    ) else {
        panic!()
    };
    let errs = f.of::<CheckError>();
    assert!(errs[0].to_string().contains("speed"));
}

// ---------------------------------------------------------------- sandbox

fn ext_error(call: &str) -> (ExtError, SourceMap) {
    let recipe = format!("use \"law.rhai\"\n\nlet r = {call}\n");
    match run(&recipe, &[("law.rhai", LAW)]) {
        Err((Fail::Eval(EvalError::Extension(e)), map)) => (*e, map),
        Err((f, _)) => panic!("{call}: {f:#?}"),
        Ok(_) => panic!("{call} ran"),
    }
}

/// The extension error names the function, points into the .rhai file and at the recipe
/// line (3) that called it.
fn assert_points_at_both(e: &ExtError, map: &SourceMap, function: &str, rhai_snippet: &str) {
    let (span, call) = match e {
        ExtError::Runaway {
            function: f,
            span,
            call,
            ..
        }
        | ExtError::Script {
            function: f,
            span,
            call,
            ..
        } => {
            assert_eq!(f, function);
            (span.expect("a span in the .rhai file"), *call)
        }
        other => panic!("{other:#?}"),
    };
    assert_eq!(map.describe(call).split(':').nth(1), Some("3"), "{e}");
    assert!(
        map.describe(span).starts_with("law.rhai:"),
        "{}",
        map.describe(span)
    );
    assert!(
        map.snippet(span).starts_with(rhai_snippet),
        "`{}` should start with `{rhai_snippet}`",
        map.snippet(span)
    );
    assert!(e.to_string().contains(function));
}

#[test]
fn an_endless_loop_is_stopped_by_the_operation_budget() {
    let (e, map) = ext_error("spin(1)");
    assert!(matches!(e, ExtError::Runaway { .. }), "{e:#?}");
    assert!(e.to_string().contains("operations"), "{e}");
    assert_points_at_both(&e, &map, "spin", "");
}

#[test]
fn endless_recursion_is_stopped_by_the_call_depth_limit() {
    let (e, map) = ext_error("deep(1)");
    assert!(e.to_string().contains("levels deep"), "{e}");
    assert_points_at_both(&e, &map, "deep", "deep");
}

#[test]
fn a_giant_array_or_string_is_stopped_by_the_size_limits() {
    let (e, map) = ext_error("giant(1)");
    assert!(e.to_string().contains("array"), "{e}");
    assert_points_at_both(&e, &map, "giant", "");
    let (e, _) = ext_error("long_string(1)");
    assert!(matches!(e, ExtError::Runaway { .. }), "{e:#?}");
    assert!(e.to_string().contains("string"), "{e}");
}

/// Rhai checks an array's whole size after every `push`, so growing one is quadratic: with
/// arrays of up to 1 000 000 items, 20 000 nested pushes took 4.7 s and the operation budget
/// allowed far more. At `MAX_ARRAY` (100 000) the growth stops at the limit with the sandbox's
/// diagnostic, after a bounded amount of work.
#[test]
fn growing_an_array_push_by_push_stops_at_the_array_limit() {
    assert_eq!(lase_runtime::ext::MAX_ARRAY, 100_000);
    let (e, map) = ext_error("nested_pushes(1)");
    assert!(matches!(e, ExtError::Runaway { .. }), "{e:#?}");
    assert!(e.to_string().contains("array"), "{e}");
    assert_points_at_both(&e, &map, "nested_pushes", "");
}

#[test]
fn extensions_have_no_file_access_and_no_eval() {
    let (e, map) = ext_error("reads_file(1)");
    assert!(e.to_string().contains("open_file"), "{e}");
    assert_points_at_both(&e, &map, "reads_file", "open_file");
    // `import` is compiled out, `eval` disabled: both are syntax errors of the module.
    for (src, word) in [
        (
            "import \"x\" as x;\n/// lase: () -> number\nfn f() { 1 }",
            "import",
        ),
        ("/// lase: () -> number\nfn f() { eval(\"1 + 1\") }", "eval"),
    ] {
        let Err((Fail::Load(f), map)) = run("use \"bad.rhai\"", &[("bad.rhai", src)]) else {
            panic!("{word} was accepted")
        };
        let errs = f.of::<ExtError>();
        let ExtError::Syntax { span, .. } = &errs[0] else {
            panic!("{:#?}", errs[0])
        };
        assert_eq!(map.snippet(*span), word, "{}", errs[0]);
    }
}

#[test]
fn script_errors_and_bad_results_point_into_the_module_and_at_the_call() {
    let (e, map) = ext_error("fails(1)");
    assert!(e.to_string().contains("out of range"), "{e}");
    assert_points_at_both(&e, &map, "fails", "throw");
    let (e, map) = ext_error("wrong_result(1)");
    let ExtError::Result {
        expected,
        found,
        call,
        ..
    } = &e
    else {
        panic!("{e:#?}")
    };
    assert_eq!(
        (expected.as_str(), found.as_str()),
        ("a plain number", "a string")
    );
    assert_eq!(map.describe(*call), "test.lase:3:9");
}

#[test]
fn bad_signatures_and_syntax_are_load_errors_in_the_module() {
    let Err((Fail::Load(f), map)) = run(
        "use \"bad.rhai\"",
        &[(
            "bad.rhai",
            "/// lase: (x: lenght) -> length\nfn f(x) { x }\n",
        )],
    ) else {
        panic!()
    };
    let errs = f.of::<ExtError>();
    assert!(errs[0].to_string().contains("lenght"), "{}", errs[0]);
    assert_eq!(map.describe(errs[0].span()), "bad.rhai:2:4");
    let Err((Fail::Load(f), map)) =
        run("use \"bad.rhai\"", &[("bad.rhai", "fn f(x) {\n  x +\n}\n")])
    else {
        panic!()
    };
    let errs = f.of::<ExtError>();
    let ExtError::Syntax { span, .. } = &errs[0] else {
        panic!()
    };
    assert!(
        map.describe(*span).starts_with("bad.rhai:3"),
        "{}",
        map.describe(*span)
    );
    let Err((Fail::Load(f), _)) = run("use stdlib::camz", &[]) else {
        panic!()
    };
    let errs = f.of::<ExtError>();
    assert!(format!("{:?}", errs[0]).contains("cams"), "{:?}", errs[0]);
}
