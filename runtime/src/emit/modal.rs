//! The modal state of a G-code interpreter, as far as a job depends on it, and the words
//! that name it. The link's modal tracker predicts it line by line, a controller reports it
//! (GRBL's `$G`), and a resumed job's re-approach ([`super::reapproach`]) restores it; the
//! words live here because `emit` is the only code that writes NC text.

/// The modal state of a controller's G-code interpreter, as far as a job depends on it. Feed
/// is in mm/min (or the inverse-time value in G93), positions in mm, work coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct ModalState {
    pub motion: MotionMode,
    pub plane: Plane,
    pub inches: bool,
    pub incremental: bool,
    pub inverse_time: bool,
    pub spindle: Spindle,
    pub flood: bool,
    pub mist: bool,
    pub feed: f64,
    pub s: f64,
}

impl Default for ModalState {
    /// GRBL's state after power-up or reset: G0 G54 G17 G21 G90 G94 M5 M9 F0 S0.
    fn default() -> Self {
        ModalState {
            motion: MotionMode::Rapid,
            plane: Plane::Xy,
            inches: false,
            incremental: false,
            inverse_time: false,
            spindle: Spindle::Off,
            flood: false,
            mist: false,
            feed: 0.0,
            s: 0.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionMode {
    Rapid,
    Linear,
    ArcCw,
    ArcCcw,
    /// G80: no motion mode.
    None,
}

impl MotionMode {
    pub fn word(self) -> &'static str {
        match self {
            MotionMode::Rapid => "G0",
            MotionMode::Linear => "G1",
            MotionMode::ArcCw => "G2",
            MotionMode::ArcCcw => "G3",
            MotionMode::None => "G80",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plane {
    Xy,
    Zx,
    Yz,
}

impl Plane {
    pub fn word(self) -> &'static str {
        match self {
            Plane::Xy => "G17",
            Plane::Zx => "G18",
            Plane::Yz => "G19",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spindle {
    Off,
    Cw,
    Ccw,
}

impl ModalState {
    /// The state in words, for messages: `G1 G90 G21 M3 F600 S400`.
    pub fn describe(&self) -> String {
        format!(
            "{} {} {} M{} F{} S{}",
            self.motion.word(),
            if self.incremental { "G91" } else { "G90" },
            if self.inches { "G20" } else { "G21" },
            match self.spindle {
                Spindle::Off => 5,
                Spindle::Cw => 3,
                Spindle::Ccw => 4,
            },
            self.feed,
            self.s
        )
    }
}
