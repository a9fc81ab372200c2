//! Source files and spans.
//!
//! Every file of a recipe (the main file and each import) lives in one [`SourceMap`] and owns a
//! range of one global offset space, as rustc's source map does. A [`Span`] is a range in that
//! space, so it names its file without carrying one, the process program can carry spans as
//! two integers, and the whole map is handed to miette once as the source of every diagnostic.

use miette::{MietteSpanContents, SourceCode, SourceSpan, SpanContents};
use serde::{Deserialize, Serialize};

/// A byte range in the global offset space of a [`SourceMap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct Span {
    pub start: u32,
    pub end: u32,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Span {
        Span {
            start: start as u32,
            end: end.max(start) as u32,
        }
    }

    /// The smallest span covering both.
    pub fn to(self, other: Span) -> Span {
        Span {
            start: self.start.min(other.start),
            end: self.end.max(other.end),
        }
    }

    pub fn len(self) -> usize {
        (self.end - self.start) as usize
    }

    pub fn is_empty(self) -> bool {
        self.start == self.end
    }
}

impl From<Span> for SourceSpan {
    fn from(s: Span) -> SourceSpan {
        SourceSpan::new((s.start as usize).into(), s.len())
    }
}

/// Index of a file in a [`SourceMap`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct FileId(pub u32);

#[derive(Debug, Clone)]
struct SourceFile {
    name: String,
    text: String,
    base: usize,
    /// Byte offset of each line's first byte, so [`SourceMap::locate`] takes a binary search
    /// instead of a scan from the start of the file (emitting locates every op: a scan made
    /// a large recipe's emit quadratic).
    line_starts: Vec<usize>,
    /// Whether the text is ASCII: then a column is a byte difference, not a count of chars.
    ascii: bool,
}

/// All source text of one recipe: the main file and its imports.
#[derive(Debug, Clone, Default)]
pub struct SourceMap {
    files: Vec<SourceFile>,
}

/// A 1-based line and column (in characters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineCol {
    pub line: usize,
    pub col: usize,
}

impl SourceMap {
    pub fn new() -> SourceMap {
        SourceMap::default()
    }

    /// Adds a file; its offsets start one past the end of the previous file so that no offset
    /// (not even an end-of-file span) is shared by two files.
    pub fn add(&mut self, name: impl Into<String>, text: impl Into<String>) -> FileId {
        let base = self
            .files
            .last()
            .map(|f| f.base + f.text.len() + 1)
            .unwrap_or(0);
        let text: String = text.into();
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        self.files.push(SourceFile {
            name: name.into(),
            ascii: text.is_ascii(),
            text,
            base,
            line_starts,
        });
        FileId(self.files.len() as u32 - 1)
    }

    pub fn name(&self, file: FileId) -> &str {
        &self.files[file.0 as usize].name
    }

    pub fn text(&self, file: FileId) -> &str {
        &self.files[file.0 as usize].text
    }

    /// The global offset of the first byte of `file`.
    pub fn base(&self, file: FileId) -> usize {
        self.files[file.0 as usize].base
    }

    pub fn files(&self) -> impl Iterator<Item = FileId> + '_ {
        (0..self.files.len() as u32).map(FileId)
    }

    /// Finds a file by name (used to avoid importing one file twice).
    pub fn find(&self, name: &str) -> Option<FileId> {
        self.files
            .iter()
            .position(|f| f.name == name)
            .map(|i| FileId(i as u32))
    }

    /// The file a global offset falls in.
    pub fn file_of(&self, offset: usize) -> Option<FileId> {
        let i = self.files.partition_point(|f| f.base <= offset);
        if i == 0 {
            return None;
        }
        let f = &self.files[i - 1];
        (offset <= f.base + f.text.len()).then_some(FileId(i as u32 - 1))
    }

    /// The source text a span covers.
    pub fn snippet(&self, span: Span) -> &str {
        match self.file_of(span.start as usize) {
            Some(id) => {
                let f = &self.files[id.0 as usize];
                let s = span.start as usize - f.base;
                let e = (span.end as usize - f.base).min(f.text.len());
                f.text.get(s..e).unwrap_or("")
            }
            None => "",
        }
    }

    /// File, line and column of a span's start.
    pub fn locate(&self, span: Span) -> Option<(FileId, LineCol)> {
        let id = self.file_of(span.start as usize)?;
        let f = &self.files[id.0 as usize];
        let local = span.start as usize - f.base;
        let local = local.min(f.text.len());
        let line = f.line_starts.partition_point(|&start| start <= local);
        let line_start = f.line_starts[line - 1];
        let col = if f.ascii {
            local - line_start
        } else {
            f.text
                .get(line_start..local)
                .map_or(local - line_start, |l| l.chars().count())
        } + 1;
        Some((id, LineCol { line, col }))
    }

    /// `file:line:col` of a span, for plain-text messages and NC comments.
    pub fn describe(&self, span: Span) -> String {
        match self.locate(span) {
            Some((id, lc)) => format!("{}:{}:{}", self.name(id), lc.line, lc.col),
            None => "<unknown>".to_string(),
        }
    }
}

impl SourceCode for SourceMap {
    fn read_span<'a>(
        &'a self,
        span: &SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'a> + 'a>, miette::MietteError> {
        let id = self
            .file_of(span.offset())
            .ok_or(miette::MietteError::OutOfBounds)?;
        let f = &self.files[id.0 as usize];
        let local = SourceSpan::new((span.offset() - f.base).into(), span.len());
        if let Some(window) = long_line_window(f, local.offset(), local.len()) {
            return Ok(window);
        }
        let inner = f
            .text
            .read_span(&local, context_lines_before, context_lines_after)?;
        // The renderer places labels relative to the contents' span, so hand it back in global
        // coordinates.
        let global = SourceSpan::new((inner.span().offset() + f.base).into(), inner.span().len());
        Ok(Box::new(MietteSpanContents::new_named(
            f.name.clone(),
            inner.data(),
            global,
            inner.line(),
            inner.column(),
            inner.line_count(),
        )))
    }
}

/// How many bytes of a line a diagnostic shows. A generated recipe may hold a whole program on
/// one line; shown whole, it floods the terminal, and a label thousands of columns in is more
/// than the renderer can pad (it panics past 65 535).
const MAX_SHOWN_LINE: usize = 160;

/// For a span on (or next to) a line longer than [`MAX_SHOWN_LINE`]: that part of its line
/// around the span's start, without context lines, still numbered by its true line and column.
fn long_line_window<'a>(
    f: &'a SourceFile,
    start: usize,
    len: usize,
) -> Option<Box<dyn SpanContents<'a> + 'a>> {
    let text = &f.text;
    let start = start.min(text.len());
    let line_start = text[..start].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[start..].find('\n').map_or(text.len(), |i| start + i);
    // A long neighbour would be shown as context: that counts as long too.
    let prev = text[..line_start.saturating_sub(1)]
        .rfind('\n')
        .map_or(0, |i| i + 1);
    let next_end = text[(line_end + 1).min(text.len())..]
        .find('\n')
        .map_or(text.len(), |i| line_end + 1 + i);
    if line_end - line_start <= MAX_SHOWN_LINE
        && line_start.saturating_sub(prev) <= MAX_SHOWN_LINE + 1
        && next_end.saturating_sub(line_end) <= MAX_SHOWN_LINE + 1
    {
        return None;
    }
    let floor = |mut i: usize| {
        while !text.is_char_boundary(i) {
            i -= 1;
        }
        i
    };
    let from = floor(start.saturating_sub(MAX_SHOWN_LINE / 4).max(line_start));
    let to = floor(
        (from + MAX_SHOWN_LINE)
            .min(line_end)
            .max(start + len.min(MAX_SHOWN_LINE)),
    )
    .min(line_end);
    let line = f.line_starts.partition_point(|&l| l <= line_start) - 1;
    // miette takes the header's `line:col` from these: the span's own column, not the window's.
    let column = text[line_start..start].chars().count();
    Some(Box::new(MietteSpanContents::new_named(
        f.name.clone(),
        &text.as_bytes()[from..to],
        SourceSpan::new((f.base + from).into(), to - from),
        line,
        column,
        1,
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_counts_lines_and_characters() {
        let mut map = SourceMap::new();
        let a = map.add("a.lase", "ab\ncd\n\nµx y");
        let b = map.add("b.lase", "one\ntwo");
        let at = |file, local: usize| {
            let s = map.base(file) + local;
            map.locate(Span::new(s, s))
                .map(|(f, lc)| (f, lc.line, lc.col))
        };
        assert_eq!(at(a, 0), Some((a, 1, 1)));
        assert_eq!(at(a, 2), Some((a, 1, 3)));
        assert_eq!(at(a, 3), Some((a, 2, 1)));
        assert_eq!(at(a, 6), Some((a, 3, 1)));
        // `µ` is two bytes and one column.
        assert_eq!(at(a, 10), Some((a, 4, 3)));
        assert_eq!(at(a, 11), Some((a, 4, 4)));
        // The end of the file is a position too.
        assert_eq!(at(a, 12), Some((a, 4, 5)));
        assert_eq!(at(b, 5), Some((b, 2, 2)));
        assert_eq!(
            map.describe(Span::new(map.base(b) + 7, map.base(b) + 7)),
            "b.lase:2:4"
        );
    }
}
