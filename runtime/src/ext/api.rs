//! What an extension can call: lase's points and profiles as registered Rhai types with their
//! methods, profile generators, the native cam motion laws, and unit helpers. Everything here
//! is pure computation; the sandbox (see `engine.rs`) adds nothing else.
//!
//! Numbers inside Rhai are plain floats in lase's internal units — mm, s, rad, W — so a
//! length arrives as millimetres and an angle as radians. `deg(x)` and `to_deg(x)` convert.

use crate::geometry::cam::{CamLaw, CamSegment, CamSegmentKind, program_lift};
use crate::geometry::{Profile, V2};
use rhai::{Array, Dynamic, Engine, EvalAltResult, FnPtr, INT, Map, NativeCallContext};
use std::rc::Rc;

type Rr<T> = Result<T, Box<EvalAltResult>>;

/// A point in mm, as Rhai sees it (`point(x, y)`, `p.x`); `dims` is 2 or 3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExtPoint {
    pub p: [f64; 3],
    pub dims: u8,
}

impl ExtPoint {
    fn v2(self) -> V2 {
        V2::new(self.p[0], self.p[1])
    }

    fn from_v2(v: V2) -> ExtPoint {
        ExtPoint {
            p: [v.x, v.y, 0.0],
            dims: 2,
        }
    }

    fn map(self, o: ExtPoint, f: impl Fn(f64, f64) -> f64) -> ExtPoint {
        ExtPoint {
            p: [
                f(self.p[0], o.p[0]),
                f(self.p[1], o.p[1]),
                f(self.p[2], o.p[2]),
            ],
            dims: self.dims.max(o.dims),
        }
    }

    fn scale(self, k: f64) -> ExtPoint {
        ExtPoint {
            p: [self.p[0] * k, self.p[1] * k, self.p[2] * k],
            dims: self.dims,
        }
    }

    fn describe(&self) -> String {
        let c: Vec<String> = self.p[..self.dims as usize]
            .iter()
            .map(|v| lase_lang::units::format_number(*v))
            .collect();
        format!("point({})", c.join(", "))
    }
}

/// A profile shared with the recipe (cheap to clone).
#[derive(Debug, Clone)]
pub struct ExtProfile(pub Rc<Profile>);

/// A number from Rhai: a float, or an integer taken as one.
pub(crate) fn num(d: &Dynamic) -> Rr<f64> {
    if let Ok(x) = d.as_float() {
        Ok(x)
    } else if let Ok(i) = d.as_int() {
        Ok(i as f64)
    } else {
        Err(format!("expected a number, found {}", d.type_name()).into())
    }
}

fn finite(x: f64, what: &str) -> Rr<f64> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("{what} is not a finite number").into())
    }
}

fn count(n: INT, what: &str, max: INT) -> Rr<usize> {
    if (2..=max).contains(&n) {
        Ok(n as usize)
    } else {
        Err(format!("{what} must be between 2 and {max}, got {n}").into())
    }
}

fn point_of(d: &Dynamic) -> Rr<ExtPoint> {
    d.clone()
        .try_cast::<ExtPoint>()
        .ok_or_else(|| format!("expected a point, found {}", d.type_name()).into())
}

fn points_of(a: &Array) -> Rr<Vec<V2>> {
    a.iter().map(|d| point_of(d).map(ExtPoint::v2)).collect()
}

fn geom<T>(r: Result<T, crate::geometry::GeomError>) -> Rr<T> {
    r.map_err(|e| e.to_string().into())
}

fn law(name: &str) -> Rr<CamLaw> {
    Ok(match name {
        "harmonic" => CamLaw::Harmonic,
        "cycloidal" => CamLaw::Cycloidal,
        "poly345" | "3-4-5" => CamLaw::Poly345,
        "modified_trapezoid" => CamLaw::ModifiedTrapezoid,
        other => {
            return Err(format!(
                "unknown cam law \"{other}\"; laws: harmonic, cycloidal, poly345, modified_trapezoid"
            )
            .into());
        }
    })
}

/// A cam program from Rhai maps `#{kind: "rise", law: "cycloidal", duration: deg(120),
/// lift: 6.0}` (durations in rad, lifts in mm).
fn segments(segs: &Array) -> Rr<Vec<CamSegment>> {
    segs.iter()
        .map(|d| {
            let m = d
                .clone()
                .try_cast::<Map>()
                .ok_or("a cam segment is a map #{kind, law, duration, lift}")?;
            let get = |k: &str| m.get(k).cloned();
            let kind = match get("kind").map(|k| k.to_string()).as_deref() {
                Some("rise") => CamSegmentKind::Rise,
                Some("return") => CamSegmentKind::Return,
                Some("dwell") => CamSegmentKind::Dwell,
                other => {
                    return Err(format!(
                        "cam segment kind {other:?}: use \"rise\", \"dwell\" or \"return\""
                    )
                    .into());
                }
            };
            let law = match get("law") {
                Some(l) => law(&l.to_string())?,
                None => CamLaw::Cycloidal,
            };
            let duration = num(&get("duration").ok_or("a cam segment needs `duration`")?)?;
            let lift = match get("lift") {
                Some(l) => num(&l)?,
                None => 0.0,
            };
            Ok(CamSegment {
                kind,
                law,
                duration_deg: duration.to_degrees(),
                lift_mm: lift,
            })
        })
        .collect()
}

/// Calls a Rhai function pointer with one number and reads a number back.
fn call_num(ctx: &NativeCallContext, f: &FnPtr, x: f64) -> Rr<Dynamic> {
    f.call_within_context::<Dynamic>(ctx, (x,))
}

fn arr_of_points(pts: impl IntoIterator<Item = V2>) -> Array {
    pts.into_iter()
        .map(|v| Dynamic::from(ExtPoint::from_v2(v)))
        .collect()
}

/// Registers the types and functions extensions may use.
pub(crate) fn register(engine: &mut Engine) {
    // ------------------------------------------------------------------ units
    engine.register_fn("deg", |x: Dynamic| num(&x).map(f64::to_radians));
    engine.register_fn("to_deg", |x: Dynamic| num(&x).map(f64::to_degrees));
    engine.register_fn("um", |x: Dynamic| num(&x).map(|v| v * 1e-3));

    // ------------------------------------------------------------------ points
    engine.register_type_with_name::<ExtPoint>("point");
    engine.register_fn("point", |x: Dynamic, y: Dynamic| -> Rr<ExtPoint> {
        Ok(ExtPoint {
            p: [finite(num(&x)?, "x")?, finite(num(&y)?, "y")?, 0.0],
            dims: 2,
        })
    });
    engine.register_fn(
        "point",
        |x: Dynamic, y: Dynamic, z: Dynamic| -> Rr<ExtPoint> {
            Ok(ExtPoint {
                p: [
                    finite(num(&x)?, "x")?,
                    finite(num(&y)?, "y")?,
                    finite(num(&z)?, "z")?,
                ],
                dims: 3,
            })
        },
    );
    engine.register_fn("polar", |r: Dynamic, a: Dynamic| -> Rr<ExtPoint> {
        let (r, a) = (num(&r)?, num(&a)?);
        Ok(ExtPoint::from_v2(V2::new(r * a.cos(), r * a.sin())))
    });
    engine.register_get("x", |p: &mut ExtPoint| p.p[0]);
    engine.register_get("y", |p: &mut ExtPoint| p.p[1]);
    engine.register_get("z", |p: &mut ExtPoint| p.p[2]);
    engine.register_fn("+", |a: ExtPoint, b: ExtPoint| a.map(b, |x, y| x + y));
    engine.register_fn("-", |a: ExtPoint, b: ExtPoint| a.map(b, |x, y| x - y));
    engine.register_fn("-", |a: ExtPoint| a.scale(-1.0));
    engine.register_fn("*", |a: ExtPoint, k: f64| a.scale(k));
    engine.register_fn("*", |k: f64, a: ExtPoint| a.scale(k));
    engine.register_fn("*", |a: ExtPoint, k: INT| a.scale(k as f64));
    engine.register_fn("*", |k: INT, a: ExtPoint| a.scale(k as f64));
    engine.register_fn("/", |a: ExtPoint, k: f64| a.scale(1.0 / k));
    engine.register_fn("/", |a: ExtPoint, k: INT| a.scale(1.0 / k as f64));
    engine.register_fn("==", |a: ExtPoint, b: ExtPoint| a == b);
    engine.register_fn("!=", |a: ExtPoint, b: ExtPoint| a != b);
    engine.register_fn("norm", |a: ExtPoint| {
        (a.p[0] * a.p[0] + a.p[1] * a.p[1] + a.p[2] * a.p[2]).sqrt()
    });
    engine.register_fn("distance", |a: ExtPoint, b: ExtPoint| {
        let d = a.map(b, |x, y| x - y);
        (d.p[0] * d.p[0] + d.p[1] * d.p[1] + d.p[2] * d.p[2]).sqrt()
    });
    engine.register_fn("dot", |a: ExtPoint, b: ExtPoint| {
        a.p[0] * b.p[0] + a.p[1] * b.p[1] + a.p[2] * b.p[2]
    });
    engine.register_fn("to_string", |p: &mut ExtPoint| p.describe());
    engine.register_fn("to_debug", |p: &mut ExtPoint| p.describe());

    // ------------------------------------------------------------------ profiles
    engine.register_type_with_name::<ExtProfile>("profile");
    engine.register_fn("length", |p: &mut ExtProfile| p.0.length());
    engine.register_fn("is_closed", |p: &mut ExtProfile| p.0.closed);
    engine.register_fn("start", |p: &mut ExtProfile| ExtPoint::from_v2(p.0.start()));
    engine.register_fn("end", |p: &mut ExtProfile| ExtPoint::from_v2(p.0.end()));
    engine.register_fn("point_at", |p: &mut ExtProfile, s: Dynamic| {
        Ok::<_, Box<EvalAltResult>>(ExtPoint::from_v2(p.0.point_at(num(&s)?)))
    });
    engine.register_fn("tangent_at", |p: &mut ExtProfile, s: Dynamic| {
        Ok::<_, Box<EvalAltResult>>(ExtPoint::from_v2(p.0.tangent_at(num(&s)?)))
    });
    engine.register_fn("normal_at", |p: &mut ExtProfile, s: Dynamic| {
        Ok::<_, Box<EvalAltResult>>(ExtPoint::from_v2(p.0.normal_at(num(&s)?)))
    });
    engine.register_fn("curvature_at", |p: &mut ExtProfile, s: Dynamic| {
        Ok::<_, Box<EvalAltResult>>(p.0.curvature_at(num(&s)?))
    });
    engine.register_fn(
        "offset",
        |p: &mut ExtProfile, d: Dynamic| -> Rr<ExtProfile> {
            Ok(ExtProfile(Rc::new(geom(p.0.offset(num(&d)?))?)))
        },
    );
    engine.register_fn("sample", |p: &mut ExtProfile, n: INT| -> Rr<Array> {
        let n = count(n, "the number of samples", 1_000_000)?;
        let len = p.0.length();
        // A closed profile's last sample would repeat its first.
        let div = if p.0.closed { n } else { n - 1 } as f64;
        Ok(arr_of_points(
            (0..n).map(|i| p.0.point_at(len * i as f64 / div)),
        ))
    });
    engine.register_fn("to_string", |p: &mut ExtProfile| {
        format!(
            "profile({} segments, {} mm)",
            p.0.segs.len(),
            lase_lang::units::format_number(p.0.length())
        )
    });
    engine.register_fn("polyline", |pts: Array, closed: bool| -> Rr<ExtProfile> {
        Ok(ExtProfile(Rc::new(geom(Profile::polyline(
            &points_of(&pts)?,
            closed,
        ))?)))
    });
    engine.register_fn("spline", |pts: Array, closed: bool| -> Rr<ExtProfile> {
        Ok(ExtProfile(Rc::new(geom(Profile::interpolate(
            &points_of(&pts)?,
            closed,
        ))?)))
    });
    engine.register_fn("circle", |c: ExtPoint, r: Dynamic| -> Rr<ExtProfile> {
        Ok(ExtProfile(Rc::new(geom(Profile::circle(
            c.v2(),
            num(&r)?,
            0.0,
            true,
        ))?)))
    });
    // Profile generators: a function of angle → radius, or of a parameter → point, sampled
    // and joined by an interpolating cubic spline (exact normals and curvature).
    engine.register_fn(
        "polar_profile",
        |ctx: NativeCallContext, f: FnPtr, samples: INT| -> Rr<ExtProfile> {
            let n = count(samples, "the number of samples", 100_000)?;
            let mut pts = Vec::with_capacity(n);
            for i in 0..n {
                let th = std::f64::consts::TAU * i as f64 / n as f64;
                let r = finite(num(&call_num(&ctx, &f, th)?)?, "the radius")?;
                if !(r > 0.0) {
                    return Err(format!(
                        "the radius at {:.3}° is {r} mm; it must be positive",
                        th.to_degrees()
                    )
                    .into());
                }
                pts.push(V2::new(th.cos(), th.sin()) * r);
            }
            Ok(ExtProfile(Rc::new(geom(Profile::interpolate(&pts, true))?)))
        },
    );
    engine.register_fn(
        "parametric_profile",
        |ctx: NativeCallContext,
         f: FnPtr,
         t0: Dynamic,
         t1: Dynamic,
         samples: INT,
         closed: bool|
         -> Rr<ExtProfile> {
            let n = count(samples, "the number of samples", 100_000)?;
            let (t0, t1) = (num(&t0)?, num(&t1)?);
            let div = if closed { n } else { n - 1 } as f64;
            let mut pts = Vec::with_capacity(n);
            for i in 0..n {
                let t = t0 + (t1 - t0) * i as f64 / div;
                pts.push(point_of(&call_num(&ctx, &f, t)?)?.v2());
            }
            Ok(ExtProfile(Rc::new(geom(Profile::interpolate(
                &pts, closed,
            ))?)))
        },
    );

    // ------------------------------------------------------------------ cam laws (native)
    engine.register_fn("cam_law", |name: &str, u: Dynamic| -> Rr<Array> {
        let (s, v, a) = law(name)?.eval(num(&u)?);
        Ok(vec![s.into(), v.into(), a.into()])
    });
    engine.register_fn("cam_lift", |segs: Array, theta: Dynamic| -> Rr<Array> {
        let segs = segments(&segs)?;
        geom(crate::geometry::cam::check_program(&segs))?;
        let (l, v, a) = program_lift(&segs, num(&theta)?.to_degrees());
        Ok(vec![l.into(), v.into(), a.into()])
    });
    engine.register_fn(
        "cam_profile",
        |base: Dynamic, segs: Array, samples: INT| -> Rr<ExtProfile> {
            let n = count(samples, "the number of samples", 100_000)?;
            Ok(ExtProfile(Rc::new(geom(Profile::cam(
                num(&base)?,
                &segments(&segs)?,
                n,
            ))?)))
        },
    );
}
