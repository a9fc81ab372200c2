//! GRBL's model of [`super::run_program`] fed a line at a time, holding what the firmware
//! holds (issue 18: `lase plan` of a job of millions of lines keeps no table per line). GRBL's
//! planner buffer is a ring of `BLOCK_BUFFER_SIZE` blocks (16; grblHAL's `planner_blocks`), and
//! its look-ahead (`planner_recalculate`) reaches no further than what that ring holds; the
//! protocol loop reads the serial stream only while a slot is free. So a block executes here as
//! soon as the blocks its look-ahead sees are in: the buffer's 15 usable blocks after it, or
//! the sync or dwell that ends the window, or the program's end. Only a wait the protocol loop
//! has not finished reading holds execution back (its length is the bytes read until the cycle
//! starts, at most a full buffer later). What is held is then at most a buffer of blocks and
//! the few items between them (each line's beam at rest), whatever the program's length.
//!
//! The arithmetic is [`super::run_program`]'s: the same reader and the same step per item, in
//! the same order; `runtime/tests/controller_stream.rs` compares every span of every example
//! and of random programs.

use super::{AxisPos, Exec, Item, Items, Limits, ModelError, Reader, Timeline, ahead};

/// GRBL's or grblHAL's model, a line at a time ([module doc](self)).
pub struct ModelStream<'a> {
    reader: Reader<'a>,
    items: Items,
    exec: Exec,
    window: usize,
    /// Keep every span and beam edge ([`Timeline::spans`], [`Timeline::edges`]), or only the
    /// totals.
    keep: bool,
}

impl<'a> ModelStream<'a> {
    /// The machine at `start`; `keep`: whether the timeline keeps its spans and edges.
    pub fn new(limits: &'a Limits, start: AxisPos, keep: bool) -> ModelStream<'a> {
        ModelStream {
            reader: Reader::new(limits, start),
            items: Items::default(),
            exec: Exec::new(start),
            window: limits.planner_blocks,
            keep,
        }
    }

    /// Reads the next line (without its newline).
    pub fn line(&mut self, raw: &str) -> Result<(), ModelError> {
        self.reader.line(raw, &mut self.items)?;
        self.run(false);
        Ok(())
    }

    /// After the last line: the executed timeline (without spans and edges unless kept).
    pub fn finish(mut self) -> Timeline {
        self.reader.finish(&mut self.items);
        self.run(true);
        self.exec.tl
    }

    /// Executes what can be: `end`, every item.
    fn run(&mut self, end: bool) {
        while let Some(front) = self.items.q.front() {
            if self.reader.waits_at(self.items.base) {
                break; // the protocol loop is still reading toward the cycle start
            }
            if let Item::Block(_) = front
                && !end
                && !self.sees_all()
            {
                break;
            }
            self.exec
                .step(front, ahead(self.items.q.iter(), self.window));
            self.items.q.pop_front();
            self.items.base += 1;
            if !self.keep {
                let tl = &mut self.exec.tl;
                // The last span stays: the next beam edge compares with its power.
                if tl.spans.len() > 1 {
                    tl.spans.drain(..tl.spans.len() - 1);
                }
                tl.edges.clear();
            }
        }
    }

    /// Whether the first item's look-ahead sees everything it will: a full buffer of blocks,
    /// or the sync or dwell that ends it.
    fn sees_all(&self) -> bool {
        let mut blocks = 0;
        for it in &self.items.q {
            match it {
                Item::Sync | Item::Dwell(_) => return true,
                Item::Block(_) => {
                    blocks += 1;
                    if blocks >= self.window {
                        return true;
                    }
                }
                _ => {}
            }
        }
        false
    }
}

impl std::fmt::Debug for ModelStream<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModelStream")
            .field("buffered", &self.items.q.len())
            .field("received", &self.items.count())
            .field("window", &self.window)
            .finish_non_exhaustive()
    }
}
