//! LinuxCNC 2.9's trajectory planner servo period by servo period (`tpRunCycle`) for a chain
//! of lines from rest to rest, each joined to the next by a parabolic blend (one of the two
//! turns a rotary axis: `tpSetupTangent` gives up on A B C motion) or tangentially (lines
//! without rotary motion whose directions agree: `TC_TERM_COND_TANGENT`, the speed carried
//! through the junction). `link::linuxcnc::tp::servo` times programs with it; the writer asks
//! it what tp does at a beam switch (`emit::writer::timing`): the summed speed when the next
//! segment's synchronized outputs switch, and the joints' speeds about it.
//!
//! What a tangent join adds to the parabolic replay (tp.c, tc.c and blendmath.c of 2.9):
//! - the look-ahead's final speeds (`tpRunOptimization` as each segment is queued: backward
//!   over at most `ARC_BLEND_OPTIMIZATION_DEPTH` segments, across at most one junction that
//!   is not tangent, stopping past `TP_OPTIMIZATION_CUTOFF` segments at their limit;
//!   `tpComputeOptimalVelocity`, `tpCalculateOptimizationInitialVel` for the last queued,
//!   not yet finalized), capped by both segments' speeds (`tpGetRealFinalVel`);
//! - a trapezoid toward that final speed (`findTrapezoidalDesiredVel`'s `v_f²` term), and the
//!   end condition solved for it (`checkEndCondition`): the split period carries the
//!   terminal speed into the next segment, which runs the rest of the period
//!   (`tpHandleSplitCycle`);
//! - a segment shorter than `1 / ARC_BLEND_RAMP_FREQ` at its entry and final speeds runs at
//!   one acceleration from one to the other (`tpActivateSegment`'s `TC_ACCEL_RAMP`,
//!   `tpCalculateRampAccel`);
//! - a segment whose predecessor joins it tangentially runs at most its length in 1.02 servo
//!   periods (`TP_MIN_SEGMENT_CYCLES`), and a kink's acceleration share is taken from both
//!   (`tcSetKinkProperties`, `tcGetOverallMaxAccel`).
//!
//! Where the real LinuxCNC 2.9 (Debian's, headless) ran otherwise than the sources read, the
//! replay follows the machine: a segment after a parabolic blend ramps at half its
//! acceleration only where its own term condition is PARABOLIC (a lead-out ending in a stop,
//! an X-only block joined tangentially to the next, run at their full acceleration from the
//! blend's first period on: `blend_prev` does not halve them), and a tangent split period
//! switches the next segment's outputs however little of the period it ran. With both, every
//! NC line of rotary_engrave (parabolic chains with tangent X-only strokes in them, rapids
//! between) started in the model in the servo period the real machine started it, and the
//! model's cycle came to 1.0002 of the real one (0.9929 before).
//!
//! The replay queues the whole chain before it runs it: the look-ahead's passes are those of
//! a queue filled ahead of motion (the task queues a segment a millisecond; a pass that a
//! segment already under way would stop is not modelled).

/// `TP_VEL_EPSILON`.
const VEL_EPSILON: f64 = 1e-8;
/// `TP_POS_EPSILON`.
const POS_EPSILON: f64 = 1e-12;
/// `TP_TIME_EPSILON`.
const TIME_EPSILON: f64 = 1e-12;
/// `TP_MIN_ARC_ANGLE`.
pub const MIN_ARC_ANGLE: f64 = 1e-3;
/// `TP_MIN_SEGMENT_CYCLES`.
const MIN_SEGMENT_CYCLES: f64 = 1.02;
/// `[TRAJ] ARC_BLEND_OPTIMIZATION_DEPTH`'s default.
pub const OPTIMIZATION_DEPTH: usize = 50;
/// `TP_OPTIMIZATION_CUTOFF`.
const OPTIMIZATION_CUTOFF: usize = 4;
/// `[TRAJ] ARC_BLEND_RAMP_FREQ`'s default (`arcBlendRampFreq`), Hz.
pub const RAMP_FREQ: f64 = 100.0;
/// `[TRAJ] ARC_BLEND_KINK_RATIO`'s default.
pub const KINK_RATIO: f64 = 0.1;

/// One line of the chain as the planner queued it (its own length unit: X Y Z length, or the
/// rotary length when X Y Z stay).
#[derive(Debug, Clone, PartialEq)]
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
    /// How tp joins it to the next segment: `None` by a parabolic blend, `Some(r)`
    /// tangentially, both segments losing the share `r` of their acceleration to the kink
    /// ([`tangent_join`]). The chain's last segment's is not read.
    pub tangent: Option<f64>,
}

/// `tpSetupTangent`: whether two lines without rotary motion, the first ending along `u0`,
/// the second starting along `u1`, join tangentially, and the share of acceleration the kink
/// takes from both ([`kink_scale`], under `ARC_BLEND_KINK_RATIO`). `None`: tp stops there (a
/// reversal, within `SHARP_CORNER_DEG` = 2°: `pmCartCartAntiParallel`), or makes a blend arc
/// or a kink at reduced speed, which the replay does not model.
pub fn tangent_join(
    (u0, u1): ([f64; 3], [f64; 3]),
    v_max: f64,
    acc: f64,
    acc_bound: [f64; 3],
    cycle: f64,
) -> Option<f64> {
    let dot: f64 = (0..3).map(|k| u0[k] * u1[k]).sum();
    let sharp = (std::f64::consts::PI * 2.0 / 180.0).powi(2);
    if 1.0 + dot < sharp {
        return None;
    }
    let scale = kink_scale((u0, u1), v_max, acc, acc_bound, cycle);
    (scale < KINK_RATIO).then_some(scale)
}

/// `tpSetupTangent`'s kink: the X Y Z acceleration that turns from direction `u0` to `u1`
/// within a servo period `cycle` at `v_max` (the slower segment's requested speed within its
/// limits), plus the second segment's own `acc` ("acceleration past final velocity during a
/// split cycle"), as a share of the axes' limits `acc_bound` (zero: no such axis), the
/// largest over the axes.
pub fn kink_scale(
    (u0, u1): ([f64; 3], [f64; 3]),
    v_max: f64,
    acc: f64,
    acc_bound: [f64; 3],
    cycle: f64,
) -> f64 {
    let a_inst = v_max / cycle + acc;
    (0..3)
        .map(|k| {
            let diff = a_inst * (u1[k] - u0[k]);
            if acc_bound[k] > 0.0 {
                (diff / acc_bound[k]).abs()
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max)
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

/// A segment's terminal condition.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Term {
    Parabolic,
    Tangent,
    /// The chain's end where the planner stops there.
    Stop,
}

#[derive(Debug, Clone, PartialEq)]
struct Tc {
    progress: f64,
    vel: f64,
    blending_next: bool,
    on_final_decel: bool,
    blend_vel: f64,
    splitting: bool,
    cycle_time: f64,
    remove: bool,
    term: Term,
    switched: bool,
    /// The look-ahead's final speed (`finalvel`; read only where the term is TANGENT).
    finalvel: f64,
    /// `TC_ACCEL_RAMP`.
    ramp: bool,
    active: bool,
    /// The speed a split period carries into the next segment.
    term_vel: f64,
}

/// `tcGetTangentialMaxAccel` for a line (its kink's share already taken from `s.acc`): half
/// where its own term condition is PARABOLIC. A parabolic blend from the segment before does
/// not halve a STOP or TANGENT one (`blend_prev`, as the real machine ran it: module doc).
fn tangential_acc(s: &ChainSeg, tc: &Tc) -> f64 {
    if tc.term == Term::Parabolic {
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

/// `tpGetRealFinalVel`: where a TANGENT segment `s` is headed, the look-ahead's final speed
/// within its own and the next segment's speeds (`v_next`: none, as `tpUpdateBlend` runs the
/// next segment of a parabolic blend, is zero); any other ends at rest.
fn final_vel(s: &ChainSeg, tc: &Tc, v_next: f64) -> f64 {
    match tc.term {
        Term::Tangent => tc.finalvel.min(s.v).min(v_next),
        _ => 0.0,
    }
}

/// `tpUpdateCycle`: one servo period (or its rest, `tc.cycle_time`) toward the final speed
/// `v_f`: a ramp where `tpActivateSegment` chose one, else the trapezoid; then
/// `tpCheckEndCondition`.
fn update(s: &ChainSeg, tc: &mut Tc, v_f: f64, period: f64) {
    let dt = tc.cycle_time;
    let dx = s.len - tc.progress;
    let a = tangential_acc(s, tc);
    let v = tc.vel;
    let ramp = tc.ramp && tc.term == Term::Tangent && v_f >= VEL_EPSILON;
    let (acc, desired) = if ramp {
        // tpCalculateRampAccel.
        let v_avg = (v + v_f) / 2.0;
        let t = if v_avg > VEL_EPSILON {
            (dx / v_avg).max(1e-16)
        } else {
            1e-16
        };
        (((v_f - v) / t).clamp(-a, a), v_f)
    } else {
        // tpCalculateTrapezoidalAccel, findTrapezoidalDesiredVel.
        let step = dt.max(TIME_EPSILON);
        let half_step = a * step * 0.5;
        let discr = v_f * v_f + a * (2.0 * dx - v * step) + half_step * half_step;
        let mut max_new = -half_step;
        if discr > half_step * half_step {
            max_new += discr.sqrt();
        }
        let new_vel = max_new.clamp(-s.v, s.v);
        (((new_vel - v) / step).clamp(-a, a), max_new)
    };
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
    tc.on_final_decel = (desired - next).abs() < VEL_EPSILON && acc < 0.0;
    end_condition(s, tc, v_f, period);
}

/// `tpCheckEndCondition` (`checkEndCondition`): flags the period in which the segment will
/// reach its end at final speed `v_f`, and the speed it carries on.
fn end_condition(s: &ChainSeg, tc: &mut Tc, v_f: f64, period: f64) {
    tc.cycle_time = period;
    let dx = s.len - tc.progress;
    if dx <= POS_EPSILON {
        tc.progress = s.len;
        tc.splitting = true;
        tc.cycle_time = 0.0;
        tc.term_vel = tc.vel;
        tc.remove |= tc.term == Term::Stop;
        return;
    }
    if tc.term == Term::Stop {
        return;
    }
    let v_avg = (tc.vel + v_f) / 2.0;
    let mut dt = TIME_EPSILON / 2.0;
    if v_avg > VEL_EPSILON {
        dt = dt.max(dx / v_avg);
    } else if dx > v_avg * period && dx > POS_EPSILON {
        return;
    }
    let a_f = (v_f - tc.vel) / dt.max(TIME_EPSILON);
    let a_max = tangential_acc(s, tc);
    let mut end_vel = v_f;
    if a_f.abs() > a_max {
        let a = a_f.clamp(-a_max, a_max);
        let disc = (tc.vel / a).powi(2) + 2.0 / a * dx;
        if disc < 0.0 {
            return;
        }
        dt = if disc < TIME_EPSILON * TIME_EPSILON {
            -tc.vel / a
        } else if a > 0.0 {
            -tc.vel / a + disc.sqrt()
        } else {
            -tc.vel / a - disc.sqrt()
        };
        end_vel = tc.vel + dt * a;
    }
    if dt < TIME_EPSILON {
        tc.progress = s.len;
        tc.splitting = true;
        tc.cycle_time = 0.0;
        tc.term_vel = end_vel;
    } else if dt < period {
        tc.splitting = true;
        tc.cycle_time = dt;
        tc.term_vel = end_vel;
    }
}

/// How the chain ends.
#[derive(Debug, Clone, Copy, PartialEq)]
enum End {
    /// The planner stops there (a rapid or `G61` next).
    Stop,
    /// The queue ends there: its last segment keeps the PARABOLIC default, not finalized.
    Queue,
    /// A prefix: segments follow, joined as its last segment's [`ChainSeg::tangent`] says.
    Open,
}

/// Runs `segs` from rest to rest; `parabolic_end`: the last segment keeps the PARABOLIC term
/// condition (the queue ends there), else STOP.
pub fn run_chain(segs: &[ChainSeg], parabolic_end: bool, period: f64) -> ChainRun {
    let end = if parabolic_end { End::Queue } else { End::Stop };
    let mut r = Replay::start(segs, end, period);
    r.run(usize::MAX);
    r.finish()
}

/// A chain run part way: [`Replay::prefix`] runs the segments a chain starts with up to where
/// tp first looks past them, so that several endings can each be run on from there
/// ([`Replay::then`]) without replaying the start again.
#[derive(Debug, Clone)]
pub struct Replay {
    /// The segments as given.
    given: Vec<ChainSeg>,
    /// As tp runs them: each one's speed and acceleration after the tangent joins' caps.
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
    fn start(segs: &[ChainSeg], end: End, period: f64) -> Replay {
        let mut r = Replay {
            given: segs.to_vec(),
            segs: Vec::new(),
            tcs: Vec::new(),
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
        (r.segs, r.tcs) = queue(&r.given, end, period);
        r.size_switches();
        r
    }

    /// One switch record per queued segment.
    fn size_switches(&mut self) {
        let m = self.segs.len();
        self.switch_s.resize(m, 0.0);
        self.switch_speed.resize(m, 0.0);
        self.switch_past.resize(m, 0.0);
        self.switch_window.resize(m, [0.0; SWITCH_WINDOW]);
    }

    /// `segs` run from rest up to the first servo period in which tp would look at a segment
    /// after them (their last is the head, or the chain has ended).
    pub fn prefix(segs: &[ChainSeg], period: f64) -> Replay {
        let mut r = Replay::start(segs, End::Open, period);
        r.run(segs.len().saturating_sub(1));
        r
    }

    /// The prefix run on into `tail` (its last segment ending in STOP): the whole chain's run.
    /// Where the tail changes what the prefix already ran on (the look-ahead's final speeds
    /// of segments joined tangentially into it, or a split period that read its first
    /// segment), the whole chain is run again from rest.
    pub fn then(&self, tail: &[ChainSeg]) -> ChainRun {
        let mut all = self.given.clone();
        all.extend_from_slice(tail);
        let (segs, tcs) = queue(&all, End::Stop, self.period);
        let n = self.segs.len();
        let last_read =
            n > 0 && self.tcs[n - 1].term == Term::Tangent && self.tcs[n - 1].progress > 0.0;
        let same = !last_read
            && (0..n).all(|k| {
                let (a, b) = (&self.tcs[k], &tcs[k]);
                segs[k] == self.segs[k] && a.term == b.term && a.finalvel == b.finalvel
            });
        if !same {
            let mut r = Replay::start(&all, End::Stop, self.period);
            r.run(usize::MAX);
            return r.finish();
        }
        // The prefix's segments as queued are the whole chain's: the tail's follow them.
        let mut r = self.clone();
        r.given = all;
        r.segs.extend(segs.into_iter().skip(n));
        r.tcs.extend(tcs.into_iter().skip(n));
        r.size_switches();
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

    /// The final speed segment `i` heads for with `next` after it.
    fn v_f(&self, i: usize, next: Option<usize>) -> f64 {
        final_vel(
            &self.segs[i],
            &self.tcs[i],
            next.map_or(0.0, |j| self.segs[j].v),
        )
    }

    /// `tpActivateSegment`, the first period segment `i` is the head: a TANGENT segment
    /// shorter than `1 / ARC_BLEND_RAMP_FREQ` at its entry and final speeds ramps.
    fn activate(&mut self, i: usize) {
        let (s, tc) = (&self.segs[i], &mut self.tcs[i]);
        if tc.active {
            return;
        }
        tc.active = true;
        let t = 2.0 * (s.len - tc.progress) / (tc.vel + tc.finalvel.min(s.v));
        tc.ramp = t < 1.0 / RAMP_FREQ && tc.term == Term::Tangent;
        tc.blending_next = false;
        tc.on_final_decel = false;
    }

    /// One servo period of `tpRunCycle`.
    fn cycle(&mut self) {
        let (n, period, head) = (self.segs.len(), self.period, self.head);
        self.activate(head);
        let mut before = [0.0; 2];
        for (k, b) in before.iter_mut().enumerate().take(n - head) {
            *b = self.tcs[head + k].progress;
        }
        let next = (head + 1 < n).then_some(head + 1);
        if self.tcs[head].splitting {
            // tpHandleSplitCycle: the segment lands on its end; the next one gets the period
            // (the rest of it, entering at the carried speed, after a tangent join) and its
            // outputs switch (after a tangent join too, however short the rest: measured).
            self.tcs[head].progress = self.segs[head].len;
            self.tcs[head].remove = true;
            if let Some(j) = next {
                if self.tcs[head].term == Term::Tangent {
                    self.tcs[j].cycle_time = period - self.tcs[head].cycle_time;
                    self.tcs[j].vel = self.tcs[head].term_vel;
                }
                let v_f = self.v_f(j, (j + 1 < n).then_some(j + 1));
                update(&self.segs[j], &mut self.tcs[j], v_f, period);
                let at = (self.tcs[j].vel, self.tcs[j].progress);
                self.switch(j, at);
            }
        } else {
            let v_f = self.v_f(head, next);
            let segs = &self.segs;
            let tcs = &mut self.tcs;
            tcs[head].cycle_time = period;
            update(&segs[head], &mut tcs[head], v_f, period);
            if let Some(j) = next {
                let (va, vb) = blend_velocity(&segs[head], &tcs[head], &segs[j], &tcs[j]);
                tcs[head].blend_vel = va;
                tcs[j].blend_vel = vb;
                let t = &mut tcs[head];
                t.blending_next |=
                    t.term == Term::Parabolic && t.on_final_decel && t.vel < t.blend_vel;
            } else {
                tcs[head].blend_vel = 0.0;
            }
            match next {
                Some(j) if tcs[head].blending_next => {
                    // tpUpdateBlend: the next segment accelerates on its own (its target
                    // speed is its requested one; the blend's scaling touches only
                    // synchronized motion), with no segment after it.
                    let v_f = final_vel(&segs[j], &tcs[j], 0.0);
                    update(&segs[j], &mut tcs[j], v_f, period);
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

/// The chain as tp queues it: each segment's speed and acceleration after its joins
/// (`tcClampVelocityByLength`; a tangent join's kink share from both sides, and its
/// successor's speed within its length in `TP_MIN_SEGMENT_CYCLES` periods), its term
/// condition, and the look-ahead's final speeds.
fn queue(given: &[ChainSeg], end: End, period: f64) -> (Vec<ChainSeg>, Vec<Tc>) {
    let n = given.len();
    let term = |i: usize| {
        if i + 1 < n || end == End::Open {
            if given[i].tangent.is_some() {
                Term::Tangent
            } else {
                Term::Parabolic
            }
        } else if end == End::Queue {
            Term::Parabolic
        } else {
            Term::Stop
        }
    };
    let kink = |i: usize| match term(i) {
        Term::Tangent => given[i].tangent.unwrap_or(0.0),
        _ => 0.0,
    };
    let mut segs = Vec::with_capacity(n);
    let mut tcs = Vec::with_capacity(n);
    for (i, g) in given.iter().enumerate() {
        let prev_tangent = i > 0 && term(i - 1) == Term::Tangent;
        let mut v = g.v.min(g.len / period);
        if prev_tangent {
            v = v.min(g.len / (period * MIN_SEGMENT_CYCLES));
        }
        let reduce = kink(i).max(if i > 0 { kink(i - 1) } else { 0.0 });
        segs.push(ChainSeg {
            v,
            acc: g.acc * (1.0 - reduce),
            ..g.clone()
        });
        tcs.push(Tc {
            progress: 0.0,
            vel: 0.0,
            blending_next: false,
            on_final_decel: false,
            blend_vel: 0.0,
            splitting: false,
            cycle_time: period,
            remove: false,
            term: term(i),
            switched: false,
            finalvel: 0.0,
            ramp: false,
            active: false,
            term_vel: 0.0,
        });
    }
    optimize(&segs, &mut tcs, end);
    (segs, tcs)
}

/// `tpRunOptimization` after each segment is queued (the chain's last is finalized only
/// where something follows it): each TANGENT segment's final speed, the highest from which
/// the segments after it can still reach theirs.
fn optimize(segs: &[ChainSeg], tcs: &mut [Tc], end: End) {
    let n = segs.len();
    if !tcs.iter().any(|t| t.term == Term::Tangent) {
        return;
    }
    let mut at_max = vec![false; n];
    let last_len = if end == End::Stop { n + 1 } else { n };
    for len in 2..=last_len {
        let (mut peaks, mut crossed) = (0, false);
        for x in 1..OPTIMIZATION_DEPTH + 2 {
            let Some(prev) = len.checked_sub(x + 1) else {
                break;
            };
            let tc = prev + 1;
            if tcs[prev].term != Term::Tangent {
                if crossed {
                    break;
                }
                crossed = true;
                continue;
            }
            let acc = tangential_acc(&segs[tc], &tcs[tc]);
            if tc + 1 < len {
                // tpComputeOptimalVelocity (the segment is finalized).
                let back = (tcs[tc].finalvel.powi(2) + 2.0 * acc * segs[tc].len).sqrt();
                let limit = segs[tc].v.min(segs[prev].v);
                if back >= limit {
                    at_max[prev] = true;
                }
                tcs[prev].finalvel = back.min(limit);
            } else {
                // tpCalculateOptimizationInitialVel: the last queued may lose half its
                // length to a blend.
                let v0 = (acc * segs[tc].len).sqrt().min(segs[tc].v);
                tcs[prev].finalvel = v0.min(segs[prev].v);
                tcs[tc].finalvel = 0.0;
            }
            if at_max[tc] {
                peaks += 1;
            }
            if peaks > OPTIMIZATION_CUTOFF {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests;
