//! `lase plan`'s axis peaks speak each axis's unit (mm for a linear axis, deg for a rotary
//! one, per s, s², s³), and the numbers are the plan summary's own.

mod common;

use common::lase;

#[test]
fn axis_peaks_carry_their_units_and_match_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    let (code, out, err) = lase(&[
        "plan",
        "examples/cam_hardening.lase",
        "--summary",
        json.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut seen = Vec::new();
    for line in out.lines().filter(|l| l.trim_start().starts_with("axis ")) {
        let w: Vec<&str> = line.split_whitespace().collect();
        // axis NAME v V UNIT/s a A UNIT/s² j J UNIT/s³
        let (name, unit) = (w[1], if "ABC".contains(w[1]) { "deg" } else { "mm" });
        assert_eq!(w[4], format!("{unit}/s"), "{line}");
        assert_eq!(w[7], format!("{unit}/s²"), "{line}");
        assert_eq!(w[10], format!("{unit}/s³"), "{line}");
        let peaks = &summary["axes"][name];
        let v: f64 = w[3].parse().unwrap();
        let a: f64 = w[6].parse().unwrap();
        assert!(
            (v - peaks["v_max"].as_f64().unwrap()).abs() < 1e-3,
            "{line}"
        );
        assert!(
            (a - peaks["a_max"].as_f64().unwrap()).abs() < 1e-3,
            "{line}"
        );
        seen.push(name.to_string());
    }
    assert_eq!(seen, ["B", "C", "X"]);
}

/// The value of the `  LABEL   N s …` line of `lase plan`'s output.
fn seconds(out: &str, label: &str) -> Option<f64> {
    let line = out.lines().find(|l| l.trim_start().starts_with(label))?;
    line.trim_start()[label.len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// `lase plan` reports first the cycle time of the controller that runs the program, by the
/// model of its planner, and names the model (issue 13): on texture_array lase's own plan
/// (11.7 s, jerk-bound blended corners) is nearly twice what either controller takes. The
/// dialect comes from `--dialect`, else the machine file, else LinuxCNC; ISO has no model, so
/// lase's plan stands in and says so. The JSON summary carries the same in `controller`,
/// beside lase's own `cycle_time_s`.
#[test]
fn the_first_cycle_time_is_the_controller_that_runs_the_program() {
    use lase_runtime::emit::Dialect;
    use lase_runtime::link::{linuxcnc::tp, sim::motion};
    let ex = "examples/texture_array.lase";
    let (_, job) = lase_runtime::compile(&mut lase_runtime::FsFiles, ex)
        .unwrap_or_else(|(_, f)| panic!("{f}"));
    let own = job.cycle_time();
    let lcnc = tp::controller_time(&job).unwrap().unwrap().total_s;
    let grbl = motion::controller_time_in(&job, Dialect::Grbl)
        .unwrap()
        .unwrap()
        .timeline
        .total_s;
    eprintln!("texture_array: lase's plan {own:.4} s, LinuxCNC {lcnc:.4} s, GRBL {grbl:.4} s");
    assert!(own > 1.5 * lcnc && own > 1.5 * grbl, "{own} {lcnc} {grbl}");
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("s.json");
    for (dialect, name, want, model) in [
        (
            None,
            "linuxcnc",
            lcnc,
            "LinuxCNC 2.9 trajectory planner model",
        ),
        (Some("grbl"), "grbl", grbl, "GRBL 1.1 planner model"),
        (
            Some("iso"),
            "iso",
            own,
            "lase's own plan: no model of an ISO controller",
        ),
    ] {
        let mut args = vec!["plan", ex, "-o", json.to_str().unwrap()];
        args.extend(dialect.iter().flat_map(|d| ["--dialect", *d]));
        let (code, out, err) = lase(&args);
        assert_eq!(code, 0, "{err}");
        let first = out.lines().nth(1).unwrap();
        assert!(first.trim_start().starts_with("cycle time"), "{out}");
        assert!(first.contains(&format!(" s on {name}")), "{first}");
        assert!(first.contains(model), "{first}");
        let t = seconds(&out, "cycle time").unwrap();
        assert!((t - want).abs() <= 5e-5, "{name}: {t} vs {want}\n{out}");
        // lase's own plan on its own line, where a model stood first.
        match seconds(&out, "lase's plan") {
            Some(p) => assert!((p - own).abs() <= 5e-5, "{out}"),
            None => assert_eq!(name, "iso", "{out}"),
        }
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let c = &s["controller"];
        assert_eq!(c["dialect"], name, "{s}");
        assert!(model.starts_with(c["model"].as_str().unwrap()), "{c}");
        assert!((c["cycle_time_s"].as_f64().unwrap() - want).abs() <= 1e-6 * want);
        assert!((s["cycle_time_s"].as_f64().unwrap() - own).abs() <= 1e-6 * own);
    }
}

/// A machine file's `dialect` is the controller `lase plan` times first and the dialect `lase
/// emit` writes without `--dialect`; a dialect lase does not know, or one the file has no post
/// for, is a diagnostic at the key.
#[test]
fn a_machine_files_dialect_is_the_default_of_plan_and_emit() {
    let dir = tempfile::tempdir().unwrap();
    let mut stock =
        std::fs::read_to_string(common::root().join("stdlib/machines/xy_table.toml")).unwrap();
    let with = |stock: &str, dialect: &str| {
        let text = stock.replacen(
            "kinematics = ",
            &format!("dialect = \"{dialect}\"\nkinematics = "),
            1,
        );
        common::write_file(dir.path(), "m.toml", &text);
        common::write_file(
            dir.path(),
            "r.lase",
            "machine \"m.toml\"\nlaser { power 20 W }\n\
             follow profile line((0, 0), (10 mm, 0)) at 10 mm/s\n",
        )
    };
    let r = with(&stock, "grblhal");
    let r = r.to_str().unwrap();
    let (code, out, err) = lase(&["plan", r]);
    assert_eq!(code, 0, "{err}");
    let first = out.lines().nth(1).unwrap();
    assert!(
        first.contains(" s on grblhal") && first.contains("grblHAL planner model"),
        "{out}"
    );
    let (code, nc, err) = lase(&["emit", r]);
    assert_eq!(code, 0, "{err}");
    assert!(
        nc.starts_with("(generated by lase")
            && nc.lines().next().unwrap().ends_with("for grblhal)"),
        "{nc}"
    );
    let (code, nc, err) = lase(&["emit", r, "--dialect", "linuxcnc"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        nc.lines().next().unwrap().ends_with("for linuxcnc)"),
        "{nc}"
    );
    let (code, _, err) = lase(&["plan", with(&stock, "fanuc").to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("lase::machine::invalid"), "{err}");
    assert!(err.contains("unknown dialect `fanuc`"), "{err}");
    assert!(
        err.contains("the dialects are linuxcnc, grbl, grblhal and iso"),
        "{err}"
    );
    assert!(err.contains("m.toml:5:11"), "{err}");
    // No `[post.iso]` (nor the ISO lines of its output and settling) for `dialect = "iso"`.
    stock = stock
        .replace("[post.iso]", "[unused]")
        .lines()
        .filter(|l| !l.starts_with("iso = "))
        .collect::<Vec<_>>()
        .join("\n");
    stock = stock.replace("[unused]\nlaser_on = [\"M3 S{s}\"]\nlaser_off = [\"M5\"]\npower = [\"S{s}\"]\ns_max = 1000\n", "");
    let (code, _, err) = lase(&["plan", with(&stock, "iso").to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(
        err.contains("the machine's dialect `iso` has no `[post.iso]`"),
        "{err}"
    );
    assert!(err.contains("m.toml:5:11"), "{err}");
}
