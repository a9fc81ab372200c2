//! A zigzag hatch over 120 × 180 mm as a streamed job: short modal lines, as a texturing job
//! writes them, line `i` computed from `i` alone, so nothing is kept whatever `n` is. Shared by
//! the bounded-memory test (`tests/stream_memory.rs`) and the streaming benchmark
//! (`examples/link_bench.rs`).

use lase_runtime::link::stream::Source;

#[derive(Debug)]
pub struct Zigzag {
    /// Lines in the job (at least 6: header, approach, beam on, first move, beam off, end).
    pub n: usize,
    /// The feed of the hatch, mm/min.
    pub feed_mm_min: u32,
}

impl Source for Zigzag {
    fn len(&self) -> usize {
        self.n
    }

    fn line(&self, i: usize) -> String {
        match i {
            0 => "G21 G90 G17 G94".into(),
            1 => "G0 X-60 Y-90".into(),
            2 => "M3 S300".into(),
            3 => format!("G1 X60 F{}", self.feed_mm_min),
            _ if i + 2 == self.n => "M5".into(),
            _ if i + 1 == self.n => "M2".into(),
            _ => {
                let k = i - 4;
                let y = -90.0 + (k + 1) as f64 * 180.0 / self.n as f64;
                let x = if k.is_multiple_of(2) { -60.0 } else { 60.0 };
                format!(
                    "X{} Y{}",
                    lase_runtime::emit::number(x),
                    lase_runtime::emit::number(y)
                )
            }
        }
    }
}
