//! LinuxCNC's synchronized outputs lead its joints by 1.5 servo periods (the cubic
//! interpolator's two trajectory periods, less tp's mean half period past a block's start:
//! `emit::writer::lead`, measured on the real LinuxCNC in `tests/linuxcnc.rs`), so the
//! LinuxCNC writer carries each flying beam switch that far along the path. Measured here from
//! the emitted NC text against the plan: every `M62 P0` / `M63 P0` sits 1.5 servo periods of
//! the planned edge speed past the planned edge, on the planned path, at the machine file's
//! servo period; GRBL and ISO programs are not cut.

mod common;

use common::job;
use lase_runtime::emit::{Dialect, EmitOptions, emit_lines};
use lase_runtime::motion::{Job, power};

/// Lit strokes on straight lines at 20 and 100 mm/s, each led in and out on the fly.
const STROKES: &str = "machine xy_table
laser { power 40 W }
follow profile polyline [(0, 0), (30 mm, 0)] at 20 mm/s
follow profile polyline [(0, 5 mm), (30 mm, 5 mm)] at 100 mm/s
follow profile polyline [(30 mm, 10 mm), (0, 10 mm), (0, 15 mm)] at 50 mm/s
move to (0, -20 mm) rapid
";

/// Where each beam switch of a LinuxCNC program is written: (on, x, y).
fn switches(j: &Job, dialect: Dialect) -> Vec<(bool, [f64; 2])> {
    let (lines, _) = emit_lines(j, dialect, &EmitOptions::default()).unwrap();
    let (mut pos, mut out) = ([0.0f64; 2], Vec::new());
    for l in &lines {
        let words: Vec<&str> = l.text.split(' ').filter(|w| !w.starts_with('N')).collect();
        match words.first().copied() {
            Some("M62") if words.get(1) == Some(&"P0") => out.push((true, pos)),
            Some("M63" | "M65") if words.get(1) == Some(&"P0") => out.push((false, pos)),
            Some("M3" | "M4") => out.push((true, pos)),
            Some("M5") => out.push((false, pos)),
            _ => {}
        }
        let num = |p: char| {
            words
                .iter()
                .find(|w| w.starts_with(p))
                .and_then(|w| w[1..].parse::<f64>().ok())
        };
        if words.first() != Some(&"G4") {
            pos = [num('X').unwrap_or(pos[0]), num('Y').unwrap_or(pos[1])];
        }
    }
    out
}

/// The planned beam edges: (on, place, speed, direction of travel) at every lit run's ends.
fn planned_edges(j: &Job) -> Vec<(bool, [f64; 2], f64, [f64; 2])> {
    let ops = &j.program.ops;
    let segs = j.plan.segments();
    let mut out = Vec::new();
    let mut pos = j.program.start;
    let mut lit = false;
    for (i, op) in ops.iter().enumerate() {
        let Some(to) = op.target() else { continue };
        if !op.moves_from(pos) {
            continue;
        }
        let r = power::op_segments(j, i);
        let dir = {
            let (dx, dy) = (to[0] - pos[0], to[1] - pos[1]);
            let n = dx.hypot(dy);
            [dx / n, dy / n]
        };
        let now = op.laser().is_some();
        if now && !lit {
            out.push((true, [pos[0], pos[1]], segs[r.start].v_entry, dir));
        }
        if !now && lit {
            out.push((false, [pos[0], pos[1]], segs[r.start].v_entry, dir));
        }
        lit = now;
        pos = to;
    }
    out
}

fn check(j: &Job, servo_s: f64) -> usize {
    let written = switches(j, Dialect::LinuxCnc);
    let planned = planned_edges(j);
    // The last switch is the footer's immediate beam-off.
    assert_eq!(written.len(), planned.len() + 1, "{written:?} {planned:?}");
    let mut carried = 0;
    for (&(on, at), &(p_on, place, v, dir)) in written.iter().zip(&planned) {
        assert_eq!(on, p_on);
        let lead = 1.5 * servo_s * v;
        let (dx, dy) = (at[0] - place[0], at[1] - place[1]);
        // Along the direction of travel, by the lead, to the 0.1 µm of the NC's words.
        let along = dx * dir[0] + dy * dir[1];
        let across = (dx * dir[1] - dy * dir[0]).abs();
        assert!(
            (along - lead).abs() < 1.5e-4 && across < 1.5e-4,
            "switch {on} at {at:?}: {along} mm past the planned edge {place:?}, lead {lead} \
             ({v} mm/s)"
        );
        if lead > 1e-3 {
            carried += 1;
        }
    }
    carried
}

#[test]
fn each_beam_switch_is_carried_one_and_a_half_servo_periods_along_the_path() {
    let mut j = job(STROKES);
    assert_eq!(j.program.machine.servo_period_s(), 0.001);
    let carried = check(&j, 0.001);
    // Every edge of the three strokes is passed at cruise: 6 switches carried, by 0.03,
    // 0.15 and 0.075 mm.
    assert_eq!(carried, 6);
    // The machine file's servo period sets the lead: at 2 ms it doubles.
    j.program
        .machine
        .post
        .get_mut("linuxcnc")
        .unwrap()
        .servo_period_s = Some(0.002);
    assert_eq!(check(&j, 0.002), 6);
}

#[test]
fn other_dialects_switch_at_the_planned_edge() {
    let j = job(STROKES);
    for d in [Dialect::Iso] {
        let planned = planned_edges(&j);
        let written = switches(&j, d);
        for (&(_, at), &(_, place, _, _)) in written.iter().zip(&planned) {
            assert!(
                (at[0] - place[0]).hypot(at[1] - place[1]) < 1e-4,
                "{d}: {at:?} vs {place:?}"
            );
        }
    }
}

#[test]
fn the_servo_period_is_a_machine_file_fact() {
    use lase_runtime::machine::parse_machine;
    let stock = lase_stdlib::machine("xy_table").unwrap();
    assert!(stock.contains("servo_period = \"1 ms\""));
    let with = |v: &str| stock.replace("servo_period = \"1 ms\"", &format!("servo_period = {v}"));
    let m = parse_machine(&with("\"2 ms\""), 0).unwrap();
    assert_eq!(m.servo_period_s(), 0.002);
    // The generated INI runs LinuxCNC at it.
    let ini = lase_runtime::link::linuxcnc::config::generate(&m, &Default::default()).ini;
    assert!(ini.contains("SERVO_PERIOD = 2000000\n"), "{ini}");
    for bad in ["\"2 mm\"", "\"0 ms\"", "\"-1 ms\""] {
        let e = parse_machine(&with(bad), 0).unwrap_err();
        assert!(format!("{e:?}").contains("servo_period"), "{bad}: {e:?}");
    }
    // Without the key: LinuxCNC's usual 1 ms.
    let m = parse_machine(&stock.replace("servo_period = \"1 ms\"", ""), 0).unwrap();
    assert_eq!(m.servo_period_s(), 0.001);
}

/// The spot's (x, y) before each line of a LinuxCNC program (where a synchronized output
/// written on that line switches) and the line's words and op tag.
fn walk(j: &Job) -> Vec<([f64; 2], Vec<String>, Option<u32>)> {
    let (lines, _) = emit_lines(j, Dialect::LinuxCnc, &EmitOptions::default()).unwrap();
    let mut pos = [0.0f64; 2];
    let mut out = Vec::new();
    for l in &lines {
        let words: Vec<String> = l
            .text
            .split(' ')
            .filter(|w| !w.starts_with('N'))
            .map(str::to_string)
            .collect();
        let num = |p: char| {
            words
                .iter()
                .find(|w| w.starts_with(p))
                .and_then(|w| w[1..].parse::<f64>().ok())
        };
        let next = [num('X').unwrap_or(pos[0]), num('Y').unwrap_or(pos[1])];
        out.push((pos, words.clone(), l.op));
        if words.first().map(String::as_str) != Some("G4") {
            pos = next;
        }
    }
    out
}

fn has(words: &[String], a: &str, b: &str) -> bool {
    words.iter().any(|w| w == a) && words.iter().any(|w| w == b)
}

#[test]
fn each_pulse_trigger_is_carried_like_the_beam_switch() {
    // texture_array's dots: rows at 20 mm/s, a pulse every 0.2 mm from each row's start. Each
    // trigger rise (`M62 P1`) is written 1.5 servo periods of 20 mm/s (0.03 mm) past its
    // planned pulse, on the row; before, on the pulse itself, 1.5 periods early on LinuxCNC.
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let name = root.join("texture_array.lase").display().to_string();
    let (_, j) = lase_runtime::compile(&mut lase_runtime::FsFiles, &name)
        .unwrap_or_else(|(_, f)| panic!("{f}"));
    let rises: Vec<[f64; 2]> = walk(&j)
        .into_iter()
        .filter(|(_, w, _)| has(w, "M62", "P1"))
        .map(|(p, _, _)| p)
        .collect();
    let pulses: Vec<_> = lase_runtime::report::pulse_events(&j).collect();
    assert_eq!(rises.len(), pulses.len());
    assert_eq!(pulses.len(), 360);
    for (r, p) in rises.iter().zip(&pulses) {
        let to = j.program.ops[p.op as usize].target().unwrap();
        let (dx, dy) = (to[0] - p.pos[0], to[1] - p.pos[1]);
        let n = dx.hypot(dy);
        let dir = if n > 1e-9 {
            [dx / n, dy / n]
        } else {
            [0.0, 0.0]
        };
        let want = [p.pos[0] + 0.03 * dir[0], p.pos[1] + 0.03 * dir[1]];
        assert!(
            (r[0] - want[0]).hypot(r[1] - want[1]) < 1.5e-4,
            "rise at {r:?}, pulse at {:?}: want {want:?}",
            p.pos
        );
    }
}

#[test]
fn each_power_step_of_an_image_row_is_carried_like_the_beam_switch() {
    // image_engrave's rows at 100 mm/s: every `M67` of a row (its runs' power steps, and the
    // beam-on's) is written 1.5 servo periods of 100 mm/s (0.15 mm) past the run's end (the
    // row's start), on the row. Before, the steps sat on the run ends (1.5 periods early on
    // LinuxCNC) and rows starting with a one-pixel run switched the beam on 1.5 periods early.
    use lase_runtime::program::OpKind;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples");
    let name = root.join("image_engrave.lase").display().to_string();
    let (_, j) = lase_runtime::compile(&mut lase_runtime::FsFiles, &name)
        .unwrap_or_else(|(_, f)| panic!("{f}"));
    let lines = walk(&j);
    let (mut carried, mut steps, mut rows) = (0, 0, 0);
    let mut from = j.program.start;
    let mut prev_pos = [0.0f64; 2];
    for (i, op) in j.program.ops.iter().enumerate() {
        let Some(to) = op.target() else { continue };
        if let OpKind::Line { row: Some(row), .. } = &op.kind {
            rows += 1;
            let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
            let n = dx.hypot(dy);
            let dir = [dx / n, dy / n];
            let mut want: Vec<[f64; 2]> = vec![[from[0], from[1]]];
            want.extend(
                row.runs[..row.runs.len() - 1]
                    .iter()
                    .map(|&(c, _)| row.end_of(c)),
            );
            for (p, w, tag) in &lines {
                // The row's lines, and the beam-on lines written in its first block's cut.
                if *tag != Some(i as u32) || !has(w, "M67", "E0") {
                    continue;
                }
                steps += 1;
                let off = want
                    .iter()
                    .map(|q| {
                        let (ex, ey) = (p[0] - q[0], p[1] - q[1]);
                        (ex * dir[0] + ey * dir[1], (ex * dir[1] - ey * dir[0]).abs())
                    })
                    .find(|&(along, across)| along.abs() < 0.2 && across < 1.5e-4)
                    .unwrap_or_else(|| panic!("row {i}: M67 at {p:?}, run ends {want:?}"));
                if (off.0 - 0.15).abs() < 1.5e-4 {
                    carried += 1;
                } else {
                    assert!(off.0.abs() < 1.5e-4, "row {i}: M67 {} mm past", off.0);
                }
            }
        }
        let _ = prev_pos;
        prev_pos = [to[0], to[1]];
        from = to;
    }
    assert!(rows > 0);
    assert_eq!((carried, steps), (steps, steps), "{rows} rows");
}
