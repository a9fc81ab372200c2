//! The simulator's G-code interpreter: one block (already stripped of spaces and comments and
//! upper-cased, as GRBL's protocol loop hands it over) is checked the way GRBL's
//! `gc_execute_line` checks it — same error codes — and turned into the parser's next state
//! and the physical steps it asks for, in GRBL's order of execution.
//!
//! Supported: G0–G3 (offset and radius arcs in all three planes), G4, G17–G19, G20/G21, G40,
//! G43.1/G49, G53, G54–G59 (with the offsets the simulator was started with), G61, G80, G90/G91, G91.1, G93/G94; M0–M2, M30, M3–M5, M8, M9;
//! F, S, T, N. G10, G28, G30, G38.x and G92 are refused with error 20 (not simulated).
//! Axis words are X, Y, Z and, on a grblHAL build with more axes, A, B, C (degrees when
//! rotary); a letter for an axis the build lacks is error 20, as in GRBL.

use crate::link::{AXIS_LETTERS, AxisPos, ModalState, MotionMode, Plane, Spindle};

/// GRBL's limits on numbers in a block.
const MAX_LINE_NUMBER: f64 = 10_000_000.0;
const MAX_TOOL: f64 = 255.0;

/// The interpreter's state: modal state and where the parser thinks the machine is.
#[derive(Debug, Clone, PartialEq)]
pub struct Gc {
    pub modal: ModalState,
    /// mm (degrees for rotary axes), machine coordinates.
    pub pos: AxisPos,
    /// The coordinate system in force, 0 for G54 … 5 for G59.
    pub coord: usize,
    /// The work offsets G54 … G59 (machine = work + offset), as `$#` reports them; GRBL keeps
    /// them in EEPROM, so a reset leaves them (the controller sets them again).
    pub offsets: [AxisPos; 6],
    pub tool: u32,
    /// Axes of the build: 3 (X Y Z) to 6 (X Y Z A B C).
    pub axes: usize,
}

impl Gc {
    pub fn new(pos: AxisPos, axes: usize) -> Gc {
        Gc {
            modal: ModalState::default(),
            pos,
            coord: 0,
            offsets: [[0.0; 6]; 6],
            tool: 0,
            axes: axes.clamp(3, AXIS_LETTERS.len()),
        }
    }

    /// `$G`: `[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]`.
    pub fn report(&self) -> String {
        let m = &self.modal;
        let k = if m.inches { 25.4 } else { 1.0 };
        format!(
            "[GC:{} G{} {} {} {} {} {} {} T{} F{} S{}]",
            m.motion.word(),
            54 + self.coord,
            m.plane.word(),
            if m.inches { "G20" } else { "G21" },
            if m.incremental { "G91" } else { "G90" },
            if m.inverse_time { "G93" } else { "G94" },
            match m.spindle {
                Spindle::Off => "M5",
                Spindle::Cw => "M3",
                Spindle::Ccw => "M4",
            },
            match (m.flood, m.mist) {
                (false, false) => "M9",
                (true, false) => "M8",
                (false, true) => "M7",
                (true, true) => "M7 M8",
            },
            self.tool,
            (if m.inverse_time { m.feed } else { m.feed / k }).round(),
            m.s.round()
        )
    }
}

/// An arc of a move.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arc {
    pub center: AxisPos,
    pub ccw: bool,
    pub plane: Plane,
}

/// A move a block asks for.
#[derive(Debug, Clone, PartialEq)]
pub struct Move {
    pub from: AxisPos,
    pub target: AxisPos,
    pub rapid: bool,
    /// mm/min; for inverse time, the whole move's duration instead.
    pub feed_mm_min: f64,
    pub inverse_time_s: Option<f64>,
    pub arc: Option<Arc>,
    /// Laser power (S) while moving, 0 when the laser is off for this move.
    pub laser_s: f64,
}

/// What a block does after its modal changes, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Wait until the planner is empty and the machine at rest.
    Sync,
    /// Switch the laser output at rest: power S (0 = off).
    LaserAtRest(f64),
    Coolant {
        flood: bool,
        mist: bool,
    },
    Dwell(f64),
    Move(Move),
    /// M2/M30: `[MSG:Pgm End]`.
    ProgramEnd,
    /// M0/M1: wait for cycle start.
    Pause,
}

/// A checked block.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    pub next: Gc,
    pub steps: Vec<Step>,
}

#[derive(Default)]
struct Words {
    // Value words (letter index → value), GRBL's value_words bitmask.
    vals: [Option<f64>; 26],
}

fn idx(c: u8) -> usize {
    (c - b'A') as usize
}

/// Reads GRBL's float format: optional sign, digits, at most one point, at least one digit.
fn read_number(s: &[u8], i: &mut usize) -> Option<f64> {
    let start = *i;
    if *i < s.len() && (s[*i] == b'-' || s[*i] == b'+') {
        *i += 1;
    }
    let mut digits = 0;
    let mut point = false;
    while *i < s.len() {
        match s[*i] {
            b'0'..=b'9' => digits += 1,
            b'.' if !point => point = true,
            _ => break,
        }
        *i += 1;
    }
    if digits == 0 {
        return None;
    }
    std::str::from_utf8(&s[start..*i]).ok()?.parse().ok()
}

/// Whether the laser is lit in this motion mode (GRBL laser mode: only G1, G2, G3).
fn lit_mode(m: MotionMode) -> bool {
    matches!(
        m,
        MotionMode::Linear | MotionMode::ArcCw | MotionMode::ArcCcw
    )
}

/// The laser power at rest in a state: M3 keeps constant power in G1/G2/G3, M4 is dark when
/// not moving.
pub fn rest_power(m: &ModalState, laser_mode: bool) -> f64 {
    let lit = if laser_mode {
        m.spindle == Spindle::Cw && lit_mode(m.motion)
    } else {
        m.spindle != Spindle::Off
    };
    if lit { m.s } else { 0.0 }
}

/// Checks and interprets one block. `Err` is GRBL's error code.
pub fn execute(line: &[u8], gc: &Gc, laser_mode: bool) -> Result<Block, u32> {
    // [1. Words] -----------------------------------------------------------------------
    let mut w = Words::default();
    let mut motion: Option<MotionMode> = None;
    let mut plane = None;
    let mut units = None;
    let mut distance = None;
    let mut feed_mode = None;
    let mut non_modal: Option<u32> = None; // 4 dwell, 53 machine coordinates
    let mut coord: Option<usize> = None;
    let mut spindle = None;
    let mut coolant: Option<(bool, bool)> = None;
    let mut flow: Option<u32> = None;
    let mut seen_groups = 0u32;
    let mut group = |g: u32| -> Result<(), u32> {
        if seen_groups & (1 << g) != 0 {
            return Err(21);
        }
        seen_groups |= 1 << g;
        Ok(())
    };
    let mut i = 0;
    while i < line.len() {
        let letter = line[i];
        if !letter.is_ascii_uppercase() {
            return Err(1);
        }
        i += 1;
        let value = read_number(line, &mut i).ok_or(2u32)?;
        let int = value.trunc();
        let mantissa = ((value - int) * 100.0).round() as i64;
        match letter {
            b'G' => {
                let (g, m) = (int as i64, mantissa);
                match (g, m) {
                    (0..=3, 0) => {
                        group(1)?;
                        motion = Some(
                            [
                                MotionMode::Rapid,
                                MotionMode::Linear,
                                MotionMode::ArcCw,
                                MotionMode::ArcCcw,
                            ][g as usize],
                        );
                    }
                    (80, 0) => {
                        group(1)?;
                        motion = Some(MotionMode::None);
                    }
                    (4, 0) => {
                        group(0)?;
                        non_modal = Some(4);
                    }
                    (53, 0) => {
                        group(0)?;
                        non_modal = Some(53);
                    }
                    (17..=19, 0) => {
                        group(2)?;
                        plane = Some([Plane::Xy, Plane::Zx, Plane::Yz][(g - 17) as usize]);
                    }
                    (20 | 21, 0) => {
                        group(6)?;
                        units = Some(g == 20);
                    }
                    (90 | 91, 0) => {
                        group(3)?;
                        distance = Some(g == 91);
                    }
                    // Arc IJK distance mode: GRBL only supports incremental (G91.1).
                    (91, 10) => group(4)?,
                    (93 | 94, 0) => {
                        group(5)?;
                        feed_mode = Some(g == 93);
                    }
                    (40, 0) => group(7)?,
                    (43, 10) | (49, 0) => group(8)?,
                    (54..=59, 0) => {
                        group(12)?;
                        coord = Some((g - 54) as usize);
                    }
                    (61, 0) => group(13)?,
                    (10 | 28 | 30 | 38 | 92, _) => return Err(20),
                    (_, m)
                        if m != 0
                            && [
                                0, 1, 2, 3, 4, 17, 18, 19, 20, 21, 53, 80, 90, 91, 93, 94, 40, 49,
                                61,
                            ]
                            .contains(&g) =>
                    {
                        return Err(23);
                    }
                    _ => return Err(20),
                }
            }
            b'M' => {
                if mantissa != 0 {
                    return Err(23);
                }
                match int as i64 {
                    0 | 1 | 2 | 30 => {
                        group(9)?;
                        flow = Some(int as u32);
                    }
                    3 => {
                        group(10)?;
                        spindle = Some(Spindle::Cw)
                    }
                    4 => {
                        group(10)?;
                        spindle = Some(Spindle::Ccw)
                    }
                    5 => {
                        group(10)?;
                        spindle = Some(Spindle::Off)
                    }
                    8 => {
                        group(11)?;
                        coolant = Some((true, gc.modal.mist));
                    }
                    9 => {
                        group(11)?;
                        coolant = Some((false, false));
                    }
                    _ => return Err(20),
                }
            }
            b'F' | b'I' | b'J' | b'K' | b'L' | b'N' | b'P' | b'R' | b'S' | b'T' | b'X' | b'Y'
            | b'Z' => {
                let slot = &mut w.vals[idx(letter)];
                if slot.is_some() {
                    return Err(25);
                }
                *slot = Some(value);
            }
            b'A' | b'B' | b'C' if AXIS_LETTERS[..gc.axes].iter().any(|&a| a as u8 == letter) => {
                let slot = &mut w.vals[idx(letter)];
                if slot.is_some() {
                    return Err(25);
                }
                *slot = Some(value);
            }
            _ => return Err(20),
        }
    }
    let v = |c: u8| w.vals[idx(c)];
    for c in [b'F', b'N', b'P', b'T', b'S'] {
        if v(c).is_some_and(|x| x < 0.0) {
            return Err(4);
        }
    }
    if v(b'N').is_some_and(|n| n > MAX_LINE_NUMBER) {
        return Err(27);
    }
    if v(b'T').is_some_and(|t| t > MAX_TOOL) {
        return Err(38);
    }

    // [2. Next state and checks] --------------------------------------------------------
    let mut next = gc.clone();
    let m = &mut next.modal;
    if let Some(f) = feed_mode {
        m.inverse_time = f;
    }
    if let Some(u) = units {
        m.inches = u;
    }
    if let Some(d) = distance {
        m.incremental = d;
    }
    if let Some(p) = plane {
        m.plane = p;
    }
    let k = if m.inches { 25.4 } else { 1.0 };
    let axis_letters: Vec<u8> = AXIS_LETTERS[..gc.axes].iter().map(|&c| c as u8).collect();
    let axis_words = axis_letters.iter().any(|&c| v(c).is_some());
    // An axis word without a motion word runs the modal motion.
    let explicit_motion = motion.is_some();
    if let Some(mm) = motion {
        m.motion = mm;
    }
    let axis_command = axis_words || (explicit_motion && m.motion != MotionMode::None);
    // Feed, as GRBL keeps it: the block's F when it has one; without, the last feed only in
    // G94 after G94 (in G93 a feed move needs F in its own block, and switching from G93 to
    // G94 leaves the feed undefined).
    let mut block_feed = None;
    if let Some(f) = v(b'F') {
        if m.inverse_time {
            block_feed = Some(f);
            m.feed = f;
        } else {
            m.feed = f * k;
        }
    } else if m.inverse_time || gc.modal.inverse_time {
        m.feed = 0.0;
    }
    if let Some(s) = v(b'S') {
        m.s = s;
    }
    if let Some(t) = v(b'T') {
        next.tool = t as u32;
    }
    if let Some(c) = coord {
        next.coord = c;
    }
    if non_modal == Some(4) && v(b'P').is_none() {
        return Err(28);
    }
    if non_modal == Some(53) && !matches!(m.motion, MotionMode::Rapid | MotionMode::Linear) {
        return Err(30);
    }
    let mut used = 0u32;
    for c in [b'N', b'F', b'S', b'T'] {
        used |= 1 << idx(c);
    }
    if non_modal == Some(4) {
        used |= 1 << idx(b'P');
    }
    // Target, in mm.
    let mut target = gc.pos;
    for (a, &c) in axis_letters.iter().enumerate() {
        if let Some(x) = v(c) {
            // Inches scale the linear axes; rotary A, B, C stay in degrees.
            let x = if a < 3 { x * k } else { x };
            // gc.c: absolute coordinates are work coordinates (the block's own coordinate
            // system, offset added), G53's are machine coordinates.
            target[a] = if non_modal == Some(53) {
                x
            } else if m.incremental {
                gc.pos[a] + x
            } else {
                x + next.offsets[next.coord][a]
            };
        }
    }
    let mut mv: Option<Move> = None;
    match m.motion {
        MotionMode::None => {
            if axis_words {
                return Err(31);
            }
        }
        _ if !axis_command => {}
        MotionMode::Rapid => {
            if axis_words {
                used |= axis_letters.iter().map(|&c| 1 << idx(c)).sum::<u32>();
                mv = Some(Move {
                    from: gc.pos,
                    target,
                    rapid: true,
                    feed_mm_min: 0.0,
                    inverse_time_s: None,
                    arc: None,
                    laser_s: 0.0,
                });
            }
        }
        mode => {
            let feed_defined = if m.inverse_time {
                block_feed.is_some_and(|f| f > 0.0)
            } else {
                m.feed > 0.0
            };
            if !feed_defined {
                return Err(22);
            }
            let inverse_time_s = block_feed.map(|f| 60.0 / f);
            if mode == MotionMode::Linear {
                if axis_words {
                    used |= axis_letters.iter().map(|&c| 1 << idx(c)).sum::<u32>();
                    mv = Some(Move {
                        from: gc.pos,
                        target,
                        rapid: false,
                        feed_mm_min: m.feed,
                        inverse_time_s,
                        arc: None,
                        laser_s: 0.0,
                    });
                }
            } else {
                if !axis_words {
                    return Err(26);
                }
                let (a0, a1) = match m.plane {
                    Plane::Xy => (0, 1),
                    Plane::Zx => (2, 0),
                    Plane::Yz => (1, 2),
                };
                let offs = [b'I', b'J', b'K'];
                if v(axis_letters[a0]).is_none() && v(axis_letters[a1]).is_none() {
                    return Err(32);
                }
                used |= axis_letters.iter().map(|&c| 1 << idx(c)).sum::<u32>();
                let x = target[a0] - gc.pos[a0];
                let y = target[a1] - gc.pos[a1];
                let ccw = mode == MotionMode::ArcCcw;
                let (c0, c1) = if let Some(r) = v(b'R') {
                    used |= 1 << idx(b'R');
                    if x == 0.0 && y == 0.0 {
                        return Err(33);
                    }
                    let r = r * k;
                    let mut h_x2_div_d = 4.0 * r * r - x * x - y * y;
                    if h_x2_div_d < 0.0 {
                        return Err(33);
                    }
                    h_x2_div_d = -h_x2_div_d.sqrt() / x.hypot(y);
                    if ccw {
                        h_x2_div_d = -h_x2_div_d;
                    }
                    if r < 0.0 {
                        h_x2_div_d = -h_x2_div_d;
                    }
                    let i = 0.5 * (x - y * h_x2_div_d);
                    let j = 0.5 * (y + x * h_x2_div_d);
                    (gc.pos[a0] + i, gc.pos[a1] + j)
                } else {
                    let (i_w, j_w) = (offs[a0], offs[a1]);
                    if v(i_w).is_none() && v(j_w).is_none() {
                        return Err(35);
                    }
                    used |= (1 << idx(i_w)) | (1 << idx(j_w));
                    let i = v(i_w).unwrap_or(0.0) * k;
                    let j = v(j_w).unwrap_or(0.0) * k;
                    // GRBL: the radius to the target may differ from the radius to the start
                    // by 0.005 mm, or by 0.5 mm and 0.1 % of the radius.
                    let r0 = i.hypot(j);
                    let r1 = (x - i).hypot(y - j);
                    let delta = (r1 - r0).abs();
                    if delta > 0.005 && (delta > 0.5 || delta > 0.001 * r0) {
                        return Err(33);
                    }
                    (gc.pos[a0] + i, gc.pos[a1] + j)
                };
                let mut center = gc.pos;
                center[a0] = c0;
                center[a1] = c1;
                mv = Some(Move {
                    from: gc.pos,
                    target,
                    rapid: false,
                    feed_mm_min: m.feed,
                    inverse_time_s,
                    arc: Some(Arc {
                        center,
                        ccw,
                        plane: m.plane,
                    }),
                    laser_s: 0.0,
                });
            }
        }
    }
    // Offset words of another plane, or I/J/K on a line, are unused.
    for c in [b'I', b'J', b'K', b'L', b'P', b'R']
        .into_iter()
        .chain(axis_letters.iter().copied())
    {
        if v(c).is_some() && used & (1 << idx(c)) == 0 {
            return Err(36);
        }
    }

    // [3. Steps, in GRBL's order] --------------------------------------------------------
    let mut steps = Vec::new();
    let before = &gc.modal;
    let new_spindle = spindle.unwrap_or(before.spindle);
    let moving = mv.is_some();
    if let Some(sp) = spindle {
        m.spindle = sp;
    }
    let rest = rest_power(m, laser_mode);
    let rest_before = rest_power(before, laser_mode);
    // Spindle state changes always synchronize; in laser mode a power or lit-mode change
    // without motion does too (the laser must change at rest, in program order).
    let spindle_changed = new_spindle != before.spindle;
    let rest_changed = (rest - rest_before).abs() > 0.0;
    if spindle_changed || (!moving && rest_changed) || (!laser_mode && m.s != before.s) {
        steps.push(Step::Sync);
        steps.push(Step::LaserAtRest(if moving {
            rest_before.min(rest)
        } else {
            rest
        }));
    }
    if let Some((flood, mist)) = coolant
        && (flood, mist) != (before.flood, before.mist)
    {
        m.flood = flood;
        m.mist = mist;
        steps.push(Step::Sync);
        steps.push(Step::Coolant { flood, mist });
    }
    if non_modal == Some(4) {
        steps.push(Step::Sync);
        steps.push(Step::Dwell(dwell_s(v(b'P').unwrap_or(0.0))));
    }
    if let Some(mut mv) = mv {
        mv.laser_s = if laser_mode {
            if m.spindle != Spindle::Off && lit_mode(m.motion) {
                m.s
            } else {
                0.0
            }
        } else if m.spindle != Spindle::Off {
            m.s
        } else {
            0.0
        };
        next.pos = mv.target;
        steps.push(Step::Move(mv));
    }
    let m = &mut next.modal;
    match flow {
        Some(2 | 30) => {
            steps.push(Step::Sync);
            m.motion = MotionMode::Linear;
            m.plane = Plane::Xy;
            m.incremental = false;
            m.inverse_time = false;
            m.spindle = Spindle::Off;
            m.flood = false;
            m.mist = false;
            steps.push(Step::LaserAtRest(0.0));
            steps.push(Step::Coolant {
                flood: false,
                mist: false,
            });
            steps.push(Step::ProgramEnd);
        }
        Some(_) => {
            steps.push(Step::Sync);
            steps.push(Step::Pause);
        }
        None => {}
    }
    Ok(Block { next, steps })
}

/// How long `G4 P…` dwells: GRBL's `delay_sec` (nuts_bolts.c; grblHAL's the same) waits
/// `ceil(1000/DWELL_TIME_STEP * P)` steps of `DWELL_TIME_STEP` = 50 ms (config.h), in single
/// precision as the firmware computes it.
pub fn dwell_s(p: f64) -> f64 {
    const DWELL_TIME_STEP_MS: f32 = 50.0;
    let steps = ((1000.0 / DWELL_TIME_STEP_MS) * p as f32).ceil().max(0.0);
    f64::from(steps) * f64::from(DWELL_TIME_STEP_MS) / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(lines: &[&str]) -> Result<Gc, (usize, u32)> {
        let mut gc = Gc::new([0.0; 6], 3);
        for (i, l) in lines.iter().enumerate() {
            gc = execute(l.as_bytes(), &gc, true).map_err(|e| (i, e))?.next;
        }
        Ok(gc)
    }

    #[test]
    fn grbl_error_codes_for_malformed_blocks() {
        for (line, code) in [
            ("1X", 1),
            ("GX", 2),
            ("G1X1.2.3", 1),
            ("G1X1", 22),
            ("G0G1X1", 21),
            ("G5X1", 20),
            ("G1.5X1", 23),
            ("M3.5", 23),
            ("M99", 20),
            ("X1X2", 25),
            ("F-1", 4),
            ("G4", 28),
            ("G80X1", 31),
            ("G2F100", 26),
            ("G2Z1F100", 32),
            ("G2X1F100", 35),
            ("G2X10I1F100", 33),
            ("G0X1I1", 36),
            ("N99999999", 27),
            ("T300", 38),
            ("E5", 20),
            ("G92X0", 20),
        ] {
            let got = execute(line.as_bytes(), &Gc::new([0.0; 6], 3), true).map(|_| ());
            assert_eq!(got, Err(code), "{line}");
        }
    }

    #[test]
    fn modal_state_and_position_follow_the_program() {
        let gc = run(&[
            "G21G90G17G94",
            "G0X-1.5Y0",
            "M3S400",
            "G3X0Y-1.5I1.5J0F1200",
            "G1G91X1",
        ])
        .unwrap();
        assert_eq!(gc.pos, [1.0, -1.5, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(gc.modal.motion, MotionMode::Linear);
        // A modal arc needs its offsets.
        assert_eq!(execute(b"G3X1", &gc, true).map(|_| ()), Ok(()).and(Err(35)));
        assert_eq!(gc.modal.feed, 1200.0);
        assert!(gc.modal.incremental);
        assert_eq!(
            gc.report(),
            "[GC:G1 G54 G17 G21 G91 G94 M3 M9 T0 F1200 S400]"
        );
        let gc = run(&["G20", "G1X1F10"]).unwrap();
        assert!((gc.pos[0] - 25.4).abs() < 1e-12);
        assert_eq!(gc.report(), "[GC:G1 G54 G17 G20 G90 G94 M5 M9 T0 F10 S0]");
    }

    #[test]
    fn a_grblhal_build_moves_rotary_axes_in_inverse_time() {
        let gc = Gc::new([0.0; 6], 6);
        let b = execute(b"G93G1X10B-5.5C90F120", &gc, true).unwrap();
        let [Step::Move(mv)] = &b.steps[..] else {
            panic!("one move: {:?}", b.steps);
        };
        assert_eq!(mv.target, [10.0, 0.0, 0.0, 0.0, -5.5, 90.0]);
        assert_eq!(mv.inverse_time_s, Some(0.5));
        // Inches scale X, Y, Z only.
        let b = execute(b"G20G94G1C45X1F10", &gc, true).unwrap();
        assert_eq!(b.next.pos, [25.4, 0.0, 0.0, 0.0, 0.0, 45.0]);
        // G93 needs F in every feed block.
        assert_eq!(execute(b"C10", &b.next.clone(), true).map(|_| ()), Ok(()));
        let g93 = execute(b"G93", &gc, true).unwrap().next;
        assert_eq!(execute(b"G1C10", &g93, true).map(|_| ()), Err(22));
        // A four-axis build has A but no B or C; GRBL has none of them.
        let four = Gc::new([0.0; 6], 4);
        assert!(execute(b"G0A10", &four, true).is_ok());
        assert_eq!(execute(b"G0B10", &four, true).map(|_| ()), Err(20));
        assert_eq!(
            execute(b"G0A10", &Gc::new([0.0; 6], 3), true).map(|_| ()),
            Err(20)
        );
        // A rotary word with an arc moves linearly along it (a helix): unused offsets still
        // count, A is used.
        assert!(execute(b"G2X1Y1I1J0A30F100", &four, true).is_ok());
    }

    #[test]
    fn a_work_offset_moves_absolute_coordinates_as_gc_c_does() {
        let mut gc = Gc::new([0.0; 6], 3);
        gc.offsets[1] = [100.0, 50.0, 0.0, 0.0, 0.0, 0.0];
        // G55 in the block applies to the block's own coordinates; it stays in force.
        let b = execute(b"G55G0X5Y5", &gc, true).unwrap();
        assert_eq!(b.next.pos, [105.0, 55.0, 0.0, 0.0, 0.0, 0.0]);
        assert_eq!(b.next.coord, 1);
        assert!(b.next.report().contains(" G55 "), "{}", b.next.report());
        let b = execute(b"G1X35F600", &b.next, true).unwrap();
        assert_eq!(b.next.pos[0], 135.0);
        // Incremental moves and G53 ignore it; G54 (zero here) takes it away.
        let b = execute(b"G91G1X1", &b.next, true).unwrap();
        assert_eq!(b.next.pos[0], 136.0);
        let b = execute(b"G90G53G0X7", &b.next, true).unwrap();
        assert_eq!(b.next.pos[0], 7.0);
        let b = execute(b"G54G0X7", &b.next, true).unwrap();
        assert_eq!(b.next.pos[0], 7.0);
    }

    #[test]
    fn the_feed_is_undefined_after_inverse_time_as_in_grbl() {
        let gc = run(&["G94G1X1F600", "G93", "G1X2F30"]).unwrap();
        assert_eq!(gc.modal.feed, 30.0);
        // Back in G94 without an F: GRBL's error 22, not the feed from before G93.
        let g94 = execute(b"G94", &gc, true).unwrap().next;
        assert_eq!(g94.modal.feed, 0.0);
        assert_eq!(execute(b"G1X3", &g94, true).map(|_| ()), Err(22));
        assert!(execute(b"G1X3F100", &g94, true).is_ok());
    }

    #[test]
    fn laser_mode_lights_feed_moves_only() {
        let gc = run(&["M3S250"]).unwrap();
        let b = execute(b"G0X1", &gc, true).unwrap();
        assert!(matches!(&b.steps[..], [Step::Move(m)] if m.laser_s == 0.0));
        let b = execute(b"G1X1F100", &gc, true).unwrap();
        assert!(matches!(&b.steps[..], [Step::Move(m)] if m.laser_s == 250.0));
        // Switching on synchronizes.
        let b = execute(b"M3S250", &Gc::new([0.0; 6], 3), true).unwrap();
        assert_eq!(b.steps[0], Step::Sync);
    }

    /// `G4` dwells whole 50 ms steps, rounded up.
    #[test]
    fn dwells_in_50_ms_steps() {
        for (p, dwelt) in [
            ("0", 0.0),
            ("0.0005", 0.05),
            ("0.05", 0.05),
            ("0.16", 0.2),
            ("0.5", 0.5),
            ("1.26", 1.3),
        ] {
            let b = execute(format!("G4P{p}").as_bytes(), &Gc::new([0.0; 6], 3), true).unwrap();
            assert_eq!(b.steps[..], [Step::Sync, Step::Dwell(dwelt)], "G4 P{p}");
        }
    }
}
