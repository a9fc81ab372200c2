//! LinuxCNC 2.9's trajectory planner servo period by servo period (`tpRunCycle`) for a chain
//! of lines joined by parabolic blends (see `link::linuxcnc::tp::servo`, which times programs
//! with it). Here, before the emitter, so that the writer can ask what tp does at a beam
//! switch in such a chain (`emit::writer::lead`): the summed speed when the next segment's
//! synchronized outputs switch.

/// `TP_VEL_EPSILON`.
const VEL_EPSILON: f64 = 1e-8;
/// `TP_POS_EPSILON`.
const POS_EPSILON: f64 = 1e-12;
/// `TP_TIME_EPSILON`.
const TIME_EPSILON: f64 = 1e-12;
/// `TP_MIN_ARC_ANGLE`.
const MIN_ARC_ANGLE: f64 = 1e-3;

/// One line of the chain as the planner queued it (its own length unit: X Y Z length, or the
/// rotary length when X Y Z stay).
#[derive(Debug, Clone)]
pub struct ChainSeg {
    pub len: f64,
    /// `tpGetRealTargetVel`: the requested speed within the segment's own limits.
    pub v: f64,
    /// `maxaccel` before blends scale it.
    pub acc: f64,
    /// X Y Z unit direction (`uVec`; (1, 0, 0) when X Y Z stay, as `pmCartLineInit` sets it).
    pub u: [f64; 3],
    /// `G64 P` in force for it.
    pub tolerance: f64,
}

/// What the chain does: when each segment's synced outputs switch, and when motion ends.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainRun {
    /// Per segment, s from the chain's first servo period.
    pub switch_s: Vec<f64>,
    /// From the first servo period to the end of the last that moves, s.
    pub total_s: f64,
    /// Per segment, tp's speed in the period its outputs switch: the finishing segment's and
    /// the next one's added where the switch falls in a parabolic blend (each in its own
    /// length unit, so the sum is a speed where both measure alike), else its own.
    pub switch_speed: Vec<f64>,
    /// Per segment, how far past its start tp's point is as its outputs switch: the next
    /// segment's progress less what the finishing one has left where the switch falls in a
    /// blend (in line, the point summed along the path), else its own progress.
    pub switch_past: Vec<f64>,
    /// Per segment, the joints' speeds about its outputs' switch, as sampled positions show
    /// them: over the periods ending at samples `n − 4 ..= n + 4`, `n` the switching period
    /// (its sample the first to show the output switched). control.c's cubic interpolator
    /// puts the joints at the way point `(p[k−3] + 4·p[k−2] + p[k−1]) / 6` of tp's points,
    /// so the joints move `(s[k−3] + 4·s[k−2] + s[k−1]) / 6` in period `k`, `s` tp's travel
    /// in each period (summed where a blend runs two segments). Where a blend lasts a few
    /// periods (an arm's), the joints still run at the finishing segment's speed as tp
    /// switches, and its blend's speeds show two periods later.
    pub switch_window: Vec<[f64; SWITCH_WINDOW]>,
}

/// Samples in [`ChainRun::switch_window`]: four before the switch's, it, and four after.
pub const SWITCH_WINDOW: usize = 9;

/// tp's periods a switch window needs: three before the first sample's, to the last's.
const TRAVEL_SPAN: usize = SWITCH_WINDOW + 2;

#[derive(Debug, Clone)]
struct Tc {
    progress: f64,
    vel: f64,
    blending_next: bool,
    on_final_decel: bool,
    blend_vel: f64,
    splitting: bool,
    cycle_time: f64,
    remove: bool,
    /// Term condition PARABOLIC (else STOP: the chain's end when the planner stops there).
    parabolic: bool,
    blend_prev: bool,
    switched: bool,
}

/// `tcGetTangentialMaxAccel` for a line.
fn tangential_acc(s: &ChainSeg, tc: &Tc) -> f64 {
    if tc.blend_prev || tc.parabolic {
        s.acc * 0.5
    } else {
        s.acc
    }
}

/// `tpComputeBlendVelocity`: the blend speeds of `a` and of `b` (both segments finalized).
fn blend_velocity(a: &ChainSeg, ta: &Tc, b: &ChainSeg, tb: &Tc) -> (f64, f64) {
    let (acc_a, acc_b) = (tangential_acc(a, ta), tangential_acc(b, tb));
    let reach_a = (acc_a * a.len).sqrt().min(a.v);
    let reach_b = (acc_b * b.len).sqrt().min(b.v);
    let t_reachable = (a.len / reach_a).min(b.len / reach_b);
    let t_blend = t_reachable.min((reach_a / acc_a).max(reach_b / acc_b));
    let mut va = reach_a.min(t_blend * acc_a);
    let mut vb = reach_b.min(t_blend * acc_b);
    let dot: f64 = (0..3).map(|k| a.u[k] * b.u[k]).sum();
    let theta = (-dot).clamp(-1.0, 1.0).acos() / 2.0;
    let cos_theta = theta.cos();
    if a.tolerance > 0.0 && cos_theta > (std::f64::consts::FRAC_PI_2 - MIN_ARC_ANGLE).cos() {
        let cap = 2.0 * (acc_a * a.tolerance / cos_theta).sqrt();
        va = va.min(cap);
        vb = vb.min(cap);
    }
    (va, vb)
}

/// `tpUpdateCycle` without its ramp mode (parabolic segments never ramp): one servo period of
/// trapezoidal motion toward a stop at the segment's end, then `tpCheckEndCondition`.
fn update(s: &ChainSeg, tc: &mut Tc, period: f64) {
    let dt = tc.cycle_time;
    let dx = s.len - tc.progress;
    let a = tangential_acc(s, tc);
    let v = tc.vel;
    let half_step = a * dt * 0.5;
    let discr = a * (2.0 * dx - v * dt) + half_step * half_step;
    let mut max_new = -half_step;
    if discr > half_step * half_step {
        max_new += discr.sqrt();
    }
    let new_vel = max_new.clamp(-s.v, s.v);
    let acc = ((new_vel - v) / dt.max(TIME_EPSILON)).clamp(-a, a);
    // tcUpdateDistFromAccel: trapezoidal integration, never past the end.
    let mut next = v + acc * dt;
    if next < 0.0 {
        next = 0.0;
        if dx < v * dt {
            tc.progress = s.len;
        }
    } else {
        tc.progress = (tc.progress + (next + v) * 0.5 * dt).min(s.len);
    }
    tc.vel = next;
    tc.on_final_decel = (max_new - next).abs() < VEL_EPSILON && acc < 0.0;
    end_condition(s, tc, period);
}

/// `tpCheckEndCondition` for a segment whose final speed is zero (parabolic or stop): flags
/// the period in which it will reach its end.
fn end_condition(s: &ChainSeg, tc: &mut Tc, period: f64) {
    tc.cycle_time = period;
    let dx = s.len - tc.progress;
    if dx <= POS_EPSILON {
        tc.progress = s.len;
        tc.splitting = true;
        tc.cycle_time = 0.0;
        tc.remove |= !tc.parabolic;
        return;
    }
    if !tc.parabolic {
        return;
    }
    let v_avg = tc.vel / 2.0;
    let mut dt = TIME_EPSILON / 2.0;
    if v_avg > VEL_EPSILON {
        dt = dt.max(dx / v_avg);
    } else if dx > v_avg * period && dx > POS_EPSILON {
        return;
    }
    let a_f = -tc.vel / dt;
    let a_max = tangential_acc(s, tc);
    if a_f < -a_max {
        let a = -a_max;
        let disc = (tc.vel / a).powi(2) + 2.0 / a * dx;
        if disc < 0.0 {
            return;
        }
        dt = if disc < TIME_EPSILON * TIME_EPSILON {
            -tc.vel / a
        } else {
            -tc.vel / a - disc.sqrt()
        };
    }
    if dt < TIME_EPSILON {
        tc.progress = s.len;
        tc.splitting = true;
        tc.cycle_time = 0.0;
    } else if dt < period {
        tc.splitting = true;
        tc.cycle_time = dt;
    }
}

/// Runs `segs` from rest to rest, every junction a parabolic blend; `parabolic_end`: the last
/// segment keeps the PARABOLIC term condition (the queue ends there), else STOP.
pub fn run_chain(segs: &[ChainSeg], parabolic_end: bool, period: f64) -> ChainRun {
    let mut r = Replay::start(segs, parabolic_end, period);
    r.run(usize::MAX);
    r.finish()
}

/// A chain run part way: [`Replay::prefix`] runs the segments a chain starts with up to where
/// tp first looks past them, so that several endings can each be run on from there
/// ([`Replay::then`]) without replaying the start again.
#[derive(Debug, Clone)]
pub struct Replay {
    segs: Vec<ChainSeg>,
    tcs: Vec<Tc>,
    period: f64,
    head: usize,
    cycles: u64,
    last_moving: u64,
    switch_s: Vec<f64>,
    switch_speed: Vec<f64>,
    switch_past: Vec<f64>,
    switch_window: Vec<[f64; SWITCH_WINDOW]>,
    /// tp's travel in each of the last periods, a ring: the latest at `recorded %
    /// TRAVEL_SPAN`, `recorded` the periods recorded (`record`).
    travel: [f64; TRAVEL_SPAN],
    recorded: usize,
    /// The segment whose outputs switched in this period.
    switched_now: Option<usize>,
    /// Switches whose windows still wait for periods: the segment and the periods to come.
    open: Vec<(usize, usize)>,
}

impl Replay {
    fn start(segs: &[ChainSeg], parabolic_end: bool, period: f64) -> Replay {
        let n = segs.len();
        let mut r = Replay {
            segs: Vec::with_capacity(n + 3),
            tcs: Vec::with_capacity(n + 3),
            period,
            head: 0,
            cycles: 0,
            last_moving: 0,
            switch_s: Vec::new(),
            switch_speed: Vec::new(),
            switch_past: Vec::new(),
            switch_window: Vec::new(),
            travel: [0.0; TRAVEL_SPAN],
            recorded: 0,
            switched_now: None,
            open: Vec::new(),
        };
        r.push(segs, parabolic_end);
        r
    }

    /// Appends `segs` to the chain (the one before them now blends into them).
    fn push(&mut self, segs: &[ChainSeg], parabolic_end: bool) {
        if let Some(last) = self.tcs.last_mut() {
            last.parabolic = true;
        }
        let n = segs.len();
        for (i, s) in segs.iter().enumerate() {
            let first = self.tcs.is_empty();
            self.tcs.push(Tc {
                progress: 0.0,
                vel: 0.0,
                blending_next: false,
                on_final_decel: false,
                blend_vel: 0.0,
                splitting: false,
                cycle_time: self.period,
                remove: false,
                parabolic: i + 1 < n || parabolic_end,
                blend_prev: !first,
                switched: false,
            });
            self.segs.push(s.clone());
        }
        let m = self.segs.len();
        self.switch_s.resize(m, 0.0);
        self.switch_speed.resize(m, 0.0);
        self.switch_past.resize(m, 0.0);
        self.switch_window.resize(m, [0.0; SWITCH_WINDOW]);
    }

    /// `segs` run from rest up to the first servo period in which tp would look at a segment
    /// after them (their last is the head, or the chain has ended).
    pub fn prefix(segs: &[ChainSeg], period: f64) -> Replay {
        let mut r = Replay::start(segs, true, period);
        r.run(segs.len().saturating_sub(1));
        r
    }

    /// The prefix run on into `tail` (its last segment ending in STOP): the whole chain's run.
    pub fn then(&self, tail: &[ChainSeg]) -> ChainRun {
        let mut r = self.clone();
        r.push(tail, false);
        r.run(usize::MAX);
        r.finish()
    }

    fn finish(mut self) -> ChainRun {
        // Windows past the chain's end: the joints come to rest.
        while !self.open.is_empty() {
            self.record(0.0);
        }
        ChainRun {
            switch_s: self.switch_s,
            total_s: self.last_moving as f64 * self.period,
            switch_speed: self.switch_speed,
            switch_past: self.switch_past,
            switch_window: self.switch_window,
        }
    }

    /// Keeps tp's travel `step` in the period just run, and fills the switch windows
    /// ([`ChainRun::switch_window`]) that have all their periods.
    fn record(&mut self, step: f64) {
        // Every period, on the replay's hot path: one store, the rest only about a switch.
        self.recorded += 1;
        let latest = self.recorded % TRAVEL_SPAN;
        self.travel[latest] = step;
        if let Some(i) = self.switched_now.take() {
            // The last sample's joints move on tp's travel up to three periods after the
            // switch's.
            self.open.push((i, 3));
        }
        if self.open.is_empty() {
            return;
        }
        let period = self.period;
        // Oldest first.
        let s: [f64; TRAVEL_SPAN] =
            std::array::from_fn(|k| self.travel[(latest + 1 + k) % TRAVEL_SPAN]);
        let windows = &mut self.switch_window;
        self.open.retain_mut(|(i, left)| {
            if *left > 0 {
                *left -= 1;
                return true;
            }
            for (k, w) in windows[*i].iter_mut().enumerate() {
                *w = (s[k] + 4.0 * s[k + 1] + s[k + 2]) / (6.0 * period);
            }
            false
        });
    }

    fn switch(&mut self, i: usize, (speed, past): (f64, f64)) {
        if !self.tcs[i].switched {
            self.tcs[i].switched = true;
            self.switch_s[i] = self.cycles as f64 * self.period;
            self.switch_speed[i] = speed;
            self.switch_past[i] = past;
            self.switched_now = Some(i);
        }
    }

    /// Runs servo periods while the head is before `stop_at` (and the chain has not ended).
    fn run(&mut self, stop_at: usize) {
        let n = self.segs.len();
        let period = self.period;
        // Each segment ends within its cruise time plus its ramps, and a period or two; the
        // bound (ten times that) only guards the loop against arithmetic that would not end.
        let limit = self
            .segs
            .iter()
            .map(|s| (((s.len / s.v + 2.0 * s.v / s.acc) / period) as u64).saturating_add(4))
            .fold(0u64, u64::saturating_add)
            .saturating_mul(10);
        while self.head < n && self.head < stop_at && self.cycles < limit {
            self.cycle();
        }
    }

    /// One servo period of `tpRunCycle`.
    fn cycle(&mut self) {
        let (n, period, head) = (self.segs.len(), self.period, self.head);
        let segs = &self.segs;
        let mut before = [0.0; 2];
        for (k, b) in before.iter_mut().enumerate().take(n - head) {
            *b = self.tcs[head + k].progress;
        }
        let next = (head + 1 < n).then_some(head + 1);
        if self.tcs[head].splitting {
            // tpHandleSplitCycle: the segment lands on its end; the next one gets the period.
            self.tcs[head].progress = segs[head].len;
            self.tcs[head].remove = true;
            if let Some(j) = next {
                update(&segs[j], &mut self.tcs[j], period);
                let at = (self.tcs[j].vel, self.tcs[j].progress);
                self.switch(j, at);
            }
        } else {
            let tcs = &mut self.tcs;
            tcs[head].cycle_time = period;
            update(&segs[head], &mut tcs[head], period);
            if let Some(j) = next {
                let (va, vb) = blend_velocity(&segs[head], &tcs[head], &segs[j], &tcs[j]);
                tcs[head].blend_vel = va;
                tcs[j].blend_vel = vb;
                let t = &mut tcs[head];
                t.blending_next |= t.parabolic && t.on_final_decel && t.vel < t.blend_vel;
            } else {
                tcs[head].blend_vel = 0.0;
            }
            match next {
                Some(j) if tcs[head].blending_next => {
                    // tpUpdateBlend: the next segment accelerates on its own (its target
                    // speed is its requested one; the blend's scaling touches only
                    // synchronized motion), with no segment after it.
                    update(&segs[j], &mut tcs[j], period);
                    let faster = if tcs[head].vel > tcs[j].vel { head } else { j };
                    let v = tcs[head].vel + tcs[j].vel;
                    let past = if faster == j {
                        tcs[j].progress - (segs[head].len - tcs[head].progress)
                    } else {
                        tcs[head].progress
                    };
                    self.switch(faster, (v, past));
                }
                _ => {
                    let at = (tcs[head].vel, tcs[head].progress);
                    self.switch(head, at)
                }
            }
        }
        self.cycles += 1;
        // tp's travel this period, and whether it moved as a sampled position shows it: a
        // step above a millionth of the segment (a split period's landing on the end is
        // below). One pass over the (at most two) segments: this runs every period.
        let (mut step, mut moved) = (0.0, false);
        for (k, b) in before.iter().enumerate().take(n - head) {
            let d = self.tcs[head + k].progress - b;
            step += d;
            moved |= d > 1e-6 * self.segs[head + k].len;
        }
        self.record(step);
        if moved {
            self.last_moving = self.cycles;
        }
        if self.tcs[head].remove {
            self.head += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real LinuxCNC 2.9 (Debian's linuxcnc-uspace, headless, 1 ms servo period, the
    /// xy_rotary INI lase generates: A at 3600 °/s²) ran rotary_engrave's first ring with its
    /// lit block 0, ¼, ½, ¾ and 1 ms longer (hand-edited F words; lead-in and lead-out as
    /// lase writes them). Through the parabolic blend into the lead-out the summed A speed,
    /// recomputed from the sampled joint positions, sat at 113.8655, 112.5055, 112.9455,
    /// 113.3885 and 113.8295 °/s: a sawtooth over the phase in which the lit block's final
    /// deceleration turns, one servo period wide and `A·T` = 1.8 °/s high. The replay gives the
    /// same speed at the lead-out's switch.
    #[test]
    fn the_replay_matches_the_real_linuxcncs_off_edge_blend_over_the_servo_phase() {
        let seg = |len: f64, f_per_min: f64| ChainSeg {
            len,
            v: len * f_per_min / 60.0,
            acc: 3600.0,
            u: [1.0, 0.0, 0.0],
            tolerance: 0.01,
        };
        let measured = [113.8655, 112.5055, 112.9455, 113.3885, 113.8295];
        for (k, real) in measured.into_iter().enumerate() {
            let lit_s = 60.0 / 19.09859 + k as f64 * 0.00025;
            let f = (60.0 / lit_s * 1e6).round() / 1e6;
            let chain = [
                seg(7.868083, 857.3745),
                seg(360.0, f),
                seg(6.980599, 984.9432),
                seg(8.068018, 852.1912),
            ];
            let run = run_chain(&chain, false, 0.001);
            // The on-edge as the real machine crossed it too (114.20 of 114.59 °/s).
            assert!((run.switch_speed[1] - 114.20).abs() < 0.005, "{run:?}");
            let model = run.switch_speed[2];
            assert!(
                (model - real).abs() < 0.002,
                "{k}/4 ms longer: replay {model:.4}, LinuxCNC {real:.4} °/s"
            );
        }
    }

    /// The real LinuxCNC 2.9 (the arm_3r INI lase generates: A and B at 900 °/s², C at
    /// 1800) ran a lead-in from rest at F1190.8894 into a lit block at F426.1399 in line in
    /// the joints (tests/linuxcnc/arm_short.lase as written while its timing was tuned on
    /// tp's summed speed). The blend lasts about two servo periods: tp switched the beam as
    /// its summed speed reached the lit speed (1.18 °/s), while the sampled joints, two
    /// periods behind, still ran at the lead-in's 0.80: their central difference over the
    /// switching sample was 0.8179 °/s, which the replay's switch window gives.
    #[test]
    fn the_joints_speed_at_a_short_blends_switch_is_the_real_linuxcncs() {
        let p0 = [-133.087689, 99.466378, -61.135992];
        let p1 = [-133.060975, 99.463241, -61.166172];
        let p2 = [-132.951481, 99.450385, -61.289873];
        let seg = |a: [f64; 3], b: [f64; 3], f_per_min: f64| {
            let d: Vec<f64> = (0..3).map(|k| (b[k] - a[k]).abs()).collect();
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let acc = [900.0, 900.0, 1800.0]
                .iter()
                .zip(&d)
                .map(|(a, d)| a * len / d)
                .fold(f64::INFINITY, f64::min);
            ChainSeg {
                len,
                v: len * f_per_min / 60.0,
                acc,
                u: [1.0, 0.0, 0.0],
                tolerance: 0.01,
            }
        };
        let chain = [seg(p0, p1, 1190.8894), seg(p1, p2, 426.1399)];
        let run = run_chain(&chain, false, 0.001);
        let lit = chain[1].v;
        assert!((lit - 1.18).abs() < 0.005, "{lit}");
        assert!((run.switch_speed[1] / lit - 1.0).abs() < 0.02, "{run:?}");
        // The central difference over the switching sample, (x[n+1] − x[n−1]) / 2T.
        let window = run.switch_window[1];
        let joints = (window[4] + window[5]) / 2.0;
        assert!(
            (joints - 0.8179).abs() < 0.002,
            "replay {joints:.4}, LinuxCNC 0.8179 °/s"
        );
        // Sample by sample from four before the switch's to four after: the blend's speeds
        // show in the joints from the sample after the switch's on.
        let real = [
            0.80221, 0.80229, 0.80221, 0.80221, 0.80287, 0.83283, 0.97841, 1.10065, 1.16537,
        ];
        for (k, (w, r)) in window.iter().zip(real).enumerate() {
            let at = k as i32 - 4;
            assert!(
                (w - r).abs() < 0.001,
                "sample {at}: replay {window:?}, LinuxCNC {real:?}"
            );
        }
    }

    #[test]
    fn a_prefix_run_on_into_its_ending_is_the_whole_chains_run() {
        let seg = |len: f64, v: f64, u: [f64; 3]| ChainSeg {
            len,
            v,
            acc: 2000.0,
            u,
            tolerance: 0.01,
        };
        let x = [1.0, 0.0, 0.0];
        let head = [
            seg(3.0, 40.0, x),
            seg(0.8, 55.0, x),
            seg(0.05, 30.0, [0.6, 0.8, 0.0]),
        ];
        let tail = [seg(2.0, 50.0, x), seg(0.4, 50.0, x), seg(1.2, 50.0, x)];
        let all: Vec<ChainSeg> = head.iter().chain(&tail).cloned().collect();
        let whole = run_chain(&all, false, 0.001);
        let parts = Replay::prefix(&head, 0.001).then(&tail);
        assert_eq!(whole, parts);
        assert!(whole.total_s > 0.0 && whole.switch_s.windows(2).all(|w| w[0] <= w[1]));
    }
}
