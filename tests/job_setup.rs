//! Job setup measured on the emitted NC (issue 20): the nested-parts example's holes are cut
//! before the outlines around them, its travel is shorter than in source order, its kerf moves
//! outlines out and holes in by half the cut's width, and its tabs leave gaps of their width
//! at evenly spaced places.

mod common;

use common::*;

/// One lit run of a LinuxCNC program (between `M62 P0` and `M63 P0`): where it starts and
/// ends, its length, its lit points (arcs sampled) and the radii of its arcs.
#[derive(Debug, Default)]
struct Run {
    start: [f64; 2],
    end: [f64; 2],
    length: f64,
    points: Vec<[f64; 2]>,
    radii: Vec<f64>,
    lines: usize,
}

/// The lit runs of a program, in order, and the length of its unlit motion (rapids, leads and
/// tab crossings).
fn lit_runs(ngc: &str) -> (Vec<Run>, f64) {
    let mut pos = [0.0f64; 2];
    let mut lit = false;
    let mut motion = 0;
    let mut out: Vec<Run> = Vec::new();
    let mut unlit = 0.0;
    // Where the beam lights: carried switches put back (`common::uncarried`).
    let ngc = common::uncarried_text(ngc);
    for line in ngc.lines() {
        let w = nc_words(line);
        let get = |c: char| w.iter().find(|(l, _)| *l == c).map(|(_, v)| *v);
        // The beam's gate is digital output 0; other outputs (air on `M62 P2`) are not cuts.
        let gate = w.iter().any(|&(c, v)| c == 'P' && v == 0.0);
        if gate && w.iter().any(|&(c, v)| c == 'M' && v == 62.0) {
            lit = true;
            out.push(Run {
                start: pos,
                end: pos,
                points: vec![pos],
                ..Run::default()
            });
        }
        if gate && w.iter().any(|&(c, v)| c == 'M' && v == 63.0) {
            lit = false;
        }
        if let Some(g) = w
            .iter()
            .find(|(c, v)| *c == 'G' && *v <= 3.0)
            .map(|(_, v)| *v as i32)
        {
            motion = g;
        }
        let (x, y) = (get('X'), get('Y'));
        if x.is_none() && y.is_none() {
            continue;
        }
        let to = [x.unwrap_or(pos[0]), y.unwrap_or(pos[1])];
        let chord = (to[0] - pos[0]).hypot(to[1] - pos[1]);
        if !(lit && motion > 0) {
            unlit += chord;
            pos = to;
            continue;
        }
        let run = out.last_mut().unwrap();
        if motion == 1 {
            run.length += chord;
            run.lines += 1;
            run.points.push(to);
        } else {
            let c = [pos[0] + get('I').unwrap(), pos[1] + get('J').unwrap()];
            let r = (pos[0] - c[0]).hypot(pos[1] - c[1]);
            let a0 = (pos[1] - c[1]).atan2(pos[0] - c[0]);
            let a1 = (to[1] - c[1]).atan2(to[0] - c[0]);
            let tau = std::f64::consts::TAU;
            let mut d = a1 - a0;
            if motion == 3 {
                while d <= 1e-12 {
                    d += tau;
                }
            } else {
                while d >= -1e-12 {
                    d -= tau;
                }
            }
            run.length += r * d.abs();
            run.radii.push(r);
            for k in 1..=16 {
                let a = a0 + d * k as f64 / 16.0;
                run.points.push([c[0] + r * a.cos(), c[1] + r * a.sin()]);
            }
        }
        run.end = to;
        pos = to;
    }
    (out, unlit)
}

fn emit(file: &str) -> String {
    let (code, out, err) = lase(&["emit", file, "--dialect", "linuxcnc"]);
    assert_eq!(code, 0, "{err}");
    out
}

/// Plates of the example: lower-left corners, 30 × 20 mm, a hole of radius 4 mm at (15, 10).
const PLATES: [[f64; 2]; 6] = [
    [-100.0, 40.0],
    [60.0, -60.0],
    [-20.0, 40.0],
    [60.0, 40.0],
    [-100.0, -60.0],
    [-20.0, -60.0],
];

fn plate_of(p: [f64; 2]) -> usize {
    PLATES
        .iter()
        .position(|c| {
            p[0] > c[0] - 1.0 && p[0] < c[0] + 31.0 && p[1] > c[1] - 1.0 && p[1] < c[1] + 21.0
        })
        .expect("every cut lies on a plate")
}

fn bbox(points: &[[f64; 2]]) -> [f64; 4] {
    points.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        },
    )
}

#[test]
fn holes_are_cut_before_their_outline_with_kerf_and_less_travel() {
    let ngc = emit("examples/nested_parts.lase");
    let (runs, unlit) = lit_runs(&ngc);
    let is_hole = |r: &Run| r.lines == 0 && !r.radii.is_empty();
    // Every hole comes before every piece of the outline around it.
    for (i, h) in runs.iter().enumerate().filter(|(_, r)| is_hole(r)) {
        let plate = plate_of(h.start);
        for (j, o) in runs.iter().enumerate().filter(|(_, r)| !is_hole(r)) {
            if plate_of(o.start) == plate {
                assert!(
                    i < j,
                    "the hole of plate {plate} (run {i}) is cut after its outline (run {j})"
                );
            }
        }
    }
    // Kerf 0.2 mm: holes 0.1 mm smaller in radius, outlines 0.1 mm larger all round (the held
    // plate has kerf 0 on its hole and the offset written into the recipe on its outline).
    for h in runs.iter().filter(|r| is_hole(r)) {
        let want = if plate_of(h.start) == 5 { 4.0 } else { 3.9 };
        for r in &h.radii {
            assert!(
                (r - want).abs() < 1e-4,
                "hole radius {r} mm, expected {want} mm"
            );
        }
    }
    for (plate, c) in PLATES.iter().enumerate() {
        let pts: Vec<[f64; 2]> = runs
            .iter()
            .filter(|r| !is_hole(r) && plate_of(r.start) == plate)
            .flat_map(|r| r.points.iter().copied())
            .collect();
        let b = bbox(&pts);
        let want = [c[0] - 0.1, c[1] - 0.1, c[0] + 30.1, c[1] + 20.1];
        for (got, want_k) in b.iter().zip(want) {
            assert!(
                (got - want_k).abs() < 1e-4,
                "plate {plate}: cut box {b:?}, expected {want:?}"
            );
        }
    }
    // The same recipe in source order travels further (the figure is printed for the notes).
    let dir = std::env::temp_dir().join(format!("lase_job_setup_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let src = std::fs::read_to_string(root().join("examples/nested_parts.lase")).unwrap();
    let file = dir.join("nested_parts_source.lase");
    std::fs::write(&file, src.replace("order inner_first", "order source")).unwrap();
    let (source_runs, unlit_source) = lit_runs(&emit(file.to_str().unwrap()));
    // The kerf does not depend on the order: in source order the holes shrink the same.
    let kerfed = source_runs
        .iter()
        .filter(|r| is_hole(r) && plate_of(r.start) != 5)
        .flat_map(|r| r.radii.iter())
        .filter(|r| (*r - 3.9).abs() < 1e-4)
        .count();
    assert!(
        kerfed >= 10,
        "{kerfed} arcs of radius 3.9 mm in source order"
    );
    std::fs::remove_dir_all(&dir).ok();
    eprintln!("unlit motion: {unlit:.3} mm ordered, {unlit_source:.3} mm in source order");
    assert!(
        unlit < 0.5 * unlit_source,
        "ordered {unlit} mm against {unlit_source} mm"
    );
}

#[test]
fn tabs_leave_gaps_of_their_width_evenly_spaced() {
    let ngc = emit("examples/nested_parts.lase");
    let (runs, _) = lit_runs(&ngc);
    let held: Vec<&Run> = runs
        .iter()
        .filter(|r| r.lines > 0 && plate_of(r.start) == 5)
        .collect();
    assert_eq!(held.len(), 4, "four tabs cut the outline in four pieces");
    // The outline is the 30 x 20 mm plate offset 0.1 mm: sides plus four quarter circles.
    let total = 2.0 * (30.0 + 20.0) + std::f64::consts::TAU * 0.1;
    for (k, r) in held.iter().enumerate() {
        let next = held[(k + 1) % 4];
        let gap = (next.start[0] - r.end[0]).hypot(next.start[1] - r.end[1]);
        assert!((gap - 1.5).abs() < 1e-4, "tab {k} is {gap} mm wide");
        assert!(
            (r.length - (total / 4.0 - 1.5)).abs() < 1e-3,
            "piece {k} is {} mm long, expected {}",
            r.length,
            total / 4.0 - 1.5
        );
    }
}

#[test]
fn plan_reports_the_travel_saved() {
    let (code, out, err) = lase(&["plan", "examples/nested_parts.lase"]);
    assert_eq!(code, 0, "{err}");
    let line = out
        .lines()
        .find(|l| l.trim_start().starts_with("cut order"))
        .expect("a cut order line");
    assert!(line.contains("12 paths"), "{line}");
    assert!(line.contains("saved"), "{line}");
}

/// The air-assist example's first path starts where the machine stands (no rapid before it):
/// it is ordered and given its kerf like any other, so the hole (radius 3 mm, kerf 0.15 mm)
/// comes first at 2.925 mm and the 30 x 20 mm outline follows 0.075 mm outside; the air's
/// `M62 P2` comes before the first cut and its `M63 P2` after the last.
#[test]
fn air_assist_example_orders_its_first_path_and_switches_the_air_around_the_cuts() {
    let ngc = emit("examples/air_assist.lase");
    let (runs, _) = lit_runs(&ngc);
    assert_eq!(runs.len(), 2, "{ngc}");
    assert!(
        runs[0].lines == 0 && !runs[0].radii.is_empty(),
        "the hole first: {ngc}"
    );
    for r in &runs[0].radii {
        assert!(
            (r - 2.925).abs() < 1e-3,
            "hole radius {r}, want 3 - 0.075 mm"
        );
    }
    let b = bbox(&runs[1].points);
    for (got, want) in b.iter().zip([-0.075, -0.075, 30.075, 20.075]) {
        assert!(
            (got - want).abs() < 1e-3,
            "outline box {b:?}, want 0.075 mm outside"
        );
    }
    let lines: Vec<&str> = ngc.lines().collect();
    let at = |l: &str| lines.iter().position(|x| *x == l).expect(l);
    let first_cut = at("M62 P0");
    let last_cut = lines.iter().rposition(|x| *x == "M63 P0").unwrap();
    assert!(at("M62 P2") < first_cut && at("M63 P2") > last_cut, "{ngc}");
}
