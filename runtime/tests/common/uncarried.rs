//! LinuxCNC programs read with the writer's carried beam switches put back (shared by the
//! runtime's and the binary's integration tests: `tests/common/mod.rs` includes this file).

/// A LinuxCNC program's lines (text, op tag) with each beam switch the writer carried along
/// the path (`emit::writer::lead`: LinuxCNC's synchronized outputs lead its joints by 1.5
/// servo periods, so the switch is written that far past the beam's edge, cutting a straight
/// block there) put back where the beam lights: before the cut block, whose two parts are one
/// block again. Tests of what the beam marks read the program through this; the lead itself
/// is measured in `runtime/tests/switch_lead.rs` and on the real LinuxCNC.
pub fn uncarried(lines: Vec<(String, Option<u32>)>) -> Vec<(String, Option<u32>)> {
    let is_switch = |t: &str| {
        let t = t.trim();
        t == "M62 P0" || t == "M63 P0" || t.starts_with("M67 ")
    };
    let words = |t: &str| -> Vec<String> {
        t.split(['(', ';'])
            .next()
            .unwrap_or("")
            .split_whitespace()
            .map(str::to_string)
            .collect()
    };
    let axis = |w: &[String], c: char| {
        w.iter()
            .find(|x| x.starts_with(c))
            .and_then(|x| x[1..].parse::<f64>().ok())
    };
    let is_motion = |w: &[String]| {
        w.iter().any(|x| x.starts_with(['X', 'Y', 'Z']))
            && !w.iter().any(|x| {
                x.starts_with('M') || x == "G4" || x.starts_with("G2") || x.starts_with("G3")
            })
    };
    let mut out: Vec<(String, Option<u32>)> = Vec::with_capacity(lines.len());
    // Where each line of `out` leaves the spot (x, y, z), and whether the last is G0/G1 linear.
    let mut pos = [0.0f64; 3];
    let mut before_last = [0.0f64; 3];
    let mut last_motion: Option<usize> = None;
    // The feed in force, mm/min: a cut's first part lasts at most 2.2 servo periods (1 ms) of
    // it (`lead::cut_at`), which tells it from a block that just runs on in line.
    let mut feed = 0.0f64;
    let mut i = 0;
    while i < lines.len() {
        let (t, tag) = &lines[i];
        let w = words(t);
        if let Some(f) = axis(&w, 'F') {
            feed = f;
        }
        if is_switch(t) && last_motion == Some(out.len() - 1) {
            // The switch group and the motion line after it.
            let mut j = i;
            while j < lines.len() && is_switch(&lines[j].0) {
                j += 1;
            }
            // A beam switch among them. A power step alone (an image row's `M67`, carried
            // with its run's end) and a pulse trigger (`M62`/`M63 P1`, carried in the pulse
            // writer) stay where written: switch_lead.rs measures them.
            let beam = lines[i..j]
                .iter()
                .any(|(s, _)| matches!(s.trim(), "M62 P0" | "M63 P0"));
            if let Some((bt, btag)) = lines.get(j).filter(|_| beam) {
                let bw = words(bt);
                let end = [
                    axis(&bw, 'X').unwrap_or(pos[0]),
                    axis(&bw, 'Y').unwrap_or(pos[1]),
                    axis(&bw, 'Z').unwrap_or(pos[2]),
                ];
                let (a, b) = (
                    [
                        pos[0] - before_last[0],
                        pos[1] - before_last[1],
                        pos[2] - before_last[2],
                    ],
                    [end[0] - pos[0], end[1] - pos[1], end[2] - pos[2]],
                );
                let cross = (a[1] * b[2] - a[2] * b[1]).abs()
                    + (a[2] * b[0] - a[0] * b[2]).abs()
                    + (a[0] * b[1] - a[1] * b[0]).abs();
                let (la, lb) = (
                    a.iter().map(|v| v * v).sum::<f64>().sqrt(),
                    b.iter().map(|v| v * v).sum::<f64>().sqrt(),
                );
                let g_change = bw.iter().any(|x| x.starts_with('G'));
                let short = la <= 2.2e-3 * feed.max(axis(&bw, 'F').unwrap_or(0.0)) / 60.0 + 2e-4;
                // With tags: both parts of a cut block carry the same op's.
                let a_tag = out[out.len() - 1].1;
                let same_op = a_tag.is_none() || a_tag == *btag;
                if is_motion(&bw)
                    && !g_change
                    && short
                    && same_op
                    && la > 0.0
                    && lb > 0.0
                    && cross < 2e-4 * (la + lb)
                    && a.iter().zip(&b).map(|(x, y)| x * y).sum::<f64>() > 0.0
                {
                    // Cut: the switches go before the first part, the parts join again.
                    let (at, atag) = out.pop().unwrap();
                    let mut merged = words(&at);
                    for x in &bw {
                        let c = x.chars().next().unwrap();
                        match merged.iter_mut().find(|m| m.starts_with(c)) {
                            Some(m) => *m = x.clone(),
                            None => merged.push(x.clone()),
                        }
                    }
                    for s in &lines[i..j] {
                        out.push(s.clone());
                    }
                    out.push((merged.join(" "), btag.or(atag)));
                    let _ = tag;
                    pos = end;
                    last_motion = Some(out.len() - 1);
                    i = j + 1;
                    continue;
                }
            }
        }
        out.push((t.clone(), *tag));
        if is_motion(&w) {
            before_last = pos;
            pos = [
                axis(&w, 'X').unwrap_or(pos[0]),
                axis(&w, 'Y').unwrap_or(pos[1]),
                axis(&w, 'Z').unwrap_or(pos[2]),
            ];
            last_motion = Some(out.len() - 1);
        } else if !is_switch(t) {
            last_motion = None;
            if w.iter().any(|x| x.starts_with(['X', 'Y', 'Z'])) {
                // An arc or other move: where it ends.
                pos = [
                    axis(&w, 'X').unwrap_or(pos[0]),
                    axis(&w, 'Y').unwrap_or(pos[1]),
                    axis(&w, 'Z').unwrap_or(pos[2]),
                ];
            }
        }
        i += 1;
    }
    out
}

/// [`uncarried`] of a program's text.
pub fn uncarried_text(nc: &str) -> String {
    let lines = uncarried(nc.lines().map(|l| (l.to_string(), None)).collect());
    let mut s: String = lines.into_iter().map(|(t, _)| t + "\n").collect();
    if !nc.ends_with('\n') {
        s.pop();
    }
    s
}
