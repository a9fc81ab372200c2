//! Streams a validated job as NC lines, keeping the modal state a controller keeps so that
//! only what changes is written.
//!
//! Power coupled to speed (PROCESS.md §1, eq. 1): GRBL (and grblHAL) scales power by speed
//! itself in its dynamic laser mode, so a coupled section is switched on with `M4` instead of
//! `M3`. LinuxCNC and ISO controls cannot, so a coupled lit move is written as the sub-blocks
//! of `motion::power` (ramps cut at 1 % speed steps, each with its time-mean power), each
//! preceded by the post's power line when the value changes; LinuxCNC's immediate `M68`
//! becomes the motion-synchronized `M67` there, so the change lands at the start of its
//! sub-block and does not break blending. Where lase's plan holds a lit move below its feed
//! (a blended lit corner, a lit arc's chords), coupled or not, the move is cut the same way
//! and each sub-block's `F` is the plan's mean speed over it (`power::lit_blocks`), so the
//! controller runs what lase planned where the beam is on.
//!
//! Axis words come from the planned job: a whole move ends at the axes motion computed for its
//! op (`Job::op_axes`), and a sub-block (power steps, pulse gates) ends on the block it is cut
//! from as the controller runs it ([`part_way`]), so nothing here runs the kinematics. Rotary
//! words are degrees through `axes::to_external`, the one conversion.

use super::format::{self, LaserWords};
use super::validate::{self, Checked, GRBL_MAX_LINE};
use super::{Dialect, EmitError, EmitOptions, EmitStats, NcLine};
use crate::axes::Axes;
use crate::motion::{Job, beam, power};
use crate::program::{Coupling, Op, OpKind, P3};
use block::{motion_line, part_way, write_block};
pub(super) use lead::at_cruise;
use std::io;

mod block;
mod chain;
mod lead;
mod pulse;
mod row;
mod settle;
mod timing;

/// Lowest feed a lit sub-block is held to, mm/s: the plan's mean speed over a block is
/// positive, but one written as `F0` would be an error on every controller.
const MIN_CAP_MM_S: f64 = 0.01;

/// ISO block numbers step by 10 (room to insert blocks by hand, as in the paper's program)
/// and wrap before six digits, since many Fanuc controls read at most N99999.
const BLOCK_STEP: u64 = 10;
const BLOCK_WRAP: u64 = 99_990;

/// Longest comment written, parentheses included, in every dialect: GRBL's line buffer, the
/// smallest of them, bounds every line.
const COMMENT_MAX: usize = GRBL_MAX_LINE;

struct Out<'s> {
    sink: &'s mut dyn FnMut(&NcLine) -> io::Result<()>,
    dialect: Dialect,
    block: u64,
    stats: EmitStats,
    /// The last lines written were the laser-off lines.
    after_off: bool,
    /// The line handed to the sink, reused: a texturing job writes millions of lines, and a
    /// fresh `String` for each was a large part of emission time.
    line: NcLine,
    /// A beam switch carried along the path on LinuxCNC (`lead`): [`write_block`] writes it
    /// where the path reaches it, any other line first writes it where it stands.
    pending: Option<lead::Pending>,
    /// LinuxCNC: the G93 blocks since tp last stopped (`chain`), and the `G64 P` in force.
    chain: chain::Chain,
    tolerance: f64,
    /// Where the lead-out op (its index) is split, as `timing::off_edge_timing` chose: the
    /// length of its first block, mm.
    split_len: Option<(usize, f64)>,
}

impl Out<'_> {
    /// Writes one block, numbered in ISO.
    fn put(&mut self, text: &str, op: Option<u32>) -> io::Result<()> {
        // A comment does nothing on the controller: a carried switch may follow it.
        if !text.starts_with('(') {
            self.flush_pending()?;
        }
        self.line.text.clear();
        if self.dialect == Dialect::Iso {
            self.block = if self.block >= BLOCK_WRAP {
                BLOCK_STEP
            } else {
                self.block + BLOCK_STEP
            };
            use std::fmt::Write as _;
            let _ = write!(self.line.text, "N{} ", self.block);
        }
        self.line.text.push_str(text);
        self.chain.after_line(text);
        self.send(op)
    }

    /// Writes one block, numbered in ISO, that `write` builds in place (no copy of its own).
    fn put_with(&mut self, write: impl FnOnce(&mut String), op: Option<u32>) -> io::Result<()> {
        self.flush_pending()?;
        self.line.text.clear();
        if self.dialect == Dialect::Iso {
            self.block = if self.block >= BLOCK_WRAP {
                BLOCK_STEP
            } else {
                self.block + BLOCK_STEP
            };
            use std::fmt::Write as _;
            let _ = write!(self.line.text, "N{} ", self.block);
        }
        write(&mut self.line.text);
        // A motion block: `write_block` keeps the chain where it knows what it wrote.
        self.chain.forget();
        self.send(op)
    }

    /// Writes the carried beam switch where the path stands now: another line comes before the
    /// path reaches its place (a stop, a power step, the program's end), and a switch is
    /// never written after a line that came after it.
    fn flush_pending(&mut self) -> io::Result<()> {
        if let Some(p) = self.pending.take() {
            for l in &p.lines {
                self.put(l, p.tag)?;
            }
            self.after_off = p.off;
        }
        Ok(())
    }

    /// Writes a line as is (ISO's `%` and program number).
    fn raw(&mut self, text: &str, op: Option<u32>) -> io::Result<()> {
        self.line.text.clear();
        self.line.text.push_str(text);
        self.send(op)
    }

    /// Hands `self.line` to the sink.
    fn send(&mut self, op: Option<u32>) -> io::Result<()> {
        let len = self.line.text.len();
        self.stats.lines += 1;
        self.stats.bytes += len as u64 + 1;
        self.stats.longest_line = self.stats.longest_line.max(len);
        self.after_off = false;
        self.line.op = op;
        (self.sink)(&self.line)
    }
}

/// A word's value as last written, in a buffer that is reused (`set` copies into it), and the
/// number it was formatted from.
#[derive(Default)]
struct Last {
    text: String,
    /// The bits of the number `text` was formatted from.
    value: u64,
    written: bool,
}

impl Last {
    fn is(&self, v: &str) -> bool {
        self.written && self.text == v
    }

    /// Whether `x` was the number last written: the same bits format to the same text, so a
    /// word that did not change (the row's Y, the feed, on every block of a dot row) is
    /// neither formatted nor compared as text.
    fn is_number(&self, x: f64) -> bool {
        self.written && self.value == x.to_bits()
    }

    /// `v`, formatted from the number `x`, is written.
    fn set(&mut self, v: &str, x: f64) {
        self.text.clear();
        self.text.push_str(v);
        self.value = x.to_bits();
        self.written = true;
    }

    fn unset(&mut self) {
        self.written = false;
    }
}

/// The least motion of a linear axis a program to 1 nm writes (`Modal::fine`): half the
/// 0.1 µm step of the other programs, so no axis moves in a block where it did not before.
const FINE_MIN_MOVE_MM: f64 = 5e-5;

/// The modal state of the controller as the program leaves it.
struct Modal {
    /// Current motion mode (G0, G1, G2, G3).
    motion: Option<&'static str>,
    /// Last F word, unset after a rapid so the next feed move repeats it.
    feed: Last,
    /// Last written value of each machine axis; unset before the first move.
    words: Vec<Last>,
    /// Scratch buffer a word's value is formatted into before it is compared with the last.
    scratch: String,
    /// Where the spot is, part coordinates.
    pos: P3,
    /// Axis positions of `pos`: the planned axes of the last block written.
    q: Axes,
    laser_on: bool,
    power_w: f64,
    /// The S word in force (GRBL family): the last one written, `None` when unknown.
    s: Option<String>,
    /// Last traceability comment.
    location: String,
    /// Feed moves are in inverse time (G93): on machines whose moves mix linear and rotary
    /// axes, F is 1 / block time, so the controller holds the spot's surface speed.
    inverse_time: bool,
    /// Linear axis words to 1 nm (`format::fine_number`) instead of 0.1 µm: on a machine
    /// whose feed moves are in inverse time the block's time is fixed by F, so a coordinate's
    /// rounding becomes a speed error of its size over the block's length, which on the
    /// shortest oriented blocks (a few hundredths of a mm) was 0.02 % of the surface speed.
    fine: bool,
    /// The direction of travel where the last block written ends (part space, unit; `None`
    /// before the first): a carried beam switch cuts a block only where it continues that
    /// one tangentially (`lead::cut_at`).
    dir: Option<P3>,
    /// The last block written turned a rotary axis: LinuxCNC joins it to the next one by a
    /// parabolic blend (`lead::shift`), never by cutting the next block.
    turned: bool,
    /// The time of the last block written where it is a G93 feed, s (`chain`).
    block_s: Option<f64>,
}

pub(super) fn write(
    job: &Job,
    facts: Option<&super::PlanFacts>,
    lit: &mut super::facts::LitBlocks<'_>,
    dialect: Dialect,
    options: &EmitOptions<'_>,
    checked: &Checked<'_>,
    sink: &mut dyn FnMut(&NcLine) -> io::Result<()>,
) -> Result<EmitStats, EmitError> {
    let program = &job.program;
    let machine = &program.machine;
    let post = checked.post;
    let mut out = Out {
        sink,
        dialect,
        block: 0,
        stats: EmitStats::default(),
        after_off: false,
        line: NcLine {
            text: String::with_capacity(128),
            op: None,
        },
        pending: None,
        chain: chain::Chain::default(),
        tolerance: 0.0,
        split_len: None,
    };
    let words = |power_w: f64| LaserWords {
        power_w,
        max_power_w: machine.laser.max_power_w,
        s_max: post.s_max,
    };

    // Header.
    if dialect == Dialect::Iso {
        out.raw("%", None)?;
        out.raw("O0001", None)?;
    }
    let version = env!("CARGO_PKG_VERSION");
    for c in [
        format!("generated by lase {version} for {dialect}"),
        format!("recipe {}", program.recipe),
        format!("machine {}", machine.name),
    ] {
        out.put(&format::comment(&c, COMMENT_MAX), None)?;
    }
    out.put("G21 G90 G17 G94", None)?;
    if let crate::program::JobOrigin::Work(g) = program.planner.origin {
        // A named work offset (issue 20): the operator's own, selected and never written
        // over (no G10 here), so the program runs where that offset puts it.
        out.put(&format!("G{g}"), None)?;
    }
    if dialect == Dialect::LinuxCnc {
        // Path blending within the junction deviation the planner assumed. `Q0` turns off
        // canon's naive-CAM detector (Q defaults to P), which would join lase's short, nearly
        // collinear lit lines into one chord: lase plans those lines and their corners itself,
        // and a chord starting at a flying switch meets the lead-in off its line, so tp blends
        // that junction and switches after the blend (serial_number's edges 0.7 mm late).
        let p = format::number(program.planner.junction_deviation_mm);
        out.put(&format!("G64 P{p} Q0"), None)?;
        out.tolerance = program.planner.junction_deviation_mm;
        if let (Some(inputs), false) = (machine.settle.linuxcnc_inputs, program.settles.is_empty())
        {
            for l in settle::linuxcnc_sub(inputs) {
                out.put(&l, None)?;
            }
        }
    }

    // GRBL family: the beam flies on S words where the post allows (`motion::beam`); the
    // arms are where it is switched on with M3/M4 S0, each at rest.
    let flying = dialect.is_grbl_family() && beam::flies(post);
    let arms = if flying {
        beam::arms(&program.ops, post)
    } else {
        Vec::new()
    };
    let arm_line = |dynamic: bool| {
        let line = format::fill(&post.laser_on[0], words(0.0));
        if dynamic {
            self::dynamic(dialect, &line)
        } else {
            line
        }
    };
    let s_word = |power_w: f64| format::fill(&post.power[0], words(power_w));
    let header_arm = arms.first().filter(|a| a.before.is_none());
    if let Some(a) = header_arm {
        // The first arm, in the header: the machine is at rest here anyway.
        out.put(&arm_line(a.dynamic), None)?;
    }

    let mut m = Modal {
        motion: None,
        feed: Last::default(),
        words: (0..machine.axes.len()).map(|_| Last::default()).collect(),
        scratch: String::with_capacity(32),
        pos: program.start,
        q: job.start,
        laser_on: false,
        power_w: 0.0,
        s: header_arm.map(|_| s_word(0.0)),
        location: String::new(),
        inverse_time: false,
        fine: job.kin.inverse_time(),
        dir: None,
        turned: false,
        block_s: None,
    };
    let inverse_time = job.kin.inverse_time();
    // LinuxCNC's synchronized outputs lead its joints (`lead`): the beam switches are carried
    // along the path, on programs in units per minute.
    // On a rotary attachment's G93 programs too: their X-only blocks meet tangentially, and
    // where a block turns A the junction is moved instead (`lead::shift`).
    let parabolic = dialect == Dialect::LinuxCnc && inverse_time && !job.kin.oriented();
    // An oriented machine's G93 blocks all turn a rotary axis: where a lead continues the lit
    // chord it meets in the axes, that junction moves as on a rotary attachment.
    let shifts = dialect == Dialect::LinuxCnc && inverse_time;
    let servo_s = (dialect == Dialect::LinuxCnc && (!inverse_time || shifts))
        .then(|| machine.servo_period_s());
    // Image-row power steps and pulse triggers are carried on programs in units per minute
    // only: a cut G93 block that turns A would need the parabolic rules `lead::shift` follows.
    let servo_g94 = servo_s.filter(|_| !inverse_time);
    let edge_lead = |i: usize, end: usize| {
        servo_s.map_or(0.0, |t| {
            lead::distance(lead::edge_speeds(job, facts, i)[end], t)
        })
    };
    // The carry at an edge passed at the plan's speeds there: `lead::shift` asks for the
    // entry speed of the lit op after an unlit one (end 0) or the exit speed of a lit op.
    let edge_lead_at = |(j, end): (usize, usize)| edge_lead(j, end);
    let arc_axes = validate::arc_axes(machine);
    let mut train = pulse::Train::default();
    // What pulse lowering needs of this program (the same for every op).
    let gate = pulse::Gate {
        dialect,
        post,
        machine,
        op_axes: &job.op_axes,
        arc_axes,
        words: &words,
    };
    let ops = &program.ops;
    // Row starts settled on the control (validated: this dialect can), each called once the
    // op that brings the table there is written.
    let settle_axes = (machine.axis_index("X"), machine.axis_index("Y"));
    // A live link settles them itself (`link::settle`).
    let nc_settles: &[crate::program::Settle] = if options.live { &[] } else { &program.settles };
    let mut settles = nc_settles.iter().peekable();
    let mut settle_upto = |i: usize, out: &mut Out<'_>, m: &mut Modal| -> io::Result<()> {
        while let Some(s) = settles.next_if(|s| s.op < i) {
            let (Some(x), Some(y)) = settle_axes else {
                continue;
            };
            let q = job.op_axes.get(s.op);
            let line = settle::call(dialect, machine, s, [q[x], q[y]]);
            out.put(&line, Some(s.op as u32))?;
            // The call leaves the motion mode and (ISO's macro) the feed unknown.
            m.motion = None;
            m.feed.unset();
        }
        Ok(())
    };
    // Whether the last op that moved the spot was lit (a lead-out follows a lit move).
    let mut last_move_lit = false;
    for (i, op) in ops.iter().enumerate() {
        let tag = Some(i as u32);
        settle_upto(i, &mut out, &mut m)?;
        if options.comments
            && let Some(locate) = options.locate
        {
            let loc = locate(op.span);
            if !loc.is_empty() && loc != m.location {
                out.put(&format::comment(&loc, COMMENT_MAX), tag)?;
                m.location = loc;
            }
        }
        match &op.kind {
            OpKind::Dwell { seconds } => {
                out.put(&dwell(dialect, *seconds), tag)?;
            }
            OpKind::MCode { code, comment } => {
                let mut text = format!("M{code}");
                if let (true, Some(c)) = (options.comments, comment) {
                    let room = COMMENT_MAX.saturating_sub(text.len() + 1 + iso_prefix(dialect));
                    if room > 4 {
                        text.push(' ');
                        text.push_str(&format::comment(c, room));
                    }
                }
                out.put(&text, tag)?;
            }
            OpKind::Event { name } => {
                // Validated: the event exists and has codes for this dialect.
                if let Some(ev) = machine.events.get(name) {
                    for line in dialect.lookup(&ev.codes).into_iter().flat_map(|(_, c)| c) {
                        out.put(line, tag)?;
                    }
                    if ev.dwell_s > 0.0 {
                        out.put(&dwell(dialect, ev.dwell_s), tag)?;
                    }
                }
            }
            OpKind::Output { name, on, .. } => {
                // Validated: the output has lines for this dialect. A non-stopping one
                // (LinuxCNC `M62`/`M63`) takes effect as the next move starts.
                let lines = machine
                    .outputs
                    .get(name)
                    .and_then(|o| dialect.lookup(&o.posts));
                if let Some((_, l)) = lines {
                    for line in if *on { &l.on } else { &l.off } {
                        out.put(line, tag)?;
                    }
                }
            }
            OpKind::Fire { .. } => {
                pulse::write_fire(op, &mut out, &gate, tag)?;
                // Its laser lines leave the S word where its last pulse put it.
                m.s = None;
            }
            OpKind::Rapid { .. } | OpKind::Line { .. } | OpKind::Arc { .. } => {
                if let Some(a) = arms.iter().find(|a| a.before == Some(i)) {
                    // A re-arm (M3 ↔ M4, or after a fire window): motion plans a stop here.
                    out.put(&arm_line(a.dynamic), tag)?;
                    m.s = Some(s_word(0.0));
                }
                if !op.moves_from(m.pos) {
                    continue;
                }
                // An image row is written one block per pixel run (`row`); any other op as is.
                let blocks = if dialect.is_grbl_family() {
                    Vec::new()
                } else {
                    lit.of(i)?
                };
                // A row held to its feed throughout: no sub-block of the plan's own.
                let at_feed = match (&op.kind, blocks.as_slice()) {
                    (_, []) => true,
                    (OpKind::Line { feed_mm_s, .. }, [b]) => b.v_cap >= feed_mm_s * (1.0 - 1e-3),
                    _ => false,
                };
                let carry = servo_g94
                    .filter(|_| at_feed)
                    .and_then(|t| lead::row(job, i, m.pos, t, lead::edge_speeds(job, facts, i)));
                let pieces = row::pieces(job, blocks, i, m.pos, m.q, carry);
                // The beam-off's lead the last run already ran into the lead-out.
                let ran_on = carry.filter(|c| c.past_end).map_or(0.0, |c| c.lead);
                let n_pieces = pieces.len();
                // A flying switch at this op's end on a parabolic junction: where the block
                // ends instead (`lead::shift`).
                let shifted = if shifts && n_pieces == 1 {
                    lead::shift(job, i, (m.pos, &m.q), edge_lead_at, false)
                } else {
                    None
                };
                // Or, where the blend is too short for that rule, by tp.c's replay.
                let timed = match (shifted, servo_s) {
                    (None, Some(t)) if shifts && n_pieces == 1 => {
                        timing::timed_lead_in(job, i, (m.pos, &m.q), t)
                    }
                    _ => None,
                };
                let shifted = shifted.or(timed.map(|(p, q, _)| (p, q)));
                // A lit op's junction with its lead-out its last block is timed about
                // (`timing::off_edge_timing`): the one moved, or where the blend is too short
                // for that rule (`short`), where it would be.
                let off_at = match (shifted, servo_s) {
                    _ if !(shifts && n_pieces == 1 && op.laser().is_some()) => None,
                    (Some(at), Some(_)) => Some((at, false)),
                    (None, Some(_)) => {
                        lead::shift(job, i, (m.pos, &m.q), edge_lead_at, true).map(|at| (at, true))
                    }
                    (_, None) => None,
                };
                // A lead-out after a lit move, before a stop: in two blocks (`lead::split`).
                let split = shifts
                    && n_pieces == 1
                    && last_move_lit
                    && op.laser().is_none()
                    && lead::split(job, i, (m.pos, &m.q), m.turned);
                last_move_lit = op.laser().is_some();
                for (k, piece) in pieces.into_iter().enumerate() {
                    let (op, q_end, blocks) = (&*piece.op, piece.q, piece.blocks);
                    // The runs of a row are all lit: only its last piece looks past the row.
                    let more = k + 1 < n_pieces;
                    let coupled = op.laser().is_some_and(|l| l.couple == Coupling::Speed);
                    train.pso(op, m.laser_on, &mut out, post, tag)?;
                    if let Some(laser) = op.laser() {
                        let first = blocks.first().map_or(laser.power_w, |b| b.power_w);
                        if flying {
                            // Armed already: the S word on the block switches the beam.
                            m.laser_on = true;
                            m.power_w = laser.power_w;
                        } else if !m.laser_on {
                            let lines: Vec<String> = post
                                .laser_on
                                .iter()
                                .map(|t| {
                                    let line = format::fill(t, words(first));
                                    if coupled {
                                        dynamic(dialect, &line)
                                    } else {
                                        line
                                    }
                                })
                                .collect();
                            // A switch off still carried is written first, where it stands.
                            out.flush_pending()?;
                            let left = if k == 0 { edge_lead(i, 0) } else { 0.0 };
                            if left > 0.0 {
                                out.pending = Some(lead::Pending {
                                    lines,
                                    left,
                                    off: false,
                                    servo_s: servo_s.unwrap_or(0.0),
                                    v: lead::edge_speeds(job, facts, i)[0],
                                    tag,
                                });
                            } else {
                                for l in &lines {
                                    out.put(l, tag)?;
                                }
                            }
                            m.laser_on = true;
                            m.power_w = first;
                        } else if blocks.is_empty()
                            && (laser.power_w - m.power_w).abs()
                                > 1e-9 * laser.power_w.abs().max(1.0)
                        {
                            for t in &post.power {
                                out.put(&format::fill(t, words(laser.power_w)), tag)?;
                            }
                            m.power_w = laser.power_w;
                        }
                    }
                    // By machine, not dialect: every dialect that can drive an oriented machine's
                    // (or a rotary attachment's) axes writes its feed moves in inverse time.
                    if inverse_time && !m.inverse_time && matches!(op.kind, OpKind::Line { .. }) {
                        out.put("G93", tag)?;
                        m.inverse_time = true;
                    }
                    let gated = if blocks.is_empty() {
                        train.gated(ops, i, post)
                    } else {
                        None
                    };
                    if let Some(pitch) = gated {
                        let lead = servo_g94.map_or(0.0, |t| {
                            lead::gated(&ops[i], lead::edge_speeds(job, facts, i), t)
                        });
                        pulse::write_gated(
                            ops, i, pitch, lead, &mut train, &mut out, &mut m, &gate, tag,
                        )?;
                    } else if blocks.is_empty() {
                        let to = op.target().unwrap_or(m.pos);
                        let cap = if dialect.is_grbl_family() || op.laser().is_some() || more {
                            None
                        } else {
                            lead::lead_cap(job, facts, i, &ops[i + 1..], to)
                        };
                        let (to, q_end) = shifted.unwrap_or((to, q_end));
                        // A lead-in whose junction moved (`lead::shift`) into a lit block:
                        // slower by the blend's mean gain, so tp's summed speeds cross the
                        // on-edge at the plan's (`lead::blend_gain`).
                        let cap = match (&op.kind, shifted, servo_s) {
                            _ if timed.is_some() => timed.map(|(.., speed)| speed),
                            (OpKind::Line { feed_mm_s, .. }, Some(_), Some(t))
                                if op.laser().is_none() =>
                            {
                                let v = cap.unwrap_or(*feed_mm_s);
                                let len = crate::program::dist(m.pos, to);
                                let gain = lead::blend_gain(machine, &m.q, &q_end, len, t);
                                // From rest, tp's own arithmetic; else the mean gain.
                                let at = ((m.pos, &m.q), (to, &q_end));
                                timing::lead_in_speed(job, i, at.0, at.1, v, t)
                                    .or(Some((v - gain).max(0.5 * v)))
                            }
                            _ => cap,
                        };
                        // A lit block before a split lead-out: timed by tp.c's arithmetic.
                        let (to, q_end, cap) = match (servo_s, off_at) {
                            (Some(t), Some(((p, qp), short))) => {
                                let at = ((m.pos, &m.q), (p, &qp));
                                let held = cap.unwrap_or(f64::INFINITY);
                                timing::off_edge_timing(&mut out, job, i, at, held, t, short)
                                    .map_or((to, q_end, cap), |(p, q, c)| (p, q, Some(c)))
                            }
                            _ => (to, q_end, cap),
                        };
                        if split {
                            let (from, from_q) = (m.pos, m.q);
                            let sub = lead::retarget(op, to);
                            // Where `timing::off_edge_timing` chose, else the mean gain's.
                            let len = sub.length_from(from);
                            let chosen = out.split_len.take().filter(|&(j, _)| j == i);
                            let f = match (chosen, &op.kind, servo_s) {
                                (Some((_, l)), ..) => (l / len).clamp(0.0, 0.9),
                                (None, OpKind::Line { feed_mm_s, .. }, Some(t)) => {
                                    lead::split_at(machine, (&from_q, &q_end), len, *feed_mm_s, t)
                                }
                                _ => 0.5,
                            };
                            let (mid, mid_q) = part_way(&sub, (from, &from_q), &q_end, f, arc_axes);
                            write_block(
                                &mut out,
                                &mut m,
                                (op, mid, mid_q, cap),
                                machine,
                                arc_axes,
                                tag,
                            )?;
                        }
                        if !flying {
                            write_block(
                                &mut out,
                                &mut m,
                                (op, to, q_end, cap),
                                machine,
                                arc_axes,
                                tag,
                            )?;
                        } else {
                            out.put_with(
                                |line| {
                                    motion_line(
                                        line, op, to, q_end, cap, &mut m, machine, arc_axes,
                                    );
                                    if flying && !matches!(op.kind, OpKind::Rapid { .. }) {
                                        // Every feed move carries its power, S0 when unlit: in laser
                                        // mode an S word on a G1/G2/G3 block changes power as the
                                        // block starts, without a stop. A G0 needs none: GRBL runs
                                        // rapids with the laser off (gcode.c: a block not in
                                        // G1/G2/G3 is GC_PARSER_LASER_DISABLE'd).
                                        let s = s_word(op.laser().map_or(0.0, |l| l.power_w));
                                        if m.s.as_deref() != Some(s.as_str()) {
                                            line.push(' ');
                                            line.push_str(&s);
                                            m.s = Some(s);
                                        }
                                    }
                                },
                                tag,
                            )?;
                            out.stats.motion_blocks += 1;
                        }
                    } else {
                        let (from, from_q) = (m.pos, m.q);
                        let mut blocks = blocks;
                        // A rotary attachment's block that turns no rotary axis lies on the
                        // surface part way too (X along it), and LinuxCNC joins such blocks
                        // tangentially: its sub-blocks keep the plan's speeds (a lit X block
                        // out of a corner ran at its mean 21.4 mm/s, crossing its edge there
                        // where the plan was back at 30).
                        let turned = lead::turns(machine, &from_q, &q_end);
                        // The plan's speed where this op ends at a beam-off edge passed
                        // moving, on LinuxCNC.
                        let off_edge = (servo_s.is_some()
                            && !(more
                                || next_move_lit(&ops[i + 1..], op.target().unwrap_or(from))))
                        .then(|| lead::edge_speeds(job, facts, i)[1])
                        .filter(|&v| v > 0.0);
                        if parabolic && !coupled {
                            if turned {
                                // Its sub-blocks as long as tp.c's parabolic blends carry
                                // at speed (`lead::triangle_s`): a lit block of the "S"
                                // held whole ran at its mean 23 where the plan passed its
                                // end at 45.7.
                                let total_len = op.length_from(from);
                                let tri = |ds: f64| {
                                    lead::triangle_s(machine, &from_q, &q_end, ds / total_len)
                                };
                                // Ending at a beam-off edge passed moving: the last block the
                                // shortest tp carries, held no slower than the edge (below).
                                if off_edge.is_some() {
                                    power::merge_short_from_back(&mut blocks, tri);
                                } else {
                                    power::merge_short(&mut blocks, tri);
                                }
                            }
                        } else if inverse_time && !coupled {
                            // In inverse time a block's F is its time: a lit move at constant
                            // power is held whole, in the plan's time, so no block ends part
                            // way, on the joints' straight line off the surface and its normal.
                            power::merge_front(&mut blocks, f64::INFINITY);
                        }
                        if dialect == Dialect::LinuxCnc {
                            lead::arc_first_block(
                                op,
                                from,
                                &mut blocks,
                                program.planner.junction_deviation_mm,
                            );
                        }
                        let total = blocks.last().map_or(0.0, |b| b.s_end);
                        for (k, b) in blocks.iter().enumerate() {
                            let changed = post.power.first().is_some_and(|t| {
                                format::fill(t, words(b.power_w))
                                    != format::fill(t, words(m.power_w))
                            });
                            if changed {
                                for t in &post.power {
                                    let line = format::fill(t, words(b.power_w));
                                    out.put(&synchronized(dialect, &line), tag)?;
                                }
                                m.power_w = b.power_w;
                            }
                            let f = if k + 1 == blocks.len() || total <= 0.0 {
                                1.0
                            } else {
                                b.s_end / total
                            };
                            let (to, q) = match shifted {
                                Some(end) if k + 1 == blocks.len() => end,
                                _ => part_way(op, (from, &from_q), &q_end, f, arc_axes),
                            };
                            // The last sub-block before a beam-off edge passed moving: no
                            // slower than the plan at the edge, which the lead-out's first
                            // part is held to (`write_block`), so LinuxCNC crosses the edge at
                            // the plan's speed where the plan speeds up through it (its mean
                            // is below that speed; above it where the plan slows down). In a
                            // parabolic chain tp switches as the next block overtakes this
                            // one's fading speed (`tpDoParabolicBlending`), about this block's
                            // own speed: rotary_engrave's "S" went dark at 41.9 of 45.7.
                            let cap = match off_edge {
                                Some(v) if k + 1 == blocks.len() => b.v_cap.max(v),
                                _ => b.v_cap,
                            };
                            let (to, q, cap) = match (servo_s, off_at) {
                                (Some(t), Some(((p, qp), short))) if k + 1 == blocks.len() => {
                                    let at = ((m.pos, &m.q), (p, &qp));
                                    timing::off_edge_timing(&mut out, job, i, at, cap, t, short)
                                        .unwrap_or((to, q, cap))
                                }
                                _ => (to, q, cap),
                            };
                            write_block(
                                &mut out,
                                &mut m,
                                (op, to, q, Some(cap)),
                                machine,
                                arc_axes,
                                tag,
                            )?;
                        }
                    }
                    if flying && m.laser_on && !(more || next_move_lit(&ops[i + 1..], m.pos)) {
                        // No M5 (it would stop the table): the next feed move says S0.
                        m.laser_on = false;
                    } else if m.laser_on && !(more || next_move_lit(&ops[i + 1..], m.pos)) {
                        let lines: Vec<String> = post
                            .laser_off
                            .iter()
                            .map(|t| format::fill(t, words(0.0)))
                            .collect();
                        let left = if ran_on > 0.0 { 0.0 } else { edge_lead(i, 1) };
                        // A trigger edge the pulse writer carried as far past the end (its
                        // last gate's fall) goes with it; any other switch still carried is
                        // written first, where it stands.
                        if let Some(p) = out
                            .pending
                            .as_mut()
                            .filter(|p| left > 0.0 && (p.left - left).abs() < 1e-4)
                        {
                            p.lines.extend(lines);
                            p.off = true;
                        } else if left > 0.0 {
                            out.flush_pending()?;
                            out.pending = Some(lead::Pending {
                                lines,
                                left,
                                off: true,
                                servo_s: servo_s.unwrap_or(0.0),
                                v: lead::edge_speeds(job, facts, i)[1],
                                tag,
                            });
                        } else {
                            out.flush_pending()?;
                            for l in &lines {
                                out.put(l, tag)?;
                            }
                            out.after_off = true;
                        }
                        m.laser_on = false;
                    }
                }
            }
        }
    }

    settle_upto(ops.len(), &mut out, &mut m)?;
    out.flush_pending()?;
    if m.inverse_time {
        // Back to units-per-minute feeds, the mode any program after this one expects.
        out.put("G94", None)?;
    }
    // Footer: the beam off (always, for safety), then the program end.
    let final_off: Vec<String> = post
        .laser_off
        .iter()
        .map(|t| {
            let line = format::fill(t, words(0.0));
            if dialect == Dialect::LinuxCnc {
                immediate(&line)
            } else {
                line
            }
        })
        .collect();
    let already_off = out.after_off
        && final_off
            .iter()
            .zip(&post.laser_off)
            .all(|(a, t)| *a == format::fill(t, words(0.0)));
    if !already_off {
        for l in &final_off {
            out.put(l, None)?;
        }
    }
    match dialect {
        Dialect::Iso => {
            out.put("M30", None)?;
            out.raw("%", None)?;
        }
        Dialect::LinuxCnc | Dialect::Grbl | Dialect::GrblHal => out.put("M2", None)?,
    }
    Ok(out.stats)
}

fn iso_prefix(dialect: Dialect) -> usize {
    if dialect == Dialect::Iso { 7 } else { 0 }
}

fn dwell(dialect: Dialect, seconds: f64) -> String {
    let s = format::number(seconds);
    match dialect {
        Dialect::Iso => format!("G4 X{s}"),
        Dialect::LinuxCnc | Dialect::Grbl | Dialect::GrblHal => format!("G4 P{s}"),
    }
}

/// LinuxCNC's M62/M63 change an output at the start of the next motion; at the program end no
/// motion follows, so the final beam-off uses the immediate M64/M65 on the same output.
fn immediate(line: &str) -> String {
    line.replace("M63", "M65")
        .replace("m63", "m65")
        .replace("M62", "M64")
        .replace("m62", "m64")
}

/// GRBL's dynamic laser mode (grblHAL's too): `M4` scales the power by the current speed over
/// the programmed feed, so a coupled section switches on with `M4` where the post writes `M3`.
fn dynamic(dialect: Dialect, line: &str) -> String {
    if !dialect.is_grbl_family() {
        return line.to_string();
    }
    line.split(' ')
        .map(|w| match w.to_ascii_uppercase().as_str() {
            "M3" | "M03" => "M4",
            _ => w,
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// LinuxCNC's `M68` sets the analog output immediately and breaks blending; `M67` sets it at
/// the start of the next motion, which is where a coupled sub-block's power belongs.
fn synchronized(dialect: Dialect, line: &str) -> String {
    if dialect == Dialect::LinuxCnc {
        line.replace("M68", "M67").replace("m68", "m67")
    } else {
        line.to_string()
    }
}

/// Whether the next op that moves the spot is lit (non-motion ops in between keep the beam
/// as it is: the laser model of this module).
fn next_move_lit(rest: &[Op], pos: P3) -> bool {
    rest.iter()
        .find(|o| o.moves_from(pos))
        .is_some_and(|o| o.laser().is_some())
}
