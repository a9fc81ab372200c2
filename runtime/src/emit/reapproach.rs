//! The NC lines that continue a job after a lost link: the re-approach that brings a
//! GRBL-family controller (GRBL, grblHAL: the same words), at rest and in any state, to the
//! modal state and position a job's next line expects, and the motion word a modal arc line
//! needs after it. `link::resume` decides where a job stands and when these lines go out;
//! what they say is written here, because `emit` is the only code that writes NC text.

use super::format::{degrees, fine_number, number};
use super::modal::{ModalState, MotionMode, Spindle};

/// A re-approach in two parts.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Reapproach {
    /// Laser off, then positioning and modal state: sent one at a time, each answered.
    pub setup: Vec<String>,
    /// The lines that re-arm the laser (power, motion mode): sent in one burst with the job's
    /// next lines, so that the beam is on at rest no longer than in the program itself.
    pub lead: Vec<String>,
}

impl Reapproach {
    pub fn all(&self) -> Vec<String> {
        self.setup.iter().chain(&self.lead).cloned().collect()
    }
}

/// The GRBL-family re-approach to `state` at `position` (work coordinates, one value per
/// entry of `letters`, the machine's axis letters; mm, degrees for A, B, C): laser off,
/// millimetres and absolute, a rapid to the point, then units, distance mode, feed mode
/// (G93/G94), plane and coolant as setup; laser power and the motion mode with its feed as
/// the lead. Letters that are not controller axes are left out.
pub fn grbl_reapproach(state: &ModalState, letters: &[char], position: &[f64]) -> Reapproach {
    let mut out = vec!["M5".to_string(), "G21 G90 G94".to_string()];
    let axes: Vec<String> = letters
        .iter()
        .zip(position)
        .filter(|(l, _)| "XYZABC".contains(l.to_ascii_uppercase()))
        // To the job's own precision (1e-6°; 1 nm, as inverse-time programs write linear
        // axes: a position read from a 0.1 µm program writes the same), so the re-approach
        // ends exactly where the job's next line starts from.
        .map(|(l, v)| match l {
            'A' | 'B' | 'C' => format!("{l}{}", degrees(*v)),
            _ => format!("{l}{}", fine_number(*v)),
        })
        .collect();
    if !axes.is_empty() {
        out.push(format!("G0 {}", axes.join(" ")));
    }
    out.push(format!(
        "{} {} {} {}",
        if state.inches { "G20" } else { "G21" },
        if state.incremental { "G91" } else { "G90" },
        if state.inverse_time { "G93" } else { "G94" },
        state.plane.word()
    ));
    out.push(
        match (state.flood, state.mist) {
            (false, false) => "M9",
            (true, false) => "M8",
            (false, true) => "M7",
            (true, true) => "M7 M8",
        }
        .into(),
    );
    let units = if state.inches { 25.4 } else { 1.0 };
    let setup = out;
    let mut out = Vec::new();
    // Power before the motion mode: in G0 the laser stays off whatever M3 says.
    out.push(match state.spindle {
        Spindle::Off => format!("S{}", number(state.s)),
        Spindle::Cw => format!("M3 S{}", number(state.s)),
        Spindle::Ccw => format!("M4 S{}", number(state.s)),
    });
    match state.motion {
        MotionMode::Rapid => {}
        MotionMode::None => out.push("G80".into()),
        // G2/G3 cannot be set without an arc: G1 stands in, and the next modal arc line
        // is sent with its motion word (`with_motion_word`).
        MotionMode::Linear | MotionMode::ArcCw | MotionMode::ArcCcw => {
            if state.inverse_time {
                // In G93 a block with a G1 word needs an F of its own, even when nothing
                // moves (GRBL's error 22). No move uses this one: each G93 move carries
                // its own.
                out.push("G1 F1".into());
            } else if state.feed > 0.0 {
                out.push(format!("G1 F{}", number(state.feed / units)));
            }
        }
    }
    Reapproach { setup, lead: out }
}

/// A modal line (one without a motion word) with `motion`'s word in front: how the first arc
/// line after a re-approach that stood in G1 for G2/G3 is sent.
pub fn with_motion_word(motion: MotionMode, line: &str) -> String {
    format!("{} {line}", motion.word())
}

/// A GRBL-family jog (`$J=`): `dist` along `axis`, relative and in millimetres (degrees for a
/// rotary axis, which G21 leaves alone), at `feed_per_min`; to a micrometre, as a person jogs.
pub fn grbl_jog(axis: char, dist: f64, feed_per_min: f64) -> String {
    let um = |v: f64| {
        let s = format!("{v:.3}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        if s == "-0" {
            "0".to_string()
        } else {
            s.to_string()
        }
    };
    format!(
        "$J=G91 G21 {}{} F{}",
        axis.to_ascii_uppercase(),
        um(dist),
        um(feed_per_min)
    )
}

/// LinuxCNC: the outputs a post switches with motion-synchronized words (`M62`/`M63 Pn`,
/// `M67 En`) switched at once (`M65 Pn`, `M68 En Q0`): the beam off at rest, after an abort
/// or before a re-approach, without waiting for a move that will not come.
pub fn linuxcnc_outputs_off(post: &crate::machine::DialectPost) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    // The gates first (`laser_off`, `pulse_off`), then the power.
    let lines = post
        .laser_off
        .iter()
        .chain(&post.pulse_off)
        .chain(&post.laser_on)
        .chain(&post.power)
        .chain(&post.pulse_on);
    for line in lines {
        let words: Vec<&str> = line.split_whitespace().collect();
        for (k, w) in words.iter().enumerate() {
            let arg = words.get(k + 1).copied().unwrap_or("");
            let off = match *w {
                "M62" | "M63" | "M64" | "M65" if arg.starts_with('P') => format!("M65 {arg}"),
                "M67" | "M68" if arg.starts_with('E') => format!("M68 {arg} Q0"),
                _ => continue,
            };
            if !out.contains(&off) {
                out.push(off);
            }
        }
    }
    out
}

/// The LinuxCNC re-approach to `position` (one value per entry of `letters`; mm, degrees):
/// outputs off at once, millimetres, absolute, units per minute, and a rapid to the point.
/// LinuxCNC's run-from-line (`set run N`) then rebuilds the modal state by reading the
/// program up to line N itself, so no modal lines follow; the beam comes back with the
/// program's own motion-synchronized lines, which the caller passes as `lead`.
pub fn linuxcnc_reapproach(
    post: &crate::machine::DialectPost,
    letters: &[char],
    position: &[f64],
    lead: Vec<String>,
) -> Reapproach {
    let mut setup = linuxcnc_outputs_off(post);
    setup.push("G21 G90 G94".to_string());
    let axes: Vec<String> = letters
        .iter()
        .zip(position)
        .map(|(l, v)| match l {
            'A' | 'B' | 'C' => format!("{l}{}", degrees(*v)),
            _ => format!("{l}{}", fine_number(*v)),
        })
        .collect();
    if !axes.is_empty() {
        setup.push(format!("G0 {}", axes.join(" ")));
    }
    Reapproach { setup, lead }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::emit::modal::Plane;

    #[test]
    fn an_inverse_time_arc_is_restored_dark_then_armed_in_g1() {
        let state = ModalState {
            motion: MotionMode::ArcCw,
            plane: Plane::Xy,
            inverse_time: true,
            spindle: Spindle::Cw,
            feed: 12.5,
            s: 400.0,
            ..ModalState::default()
        };
        let r = grbl_reapproach(&state, &['X', 'Y', 'B'], &[10.0, -2.5, 90.1234567]);
        assert_eq!(
            r.setup,
            [
                "M5",
                "G21 G90 G94",
                "G0 X10 Y-2.5 B90.123457",
                "G21 G90 G93 G17",
                "M9"
            ]
        );
        assert_eq!(r.lead, ["M3 S400", "G1 F1"]);
        assert_eq!(
            with_motion_word(state.motion, "X1 Y2 I1 J0"),
            "G2 X1 Y2 I1 J0"
        );
    }

    #[test]
    fn a_rapid_state_in_inches_keeps_the_laser_power_and_adds_no_motion_line() {
        let state = ModalState {
            inches: true,
            s: 250.0,
            flood: true,
            mist: true,
            ..ModalState::default()
        };
        let r = grbl_reapproach(&state, &['X', 'Q'], &[1.0, 2.0]);
        assert_eq!(
            r.setup,
            ["M5", "G21 G90 G94", "G0 X1", "G20 G90 G94 G17", "M7 M8"]
        );
        assert_eq!(r.lead, ["S250"]);
    }
}
