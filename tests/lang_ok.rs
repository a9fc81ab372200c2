//! Evaluation tests: every `tests/ok/*.lase` checks clean, evaluates, and produces the process
//! program pinned in `tests/ok/NAME.ops` (one line per op: recipe line, kind, numbers in mm,
//! mm/s, s, W).

mod common;

use common::*;
use lase_lang::SourceMap;
use lase_runtime::compile::{self, FsFiles};
use lase_runtime::program::{OpKind, ProcessProgram};
use libtest_mimic::{Arguments, Failed, Trial};
use std::fmt::Write;
use std::path::Path;

fn n(v: f64) -> String {
    lase_lang::units::format_number(v)
}

fn p3(p: [f64; 3]) -> String {
    format!("({}, {}, {})", n(p[0]), n(p[1]), n(p[2]))
}

/// A recipe's process program, through the pipeline `lase` runs (up to planning).
pub fn evaluate(path: &Path) -> Result<(SourceMap, ProcessProgram), Failed> {
    let fail = |f: compile::Failure| Failed::from(format!("{}: {f}", path.display()));
    let mut recipe =
        compile::load(&mut FsFiles, &path.to_string_lossy()).map_err(|(_, f)| fail(f))?;
    compile::check(&recipe).map_err(fail)?;
    let p = compile::evaluate(&mut recipe, &mut FsFiles).map_err(fail)?;
    Ok((recipe.map, p))
}

fn dump(map: &SourceMap, p: &ProcessProgram) -> String {
    let mut s = String::new();
    for op in &p.ops {
        let line = map.locate(op.span).map(|(_, lc)| lc.line).unwrap_or(0);
        let laser = |l: Option<&lase_runtime::program::Laser>| match l {
            Some(l) => format!(
                " laser {} W spot {} mm{}",
                n(l.power_w),
                n(l.spot_mm),
                match &l.pulse {
                    Some(pu) => format!(" pulse {:?}", pu.mode),
                    None => String::new(),
                }
            ),
            None => String::new(),
        };
        let text = match &op.kind {
            OpKind::Rapid { to, .. } => format!("rapid {}", p3(*to)),
            OpKind::Line {
                to,
                feed_mm_s,
                laser: l,
                ..
            } => {
                format!(
                    "line  {} feed {}{}",
                    p3(*to),
                    n(*feed_mm_s),
                    laser(l.as_deref())
                )
            }
            OpKind::Arc {
                to,
                center,
                ccw,
                feed_mm_s,
                laser: l,
            } => format!(
                "arc   {} center ({}, {}) {} feed {}{}",
                p3(*to),
                n(center[0]),
                n(center[1]),
                if *ccw { "ccw" } else { "cw" },
                n(*feed_mm_s),
                laser(l.as_deref())
            ),
            OpKind::Dwell { seconds } => format!("dwell {}", n(*seconds)),
            OpKind::MCode { code, comment } => format!("mcode {code} {comment:?}"),
            OpKind::Event { name } => format!("event {name}"),
            OpKind::Output { name, on, stops } => format!("output {name} {on} stops {stops}"),
            OpKind::Fire {
                count,
                period_s,
                laser: l,
                ..
            } => format!("fire  {count} every {}{}", n(*period_s), laser(Some(l))),
        };
        writeln!(s, "{line:>3}  {text}").unwrap();
    }
    s
}

/// One test per `tests/ok/*.lase` (named by the file: `cargo test --test lang_ok units`),
/// and the tests of particular programs.
fn main() {
    let files = lase_files(&root().join("tests/ok"));
    assert!(files.len() >= 4);
    let mut trials: Vec<Trial> = files
        .into_iter()
        .map(|f| {
            let name = f.file_stem().unwrap().to_string_lossy().into_owned();
            Trial::test(name, move || {
                let (map, p) = evaluate(&f)?;
                golden(&f.with_extension("ops"), &dump(&map, &p));
                Ok(())
            })
        })
        .collect();
    trials.push(Trial::test(
        "units_convert_to_internal_units",
        units_convert_to_internal_units,
    ));
    trials.push(Trial::test(
        "functions_and_loops_produce_the_expected_geometry",
        functions_and_loops_produce_the_expected_geometry,
    ));
    libtest_mimic::run(&Arguments::from_args(), trials).exit();
}

fn units_convert_to_internal_units() -> Result<(), Failed> {
    let (_, p) = evaluate(&root().join("tests/ok/units.lase"))?;
    let OpKind::Line { to, feed_mm_s, .. } = &p.ops[0].kind else {
        panic!()
    };
    assert_eq!(*to, [25.4, 50.8, 0.0]);
    assert!((feed_mm_s - 10.0).abs() < 1e-12);
    let OpKind::Line { to, feed_mm_s, .. } = &p.ops[1].kind else {
        panic!()
    };
    assert!((to[2] + 0.5).abs() < 1e-12);
    assert!((feed_mm_s - 500.0 / 60.0).abs() < 1e-12);
    let OpKind::Dwell { seconds } = &p.ops[2].kind else {
        panic!()
    };
    assert!((seconds - 0.25).abs() < 1e-15);
    let OpKind::Line { feed_mm_s, .. } = &p.ops[3].kind else {
        panic!()
    };
    assert!((feed_mm_s - 20.0).abs() < 1e-12);
    let l = p.ops[4].laser().expect("lit");
    assert_eq!(l.power_w, 250.0);
    assert!((l.spot_mm - 0.04).abs() < 1e-15);
    Ok(())
}

fn functions_and_loops_produce_the_expected_geometry() -> Result<(), Failed> {
    let (_, p) = evaluate(&root().join("tests/ok/control.lase"))?;
    // fib(6) = 8: the squares start at x = 8 mm.
    let OpKind::Rapid { to, .. } = &p.ops[0].kind else {
        panic!("{:?}", p.ops[0])
    };
    assert_eq!(*to, [8.0, 0.0, 0.0]);
    let lit: f64 = p
        .ops
        .windows(2)
        .filter(|w| w[1].laser().is_some())
        .map(|w| {
            let a = w[0].target().unwrap();
            let b = w[1].target().unwrap();
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .sum();
    assert!((lit - 4.0 * (1.0 + 2.0)).abs() < 1e-12, "{lit}");
    Ok(())
}
