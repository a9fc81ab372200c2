//! From an accepted G-code line to planner blocks: arcs split into chords by `$12` (GRBL's
//! `mc_arc`), each chord's rate (feed or G93 time, capped by `$110`–`$115`, scaled by the
//! overrides), the soft-limit check, and the line's work fed into the bounded planner buffer
//! (its `ok` waits until everything is in).

use super::record::{LineResult, MotionEffect, effect_of};
use super::{Controller, PBlock, Pending, St, Work};
use crate::link::sim::gcode::{self, Step};
use crate::link::{AxisPos, MAX_AXES, Plane};
use std::collections::VecDeque;

impl Controller {
    pub(super) fn chords(&self, seq: u64, mv: &gcode::Move, rest_after: f64) -> VecDeque<PBlock> {
        let mut points = Vec::new();
        if let Some(arc) = mv.arc {
            let (a0, a1) = match arc.plane {
                Plane::Xy => (0, 1),
                Plane::Zx => (2, 0),
                Plane::Yz => (1, 2),
            };
            let c = arc.center;
            let r0 = [mv.from[a0] - c[a0], mv.from[a1] - c[a1]];
            let r1 = [mv.target[a0] - c[a0], mv.target[a1] - c[a1]];
            let others: Vec<usize> = (0..MAX_AXES).filter(|&k| k != a0 && k != a1).collect();
            let radius = r0[0].hypot(r0[1]);
            // GRBL's mc_arc: the angular travel, a full circle when start and end coincide.
            let mut ang = (r0[0] * r1[1] - r0[1] * r1[0]).atan2(r0[0] * r1[0] + r0[1] * r1[1]);
            let tol = self.setting(12).max(1e-6);
            if arc.ccw {
                if ang <= 1e-6 {
                    ang += std::f64::consts::TAU;
                }
            } else if ang >= -1e-6 {
                ang -= std::f64::consts::TAU;
            }
            let seg_len = (tol * (2.0 * radius - tol)).max(1e-12).sqrt();
            let n = ((0.5 * ang.abs() * radius / seg_len).floor() as usize).clamp(1, 100_000);
            let a_start = r0[1].atan2(r0[0]);
            for i in 1..n {
                let f = i as f64 / n as f64;
                let a = a_start + ang * f;
                let mut p = [0.0; MAX_AXES];
                p[a0] = c[a0] + radius * a.cos();
                p[a1] = c[a1] + radius * a.sin();
                // The other axes move linearly (a helix along the plane's normal).
                for &k in &others {
                    p[k] = mv.from[k] + (mv.target[k] - mv.from[k]) * f;
                }
                points.push(p);
            }
        }
        points.push(mv.target);
        let total_len: f64 = {
            let mut prev = mv.from;
            points
                .iter()
                .map(|p| {
                    let d = dist(prev, *p);
                    prev = *p;
                    d
                })
                .sum()
        };
        let mut out = VecDeque::new();
        let mut prev = mv.from;
        for p in points {
            let len = dist(prev, p);
            if len <= 1e-9 {
                prev = p;
                continue;
            }
            let dir: AxisPos = std::array::from_fn(|i| (p[i] - prev[i]).abs() / len);
            // The fastest the axes allow along this direction, mm/min (degrees count as mm,
            // as grblHAL counts them).
            let axis_cap = (0..self.cfg.firmware.axes())
                .filter(|&i| dir[i] > 1e-12)
                .map(|i| self.setting(110 + i as u32) / dir[i])
                .fold(f64::INFINITY, f64::min);
            let (rate, duration) = match mv.inverse_time_s {
                Some(t) if total_len > 0.0 => {
                    let d = t * len / total_len;
                    (len / d * 60.0, d)
                }
                _ => {
                    let rate = if mv.rapid {
                        axis_cap * f64::from(self.overrides[1]) / 100.0
                    } else {
                        mv.feed_mm_min.min(axis_cap) * f64::from(self.overrides[0]) / 100.0
                    };
                    let rate = if rate.is_finite() && rate > 0.0 {
                        rate
                    } else {
                        1000.0
                    };
                    (rate, len / (rate / 60.0))
                }
            };
            out.push_back(PBlock {
                seq,
                from: prev,
                to: p,
                duration,
                feed_mm_min: rate,
                laser_s: mv.laser_s,
                rapid: mv.rapid,
                rest_after,
            });
            prev = p;
        }
        out
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
                    }
                }
                Step::Move(mv) => {
                    let chords = self.chords(seq, mv, rest_after);
                    if chords.iter().any(|b| self.outside_travel(b.to)) {
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
        self.planner.clear();
        self.exec_t = 0.0;
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
                Work::Dwell { left, total } => {
                    if *left > 0.0 {
                        self.pending = Some(p);
                        return false;
                    }
                    self.rec.dwells.push((p.seq, *total));
                    p.work.pop_front();
                }
                Work::Blocks(q) => {
                    while self.planner.len() < self.cfg.planner_blocks {
                        let Some(b) = q.pop_front() else { break };
                        self.planner.push_back(b);
                        if self.state == St::Idle {
                            self.state = St::Cycle;
                        }
                    }
                    self.rec.max_planner_fill = self.rec.max_planner_fill.max(self.planner.len());
                    if !q.is_empty() {
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

fn dist(a: AxisPos, b: AxisPos) -> f64 {
    a.iter()
        .zip(&b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}
