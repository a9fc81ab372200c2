//! NC words: numbers, comments, post templates and the M words inside a line of machine-file
//! text.

/// A number as NC text: 4 decimals (0.1 µm in mm, 0.1 ms in s), trailing zeros and a trailing
/// point trimmed, never `-0`.
pub fn number(x: f64) -> String {
    let mut s = String::with_capacity(12);
    number_into(&mut s, x);
    s
}

/// [`number`] appended to `out`: the emitter writes every coordinate of a multi-million-line
/// program through here, into buffers it reuses, so formatting allocates nothing.
pub fn number_into(out: &mut String, x: f64) {
    // Fast path, byte for byte what `{:.4}` writes: away from a rounding tie the product
    // x·10⁴ (within an ulp of the exact value) rounds to the same integer as the exact decimal
    // expansion `{:.4}` rounds. Ties and huge values take the exact formatter.
    let y = x * 1e4;
    if y.is_finite() && y.abs() < 9e15 && ((y - y.floor()) - 0.5).abs() > 1e-6 {
        fixed4_into(out, y.round() as i64);
        return;
    }
    out.push_str(&trimmed(format!("{x:.4}")));
}

/// A fixed-point number with trailing zeros and a trailing point trimmed, never `-0`.
fn trimmed(mut s: String) -> String {
    if s.contains('.') {
        let t = s.trim_end_matches('0').trim_end_matches('.').len();
        s.truncate(t);
    }
    if s == "-0" { "0".to_string() } else { s }
}

/// A linear axis position in mm to 6 decimals (1 nm), for programs in inverse time (G93),
/// where a block's time is fixed by its F and a coordinate rounded to 0.1 µm would change a
/// short block's speed by as much as 0.1 µm over its length.
pub fn fine_number(x: f64) -> String {
    trimmed(format!("{x:.6}"))
}

/// A rotary axis position in degrees: 6 decimals, since an angle is multiplied by the lever it
/// turns (1e-6° on a 500 mm arm is 9 nm, where 1e-4° would be 0.9 µm).
pub fn degrees(x: f64) -> String {
    trimmed(format!("{x:.6}"))
}

/// An inverse-time feed (G93's F, 1/min) to at least 7 significant digits, so the block time
/// the controller derives is within 1e-6 of the planned one however long the block is.
pub fn inverse_time(x: f64) -> String {
    let digits = if x.abs() >= 1.0 {
        x.abs().log10().floor() as i32 + 1
    } else {
        0
    };
    let decimals = (7 - digits).clamp(4, 10) as usize;
    trimmed(format!("{x:.decimals$}"))
}

/// `n / 10⁴` with trailing zeros and point trimmed, never `-0`, appended to `out`.
fn fixed4_into(out: &mut String, n: i64) {
    let a = n.unsigned_abs();
    let (mut int, mut frac) = (a / 10_000, a % 10_000);
    // Digits right to left into a small buffer: sign, up to 20 integer digits, point, 4.
    let mut buf = [0u8; 27];
    let mut i = buf.len();
    let mut started = false;
    for _ in 0..4 {
        let d = (frac % 10) as u8;
        frac /= 10;
        if started || d != 0 {
            i -= 1;
            buf[i] = b'0' + d;
            started = true;
        }
    }
    if started {
        i -= 1;
        buf[i] = b'.';
    }
    loop {
        i -= 1;
        buf[i] = b'0' + (int % 10) as u8;
        int /= 10;
        if int == 0 {
            break;
        }
    }
    if n < 0 {
        i -= 1;
        buf[i] = b'-';
    }
    // Only ASCII digits, '.' and '-' were written: pushed one by one, which is cheaper for a
    // handful of bytes than a UTF-8 check and a copy call.
    out.reserve(buf.len() - i);
    for &b in &buf[i..] {
        out.push(b as char);
    }
}

/// A comment in parentheses. Parentheses inside would end it early (and nested comments are an
/// error in rs274ngc), so they become brackets; anything but printable ASCII becomes `_` (GRBL
/// and many ISO controls read 7-bit text), and so do `?`, `!` and `~`, which GRBL takes as
/// real-time commands (status, feed hold, resume) wherever they appear in the stream.
/// `max_len` bounds the whole comment, parentheses included.
pub fn comment(text: &str, max_len: usize) -> String {
    let mut body: String = text
        .chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            '?' | '!' | '~' => '_',
            ' '..='}' => c,
            _ => '_',
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
    fill_into(&mut out, template, w);
    out
}

/// [`fill`] appended to `out` (the pulse lines of a dot raster, millions of them).
pub fn fill_into(out: &mut String, template: &str, w: LaserWords) {
    let mut rest = template;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let Some(close) = after.find('}') else {
            out.push_str(&rest[open..]);
            return;
        };
        let value = match &after[..close] {
            "power" => Some(w.power_w),
            "s" => Some(w.power_w / w.max_power_w * w.s_max),
            "pct" => Some(100.0 * w.power_w / w.max_power_w),
            _ => None,
        };
        match value {
            Some(v) => number_into(out, v),
            None => out.push_str(&rest[open..open + close + 2]),
        }
        rest = &after[close + 1..];
    }
    out.push_str(rest);
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

/// Fills `{pitch}` (mm) and `{ppi}` (pulses per inch) of a PSO template (`[post.*] pso`); the
/// other placeholders are left for [`fill`].
pub fn fill_pitch(template: &str, pitch_mm: f64) -> String {
    template
        .replace("{pitch}", &number(pitch_mm))
        .replace("{ppi}", &number(25.4 / pitch_mm))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fast_number_path_writes_what_the_exact_formatter_writes() {
        let exact = |x: f64| {
            let mut s = format!("{x:.4}");
            if s.contains('.') {
                let t = s.trim_end_matches('0').trim_end_matches('.').len();
                s.truncate(t);
            }
            if s == "-0" { "0".to_string() } else { s }
        };
        let mut x = -1234.5678f64;
        let mut k = 0u64;
        while x < 1234.5678 {
            for v in [
                x,
                x * 1e-3,
                x * 37.0,
                0.1 * (k as f64),
                -0.00005 * (k as f64),
            ] {
                assert_eq!(number(v), exact(v), "{v:e}");
            }
            x += 0.0137;
            k += 1;
        }
    }

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
        assert_eq!(comment("a (b) ° ok? stop! ~", 80), "(a [b] _ ok_ stop_ _)");
        let c = comment(&"x".repeat(100), 20);
        assert_eq!(c.len(), 20);
        assert!(c.ends_with("...)"));
    }
}
