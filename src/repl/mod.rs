//! The REPL at the machine: statements evaluated into one persistent session (bindings,
//! machine, limits, laser settings survive between inputs), errors shown as the same
//! diagnostics as the CLI while the session goes on, and `:commands` that plan, plot, emit,
//! jog, home and run on a controller — the built-in simulator unless `--link` names another.
//!
//! With a terminal it uses rustyline ([`editor`]: completion, highlighting, hints, multi-line
//! input while brackets are open, history in `~/.lase_history`). Without one (input piped in)
//! it reads standard input with no prompt, no banner and no colour, so sessions can be
//! scripted and their output compared with a golden file.
//!
//! - [`commands`]: the `:command` table and what each does.
//! - [`machine`]: the controller link, jobs with the progress bar, Ctrl-C as a feed hold.

mod commands;
mod editor;
mod machine;
mod overrides;

use crate::driver::{self, Failure};
use lase_lang::parser::{ReplInput, is_incomplete, parse_repl};
use lase_lang::{Checker, Program, SourceMap, Span};
use lase_runtime::FsFiles;
use lase_runtime::eval::Evaluator;
use lase_runtime::link::LinkUrl;
use std::io::{BufRead, IsTerminal};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Power and speed overrides for the runs that follow (`:set`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Overrides {
    /// Laser power, W, or a factor on the programmed power.
    pub power: Option<Amount>,
    /// Feed of `at` moves, mm/s, or a factor on the programmed feed.
    pub speed: Option<Amount>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Amount {
    Value(f64),
    Factor(f64),
}

struct Session {
    map: SourceMap,
    program: Program,
    checker: Checker,
    eval: Evaluator,
    /// Colour for diagnostics and the editor.
    color: bool,
    inputs: usize,
    station: machine::Station,
    overrides: Overrides,
    names: editor::Names,
    /// The recipe `:load` read last.
    loaded: Option<PathBuf>,
}

impl Session {
    fn new(color: bool, interactive: bool, url: LinkUrl) -> Session {
        let program = Program::default();
        Session {
            map: SourceMap::new(),
            checker: Checker::new(program.clone()),
            program,
            eval: Evaluator::new(),
            color,
            inputs: 0,
            station: machine::Station::new(url, interactive),
            overrides: Overrides::default(),
            names: Default::default(),
            loaded: None,
        }
    }

    /// Reports what the checker found in the line just checked; true when it found nothing.
    fn checked_clean(&mut self) -> bool {
        let errs = self.checker.take_errors();
        if errs.is_empty() {
            return true;
        }
        self.report(&Failure::many(errs));
        false
    }

    fn report(&self, f: &Failure) {
        self.report_in(&self.map, f);
    }

    fn report_in(&self, map: &SourceMap, f: &Failure) {
        eprint!("{}", driver::render(map, f, self.color));
    }

    /// A one-line problem that is not a diagnostic of the recipe (bad command arguments, a
    /// controller refusing something).
    fn say_error(&self, msg: &str) {
        if self.color {
            eprintln!("\x1b[1;31merror\x1b[0m: {msg}");
        } else {
            eprintln!("error: {msg}");
        }
    }

    fn refresh_names(&self) {
        let mut names = self.eval.names();
        names.extend(self.checker.names());
        names.sort();
        names.dedup();
        *self.names.borrow_mut() = names;
    }

    /// Evaluates one complete input (one or more lines of source): parse, check, evaluate.
    /// Nothing of it is kept when any phase fails.
    fn input(&mut self, text: &str, name: &str) -> bool {
        self.inputs += 1;
        let id = self.map.add(name, text);
        let base = self.map.base(id);
        let parsed = match parse_repl(text, base) {
            Ok(p) => p,
            Err(e) => {
                self.report(&Failure::one(e));
                return false;
            }
        };
        // A lone call (`sqrt(2)`, `ring(5 mm)`) parses as a statement; the REPL shows its
        // value too, when it has one.
        let parsed = match parsed {
            ReplInput::Stmts(mut stmts)
                if stmts.len() == 1
                    && matches!(&stmts[0].kind, lase_lang::ast::StmtKind::Expr(_)) =>
            {
                match stmts.pop().map(|s| s.kind) {
                    Some(lase_lang::ast::StmtKind::Expr(e)) => ReplInput::Expr(e),
                    _ => ReplInput::Stmts(stmts),
                }
            }
            other => other,
        };
        let ok = match parsed {
            ReplInput::Stmts(stmts) => {
                // Imports, then `use` lines (their extension module or preset goes into the
                // session before checking), as `lase` loads a recipe.
                if let Err(f) = lase_runtime::compile::load_input(
                    &mut self.program,
                    &mut self.map,
                    id,
                    &stmts,
                    self.eval.extensions_mut(),
                    &mut FsFiles,
                ) {
                    self.report(&f);
                    return false;
                }
                self.checker.set_program(self.program.clone());
                self.checker.check_stmts(&stmts);
                if !self.checked_clean() {
                    return false;
                }
                match self
                    .eval
                    .run(&stmts, &self.program, &mut self.map, &mut FsFiles)
                {
                    Ok(()) => true,
                    Err(e) => {
                        self.report(&Failure::one(e));
                        false
                    }
                }
            }
            ReplInput::Expr(e) => {
                self.checker.check_expr_stmt(&e);
                if !self.checked_clean() {
                    return false;
                }
                match self
                    .eval
                    .eval_expr(&e, &self.program, &mut self.map, &mut FsFiles)
                {
                    Ok(lase_runtime::eval::Value::Nothing) => true,
                    Ok(v) => {
                        println!("{v}");
                        true
                    }
                    Err(err) => {
                        self.report(&Failure::one(err));
                        false
                    }
                }
            }
        };
        self.refresh_names();
        ok
    }

    /// The process program of what the session produced since the last run.
    fn pending(&self) -> Result<lase_runtime::program::ProcessProgram, Failure> {
        self.eval
            .program("repl", Span::default())
            .map_err(Failure::one)
    }

    /// One complete input: a `:command` or source. `false` ends the session.
    fn handle(&mut self, text: &str) -> bool {
        let t = text.trim();
        if t.is_empty() {
            return true;
        }
        if t.starts_with(':') {
            return self.command(t);
        }
        let name = format!("<repl:{}>", self.inputs + 1);
        self.input(text, &name);
        true
    }

    /// Whether the session may end now: not while the controller moves or holds a job.
    fn may_leave(&mut self) -> bool {
        match self.station.before_exit() {
            Ok(()) => true,
            Err(machine::Trouble::Say(m)) => {
                self.say_error(&m);
                false
            }
            Err(machine::Trouble::Diag(f)) => {
                self.report(&f);
                false
            }
        }
    }
}

/// `lase repl [FILE] [--link URL]`.
pub fn run(file: Option<&Path>, link: Option<&str>, color: bool) -> ExitCode {
    let interactive = std::io::stdin().is_terminal() && std::io::stdout().is_terminal();
    let url = match LinkUrl::parse(link.unwrap_or("sim")) {
        Ok(u) => u,
        Err(e) => {
            eprint!(
                "{}",
                driver::render(&SourceMap::new(), &Failure::one(e), color)
            );
            return ExitCode::FAILURE;
        }
    };
    let mut s = Session::new(color && interactive, interactive, url);
    if let Some(f) = file {
        s.command(&format!(":load {}", f.display()));
    }
    if interactive {
        run_terminal(&mut s)
    } else {
        run_piped(&mut s)
    }
}

fn run_piped(s: &mut Session) -> ExitCode {
    let stdin = std::io::stdin();
    let mut buf = String::new();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        // A command is one line; source continues while brackets are open.
        if buf.is_empty() && line.trim_start().starts_with(':') {
            if !s.handle(&line) {
                if s.may_leave() {
                    return ExitCode::SUCCESS;
                }
                return ExitCode::FAILURE;
            }
            continue;
        }
        buf.push_str(&line);
        buf.push('\n');
        if is_incomplete(&buf) {
            continue;
        }
        let text = std::mem::take(&mut buf);
        s.handle(&text);
    }
    if !buf.trim().is_empty() {
        s.handle(&buf);
    }
    if s.may_leave() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

fn history_path() -> Option<PathBuf> {
    std::env::var_os("LASE_HISTORY")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".lase_history")))
}

fn run_terminal(s: &mut Session) -> ExitCode {
    use rustyline::error::ReadlineError;
    let config = rustyline::Config::builder()
        .auto_add_history(false)
        .completion_type(rustyline::CompletionType::List)
        .build();
    let mut rl: rustyline::Editor<editor::LaseHelper, rustyline::history::DefaultHistory> =
        match rustyline::Editor::with_config(config) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("error: cannot start the line editor: {e}");
                return ExitCode::FAILURE;
            }
        };
    rl.set_helper(Some(editor::LaseHelper::new(s.names.clone(), s.color)));
    let history = history_path();
    if let Some(h) = &history {
        let _ = rl.load_history(h);
    }
    println!(
        "lase {} — statements run into the session; :help for commands, Ctrl-D to leave (link: {})",
        env!("CARGO_PKG_VERSION"),
        s.station.url()
    );
    loop {
        match rl.readline("lase> ") {
            Ok(text) => {
                if !text.trim().is_empty() {
                    let _ = rl.add_history_entry(text.trim_end());
                }
                if !s.handle(&text) && s.may_leave() {
                    break;
                }
            }
            // Ctrl-C at the prompt clears the line.
            Err(ReadlineError::Interrupted) => {}
            // Ctrl-D leaves once the controller is at rest.
            Err(ReadlineError::Eof) => {
                if s.may_leave() {
                    break;
                }
            }
            Err(e) => {
                eprintln!("error: {e}");
                break;
            }
        }
        // Kept as it grows, so a session that dies keeps its history.
        if let Some(h) = &history {
            let _ = rl.append_history(h);
        }
    }
    ExitCode::SUCCESS
}
