//! The sampled trace: one CSV row per period of the job's timeline, streamed.

use super::pulses::pulse_events;
use super::{beam_at, fixed6};
use crate::axes;
use crate::motion::Job;
use std::io::{self, Write};

/// Writes the trace of `job` as CSV: `t,<axes>,px,py,pz,v,a,laser,power,pulses`.
///
/// Rows at t = k·period from 0, and a last row exactly at the cycle time when that is not on
/// the grid. Axis values in mm (deg for rotary axes), px/py/pz the spot in part coordinates,
/// v and a the path speed and acceleration, laser 0/1 (the beam of lit moves), power in W (0
/// when off; `P_set · v / F` when the laser is coupled to speed, PROCESS.md §1 eq. 1), pulses
/// the number of pulses fired at or before t (within 1 ns) — single pulses of dot mode, fired
/// at rest, show there and not in `laser`. At most 6 decimals.
///
/// Rows are written one at a time; wrap `out` in a `BufWriter` for files.
pub fn write_trace(job: &Job, period_s: f64, out: &mut dyn Write) -> io::Result<()> {
    if !(period_s > 0.0 && period_s.is_finite()) {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("trace period must be a positive number of seconds, got {period_s}"),
        ));
    }
    let machine = &job.program.machine;
    let mut row = String::from("t");
    for a in &machine.axes {
        row.push(',');
        row.push_str(&a.name);
    }
    row.push_str(",px,py,pz,v,a,laser,power,pulses\n");
    out.write_all(row.as_bytes())?;

    let total = job.cycle_time();
    let n = (total / period_s + 1e-9).floor() as u64;
    let off_grid = total - n as f64 * period_s > 1e-9 * total.max(1.0);
    let rows = n + 1 + u64::from(off_grid);
    let mut pulses = pulse_events(job).peekable();
    let mut fired: u64 = 0;
    for k in 0..rows {
        let t = if k > n {
            total
        } else {
            (k as f64 * period_s).min(total)
        };
        let (sample, lit, power) = beam_at(job, t);
        while pulses.peek().is_some_and(|p| p.t <= t + 1e-9) {
            pulses.next();
            fired += 1;
        }
        let spot = job.spot(&sample.pos, sample.tag);
        row.clear();
        row.push_str(&fixed6(t));
        for (i, a) in machine.axes.iter().enumerate() {
            row.push(',');
            row.push_str(&fixed6(axes::to_external(a.kind, sample.pos[i])));
        }
        for x in [spot[0], spot[1], spot[2], sample.v, sample.a] {
            row.push(',');
            row.push_str(&fixed6(x));
        }
        row.push_str(if lit { ",1," } else { ",0," });
        row.push_str(&fixed6(power));
        row.push(',');
        row.push_str(&fired.to_string());
        row.push('\n');
        out.write_all(row.as_bytes())?;
    }
    Ok(())
}
