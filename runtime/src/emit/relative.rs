//! Settled rows written relative to their settled start (issue 15, PROCESS.md §3).
//!
//! A live link settles a row start (`link::settle`) with jogs, which leave the controller's
//! parser at the corrected position. A row written in absolute coordinates would then take the
//! correction back with its first move: the controller counts from the programmed start, and
//! the table's error is with the table again. So the lines of a settled row (the ops after its
//! settle op up to its end, `Settle::end`) go out in `G91`, each axis word the increment from
//! the word before, and `G90` follows the row: the row runs from wherever the settle left it,
//! and its spots keep their pitch exactly (increments of the 4-decimal words the emitter
//! wrote, so they sum to the same absolute positions).
//!
//! Out of the row the program stays absolute and untouched, except that the first motion
//! line after a row names every axis the emitter had left out: in `G90` a word left out
//! means "stay", which would carry the correction into the next move.
//!
//! Only for a live link (`EmitOptions::live`): an NC file cannot settle (`validate`), and the
//! rewrite runs on the text as written, after the emitter, so no code path of the writer
//! needs to know about it.

use super::format;
use super::{EmitStats, NcLine};
use crate::program::ProcessProgram;
use std::io;

/// Words that carry axis letters that are not a target position: the line is passed on
/// without reading its axis words (lase writes none of these inside a row).
const NOT_A_TARGET: [&str; 5] = ["G10", "G92", "G53", "G28", "G30"];

/// The rewriting sink: rows in `G91`, the rest as written.
pub(super) struct Rows<'s> {
    sink: &'s mut dyn FnMut(&NcLine) -> io::Result<()>,
    /// The ops of each settled row, `start .. end`, in op order.
    rows: Vec<(u32, u32)>,
    next: usize,
    inside: bool,
    /// After a row: the next motion line names every axis.
    fill: bool,
    /// Axis letters of the machine, and the last absolute value of each, in 1e-4 mm (deg).
    letters: Vec<char>,
    last: Vec<Option<i64>>,
    line: NcLine,
    /// Lines and bytes added, for the emitter's statistics.
    added_lines: u64,
    added_bytes: i64,
}

impl<'s> Rows<'s> {
    /// The rewriting of `program`'s lines into `sink`; `rows` are its [`row_ranges`].
    pub(super) fn new(
        program: &ProcessProgram,
        rows: Vec<(u32, u32)>,
        sink: &'s mut dyn FnMut(&NcLine) -> io::Result<()>,
    ) -> Rows<'s> {
        let letters: Vec<char> = program
            .machine
            .axes
            .iter()
            .filter_map(|a| {
                let mut c = a.name.chars();
                match (c.next(), c.next()) {
                    (Some(l), None) => Some(l.to_ascii_uppercase()),
                    _ => None,
                }
            })
            .collect();
        Rows {
            sink,
            rows,
            next: 0,
            inside: false,
            fill: false,
            last: vec![None; letters.len()],
            letters,
            line: NcLine {
                text: String::with_capacity(128),
                op: None,
            },
            added_lines: 0,
            added_bytes: 0,
        }
    }

    /// Whether op `op` is in a settled row.
    fn in_row(&mut self, op: Option<u32>) -> bool {
        let Some(op) = op else { return false };
        while self.rows.get(self.next).is_some_and(|r| r.1 <= op) {
            self.next += 1;
        }
        self.rows.get(self.next).is_some_and(|r| r.0 <= op)
    }

    fn insert(&mut self, text: &str, op: Option<u32>) -> io::Result<()> {
        self.line.text.clear();
        self.line.text.push_str(text);
        self.line.op = op;
        self.added_lines += 1;
        self.added_bytes += text.len() as i64 + 1;
        (self.sink)(&self.line)
    }

    /// Passes one line of the emitter on, rewritten where it belongs to a settled row.
    pub(super) fn put(&mut self, l: &NcLine) -> io::Result<()> {
        let row = self.in_row(l.op);
        if row && !self.inside {
            self.insert("G91", l.op)?;
            self.inside = true;
        } else if !row && self.inside {
            self.insert("G90", l.op)?;
            self.inside = false;
            self.fill = true;
        }
        let text = self.rewrite(&l.text);
        self.added_bytes += text.len() as i64 - l.text.len() as i64;
        self.line.text = text;
        self.line.op = l.op;
        (self.sink)(&self.line)
    }

    /// The line in the current mode: increments inside a row; outside, the absolute line
    /// (with the words a row left out, on the first motion after it).
    fn rewrite(&mut self, text: &str) -> String {
        if text.starts_with('(') || NOT_A_TARGET.iter().any(|w| has_word(text, w)) {
            return text.to_string();
        }
        let mut out = String::with_capacity(text.len() + 16);
        let mut seen = vec![false; self.letters.len()];
        let mut last_axis_end = None;
        let mut comment = false;
        for tok in text.split(' ') {
            if !out.is_empty() {
                out.push(' ');
            }
            comment |= tok.starts_with('(');
            let axis = (!comment)
                .then(|| self.axis_word(tok))
                .flatten()
                .filter(|(k, _)| !seen[*k]);
            let Some((k, ticks)) = axis else {
                out.push_str(tok);
                continue;
            };
            seen[k] = true;
            match (self.inside, self.last[k]) {
                (true, Some(prev)) => {
                    out.push(self.letters[k]);
                    format::number_into(&mut out, (ticks - prev) as f64 * 1e-4);
                }
                // Unknown before (no motion yet): cannot happen in a row, whose entry move
                // named every axis; passed on as written.
                _ => out.push_str(tok),
            }
            self.last[k] = Some(ticks);
            last_axis_end = Some(out.len());
        }
        if self.fill
            && let Some(at) = last_axis_end
        {
            let mut missing = String::new();
            for (k, l) in self.letters.iter().enumerate() {
                if let (false, Some(v)) = (seen[k], self.last[k]) {
                    missing.push(' ');
                    missing.push(*l);
                    format::number_into(&mut missing, v as f64 * 1e-4);
                }
            }
            out.insert_str(at, &missing);
            self.fill = false;
        }
        out
    }

    /// An axis word `X1.2345`: its axis index and value in 1e-4 units.
    fn axis_word(&self, tok: &str) -> Option<(usize, i64)> {
        let mut c = tok.chars();
        let l = c.next()?.to_ascii_uppercase();
        let k = self.letters.iter().position(|&a| a == l)?;
        let v: f64 = c.as_str().parse().ok().filter(|v: &f64| v.is_finite())?;
        Some((k, (v * 1e4).round() as i64))
    }

    /// Ends the program's rewriting: the statistics count the lines as they went out.
    pub(super) fn finish(self, stats: &mut EmitStats) {
        stats.lines += self.added_lines;
        stats.bytes = (stats.bytes as i64 + self.added_bytes).max(0) as u64;
    }
}

/// The ops of each settled row of `program` (`start .. end`, in op order); empty when it
/// settles none, and its lines then go out as written.
pub(super) fn row_ranges(program: &ProcessProgram) -> Vec<(u32, u32)> {
    program
        .settles
        .iter()
        .filter(|s| s.end > s.op + 1)
        .map(|s| (s.op as u32 + 1, s.end as u32))
        .collect()
}

/// Whether `text` has the word `w` (e.g. `G10`, not `G100`) outside comments.
fn has_word(text: &str, w: &str) -> bool {
    text.split(' ')
        .take_while(|t| !t.starts_with('('))
        .any(|t| t.eq_ignore_ascii_case(w))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(ranges: Vec<(u32, u32)>, lines: &[(&str, Option<u32>)]) -> Vec<String> {
        let mut out = Vec::new();
        let mut sink = |l: &NcLine| {
            out.push(l.text.clone());
            Ok(())
        };
        let mut r = Rows {
            sink: &mut sink,
            rows: ranges,
            next: 0,
            inside: false,
            fill: false,
            letters: vec!['X', 'Y', 'Z'],
            last: vec![None; 3],
            line: NcLine {
                text: String::new(),
                op: None,
            },
            added_lines: 0,
            added_bytes: 0,
        };
        for (t, op) in lines {
            r.put(&NcLine {
                text: t.to_string(),
                op: *op,
            })
            .unwrap();
        }
        out
    }

    #[test]
    fn a_row_goes_out_in_increments_between_g91_and_g90() {
        let out = rows(
            vec![(2, 4)],
            &[
                ("G21 G90 G17 G94", None),
                ("G0 X0 Y0 Z0", Some(0)),
                ("G1 X-0.1 Y0.2 F1200 S0", Some(1)),
                ("(row)", Some(2)),
                ("G1 X0.0999 S1000", Some(2)),
                ("X0.3", Some(3)),
                ("G0 X2.5", Some(4)),
                ("G1 X2.6 F600", Some(5)),
                ("M2", None),
            ],
        );
        assert_eq!(
            out,
            [
                "G21 G90 G17 G94",
                "G0 X0 Y0 Z0",
                "G1 X-0.1 Y0.2 F1200 S0",
                "G91",
                "(row)",
                "G1 X0.1999 S1000",
                "X0.2001",
                "G90",
                // The first move after the row names the axes it left out.
                "G0 X2.5 Y0.2 Z0",
                "G1 X2.6 F600",
                "M2",
            ]
        );
    }

    #[test]
    fn lines_whose_axis_words_are_not_targets_pass_as_written() {
        let out = rows(
            vec![(1, 2)],
            &[
                ("G10 L20 P1 X5 Y5", None),
                ("G1 X1 Y1 Z0", Some(0)),
                ("G1 X2 Y1", Some(1)),
                ("M2", None),
            ],
        );
        assert_eq!(
            out,
            [
                "G10 L20 P1 X5 Y5",
                "G1 X1 Y1 Z0",
                "G91",
                "G1 X1 Y0",
                "G90",
                "M2"
            ]
        );
        assert!(has_word("G10 L20 P1", "G10") && !has_word("G100", "G10"));
        assert!(has_word("G53 G0 X1", "G53") && !has_word("(G53)", "G53"));
    }
}
