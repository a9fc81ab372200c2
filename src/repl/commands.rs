//! The REPL's `:commands`: one table (name, arguments, what it does) that `:help`, completion
//! and hints read, and the handlers.

use super::Session;
use super::machine::{Ran, Stream, Trouble};
use crate::driver::{self, Failure};
use lase_lang::units::{self, Dim};
use lase_lang::{SourceMap, Span};
use lase_runtime::compile::{self, Files, FsFiles};
use lase_runtime::emit::{Dialect, NcLine};
use lase_runtime::link::{self, LinkUrl};
use lase_runtime::machine::AxisKind;
use lase_runtime::motion::Job;
use std::io::Write;
use std::path::Path;

#[derive(Debug)]
pub struct Command {
    pub name: &'static str,
    pub args: &'static str,
    pub help: &'static str,
}

const fn cmd(name: &'static str, args: &'static str, help: &'static str) -> Command {
    Command { name, args, help }
}

pub const COMMANDS: &[Command] = &[
    cmd(":load", "FILE", "evaluate a recipe into the session"),
    cmd(
        ":check",
        "[FILE]",
        "check and plan what would run now (or a recipe file), run nothing",
    ),
    cmd(
        ":plan",
        "",
        "plan what would run now: ops, the controller's cycle time, path and lit length",
    ),
    cmd(
        ":plot",
        "[FILE.svg]",
        "draw what would run now (default lase-repl.svg)",
    ),
    cmd(
        ":emit",
        "[--dialect D] [FILE]",
        "the NC program of what would run now (linuxcnc, grbl, grblhal, iso)",
    ),
    cmd(
        ":connect",
        "[URL]",
        "use a controller: sim (default), tcp://HOST:PORT, serial:///dev/ttyUSB0?baud=115200",
    ),
    cmd(
        ":status",
        "",
        "the controller's live state: position, laser, overrides",
    ),
    cmd(
        ":jog",
        "AXIS DIST [at SPEED]",
        "jog one axis by a distance (`:jog x 10 mm`, `:jog c 90 deg`), laser off; Ctrl-C cancels",
    ),
    cmd(":home", "", "run the controller's homing cycle"),
    cmd(
        ":run",
        "[NAME | FILE]",
        "stream what the session produced since the last run, a process `fn NAME()`, or a recipe file",
    ),
    cmd(
        ":frame",
        "[FILE]",
        "trace the box of what would run now (or a recipe file) beam off at 50 mm/s, back to the start",
    ),
    cmd(":hold", "", "feed hold now (the laser goes off while held)"),
    cmd(
        ":resume",
        "",
        "resume after a hold, or continue a job a lost link interrupted",
    ),
    cmd(
        ":abort",
        "",
        "stop: feed hold, then soft reset (buffers emptied, laser off)",
    ),
    cmd(
        ":set",
        "[power P | speed S] [off]",
        "overrides for the next runs: `:set power 1.1 kW`, `:set power 80%`, `:set speed 50%`; `:set power off` clears",
    ),
    cmd(
        ":clear",
        "",
        "drop what the session produced since the last run, keeping its names",
    ),
    cmd(":names", "", "the names bound in the session"),
    cmd(
        ":help",
        "[TOPIC]",
        "this list, or the language reference: functions, profiles, settings, units, offset, laser, ...",
    ),
    cmd(
        ":quit",
        "",
        "leave (also Ctrl-D); waits while the controller moves",
    ),
];

fn find(name: &str) -> Option<&'static Command> {
    let aliases = [
        (":q", ":quit"),
        (":exit", ":quit"),
        (":h", ":help"),
        (":?", ":help"),
    ];
    let name = aliases
        .iter()
        .find(|(a, _)| *a == name)
        .map_or(name, |(_, n)| n);
    COMMANDS.iter().find(|c| c.name == name)
}

fn commands_help() -> String {
    let mut out = String::from(
        "Type statements (`machine`, `let`, `laser`, `follow`, ...) or an expression to see its value.\n\
         Motion accumulates in the session until `:run` streams it (checked and planned first).\n\
         Commands:\n",
    );
    for c in COMMANDS {
        let head = format!("{} {}", c.name, c.args);
        out.push_str(&format!("  {head:<28} {}\n", c.help));
    }
    out.push_str(
        "During a run: Ctrl-C = feed hold (laser off) and a question; h = hold, r = resume, a = abort.\n\
         `:help TOPIC` shows the language reference (`:help functions`, `:help offset`, `:help units`).",
    );
    out
}

/// A quantity typed after a command: `1.1 kW`, `1.1kW`, `-5 mm`, `80%`. A bare number is
/// `Err` unless `bare` gives its unit's dimension and the caller accepts it.
pub(super) enum Typed {
    Quantity(f64, Dim),
    Percent(f64),
    Bare(f64),
}

pub(super) fn parse_typed(text: &str) -> Result<Typed, String> {
    let t = text.trim();
    if let Some(p) = t.strip_suffix('%') {
        return p
            .trim()
            .parse::<f64>()
            .map(|v| Typed::Percent(v / 100.0))
            .map_err(|_| format!("`{t}` is not a percentage"));
    }
    match units::parse_quantity(t) {
        Ok(q) if q.bare => Ok(Typed::Bare(q.value)),
        Ok(q) => Ok(Typed::Quantity(q.value, q.dim)),
        Err(units::QuantityError::NotANumber(_)) => {
            Err(format!("`{t}` is not a number with a unit (e.g. 1.1 kW)"))
        }
        Err(units::QuantityError::UnknownUnit(e)) => Err(format!(
            "unknown unit `{}`{}",
            e.atom,
            e.suggestion
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default()
        )),
        Err(e @ units::QuantityError::NotFinite(_)) => Err(e.to_string()),
    }
}

impl Session {
    /// Runs a `:command`; `false` asks to leave.
    pub(super) fn command(&mut self, line: &str) -> bool {
        let (name, rest) = line
            .split_once(char::is_whitespace)
            .map_or((line, ""), |(n, r)| (n, r.trim()));
        let Some(c) = find(name) else {
            let names = COMMANDS.iter().map(|c| c.name);
            let hint = units::suggest(name, names)
                .map(|s| format!(" (did you mean `{s}`?)"))
                .unwrap_or_default();
            self.say_error(&format!(
                "unknown command `{name}`{hint}; `:help` lists them"
            ));
            return true;
        };
        let arg = (!rest.is_empty()).then_some(rest);
        match c.name {
            ":quit" => return false,
            ":help" => self.help(arg),
            ":names" => println!("{}", self.names.borrow().join(" ")),
            ":load" => self.load(arg),
            ":check" => self.check(arg),
            ":plan" => self.plan(),
            ":plot" => self.plot(arg),
            ":emit" => self.emit(rest),
            ":connect" => self.connect(arg),
            ":status" => {
                let r = self.station.status(self.eval.machine());
                self.show(r);
            }
            ":jog" => self.jog(rest),
            ":home" => {
                let r = self.station.home(self.eval.machine());
                self.show(r);
            }
            ":hold" => {
                let r = self.station.hold(self.eval.machine());
                self.show(r);
            }
            ":resume" => {
                let r = self.station.resume(self.eval.machine());
                self.show(r);
            }
            ":abort" => {
                let r = self.station.abort(self.eval.machine());
                self.show(r);
            }
            ":run" => self.run(arg),
            ":frame" => self.frame(arg),
            ":set" => self.set(rest),
            ":clear" => {
                let n = self.eval.ops().len();
                self.eval.discard();
                println!("dropped {n} ops");
            }
            _ => {}
        }
        true
    }

    fn show(&self, r: Result<String, Trouble>) {
        match r {
            Ok(msg) => println!("{msg}"),
            Err(Trouble::Say(m)) => self.say_error(&m),
            Err(Trouble::Diag(f)) => self.report(&f),
        }
    }

    fn help(&self, topic: Option<&str>) {
        match topic {
            None | Some("commands") => println!("{}", commands_help()),
            Some(t) if t.starts_with(':') => match find(t) {
                Some(c) => println!("{} {}\n  {}", c.name, c.args, c.help),
                None => self.say_error(&format!("no command `{t}`")),
            },
            // The same text as `lase doc TOPIC`.
            Some(t) => match crate::doc::lookup(Some(t)) {
                Some(text) => print!("{text}"),
                None => self.say_error(&format!(
                    "no help on `{t}`{}; `:help` lists the topics",
                    crate::doc::suggest(t)
                        .map(|s| format!(" (did you mean `{s}`?)"))
                        .unwrap_or_default()
                )),
            },
        }
    }

    fn load(&mut self, arg: Option<&str>) {
        let Some(path) = arg else {
            self.say_error("usage: :load FILE");
            return;
        };
        match FsFiles.read("", path) {
            Ok((_, text)) => {
                let before = self.eval.ops().len();
                if self.input(&text, path) {
                    self.loaded = Some(path.into());
                    // The ops the recipe wrote, as `:plan` counts them first.
                    println!(
                        "loaded {path}: {} ops to run",
                        self.eval.ops().len().saturating_sub(before)
                    );
                }
            }
            Err(reason) => self.say_error(&format!("cannot read {reason}")),
        }
    }

    /// The pending program with the overrides applied, planned for the controller `dialect`
    /// (`:emit --dialect`) or, with `None`, the GRBL-family link the REPL streams to.
    fn job(&self, dialect: Option<Dialect>) -> Option<Job> {
        let mut program = match self.pending() {
            Ok(p) => p,
            Err(f) => {
                self.report(&f);
                return None;
            }
        };
        if !self.apply_overrides(&self.map, &mut program) {
            return None;
        }
        let dialect = dialect.unwrap_or_else(|| link::live_dialect(&program.machine));
        program.machine.run_on(dialect.name());
        match compile::plan(program) {
            Ok(j) => Some(j),
            Err(f) => {
                self.report(&f);
                None
            }
        }
    }

    fn summary_line(&self, job: &Job) -> String {
        let s = lase_runtime::report::summarize(job);
        // The time of the controller the REPL streams to (a GRBL-family link), by its model.
        let dialect = lase_runtime::link::live_dialect(&job.program.machine);
        let mut line = format!(
            "{}, {}, path {:.4} mm, laser on {:.4} mm",
            crate::output::ops_count(job),
            crate::output::controller_cycle(job, dialect).1,
            s.path_length_mm,
            s.laser_on_length_mm
        );
        let note = self.overrides_note();
        if !note.is_empty() {
            line.push_str(&format!(" ({note})"));
        }
        line
    }

    fn plan(&self) {
        if self.eval.machine().is_none() && self.eval.ops().is_empty() {
            println!("nothing to plan yet: say which machine (`machine xy_table`) and what to do");
            return;
        }
        if let Some(job) = self.job(None) {
            println!("{}", self.summary_line(&job));
        }
    }

    fn check(&self, arg: Option<&str>) {
        if let Some(file) = arg {
            // As `lase check FILE`, for the controller `:run FILE` streams it to (the link's):
            // planned in windows, and what `lase emit` refuses checked.
            match driver::check(Path::new(file), link::live_dialect) {
                Ok((recipe, job, warnings)) => {
                    for warn in &warnings {
                        println!("warning: {warn}");
                    }
                    println!("{}", driver::ok_line(&recipe, &job));
                }
                Err((map, f)) => self.report_in(&map, &f),
            }
            return;
        }
        if self.eval.ops().is_empty() {
            println!("ok — nothing to run yet");
            return;
        }
        if let Some(job) = self.job(None) {
            let dialect = link::live_dialect(&job.program.machine);
            if let Some(nc) = self.nc_lines(&job, dialect) {
                println!(
                    "ok — {}, {} {dialect} lines",
                    self.summary_line(&job),
                    nc.len()
                );
            }
        }
    }

    fn plot(&self, arg: Option<&str>) {
        let Some(job) = self.job(None) else { return };
        let path = arg.unwrap_or("lase-repl.svg");
        // `.png` rasterizes, as `lase plot -o f.png` does.
        let opts = Default::default();
        let bytes = if path.to_ascii_lowercase().ends_with(".png") {
            lase_runtime::report::plot_png(&job, &opts)
        } else {
            lase_runtime::report::plot_svg(&job, &opts)
                .map(String::into_bytes)
                .map_err(|e| e.to_string())
        };
        let bytes = match bytes {
            Ok(b) => b,
            Err(e) => {
                self.say_error(&format!("cannot draw the plot: {e}"));
                return;
            }
        };
        match crate::output::write_atomic(Path::new(path), |w| {
            w.write_all(&bytes).map_err(|e| {
                (
                    SourceMap::new(),
                    Failure::one(driver::IoError {
                        message: e.to_string(),
                    }),
                )
            })
        }) {
            Ok(()) => println!("wrote {path}"),
            Err((map, f)) => self.report_in(&map, &f),
        }
    }

    /// `file:line` of a span for NC comments: the file's name, or `repl:N` for input N.
    fn locate(map: &SourceMap, span: Span) -> String {
        match map.locate(span) {
            Some((f, lc)) => {
                let name = map.name(f);
                let name = Path::new(name.trim_matches(|c| c == '<' || c == '>'))
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                format!("{name}:{}", lc.line)
            }
            None => String::new(),
        }
    }

    fn nc_lines_in(&self, map: &SourceMap, job: &Job, dialect: Dialect) -> Option<Vec<NcLine>> {
        let locate = |s: Span| Self::locate(map, s);
        match lase_runtime::emit::emit_lines(job, dialect, &crate::emit_options(&locate)) {
            Ok((lines, stats)) => {
                for w in &stats.warnings {
                    eprintln!("warning: {w}");
                }
                Some(lines)
            }
            Err(e) => {
                self.report_in(map, &Failure::one(e));
                None
            }
        }
    }

    fn nc_lines(&self, job: &Job, dialect: Dialect) -> Option<Vec<NcLine>> {
        self.nc_lines_in(&self.map, job, dialect)
    }

    fn emit(&self, rest: &str) {
        let mut dialect = Dialect::LinuxCnc;
        let mut file = None;
        let mut words = rest.split_whitespace();
        while let Some(w) = words.next() {
            let d = if w == "--dialect" || w == "-d" {
                match words.next() {
                    Some(d) => d,
                    None => {
                        self.say_error("usage: :emit [--dialect linuxcnc|grbl|grblhal|iso] [FILE]");
                        return;
                    }
                }
            } else if let Some(d) = w.strip_prefix("--dialect=") {
                d
            } else if w.parse::<Dialect>().is_ok() {
                w
            } else {
                file = Some(w);
                continue;
            };
            match d.parse::<Dialect>() {
                Ok(d) => dialect = d,
                Err(_) => {
                    self.say_error(&format!(
                        "unknown dialect `{d}`: choose linuxcnc, grbl, grblhal or iso"
                    ));
                    return;
                }
            }
        }
        let Some(job) = self.job(Some(dialect)) else {
            return;
        };
        let Some(lines) = self.nc_lines(&job, dialect) else {
            return;
        };
        match file {
            None => {
                let stdout = std::io::stdout();
                let mut w = stdout.lock();
                for l in &lines {
                    let _ = writeln!(w, "{}", l.text);
                }
            }
            Some(path) => {
                let r = crate::output::write_atomic(Path::new(path), |w| {
                    for l in &lines {
                        writeln!(w, "{}", l.text).map_err(|e| {
                            (
                                SourceMap::new(),
                                Failure::one(driver::IoError {
                                    message: e.to_string(),
                                }),
                            )
                        })?;
                    }
                    Ok(())
                });
                match r {
                    Ok(()) => println!("wrote {path} ({} lines, {dialect})", lines.len()),
                    Err((map, f)) => self.report_in(&map, &f),
                }
            }
        }
    }

    fn connect(&mut self, arg: Option<&str>) {
        let previous = self.station.url().clone();
        if let Some(u) = arg {
            match LinkUrl::parse(u) {
                Ok(url) => self.station.set_url(url),
                Err(e) => {
                    self.report(&Failure::one(e));
                    return;
                }
            }
        }
        let r = self.station.connect(self.eval.machine());
        match r {
            Ok(d) => println!("connected: {d}"),
            Err(t) => {
                self.show(Err(t));
                // A link that does not answer is not the one to use next.
                if arg.is_some() {
                    self.station.set_url(previous);
                    eprintln!("still using {}", self.station.url());
                }
            }
        }
    }

    fn jog(&mut self, rest: &str) {
        let usage = "usage: :jog AXIS DIST [at SPEED], e.g. `:jog x 10 mm`, `:jog y -0.5 mm at 5 mm/s` or `:jog c 90 deg at 30 deg/s`";
        let (main, speed) = match rest.split_once(" at ") {
            Some((m, s)) => (m.trim(), Some(s.trim())),
            None => (rest.trim(), None),
        };
        let Some((axis, dist)) = main.split_once(char::is_whitespace) else {
            self.say_error(usage);
            return;
        };
        let axis = axis.trim().to_ascii_lowercase();
        let letter = match axis.as_str() {
            "x" | "y" | "z" | "a" | "b" | "c" => axis.chars().next().unwrap_or('x'),
            _ => {
                self.say_error(&format!("`{axis}`: jog x, y, z, a, b or c"));
                return;
            }
        };
        let machine = self.eval.machine();
        let axis_spec =
            machine.and_then(|m| m.axes.iter().find(|a| a.name.eq_ignore_ascii_case(&axis)));
        if let Some(m) = machine
            && axis_spec.is_none()
        {
            self.say_error(&format!("machine `{}` has no axis {axis}", m.name));
            return;
        }
        // A rotary axis jogs by an angle, sent in degrees (deg/min for its rate); without a
        // machine, x, y, z are linear and a, b, c rotary.
        let rotary = axis_spec.map_or(letter >= 'a', |a| a.kind == AxisKind::Rotary);
        let (dist_dim, speed_dim, to_wire, unit) = if rotary {
            (
                Dim::ANGLE,
                Dim::ANGULAR_SPEED,
                lase_runtime::axes::external_scale(AxisKind::Rotary),
                "deg",
            )
        } else {
            (Dim::LENGTH, Dim::SPEED, 1.0, "mm")
        };
        let dist_internal = match parse_typed(dist) {
            Ok(Typed::Quantity(v, d)) if d == dist_dim => v,
            Ok(Typed::Bare(v)) if v == 0.0 => v,
            Ok(Typed::Bare(_)) => {
                self.say_error(&format!(
                    "give the distance with a unit: `:jog {axis} {} {unit}`",
                    dist.trim()
                ));
                return;
            }
            Ok(_) if rotary => {
                self.say_error(&format!(
                    "axis {axis} is rotary: the distance is an angle (deg, rad)"
                ));
                return;
            }
            Ok(_) => {
                self.say_error("the distance is a length (mm, um, in, ...)");
                return;
            }
            Err(e) => {
                self.say_error(&e);
                return;
            }
        };
        let v_max = axis_spec.map_or(f64::INFINITY, |a| a.v_max);
        // Default: 20 mm/s, or 30 deg/s on a rotary axis, within the axis's limit.
        let default_speed = if rotary { 30.0 / to_wire } else { 20.0 };
        let speed_internal = match speed.map(parse_typed) {
            None => v_max.min(default_speed),
            Some(Ok(Typed::Quantity(v, d))) if d == speed_dim && v > 0.0 => {
                if v > v_max {
                    self.say_error(&format!(
                        "{} is above axis {axis}'s {}",
                        units::format_quantity(v, speed_dim),
                        units::format_quantity(v_max, speed_dim)
                    ));
                    return;
                }
                v
            }
            Some(Ok(_)) if rotary => {
                self.say_error("the jog speed of a rotary axis is a positive angular speed (deg/s, rad/s, ...)");
                return;
            }
            Some(Ok(_)) => {
                self.say_error("the jog speed is a positive speed (mm/s, mm/min, ...)");
                return;
            }
            Some(Err(e)) => {
                self.say_error(&e);
                return;
            }
        };
        let r = self.station.jog(
            self.eval.machine(),
            letter,
            dist_internal * to_wire,
            speed_internal * to_wire * 60.0,
        );
        self.show(r);
    }

    /// `:run`, `:run NAME`, `:run FILE`.
    fn run(&mut self, arg: Option<&str>) {
        match arg {
            Some(a) if a.ends_with(".lase") || Path::new(a).is_file() => {
                self.run_file(Path::new(a))
            }
            Some(name) => {
                if !self.eval.ops().is_empty() {
                    self.say_error(&format!(
                        "the session has {} ops that have not run: `:run` them first, or `:clear`",
                        self.eval.ops().len()
                    ));
                    return;
                }
                if !self.names.borrow().iter().any(|n| n == name) {
                    self.say_error(&format!(
                        "no process `{name}`: define one with `fn {name}() {{ ... }}`"
                    ));
                    return;
                }
                if !self.input(&format!("{name}()\n"), &format!("<run {name}>")) {
                    self.eval.discard();
                    return;
                }
                let ran = self.run_pending(name);
                // The process's moves are not the operator's to keep: drop them if they
                // never ran.
                if ran == Ran::NotStarted {
                    self.eval.discard();
                }
            }
            None => {
                if self.eval.ops().is_empty() {
                    self.say_error(
                        "nothing to run: type motion statements (`follow`, `move`), `:load FILE`, or `:run NAME` for a process `fn NAME()`",
                    );
                    return;
                }
                self.run_pending("repl");
            }
        }
    }

    /// `:frame`: the lit work's bounding box traced dark (`ProcessProgram::frame`), as `lase
    /// frame` does, over the session's controller; the session's moves stay pending.
    fn frame(&mut self, arg: Option<&str>) {
        let (map, program) = match arg {
            Some(file) => {
                let mut recipe = match compile::load(&mut FsFiles, file) {
                    Ok(r) => r,
                    Err((map, f)) => return self.report_in(&map, &f),
                };
                match compile::check(&recipe)
                    .and_then(|()| compile::evaluate(&mut recipe, &mut FsFiles))
                {
                    Ok(p) => (recipe.map, p),
                    Err(f) => return self.report_in(&recipe.map, &f),
                }
            }
            None => {
                if let Err(Trouble::Say(m)) = self.sync_start(true) {
                    return self.say_error(&m);
                }
                match self.pending() {
                    Ok(p) => (self.map.clone(), p),
                    Err(f) => return self.report(&f),
                }
            }
        };
        if lase_runtime::kinematics::for_machine(&program.machine).oriented() {
            return self.say_error("this machine orients the beam: a frame traces a flat bed");
        }
        let Some(mut frame) = program.frame(50.0, None) else {
            return self.say_error("nothing lit to frame: `follow` a path first, or `:frame FILE`");
        };
        frame
            .machine
            .run_on(link::live_dialect(&frame.machine).name());
        let job = match compile::plan(frame) {
            Ok(j) => j,
            Err(f) => return self.report_in(&map, &f),
        };
        let dialect = link::live_dialect(&job.program.machine);
        if let Some(nc) = self.nc_lines_in(&map, &job, dialect) {
            let _ = self.stream(&map, &job, &nc, "frame");
        }
    }

    /// Before the session's moves run on a flat-bed machine (and, quietly, after a job
    /// finished): if the machine is not where the session left it (after a `:jog`, an aborted job, a move from the controller's own
    /// console), the pending moves start from where it is, so the first one is planned (and
    /// lit, if it is a cut) from the real position. Oriented machines start every job from
    /// their home pose with a rapid, whatever the position.
    fn sync_start(&mut self, announce: bool) -> Result<(), Trouble> {
        let Some(m) = self.eval.machine() else {
            return Ok(());
        };
        let kin = lase_runtime::kinematics::for_machine(m);
        if kin.oriented() {
            return Ok(());
        }
        let m = m.clone();
        let reported = self.station.position(Some(&m))?;
        let q = link::ControllerAxes::of(&m).from_controller(&reported);
        let spot = kin.forward(&q).spot;
        let here = [spot.x, spot.y, spot.z];
        let was = self.eval.start();
        let off = (0..3)
            .map(|i| (here[i] - was[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        // The controller reports 3 decimals.
        if off > 2e-3 {
            if announce {
                let show = |p: [f64; 3]| {
                    p.iter()
                        .map(|v| units::format_number((v * 1e3).round() / 1e3))
                        .collect::<Vec<_>>()
                        .join(", ")
                };
                println!(
                    "the machine is at ({}), not at ({}) where the session left it: the moves start from there",
                    show(here),
                    show(was)
                );
            }
            self.eval.rebase(here);
        }
        Ok(())
    }

    /// Streams the session's pending ops; they are consumed once lines went out.
    fn run_pending(&mut self, name: &str) -> Ran {
        match self.sync_start(true) {
            Ok(()) => {}
            Err(Trouble::Say(m)) => {
                self.say_error(&m);
                return Ran::NotStarted;
            }
            Err(Trouble::Diag(f)) => {
                self.report(&f);
                return Ran::NotStarted;
            }
        }
        let Some(job) = self.job(None) else {
            return Ran::NotStarted;
        };
        let dialect = link::live_dialect(&job.program.machine);
        let Some(nc) = self.nc_lines(&job, dialect) else {
            return Ran::NotStarted;
        };
        let map = self.map.clone();
        let (ran, done) = self.stream(&map, &job, &nc, name);
        if ran == Ran::Started {
            let _ = self.eval.take_program("repl", Span::default());
        }
        if done {
            // Where the job left the machine (its lead-out included) is where the session
            // goes on from; only a move the session did not make is announced.
            let _ = self.sync_start(false);
        }
        ran
    }

    fn run_file(&mut self, path: &Path) {
        // The pipeline of `lase run`, with the session's overrides between evaluating and
        // planning.
        let mut recipe = match compile::load(&mut FsFiles, &path.to_string_lossy()) {
            Ok(r) => r,
            Err((map, f)) => return self.report_in(&map, &f),
        };
        if let Err(f) = compile::check(&recipe) {
            return self.report_in(&recipe.map, &f);
        }
        let mut program = match compile::evaluate(&mut recipe, &mut FsFiles) {
            Ok(p) => p,
            Err(f) => return self.report_in(&recipe.map, &f),
        };
        if !self.apply_overrides(&recipe.map, &mut program) {
            return;
        }
        program
            .machine
            .run_on(link::live_dialect(&program.machine).name());
        let job = match compile::plan(program) {
            Ok(j) => j,
            Err(f) => return self.report_in(&recipe.map, &f),
        };
        let dialect = link::live_dialect(&job.program.machine);
        let Some(nc) = self.nc_lines_in(&recipe.map, &job, dialect) else {
            return;
        };
        let name = recipe.name();
        let _ = self.stream(&recipe.map, &job, &nc, &name);
    }

    /// Streams a job; whether lines went out, and whether it finished.
    fn stream(&mut self, map: &SourceMap, job: &Job, nc: &[NcLine], name: &str) -> (Ran, bool) {
        let note = self.overrides_note();
        if !note.is_empty() {
            println!("{name}: {note}");
        }
        let machine = job.program.machine.clone();
        let (ran, r) = self.station.run(&machine, &Stream { job, nc }, name);
        let done = r.is_ok();
        match r {
            Ok(msg) => println!("{msg}"),
            Err(Trouble::Say(m)) => self.say_error(&m),
            Err(Trouble::Diag(f)) => self.report_in(map, &f),
        }
        (ran, done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_quantities_parse() {
        assert!(
            matches!(parse_typed("1.1 kW"), Ok(Typed::Quantity(v, d)) if (v - 1100.0).abs() < 1e-9 && d == Dim::POWER)
        );
        assert!(matches!(parse_typed("-5mm"), Ok(Typed::Quantity(v, _)) if v == -5.0));
        assert!(matches!(parse_typed("80%"), Ok(Typed::Percent(k)) if (k - 0.8).abs() < 1e-12));
        assert!(matches!(parse_typed("3"), Ok(Typed::Bare(v)) if v == 3.0));
        assert!(parse_typed("3 kw").is_err());
    }

    #[test]
    fn every_command_has_help() {
        for c in COMMANDS {
            assert!(c.name.starts_with(':') && !c.help.is_empty());
        }
        assert_eq!(find(":q").map(|c| c.name), Some(":quit"));
    }
}
