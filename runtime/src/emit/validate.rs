//! Checks a whole program against a dialect before a single line is written: M-codes, events,
//! axis letters, post templates, arc planes, (GRBL family) line lengths, and (LinuxCNC) that
//! no post line the plan switches on the fly stops the machine.

use super::format::{self, LaserWords};
use super::{Dialect, EmitError, EmitWarning, PlanFacts};
use crate::machine::{AxisKind, DialectPost, Machine};
use crate::motion::Job;
use crate::planner::Segment;
use crate::program::PulseMode;
use crate::program::{Coupling, Op, OpKind, ProcessProgram};
use lase_lang::Span;

/// GRBL's serial line buffer (`LINE_BUFFER_SIZE`): longer lines overflow it.
pub(super) const GRBL_MAX_LINE: usize = 80;

/// grblHAL's line buffer: `LINE_BUFFER_SIZE` is 257 in its `protocol.h`, "256 characters plus
/// terminator", and unlike GRBL 1.1 it keeps spaces and comments in the count.
const GRBLHAL_MAX_LINE: usize = 256;

/// The longest line a dialect's controller reads, without the newline; `None`: no limit lase
/// knows of.
fn max_line(dialect: Dialect) -> Option<usize> {
    match dialect {
        Dialect::Grbl => Some(GRBL_MAX_LINE),
        Dialect::GrblHal => Some(GRBLHAL_MAX_LINE),
        Dialect::LinuxCnc | Dialect::Iso => None,
    }
}

/// The controller's own spelling, for messages.
fn controller(dialect: Dialect) -> &'static str {
    match dialect {
        Dialect::LinuxCnc => "LinuxCNC",
        Dialect::Grbl => "GRBL",
        Dialect::GrblHal => "grblHAL",
        Dialect::Iso => "ISO",
    }
}

/// What validation learned that the writer needs.
#[derive(Debug)]
pub(super) struct Checked<'j> {
    pub post: &'j DialectPost,
    pub warnings: Vec<EmitWarning>,
}

/// Whether `dialect` accepts `M<code>` as written.
pub(super) fn mcode_supported(dialect: Dialect, code: u32) -> bool {
    match dialect {
        // rs274ngc's built-in M-codes plus user M100–M199.
        Dialect::LinuxCnc => matches!(code, 0..=9 | 30 | 48..=53 | 60..=68 | 70..=73 | 100..=199),
        // GRBL 1.1's M-codes; M56 (parking override) exists only in some builds. grblHAL
        // knows more (M56, M62–M68 with aux I/O) depending on its build; lase keeps to GRBL's.
        Dialect::Grbl | Dialect::GrblHal => matches!(code, 0..=5 | 7..=9 | 30),
        Dialect::Iso => true,
    }
}

fn mcode_list(dialect: Dialect) -> &'static str {
    match dialect {
        Dialect::LinuxCnc => "M0–M9, M30, M48–M53, M60–M68, M70–M73 and user M100–M199",
        Dialect::Grbl | Dialect::GrblHal => "M0, M1, M2, M3, M4, M5, M7, M8, M9 and M30",
        Dialect::Iso => "any M-code",
    }
}

/// Where an M word came from, for the diagnostic's label: an op, the post lines `what` of
/// `[post.<key>]`, or the `codes.<key>` of an event.
enum Origin<'a> {
    Op,
    Post { key: &'a str, what: &'a str },
    Event { name: &'a str, key: &'a str },
    Output { name: &'a str, key: &'a str },
}

fn check_mcode(
    dialect: Dialect,
    code: u32,
    span: Span,
    origin: Origin<'_>,
    machine: &str,
) -> Result<(), EmitError> {
    if mcode_supported(dialect, code) {
        return Ok(());
    }
    let (label, help) = match origin {
        Origin::Op => (
            format!("{dialect} has no M{code}"),
            format!(
                "{dialect} accepts {}; for a machine function use an `event` mapped by the \
                 machine file, e.g. `event swing_right` with `[events.swing_right]` \
                 `codes = {{ {dialect} = [\"M64 P1\"] }}`",
                mcode_list(dialect)
            ),
        ),
        Origin::Post { key, what } => (
            format!("the {what} lines of machine `{machine}` use M{code}"),
            format!(
                "{dialect} accepts {}; fix `[post.{key}] {what}` in the machine file",
                mcode_list(dialect)
            ),
        ),
        Origin::Event { name, key } => (
            format!("event `{name}` of machine `{machine}` uses M{code}"),
            format!(
                "{dialect} accepts {}; fix `[events.{name}] codes.{key}` in the machine file",
                mcode_list(dialect)
            ),
        ),
        Origin::Output { name, key } => (
            format!("output `{name}` of machine `{machine}` uses M{code}"),
            format!(
                "{dialect} accepts {}; fix `[outputs.{name}] {key}` in the machine file",
                mcode_list(dialect)
            ),
        ),
    };
    Err(EmitError::UnsupportedMCode {
        code,
        dialect,
        span,
        label,
        help,
    })
}

fn too_long(dialect: Dialect, line: &str, span: Span, what: &str) -> Result<(), EmitError> {
    match max_line(dialect) {
        Some(max) if line.len() > max => {
            let name = controller(dialect);
            Err(EmitError::Dialect {
                message: format!(
                    "{what} `{line}` is {} characters; {name} reads at most {max}",
                    line.len()
                ),
                dialect,
                span,
                label: format!("emits a line too long for {name}"),
                help: "shorten the line in the machine file (comments count)".into(),
            })
        }
        _ => Ok(()),
    }
}

pub(super) fn validate<'j>(
    job: &'j Job,
    dialect: Dialect,
    facts: Option<&PlanFacts>,
) -> Result<Checked<'j>, EmitError> {
    let program = &job.program;
    let machine = &program.machine;
    let ops = &program.ops;
    let first_span = ops.first().map(|o| o.span).unwrap_or_default();
    let (key, post) = dialect
        .lookup(&machine.post)
        .ok_or_else(|| EmitError::NoPost {
            machine: machine.name.clone(),
            dialect,
            span: first_span,
            help: format!(
                "the machine has posts for: {}; add a {} section (laser_on, laser_off, power) \
                 to its file",
                names(machine.post.keys()),
                alternatives(dialect, |k| format!("[post.{k}]"))
            ),
        })?;
    check_axes(machine, dialect, first_span)?;
    let mut warnings = Vec::new();

    if let Some(lit) = ops
        .iter()
        .find(|o| o.laser().is_some() || matches!(o.kind, OpKind::Fire { .. }))
    {
        check_post(post, key, machine, dialect, lit.span, PostLines::Laser)?;
    }
    if let Some(pulsed) = ops.iter().find(|o| {
        matches!(o.kind, OpKind::Fire { .. })
            || o.laser()
                .and_then(|l| l.pulse.as_ref())
                .is_some_and(|p| matches!(p.mode, crate::program::PulseMode::Distance { .. }))
    }) {
        check_post(post, key, machine, dialect, pulsed.span, PostLines::Pulse)?;
    }
    if let Some(coupled) = ops
        .iter()
        .find(|o| o.laser().is_some_and(|l| l.couple == Coupling::Speed))
    {
        check_coupling(post, key, machine, dialect, coupled.span)?;
    }
    if dialect == Dialect::LinuxCnc {
        check_flying_switches(job, key, post, facts)?;
    }
    for (i, op) in ops.iter().enumerate() {
        match &op.kind {
            OpKind::MCode { code, .. } => {
                check_mcode(dialect, *code, op.span, Origin::Op, &machine.name)?;
                if dialect == Dialect::LinuxCnc && (100..=199).contains(code) {
                    warnings.push(EmitWarning::UserMCode {
                        code: *code,
                        span: op.span,
                    });
                }
                if matches!(code, 2 | 30) && i + 1 < ops.len() {
                    warnings.push(EmitWarning::ProgramEnd {
                        code: *code,
                        span: op.span,
                    });
                }
            }
            OpKind::Event { name } => check_event(op, name, machine, dialect)?,
            OpKind::Output { name, .. } => check_output(op, name, machine, dialect)?,
            OpKind::Arc { .. } => check_arc_plane(machine, dialect, op.span)?,
            _ => {}
        }
    }
    Ok(Checked { post, warnings })
}

fn names<'a>(it: impl Iterator<Item = &'a String>) -> String {
    let v: Vec<&str> = it.map(String::as_str).collect();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// `[post.a]`-style mentions of every key `dialect` reads, joined with "or".
fn alternatives(dialect: Dialect, mention: impl Fn(&str) -> String) -> String {
    let v: Vec<String> = dialect.post_keys().iter().map(|k| mention(k)).collect();
    v.join(" or ")
}

/// The axes the GRBL family drives: GRBL 1.1 linear X, Y and Z; grblHAL also A, B and C, each
/// rotary or linear as the controller is configured. Other dialects take any letter.
fn check_axes(machine: &Machine, dialect: Dialect, span: Span) -> Result<(), EmitError> {
    let (drives, help, accepts): (&str, &str, fn(&str, AxisKind) -> bool) = match dialect {
        Dialect::Grbl => (
            "X, Y and Z only",
            "a grblHAL controller also drives A, B and C: emit or run with `--dialect grblhal`; or emit for linuxcnc or iso",
            |name, kind| kind == AxisKind::Linear && matches!(name, "X" | "Y" | "Z"),
        ),
        Dialect::GrblHal => (
            "linear X, Y and Z and A, B and C only",
            "emit for linuxcnc or iso, or name the machine's axes X, Y, Z (linear) and A, B, C",
            |name, kind| match name {
                "X" | "Y" | "Z" => kind == AxisKind::Linear,
                "A" | "B" | "C" => true,
                _ => false,
            },
        ),
        Dialect::LinuxCnc | Dialect::Iso => return Ok(()),
    };
    let Some(a) = machine.axes.iter().find(|a| !accepts(&a.name, a.kind)) else {
        return Ok(());
    };
    let name = controller(dialect);
    Err(EmitError::Dialect {
        message: format!(
            "{name} drives {drives}; machine `{}` has {} axis {}",
            machine.name,
            match a.kind {
                AxisKind::Rotary => "rotary",
                AxisKind::Linear => "linear",
            },
            a.name
        ),
        dialect,
        span,
        label: format!("this program cannot run on {name}"),
        help: help.into(),
    })
}

/// Which template lines of a post a program uses.
#[derive(Debug, Clone, Copy)]
enum PostLines {
    /// `laser_on`, `laser_off`, `power`: every lit program.
    Laser,
    /// `pulse_on`, `pulse_off`, `pso`: pulses by distance and dot mode (`writer::pulse`).
    Pulse,
}

fn check_post(
    post: &DialectPost,
    key: &str,
    machine: &Machine,
    dialect: Dialect,
    span: Span,
    which: PostLines,
) -> Result<(), EmitError> {
    let (lines, extra, fill): (_, _, fn(&str) -> String) = match which {
        PostLines::Laser => (
            [
                ("laser_on", &post.laser_on),
                ("laser_off", &post.laser_off),
                ("power", &post.power),
            ],
            " (W), {s} (power scaled to s_max) and {pct} (percent of max power)",
            str::to_string,
        ),
        PostLines::Pulse => (
            [
                ("pulse_on", &post.pulse_on),
                ("pulse_off", &post.pulse_off),
                ("pso", &post.pso),
            ],
            ", {s}, {pct}, and in pso {pitch} (mm) and {ppi} (pulses per inch)",
            |t| format::fill_pitch(t, 0.001),
        ),
    };
    let help = |what: &str| format!("templates in [post.{key}] {what} may use {{power}}{extra}");
    check_templates(post, key, machine, dialect, span, &lines, &fill, &help)
}

/// Each template of a post section: its placeholders, its M-codes in this dialect, and its
/// length at full power (the longest value a placeholder can take). `prepare` fills what is
/// known only per job (a pulse pitch) with a stand-in.
#[allow(clippy::too_many_arguments)]
fn check_templates(
    post: &DialectPost,
    key: &str,
    machine: &Machine,
    dialect: Dialect,
    span: Span,
    lines: &[(&'static str, &Vec<String>)],
    prepare: &dyn Fn(&str) -> String,
    help: &dyn Fn(&str) -> String,
) -> Result<(), EmitError> {
    let full = LaserWords {
        power_w: machine.laser.max_power_w,
        max_power_w: machine.laser.max_power_w,
        s_max: post.s_max,
    };
    for &(what, templates) in lines {
        for t in templates {
            let t = prepare(t);
            if let Some(message) = format::template_problem(&t) {
                return Err(EmitError::Template {
                    template: t.clone(),
                    machine: machine.name.clone(),
                    message,
                    span,
                    help: help(what),
                });
            }
            for code in format::m_words(&t) {
                let origin = Origin::Post { key, what };
                check_mcode(dialect, code, span, origin, &machine.name)?;
            }
            too_long(dialect, &format::fill(&t, full), span, what)?;
        }
    }
    Ok(())
}

/// Power that follows the speed needs a way to say so: the GRBL family's dynamic mode (an
/// `M3` in `laser_on` to turn into `M4`), elsewhere a `power` line per sub-block.
fn check_coupling(
    post: &DialectPost,
    key: &str,
    machine: &Machine,
    dialect: Dialect,
    span: Span,
) -> Result<(), EmitError> {
    let ok = if dialect.is_grbl_family() {
        post.laser_on
            .iter()
            .any(|t| format::m_words(t).iter().any(|&c| c == 3 || c == 4))
    } else {
        !post.power.is_empty()
    };
    if ok {
        return Ok(());
    }
    let (message, help) = if dialect.is_grbl_family() {
        (
            format!(
                "power coupled to speed needs {}'s M4, but [post.{key}] laser_on of machine `{}` \
                 has no M3",
                controller(dialect),
                machine.name
            ),
            format!(
                "switch the laser with `M3 S{{s}}` in [post.{key}] laser_on, or remove \
                 `couple speed`"
            ),
        )
    } else {
        (
            format!(
                "power coupled to speed needs a power line, but [post.{key}] power of \
                 machine `{}` is empty",
                machine.name
            ),
            format!(
                "add e.g. `power = [\"S{{s}}\"]` to [post.{key}] in the machine file, emit for \
                 another dialect, or remove `couple speed`"
            ),
        )
    };
    Err(EmitError::Dialect {
        message,
        dialect,
        span,
        label: "the power follows the speed here".into(),
        help,
    })
}

fn check_event(op: &Op, name: &str, machine: &Machine, dialect: Dialect) -> Result<(), EmitError> {
    let Some(ev) = machine.events.get(name) else {
        return Err(EmitError::UnsupportedEvent {
            name: name.to_string(),
            dialect,
            machine: machine.name.clone(),
            span: op.span,
            help: format!(
                "machine `{}` defines the events: {}",
                machine.name,
                names(machine.events.keys())
            ),
        });
    };
    let Some((key, codes)) = dialect.lookup(&ev.codes) else {
        return Err(EmitError::UnsupportedEvent {
            name: name.to_string(),
            dialect,
            machine: machine.name.clone(),
            span: op.span,
            help: format!(
                "event `{name}` has codes for: {}; emit for one of those, or add {} to \
                 `[events.{name}] codes` in the machine file",
                names(ev.codes.keys()),
                alternatives(dialect, |k| format!("`{k} = [...]`"))
            ),
        });
    };
    for line in codes {
        for code in format::m_words(line) {
            let origin = Origin::Event { name, key };
            check_mcode(dialect, code, op.span, origin, &machine.name)?;
        }
        too_long(dialect, line, op.span, &format!("event `{name}` line"))?;
    }
    Ok(())
}

/// An output has lines for the dialect, and every M-word in them is one the controller runs.
fn check_output(op: &Op, name: &str, machine: &Machine, dialect: Dialect) -> Result<(), EmitError> {
    let out = machine.outputs.get(name);
    let Some((key, lines)) = out.and_then(|o| dialect.lookup(&o.posts)) else {
        return Err(EmitError::UnsupportedOutput {
            name: name.to_string(),
            dialect,
            machine: machine.name.clone(),
            span: op.span,
            help: format!(
                "output `{name}` has lines for: {}; emit for one of those, or add {} to \
                 `[outputs.{name}]` in the machine file",
                names(out.into_iter().flat_map(|o| o.posts.keys())),
                alternatives(dialect, |k| format!(
                    "`{k} = {{ on = [...], off = [...] }}`"
                ))
            ),
        });
    };
    for line in lines.on.iter().chain(&lines.off) {
        for code in format::m_words(line) {
            let origin = Origin::Output { name, key };
            check_mcode(dialect, code, op.span, origin, &machine.name)?;
        }
        too_long(dialect, line, op.span, &format!("output `{name}` line"))?;
    }
    Ok(())
}

/// Axis indices (X, Y, optional Z) of the G17 plane. G2/G3 take I and J by letter, so arcs
/// need an axis named X moving part x and one named Y moving part y.
pub(super) fn arc_axes(machine: &Machine) -> Option<(usize, usize, Option<usize>)> {
    let find = |letter: &str, part: &str| {
        machine
            .axes
            .iter()
            .position(|a| a.name == letter && a.part_axis.as_deref() == Some(part))
    };
    Some((find("X", "x")?, find("Y", "y")?, find("Z", "z")))
}

fn check_arc_plane(machine: &Machine, dialect: Dialect, span: Span) -> Result<(), EmitError> {
    if arc_axes(machine).is_some() {
        return Ok(());
    }
    Err(EmitError::Dialect {
        message: format!(
            "machine `{}` has no X and Y axes along part x and y, so G2/G3 cannot describe \
             this arc",
            machine.name
        ),
        dialect,
        span,
        label: "arc".into(),
        help: "use a machine with X and Y axes, or write the path as straight moves".into(),
    })
}

/// LinuxCNC's immediate output words: `M64`/`M65` (digital) and `M68` (analog) wait for the
/// motion queue to drain, so the machine stops before the output changes; `M62`/`M63` and
/// `M67` change it at the start of the next move without breaking blending (CONTROLLERS.md).
/// The synchronized word for each.
fn synchronized_word(code: u32) -> Option<u32> {
    match code {
        64 => Some(62),
        65 => Some(63),
        68 => Some(67),
        _ => None,
    }
}

/// `(op, speed where its first segment starts, speed where its last ends)` of every op with
/// segments in `segs` (a plan's, in op order).
pub(super) fn op_speeds(segs: &[Segment]) -> impl Iterator<Item = (usize, f64, f64)> + '_ {
    segs.chunk_by(|a, b| a.tag == b.tag)
        .map(|c| (c[0].tag as usize, c[0].v_entry, c[c.len() - 1].v_exit))
}

/// Whether a post line the plan may switch on the fly holds an immediate output word
/// (`check_flying_switches`): only then do the planned speeds matter to validation.
pub(super) fn has_immediate_words(post: &DialectPost) -> bool {
    [
        &post.laser_on,
        &post.laser_off,
        &post.power,
        &post.pulse_on,
        &post.pulse_off,
    ]
    .iter()
    .any(|lines| {
        lines.iter().any(|t| {
            format::m_words(t)
                .into_iter()
                .any(|c| synchronized_word(c).is_some())
        })
    })
}

/// Every post line LinuxCNC runs where the plan keeps moving (a flying beam switch of style b,
/// a power change inside a lit section, a pulse edge by distance) must keep motion
/// synchronized: with an immediate word the machine would stop there, switch at rest, and the
/// lit section would start or end at the wrong speed. Where the plan itself stops (a machine
/// whose switch needs rest, a dwell, an M-code) immediate words are fine.
fn check_flying_switches(
    job: &Job,
    key: &str,
    post: &DialectPost,
    facts: Option<&PlanFacts>,
) -> Result<(), EmitError> {
    if !has_immediate_words(post) {
        // Nothing here could stop the machine: no speeds needed (`PlanFacts` gathers none).
        return Ok(());
    }
    let ops = &job.program.ops;
    let spans = &post.spans;
    let lines = |what: &'static str| -> (&[String], &[Span]) {
        match what {
            "laser_on" => (&post.laser_on, &spans.laser_on),
            "laser_off" => (&post.laser_off, &spans.laser_off),
            "power" => (&post.power, &spans.power),
            "pulse_on" => (&post.pulse_on, &spans.pulse_on),
            _ => (&post.pulse_off, &spans.pulse_off),
        }
    };
    let check = |what: &'static str, speed: f64, op: &Op| -> Result<(), EmitError> {
        if speed <= 1e-9 {
            return Ok(());
        }
        let (texts, line_spans) = lines(what);
        for (k, t) in texts.iter().enumerate() {
            let Some((code, sync)) = format::m_words(t)
                .into_iter()
                .find_map(|c| synchronized_word(c).map(|s| (c, s)))
            else {
                continue;
            };
            return Err(EmitError::ImmediateOutput {
                message: format!(
                    "`{t}` in [post.{key}] {what} of machine `{}` switches an output \
                     immediately (M{code}), where lase plans the switch on the fly at {} mm/s",
                    job.program.machine.name,
                    lase_lang::units::format_number(speed)
                ),
                code,
                span: line_spans.get(k).copied().unwrap_or(op.span),
                help: format!(
                    "write M{sync} for M{code} in [post.{key}] {what} of the machine file: \
                     LinuxCNC's M62/M63 (digital) and M67 (analog) take effect at the start of \
                     the next move without stopping; or set `laser_switch_stops = true` there \
                     if the beam must switch at rest (lase then plans stops)"
                ),
            });
        }
        Ok(())
    };
    let mut on = false;
    let mut power_w = 0.0;
    // The planned speeds where each op starts and ends are read off the plan in one walk with
    // the ops (its segments are in op order, tagged with their op): a table of them was 24
    // bytes an op, the most emitting a long job held (issue 18). A lit op's section ends unless
    // the next op that plans motion is lit too, so its `laser_off` is checked on reaching that
    // op (or the end), before anything of it: the checks run in op order, as ever.
    // A plan made in windows left its speeds in `facts`; a whole plan is walked.
    let speeds: Box<dyn Iterator<Item = (usize, f64, f64)> + '_> = match facts {
        Some(f) => Box::new(f.op_speeds()),
        None => Box::new(op_speeds(job.plan.segments())),
    };
    let mut lit_before: Option<(&Op, f64)> = None;
    for (i, v0, v1) in speeds {
        let op = &ops[i];
        if op.target().is_none() {
            continue;
        }
        if let Some((before, v_out)) = lit_before.take()
            && op.laser().is_none()
        {
            check("laser_off", v_out, before)?;
            on = false;
        }
        let Some(laser) = op.laser() else { continue };
        if !on {
            check("laser_on", v0, op)?;
            on = true;
        } else if laser.couple != Coupling::Speed
            && (laser.power_w - power_w).abs() > 1e-9 * laser.power_w.abs().max(1.0)
        {
            // (Coupled power steps are written with M67 by the writer itself.)
            check("power", v0, op)?;
        }
        power_w = laser.power_w;
        if laser
            .pulse
            .as_ref()
            .is_some_and(|p| matches!(p.mode, PulseMode::Distance { .. }))
        {
            check("pulse_on", v0, op)?;
            check("pulse_off", v0, op)?;
        }
        lit_before = Some((op, v1));
    }
    if let Some((last, v_out)) = lit_before {
        check("laser_off", v_out, last)?;
    }
    Ok(())
}

/// Row-start settling (`scan … { settle }`) reads the machine's position and loops until it
/// is within the window. An NC program does that only where the machine file says how
/// (`[settle]`: LinuxCNC's scale inputs, an ISO control's macro; `emit::writer::settle`), on
/// a table whose X and Y are the part's x and y; anywhere else, writing one that fires without
/// settling would pass off an open loop as the closed one the recipe asked for.
pub(super) fn check_settles(
    program: &crate::program::ProcessProgram,
    dialect: Dialect,
) -> Result<(), EmitError> {
    let Some(s) = program.settles.first() else {
        return Ok(());
    };
    let machine = &program.machine;
    let cartesian = machine.kinematics == crate::machine::KinematicsKind::Cartesian
        && machine.axis_index("X").is_some()
        && machine.axis_index("Y").is_some();
    let known = match dialect {
        Dialect::LinuxCnc => machine.settle.linuxcnc_inputs.is_some(),
        Dialect::Iso => machine.settle.iso_call.is_some(),
        Dialect::Grbl | Dialect::GrblHal => false,
    };
    if known && cartesian {
        return Ok(());
    }
    let name = &machine.name;
    let (message, help) = match dialect {
        Dialect::Grbl | Dialect::GrblHal => (
            format!(
                "{dialect} cannot settle a row start in an NC program: it can neither loop nor read its position"
            ),
            "stream it with `lase run`, which reads the position between rows and settles \
             each row start; or leave `settle` out to write the open-loop program"
                .to_string(),
        ),
        _ if !cartesian => (
            format!(
                "row-start settling needs a table whose X and Y are the part's x and y; `{name}` is not one"
            ),
            "leave `settle` out on this machine".to_string(),
        ),
        Dialect::LinuxCnc => (
            format!(
                "machine `{name}` does not say where LinuxCNC reads its scales, so lase cannot write the settling loop"
            ),
            "name the HAL analog inputs of the X and Y scales in the machine file: \
             `[settle] linuxcnc = { x_input = 0, y_input = 1 }`; or leave `settle` out"
                .to_string(),
        ),
        Dialect::Iso => (
            format!("machine `{name}` names no settling macro for ISO controls"),
            "name the call in the machine file, e.g. `[settle] iso = { call = \"G65 P9100 X{x} Y{y} …\" }` \
             (stdlib/machines/README.md); or leave `settle` out"
                .to_string(),
        ),
    };
    Err(EmitError::Dialect {
        message,
        dialect,
        span: s.span,
        label: "row-start settling asked here".into(),
        help,
    })
}

/// Holds the job's pulses to the controller's pulse budget (`PulseBudget` of the post): no two
/// planned pulses closer in time than `1 / max_pulse_rate` (the rate the controller has to
/// trigger, ramps and dot-mode windows included), and at most `max_pulses` in the job. The
/// diagnostic points at the recipe statement of the first pulse over the budget.
pub(super) fn check_pulse_budget(
    job: &Job,
    dialect: Dialect,
    post: &DialectPost,
) -> Result<(), EmitError> {
    let Some(mut check) = BudgetCheck::new(post) else {
        return Ok(());
    };
    for p in crate::report::pulse_events(job) {
        if !check.pulse(p.t, p.op) {
            break;
        }
    }
    check.result(&job.program, dialect)
}

/// The pulse budget of one post, checked pulse by pulse in time order as they come, whole
/// ([`check_pulse_budget`]) or from a plan made in windows (`PlanFacts`, with
/// `report::PulseStream`): the running count and the last pulse's time, and the first pulse
/// over the budget, which [`result`](Self::result) turns into the diagnostic.
#[derive(Debug, Clone)]
pub(super) struct BudgetCheck {
    max_pulses: Option<u64>,
    max_rate_hz: Option<f64>,
    count: u64,
    last_t: Option<f64>,
    over: Option<Over>,
}

/// The first pulse over a budget: its op and number, and, when it came too soon, the time
/// since the one before.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Over {
    pub op: u32,
    pub count: u64,
    pub dt: Option<f64>,
}

impl BudgetCheck {
    /// The check of `post`'s budget; `None` when it has none.
    pub(super) fn new(post: &DialectPost) -> Option<BudgetCheck> {
        let budget = &post.budget;
        if budget.max_rate_hz.is_none() && budget.max_pulses.is_none() {
            return None;
        }
        Some(BudgetCheck {
            max_pulses: budget.max_pulses,
            max_rate_hz: budget.max_rate_hz,
            count: 0,
            last_t: None,
            over: None,
        })
    }

    /// The next pulse, at job time `t`, fired by op `op`. False once a pulse went over the
    /// budget: the later ones change nothing.
    pub(super) fn pulse(&mut self, t: f64, op: u32) -> bool {
        if self.over.is_some() {
            return false;
        }
        self.count += 1;
        let count = self.count;
        if self.max_pulses.is_some_and(|m| count > m) {
            self.over = Some(Over {
                op,
                count,
                dt: None,
            });
            return false;
        }
        if let (Some(max), Some(t0)) = (self.max_rate_hz, self.last_t) {
            let dt = t - t0;
            // A relative margin: a rate computed to equal the limit passes.
            if dt < (1.0 / max) * (1.0 - 1e-9) {
                self.over = Some(Over {
                    op,
                    count,
                    dt: Some(dt),
                });
                return false;
            }
        }
        self.last_t = Some(t);
        true
    }

    /// The first pulse over the budget so far.
    pub(super) fn over(&self) -> Option<Over> {
        self.over
    }

    /// The diagnostic of the first pulse over the budget of `program`'s post for `dialect`.
    pub(super) fn result(
        &self,
        program: &ProcessProgram,
        dialect: Dialect,
    ) -> Result<(), EmitError> {
        use lase_lang::units::{Dim, format_quantity};
        let Some(over) = self.over else {
            return Ok(());
        };
        let op = &program.ops[over.op as usize];
        let count = over.count;
        let name = &program.machine.name;
        let key = dialect
            .lookup(&program.machine.post)
            .map_or("…", |(k, _)| k);
        let Some(dt) = over.dt else {
            let max = self.max_pulses.unwrap_or_default();
            return Err(EmitError::PulseBudget {
                message: format!(
                    "the job fires more than {max} pulses, the most {} takes in one job",
                    controller(dialect)
                ),
                span: op.span,
                label: format!("pulse {count} is fired here"),
                help: format!(
                    "split the job (fewer passes or a smaller array per job); `max_pulses` of \
                     [post.{key}] in machine `{name}` sets the limit"
                ),
            });
        };
        let max = self.max_rate_hz.unwrap_or_default();
        let slower = match op.laser().and_then(|l| l.pulse.as_ref()).map(|p| p.mode) {
            Some(PulseMode::Distance { pitch_mm }) => format!(
                "with pulses every {} the fastest speed {} triggers is {}",
                format_quantity(pitch_mm, Dim::LENGTH),
                controller(dialect),
                format_quantity(max * pitch_mm, Dim::SPEED)
            ),
            _ => format!(
                "space the pulses at least {} apart (a lower pulse `rate`)",
                format_quantity(1.0 / max, Dim::TIME)
            ),
        };
        Err(EmitError::PulseBudget {
            message: format!(
                "pulses at {} are faster than {} triggers them ({} at most)",
                format_quantity(1.0 / dt.max(1e-12), Dim::FREQUENCY),
                controller(dialect),
                format_quantity(max, Dim::FREQUENCY)
            ),
            span: op.span,
            label: format!("pulse {count} follows the one before it too soon"),
            help: format!(
                "{slower}; `max_pulse_rate` of [post.{key}] in machine `{name}` sets the limit"
            ),
        })
    }
}
