//! The `lase` command: check, emit, plan, plot and run laser-process recipes, and the REPL.
//!
//! Only this binary touches the terminal, the file system for outputs, rustyline and miette's
//! graphical renderer.

mod doc;
mod driver;
mod live;
mod origin;
mod output;
mod repl;

use clap::{Parser, Subcommand};
use driver::{Failure, IoError};
use lase_lang::SourceMap;
use lase_runtime::emit::{Dialect, EmitOptions, NcLine};
use output::{out, outln};
use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Debug, Parser)]
#[command(
    name = "lase",
    version,
    about = "A recipe language for laser processing machines"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Check a recipe: syntax, names, units, machine limits, reachability, and what `lase emit`
    /// refuses for the controller that runs it (post words, pulse budget). Exit 1 on errors.
    Check {
        file: PathBuf,
        /// The controller's NC dialect: linuxcnc, grbl, grblhal or iso (default: the machine
        /// file's `dialect`, else linuxcnc); the recipe is planned and checked for it.
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Write the NC program of a recipe (stdout unless -o).
    Emit {
        file: PathBuf,
        /// Write the NC program to this file (atomically) instead of stdout.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// NC dialect: linuxcnc, grbl (GRBL 1.1: X, Y, Z), grblhal (up to six axes) or iso
        /// (default: the machine file's `dialect`, else linuxcnc); the recipe is planned for
        /// it.
        #[arg(long)]
        dialect: Option<String>,
        /// Where the recipe's zero is: absolute (machine coordinates) or current (the
        /// program is written in a work frame the operator sets by jogging to the job's zero:
        /// its header sets G54 there with G10 L20 P1); default: the recipe's
        /// `planner { origin ... }`, else absolute. g54 … g59: the controller's work offset,
        /// selected by the program and never written (see --work-offset, --set-origin).
        #[arg(long, value_enum)]
        origin: Option<origin::JobOrigin>,
        /// With --origin g54 … g59: the offset as set on the controller, e.g. "X100 Y50" (mm,
        /// deg for rotary axes), so the travel is checked at machine positions; default: the
        /// machine file's `[work_offsets]`.
        #[arg(long, value_name = "WORDS")]
        work_offset: Option<String>,
        /// With --origin g54 … g59: set that offset where the spot stands (`G10 L20 P2` for
        /// G55) before the job, as --origin current does for G54.
        #[arg(long)]
        set_origin: bool,
    },
    /// Plan the motion: cycle time, peaks and where the time goes; optionally a JSON summary
    /// (`-o`), a CSV trace (`--trace`) and every pulse (`--pulses`).
    Plan {
        file: PathBuf,
        /// Write the job summary as JSON to this file (`--summary` is an old spelling).
        // `-o` is every command's output file, as in `emit` and `plot`; `--summary` stays as a
        // hidden alias so existing scripts keep working.
        #[arg(short, long, alias = "summary")]
        output: Option<PathBuf>,
        /// Write a sampled trace as CSV.
        #[arg(long)]
        trace: Option<PathBuf>,
        /// Write every laser pulse as CSV: time, spot position, speed, op.
        #[arg(long)]
        pulses: Option<PathBuf>,
        /// Trace sampling period, with a unit (e.g. 1ms, 500us).
        #[arg(long, default_value = "1ms")]
        period: String,
        /// The controller that runs the program, by its NC dialect (linuxcnc, grbl, grblhal,
        /// iso): its planner's model gives the first cycle time (default: the machine file's
        /// `dialect`, else linuxcnc).
        #[arg(long)]
        dialect: Option<String>,
    },
    /// Draw the toolpath (laser state, speed, every pulse) and the speed, limits, power and
    /// events over time, as SVG or PNG.
    Plot {
        file: PathBuf,
        /// Output file: `.png` writes a PNG (2 px per SVG unit), anything else SVG (default:
        /// the recipe's name with `.svg`).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Fit the toolpath view to all motion (approach, travel, overscan), not the lit work.
        #[arg(long)]
        full: bool,
        /// Speed unit of the plot: mm/s or mm/min (default: the one the recipe's feeds use).
        #[arg(long)]
        speed_unit: Option<String>,
    },
    /// Check, plan and stream the job to a controller (the built-in simulator by default).
    ///
    /// Links: `sim` (in-process simulated GRBL/grblHAL controller, the default; options as a query:
    /// `sim://?time-scale=real&baud=115200`), `tcp://HOST:PORT`, `serial:///dev/ttyUSB0?baud=115200`,
    /// `linuxcnc://HOST:5007` (LinuxCNC 2.9 over linuxcncrsh: the program is written to a folder
    /// the controller reads, `?dir=LOCAL&remote-dir=ON-CONTROLLER`, and run there in AUTO mode;
    /// `&timeout=SECONDS`, default 30, bounds every wait on LinuxCNC).
    /// Over tcp and serial a journal records every line sent and acknowledged (default: in the
    /// user's state directory, `$XDG_STATE_HOME/lase/journals/` or
    /// `~/.local/state/lase/journals/`, one file per recipe path; the run prints where); after
    /// a dropped link, `lase run FILE --resume` (or `--resume JOURNAL`) continues the job.
    Run(live::RunArgs),
    /// Trace the bounding box of a recipe's lit work with the beam off over the link (the
    /// built-in simulator by default) and return to the job's start: where will it burn?
    Frame(live::FrameArgs),
    /// Run the simulated controller as a TCP server: GRBL 1.1, or grblHAL with up to six axes
    /// for a machine with axes beyond X, Y, Z.
    Sim(live::SimArgs),
    /// Print the reference of a statement, function, profile, unit or standard library topic
    /// (`lase doc` lists the topics; `lase doc --markdown` prints docs/reference.md).
    Doc {
        /// A topic: `follow`, `offset`, `units`, `extensions`, `stdlib::cams`, `presets`, ...
        name: Option<String>,
        /// The whole reference as Markdown.
        #[arg(long)]
        markdown: bool,
    },
    /// Interactive session at the machine: statements evaluated as you type, `:run` streams
    /// them (`:help` lists the commands). Input piped in runs without prompts or colours.
    Repl {
        /// A recipe to load first.
        file: Option<PathBuf>,
        /// Controller link URL (default: the simulator in-process): sim, tcp://HOST:PORT,
        /// serial:///dev/ttyUSB0?baud=115200.
        #[arg(long)]
        link: Option<String>,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let color = std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none();
    let result = match cli.command {
        Command::Check { file, dialect } => cmd_check(&file, dialect.as_deref()),
        Command::Emit {
            file,
            output,
            dialect,
            origin,
            work_offset,
            set_origin,
        } => cmd_emit(
            &file,
            output.as_deref(),
            dialect.as_deref(),
            origin,
            (work_offset.as_deref(), set_origin),
        ),
        Command::Plan {
            file,
            output: summary,
            trace,
            pulses,
            period,
            dialect,
        } => cmd_plan(
            &file,
            summary.as_deref(),
            trace.as_deref(),
            pulses.as_deref(),
            (&period, dialect.as_deref()),
        ),
        Command::Plot {
            file,
            output,
            full,
            speed_unit,
        } => cmd_plot(&file, output.as_deref(), full, speed_unit.as_deref()),
        Command::Run(args) => live::cmd_run(args),
        Command::Frame(args) => live::cmd_frame(args),
        Command::Sim(args) => live::cmd_sim(args),
        Command::Repl { file, link } => return repl::run(file.as_deref(), link.as_deref(), color),
        Command::Doc { name, markdown } => return cmd_doc(name.as_deref(), markdown),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err((map, failure)) => {
            eprint!("{}", driver::render(&map, &failure, color));
            ExitCode::FAILURE
        }
    }
}

type CmdResult = Result<(), (SourceMap, Failure)>;

fn io_fail(message: String) -> (SourceMap, Failure) {
    (SourceMap::new(), Failure::one(IoError { message }))
}

fn cmd_check(file: &Path, dialect: Option<&str>) -> CmdResult {
    let dialect = dialect.map(parse_dialect).transpose()?;
    let (recipe, job, warnings) = driver::check(file, |m| {
        dialect.unwrap_or_else(|| lase_runtime::link::estimate::default_dialect(m))
    })?;
    for warn in &warnings {
        eprintln!("warning: {warn}");
    }
    outln!("{}", driver::ok_line(&recipe, &job));
    Ok(())
}

fn parse_dialect(d: &str) -> Result<Dialect, (SourceMap, Failure)> {
    d.parse::<Dialect>().map_err(|_| {
        io_fail(format!(
            "unknown dialect `{d}`: choose linuxcnc, grbl, grblhal or iso"
        ))
    })
}

fn cmd_emit(
    file: &Path,
    output: Option<&Path>,
    dialect: Option<&str>,
    origin: Option<origin::JobOrigin>,
    (work_offset, set_origin): (Option<&str>, bool),
) -> CmdResult {
    // A bad --dialect is refused before the recipe is compiled; without one, the machine's.
    let given_dialect = dialect.map(parse_dialect).transpose()?;
    // No spinner over NC text printed on the terminal itself.
    let busy = if output.is_none() && std::io::stdout().is_terminal() {
        output::Busy::off()
    } else {
        output::Busy::start(&format!("compiling {}", file.display()))
    };
    let (recipe, mut program) = driver::program(file)?;
    let dialect = given_dialect
        .unwrap_or_else(|| lase_runtime::link::estimate::default_dialect(&program.machine));
    program.machine.run_on(dialect.name());
    let chosen = origin::chosen(origin, &program);
    program.planner.origin = chosen.into();
    if set_origin && chosen.work().is_none() {
        let e = origin::OriginError::SetOrigin(format!("{chosen:?}").to_lowercase());
        return Err((recipe.map, Failure::one(e)));
    }
    let given = match work_offset.map(|t| origin::parse_offset(t, &program.machine)) {
        Some(Err(e)) => return Err(io_fail(format!("--work-offset: {e}"))),
        Some(Ok(v)) => Some(v),
        None => None,
    };
    let mut windowed = None;
    let planned = match (chosen, chosen.work()) {
        (_, Some(g)) => origin::named(program, dialect, g, given, set_origin).map(|(job, s, w)| {
            if let Some(w) = w {
                eprintln!("warning: {w}");
            }
            (job, s)
        }),
        (origin::JobOrigin::Current, _) => origin::work_frame(program, dialect),
        _ => {
            // Planned in windows that are read and dropped (issue 18): the job never holds
            // its plan, only what the writer reads of it (`emit::PlanFacts`, which checks the
            // post's pulse budget too).
            let mut facts = lase_runtime::emit::PlanFacts::new(&program, dialect);
            lase_runtime::compile::plan_in_windows(program, |p, w| facts.window(p, &w)).map(
                |(job, _)| {
                    facts.finish(&job.program);
                    windowed = Some(facts);
                    (job, Vec::new())
                },
            )
        }
    };
    let (job, setup) = match planned {
        Ok(p) => p,
        Err(f) => return Err((recipe.map, f)),
    };
    let locate = |s: lase_lang::Span| recipe.locate(s);
    let options = emit_options(&locate);
    let mut written = (0u64, 0u64);
    let mut write = |w: &mut dyn Write| -> Result<(), (SourceMap, Failure)> {
        let mut io_err = None;
        busy.say(format!("writing {dialect} NC"));
        let mut lines = 0u64;
        let mut setup = setup.iter();
        // The work frame's lines are ours, not the emitter's: counted here for the result line.
        let mut extra = (0u64, 0u64);
        // Lines are gathered into one large buffer of bytes and written a batch at a time:
        // a texturing program is millions of short lines, and a write call (through `dyn
        // Write`) for each line and each newline was a tenth of the time of `lase emit`.
        const BATCH: usize = 1 << 20;
        let mut batch: Vec<u8> = Vec::with_capacity(BATCH + 512);
        let mut sink = |l: &NcLine| {
            lines += 1;
            if lines.is_multiple_of(1 << 16) && busy.shown() {
                busy.say(format!("writing {dialect} NC: {lines} lines"));
            }
            batch.extend_from_slice(l.text.as_bytes());
            batch.push(b'\n');
            // The work frame is set right after the header's units and distance mode.
            // (ISO numbers its blocks: `N30 G21 G90 …`.)
            let body = l
                .text
                .trim_start_matches(|c: char| c == 'N' || c.is_ascii_digit());
            if body.trim_start().starts_with("G21 G90") {
                for line in setup.by_ref() {
                    batch.extend_from_slice(line.as_bytes());
                    batch.push(b'\n');
                    extra = (extra.0 + 1, extra.1 + line.len() as u64 + 1);
                }
            }
            if batch.len() >= BATCH {
                w.write_all(&batch)
                    .inspect_err(|e| io_err = Some(e.to_string()))?;
                batch.clear();
            }
            Ok(())
        };
        let r = match &windowed {
            Some(facts) => {
                lase_runtime::emit::emit_planned(&job, facts, dialect, &options, &mut sink)
            }
            None => lase_runtime::emit::emit(&job, dialect, &options, &mut sink),
        }
        .and_then(|stats| {
            w.write_all(&batch)
                .inspect_err(|e| io_err = Some(e.to_string()))?;
            Ok(stats)
        });
        match r {
            Ok(stats) => {
                for warn in &stats.warnings {
                    eprintln!("warning: {warn}");
                }
                written = (stats.lines + extra.0, stats.bytes + extra.1);
                Ok(())
            }
            Err(e) => match io_err {
                Some(msg) => Err(io_fail(format!("cannot write the NC program: {msg}"))),
                None => Err((recipe.map.clone(), Failure::one(e))),
            },
        }
    };
    match output {
        Some(path) => {
            output::write_atomic(path, |w| write(w))?;
            drop(busy);
            // A one-line result, as `plot -o` prints: the file holds the program.
            let size = match written.1 {
                b if b >= 1_000_000 => format!("{:.1} MB", b as f64 / 1e6),
                b => format!("{:.1} kB", b as f64 / 1e3),
            };
            outln!(
                "{}: wrote {} ({} lines, {size}, {dialect})",
                recipe.name(),
                path.display(),
                written.0,
            );
            Ok(())
        }
        None => {
            // A reader that stops early (`| head`) ends lase quietly, as it would `cat`.
            let mut out = std::io::BufWriter::with_capacity(
                1 << 16,
                output::Stdout(std::io::stdout().lock()),
            );
            write(&mut out)?;
            out.flush().map_err(|e| io_fail(format!("stdout: {e}")))
        }
    }
}

/// The options of every NC text lase produces, so `emit` and `run` send identical lines.
pub(crate) fn emit_options(locate: &dyn Fn(lase_lang::Span) -> String) -> EmitOptions<'_> {
    EmitOptions {
        locate: Some(locate),
        comments: true,
        live: false,
    }
}

fn parse_period(p: &str) -> Result<f64, (SourceMap, Failure)> {
    let bad = || {
        io_fail(format!(
            "bad --period `{p}`: give a time with a unit, e.g. 1ms or 0.5ms"
        ))
    };
    match lase_lang::units::parse_quantity(p) {
        Ok(q) if q.dim == lase_lang::units::Dim::TIME && q.value > 0.0 => Ok(q.value),
        _ => Err(bad()),
    }
}

fn cmd_plan(
    file: &Path,
    summary: Option<&Path>,
    trace: Option<&Path>,
    pulses: Option<&Path>,
    (period, dialect): (&str, Option<&str>),
) -> CmdResult {
    use lase_runtime::link::estimate;
    let period = parse_period(period)?;
    let given_dialect = dialect.map(parse_dialect).transpose()?;
    let (recipe, mut program) = driver::program(file)?;
    let dialect = given_dialect.unwrap_or_else(|| estimate::default_dialect(&program.machine));
    program.machine.run_on(dialect.name());
    // Every controller the report times: the one that runs the program, then the others
    // this machine has posts for.
    let dialects: Vec<_> = std::iter::once(dialect)
        .chain(estimate::other_dialects(&program.machine, dialect))
        .collect();
    // Planned in windows that are counted and dropped (issue 18), unless a trace or the pulses
    // are asked for (they sample the whole plan): the summary and the time split are running
    // totals (`report::PlanTotals`), and each controller's model reads its program from the
    // emitter line by line, from what the windows left for it (`emit::PlanFacts`, with each
    // post's pulse budget checked on the pulses as they pass).
    let windows = trace.is_none() && pulses.is_none();
    let (job, totals, facts) = if windows {
        let mut totals = lase_runtime::report::PlanTotals::new(&program);
        // One set of facts for every controller: they are the plan's (`PlanFacts::for_dialects`).
        let mut facts = lase_runtime::emit::PlanFacts::for_dialects(&program, &dialects);
        let planned = lase_runtime::compile::plan_in_windows(program, |p, w| {
            totals.window(p, &w);
            facts.window(p, &w);
        });
        let (job, planned) = match planned {
            Ok(p) => p,
            Err(f) => return Err((recipe.map, f)),
        };
        totals.finish(&job.program, planned.length);
        facts.finish(&job.program);
        (job, totals, Some(facts))
    } else {
        let job = match lase_runtime::compile::plan(program) {
            Ok(job) => job,
            Err(f) => return Err((recipe.map, f)),
        };
        let totals = lase_runtime::report::PlanTotals::of(&job);
        (job, totals, None)
    };
    let cycle = |k: usize| estimate::controller_cycle_from(&job, facts.as_ref(), dialects[k]);
    let mut s = totals.summary(&job);
    // The controller that runs the program, first: lase's own plan is ideal, the machine
    // runs its controller's planner (issue 13).
    let controller = cycle(0);
    s.controller = Some(controller.clone());
    if let Some(path) = summary {
        output::write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &s).map_err(|e| io_fail(e.to_string()))?;
            writeln!(w).map_err(|e| io_fail(e.to_string()))
        })?;
    }
    if let Some(path) = trace {
        output::write_atomic(path, |w| {
            lase_runtime::report::write_trace(&job, period, w).map_err(|e| io_fail(e.to_string()))
        })?;
    }
    if let Some(path) = pulses {
        output::write_atomic(path, |w| {
            lase_runtime::report::write_pulses(&job, w).map_err(|e| io_fail(e.to_string()))
        })?;
    }
    outln!(
        "{} on `{}` ({:?} ramps)",
        recipe.name(),
        job.program.machine.name,
        job.program.planner.ramp
    );
    outln!("{}", cycle_line("cycle time", &controller));
    if controller.note.is_none() {
        // lase's own plan: what places lead-ins, overscan and power coupling, with every axis
        // within its limits at every instant (corners blended within `corner`).
        outln!(
            "  lase's plan     {:.4} s ({}, which places lead-ins, overscan and power coupling)",
            s.cycle_time_s,
            estimate::OWN_PLAN
        );
    }
    // The other controllers this machine has posts for, by their models.
    for (k, &d) in dialects.iter().enumerate().skip(1) {
        let c = cycle(k);
        if c.note.is_none() {
            outln!("{}", cycle_line("controller", &c));
        } else {
            outln!(
                "  controller      {d} not modelled: {}",
                c.note.unwrap_or_default()
            );
        }
    }
    outln!(
        "  path length     {:.4} mm ({:.4} mm rapid)",
        s.path_length_mm,
        s.rapid_length_mm
    );
    outln!(
        "  laser on        {:.4} mm, {:.4} s while moving",
        s.laser_on_length_mm,
        s.laser_on_time_s
    );
    if let Some(o) = &job.program.ordering {
        // What `planner { order ... }` saved against the recipe's own order.
        let saved = o.source_travel_mm - o.travel_mm;
        outln!(
            "  cut order       {} paths: travel {:.4} mm, {:.4} mm as written ({:.4} mm saved, {:.1} %)",
            o.paths,
            o.travel_mm,
            o.source_travel_mm,
            saved,
            if o.source_travel_mm > 0.0 {
                100.0 * saved / o.source_travel_mm
            } else {
                0.0
            }
        );
    }
    // Dot mode fires with the spot at rest: say so, or "laser on 0 mm" next to a pulse count
    // reads as a contradiction.
    if s.pulses_standstill > 0 {
        outln!(
            "  laser at rest   {:.4} s in dot-mode windows",
            s.standstill_fire_time_s
        );
        outln!(
            "  pulses          {} ({} at rest, {} along lit moves)",
            s.pulses,
            s.pulses_standstill,
            s.pulses_moving
        );
    } else {
        outln!("  pulses          {}", s.pulses);
    }
    time_split_lines(totals.time_split(&job), s.cycle_time_s);
    outln!(
        "  blocks          {} planned moves from {}",
        s.blocks,
        output::ops_count(&job)
    );
    for (axis, p) in &s.axes {
        // Peaks in the axis's own unit, as the machine file and the controller speak it.
        let unit = job
            .program
            .machine
            .axes
            .iter()
            .find(|a| &a.name == axis)
            .map(|a| lase_runtime::axes::external_unit(a.kind))
            .unwrap_or("mm");
        let j = p
            .j_max
            .map(|j| format!("{j:.1} {unit}/s³"))
            .unwrap_or_else(|| "unbounded (trapezoid)".into());
        outln!(
            "  axis {axis:<3}  v {:.3} {unit}/s  a {:.3} {unit}/s²  j {j}",
            p.v_max,
            p.a_max
        );
    }
    Ok(())
}

/// `  cycle time      6.3400 s on linuxcnc, beam on … s (MODEL: DETAIL)`, or lase's own plan's
/// time with the reason it stands in for the controller.
fn cycle_line(label: &str, c: &lase_runtime::report::ControllerCycle) -> String {
    let beam = c
        .beam_on_s
        .map(|b| format!(", beam on {b:.4} s"))
        .unwrap_or_default();
    let what = match &c.note {
        Some(note) => format!("{}: {note}", c.model),
        None => format!("{}: {}", c.model, c.detail),
    };
    format!(
        "  {label:<15} {:.4} s on {}{beam} ({what})",
        c.cycle_time_s, c.dialect
    )
}

/// Where the cycle goes: lit, unlit at a feed (overscan, lead-ins), rapid, standing still; and
/// a hint when unlit motion takes longer than the lit work, which is where a recipe can win
/// most (a hatch fill whose rows are mostly overscan).
fn time_split_lines(t: lase_runtime::report::TimeSplit, cycle_s: f64) {
    let pct = |x: f64| {
        if cycle_s > 0.0 {
            100.0 * x / cycle_s
        } else {
            0.0
        }
    };
    outln!(
        "  time split      lit {:.4} s ({:.0} %), unlit feed {:.4} s ({:.0} %), rapid {:.4} s ({:.0} %), still {:.4} s",
        t.lit_s,
        pct(t.lit_s),
        t.unlit_feed_s,
        pct(t.unlit_feed_s),
        t.rapid_s,
        pct(t.rapid_s),
        t.still_s
    );
    if t.unlit_motion_s() > t.lit_s && t.unlit_motion_s() > 0.1 * cycle_s {
        let (what, fix) = if t.unlit_feed_s >= t.rapid_s {
            (
                "unlit moves at a feed (scan overscan, lead-ins and -outs, unlit `move ... at`)",
                "for a scan, a shorter `overscan`, rows along the region's long side (`angle`) or a lower `speed` (shorter ramps) cut it",
            )
        } else {
            (
                "rapid travel (approaches, a unidirectional scan's return strokes)",
                "`order serpentine` for a scan, or start each path near where the last one ends",
            )
        };
        outln!(
            "  hint: {:.0} % of the cycle is unlit motion, mostly {what}; {fix}",
            pct(t.unlit_motion_s())
        );
    }
}

fn cmd_plot(file: &Path, output: Option<&Path>, full: bool, unit: Option<&str>) -> CmdResult {
    use lase_runtime::report::{PlotOptions, SpeedUnit};
    let speed_unit = match unit {
        None => None,
        Some("mm/s") => Some(SpeedUnit::MmPerS),
        Some("mm/min") => Some(SpeedUnit::MmPerMin),
        Some(other) => {
            return Err(io_fail(format!(
                "bad --speed-unit `{other}`: give mm/s or mm/min"
            )));
        }
    };
    let (recipe, job) = driver::compile(file)?;
    let opts = PlotOptions {
        full_extent: full,
        speed_unit: speed_unit
            .unwrap_or_else(|| SpeedUnit::of_source(recipe.map.text(recipe.main))),
    };
    let default = file.with_extension("svg");
    let path = output.unwrap_or(&default);
    let png = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    let bytes = if png {
        lase_runtime::report::plot_png(&job, &opts).map_err(io_fail)?
    } else {
        lase_runtime::report::plot_svg(&job, &opts)
            .map_err(|e| io_fail(e.to_string()))?
            .into_bytes()
    };
    output::write_atomic(path, |w| {
        w.write_all(&bytes).map_err(|e| io_fail(e.to_string()))
    })?;
    outln!("{}: wrote {}", recipe.name(), path.display());
    Ok(())
}

/// `lase doc [NAME]`: one reference text for the CLI, the REPL's `:help` and docs/reference.md.
fn cmd_doc(name: Option<&str>, markdown: bool) -> ExitCode {
    if markdown {
        out!("{}", doc::reference_markdown());
        return ExitCode::SUCCESS;
    }
    match doc::lookup(name) {
        Some(text) => {
            out!("{text}");
            ExitCode::SUCCESS
        }
        None => {
            let name = name.unwrap_or_default();
            match doc::suggest(name) {
                Some(s) => eprintln!("no topic `{name}`; did you mean `{s}`?"),
                None => eprintln!("no topic `{name}`; `lase doc` lists the topics"),
            }
            ExitCode::FAILURE
        }
    }
}
