//! From an accepted G-code line to planner blocks: arcs split into chords by `$12` (GRBL's
//! `mc_arc`), each chord's rate (feed or G93 time, capped by `$110`–`$115`, scaled by the
//! overrides), the soft-limit check, and the line's work fed into the bounded planner buffer
//! (its `ok` waits until everything is in).

use super::record::{LineResult, MotionEffect, effect_of};
use super::{Controller, PBlock, Pending, St, Work};
use crate::link::sim::gcode::{self, Step};
use crate::link::{AxisPos, MAX_AXES};
use std::collections::VecDeque;

impl Controller {
    /// The planner blocks of a move, through GRBL's `plan_buffer_line` (arcs split by `$12`,
    /// rates and accelerations from `$110`… and `$120`…, the overrides, junctions by `$11`).
    pub(super) fn chords(
        &mut self,
        seq: u64,
        mv: &gcode::Move,
        rest_after: f64,
    ) -> VecDeque<PBlock> {
        // Settings may have changed since the last line (`$120=…`).
        let limits = self
            .cfg
            .firmware
            .limits(&self.settings, self.cfg.planner_blocks);
        if limits != self.pl.limits {
            self.pl.limits = limits;
        }
        let (feed_ov, rapid_ov) = (f64::from(self.overrides[0]), f64::from(self.overrides[1]));
        self.pl
            .segments(mv)
            .iter()
            .filter_map(|seg| {
                // Whether the buffer is empty is decided when the block joins it.
                let b = self.pl.block(seq, seg, false, feed_ov, rapid_ov)?;
                Some(PBlock { seq, b, rest_after })
            })
            .collect()
    }

    /// A block joins the planner buffer: from rest when the buffer was empty (GRBL's
    /// `plan_buffer_line`), and the running block may now end faster.
    pub(super) fn push_block(&mut self, mut b: PBlock) {
        if self.planner.is_empty() {
            b.b.max_entry_sq = 0.0;
        }
        self.planner.push_back(b);
        self.replan_front();
    }

    pub(super) fn outside_travel(&self, p: AxisPos) -> bool {
        if self.setting(20) != 1.0 {
            return false;
        }
        (0..MAX_AXES).any(|k| match self.cfg.travel[k] {
            Some((lo, hi)) => p[k] < lo - 1e-6 || p[k] > hi + 1e-6,
            None => p[k].abs() > 1e-6,
        })
    }

    pub(super) fn gcode(&mut self, seq: u64, text: String, line: &[u8]) {
        let laser_mode = self.laser_mode();
        let block = match gcode::execute(line, &self.gc, laser_mode) {
            Ok(b) => b,
            Err(code) => {
                self.record(seq, text, LineResult::Error(code), None);
                self.reply(Err(code));
                return;
            }
        };
        let rest_after = gcode::rest_power(&block.next.modal, laser_mode);
        let mut work = VecDeque::new();
        let mut effect = effect_of(&self.gc, &block.next);
        for step in &block.steps {
            work.push_back(match step {
                Step::Sync => Work::Sync,
                Step::LaserAtRest(s) => Work::LaserAtRest(*s),
                Step::Coolant { flood, mist } => Work::Coolant(*flood, *mist),
                Step::Dwell(t) => {
                    effect.dwell_s = Some(*t);
                    Work::Dwell {
                        left: *t,
                        total: *t,
                        begun: false,
                    }
                }
                Step::Move(mv) => {
                    let chords = self.chords(seq, mv, rest_after);
                    if chords.iter().any(|b| self.outside_travel(b.b.to)) {
                        self.record(seq, text, LineResult::Alarm(2), None);
                        self.soft_limit();
                        return;
                    }
                    if !chords.is_empty() || mv.arc.is_some() {
                        effect.motion = Some(MotionEffect {
                            mode: block.next.modal.motion,
                            target: mv.target,
                            center: mv.arc.map(|a| a.center),
                            laser_s: mv.laser_s,
                            inverse_time_s: mv.inverse_time_s,
                        });
                    }
                    Work::Blocks(chords)
                }
                Step::ProgramEnd => {
                    effect.flow = Some("end");
                    Work::ProgramEnd
                }
                Step::Pause => {
                    effect.flow = Some("pause");
                    Work::Pause
                }
            });
        }
        self.gc = block.next;
        self.record(seq, text, LineResult::Ok, Some(effect));
        if self.state == St::Check {
            self.reply(Ok(()));
            return;
        }
        self.pending = Some(Pending { seq, work });
        self.progress_pending();
    }

    fn soft_limit(&mut self) {
        self.mpos = self.position();
        self.stop_motion();
        self.pending = None;
        self.rest_laser = 0.0;
        self.say("ALARM:2");
        self.say("[MSG:Reset to continue]");
        self.rec.alarms.push(2);
        self.state = St::Alarm { critical: true };
        self.note_laser();
    }

    /// Moves the line in progress along; `true` once it is answered.
    pub(super) fn progress_pending(&mut self) -> bool {
        let Some(mut p) = self.pending.take() else {
            return true;
        };
        while let Some(w) = p.work.front_mut() {
            match w {
                Work::Sync => {
                    if !self.planner.is_empty() || matches!(self.state, St::Hold { .. }) {
                        // `protocol_buffer_synchronize` starts what is queued, then waits.
                        self.auto_cycle_start();
                        self.pending = Some(p);
                        return false;
                    }
                    p.work.pop_front();
                }
                Work::LaserAtRest(s) => {
                    self.rest_laser = *s;
                    p.work.pop_front();
                    self.note_laser();
                }
                Work::Coolant(f, m) => {
                    let _ = (f, m);
                    p.work.pop_front();
                }
                Work::Dwell { left, total, begun } => {
                    if !*begun {
                        // `mc_dwell`: it begins once the loop has read the bytes before it.
                        *begun = true;
                        if let Some(r) = self.reading.take() {
                            *left += (r - self.now).max(0.0);
                        }
                    }
                    if *left > 0.0 {
                        self.pending = Some(p);
                        return false;
                    }
                    self.rec.dwells.push((p.seq, *total));
                    self.rec.executed_s = self.now;
                    // The loop reads on from the dwell's end.
                    self.reading = Some(self.now);
                    p.work.pop_front();
                }
                Work::Blocks(q) => {
                    while self.planner.len() < self.cfg.planner_blocks {
                        let Some(b) = q.pop_front() else { break };
                        self.push_block(b);
                        // Blocks queued at rest wait for the cycle start.
                        if self.state == St::Idle
                            && self.reading.is_none()
                            && self.start_at.is_none()
                        {
                            self.state = St::Cycle;
                        }
                    }
                    self.rec.max_planner_fill = self.rec.max_planner_fill.max(self.planner.len());
                    if !q.is_empty() {
                        // `mc_line` finds the planner full: cycle start.
                        self.auto_cycle_start();
                        self.pending = Some(p);
                        return false;
                    }
                    p.work.pop_front();
                }
                Work::ProgramEnd => {
                    self.say("[MSG:Pgm End]");
                    p.work.pop_front();
                }
                Work::Pause => {
                    self.state = St::Hold { complete: true };
                    p.work.pop_front();
                }
            }
        }
        self.reply(Ok(()));
        true
    }
}
