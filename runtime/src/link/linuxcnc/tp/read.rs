//! The NC text as LinuxCNC's interpreter and canon hand it to the planner: a line at a time
//! into the queue's segments (canon's segment limits, the module doc's first point), the
//! stops between them and the outputs they switch.

use super::{ACC_RATIO_NORMAL, Joint, POS_EPSILON, Seg, TpLimits};
use std::collections::VecDeque;

/// The words of one line: letters (upper case) and their numbers, comments dropped.
pub(super) fn words(line: &str) -> Result<Vec<(char, f64)>, String> {
    let mut text = String::new();
    let mut depth = 0;
    for c in line.chars() {
        match c {
            ';' if depth == 0 => break,
            '(' => depth += 1,
            ')' if depth > 0 => depth -= 1,
            _ if depth > 0 || c.is_whitespace() => {}
            _ => text.push(c.to_ascii_uppercase()),
        }
    }
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let letter = b[i] as char;
        if !letter.is_ascii_alphabetic() {
            return Err(format!("`{line}`: `{letter}` is not a word"));
        }
        let start = i + 1;
        let mut j = start;
        while j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.' || b[j] == b'-' || b[j] == b'+')
        {
            j += 1;
        }
        let v: f64 = text[start..j]
            .parse()
            .map_err(|_| format!("`{line}`: `{letter}` has no number"))?;
        out.push((letter, v));
        i = j;
    }
    Ok(out)
}

/// The program as the planner's queue sees it: the segments read and not yet made into
/// pieces (all of them for [`run_program_from`]; the last one or two for [`stream::TpStream`]).
#[derive(Debug, Default)]
pub(super) struct Queue {
    pub(super) segs: VecDeque<Seg>,
    /// `joints[i]` follows `segs[i]`.
    pub(super) joints: VecDeque<Option<Joint>>,
    /// The `G64 P` in force for each segment.
    pub(super) tolerances: VecDeque<f64>,
    /// Immediate output changes at the stop after segment `i` (or before the first: `None`),
    /// in segment order.
    pub(super) immediate: VecDeque<(Option<usize>, u32, bool)>,
    /// Dwells before the first segment.
    pub(super) stops: usize,
    /// The index of `segs[0]` among every segment read.
    pub(super) base: usize,
}

impl Queue {
    /// Segments read so far.
    pub(super) fn count(&self) -> usize {
        self.base + self.segs.len()
    }

    /// Ends the current chain: a stop after the last segment (or before the first).
    fn stop(&mut self, dwell: f64) {
        match self.joints.back_mut() {
            Some(j @ None) => *j = Some(Joint::Stop { dwell, drain: true }),
            Some(Some(Joint::Stop { dwell: d, .. })) => *d += dwell,
            _ => self.stops += usize::from(dwell > 0.0),
        }
    }
}

/// The interpreter's modal state between lines.
#[derive(Debug)]
pub(super) struct Reader {
    pos: Vec<f64>,
    motion: u32,
    feed: f64,
    inverse_time: bool,
    exact_stop: bool,
    tolerance: f64,
    /// G64 Q, the naive CAM detector's tolerance: P when Q is not given.
    naive: f64,
    pending: Vec<(u32, bool)>,
    /// canon's naive-CAM detector: the open chain of straight feeds, as (where it starts, the
    /// points joined so far); see [`super::naive::joins`]. Its segment is always the queue's
    /// last, and [`super::stream::TpStream`] makes the one before it into pieces only once
    /// the chain has ended ([`Reader::chain_open`]).
    chain: Option<(Vec<f64>, Vec<Vec<f64>>)>,
}

impl Reader {
    pub(super) fn new(limits: &TpLimits, start: &[f64]) -> Reader {
        Reader {
            pos: (0..limits.axes.len())
                .map(|k| start.get(k).copied().unwrap_or(0.0))
                .collect(),
            motion: 0,
            feed: 0.0,
            inverse_time: false,
            exact_stop: false,
            tolerance: 0.0,
            naive: 0.0,
            pending: Vec::new(),
            chain: None,
        }
    }

    /// Whether the queue's last segment is a chain of straight feeds the next line may still
    /// lengthen.
    pub(super) fn chain_open(&self) -> bool {
        self.chain.is_some()
    }

    /// Reads NC line `number` (0-based) into `q`.
    pub(super) fn line(
        &mut self,
        q: &mut Queue,
        limits: &TpLimits,
        number: usize,
        raw: &str,
    ) -> Result<(), String> {
        let index = |c: char| limits.axes.iter().position(|a| a.letter == c);
        let w = words(raw)?;
        if w.is_empty() {
            return Ok(());
        }
        let feed_before = self.feed;
        let mut target = self.pos.clone();
        let mut moved = false;
        let mut center = [None, None];
        let mut dwell = None;
        let mut p_word = None;
        for &(c, v) in &w {
            match c {
                'G' => match (v * 10.0).round() as i64 {
                    0 => self.motion = 0,
                    10 => self.motion = 1,
                    20 => self.motion = 2,
                    30 => self.motion = 3,
                    40 => dwell = Some(0.0),
                    930 => self.inverse_time = true,
                    940 => self.inverse_time = false,
                    610 | 611 => self.exact_stop = true,
                    640 => self.exact_stop = false,
                    170 | 210 | 900 | 910 | 400 | 490 | 800 | 540 => {}
                    _ => return Err(format!("`{raw}`: G{v} is not modelled")),
                },
                'F' => self.feed = v,
                'P' => p_word = Some(v),
                'Q' | 'E' | 'S' | 'N' | 'K' => {}
                'I' => center[0] = Some(v),
                'J' => center[1] = Some(v),
                'M' => {}
                c => match index(c) {
                    Some(k) => {
                        target[k] = v;
                        moved = true;
                    }
                    None => return Err(format!("`{raw}`: the machine has no axis {c}")),
                },
            }
        }
        let has_g = |g: f64| w.iter().any(|&(c, v)| c == 'G' && (v - g).abs() < 1e-9);
        if has_g(64.0) {
            self.tolerance = p_word.unwrap_or(0.0);
            self.naive = w
                .iter()
                .find(|(c, _)| *c == 'Q')
                .map_or(self.tolerance, |(_, q)| *q);
        }
        // Outputs come before the block's motion (rs274ngc's order of execution).
        for &(c, v) in &w {
            if c != 'M' {
                continue;
            }
            match v as i64 {
                62 | 63 => self
                    .pending
                    .push((p_word.unwrap_or(0.0) as u32, v as i64 == 62)),
                67 => {}
                64 | 65 => {
                    q.stop(0.0);
                    let at = q.count().checked_sub(1);
                    q.immediate
                        .push_back((at, p_word.unwrap_or(0.0) as u32, v as i64 == 64));
                }
                2 | 30 => q.stop(0.0),
                // Any other M-code is run by the task after motion has ended.
                _ => q.stop(0.0),
            }
        }
        if dwell.is_some() {
            q.stop(p_word.unwrap_or(0.0));
            return Ok(());
        }
        if !moved {
            self.chain = None;
            return Ok(());
        }
        // A straight feed the detector chains: in G64 with a Q tolerance, G94, moving no
        // rotary axis. It joins the open chain only at the chain's feed and with no output
        // or other word before it, since those flush the chain first (a new F does, and every
        // synchronized output: SET_MOTION_OUTPUT_BIT and its kin call flush_segments before
        // queueing).
        let chainable = self.motion == 1
            && !self.inverse_time
            && !self.exact_stop
            && self.naive > 0.0
            && limits
                .axes
                .iter()
                .zip(self.pos.iter().zip(&target))
                .all(|(a, (p, t))| !a.rotary || p == t);
        let extends = chainable
            && self.pending.is_empty()
            && self.feed == feed_before
            && w.iter().all(|&(c, v)| match c {
                'G' => (v - 1.0).abs() < 1e-9,
                'M' | 'P' | 'Q' | 'E' | 'S' => false,
                _ => true,
            });
        if !extends {
            self.chain = None;
        }
        if let Some((from, points)) = self.chain.as_mut()
            && super::naive::joins(from, points, &target, self.naive)
            && matches!(q.joints.back(), Some(None))
        {
            // The chain's segment now ends here: one line from where the chain started.
            if let Some(mut seg) = segment(
                from,
                &target,
                1,
                [None, None],
                self.feed,
                false,
                None,
                limits,
                raw,
            )? {
                let last = q.segs.back_mut().expect("a chain has a segment");
                seg.dio = std::mem::take(&mut last.dio);
                seg.line = number + 1;
                *last = seg;
                points.push(target.clone());
                self.pos = target;
                return Ok(());
            }
        }
        let small_arc = (!self.exact_stop).then_some(self.naive);
        let seg = segment(
            &self.pos,
            &target,
            self.motion,
            center,
            self.feed,
            self.inverse_time,
            small_arc,
            limits,
            raw,
        )?;
        let from = std::mem::replace(&mut self.pos, target);
        let Some(mut seg) = seg else {
            self.chain = None;
            return Ok(());
        };
        self.chain = chainable.then(|| (from, vec![self.pos.clone()]));
        seg.dio = std::mem::take(&mut self.pending);
        seg.line = number + 1;
        if let (Some(j @ None), true) = (q.joints.back_mut(), self.exact_stop) {
            // G61: the term condition STOP, inside the planner.
            *j = Some(Joint::Stop {
                dwell: 0.0,
                drain: false,
            });
        }
        q.segs.push_back(seg);
        q.joints.push_back(None);
        q.tolerances.push_back(self.tolerance);
        Ok(())
    }
}

/// Reads the NC text into segments and the stops between them.
pub(super) fn read(nc: &str, limits: &TpLimits, start: &[f64]) -> Result<Queue, String> {
    let mut q = Queue::default();
    let mut reader = Reader::new(limits, start);
    for (number, raw) in nc.lines().enumerate() {
        reader.line(&mut q, limits, number, raw)?;
    }
    Ok(q)
}

/// The segment from `from` to `to`, `None` when nothing moves.
#[allow(clippy::too_many_arguments)]
fn segment(
    from: &[f64],
    to: &[f64],
    motion: u32,
    center: [Option<f64>; 2],
    feed: f64,
    inverse_time: bool,
    small_arc: Option<f64>,
    limits: &TpLimits,
    raw: &str,
) -> Result<Option<Seg>, String> {
    let axes = &limits.axes;
    let d: Vec<f64> = from.iter().zip(to).map(|(a, b)| b - a).collect();
    let xyz_of = |v: &[f64]| -> [f64; 3] {
        let mut out = [0.0; 3];
        for (k, a) in axes.iter().enumerate() {
            if let Some(i) = "XYZ".find(a.letter) {
                out[i] = v[k];
            }
        }
        out
    };
    let mut acc_bound = [0.0; 3];
    for a in axes {
        if let Some(i) = "XYZ".find(a.letter) {
            acc_bound[i] = a.a;
        }
    }
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let dxyz = xyz_of(&d);
    let lin = norm(&dxyz);
    let rot: f64 = norm(
        &axes
            .iter()
            .zip(&d)
            .filter(|(a, _)| a.rotary)
            .map(|(_, v)| *v)
            .collect::<Vec<_>>(),
    );
    let rotary = rot > POS_EPSILON;
    if motion >= 2 {
        // An arc in the XY plane (G17, the only plane lase writes).
        let (ix, iy) = (
            axes.iter().position(|a| a.letter == 'X'),
            axes.iter().position(|a| a.letter == 'Y'),
        );
        let (Some(ix), Some(iy)) = (ix, iy) else {
            return Err(format!("`{raw}`: an arc needs X and Y"));
        };
        let c = [
            from[ix] + center[0].unwrap_or(0.0),
            from[iy] + center[1].unwrap_or(0.0),
        ];
        let r0 = [from[ix] - c[0], from[iy] - c[1]];
        let r1 = [to[ix] - c[0], to[iy] - c[1]];
        let radius = r0[0].hypot(r0[1]);
        let mut sweep = (r0[0] * r1[1] - r0[1] * r1[0]).atan2(r0[0] * r1[0] + r0[1] * r1[1]);
        let ccw = motion == 3;
        if ccw && sweep <= 1e-12 {
            sweep += std::f64::consts::TAU;
        } else if !ccw && sweep >= -1e-12 {
            sweep -= std::f64::consts::TAU;
        }
        let len = radius * sweep.abs();
        if len < POS_EPSILON {
            return Ok(None);
        }
        // In blending mode an arc whose chord strays less than the naive CAM tolerance from it
        // runs as that chord: measured, dial_marks' 0.25 mm arcs turn at their chord ends.
        let sagitta = radius * (1.0 - (sweep.abs() / 2.0).cos());
        let as_chord =
            small_arc.is_some_and(|tol| sweep.abs() <= std::f64::consts::PI && sagitta < tol);
        if as_chord {
            return segment(
                from,
                to,
                1,
                [None, None],
                feed,
                inverse_time,
                None,
                limits,
                raw,
            );
        }
        let tangent = |r: [f64; 2]| -> [f64; 3] {
            let s = if ccw { 1.0 } else { -1.0 };
            let l = r[0].hypot(r[1]).max(1e-300);
            [-s * r[1] / l, s * r[0] / l, 0.0]
        };
        let (vx, vy) = (axes[ix].v, axes[iy].v);
        let (ax, ay) = (axes[ix].a, axes[iy].a);
        let acc = ax.min(ay);
        let req = if inverse_time {
            (len * feed).max(0.1) / 60.0
        } else {
            feed / 60.0
        };
        let vmax = vx
            .min(vy)
            .min(limits.max_linear_v)
            .min((ACC_RATIO_NORMAL * acc * radius).sqrt())
            .min(len / limits.cycle_s);
        return Ok(Some(Seg {
            len,
            req: req.min(vmax),
            vmax,
            acc,
            rapid: false,
            arc: true,
            rotary,
            u0: tangent(r0),
            u1: tangent(r1),
            dio: Vec::new(),
            acc_bound,
            line: 0,
        }));
    }
    // A line: its length is X Y Z's, or the rotary axes' when X Y Z stay.
    let len = if lin > POS_EPSILON { lin } else { rot };
    if len < POS_EPSILON {
        return Ok(None);
    }
    // canon: the time each axis needs at its limit; the line's limit is its length over the
    // longest.
    let t_v = axes
        .iter()
        .zip(&d)
        .map(|(a, x)| x.abs() / a.v)
        .fold(0.0, f64::max);
    let t_a = axes
        .iter()
        .zip(&d)
        .map(|(a, x)| x.abs() / a.a)
        .fold(0.0, f64::max);
    let mut vmax = len / t_v.max(1e-300);
    if lin > POS_EPSILON {
        vmax = vmax.min(limits.max_linear_v);
    }
    vmax = vmax.min(len / limits.cycle_s);
    let acc = len / t_a.max(1e-300);
    let rapid = motion == 0;
    let req = if rapid {
        vmax
    } else if inverse_time {
        (len * feed).max(0.1) / 60.0
    } else {
        feed / 60.0
    };
    let u = if lin > POS_EPSILON {
        [dxyz[0] / lin, dxyz[1] / lin, dxyz[2] / lin]
    } else {
        [0.0; 3]
    };
    Ok(Some(Seg {
        len,
        req: req.min(vmax),
        vmax,
        acc,
        rapid,
        arc: false,
        rotary,
        u0: u,
        u1: u,
        dio: Vec::new(),
        acc_bound,
        line: 0,
    }))
}
