//! The job journal: an append-only text file that records, for one job, each line sent and
//! each line acknowledged, so a job whose link dropped can be continued without losing or
//! repeating a line.
//!
//! Write-ahead: before a line goes to the controller, the journal holds a `w N` record
//! ("lines below N may have been sent"), fsync'd. This is the one invariant that makes a
//! resume safe, and everything else here only decides how often it costs an fsync.
//!
//! Group commit: one synced reservation covers a window of lines, so the fsync is paid once
//! per window rather than once per line. The window adapts to the link: it starts at
//! [`RESERVE`] lines and doubles (up to [`RESERVE_MAX`]) while a window is used up in less
//! than [`FAST_WINDOW`], and falls back when one lasts longer than [`SLOW_WINDOW`]. A fast
//! link (a simulator, TCP to grblHAL: hundreds of thousands of lines per second) then syncs a
//! few hundred times a second instead of ten thousand, while a slow one (GRBL over 115 200
//! baud, a few hundred lines per second) keeps small windows, and with them a narrow range
//! for the resume logic to search after a crash. Acknowledgements are written as `a N`
//! records, one for every [`ACKS_PER_RECORD`] lines and one at every sync (the reader keeps
//! the highest, so the latest says all); no record is written per line sent, since the synced
//! reservation already bounds it (older journals' `s` records are still read).
//!
//! After a crash the journal therefore bounds what the controller may have received from
//! above (`w`, `s`) and what it surely received from below (`a`, `r`); the resume logic
//! settles the lines in between by asking the controller. When the link drops while lase
//! runs on, it knows exactly how many lines went out and says so with a `t N` record ("exactly
//! N lines were sent"), synced, which replaces the reservation's upper bound: a large window
//! costs nothing on the common path of a dropped cable.
//!
//! ```text
//! lase-journal 1
//! recipe examples/frame_marking.lase
//! link tcp://127.0.0.1:5000
//! dialect grbl
//! lines 42
//! hash 0f3a…
//! start 0 0 0
//! w 32
//! a 1023
//! …
//! t 40            the link dropped after exactly 40 lines were sent
//! r 17 6          resumed: 17 lines had run, 6 re-approach lines follow
//! p M5
//! …
//! e done          or `e error 12 20`, `e alarm 2`, `e abort`
//! ```

use super::{AxisPos, LinkError, MAX_AXES};
use std::fmt::Write as _;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Lines reserved per write-ahead record at first, and at least.
pub const RESERVE: usize = 32;

/// The largest window one synced reservation covers.
pub const RESERVE_MAX: usize = 16384;

/// A window used up faster than this doubles the next one.
pub const FAST_WINDOW: std::time::Duration = std::time::Duration::from_millis(50);

/// Acknowledgements between two `a` records: only the latest counts (the reader takes the
/// highest), so one record stands for a run of them.
const ACKS_PER_RECORD: usize = 1024;

/// A window that lasts longer than this halves the next one.
pub const SLOW_WINDOW: std::time::Duration = std::time::Duration::from_millis(200);

/// What a journal is about.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// The recipe, as given on the command line.
    pub recipe: String,
    pub link: String,
    pub dialect: String,
    pub lines: usize,
    /// FNV-1a of the program text, to refuse resuming a changed recipe.
    pub hash: u64,
    /// Work position when the job started, X Y Z A B C (written as three values when A, B
    /// and C are zero, as journals of GRBL jobs always were).
    pub start: AxisPos,
}

/// FNV-1a 64 of the lines, each followed by a newline.
pub fn program_hash<'a>(lines: impl IntoIterator<Item = &'a str>) -> u64 {
    let mut h = ProgramHash::new();
    for l in lines {
        h.add(l);
    }
    h.finish()
}

/// [`program_hash`] one line at a time, for lines that are made and dropped as they go.
#[derive(Debug, Clone, Copy)]
pub struct ProgramHash(u64);

impl Default for ProgramHash {
    fn default() -> Self {
        ProgramHash::new()
    }
}

impl ProgramHash {
    pub fn new() -> ProgramHash {
        ProgramHash(0xcbf2_9ce4_8422_2325)
    }

    pub fn add(&mut self, line: &str) {
        for b in line.bytes().chain(std::iter::once(b'\n')) {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }

    pub fn finish(self) -> u64 {
        self.0
    }
}

/// A journal read back.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub header: Header,
    /// Lines surely received: one past the highest acknowledged line or resume point.
    pub acked: usize,
    /// Lines possibly sent: one past the highest reservation or sent line.
    pub sent_bound: usize,
    /// How the job ended, if it did (`done`, `error …`, `alarm …`, `abort`).
    pub end: Option<String>,
    /// Resume points so far.
    pub resumes: Vec<usize>,
}

/// An open journal, appending.
#[derive(Debug)]
pub struct Journal {
    file: File,
    path: PathBuf,
    reserved: usize,
    /// The size of the next reservation, lines (group commit, see the module header).
    window: usize,
    /// When the last reservation was synced.
    reserved_at: Option<std::time::Instant>,
    /// The latest acknowledged line not yet in an `a` record, and how many acks since one.
    acked: Option<usize>,
    acks: usize,
    buf: String,
}

fn jerr(path: &Path, reason: impl std::fmt::Display) -> LinkError {
    LinkError::Journal {
        path: path.display().to_string(),
        reason: reason.to_string(),
        help: None,
    }
}

impl Journal {
    /// Starts a journal for a new job. An existing journal of a job that did not end is kept:
    /// it is the only record of what that job's controller received.
    pub fn create(path: &Path, header: &Header) -> Result<Journal, LinkError> {
        if path.exists() {
            match read(path) {
                Ok(st) if st.end.is_none() => {
                    return Err(LinkError::Journal {
                        path: path.display().to_string(),
                        reason: format!(
                            "an unfinished job is recorded there ({} of {} lines acknowledged)",
                            st.acked, st.header.lines
                        ),
                        help: Some(format!(
                            "continue it with `lase run --resume {}`, or delete the file to start over",
                            path.display()
                        )),
                    });
                }
                _ => {}
            }
        }
        let mut file = File::create(path).map_err(|e| jerr(path, e))?;
        let h = header;
        let n = if h.start[3..].iter().all(|v| *v == 0.0) {
            3
        } else {
            MAX_AXES
        };
        let start: Vec<String> = h.start[..n].iter().map(f64::to_string).collect();
        let text = format!(
            "lase-journal 1\nrecipe {}\nlink {}\ndialect {}\nlines {}\nhash {:016x}\nstart {}\n",
            h.recipe,
            h.link,
            h.dialect,
            h.lines,
            h.hash,
            start.join(" ")
        );
        file.write_all(text.as_bytes()).map_err(|e| jerr(path, e))?;
        file.sync_all().map_err(|e| jerr(path, e))?;
        // The directory entry too, or a crash could lose the new file.
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
            && let Ok(d) = File::open(dir)
        {
            let _ = d.sync_all();
        }
        Ok(Journal {
            file,
            path: path.to_path_buf(),
            reserved: 0,
            window: RESERVE,
            reserved_at: None,
            acked: None,
            acks: 0,
            buf: String::new(),
        })
    }

    /// Opens a journal to continue it.
    pub fn append(path: &Path) -> Result<(Journal, State), LinkError> {
        let st = read(path)?;
        // Cut a torn last record: appending after it would glue two records together.
        let bytes = std::fs::read(path).map_err(|e| jerr(path, e))?;
        let complete = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let file = OpenOptions::new()
            .append(true)
            .open(path)
            .map_err(|e| jerr(path, e))?;
        if complete < bytes.len() {
            file.set_len(complete as u64).map_err(|e| jerr(path, e))?;
        }
        Ok((
            Journal {
                file,
                path: path.to_path_buf(),
                reserved: st.sent_bound,
                window: RESERVE,
                reserved_at: None,
                acked: None,
                acks: 0,
                buf: String::new(),
            },
            st,
        ))
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    fn flush(&mut self, sync: bool) -> Result<(), LinkError> {
        if let Some(a) = self.acked.take() {
            // Before what was appended since: the records stay in the order things happened.
            let rest = std::mem::take(&mut self.buf);
            let _ = writeln!(self.buf, "a {a}");
            self.buf.push_str(&rest);
            self.acks = 0;
        }
        if !self.buf.is_empty() {
            self.file
                .write_all(self.buf.as_bytes())
                .map_err(|e| jerr(&self.path, e))?;
            self.buf.clear();
        }
        if sync {
            self.file.sync_data().map_err(|e| jerr(&self.path, e))?;
        }
        Ok(())
    }

    /// Whether a synced reservation covers line `index` already (then [`Journal::will_send`]
    /// does nothing).
    pub fn covers(&self, index: usize) -> bool {
        index < self.reserved
    }

    /// How many lines the next reservation may cover from its first line (callers look that
    /// far ahead for a line that must stop it, see [`Journal::will_send`]).
    pub fn window(&self) -> usize {
        self.window
    }

    /// Call before sending line `index`: makes sure a synced reservation covers it. The
    /// reservation stops before `limit` (a line the resume logic needs kept out of any
    /// window until earlier lines are acknowledged, see [`super::resume::send_guards`]).
    ///
    /// The `w` record is written and fsync'd before this returns, so no line is ever sent
    /// that a journal on disk does not cover (see the module header).
    pub fn will_send(&mut self, index: usize, limit: usize) -> Result<(), LinkError> {
        if index < self.reserved {
            return Ok(());
        }
        let now = std::time::Instant::now();
        if let Some(t) = self.reserved_at {
            let lasted = now.duration_since(t);
            if lasted < FAST_WINDOW {
                self.window = (self.window * 2).min(RESERVE_MAX);
            } else if lasted > SLOW_WINDOW {
                self.window = (self.window / 2).max(RESERVE);
            }
        }
        self.reserved = (index + self.window).min(limit).max(index + 1);
        let _ = writeln!(self.buf, "w {}", self.reserved);
        self.flush(true)?;
        self.reserved_at = Some(std::time::Instant::now());
        Ok(())
    }

    /// Line `index` went out. Nothing is written: the synced reservation that had to cover
    /// it (see [`Journal::will_send`]) bounds it already.
    pub fn sent(&mut self, index: usize) {
        debug_assert!(
            self.covers(index),
            "line {index} sent outside a reservation"
        );
    }

    /// Line `index` was acknowledged: recorded with the next `a` record (see the module
    /// header), written to the file every [`ACKS_PER_RECORD`] lines.
    pub fn acked(&mut self, index: usize) {
        self.acked = Some(self.acked.map_or(index, |a| a.max(index)));
        self.acks += 1;
        if self.acks >= ACKS_PER_RECORD {
            let _ = self.flush(false);
        }
    }

    /// Records that exactly `count` lines were sent (the link dropped while lase went on
    /// running) and syncs: the resume logic then searches `[acked, count]` instead of up to
    /// the end of the last reservation.
    pub fn settle(&mut self, count: usize) -> Result<(), LinkError> {
        let _ = writeln!(self.buf, "t {count}");
        // The journal on disk covers no line past `count` now: any further line needs a new
        // reservation.
        self.reserved = count;
        self.flush(true)
    }

    /// Records a resume: `executed` lines had run; the re-approach lines follow.
    pub fn resumed(&mut self, executed: usize, preamble: &[String]) -> Result<(), LinkError> {
        self.buf
            .push_str(&format!("r {executed} {}\n", preamble.len()));
        for p in preamble {
            self.buf.push_str(&format!("p {p}\n"));
        }
        self.flush(true)
    }

    /// Records how the job ended and syncs.
    pub fn finish(&mut self, how: &str) -> Result<(), LinkError> {
        self.buf.push_str(&format!("e {how}\n"));
        self.flush(true)
    }

    /// Writes and syncs what is buffered.
    pub fn sync(&mut self) -> Result<(), LinkError> {
        self.flush(true)
    }
}

impl Drop for Journal {
    fn drop(&mut self) {
        let _ = self.flush(true);
    }
}

/// Reads a journal. A torn last record (a crash mid-write) is ignored.
pub fn read(path: &Path) -> Result<State, LinkError> {
    let text = std::fs::read(path).map_err(|e| jerr(path, e))?;
    let text = String::from_utf8_lossy(&text);
    let complete = match text.rfind('\n') {
        Some(i) => &text[..=i],
        None => "",
    };
    let mut lines = complete.lines();
    let bad = |what: &str| LinkError::Journal {
        path: path.display().to_string(),
        reason: format!("not a lase journal ({what})"),
        help: Some("give the journal file `lase run` wrote for the job".into()),
    };
    if lines.next() != Some("lase-journal 1") {
        return Err(bad("first line"));
    }
    let mut field = |name: &str| -> Result<String, LinkError> {
        lines
            .next()
            .and_then(|l| l.strip_prefix(name))
            .and_then(|l| l.strip_prefix(' '))
            .map(str::to_string)
            .ok_or_else(|| bad(name))
    };
    let recipe = field("recipe")?;
    let link = field("link")?;
    let dialect = field("dialect")?;
    let n: usize = field("lines")?.parse().map_err(|_| bad("lines"))?;
    let hash = u64::from_str_radix(&field("hash")?, 16).map_err(|_| bad("hash"))?;
    let start: Vec<f64> = field("start")?
        .split_whitespace()
        .filter_map(|v| v.parse().ok())
        .collect();
    if !(3..=MAX_AXES).contains(&start.len()) {
        return Err(bad("start"));
    }
    let start: AxisPos = std::array::from_fn(|i| start.get(i).copied().unwrap_or(0.0));
    let mut st = State {
        header: Header {
            recipe,
            link,
            dialect,
            lines: n,
            hash,
            start,
        },
        acked: 0,
        sent_bound: 0,
        end: None,
        resumes: Vec::new(),
    };
    for l in lines {
        let (tag, rest) = l.split_once(' ').unwrap_or((l, ""));
        let num = || {
            rest.split_whitespace()
                .next()
                .and_then(|v| v.parse::<usize>().ok())
        };
        match tag {
            "w" => st.sent_bound = st.sent_bound.max(num().ok_or_else(|| bad(l))?),
            "s" => st.sent_bound = st.sent_bound.max(num().ok_or_else(|| bad(l))? + 1),
            // Exact: every reservation before it is settled.
            "t" => st.sent_bound = num().ok_or_else(|| bad(l))?,
            "a" => st.acked = st.acked.max(num().ok_or_else(|| bad(l))? + 1),
            "r" => {
                let k = num().ok_or_else(|| bad(l))?;
                st.acked = st.acked.max(k);
                st.resumes.push(k);
                st.end = None;
            }
            "p" => {}
            "e" => st.end = Some(rest.to_string()),
            _ => return Err(bad(l)),
        }
    }
    st.sent_bound = st.sent_bound.clamp(st.acked, n);
    Ok(st)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn journal_round_trips_and_survives_a_torn_record() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("job.journal");
        let header = Header {
            recipe: "r.lase".into(),
            link: "sim".into(),
            dialect: "grbl".into(),
            lines: 100,
            hash: program_hash(["G0 X1", "M2"]),
            start: [0.0, 1.5, 0.0, 0.0, 0.0, 0.0],
        };
        {
            let mut j = Journal::create(&path, &header).unwrap();
            for i in 0..10 {
                j.will_send(i, usize::MAX).unwrap();
                j.sent(i);
            }
            for i in 0..7 {
                j.acked(i);
            }
            j.sync().unwrap();
        }
        let st = read(&path).unwrap();
        assert_eq!(st.header, header);
        assert!(
            std::fs::read_to_string(&path)
                .unwrap()
                .contains("\nstart 0 1.5 0\n")
        );
        assert_eq!((st.acked, st.sent_bound, st.end.clone()), (7, 32, None));
        // A new job must not overwrite an unfinished one.
        assert!(Journal::create(&path, &header).is_err());
        std::fs::OpenOptions::new()
            .append(true)
            .open(&path)
            .unwrap()
            .write_all(b"a 9")
            .unwrap();
        assert_eq!(read(&path).unwrap().acked, 7);
        let (mut j, _) = Journal::append(&path).unwrap();
        j.resumed(8, &["M5".into()]).unwrap();
        j.finish("done").unwrap();
        drop(j);
        let st = read(&path).unwrap();
        assert_eq!((st.acked, st.end.as_deref()), (8, Some("done")));
    }

    #[test]
    fn windows_grow_on_a_fast_link_and_a_drop_settles_the_exact_count() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("fast.journal");
        let header = Header {
            recipe: "r.lase".into(),
            link: "sim".into(),
            dialect: "grbl".into(),
            lines: 100_000,
            hash: 1,
            start: [0.0; MAX_AXES],
        };
        let mut j = Journal::create(&path, &header).unwrap();
        let sent = 20_000;
        for i in 0..sent {
            j.will_send(i, usize::MAX).unwrap();
            assert!(
                j.covers(i),
                "line {i} is sent only under a synced reservation"
            );
            j.sent(i);
        }
        j.sync().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let syncs = text.lines().filter(|l| l.starts_with("w ")).count();
        // 32 lines per sync would be 625 syncs; windows that double to 4096 need far fewer.
        assert!(syncs < 40, "{syncs} reservations for {sent} lines");
        let st = read(&path).unwrap();
        assert!(st.sent_bound >= sent && st.sent_bound <= sent + RESERVE_MAX);
        // The link drops: the exact count replaces the reservation's bound.
        j.settle(sent).unwrap();
        assert_eq!(read(&path).unwrap().sent_bound, sent);
        // Limits still stop a reservation (a guarded line).
        j.will_send(sent, sent + 3).unwrap();
        assert!(j.covers(sent + 2) && !j.covers(sent + 3));
    }

    #[test]
    fn a_rotary_start_position_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cam.journal");
        let header = Header {
            recipe: "cam.lase".into(),
            link: "sim".into(),
            dialect: "grblhal".into(),
            lines: 3,
            hash: 1,
            start: [12.5, 0.0, 0.0, 0.0, -30.25, 720.0],
        };
        drop(Journal::create(&path, &header).unwrap());
        assert_eq!(read(&path).unwrap().header, header);
    }
}
