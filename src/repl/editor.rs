//! The line editor's helper: completion, syntax highlighting, hints and multi-line input.
//!
//! Everything it knows about the language comes from `lase_lang::schema` (keywords,
//! functions, profile kinds, settings), `lase_lang::units` and the names the session has
//! bound so far, which the session shares through [`Names`].

use super::commands::COMMANDS;
use lase_lang::parser::is_incomplete;
use lase_lang::schema;
use rustyline::completion::{Completer, FilenameCompleter, Pair};
use rustyline::highlight::{CmdKind, Highlighter};
use rustyline::hint::{Hint, Hinter};
use rustyline::validate::{ValidationContext, ValidationResult, Validator};
use rustyline::{Context, Helper};
use std::borrow::Cow;
use std::cell::RefCell;
use std::rc::Rc;

/// Names bound in the session, refreshed after every input.
pub type Names = Rc<RefCell<Vec<String>>>;

pub struct LaseHelper {
    pub names: Names,
    pub color: bool,
    files: FilenameCompleter,
}

impl LaseHelper {
    pub fn new(names: Names, color: bool) -> LaseHelper {
        LaseHelper {
            names,
            color,
            files: FilenameCompleter::new(),
        }
    }
}

/// Compound units worth offering whole after a number.
const COMPOUND_UNITS: &[&str] = &[
    "mm/s", "mm/min", "m/min", "m/s", "m/s^2", "mm/s^2", "m/s^3", "mm/s^3", "deg/s", "rev/min",
];

fn is_ident(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// Where the word being typed starts.
fn word_start(line: &str, pos: usize) -> usize {
    line[..pos]
        .char_indices()
        .rev()
        .find(|(_, c)| !(is_ident(*c) || *c == '/' || *c == '^'))
        .map(|(i, c)| i + c.len_utf8())
        .unwrap_or(0)
}

/// Whether `pos` is inside a string literal.
fn in_string(line: &str, pos: usize) -> bool {
    line[..pos].chars().filter(|c| *c == '"').count() % 2 == 1
}

/// The statement whose `{ ... }` settings list the cursor is in, if any.
fn settings_context(text: &str) -> Option<&'static [schema::SettingSpec]> {
    let mut depth = 0i32;
    for (i, c) in text.char_indices().rev() {
        match c {
            '}' => depth += 1,
            '{' if depth > 0 => depth -= 1,
            '{' => {
                let before = text[..i].trim_end();
                let words: Vec<&str> = before.split_whitespace().collect();
                let last = words.last().copied().unwrap_or("");
                return match last {
                    "laser" => Some(schema::LASER_SETTINGS),
                    "pulse" => Some(schema::PULSE_SETTINGS),
                    "planner" => Some(schema::PLANNER_SETTINGS),
                    "rotary" => Some(schema::ROTARY_SETTINGS),
                    _ if words.contains(&"follow") => Some(schema::FOLLOW_SETTINGS),
                    _ => None,
                };
            }
            _ => {}
        }
    }
    None
}

fn pairs<'a>(prefix: &str, items: impl Iterator<Item = &'a str>, suffix: &str) -> Vec<Pair> {
    let mut v: Vec<Pair> = items
        .filter(|i| i.starts_with(prefix))
        .map(|i| Pair {
            display: i.to_string(),
            replacement: format!("{i}{suffix}"),
        })
        .collect();
    v.sort_by(|a, b| a.display.cmp(&b.display));
    v.dedup_by(|a, b| a.display == b.display);
    v
}

impl LaseHelper {
    fn complete_command(&self, line: &str, pos: usize) -> (usize, Vec<Pair>) {
        let head = &line[..pos];
        let Some((cmd, rest)) = head.split_once(char::is_whitespace) else {
            // The command name itself.
            return (
                0,
                pairs(head, COMMANDS.iter().map(|c| c.name), " ")
                    .into_iter()
                    .map(|mut p| {
                        if matches!(
                            p.display.as_str(),
                            ":quit"
                                | ":status"
                                | ":home"
                                | ":check"
                                | ":plan"
                                | ":hold"
                                | ":resume"
                                | ":abort"
                        ) {
                            p.replacement = p.display.clone();
                        }
                        p
                    })
                    .collect(),
            );
        };
        let start = pos - rest.len() + rest.rfind(char::is_whitespace).map_or(0, |i| i + 1);
        let word = &line[start..pos];
        let names = self.names.borrow();
        let list: Vec<Pair> = match cmd {
            ":help" | ":h" => {
                let mut t: Vec<&str> = crate::doc::topics();
                t.push("commands");
                t.extend(COMMANDS.iter().map(|c| c.name));
                pairs(word, t.into_iter(), "")
            }
            ":connect" => pairs(
                word,
                ["sim", "sim://?time-scale=real", "tcp://", "serial://"].into_iter(),
                "",
            ),
            ":set" => pairs(word, ["power", "speed"].into_iter(), " "),
            ":jog" => pairs(word, ["x", "y", "z", "a", "b", "c"].into_iter(), " "),
            ":emit" if word.starts_with('-') => pairs(word, ["--dialect"].into_iter(), " "),
            ":emit"
                if rest.trim_end().ends_with("--dialect")
                    || rest.split_whitespace().last() == Some("--dialect") =>
            {
                pairs(
                    word,
                    ["linuxcnc", "grbl", "grblhal", "iso"].into_iter(),
                    " ",
                )
            }
            ":run" => {
                let mut v = pairs(word, names.iter().map(String::as_str), "");
                if let Ok((_, files)) = self.files.complete_path(line, pos) {
                    v.extend(files);
                }
                v
            }
            _ => match self.files.complete_path(line, pos) {
                Ok((s, v)) => return (s, v),
                Err(_) => Vec::new(),
            },
        };
        (start, list)
    }

    fn complete_code(&self, line: &str, pos: usize) -> (usize, Vec<Pair>) {
        if in_string(line, pos) {
            return self
                .files
                .complete_path(line, pos)
                .unwrap_or((pos, Vec::new()));
        }
        let start = word_start(line, pos);
        let word = &line[start..pos];
        let before = line[..start].trim_end();
        // A unit after a number.
        if before.ends_with(|c: char| c.is_ascii_digit() || c == '.') && start > before.len() {
            let units = lase_lang::units::unit_names().chain(COMPOUND_UNITS.iter().copied());
            return (start, pairs(word, units, ""));
        }
        if before.ends_with("profile") {
            return (
                start,
                pairs(
                    word,
                    schema::PROFILE_KINDS
                        .iter()
                        .filter(|k| !k.unsupported)
                        .map(|k| k.name),
                    "",
                ),
            );
        }
        if before.ends_with(':') && before[..before.len() - 1].trim_start().starts_with("let")
            || before.ends_with("->")
        {
            return (start, pairs(word, schema::TYPE_NAMES.iter().copied(), ""));
        }
        if word.is_empty() {
            return (pos, Vec::new());
        }
        if let Some(specs) = settings_context(&line[..start]) {
            let v = pairs(word, specs.iter().map(|s| s.key), " ");
            if !v.is_empty() {
                return (start, v);
            }
        }
        let names = self.names.borrow();
        let mut v = pairs(word, schema::BUILTINS.iter().map(|b| b.name), "(");
        v.extend(pairs(word, names.iter().map(String::as_str), ""));
        v.extend(pairs(word, schema::KEYWORDS.iter().copied(), " "));
        v.extend(pairs(word, lase_runtime_stock().into_iter(), ""));
        v.sort_by(|a, b| a.display.cmp(&b.display));
        v.dedup_by(|a, b| a.display == b.display);
        (start, v)
    }
}

/// Stock machine names, completed after `machine`.
fn lase_runtime_stock() -> Vec<&'static str> {
    lase_stdlib::machine_names().collect()
}

impl Completer for LaseHelper {
    type Candidate = Pair;

    fn complete(
        &self,
        line: &str,
        pos: usize,
        _ctx: &Context<'_>,
    ) -> rustyline::Result<(usize, Vec<Pair>)> {
        // Complete within the current line of a multi-line input.
        let line_start = line[..pos].rfind('\n').map_or(0, |i| i + 1);
        let cur = &line[line_start..];
        let p = pos - line_start;
        let (s, v) = if line_start == 0 && cur.trim_start().starts_with(':') {
            self.complete_command(cur, p)
        } else {
            let (s, v) = self.complete_code(cur, p);
            // Settings lists may span lines: look at the whole input for the context.
            (s, v)
        };
        Ok((s + line_start, v))
    }
}

/// A hint shown after the cursor in grey; only command names are completed by it.
pub struct LaseHint {
    display: String,
    complete: Option<String>,
}

impl Hint for LaseHint {
    fn display(&self) -> &str {
        &self.display
    }
    fn completion(&self) -> Option<&str> {
        self.complete.as_deref()
    }
}

impl Hinter for LaseHelper {
    type Hint = LaseHint;

    fn hint(&self, line: &str, pos: usize, _ctx: &Context<'_>) -> Option<LaseHint> {
        if pos != line.len() || line.contains('\n') {
            return None;
        }
        if line.starts_with(':') {
            let (cmd, rest) = line.split_once(' ').unwrap_or((line, ""));
            let matches: Vec<_> = COMMANDS
                .iter()
                .filter(|c| c.name.starts_with(cmd))
                .collect();
            if let [c] = matches.as_slice() {
                if !rest.is_empty() || line.ends_with(' ') {
                    return None;
                }
                let tail = &c.name[cmd.len()..];
                let usage = if c.args.is_empty() {
                    String::new()
                } else {
                    format!(" {}", c.args)
                };
                return Some(LaseHint {
                    display: format!("{tail}{usage}"),
                    complete: (!tail.is_empty()).then(|| tail.to_string()),
                });
            }
            return None;
        }
        // Inside a call to a builtin: its parameters.
        let open = line.rfind('(')?;
        if line[open..].contains(')') {
            return None;
        }
        let start = word_start(line, open);
        let name = &line[start..open];
        let params = schema::builtin(name)
            .map(|b| b.params)
            .or_else(|| schema::profile_kind(name).map(|k| k.params))?;
        if line[open + 1..].trim().is_empty() {
            let sig = crate::doc::signature("", params);
            return Some(LaseHint {
                display: sig[1..].to_string(),
                complete: None,
            });
        }
        None
    }
}

const RESET: &str = "\x1b[0m";

impl Highlighter for LaseHelper {
    fn highlight<'l>(&self, line: &'l str, _pos: usize) -> Cow<'l, str> {
        if !self.color {
            return Cow::Borrowed(line);
        }
        Cow::Owned(highlight(line))
    }

    fn highlight_hint<'h>(&self, hint: &'h str) -> Cow<'h, str> {
        if !self.color {
            return Cow::Borrowed(hint);
        }
        Cow::Owned(format!("\x1b[2m{hint}{RESET}"))
    }

    fn highlight_prompt<'b, 's: 'b, 'p: 'b>(
        &'s self,
        prompt: &'p str,
        _default: bool,
    ) -> Cow<'b, str> {
        if !self.color {
            return Cow::Borrowed(prompt);
        }
        Cow::Owned(format!("\x1b[1;36m{prompt}{RESET}"))
    }

    fn highlight_char(&self, _line: &str, _pos: usize, _kind: CmdKind) -> bool {
        self.color
    }
}

/// ANSI colours for one input: keywords, builtins, numbers with their units, strings,
/// comments and REPL commands. The text itself is unchanged.
pub fn highlight(line: &str) -> String {
    let mut out = String::with_capacity(line.len() * 2);
    if line.trim_start().starts_with(':') {
        let end = line.find(char::is_whitespace).unwrap_or(line.len());
        out.push_str("\x1b[1;32m");
        out.push_str(&line[..end]);
        out.push_str(RESET);
        out.push_str(&line[end..]);
        return out;
    }
    let b = line.as_bytes();
    let mut i = 0;
    let mut after_number = false;
    while i < line.len() {
        let c = line[i..].chars().next().unwrap_or(' ');
        if line[i..].starts_with("//") {
            let end = line[i..].find('\n').map_or(line.len(), |e| i + e);
            out.push_str(&format!("\x1b[2m{}{RESET}", &line[i..end]));
            i = end;
            continue;
        }
        if c == '"' {
            let end = line[i + 1..].find('"').map_or(line.len(), |e| i + e + 2);
            out.push_str(&format!("\x1b[32m{}{RESET}", &line[i..end]));
            i = end;
            after_number = false;
            continue;
        }
        if c.is_ascii_digit() {
            let mut end = i;
            while end < line.len() && (b[end].is_ascii_digit() || b[end] == b'.') {
                end += 1;
            }
            // `0..3` is a range, not a number with a decimal point.
            if let Some(dots) = line[i..end].find("..") {
                end = i + dots;
            }
            out.push_str(&format!("\x1b[33m{}{RESET}", &line[i..end]));
            i = end.max(i + 1);
            after_number = true;
            continue;
        }
        if is_ident(c) {
            let mut end = i;
            for ch in line[i..].chars() {
                if is_ident(ch) {
                    end += ch.len_utf8();
                } else {
                    break;
                }
            }
            let mut word_end = end;
            if after_number && lase_lang::units::parse_unit(&line[i..end]).is_ok() {
                // The whole unit literal: `mm/s^2`.
                while word_end < line.len()
                    && (is_ident(b[word_end] as char)
                        || matches!(b[word_end], b'/' | b'^' | b'*' | b'-'))
                {
                    word_end += 1;
                }
                out.push_str(&format!("\x1b[36m{}{RESET}", &line[i..word_end]));
            } else {
                let w = &line[i..end];
                if schema::KEYWORDS.contains(&w) {
                    out.push_str(&format!("\x1b[1;35m{w}{RESET}"));
                } else if schema::builtin(w).is_some() || schema::profile_kind(w).is_some() {
                    out.push_str(&format!("\x1b[34m{w}{RESET}"));
                } else {
                    out.push_str(w);
                }
            }
            i = word_end;
            after_number = false;
            continue;
        }
        if !c.is_whitespace() {
            after_number = false;
        }
        out.push(c);
        i += c.len_utf8();
    }
    out
}

impl Validator for LaseHelper {
    fn validate(&self, ctx: &mut ValidationContext<'_>) -> rustyline::Result<ValidationResult> {
        let input = ctx.input();
        if input.trim_start().starts_with(':') || !is_incomplete(input) {
            Ok(ValidationResult::Valid(None))
        } else {
            Ok(ValidationResult::Incomplete)
        }
    }
}

impl Helper for LaseHelper {}

#[cfg(test)]
mod tests {
    use super::*;

    fn strip(s: &str) -> String {
        let mut out = String::new();
        let mut esc = false;
        for c in s.chars() {
            match (esc, c) {
                (false, '\x1b') => esc = true,
                (true, 'm') => esc = false,
                (true, _) => {}
                (false, c) => out.push(c),
            }
        }
        out
    }

    #[test]
    fn highlighting_keeps_the_text() {
        for l in [
            "let v = 20 mm/s^2 // fast",
            "follow offset(p, 1.5 mm) at 3000 mm/min { power 40 W }",
            "for i in 0..3 { }",
            ":run ring",
            "machine \"my.toml\"",
        ] {
            let h = highlight(l);
            assert_eq!(strip(&h), l);
            assert!(h.contains('\x1b'), "{l}");
        }
    }

    #[test]
    fn settings_lists_are_recognized() {
        assert!(settings_context("laser { po").is_some());
        assert!(settings_context("follow p at 2 mm/s { po").is_some());
        assert!(settings_context("let a = { ").is_none());
        assert!(settings_context("laser { power 2 W } ").is_none());
    }
}
