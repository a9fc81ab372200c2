//! NC words: numbers, comments, post templates and the M words inside a line of machine-file
//! text.

use std::fmt::Write as _;

/// A number as NC text: 4 decimals (0.1 µm in mm, 0.1 ms in s), trailing zeros and a trailing
/// point trimmed, never `-0`.
pub fn number(x: f64) -> String {
    let mut s = format!("{x:.4}");
    if s.contains('.') {
        let t = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(t);
    }
    if s == "-0" { "0".to_string() } else { s }
}

/// A comment in parentheses. Parentheses inside would end it early (and nested comments are an
/// error in rs274ngc), so they become brackets; anything but printable ASCII becomes `?` (GRBL
/// and many ISO controls read 7-bit text). `max_len` bounds the whole comment, parentheses
/// included.
pub fn comment(text: &str, max_len: usize) -> String {
    let mut body: String = text
        .chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            ' '..='~' => c,
            _ => '?',
        })
        .collect();
    let room = max_len.saturating_sub(2);
    if body.len() > room {
        body.truncate(room.saturating_sub(3));
        body.push_str("...");
    }
    format!("({body})")
}

/// The placeholders a post template may use.
pub const PLACEHOLDERS: [&str; 3] = ["power", "s", "pct"];

/// Values for a template's placeholders.
#[derive(Debug, Clone, Copy)]
pub struct LaserWords {
    pub power_w: f64,
    pub max_power_w: f64,
    pub s_max: f64,
}

/// Fills `{power}` (W), `{s}` (power scaled to `s_max`) and `{pct}` (percent of max power).
/// Templates are validated before emission, so an unknown placeholder cannot occur here; it
/// would be left as written.
pub fn fill(template: &str, w: LaserWords) -> String {
    let mut out = String::with_capacity(template.len() + 8);
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let Some(close) = after.find('}') else {
            out.push_str(&rest[open..]);
            return out;
        };
        let value = match &after[..close] {
            "power" => Some(w.power_w),
            "s" => Some(w.power_w / w.max_power_w * w.s_max),
            "pct" => Some(100.0 * w.power_w / w.max_power_w),
            _ => None,
        };
        match value {
            Some(v) => {
                let _ = write!(out, "{}", number(v));
            }
            None => out.push_str(&rest[open..open + close + 2]),
        }
        rest = &after[close + 1..];
    }
    out.push_str(rest);
    out
}

/// The placeholders of a template that are not known, or a description of a broken brace.
pub fn template_problem(template: &str) -> Option<String> {
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        let after = &rest[open + 1..];
        let Some(close) = after.find('}') else {
            return Some("`{` without a closing `}`".into());
        };
        let name = &after[..close];
        if !PLACEHOLDERS.contains(&name) {
            return Some(format!("unknown placeholder `{{{name}}}`"));
        }
        rest = &after[close + 1..];
    }
    None
}

/// The M-code numbers in a line of NC text, outside comments (`(...)` and after `;`).
pub fn m_words(line: &str) -> Vec<u32> {
    let mut out = Vec::new();
    let mut depth = 0;
    let bytes = line.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b'(' => depth += 1,
            b')' => depth = (depth - 1).max(0),
            b';' if depth == 0 => break,
            b'M' | b'm' if depth == 0 => {
                let mut j = i + 1;
                while j < bytes.len() && bytes[j] == b' ' {
                    j += 1;
                }
                let start = j;
                while j < bytes.len() && bytes[j].is_ascii_digit() {
                    j += 1;
                }
                if let Ok(n) = line[start..j].parse() {
                    out.push(n);
                }
                i = j;
                continue;
            }
            _ => {}
        }
        i += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_trimmed_and_never_negative_zero() {
        assert_eq!(number(1.0), "1");
        assert_eq!(number(1.5), "1.5");
        assert_eq!(number(-0.00001), "0");
        assert_eq!(number(-0.0), "0");
        assert_eq!(number(12.34567), "12.3457");
        assert_eq!(number(-3.10), "-3.1");
        assert_eq!(number(1200.0), "1200");
        assert_eq!(number(100.0), "100");
    }

    #[test]
    fn templates_fill_power_s_and_percent() {
        let w = LaserWords {
            power_w: 25.0,
            max_power_w: 100.0,
            s_max: 1000.0,
        };
        assert_eq!(fill("M3 S{s}", w), "M3 S250");
        assert_eq!(fill("M68 E0 Q{pct}", w), "M68 E0 Q25");
        assert_eq!(fill("(P {power} W)", w), "(P 25 W)");
        assert_eq!(template_problem("M3 S{s}"), None);
        assert!(template_problem("M3 S{watts}").unwrap().contains("watts"));
        assert!(template_problem("M3 S{s").is_some());
    }

    #[test]
    fn m_words_skip_comments() {
        assert_eq!(m_words("M68 E0 Q{pct}"), vec![68]);
        assert_eq!(m_words("M64 P0 (M99 is not here) M65"), vec![64, 65]);
        assert_eq!(m_words("G4 P1 ; M7"), Vec::<u32>::new());
        assert_eq!(m_words("m3 s100"), vec![3]);
    }

    #[test]
    fn comments_are_sanitized_and_bounded() {
        assert_eq!(comment("a (b) °", 80), "(a [b] ?)");
        let c = comment(&"x".repeat(100), 20);
        assert_eq!(c.len(), 20);
        assert!(c.ends_with("...)"));
    }
}
