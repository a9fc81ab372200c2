//! The machine moving: the running block executed along a trapezoid from GRBL's motion model
//! ([`crate::link::sim::motion`]), replanned whenever a block joins the buffer behind it (as
//! GRBL's `st_update_plan_block_parameters` lets the stepper pick up a raised exit speed),
//! and a feed hold decelerating at the block's acceleration, across block ends if it must,
//! to a stop inside the buffer.

use super::record::ExecutedBlock;
use super::{Controller, St};
use crate::link::AxisPos;
use crate::link::sim::motion::{Trapezoid, exit_speed};
use crate::link::sim::poserr::RowStartRecord;

/// The running block's progress.
#[derive(Debug, Clone, Copy)]
pub(super) struct Exec {
    pub profile: Trapezoid,
    /// Distance done along the block before `profile` starts, mm.
    pub done: f64,
    /// Time into `profile`, s.
    pub t: f64,
    /// When the block started, simulated s.
    pub t_start: f64,
    /// Its speed when it started, mm/s.
    pub entry: f64,
    /// Decelerating for a feed hold.
    pub hold: bool,
}

impl Controller {
    /// Distance done along the running block and its speed now.
    pub(super) fn progress(&self) -> (f64, f64) {
        match self.exec {
            Some(e) => {
                let (d, v) = e.profile.at(e.t);
                (e.done + d, v)
            }
            // Between blocks: the speed the last one ended at.
            None => (0.0, self.v),
        }
    }

    /// Speed along the path now, mm/s.
    pub fn speed(&self) -> f64 {
        self.progress().1
    }

    /// Where the running block is now.
    pub(super) fn front_position(&self) -> Option<AxisPos> {
        let b = &self.planner.front()?.b;
        let (d, _) = self.progress();
        let f = if b.len > 0.0 {
            (d / b.len).clamp(0.0, 1.0)
        } else {
            1.0
        };
        Some(std::array::from_fn(|i| {
            b.from[i] + f * (b.to[i] - b.from[i])
        }))
    }

    fn moving_state(&self) -> bool {
        matches!(
            self.state,
            St::Cycle | St::Jog | St::Hold { complete: false }
        )
    }

    /// Starts the front block when the machine is moving and it has not started yet.
    pub(super) fn start_front(&mut self) {
        if self.exec.is_some() || !self.moving_state() {
            return;
        }
        let Some(front) = self.planner.front() else {
            return;
        };
        let b = &front.b;
        let entry = self.v;
        let hold = matches!(self.state, St::Hold { .. });
        let profile = if hold {
            decel(b.len, entry, b.accel)
        } else {
            let exit = exit_speed(
                entry,
                b.len,
                b.accel,
                self.planner.iter().skip(1).map(|p| &p.b),
            );
            Trapezoid::new(b.len, entry, exit, b.nominal, b.accel)
        };
        // A row's first pulse: the first lit feed block since the table stood still or ran a
        // rapid (rows of pulses by distance run up from rest; issue 15's record).
        if entry <= 1e-9 || b.rapid {
            self.row_pending = true;
        }
        // Recorded only with the error model on (what the record is for): a job of millions
        // of rows would otherwise grow it without bound.
        if self.row_pending && !b.rapid && b.laser_s > 0.0 && self.perr.is_some() {
            self.row_pending = false;
            let commanded = b.from;
            let actual = match &mut self.perr {
                Some(m) => {
                    m.follow(&commanded);
                    m.actual(self.now)
                }
                None => commanded,
            };
            self.rec.row_starts.push(RowStartRecord {
                t: self.now,
                commanded,
                actual,
            });
        }
        self.exec = Some(Exec {
            profile,
            done: 0.0,
            t: 0.0,
            t_start: self.now,
            entry,
            hold,
        });
    }

    /// A block joined the buffer: the running block may now end faster.
    pub(super) fn replan_front(&mut self) {
        let Some(e) = self.exec else { return };
        if e.hold {
            return;
        }
        let Some(front) = self.planner.front() else {
            return;
        };
        let b = &front.b;
        let (d, v) = e.profile.at(e.t);
        let done = e.done + d;
        let rest = (b.len - done).max(0.0);
        let exit = exit_speed(v, rest, b.accel, self.planner.iter().skip(1).map(|p| &p.b));
        self.exec = Some(Exec {
            profile: Trapezoid::new(rest, v, exit, b.nominal, b.accel),
            done,
            t: 0.0,
            ..e
        });
    }

    /// Feed hold: decelerate from here at the block's acceleration.
    pub(super) fn begin_hold(&mut self) {
        let Some(e) = self.exec else { return };
        let Some(front) = self.planner.front() else {
            return;
        };
        let b = &front.b;
        let (d, v) = e.profile.at(e.t);
        let done = e.done + d;
        self.exec = Some(Exec {
            profile: decel((b.len - done).max(0.0), v, b.accel),
            done,
            t: 0.0,
            hold: true,
            ..e
        });
    }

    /// Seconds until the running block (or the hold's deceleration) ends.
    pub(super) fn motion_event(&self) -> f64 {
        match self.exec {
            Some(e) => (e.profile.duration() - e.t).max(0.0),
            None => f64::INFINITY,
        }
    }

    /// Lets `dt` pass for the running block; it ends when its profile does.
    pub(super) fn advance_motion(&mut self, dt: f64) {
        let Some(mut e) = self.exec else { return };
        e.t += dt;
        self.exec = Some(e);
        if e.t < e.profile.duration() - 1e-12 {
            return;
        }
        let Some(front) = self.planner.front_mut() else {
            self.exec = None;
            return;
        };
        let reached = e.done + e.profile.len;
        if e.hold && e.profile.exit <= 1e-9 && reached < front.b.len - 1e-9 {
            // Stopped inside the block: the part it ran is recorded, what is left of it
            // waits in the buffer.
            let f = reached / front.b.len;
            let from = front.b.from;
            let stop: AxisPos = std::array::from_fn(|i| from[i] + f * (front.b.to[i] - from[i]));
            front.b.from = stop;
            front.b.len -= reached;
            let (seq, rapid, laser_s) = (front.seq, front.b.rapid, front.b.laser_s);
            if self.state != St::Jog {
                self.rec.executed_s = self.now;
                self.rec.push_block(ExecutedBlock {
                    seq,
                    from,
                    to: stop,
                    rapid,
                    laser_s,
                    t_start: e.t_start,
                    t_end: self.now,
                    duration: self.now - e.t_start,
                    entry_mm_s: e.entry,
                    exit_mm_s: 0.0,
                });
            }
            self.exec = None;
            self.v = 0.0;
            self.mpos = front.b.from;
            self.state = St::Hold { complete: true };
            self.resume_if_asked();
            return;
        }
        let done = self.planner.pop_front().unwrap_or_else(|| unreachable!());
        self.exec = None;
        self.v = e.profile.exit;
        self.mpos = done.b.to;
        if let Some(m) = &mut self.perr {
            m.block_done(&done.b.from, &done.b.to, e.profile.exit <= 1e-9);
        }
        self.rest_laser = done.rest_after;
        if self.state == St::Jog {
            self.gc.pos = self.mpos;
        } else {
            self.rec.executed_s = self.now;
            self.rec.push_block(ExecutedBlock {
                seq: done.seq,
                from: done.b.from,
                to: done.b.to,
                rapid: done.b.rapid,
                laser_s: done.b.laser_s,
                t_start: e.t_start,
                t_end: self.now,
                duration: self.now - e.t_start,
                entry_mm_s: e.entry,
                exit_mm_s: e.profile.exit,
            });
        }
        if self.planner.is_empty() || (e.hold && self.v <= 1e-9) {
            self.v = 0.0;
            match self.state {
                St::Hold { .. } => self.state = St::Hold { complete: true },
                _ => self.come_to_rest(),
            }
            self.resume_if_asked();
        }
    }

    /// Everything buffered is dropped (reset, alarm, jog cancel): the machine stands where it
    /// is and the planner starts again from there.
    pub(super) fn stop_motion(&mut self) {
        self.planner.clear();
        self.exec = None;
        self.v = 0.0;
        self.resume_asked = false;
        self.reading = Some(self.now);
        self.start_at = None;
        self.pl.sync_position(self.mpos);
    }

    /// A cycle start that came during the deceleration takes effect once the hold is complete.
    pub(super) fn resume_if_asked(&mut self) {
        if self.state == (St::Hold { complete: true }) && std::mem::take(&mut self.resume_asked) {
            if self.planner.is_empty() {
                self.come_to_rest();
            } else {
                self.state = St::Cycle;
                self.reading = None;
                self.start_at = None;
            }
        }
    }
}

/// Decelerating from `v` at `a` over at most `len`: to a stop inside it, or through its end.
fn decel(len: f64, v: f64, a: f64) -> Trapezoid {
    let stop = v * v / (2.0 * a.max(1e-9));
    if stop <= len {
        Trapezoid::new(stop, v, 0.0, v, a)
    } else {
        let exit = (v * v - 2.0 * a * len).max(0.0).sqrt();
        Trapezoid::new(len, v, exit, v, a)
    }
}
