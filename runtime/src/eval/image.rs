//! `scan image`: the recipe side of image engraving (the pixels and the path are in
//! `crate::raster::image`). Binds the settings (`schema::IMAGE_SCAN`), reads the file through
//! the host (the compile pipeline's `Files`, with its IO limits), decodes it under the pixel
//! limit, places it by `width`/`height` or `dpi` at `origin`, takes the overscan from the
//! planner's ramps as `scan raster` does, and appends the ops: per row one lit `Line` carrying
//! its runs of equal pixels as a `PixelRow` (a white run inside the row at 0 W, so the row is
//! one lit section at speed and the lead-ins or the overscan extend only its ends). The emitter
//! writes a block per run; the runs count against `MAX_RUNS`, the row as one op.
//!
//! The beam's power follows the speed (`Coupling::Speed`): GRBL and grblHAL get `M4` with an
//! `S` word per block (LaserGRBL's and LightBurn's setting for rasters, so a feed hold or a
//! junction slowdown does not burn darker), LinuxCNC an `M67` per block, synchronized with
//! motion. Pulse settings do not apply: the power per block is the modulation.

use super::{Cx, EvalError, Evaluator, Kind, R, Value, bad, type_err};
use crate::geometry::V2;
use crate::program::*;
use crate::raster::image::{self as img, Dither, ImageLayout, ImageStep, Mapping, Mode};
use crate::raster::{Frame, Order};
use lase_lang::Span;
use lase_lang::ast::*;
use lase_lang::units::{Dim, format_quantity};
use std::sync::Arc;

/// The settings of one `scan image` statement, bound and converted.
struct ImageSet {
    speed: Option<(f64, Span)>,
    angle: f64,
    order: Order,
    passes: u32,
    overscan: Option<(f64, Span)>,
    origin: V2,
    width: Option<(f64, Span)>,
    height: Option<(f64, Span)>,
    dpi: Option<(f64, Span)>,
    min_power: Option<(f64, Span)>,
    mode: &'static str,
    dither: Dither,
    gamma: f64,
    threshold: f64,
    invert: bool,
    line_offset: f64,
}

impl Evaluator {
    pub(super) fn scan_image(
        &mut self,
        file: &Expr,
        settings: &[Setting],
        span: Span,
        cx: &mut Cx,
    ) -> R<()> {
        self.need_machine(span)?;
        let set = self.image_settings(settings, cx)?;
        let laser_keys: Vec<Setting> = settings
            .iter()
            .filter(|s| matches!(s.key.name.as_str(), "power" | "spot"))
            .cloned()
            .collect();
        let ls = self.laser_settings(&laser_keys, cx)?;
        let laser = self.current_laser(span, &ls)?;
        let max_w = laser.power_w;
        let min_w = set.min_power.map_or(0.0, |m| m.0);
        if let Some((m, sp)) = set.min_power
            && !(m >= 0.0 && m <= max_w)
        {
            return Err(bad(
                Kind::OutOfRange,
                sp,
                &format!(
                    "`min_power` {} is outside 0 .. the scan's power {}",
                    format_quantity(m, Dim::POWER),
                    format_quantity(max_w, Dim::POWER)
                ),
                "out of range",
                Some("give a `min_power` between 0 W and `power` (the darkest pixels' power)"),
            ));
        }
        let (speed, speed_span) = set.speed.ok_or_else(|| {
            bad(
                Kind::MissingSetting,
                span,
                "`scan image` needs a `speed`",
                "no speed",
                Some("add the table speed along the rows, e.g. `speed 100 mm/s`"),
            )
        })?;
        if !(speed > 0.0 && speed.is_finite()) {
            return Err(bad(
                Kind::NotPositive,
                speed_span,
                "the scan speed must be greater than zero",
                "not positive",
                None,
            ));
        }
        self.in_range(speed, &super::bounds::FEED, "the scan speed", speed_span)?;

        // The file, through the host's IO limits, then the decoder's pixel limit.
        let path = match self.expr(file, cx)? {
            Value::Str(s) => s,
            other => {
                return Err(type_err(
                    "a string (a PNG or JPEG file's path)",
                    &other,
                    file.span,
                    "the image of `scan image`",
                ));
            }
        };
        let importer = cx
            .map
            .file_of(span.start as usize)
            .map(|f| cx.map.name(f).to_string())
            .unwrap_or_default();
        let image_error = |message: String, label: &str, help: &str| EvalError::Image {
            message,
            span: file.span,
            label: label.into(),
            help: Some(help.into()),
        };
        let (_, bytes) = cx.host.binary_file(&importer, &path).map_err(|reason| {
            image_error(
                format!("cannot read \"{path}\": {reason}"),
                "this file",
                "paths are relative to the recipe's folder",
            )
        })?;
        let gray = img::decode(&bytes).map_err(|e| {
            let help = match e {
                img::ImageError::TooLarge { .. } => {
                    "scale the image down: an engraving needs one pixel per scan line and spot"
                }
                img::ImageError::Format => "save the image as PNG or JPEG",
                _ => "open and save the file again with an image editor",
            };
            image_error(format!("\"{path}\": {e}"), "this image", help)
        })?;

        // Placement: pixel size from the width, the height or the dpi.
        let (w, h) = (f64::from(gray.w), f64::from(gray.h));
        let (px, py) = match (set.width, set.height, set.dpi) {
            (Some(_), _, Some((_, sp))) | (_, Some(_), Some((_, sp))) => {
                return Err(bad(
                    Kind::Conflict,
                    sp,
                    "`dpi` and a size place the image twice",
                    "a second placement",
                    Some("give the size (`width`, `height`) or the `dpi`, not both"),
                ));
            }
            (Some((wd, _)), Some((ht, _)), None) => (wd / w, ht / h),
            (Some((wd, _)), None, None) => (wd / w, wd / w),
            (None, Some((ht, _)), None) => (ht / h, ht / h),
            (None, None, Some((dpi, _))) => (25.4 / dpi, 25.4 / dpi),
            (None, None, None) => {
                return Err(bad(
                    Kind::MissingSetting,
                    span,
                    &format!(
                        "`scan image` needs a size: the image is {} × {} pixels",
                        gray.w, gray.h
                    ),
                    "no size",
                    Some("add `width 40 mm` (or `height`, or both), or `dpi 254` (0.1 mm pixels)"),
                ));
            }
        };
        for (what, v) in [
            ("width", set.width),
            ("height", set.height),
            ("dpi", set.dpi),
        ] {
            if let Some((x, sp)) = v {
                if !(x > 0.0 && x.is_finite()) {
                    return Err(bad(
                        Kind::NotPositive,
                        sp,
                        &format!("the image's `{what}` must be greater than zero"),
                        "not positive",
                        None,
                    ));
                }
                let p = if what == "height" { py } else { px };
                self.in_range(p, &super::bounds::FINE_LENGTH, "the pixel size", sp)?;
            }
        }

        let mapping = Mapping {
            mode: match set.mode {
                "dither" => Mode::Dither(set.dither),
                "threshold" => Mode::Threshold(set.threshold),
                _ => Mode::Grayscale,
            },
            gamma: set.gamma,
            invert: set.invert,
        };
        let shades = img::shades(&gray, &mapping);
        let rows = img::image_rows(&shades, gray.w, gray.h, py);
        if rows.is_empty() {
            return Err(bad(
                Kind::Empty,
                file.span,
                &format!("\"{path}\" has no pixel to engrave after the mapping"),
                "nothing to engrave",
                Some(if set.invert {
                    "the image is black: drop `invert`"
                } else {
                    "the image is white: check `threshold`, `gamma` or `invert`"
                }),
            ));
        }
        // A row is one op (up to four with its travel and overscan) whatever its runs; the
        // runs, 8 B each, count against their own budget.
        let runs: usize = rows.iter().map(|(_, r)| r.len()).sum();
        let help =
            "use larger pixels (a smaller image), `mode dither` with fewer runs, or fewer passes";
        self.room_for_ops(
            (4 * rows.len()) as f64 * f64::from(set.passes),
            "this image scan",
            help,
            span,
        )?;
        self.room_for_runs(
            runs as f64 * f64::from(set.passes),
            "this image scan",
            help,
            span,
        )?;

        // Overscan: the recipe's, else the planner's ramp along the rows, as `scan raster`.
        let frame = Frame::new(set.origin, set.angle);
        let needed = self.row_run_up(&frame, speed, speed_span)?;
        if let Some((o, sp)) = set.overscan
            && !(o >= 0.0 && o.is_finite())
        {
            return Err(bad(
                Kind::Negative,
                sp,
                "the overscan cannot be negative",
                "negative",
                None,
            ));
        }
        let leadin = self.planner_settings_now().leadin;
        let overscan =
            super::scan::overscan(set.overscan, leadin, needed, needed, speed, "engrave")?;
        let steps = img::image_path(
            &rows,
            &ImageLayout {
                frame,
                px,
                py,
                order: set.order,
                passes: set.passes,
                overscan,
                lead: needed,
                line_offset: set.line_offset,
            },
        );

        let z = self.pos[2];
        let origin = [set.origin.x, set.origin.y];
        for st in steps {
            let at = |p: V2| [p.x, p.y, z];
            match st {
                ImageStep::Travel(p) => self.push_motion(
                    OpKind::Rapid {
                        to: at(p),
                        orient: None,
                    },
                    span,
                ),
                ImageStep::Idle(p) => self.push_motion(
                    OpKind::Line {
                        to: at(p),
                        feed_mm_s: speed,
                        laser: None,
                        orient: None,
                        row: None,
                    },
                    span,
                ),
                ImageStep::Row { to, v, shift, runs } => {
                    let row = PixelRow {
                        origin,
                        angle: set.angle,
                        v,
                        shift,
                        px,
                        min_w,
                        max_w,
                        runs,
                    };
                    // The row's own power is its brightest run's: what checks and reports
                    // that see the row as one lit move take it for.
                    self.runs += row.runs.len();
                    let top = row.runs.iter().map(|r| r.1).max().unwrap_or(0);
                    let laser = Laser {
                        power_w: row.power_w(top),
                        spot_mm: laser.spot_mm,
                        pulse: None,
                        couple: Coupling::Speed,
                        // A row is a line across the image, not an outline: no kerf.
                        kerf_mm: 0.0,
                    };
                    self.push_motion(
                        OpKind::Line {
                            to: at(to),
                            feed_mm_s: speed,
                            laser: Some(Arc::new(laser)),
                            orient: None,
                            row: Some(Box::new(row)),
                        },
                        span,
                    )
                }
            }
        }
        Ok(())
    }

    fn image_settings(&mut self, settings: &[Setting], cx: &mut Cx) -> R<ImageSet> {
        let mut set = ImageSet {
            speed: None,
            angle: 0.0,
            order: Order::Serpentine,
            passes: 1,
            overscan: None,
            origin: V2::zeros(),
            width: None,
            height: None,
            dpi: None,
            min_power: None,
            mode: "grayscale",
            dither: Dither::FloydSteinberg,
            gamma: 1.0,
            threshold: 0.5,
            invert: false,
            line_offset: 0.0,
        };
        for s in settings {
            let key = s.key.name.as_str();
            if key == "invert" {
                set.invert = true;
                continue;
            }
            let Some(e) = &s.value else { continue };
            // Words, checked against the schema's lists by the checker.
            let word = match &e.kind {
                ExprKind::Var(w) => w.as_str(),
                _ => "",
            };
            match key {
                "order" if word == "unidirectional" => set.order = Order::Unidirectional,
                "order" => set.order = Order::Serpentine,
                "mode" => {
                    set.mode = match word {
                        "dither" => "dither",
                        "threshold" => "threshold",
                        _ => "grayscale",
                    }
                }
                "dither" => set.dither = Dither::from_word(word).unwrap_or(Dither::FloydSteinberg),
                "power" | "spot" => {}
                _ => {
                    let v = self.expr(e, cx)?;
                    let ctx = format!("`{key}`");
                    let len = |me: &Self| me.as_dim(&v, Dim::LENGTH, e.span, &ctx);
                    match key {
                        "speed" => {
                            set.speed = Some((self.as_dim(&v, Dim::SPEED, e.span, &ctx)?, e.span))
                        }
                        "angle" => set.angle = self.as_dim(&v, Dim::ANGLE, e.span, &ctx)?,
                        "overscan" => set.overscan = Some((len(self)?, e.span)),
                        "width" => set.width = Some((len(self)?, e.span)),
                        "height" => set.height = Some((len(self)?, e.span)),
                        "line_offset" => {
                            let x = len(self)?;
                            if x.abs() > 0.0 {
                                self.in_range(
                                    x.abs(),
                                    &super::bounds::FINE_LENGTH,
                                    "the line offset",
                                    e.span,
                                )?;
                            }
                            set.line_offset = x;
                        }
                        "dpi" => {
                            set.dpi = Some((self.as_dim(&v, Dim::NONE, e.span, &ctx)?, e.span))
                        }
                        "min_power" => {
                            set.min_power =
                                Some((self.as_dim(&v, Dim::POWER, e.span, &ctx)?, e.span))
                        }
                        "origin" => {
                            let (p, _) = self.as_point(&v, e.span, &ctx)?;
                            set.origin = V2::new(p[0], p[1]);
                        }
                        "gamma" | "threshold" => {
                            let x = self.as_dim(&v, Dim::NONE, e.span, &ctx)?;
                            let ok = if key == "gamma" {
                                x > 0.0 && x <= 10.0
                            } else {
                                x > 0.0 && x <= 1.0
                            };
                            if !ok {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    &format!(
                                        "{ctx} must be in {}",
                                        if key == "gamma" { "(0, 10]" } else { "(0, 1]" }
                                    ),
                                    "out of range",
                                    Some(if key == "gamma" {
                                        "1 is linear; 2.2 lightens the mid-tones as a screen does"
                                    } else {
                                        "the tone runs from 0 (white) to 1 (black); 0.5 splits it"
                                    }),
                                ));
                            }
                            if key == "gamma" {
                                set.gamma = x;
                            } else {
                                set.threshold = x;
                            }
                        }
                        "passes" => {
                            let n = self.as_count(&v, e.span, &ctx)?;
                            if !(1..=1000).contains(&n) {
                                return Err(bad(
                                    Kind::OutOfRange,
                                    e.span,
                                    "`passes` must be 1 to 1000",
                                    "out of range",
                                    None,
                                ));
                            }
                            set.passes = n as u32;
                        }
                        _ => {}
                    }
                }
            }
        }
        Ok(set)
    }
}
