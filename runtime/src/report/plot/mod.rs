//! The job as a picture: the toolpath in the part plane (top, `path.rs`) and the path speed
//! over time with its limits, the laser power and the events (bottom, `speed.rs`), one
//! hand-written SVG; `png.rs` rasterizes it. Written by hand rather than through plotters:
//! every element carries an id or class that says what it shows, so tests can count pulse
//! marks and find limit lines in the document itself.
//!
//! The plan is sampled adaptively: every segment boundary, plus interior points shared out by
//! duration, within a budget of [`MAX_POINTS`]; a job with more segments than that is sampled
//! uniformly in time instead.

mod path;
mod png;
mod shade;
mod speed;
mod svg;

pub use png::{PNG_SCALE, plot_png, svg_to_png};

use super::{lit_at, segment_is_rapid, segment_laser};
use crate::motion::Job;
use std::fmt::{self, Write};
use svg::{num, xml};

/// Budget of sample points for the whole plot.
const MAX_POINTS: usize = 20_000;
/// Most interior points one segment gets (its geometry is a straight line in axis space).
const MAX_PER_SEGMENT: usize = 200;
/// Above this many pulses the toolpath shows a density view (pulses per cell of 4 × 4 px)
/// instead of one mark per pulse: past it the marks overlap into a blot and the SVG grows by
/// ~100 bytes a pulse.
pub const DOT_LIMIT: u64 = 10_000;

const WIDTH: f64 = 1040.0;
const LEFT: f64 = 72.0;
const PLOT_W: f64 = 690.0;
const TOP: f64 = 48.0;
const SPEED_H: f64 = 220.0;
const GAP: f64 = 70.0;

/// What `lase plot` draws beyond the defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlotOptions {
    /// Fit the toolpath view to everything that moves (approach, travel, overscan) instead
    /// of to the lit work.
    pub full_extent: bool,
    /// The unit of the speed axis and the colour bar.
    pub speed_unit: SpeedUnit,
}

/// The unit speeds are shown in: the one the recipe writes its feeds in.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum SpeedUnit {
    #[default]
    MmPerS,
    MmPerMin,
}

impl SpeedUnit {
    /// The speed unit a recipe speaks: mm/min when its speed literals (outside comments) are
    /// mostly per minute (`950 mm/min`, `3 m/min`), mm/s otherwise.
    pub fn of_source(text: &str) -> SpeedUnit {
        let (mut per_min, mut per_s) = (0usize, 0usize);
        for line in text.lines() {
            let code = line.split("//").next().unwrap_or_default();
            for (at, _) in code.match_indices("m/") {
                let rest = &code[at + 2..];
                if rest.starts_with("min") {
                    per_min += 1;
                } else if rest.starts_with('s')
                    && !rest[1..].starts_with(|c: char| c.is_alphanumeric() || "^²³".contains(c))
                {
                    per_s += 1;
                }
            }
        }
        if per_min > per_s {
            SpeedUnit::MmPerMin
        } else {
            SpeedUnit::MmPerS
        }
    }

    /// How many of this unit one mm/s is.
    pub fn per_mm_s(self) -> f64 {
        match self {
            SpeedUnit::MmPerS => 1.0,
            SpeedUnit::MmPerMin => 60.0,
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            SpeedUnit::MmPerS => "mm/s",
            SpeedUnit::MmPerMin => "mm/min",
        }
    }
}

/// What a piece of the path is, for its style.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Rapid,
    /// A feed move with the laser off (approach, lead, overscan, travel).
    Feed,
    /// A lit move with the beam on continuously.
    Lit,
    /// A lit move that fires pulses: the pulses are the marks, the move is travel between.
    Pulsed,
    /// A lit image row: its pixel runs are drawn shaded by power (`shade`), not by speed.
    Shaded,
}

impl Kind {
    fn lit(self) -> bool {
        matches!(self, Kind::Lit | Kind::Pulsed | Kind::Shaded)
    }
}

/// One sample of the plan.
#[derive(Debug, Clone, Copy)]
struct Pt {
    /// Job time.
    t: f64,
    /// Part-plane coordinates (x and y, or x and z).
    h: f64,
    w: f64,
    /// Path speed, mm/s.
    v: f64,
    /// Laser power, W (0 when off).
    power: f64,
    kind: Kind,
    /// Segment and time in it, to recompute the pose (beam arrows).
    seg: usize,
    t_local: f64,
}

/// What both panels need: the samples and the plane they are drawn in.
struct Ctx<'a> {
    job: &'a Job,
    opts: PlotOptions,
    pts: Vec<Pt>,
    /// Index of the part axis drawn vertically (1: y, 2: z on a machine without y).
    plane_w: usize,
    has_y: bool,
}

/// The toolpath and the speed profile of `job` as an SVG document.
pub fn plot_svg(job: &Job, opts: &PlotOptions) -> Result<String, fmt::Error> {
    let machine = &job.program.machine;
    let has_y = machine
        .axes
        .iter()
        .any(|a| a.part_axis.as_deref() == Some("y"))
        || machine.axes.iter().all(|a| a.part_axis.is_none());
    let plane_w = if has_y { 1 } else { 2 };
    let ctx = Ctx {
        job,
        opts: *opts,
        pts: sample(job, plane_w),
        plane_w,
        has_y,
    };
    let top = path::Panel::new(&ctx);
    let speed_top = TOP + top.height + GAP;
    let height = speed_top + SPEED_H + 58.0;

    let mut svg = String::with_capacity(64 * ctx.pts.len() + 8192);
    let s = &mut svg;
    writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height:.0}" viewBox="0 0 {WIDTH} {height:.0}" font-family="sans-serif" font-size="11">"#
    )?;
    writeln!(
        s,
        r##"<defs><marker id="arrow" viewBox="0 0 8 8" refX="7" refY="4" markerWidth="7" markerHeight="7" orient="auto"><path d="M0,0 L8,4 L0,8 z" fill="#5e35b1"/></marker></defs>"##
    )?;
    writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#)?;
    writeln!(
        s,
        r#"<text x="{LEFT}" y="20" font-size="13" font-weight="bold">{} on {} — cycle {} s</text>"#,
        xml(&job.program.recipe),
        xml(&machine.name),
        num(job.cycle_time())
    )?;
    top.draw(s, &ctx)?;
    speed::draw(s, &ctx, speed_top)?;
    if job.plan.segments().is_empty() {
        writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">no motion</text>"#,
            LEFT + PLOT_W / 2.0,
            TOP + top.height / 2.0
        )?;
    }
    writeln!(s, "</svg>")?;
    Ok(svg)
}

/// Samples: per segment when the budget allows, uniform in time otherwise.
fn sample(job: &Job, plane_w: usize) -> Vec<Pt> {
    let plan = &job.plan;
    let segs = plan.segments();
    let kind_of = |i: usize| {
        if segment_is_rapid(job, i) {
            Kind::Rapid
        } else {
            let row = plan.segments().get(i).is_some_and(|s| {
                job.program.ops.get(s.tag as usize).is_some_and(|o| {
                    matches!(o.kind, crate::program::OpKind::Line { row: Some(_), .. })
                })
            });
            match segment_laser(job, i) {
                Some(_) if row => Kind::Shaded,
                Some(l) if l.pulse.is_some() => Kind::Pulsed,
                Some(_) => Kind::Lit,
                None => Kind::Feed,
            }
        }
    };
    let point = |i: usize, t_local: f64| {
        let s = plan.sample_segment(i, t_local);
        let spot = job.spot(&s.pos, s.tag);
        let power = match segment_laser(job, i) {
            Some(l) if lit_at(job, i, t_local.min(segs[i].motion_duration() * 0.999_999)) => {
                let p = l.power_at(s.v, segs[i].feed);
                // An image row: its run's power under the spot, coupled to speed alike.
                match job.program.ops.get(s.tag as usize).map(|o| &o.kind) {
                    Some(crate::program::OpKind::Line { row: Some(row), .. })
                        if l.power_w > 0.0 =>
                    {
                        p / l.power_w * row.power_w_at([spot[0], spot[1]])
                    }
                    _ => p,
                }
            }
            _ => 0.0,
        };
        Pt {
            t: job.initial_dwell_s + s.t,
            h: spot[0],
            w: spot[plane_w],
            v: s.v,
            power,
            kind: kind_of(i),
            seg: i,
            t_local,
        }
    };
    let mut pts: Vec<Pt> = Vec::new();
    if segs.len() * 2 <= MAX_POINTS {
        let motion_total: f64 = segs.iter().map(|s| s.motion_duration()).sum();
        let spare = (MAX_POINTS - segs.len() * 2) as f64;
        for (i, seg) in segs.iter().enumerate() {
            let motion = seg.motion_duration();
            let share = if motion_total > 0.0 {
                motion / motion_total
            } else {
                0.0
            };
            let n = ((spare * share) as usize).min(MAX_PER_SEGMENT);
            for k in 0..=n + 1 {
                pts.push(point(i, motion * k as f64 / (n + 1) as f64));
            }
            if seg.dwell > 0.0 {
                let mut p = point(i, seg.duration());
                if !super::dwell_lit(job, i) {
                    p.power = 0.0;
                }
                pts.push(p);
            }
        }
    } else {
        let duration = plan.duration();
        for k in 0..MAX_POINTS {
            let s = plan.sample(duration * k as f64 / (MAX_POINTS - 1) as f64);
            pts.push(point(s.segment, s.t - segs[s.segment].t_start));
        }
    }
    pts
}
