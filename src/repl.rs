//! The REPL: statements evaluated into one persistent session, errors shown as the same
//! diagnostics as the CLI, and the session goes on.
//!
//! With a terminal it uses rustyline (line editing, history in `~/.lase_history`, multi-line
//! input while brackets are open). Without one (input piped in) it reads standard input with
//! no prompt and no colour, so sessions can be scripted.

use crate::driver::{self, Failure, FsLoader};
use lase_lang::parser::{ReplInput, is_incomplete, parse_repl};
use lase_lang::{Checker, Program, SourceMap, Span};
use lase_runtime::emit::Dialect;
use lase_runtime::eval::Evaluator;
use std::io::{BufRead, IsTerminal};
use std::path::Path;
use std::process::ExitCode;

struct Session {
    map: SourceMap,
    program: Program,
    checker: Checker,
    eval: Evaluator,
    color: bool,
    inputs: usize,
}

const HELP: &str = "\
Type statements (`let`, `machine`, `follow`, ...) or an expression to see its value.
Commands:
  :load FILE            evaluate a recipe into the session
  :plan                 plan what the session has produced so far and show the summary
  :emit [DIALECT]       print the NC program of the session so far (linuxcnc, grbl, iso)
  :run                  plan and send the session's motion to the built-in simulator, then clear it
  :names                names defined in the session
  :help                 this text
  :quit                 leave (also Ctrl-D)";

impl Session {
    fn new(color: bool) -> Session {
        let program = Program::default();
        Session {
            map: SourceMap::new(),
            checker: Checker::new(program.clone()),
            program,
            eval: Evaluator::new(),
            color,
            inputs: 0,
        }
    }

    fn report(&self, f: &Failure) {
        eprint!("{}", driver::render(&self.map, f, self.color));
    }

    /// Evaluates one complete input (one or more lines of source).
    fn input(&mut self, text: &str, name: &str) -> bool {
        self.inputs += 1;
        let id = self.map.add(name, text);
        let base = self.map.base(id);
        let parsed = match parse_repl(text, base) {
            Ok(p) => p,
            Err(e) => {
                self.report(&driver::parse_failure(vec![e]));
                return false;
            }
        };
        match parsed {
            ReplInput::Stmts(stmts) => {
                let mut errors = Vec::new();
                lase_lang::resolve_imports(
                    &mut self.program,
                    &mut self.map,
                    id,
                    &stmts,
                    &mut FsLoader,
                    &mut errors,
                    &mut vec![id],
                );
                if !errors.is_empty() {
                    self.report(&driver::parse_failure(errors));
                    return false;
                }
                self.checker.set_program(self.program.clone());
                self.checker.check_stmts(&stmts);
                let errs = self.checker.take_errors();
                if !errs.is_empty() {
                    self.report(&driver::check_failure(errs));
                    return false;
                }
                if let Err(e) = self
                    .eval
                    .run(&stmts, &self.program, &mut self.map, &mut FsLoader)
                {
                    self.report(&Failure::one(e));
                    return false;
                }
                true
            }
            ReplInput::Expr(e) => {
                self.checker.check_expr_stmt(&e);
                let errs = self.checker.take_errors();
                if !errs.is_empty() {
                    self.report(&driver::check_failure(errs));
                    return false;
                }
                match self
                    .eval
                    .eval_expr(&e, &self.program, &mut self.map, &mut FsLoader)
                {
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
        }
    }

    fn job(&self) -> Option<lase_runtime::motion::Job> {
        let program = match self.eval.program("repl", Span::default()) {
            Ok(p) => p,
            Err(e) => {
                self.report(&Failure::one(e));
                return None;
            }
        };
        match driver::plan(program) {
            Ok(j) => Some(j),
            Err(f) => {
                self.report(&f);
                None
            }
        }
    }

    /// Runs a `:command`; returns false to quit.
    fn command(&mut self, line: &str) -> bool {
        let mut parts = line.split_whitespace();
        let cmd = parts.next().unwrap_or("");
        let arg = parts.next();
        match cmd {
            ":quit" | ":q" | ":exit" => return false,
            ":help" | ":h" => println!("{HELP}"),
            ":names" => println!("{}", self.eval.names().join(" ")),
            ":load" => match arg {
                Some(path) => match std::fs::read_to_string(path) {
                    Ok(text) => {
                        if self.input(&text, path) {
                            println!("loaded {path}");
                        }
                    }
                    Err(e) => eprintln!("error: cannot read {path}: {e}"),
                },
                None => eprintln!("usage: :load FILE"),
            },
            ":plan" => {
                if let Some(job) = self.job() {
                    let s = lase_runtime::report::summarize(&job);
                    println!(
                        "{} ops, cycle time {:.4} s, path {:.4} mm, laser on {:.4} mm",
                        job.program.ops.len(),
                        s.cycle_time_s,
                        s.path_length_mm,
                        s.laser_on_length_mm
                    );
                }
            }
            ":emit" => {
                let dialect = match arg.unwrap_or("linuxcnc").parse::<Dialect>() {
                    Ok(d) => d,
                    Err(_) => {
                        eprintln!("error: unknown dialect; choose linuxcnc, grbl or iso");
                        return true;
                    }
                };
                if let Some(job) = self.job() {
                    match lase_runtime::emit::emit_to_string(&job, dialect) {
                        Ok(text) => print!("{text}"),
                        Err(e) => self.report(&Failure::one(e)),
                    }
                }
            }
            ":run" => {
                if let Some(job) = self.job() {
                    let mut link = match lase_runtime::link::open(None, &job.program.machine) {
                        Ok(l) => l,
                        Err(e) => {
                            self.report(&Failure::one(e));
                            return true;
                        }
                    };
                    match lase_runtime::emit::emit_to_string(&job, Dialect::LinuxCnc) {
                        Ok(text) => {
                            for l in text.lines() {
                                if let Ok(lase_runtime::link::Reply::Error { message, .. }) =
                                    link.send(l)
                                {
                                    eprintln!("error: controller rejected `{l}`: {message}");
                                    return true;
                                }
                            }
                            let _ = self.eval.take_program("repl", Span::default());
                            println!("{}", link.status());
                        }
                        Err(e) => self.report(&Failure::one(e)),
                    }
                }
            }
            other => eprintln!("unknown command `{other}`; :help lists them"),
        }
        true
    }
}

pub fn run(file: Option<&Path>, color: bool) -> ExitCode {
    let interactive = std::io::stdin().is_terminal();
    let mut s = Session::new(color && interactive);
    if let Some(f) = file {
        s.command(&format!(":load {}", f.display()));
    }
    if interactive {
        run_terminal(&mut s)
    } else {
        run_piped(&mut s)
    }
}

fn handle(s: &mut Session, text: &str) -> bool {
    let t = text.trim();
    if t.is_empty() {
        return true;
    }
    if t.starts_with(':') {
        return s.command(t);
    }
    let name = format!("<repl:{}>", s.inputs + 1);
    s.input(text, &name);
    true
}

fn run_piped(s: &mut Session) -> ExitCode {
    let stdin = std::io::stdin();
    let mut buf = String::new();
    let mut failed = false;
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        buf.push_str(&line);
        buf.push('\n');
        if is_incomplete(&buf) {
            continue;
        }
        let before = s.inputs;
        let text = std::mem::take(&mut buf);
        if !handle(s, &text) {
            break;
        }
        let _ = before;
        failed |= false;
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

fn run_terminal(s: &mut Session) -> ExitCode {
    let mut rl = match rustyline::DefaultEditor::new() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("error: cannot start the line editor: {e}");
            return ExitCode::FAILURE;
        }
    };
    let history = std::env::var_os("HOME").map(|h| Path::new(&h).join(".lase_history"));
    if let Some(h) = &history {
        let _ = rl.load_history(h);
    }
    println!(
        "lase {} — :help for commands, Ctrl-D to leave",
        env!("CARGO_PKG_VERSION")
    );
    let mut buf = String::new();
    loop {
        let prompt = if buf.is_empty() { "lase> " } else { "....> " };
        match rl.readline(prompt) {
            Ok(line) => {
                buf.push_str(&line);
                buf.push('\n');
                if is_incomplete(&buf) {
                    continue;
                }
                let text = std::mem::take(&mut buf);
                let _ = rl.add_history_entry(text.trim_end());
                if !handle(s, &text) {
                    break;
                }
            }
            Err(rustyline::error::ReadlineError::Interrupted) => buf.clear(),
            Err(_) => break,
        }
    }
    if let Some(h) = &history {
        let _ = rl.save_history(h);
    }
    ExitCode::SUCCESS
}
