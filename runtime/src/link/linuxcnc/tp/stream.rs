//! The model of [`super::run_program_from`] fed a line at a time, holding what LinuxCNC's own
//! planner holds (issue 18: `lase plan` of a job of millions of lines keeps no table per
//! line): tp.c's queue is a ring of `DEFAULT_TC_QUEUE_SIZE` segments (2000, `emcmotcfg.h`:
//! "a TC_STRUCT is about 512 bytes so this queue is about a megabyte"), and
//! `tpRunOptimization` plans end speeds backward over `ARC_BLEND_OPTIMIZATION_DEPTH` (50) of
//! them; the task reads ahead of motion only as far as that queue lets it. So here a segment becomes its pieces as
//! soon as the next one is read (its junction, its scaled acceleration and its blend arcs need
//! nothing further), and a piece runs as soon as the 50 after it are made (its exit speed
//! plans to a stop 50 pieces on), so no more than about 51 pieces and two segments are held
//! (three while canon's naive-CAM detector may still lengthen the last:
//! [`super::read::Reader::chain_open`]).
//! The one exception is a chain of parabolic blends (and tangent joins after its first
//! junction) from rest to rest, which
//! [`super::servo::run_chain`] replays whole: whether a chain is replayed is known only at its
//! end (every segment a line that can move, ending at a stop), so its segments and pieces wait
//! there, one [`ChainSeg`] and one piece a line. Such chains are the rotary and cam sections
//! between two stops (a cam's profile, a rotary attachment's path), not a job's length.
//!
//! The arithmetic is [`super::run_program_from`]'s, operation for operation, in the same
//! order: `tests.rs` and `runtime/tests/controller_stream.rs` compare every field on every
//! example and on random programs.

use super::read::{Queue, Reader};
use super::servo::{ChainSeg, chain_seg, replayable, run_chain, tangent_share};
use super::{
    ACC_RATIO_TANGENTIAL, DRAIN_CYCLES, Joint, Kind, OPTIMIZATION_DEPTH, Piece, TpLimits, TpTime,
    junction, piece_time, quantised, seg_pieces,
};
use std::collections::{BTreeMap, VecDeque};

/// A piece waiting to run, with its chain time once that is known (`None` inside a chain
/// whose end is not read yet).
#[derive(Debug)]
struct Waiting {
    piece: Piece,
    chain: Option<Option<f64>>,
    /// Its segment's NC line.
    line: usize,
}

/// A run of segments joined by parabolic blends and tangent joins, from rest, its first
/// junction parabolic: a chain [`run_chain`] may replay.
#[derive(Debug)]
struct Chain {
    /// Index of its first piece.
    first_piece: usize,
    segs: Vec<ChainSeg>,
    /// Every segment a line with somewhere to go at some speed.
    ok: bool,
}

/// LinuxCNC's planner model, a line at a time ([module doc](self)).
#[derive(Debug)]
pub struct TpStream<'a> {
    limits: &'a TpLimits,
    reader: Reader,
    q: Queue,
    lines: usize,
    // Between segments: the junction before the next one, and its effects on the next one.
    prev_kind: Option<Kind>,
    prev_stops_after: bool,
    trim_start: f64,
    chain: Option<Chain>,
    // The pieces made and not yet run, the first one's index.
    pieces: VecDeque<Waiting>,
    piece_base: usize,
    // The forward pass.
    total: f64,
    beam_on: f64,
    outputs: BTreeMap<u32, bool>,
    stops: usize,
    entry: f64,
    /// When the current rest-to-rest run began.
    run_start: f64,
    last_seg: Option<usize>,
    starts: Option<Vec<(usize, f64)>>,
}

impl<'a> TpStream<'a> {
    /// The machine starting at `start` (as [`super::run_program_from`]); `starts`: keep
    /// [`TpTime::starts`] (a pair per segment) or leave it empty.
    pub fn new(limits: &'a TpLimits, start: &[f64], starts: bool) -> TpStream<'a> {
        TpStream {
            limits,
            reader: Reader::new(limits, start),
            q: Queue::default(),
            lines: 0,
            prev_kind: None,
            prev_stops_after: true,
            trim_start: 0.0,
            chain: None,
            pieces: VecDeque::new(),
            piece_base: 0,
            total: 0.0,
            beam_on: 0.0,
            outputs: BTreeMap::new(),
            stops: 0,
            entry: 0.0,
            run_start: 0.0,
            last_seg: None,
            starts: starts.then(Vec::new),
        }
    }

    /// Reads the next NC line (without its newline).
    pub fn line(&mut self, raw: &str) -> Result<(), String> {
        self.reader
            .line(&mut self.q, self.limits, self.lines, raw)?;
        self.lines += 1;
        // A segment's joint is final once the next one is final: read, and not a chain of
        // straight feeds canon's naive-CAM detector may still lengthen (its direction, so the
        // junction before it, moves as it grows).
        let open = usize::from(self.reader.chain_open());
        while self.q.segs.len() >= 2 + open {
            self.make(false);
        }
        self.run(false);
        Ok(())
    }

    /// After the last line: the model's times.
    pub fn finish(mut self) -> TpTime {
        let n = self.q.count();
        if n == 0 {
            return TpTime {
                total_s: 0.0,
                beam_on_s: 0.0,
                segments: 0,
                stops: 0,
                starts: Vec::new(),
            };
        }
        while !self.q.segs.is_empty() {
            self.make(true);
        }
        self.run(true);
        TpTime {
            total_s: self.total,
            beam_on_s: self.beam_on,
            segments: n,
            stops: self.stops + self.q.stops,
            starts: self.starts.unwrap_or_default(),
        }
    }

    /// Makes the first queued segment into its pieces: the one after it is read, or `end`.
    fn make(&mut self, end: bool) {
        let cycle = self.limits.cycle_s;
        let i = self.q.base;
        let last = end && self.q.segs.len() == 1;
        let joint = self.q.joints[0];
        let kind = match joint {
            None if !last => Some(junction(
                &self.q.segs[0],
                &self.q.segs[1],
                self.q.tolerances[1],
                cycle,
            )),
            _ => None,
        };
        let (Some(s), Some(_), Some(tolerance)) = (
            self.q.segs.pop_front(),
            self.q.joints.pop_front(),
            self.q.tolerances.pop_front(),
        ) else {
            return;
        };
        self.q.base += 1;
        // tpGetScaledAccel, as the whole model multiplies it: the tangent before, then after.
        let mut acc = s.acc * if s.arc { ACC_RATIO_TANGENTIAL } else { 1.0 };
        if let Some(Kind::Tangent { keep, .. }) = self.prev_kind {
            acc *= keep;
        }
        if let Some(Kind::Tangent { keep, .. }) = kind {
            acc *= keep;
        }
        // Halved by its own parabolic term condition only (`super`'s module doc).
        let half = match kind {
            Some(Kind::Parabolic { .. }) => true,
            None => last || matches!(joint, Some(Joint::Stop { drain: true, .. })),
            _ => false,
        };
        let a = if half { acc * 0.5 } else { acc };
        // Chains of parabolic blends and tangent joins (`servo::chain_times`): a run starts
        // where the last one ended, at a parabolic blend, and is replayed when it starts and
        // ends at rest.
        let first_piece = self.piece_base + self.pieces.len();
        let parabolic = matches!(kind, Some(Kind::Parabolic { .. }));
        let tangent = tangent_share(joint, kind);
        let stops_after =
            last || matches!(joint, Some(Joint::Stop { .. })) || matches!(kind, Some(Kind::Stop));
        if self.chain.is_none() && self.prev_stops_after && parabolic {
            self.chain = Some(Chain {
                first_piece,
                segs: Vec::new(),
                ok: true,
            });
        }
        let line = s.line;
        if let Some(c) = &mut self.chain {
            c.ok &= replayable(&s);
            c.segs.push(chain_seg(&s, tolerance, tangent));
        }
        let mut made = Vec::with_capacity(2);
        self.trim_start = seg_pieces(i, &s, (kind, joint), a, self.trim_start, cycle, &mut made);
        let pending = self.chain.is_some();
        for piece in made {
            self.pieces.push_back(Waiting {
                piece,
                chain: (!pending).then_some(None),
                line,
            });
        }
        if !parabolic
            && tangent.is_none()
            && let Some(c) = self.chain.take()
        {
            // The run ends here: replayed if it ends at a stop and every line can move.
            let times = (stops_after && c.ok).then(|| {
                let parabolic_end = last || matches!(joint, Some(Joint::Stop { drain: true, .. }));
                let run = run_chain(&c.segs, parabolic_end, cycle);
                (0..c.segs.len())
                    .map(|k| {
                        let end = run.switch_s.get(k + 1).copied().unwrap_or(run.total_s);
                        (end - run.switch_s[k]).max(0.0)
                    })
                    .collect::<Vec<_>>()
            });
            let from = c.first_piece - self.piece_base;
            for (k, w) in self.pieces.iter_mut().enumerate().skip(from) {
                w.chain = Some(times.as_ref().and_then(|t| t.get(k - from).copied()));
            }
        }
        self.prev_kind = kind;
        self.prev_stops_after = stops_after;
    }

    /// Runs the pieces whose exit speed and time are known: `end`, after the last segment.
    fn run(&mut self, end: bool) {
        let cycle = self.limits.cycle_s;
        let limits = self.limits;
        let lit = |outputs: &BTreeMap<u32, bool>| {
            limits
                .beam_output
                .is_some_and(|b| outputs.get(&b).copied().unwrap_or(false))
        };
        while let Some(front) = self.pieces.front() {
            let Some(chain_time) = front.chain else { break };
            let k = self.piece_base;
            let made = self.piece_base + self.pieces.len();
            if !end && made <= k + OPTIMIZATION_DEPTH {
                break;
            }
            let m = made; // at `end`, every piece
            // Backward (tpRunOptimization), as the whole model plans it from this piece.
            let exit = {
                let pieces = &self.pieces;
                let p = |j: usize| &pieces[j - k].piece;
                let entry_of = |j: usize, exit: f64| {
                    (exit * exit + 2.0 * p(j).acc * p(j).len)
                        .sqrt()
                        .min(p(j).v_top)
                };
                let exit_of = |j: usize, next_entry: f64| match p(j).joint {
                    Joint::Stop { .. } => 0.0,
                    Joint::Through { cap, ratio } => (next_entry / ratio).min(cap).min(p(j).v_top),
                };
                let last = (k + OPTIMIZATION_DEPTH).min(m - 1);
                let mut v = 0.0; // the exit of `last`: the horizon's stop
                for j in (k + 1..=last).rev() {
                    v = exit_of(j - 1, entry_of(j, v));
                }
                v
            };
            if k == 0 {
                self.apply_immediate(None);
            }
            let Some(Waiting { piece: p, line, .. }) = self.pieces.pop_front() else {
                break;
            };
            self.piece_base += 1;
            // Forward: from its entry to its exit, the outputs as they switch.
            if self.last_seg != Some(p.seg) {
                self.last_seg = Some(p.seg);
                if let Some(starts) = &mut self.starts {
                    starts.push((line, self.total));
                }
            }
            for &(o, on) in &p.dio {
                self.outputs.insert(o, on);
            }
            let v0 = self.entry.min(p.v_top);
            let v1 = exit
                .min((v0 * v0 + 2.0 * p.acc * p.len).sqrt())
                .min(p.v_top);
            let t = chain_time.unwrap_or_else(|| piece_time(&p, v0, v1));
            self.total += t;
            if lit(&self.outputs) {
                self.beam_on += t;
            }
            match p.joint {
                Joint::Stop { dwell, drain } => {
                    self.entry = 0.0;
                    let run = self.total - self.run_start;
                    let pad = quantised(run, cycle) - run;
                    self.total += pad;
                    if lit(&self.outputs) {
                        self.beam_on += pad;
                    }
                    let lit_before = lit(&self.outputs);
                    self.apply_immediate(Some(p.seg));
                    if k + 1 < m {
                        self.stops += 1;
                        let latency = if drain { DRAIN_CYCLES * cycle } else { 0.0 };
                        self.total += latency + dwell;
                        if lit_before || lit(&self.outputs) {
                            self.beam_on += latency;
                        }
                        if lit(&self.outputs) {
                            self.beam_on += dwell;
                        }
                    }
                    self.run_start = self.total;
                }
                Joint::Through { ratio, .. } => self.entry = v1 * ratio,
            }
        }
    }

    /// The immediate outputs queued at the stop after segment `at` (`None`: before the first).
    fn apply_immediate(&mut self, at: Option<usize>) {
        while let Some(&(i, o, on)) = self.q.immediate.front() {
            if i != at {
                break;
            }
            self.outputs.insert(o, on);
            self.q.immediate.pop_front();
        }
    }
}
