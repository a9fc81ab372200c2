//! The cycle time of the controller that runs a job (issue 13). lase's own plan is ideal:
//! every axis within its v, a and j at every instant, corners blended within `corner`; it
//! places lead-ins, overscan and power coupling. The machine, though, runs the NC program
//! through its controller's own planner, which on jerk-bound jobs is far faster (texture_array:
//! lase 11.7 s, GRBL 5.9 s, LinuxCNC 6.3 s) and elsewhere slower. So `lase plan`, its JSON
//! summary, `lase run`'s ETA and the REPL report first the time of the controller the
//! program is written for, by the model of its firmware:
//! - `grbl`, `grblhal`: GRBL 1.1's or grblHAL's planner with the settings the machine file
//!   implies (`sim::motion`);
//! - `linuxcnc`: LinuxCNC 2.9's trajectory planner with the INI lase writes (`linuxcnc::tp`);
//! - `iso`, or a program the model cannot run: lase's own plan, saying why.
//!
//! Which controller: `--dialect`, else the machine file's `dialect`, else LinuxCNC (as `lase
//! emit` defaults); a live link names its own.

use crate::emit::Dialect;
use crate::motion::Job;
use crate::report::{ControllerCycle, round_sig};

/// What lase's own plan is called where it stands in for a controller.
pub const OWN_PLAN: &str = "lase's own plan";

/// The dialect a machine's programs are written in when no `--dialect` says otherwise: the
/// machine file's `dialect` (checked when the file was read), else LinuxCNC.
pub fn default_dialect(machine: &crate::machine::Machine) -> Dialect {
    machine
        .dialect
        .as_deref()
        .and_then(|d| d.parse().ok())
        .unwrap_or(Dialect::LinuxCnc)
}

/// The time of the controller that runs `job` written in `dialect`.
pub fn controller_cycle(job: &Job, dialect: Dialect) -> ControllerCycle {
    controller_cycle_from(job, None, dialect)
}

/// [`controller_cycle`] of a job planned whole (`facts` `None`) or in windows (`facts`
/// gathered from them for `dialect`, `emit::PlanFacts`). Either way the program goes from the
/// emitter to the model line by line and the model holds only its controller's queue
/// (`linuxcnc::tp::TpStream`, `sim::motion::ModelStream`; issue 18).
pub fn controller_cycle_from(
    job: &Job,
    facts: Option<&crate::emit::PlanFacts>,
    dialect: Dialect,
) -> ControllerCycle {
    let own = |note: String| ControllerCycle {
        dialect: dialect.name().into(),
        model: OWN_PLAN.into(),
        cycle_time_s: round_sig(job.cycle_time()),
        beam_on_s: None,
        detail: String::new(),
        note: Some(note),
    };
    let plural = |n: usize, what: &str| format!("{n} {what}{}", if n == 1 { "" } else { "s" });
    match dialect {
        Dialect::Grbl | Dialect::GrblHal => {
            match super::sim::motion::controller_time_from(job, facts, dialect) {
                Some(Ok(c)) => ControllerCycle {
                    dialect: dialect.name().into(),
                    model: c.model.into(),
                    cycle_time_s: round_sig(c.timeline.total_s),
                    beam_on_s: None,
                    detail: format!(
                        "{}, {}",
                        plural(c.timeline.blocks, "block"),
                        plural(c.timeline.syncs, "stop")
                    ),
                    note: None,
                },
                Some(Err(why)) => own(format!("the {dialect} model cannot run it: {why}")),
                None => own(format!("the machine has no {dialect} post")),
            }
        }
        Dialect::LinuxCnc => match super::linuxcnc::tp::controller_time_from(job, facts) {
            Some(Ok(t)) => ControllerCycle {
                dialect: dialect.name().into(),
                model: super::linuxcnc::tp::MODEL.into(),
                cycle_time_s: round_sig(t.total_s),
                beam_on_s: Some(round_sig(t.beam_on_s)),
                detail: format!(
                    "{}, {}",
                    plural(t.segments, "segment"),
                    plural(t.stops, "stop")
                ),
                note: None,
            },
            Some(Err(why)) => own(format!("the LinuxCNC model cannot run it: {why}")),
            None => own("the machine has no linuxcnc post".into()),
        },
        Dialect::Iso => own("no model of an ISO controller".into()),
    }
}

/// The other controllers a machine's programs could run on, for `lase plan`'s further lines:
/// the GRBL family it streams to (`link::live_dialect`) and LinuxCNC, where it has posts for
/// them, less `chosen`.
pub fn other_dialects(machine: &crate::machine::Machine, chosen: Dialect) -> Vec<Dialect> {
    [super::live_dialect(machine), Dialect::LinuxCnc]
        .into_iter()
        .filter(|&d| d != chosen && d.lookup(&machine.post).is_some())
        .collect()
}
