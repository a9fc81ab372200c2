//! GRBL `$$` settings compared with what a job needs: laser mode (`$32`), the S value of full
//! power (`$30`), mm reports (`$13`), the axes the controller has (from its status report:
//! three on GRBL, up to six on grblHAL), and per axis the maximum rate (`$110`–`$115`, mm/min
//! or deg/min) and acceleration (`$120`–`$125`, mm/s² or deg/s²), which must not be below
//! the plan's peaks.

use crate::link::{AXIS_LETTERS, Requirements, SettingMismatch, axis_index};
use std::collections::BTreeMap;

/// Settings as read from `$$`.
pub type Settings = BTreeMap<u32, f64>;

/// A rate a controller rounds to 3 decimals still satisfies a need up to that rounding.
fn at_least(found: f64, needed: f64) -> bool {
    found + 1e-3 + 1e-9 * needed.abs() >= needed
}

fn show(v: f64) -> String {
    lase_lang::units::format_number(v)
}

/// One diagnostic per setting that would make the job run differently from its plan.
/// `axes` is how many axes the controller reports positions for, when known.
pub fn compare(
    settings: &Settings,
    needs: &Requirements,
    axes: Option<usize>,
) -> Vec<SettingMismatch> {
    let mut out = Vec::new();
    if let Some(n) = axes
        && let Some((axis, k)) = needs
            .axes
            .iter()
            .filter_map(|a| axis_index(a.letter).map(|k| (a, k)))
            .find(|(_, k)| *k >= n)
    {
        let has: String = AXIS_LETTERS[..n.min(AXIS_LETTERS.len())].iter().collect();
        out.push(SettingMismatch {
            setting: "axis count".into(),
            found: format!("{n} ({has})"),
            needed: format!("{} (up to {})", k + 1, axis.letter),
            span: axis.v_span,
            label: format!("{} moves here", axis.letter),
            help: if n <= 3 {
                format!(
                    "GRBL 1.1 drives X, Y and Z only: this job needs a grblHAL controller built with at least {} axes",
                    k + 1
                )
            } else {
                format!(
                    "the controller's build has {n} axes: rebuild it with at least {} (grblHAL N_AXIS)",
                    k + 1
                )
            },
        });
        return out;
    }
    let get = |id: u32| settings.get(&id).copied();
    let found = |id: u32| get(id).map(show).unwrap_or_else(|| "missing".into());
    if let Some(span) = needs.laser
        && get(32) != Some(1.0)
    {
        out.push(SettingMismatch {
            setting: "$32 (laser mode)".into(),
            found: found(32),
            needed: "1".into(),
            span,
            label: "the laser first fires here".into(),
            help: "send `$32=1`: without laser mode GRBL stops at every power change and keeps the beam on during rapids".into(),
        });
    }
    if let Some((s_max, span)) = needs.s_max
        && get(30).is_none_or(|v| (v - s_max).abs() > 1e-6 * s_max.max(1.0))
    {
        out.push(SettingMismatch {
            setting: "$30 (S for full power)".into(),
            found: found(30),
            needed: show(s_max),
            span,
            label: "power is written as S words scaled to this value".into(),
            help: format!(
                "send `$30={}` (or set `s_max` in the machine's [post.grbl] to the controller's $30), or every power would be off by the ratio",
                show(s_max)
            ),
        });
    }
    if get(13).is_some_and(|v| v != 0.0) {
        out.push(SettingMismatch {
            setting: "$13 (report inches)".into(),
            found: found(13),
            needed: "0".into(),
            span: needs.laser.unwrap_or_default(),
            label: "positions are compared in mm".into(),
            help: "send `$13=0` so status reports are in mm".into(),
        });
    }
    for axis in &needs.axes {
        let Some(k) = axis_index(axis.letter) else {
            continue;
        };
        let k = k as u32;
        let (per_min, per_s2) = if axis.rotary {
            ("deg/min", "deg/s²")
        } else {
            ("mm/min", "mm/s²")
        };
        // $110+k (max rate) and $120+k (acceleration) against what the plan needs of axis k.
        let checks = [
            (
                110 + k,
                "max rate",
                per_min,
                axis.v_per_min,
                axis.v_span,
                "reaches",
                "the machine file's v_max, or lower the speed in the recipe's `limits`; the \
                 controller would run slower than the plan",
            ),
            (
                120 + k,
                "acceleration",
                per_s2,
                axis.a_per_s2,
                axis.a_span,
                "accelerates at",
                "the machine file's a_max, or lower the acceleration in the recipe's `limits`",
            ),
        ];
        for (id, what, unit, need, span, verb, remedy) in checks {
            if !get(id).is_some_and(|v| at_least(v, need)) {
                out.push(SettingMismatch {
                    setting: format!("${id} ({} {what}, {unit})", axis.letter),
                    found: found(id),
                    needed: format!("at least {}", show(need)),
                    span,
                    label: format!("{} {verb} {} {unit} here", axis.letter, show(need)),
                    help: format!("raise `${id}` to {remedy}"),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::AxisNeed;
    use lase_lang::Span;

    #[test]
    fn low_rates_and_laser_mode_are_reported() {
        let needs = Requirements {
            laser: Some(Span::new(1, 2)),
            axes: vec![AxisNeed {
                letter: 'Y',
                rotary: false,
                v_per_min: 12000.0,
                a_per_s2: 2000.0,
                v_span: Span::new(3, 4),
                a_span: Span::new(5, 6),
            }],
            s_max: Some((1000.0, Span::new(1, 2))),
        };
        let mut s: Settings = [(32, 1.0), (30, 1000.0), (111, 12000.0), (121, 2000.0)]
            .into_iter()
            .collect();
        assert!(compare(&s, &needs, Some(3)).is_empty());
        s.insert(32, 0.0);
        s.insert(111, 6000.0);
        let errs = compare(&s, &needs, None);
        assert_eq!(errs.len(), 2, "{errs:?}");
        assert!(errs[0].to_string().contains("$32"));
        assert!(errs[1].to_string().contains("$111"));
    }

    #[test]
    fn a_job_moving_c_needs_a_controller_with_six_axes() {
        let needs = Requirements {
            laser: None,
            axes: vec![AxisNeed {
                letter: 'C',
                rotary: true,
                v_per_min: 3600.0,
                a_per_s2: 100.0,
                v_span: Span::new(7, 9),
                a_span: Span::new(7, 9),
            }],
            s_max: None,
        };
        let s: Settings = [(115, 3600.0), (125, 100.0)].into_iter().collect();
        let errs = compare(&s, &needs, Some(3));
        assert_eq!(errs.len(), 1, "{errs:?}");
        assert_eq!(errs[0].found, "3 (XYZ)");
        assert!(errs[0].help.contains("grblHAL"), "{}", errs[0].help);
        assert_eq!(errs[0].span, Span::new(7, 9));
        assert!(compare(&s, &needs, Some(6)).is_empty());
    }
}
