//! Row-start settling in an NC program (issue 15, PROCESS.md §3): the control itself reads
//! the table's scales after a row's approach and steps toward the window, as `link::settle`
//! does over a live link.
//!
//! * LinuxCNC: one subroutine, `o<lase_settle>`, written in the header and called after each
//!   row's approach. It takes up the play in the row's direction, then reads the scales from
//!   the HAL analog inputs the machine file names (`M66 E<n> L0`: a queue buster, so the
//!   reading is taken at rest), and while the error is outside the window steps `settle_step`
//!   toward it (`G91 G1`; a step back along the row overshoots by the preload and comes
//!   forward again, so the play stays taken up the way the row runs). After `settle_steps`
//!   steps it ends the program with `(abort, …)`, whose message LinuxCNC shows. `M73` restores
//!   the caller's modal state (G90, feed) at its return; the motion mode it does not restore,
//!   so the writer names it again after a call.
//! * ISO: the machine file's call of the control's own macro, filled with the row start, its
//!   direction and the window.
//!
//! Either way the row after the call is written relative to its settled start
//! (`emit::relative`).

use super::super::format;
use crate::emit::Dialect;
use crate::machine::Machine;
use crate::program::Settle;

/// Feed of a corrective step, mm/min: slow, a step is a fraction of a micrometre (as
/// `link::settle`'s jogs).
const STEP_FEED_MM_MIN: f64 = 60.0;

/// The preload, mm: the play is taken up by backing off this much against the row's
/// direction and coming forward (as `link::settle::PRELOAD_MM`).
const PRELOAD_MM: f64 = 0.005;

/// Slack on the window's edges, mm: a scale reading on the edge is within it.
const EDGE_MM: f64 = 1e-6;

/// LinuxCNC's settling subroutine, reading X on analog input `inputs[0]` and Y on
/// `inputs[1]`, as header lines.
pub(super) fn linuxcnc_sub(inputs: [u32; 2]) -> Vec<String> {
    let [ex, ey] = inputs;
    let p = format::number(PRELOAD_MM);
    let f = format::number(STEP_FEED_MM_MIN);
    let e = format::number(EDGE_MM);
    [
        "o<lase_settle> sub".to_string(),
        "(#1 #2 row start X Y, #3 #4 row direction, #5 #6 window along, #7 across)".into(),
        "(#8 step, #9 most steps, #10 #11 pass and row; lase, issue 15)".into(),
        "M73".into(),
        format!("G91 G1 X[-{p} * #3] Y[-{p} * #4] F{f}"),
        format!("X[{p} * #3] Y[{p} * #4]"),
        "#<n> = 0".into(),
        "o<lase_settle_loop> do".into(),
        format!("M66 E{ex} L0"),
        "#<dx> = [#5399 - #1]".into(),
        format!("M66 E{ey} L0"),
        "#<dy> = [#5399 - #2]".into(),
        "#<along> = [#<dx> * #3 + #<dy> * #4]".into(),
        "#<across> = [#<dy> * #3 - #<dx> * #4]".into(),
        "#<a> = 0".into(),
        "#<c> = 0".into(),
        format!("o<lase_settle_a> if [#<along> LT [#5 - {e}]]"),
        "#<a> = #8".into(),
        format!("o<lase_settle_a> elseif [#<along> GT [#6 + {e}]]"),
        "#<a> = [0 - #8]".into(),
        "o<lase_settle_a> endif".into(),
        format!("o<lase_settle_c> if [#<across> LT [0 - #7 - {e}]]"),
        "#<c> = #8".into(),
        format!("o<lase_settle_c> elseif [#<across> GT [#7 + {e}]]"),
        "#<c> = [0 - #8]".into(),
        "o<lase_settle_c> endif".into(),
        "o<lase_settle_step> if [[#<a> NE 0] OR [#<c> NE 0]]".into(),
        "o<lase_settle_give_up> if [#<n> GE #9]".into(),
        "(abort, lase: row #11 of pass #10 did not settle in #9 steps: #<along> mm along, #<across> mm across)"
            .into(),
        "o<lase_settle_give_up> endif".into(),
        "o<lase_settle_back> if [#<a> LT 0]".into(),
        format!("X[[#<a> - {p}] * #3 - #<c> * #4] Y[[#<a> - {p}] * #4 + #<c> * #3]"),
        format!("X[{p} * #3] Y[{p} * #4]"),
        "o<lase_settle_back> else".into(),
        "X[#<a> * #3 - #<c> * #4] Y[#<a> * #4 + #<c> * #3]".into(),
        "o<lase_settle_back> endif".into(),
        "#<n> = [#<n> + 1]".into(),
        "o<lase_settle_step> endif".into(),
        "o<lase_settle_loop> while [[#<a> NE 0] OR [#<c> NE 0]]".into(),
        "o<lase_settle> endsub".into(),
    ]
    .into()
}

/// The block that settles row start `s` at controller X, Y `target`, mm.
pub(super) fn call(dialect: Dialect, machine: &Machine, s: &Settle, target: [f64; 2]) -> String {
    let n = format::number;
    let [ux, uy] = s.dir;
    match dialect {
        Dialect::Iso => {
            let template = machine.settle.iso_call.as_deref().unwrap_or_default();
            let mut out = template.to_string();
            for (k, v) in [
                ("x", n(target[0])),
                ("y", n(target[1])),
                ("ux", n(ux)),
                ("uy", n(uy)),
                ("low", n(s.window_mm.0)),
                ("high", n(s.window_mm.1)),
                ("across", n(s.across_mm)),
                ("step", n(s.step_mm)),
                ("steps", s.max_steps.to_string()),
            ] {
                out = out.replace(&format!("{{{k}}}"), &v);
            }
            out
        }
        _ => format!(
            "o<lase_settle> call [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}] [{}]",
            n(target[0]),
            n(target[1]),
            n(ux),
            n(uy),
            n(s.window_mm.0),
            n(s.window_mm.1),
            n(s.across_mm),
            n(s.step_mm),
            s.max_steps,
            s.pass + 1,
            s.row + 1
        ),
    }
}
