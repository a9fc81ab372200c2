//! Which beam switches stop the machine: the one rule `motion` plans by and the GRBL-family
//! emitter writes by, so that a switch is planned as flying only where the NC lets the
//! controller fly through it.
//!
//! GRBL 1.1 (and grblHAL, which keeps its parser's rule) syncs every spindle state change:
//! `M3`, `M4` and `M5` empty the planner and stop the table first, even in laser mode (gcode.c,
//! "All spindle state changes are synced, even in laser mode"). An `S` word on a `G1`/`G2`/`G3`
//! block with axis words does not: in laser mode it is passed to the planner with the block and
//! changes power as that block starts. And a block whose motion mode is not G1/G2/G3 (a `G0`)
//! runs with the laser off whatever `M3`/`M4` and `S` say (gcode.c sets
//! `GC_PARSER_LASER_DISABLE`, so the block is planned at spindle speed 0; grblHAL's core
//! gcode.c decides the same with `motion_is_lasercut`). A standalone `S` line, by contrast,
//! syncs. So a post *flies* when its beam can be driven by S words alone:
//! the laser is armed once with `M3 S0`/`M4 S0` at rest, every feed move carries its power
//! (`S0` when unlit), and `M5` comes only at the end. Switching between `M3` (constant power)
//! and `M4` (power scaled with speed) is a spindle state change, so it re-arms at a planned
//! stop ([`arms`]). A post that cannot fly (its power line is not one S word, its laser-on line
//! not one `M3`/`M4` with an S word, or it says `laser_switch_stops`) switches with its own
//! lines at every lit section, and each of those switches is planned as a stop.

use crate::machine::DialectPost;
use crate::program::{Coupling, Op, OpKind};

/// Whether `key` names a post of the GRBL family (`[post.grbl]`, `[post.grblhal]`).
pub fn grbl_family_key(key: &str) -> bool {
    matches!(key, "grbl" | "grblhal")
}

/// Whether a GRBL-family post can switch the beam by S words on the feed moves (see the
/// module header): not `laser_switch_stops`, one `power` line that is one S word, one
/// `laser_on` line of an `M3`/`M4` and an S word.
pub fn flies(post: &DialectPost) -> bool {
    let s_word = |w: &str| w.len() > 1 && w.as_bytes()[0].eq_ignore_ascii_case(&b'S');
    let power_ok = matches!(post.power.as_slice(), [p] if {
        let words: Vec<&str> = p.split_whitespace().collect();
        matches!(words.as_slice(), [w] if s_word(w))
    });
    let on_ok = matches!(post.laser_on.as_slice(), [l] if {
        let words: Vec<&str> = l.split_whitespace().collect();
        words.len() == 2
            && words.iter().filter(|w| spindle_word(w).is_some()).count() == 1
            && words.iter().filter(|w| s_word(w)).count() == 1
    });
    !post.laser_switch_stops && power_ok && on_ok
}

/// `Some(true)` for `M4` (dynamic power), `Some(false)` for `M3`, else `None`.
fn spindle_word(w: &str) -> Option<bool> {
    match w.to_ascii_uppercase().as_str() {
        "M3" | "M03" => Some(false),
        "M4" | "M04" => Some(true),
        _ => None,
    }
}

/// Whether the post's own laser-on line is `M4` (power scaled with speed everywhere).
pub fn post_dynamic(post: &DialectPost) -> bool {
    post.laser_on
        .first()
        .is_some_and(|l| l.split_whitespace().any(|w| spindle_word(w) == Some(true)))
}

/// Where a flying post arms the laser: an `M3 S0` or `M4 S0` at rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Arm {
    /// The op the arm line is written before; `None`: in the header, before any op, where the
    /// machine is at rest (the first arm of a program).
    pub before: Option<usize>,
    /// `M4` (power scaled with speed) rather than `M3`.
    pub dynamic: bool,
}

/// The arms of a flying post over `ops`: one in the header for the first lit section, and one
/// more wherever a section needs the other mode (`M4` for a section whose power follows the
/// speed, under an `M3` post) or the laser was switched off in between (a dot-mode fire window
/// ends with the post's `laser_off`). A later arm goes before the motion op that leads into the
/// section (its lead-in), and `motion` plans a stop there, since `M3`/`M4` sync.
pub fn arms(ops: &[Op], post: &DialectPost) -> Vec<Arm> {
    let always_dynamic = post_dynamic(post);
    let mut out = Vec::new();
    let mut armed: Option<bool> = None;
    let mut disarmed = false;
    let mut lit_prev = false;
    let mut last_motion: Option<usize> = None;
    for (i, op) in ops.iter().enumerate() {
        match &op.kind {
            OpKind::Fire { .. } => {
                armed = None;
                disarmed = true;
            }
            OpKind::Rapid { .. } | OpKind::Line { .. } | OpKind::Arc { .. } => {
                let lit = op.laser();
                if let Some(l) = lit
                    && !lit_prev
                {
                    let dynamic = always_dynamic || l.couple == Coupling::Speed;
                    if armed != Some(dynamic) {
                        let before = if armed.is_none() && !disarmed {
                            None
                        } else {
                            Some(last_motion.unwrap_or(i))
                        };
                        out.push(Arm { before, dynamic });
                        armed = Some(dynamic);
                    }
                }
                lit_prev = lit.is_some();
                last_motion = Some(i);
            }
            _ => {}
        }
    }
    out
}

/// The switch stops of a whole program, for every post of its machine (one plan serves every
/// dialect, so it stops wherever any of them must).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SwitchStops {
    /// Every beam switch (on and off) needs the machine at rest.
    pub every_switch: bool,
    /// Ops before which a flying post re-arms (`M3`/`M4`), so the motion before them ends at rest.
    pub before_op: Vec<usize>,
}

/// See [`SwitchStops`].
pub fn switch_stops<'p>(
    ops: &[Op],
    posts: impl IntoIterator<Item = (&'p String, &'p DialectPost)>,
) -> SwitchStops {
    let mut s = SwitchStops::default();
    for (key, post) in posts {
        if post.laser_switch_stops || (grbl_family_key(key) && !flies(post)) {
            s.every_switch = true;
        } else if grbl_family_key(key) {
            s.before_op
                .extend(arms(ops, post).into_iter().filter_map(|a| a.before));
        }
    }
    s.before_op.sort_unstable();
    s.before_op.dedup();
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::program::Laser;
    use lase_lang::Span;

    fn post(on: &str, power: &[&str]) -> DialectPost {
        DialectPost {
            laser_on: vec![on.into()],
            laser_off: vec!["M5".into()],
            power: power.iter().map(|s| s.to_string()).collect(),
            s_max: 1000.0,
            laser_switch_stops: false,
            pulse_on: vec![],
            pulse_off: vec![],
            pso: vec![],
            budget: Default::default(),
            servo_period_s: None,
            spans: Default::default(),
        }
    }

    fn line(x: f64, couple: Option<Coupling>) -> Op {
        Op {
            kind: OpKind::Line {
                to: [x, 0.0, 0.0],
                feed_mm_s: 10.0,
                orient: None,
                laser: couple.map(|couple| {
                    std::sync::Arc::new(Laser {
                        power_w: 10.0,
                        spot_mm: 0.1,
                        pulse: None,
                        couple,
                        kerf_mm: 0.0,
                    })
                }),
                row: None,
            },
            span: Span::default(),
        }
    }

    #[test]
    fn stock_grbl_posts_fly_and_others_do_not() {
        assert!(flies(&post("M3 S{s}", &["S{s}"])));
        assert!(flies(&post("M4 S{pct}", &["S{pct}"])));
        assert!(!flies(&post("M3 S{s}", &["M3 S{s}"])));
        assert!(!flies(&post("M7", &["S{s}"])));
        let mut stops = post("M3 S{s}", &["S{s}"]);
        stops.laser_switch_stops = true;
        assert!(!flies(&stops));
    }

    #[test]
    fn an_m3_post_arms_once_at_the_start_and_again_before_a_coupled_section() {
        let c = Some(Coupling::default());
        let ops = vec![
            line(1.0, None),
            line(2.0, c),
            line(3.0, None),
            line(4.0, c),
            line(5.0, None),
            line(6.0, Some(Coupling::Speed)),
            line(7.0, None),
        ];
        let p = post("M3 S{s}", &["S{s}"]);
        assert_eq!(
            arms(&ops, &p),
            [
                Arm {
                    before: None,
                    dynamic: false
                },
                Arm {
                    before: Some(4),
                    dynamic: true
                }
            ]
        );
        let key = "grbl".to_string();
        assert_eq!(switch_stops(&ops, [(&key, &p)]).before_op, [4]);
        // An M4 post is dynamic everywhere: one arm.
        assert_eq!(arms(&ops, &post("M4 S{s}", &["S{s}"])).len(), 1);
    }
}
