//! What the language knows by name: builtin functions, profile constructors, statement
//! settings and type names — with their documentation. This table is the one source of truth
//! for the checker, the evaluator's argument binding, completion and `lase doc`.
//!
//! Nothing here knows a machine: axis names in `limits` and event names are checked against
//! the machine at evaluation.

use crate::units::Dim;

/// The type of a parameter or setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PTy {
    /// A number of this dimension (a literal `0` fits any).
    Dim(Dim),
    /// Either of two dimensions (e.g. a linear or an angular speed).
    Either(Dim, Dim),
    /// Any number.
    AnyNum,
    Point,
    Profile,
    /// A list of points.
    Points,
    List,
    /// A list or a string (`len`).
    ListOrStr,
    /// Any value (the values `format` fills in).
    Any,
    Bool,
    Str,
    /// One word of a fixed set, written as a bare name (`ramp scurve`).
    Word(&'static [&'static str]),
    /// A flag: a setting with no value.
    Flag,
}

impl PTy {
    pub fn describe(self) -> String {
        match self {
            PTy::Dim(d) => d.describe(),
            PTy::Either(a, b) => format!("{} or {}", a.describe(), b.describe()),
            PTy::AnyNum => "a number".into(),
            PTy::Point => "a point".into(),
            PTy::Profile => "a profile".into(),
            PTy::Points => "a list of points".into(),
            PTy::List => "a list".into(),
            PTy::ListOrStr => "a list or a string".into(),
            PTy::Any => "any value".into(),
            PTy::Bool => "a bool".into(),
            PTy::Str => "a string".into(),
            PTy::Word(w) => format!("one of {}", w.join(", ")),
            PTy::Flag => "nothing (a flag)".into(),
        }
    }
}

#[derive(Debug, Clone, Copy)]
pub struct ParamSpec {
    pub name: &'static str,
    pub ty: PTy,
    pub required: bool,
}

const fn req(name: &'static str, ty: PTy) -> ParamSpec {
    ParamSpec {
        name,
        ty,
        required: true,
    }
}

const fn opt(name: &'static str, ty: PTy) -> ParamSpec {
    ParamSpec {
        name,
        ty,
        required: false,
    }
}

/// What a builtin returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ret {
    Dim(Dim),
    Point,
    Profile,
    Points,
    Str,
    /// A list of profiles (2D codes' modules, `tabs`' pieces).
    Profiles,
    /// The dimension of the first argument (abs, min, max).
    SameAsFirst,
    /// The square root of the first argument's dimension.
    SqrtOfFirst,
}

#[derive(Debug, Clone, Copy)]
pub struct Builtin {
    pub name: &'static str,
    pub params: &'static [ParamSpec],
    pub ret: Ret,
    pub doc: &'static str,
}

const L: PTy = PTy::Dim(Dim::LENGTH);
const ANG: PTy = PTy::Dim(Dim::ANGLE);
const NUM: PTy = PTy::Dim(Dim::NONE);

pub const BUILTINS: &[Builtin] = &[
    Builtin {
        name: "offset",
        params: &[
            req("profile", PTy::Profile),
            req("distance", L),
            opt("trim", PTy::Bool),
        ],
        ret: Ret::Profile,
        doc: "The equidistant curve C0 = C ± d·n. For a closed profile a positive distance \
              grows it outward; for an open one it moves to the left of the direction of \
              travel. A distance larger than a concave radius of the profile folds the \
              offset over itself: lase reports it instead of emitting a self-intersecting path, \
              unless `trim: true` asks for the clean offset with the loops cut away.",
    },
    Builtin {
        name: "reverse",
        params: &[req("profile", PTy::Profile)],
        ret: Ret::Profile,
        doc: "The same profile traversed the other way.",
    },
    Builtin {
        name: "translate",
        params: &[req("profile", PTy::Profile), req("by", PTy::Point)],
        ret: Ret::Profile,
        doc: "The profile moved by a vector.",
    },
    Builtin {
        name: "rotate",
        params: &[
            req("profile", PTy::Profile),
            req("angle", ANG),
            opt("about", PTy::Point),
        ],
        ret: Ret::Profile,
        doc: "The profile turned counter-clockwise by `angle` about a point (the origin by default).",
    },
    Builtin {
        name: "length",
        params: &[req("profile", PTy::Profile)],
        ret: Ret::Dim(Dim::LENGTH),
        doc: "The arc length of a profile.",
    },
    Builtin {
        name: "start",
        params: &[req("profile", PTy::Profile)],
        ret: Ret::Point,
        doc: "The first point of a profile.",
    },
    Builtin {
        name: "end",
        params: &[req("profile", PTy::Profile)],
        ret: Ret::Point,
        doc: "The last point of a profile (its start, when closed).",
    },
    Builtin {
        name: "point_at",
        params: &[req("profile", PTy::Profile), req("s", L)],
        ret: Ret::Point,
        doc: "The point at arc length `s` from the profile's start.",
    },
    Builtin {
        name: "polar",
        params: &[req("radius", L), req("angle", ANG)],
        ret: Ret::Point,
        doc: "The point (r·cos a, r·sin a).",
    },
    Builtin {
        name: "distance",
        params: &[req("a", PTy::Point), req("b", PTy::Point)],
        ret: Ret::Dim(Dim::LENGTH),
        doc: "The straight-line distance between two points.",
    },
    Builtin {
        name: "sqrt",
        params: &[req("x", PTy::AnyNum)],
        ret: Ret::SqrtOfFirst,
        doc: "Square root; the dimension is halved (sqrt of mm^2 is mm).",
    },
    Builtin {
        name: "abs",
        params: &[req("x", PTy::AnyNum)],
        ret: Ret::SameAsFirst,
        doc: "Absolute value.",
    },
    Builtin {
        name: "min",
        params: &[req("a", PTy::AnyNum), req("b", PTy::AnyNum)],
        ret: Ret::SameAsFirst,
        doc: "The smaller of two quantities of one dimension.",
    },
    Builtin {
        name: "max",
        params: &[req("a", PTy::AnyNum), req("b", PTy::AnyNum)],
        ret: Ret::SameAsFirst,
        doc: "The larger of two quantities of one dimension.",
    },
    Builtin {
        name: "sin",
        params: &[req("angle", ANG)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Sine of an angle.",
    },
    Builtin {
        name: "cos",
        params: &[req("angle", ANG)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Cosine of an angle.",
    },
    Builtin {
        name: "tan",
        params: &[req("angle", ANG)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Tangent of an angle.",
    },
    Builtin {
        name: "atan2",
        params: &[req("y", PTy::AnyNum), req("x", PTy::AnyNum)],
        ret: Ret::Dim(Dim::ANGLE),
        doc: "The angle of the vector (x, y); both of one dimension.",
    },
    Builtin {
        name: "floor",
        params: &[req("x", NUM)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Largest whole number not above x.",
    },
    Builtin {
        name: "ceil",
        params: &[req("x", NUM)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Smallest whole number not below x.",
    },
    Builtin {
        name: "round",
        params: &[req("x", NUM)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Nearest whole number.",
    },
    Builtin {
        name: "len",
        params: &[req("list", PTy::ListOrStr)],
        ret: Ret::Dim(Dim::NONE),
        doc: "Number of items in a list, or of characters in a string.",
    },
    // Marking (issue 19): string formatting and 2D codes.
    Builtin {
        name: "format",
        params: &[req("template", PTy::Str), opt("values", PTy::Any)],
        ret: Ret::Str,
        doc: "A string from a template and any number of values: `format(\"SN {:04}\", n)`. \
              Each `{}` takes the next value; `{{` and `}}` are literal braces. A spec after a \
              colon: an alignment `<` `^` `>` (default: right for numbers, left for the rest), \
              a `0` to pad numbers with zeros after their sign, a width, and `.N` digits after \
              the point. A plain number without `.N` prints as a whole number when it is one; \
              a quantity with a unit prints with its unit (`12.5 mm`) and takes no `0` or `.N` \
              (divide by a unit first: `format(\"{:.2}\", d / 1 mm)`).",
    },
    Builtin {
        name: "qr",
        params: &[
            req("text", PTy::Str),
            req("module", L),
            opt("origin", PTy::Point),
            opt("quiet", NUM),
        ],
        ret: Ret::Profiles,
        doc: "A QR code of the text (byte mode, error correction M, the smallest version that \
              holds it) as closed profiles to fill with a `raster` scan: one rectangle per run of \
              dark modules in a row, `module` wide per module. `origin` is the lower-left corner of \
              the symbol's quiet zone (default the origin); `quiet` is the quiet zone in modules \
              (default 4, the standard's), which the size counts but no profile fills.",
    },
    Builtin {
        name: "qr_dots",
        params: &[
            req("text", PTy::Str),
            req("module", L),
            opt("origin", PTy::Point),
            opt("quiet", NUM),
        ],
        ret: Ret::Points,
        doc: "The QR code of `qr` as the centres of its dark modules, for a `dots` scan (one \
              pulse per module).",
    },
    Builtin {
        name: "datamatrix",
        params: &[
            req("text", PTy::Str),
            req("module", L),
            opt("origin", PTy::Point),
            opt("quiet", NUM),
        ],
        ret: Ret::Profiles,
        doc: "A Data Matrix (ECC 200, the smallest square symbol that holds the text) as closed \
              profiles to fill with a `raster` scan, as `qr` does; the quiet zone defaults to 1 \
              module, the standard's minimum.",
    },
    Builtin {
        name: "datamatrix_dots",
        params: &[
            req("text", PTy::Str),
            req("module", L),
            opt("origin", PTy::Point),
            opt("quiet", NUM),
        ],
        ret: Ret::Points,
        doc: "The Data Matrix of `datamatrix` as the centres of its dark modules, for \
              a `dots` scan.",
    },
    // Job setup (issue 20): pieces of a profile by arc length and tabs.
    Builtin {
        name: "segment",
        params: &[req("profile", PTy::Profile), req("from", L), req("to", L)],
        ret: Ret::Profile,
        doc: "The open piece of a profile from arc length `from` to `to` (both from 0 to \
              `length(p)`). On a closed profile `from` past `to` runs across the start. Lines \
              and arcs are cut exactly; a spline is cut on its line/arc rendition (within \
              1 µm).",
    },
    Builtin {
        name: "tabs",
        params: &[
            req("profile", PTy::Profile),
            opt("count", NUM),
            opt("spacing", L),
            req("width", L),
        ],
        ret: Ret::Profiles,
        doc: "The lit pieces of a profile with tabs: `width`-wide gaps left uncut so the part \
              stays held in the sheet, either `count` of them or about one every `spacing`, \
              evenly spaced (on a closed profile centred at (k + ½)·L/n, piece k running from \
              tab k to tab k + 1; on an open one at k·L/(n + 1), both ends cut). `follow` takes \
              the list and crosses each gap with the beam off at the cutting speed.",
    },
];

/// Builtins whose last parameter takes any number of positional arguments.
pub const VARIADIC: &[&str] = &["format"];

/// Names bound in every recipe.
pub const CONSTANTS: &[(&str, f64, &str)] = &[
    ("pi", std::f64::consts::PI, "π, a plain number."),
    ("tau", std::f64::consts::TAU, "2π, a plain number."),
];

pub fn builtin(name: &str) -> Option<&'static Builtin> {
    BUILTINS.iter().find(|b| b.name == name)
}

/// A profile constructor: `profile KIND ...`.
#[derive(Debug, Clone, Copy)]
pub struct ProfileKind {
    pub name: &'static str,
    pub params: &'static [ParamSpec],
    pub flags: &'static [&'static str],
    pub doc: &'static str,
    /// Known but not built yet: the checker says so instead of "unknown".
    pub unsupported: bool,
}

pub const PROFILE_KINDS: &[ProfileKind] = &[
    ProfileKind {
        name: "polyline",
        params: &[req("points", PTy::Points)],
        flags: &["closed"],
        doc: "Straight segments through the points, in order; `closed` joins the last to the first.",
        unsupported: false,
    },
    ProfileKind {
        name: "line",
        params: &[req("from", PTy::Point), req("to", PTy::Point)],
        flags: &[],
        doc: "One straight segment.",
        unsupported: false,
    },
    ProfileKind {
        name: "arc",
        params: &[
            req("center", PTy::Point),
            req("radius", L),
            req("start", ANG),
            req("end", ANG),
        ],
        flags: &["cw", "ccw"],
        doc: "A circular arc from angle `start` to `end` about `center` (counter-clockwise unless `cw`).",
        unsupported: false,
    },
    ProfileKind {
        name: "circle",
        params: &[
            req("center", PTy::Point),
            req("radius", L),
            opt("start", ANG),
        ],
        flags: &["cw", "ccw"],
        doc: "A full circle, starting at angle `start` (0 by default), counter-clockwise unless `cw`.",
        unsupported: false,
    },
    ProfileKind {
        name: "rect",
        params: &[req("corner", PTy::Point), req("width", L), req("height", L)],
        flags: &[],
        doc: "A closed axis-aligned rectangle from its lower-left corner, counter-clockwise.",
        unsupported: false,
    },
    ProfileKind {
        name: "spline",
        params: &[req("points", PTy::Points)],
        flags: &["closed"],
        doc: "The cubic B-spline through measured points (PROCESS.md §2: P(j-1) + 4 P(j) + \
              P(j+1) = 6 Q(j)); `closed` solves the cyclic system, so the curve is C² at the \
              seam. Passes through every point; normals and curvature are exact.",
        unsupported: false,
    },
    ProfileKind {
        name: "cam",
        params: &[
            req("base", L),
            opt("lift", L),
            opt("rise", ANG),
            opt("top", ANG),
            opt("fall", ANG),
            opt("law", PTy::Str),
            opt("table", PTy::Str),
        ],
        flags: &[],
        doc: "A disc cam about the origin, r(θ) = base + lift(θ), counter-clockwise from +x. \
              Either a motion program — rise by `lift` over `rise`, dwell at the top over `top`, \
              fall back over `fall` (default: as `rise`), dwell at the base for the rest of the turn — with \
              `law` one of \"harmonic\", \"cycloidal\" (default), \"345\", \
              \"modified_trapezoid\"; or a lift table file `table: \"lift.csv\"` of \
              `angle_deg, lift_mm` rows.",
        unsupported: false,
    },
    ProfileKind {
        name: "dxf",
        params: &[req("file", PTy::Str), opt("index", NUM)],
        flags: &[],
        doc: "A contour imported from a DXF file (LINE, ARC, CIRCLE, LWPOLYLINE with bulges, \
              SPLINE), chained end to end; `index` picks one of several contours (0 first).",
        unsupported: false,
    },
    ProfileKind {
        name: "svg",
        params: &[
            req("path", PTy::Str),
            opt("index", NUM),
            opt("id", PTy::Str),
        ],
        flags: &[],
        doc: "A contour from SVG path data (the `d` attribute: M, L, H, V, C, S, Q, T, A, Z), \
              in mm with y up, or from an SVG file (`svg(\"part.svg\")`, a name ending in \
              .svg, relative to the recipe): its `<path>` elements, one user unit per mm, \
              without transforms; `id: \"outline\"` picks the path with that id; `index` \
              picks one of several contours (subpaths, or the paths of a file in document \
              order).",
        unsupported: false,
    },
    // Marking (issue 19): text.
    ProfileKind {
        name: "text",
        params: &[
            req("text", PTy::Str),
            req("height", L),
            opt("origin", PTy::Point),
            opt("align", PTy::Str),
            opt("spacing", L),
            opt("angle", ANG),
            opt("radius", L),
            opt("font", PTy::Str),
        ],
        flags: &[],
        doc: "Text as a list of profiles. Without `font`, lase's built-in single-stroke font \
              (Hershey Simplex, ASCII 32–126): open strokes to `follow`. With `font: \
              \"file.ttf\"` (TrueType or OpenType, relative to the recipe): each glyph's closed \
              outlines, curves flattened within the planner's tolerance, to fill with a `raster` \
              scan. `height` is the height of a capital letter; `origin` the anchor on the \
              baseline (default the origin); `align` is \"left\" (default), \"center\" or \
              \"right\" of the anchor; `spacing` is added between letters; `angle` turns the \
              baseline (default 0 deg). With `radius` the baseline is an arc of that radius \
              about `origin`, the anchor at polar angle `angle` (default 90 deg), the letters \
              upright outward and reading clockwise (a negative radius puts them inside, \
              reading counter-clockwise).",
        unsupported: false,
    },
];

pub fn profile_kind(name: &str) -> Option<&'static ProfileKind> {
    PROFILE_KINDS.iter().find(|k| k.name == name)
}

/// A setting inside a statement's `{ ... }`.
#[derive(Debug, Clone, Copy)]
pub struct SettingSpec {
    pub key: &'static str,
    pub ty: PTy,
    pub doc: &'static str,
}

const fn set(key: &'static str, ty: PTy, doc: &'static str) -> SettingSpec {
    SettingSpec { key, ty, doc }
}

pub const LASER_SETTINGS: &[SettingSpec] = &[
    set(
        "power",
        PTy::Dim(Dim::POWER),
        "Laser power while the beam is on.",
    ),
    set("spot", L, "Spot diameter on the surface."),
    set(
        "couple",
        PTy::Word(COUPLINGS),
        "`speed`: power follows the planned speed (P = P_set · v / feed), constant energy per \
         length where the speed must ramp with the beam on; `none` (default): constant power.",
    ),
    set(
        "standoff",
        L,
        "Distance from the lens to the spot along the beam, held constant on machines that \
         orient the beam (cam_xwb, arm_3r); required there.",
    ),
    set(
        "kerf",
        L,
        "Width of the cut (issue 20): every closed path cut with it is moved half of it \
         outward when it is an outline and inward when it is a hole (inside an odd number of \
         closed paths), so the part and its holes come out at their drawn size; open paths \
         stay as drawn. Default 0.",
    ),
];

pub const COUPLINGS: &[&str] = &["none", "speed"];

pub const FOLLOW_SETTINGS: &[SettingSpec] = &[
    set(
        "power",
        PTy::Dim(Dim::POWER),
        "Laser power for this path only.",
    ),
    set("spot", L, "Spot diameter for this path only."),
    set(
        "couple",
        PTy::Word(COUPLINGS),
        "Power coupling for this path only: `speed` or `none`.",
    ),
    set(
        "standoff",
        L,
        "Lens-to-spot distance along the beam for this path only (oriented machines).",
    ),
    set(
        "side",
        PTy::Word(SIDES),
        "Where the head stands, on machines that orient the beam: `outside` (default for a \
         closed profile) or `inside` it, or `left` (default for an open profile) or `right` \
         of the direction of travel. The beam points back along the exact surface normal.",
    ),
    set(
        "normals",
        PTy::Word(NORMALS),
        "How the beam direction is found on machines that orient it: `exact` (default), the \
         profile's exact normal at each scan point; `chord`, PROCESS.md §1's discrete method — \
         scan points at the midpoints of the step chords, the beam along their perpendicular \
         bisectors (second-order accurate: for comparison with the paper).",
    ),
    set(
        "step",
        L,
        "Scan step on machines that orient the beam: the path is resampled at this constant \
         arc length (shortened until the chord error is within the planner's `tolerance`), \
         one pose per point (default: the planner's `step`, else 1 mm). A step is halved \
         where the controller's straight joint motion between two poses would take the spot \
         off the surface by more than the `tolerance` or change its speed by more than 0.1 %.",
    ),
];

pub const SIDES: &[&str] = &["outside", "inside", "left", "right"];

pub const NORMALS: &[&str] = &["exact", "chord"];

pub const PULSE_SETTINGS: &[SettingSpec] = &[
    set(
        "interval",
        PTy::Either(Dim::LENGTH, Dim::TIME),
        "A length fires a pulse every so far along the lit path (position-synchronized); a \
         time fires on a timer.",
    ),
    set(
        "rate",
        PTy::Dim(Dim::FREQUENCY),
        "Pulse repetition rate (timer mode).",
    ),
    set("width", PTy::Dim(Dim::TIME), "Pulse width."),
    set("energy", PTy::Dim(Dim::ENERGY), "Energy per pulse."),
];

pub const RAMPS: &[&str] = &["trapezoid", "scurve"];

pub const PLANNER_SETTINGS: &[SettingSpec] = &[
    set(
        "ramp",
        PTy::Word(RAMPS),
        "Velocity profile: `trapezoid` (constant acceleration) or `scurve` (jerk-limited, 7 phases).",
    ),
    set(
        "corner",
        L,
        "Junction deviation: how far the path may cut a corner's apex, which sets the corner speed.",
    ),
    set(
        "tolerance",
        L,
        "Chord tolerance used when arcs and curves are split into straight moves, and how \
         far the spot may leave the surface between two poses on machines that orient the \
         beam.",
    ),
    set(
        "lookahead",
        NUM,
        "How many moves the planner looks ahead when streaming (the offline plan sees all).",
    ),
    set(
        "step",
        L,
        "Default scan step of `follow` on machines that orient the beam.",
    ),
    set(
        "leadin",
        PTy::Word(LEADINS),
        "`auto` (default): lead-ins and lead-outs so that the beam is only on at the programmed \
         speed; `none`: the program as written (`off` is a keyword).",
    ),
    set(
        "order",
        PTy::Word(CUT_ORDERS),
        "Cut order of the job's paths (each a rapid and the cut after it): `source` (default), \
         as written; `nearest`, the nearest path next (greedy), entering a closed path at its \
         vertex nearest the spot and an open one at its nearer end; `inner_first`, as \
         `nearest` but a path inside a closed path is cut before it (holes before the \
         outline, so the part does not drop first). `lase plan` reports the travel saved.",
    ),
    set(
        "origin",
        PTy::Word(JOB_ORIGINS),
        "Where the recipe's zero is on the machine: `absolute` (default), the controller's \
         coordinates; `current`, the spot's position when the job starts (`lase run` reads it \
         from the controller and refuses a job that would leave the travel from there; `lase \
         emit` writes a work frame its header sets with `G10 L20 P1`); `g54` … `g59`, the \
         controller's work offset, selected and never written (the travel is checked at \
         machine positions: `lase run` reads the offset, `lase emit` takes `--work-offset` or \
         the machine file's `[work_offsets]`). `--origin` overrides it.",
    ),
];

pub const LEADINS: &[&str] = &["auto", "none"];

/// Cut orders of `planner { order ... }` (issue 20).
pub const CUT_ORDERS: &[&str] = &["source", "nearest", "inner_first"];

// Issue 20's job-setup words: `planner { origin }` and the `rotary` statement.
mod job_setup;
pub use job_setup::{JOB_ORIGINS, ROTARY_SETTINGS};

pub const LIMIT_SETTINGS: &[SettingSpec] = &[
    set(
        "v",
        PTy::Either(Dim::SPEED, Dim::ANGULAR_SPEED),
        "Maximum axis speed.",
    ),
    set(
        "a",
        PTy::Either(Dim::ACCEL, Dim::ANGULAR_ACCEL),
        "Maximum axis acceleration.",
    ),
    set(
        "j",
        PTy::Either(Dim::JERK, Dim::ANGULAR_JERK),
        "Maximum axis jerk (used by `ramp scurve`).",
    ),
];

/// A kind of `scan` statement: `scan KIND REGION { settings }`.
#[derive(Debug, Clone, Copy)]
pub struct ScanKind {
    pub name: &'static str,
    /// What the region expression may be.
    pub region: &'static str,
    pub settings: &'static [SettingSpec],
    pub doc: &'static str,
}

pub const SCAN_ORDERS: &[&str] = &["serpentine", "unidirectional"];
pub const SCAN_LAYOUTS: &[&str] = &["grid", "stagger", "hex"];
pub const SCAN_MODES: &[&str] = &["fly", "dot"];

const SCAN_COMMON: [SettingSpec; 8] = [
    set(
        "speed",
        PTy::Dim(Dim::SPEED),
        "Table speed along the rows (required); in dot mode the positioning speed between spots.",
    ),
    set(
        "angle",
        ANG,
        "Row direction, counter-clockwise from +x (default 0 deg). Rows step along the direction turned +90°.",
    ),
    set(
        "order",
        PTy::Word(SCAN_ORDERS),
        "`serpentine` (default): rows alternate direction (boustrophedon, the optimized strategy of PROCESS.md §3); `unidirectional`: every row in the same direction with an idle return stroke (the old one).",
    ),
    set(
        "passes",
        NUM,
        "Times the whole raster is repeated (default 1). Each pass starts at the first row's approach point A, reached from one row pitch before it, so every row start — A included — is approached in the row-step direction. With serpentine order an even number of rows ends a pass on the start side, an odd number on the far side.",
    ),
    set(
        "overscan",
        L,
        "Extension of every row before its first and after its last spot or line, so they are passed at the programmed speed. Default: computed from the planner's ramps (the lead-in length for the speed, the axes' limits and the ramp kind); for `scan dots` on the fly, plus 5 ms of travel at the scan speed, so every row is at cruise for 5 ms before its first pulse and every pulse fires at the programmed speed with room to spare.",
    ),
    set(
        "origin",
        PTy::Point,
        "Where the lattice (or the first hatch line) is anchored. Default: the corner of the region's bounding box in the raster's frame (hatch lines half a pitch inside).",
    ),
    set(
        "power",
        PTy::Dim(Dim::POWER),
        "Laser power for this scan only (default: the `laser` power in force).",
    ),
    set(
        "spot",
        L,
        "Spot diameter for this scan only (default: the `laser` spot in force).",
    ),
];

// Row-start settling (issue 15, PROCESS.md §3): closed-loop positioning of each row start
// from the scale before the row fires. Kept in one block so merges stay simple.
pub const SETTLE_WINDOW_UM: (f64, f64) = (-0.5, 1.5);
pub const SETTLE_ACROSS_UM: f64 = 1.0;
pub const SETTLE_STEP_UM: f64 = 0.5;
pub const SETTLE_MAX_STEPS: u32 = 20;
pub const SETTLE_TIMEOUT_S: f64 = 5.0;

const SCAN_SETTLE: [SettingSpec; 6] = [
    set(
        "settle",
        PTy::Flag,
        "Row-start settling (PROCESS.md §3, seed 3): before each row of each pass fires, the table stops at the row's start, its position is read from the controller (the scale), and corrective steps of `settle_step` are sent until the error is within `settle_window` along the row and `settle_across` across it. Needs the live link (`lase run`, the REPL), or for an NC file a machine whose `[settle]` names LinuxCNC's scale inputs or an ISO macro; the row then runs relative to its settled start. A flag: write `settle`. Any other `settle_*` setting turns it on too.",
    ),
    set(
        "settle_window",
        PTy::List,
        "The accepted error along the row, in the row's direction of travel, as `[low, high]` (default the seed's `[-0.5 um, 1.5 um]`). Must contain 0 and be at least one `settle_step` wide.",
    ),
    set(
        "settle_across",
        L,
        "The accepted error across the row, either way (default 1 um: the seed states none; one count of a 1 µm scale).",
    ),
    set(
        "settle_step",
        L,
        "One corrective step (default 0.5 um: the seed's servo increment).",
    ),
    set(
        "settle_steps",
        NUM,
        "Corrective steps allowed per row start before the job stops with a diagnostic here (default 20).",
    ),
    set(
        "settle_timeout",
        PTy::Dim(Dim::TIME),
        "Time allowed per row start, from the stop to within the window, before the job stops with a diagnostic here (default 5 s).",
    ),
];

pub const SCAN_KINDS: &[ScanKind] = &[
    ScanKind {
        name: "dots",
        region: "a point (the origin of a `rows` × `cols` array), a closed profile, a list of closed profiles (a profile inside another is a hole), or a list of points (explicit spots)",
        settings: &[
            SCAN_COMMON[0],
            SCAN_COMMON[1],
            SCAN_COMMON[2],
            SCAN_COMMON[3],
            SCAN_COMMON[4],
            SCAN_COMMON[5],
            SCAN_COMMON[6],
            SCAN_COMMON[7],
            SCAN_SETTLE[0],
            SCAN_SETTLE[1],
            SCAN_SETTLE[2],
            SCAN_SETTLE[3],
            SCAN_SETTLE[4],
            SCAN_SETTLE[5],
            set(
                "pitch",
                L,
                "L1: spot spacing along a row (required, except for a list of points, where it defaults to the spot diameter and only sets the row grouping).",
            ),
            set(
                "row_pitch",
                L,
                "L2: spacing between rows (default: `pitch`; with `layout hex`, pitch·√3/2).",
            ),
            set(
                "rows",
                NUM,
                "Rows of an array given by its origin point (required with a point region).",
            ),
            set(
                "cols",
                NUM,
                "Spots per row of an array given by its origin point (required with a point region).",
            ),
            set(
                "layout",
                PTy::Word(SCAN_LAYOUTS),
                "`grid` (default), `stagger` (odd rows shifted by half a pitch) or `hex` (staggered, rows pitch·√3/2 apart: every spot L1 from six neighbours).",
            ),
            set(
                "pulses",
                NUM,
                "Pulses per spot per pass (default 1: seed 3's single pulse, repeated over `passes`). More than one needs the spot at rest: dot mode.",
            ),
            set(
                "mode",
                PTy::Word(SCAN_MODES),
                "`fly` (default with one pulse per spot): the table passes the spots at `speed` and a pulse fires at each, synchronized with the position; `dot`: move to each spot, stop, fire, move on (slow; any controller).",
            ),
            set(
                "inset",
                L,
                "Keep spot centers this far inside the region's borders (offset machinery; default 0 mm).",
            ),
        ],
        doc: "A texturing dot array: spots on a lattice (L1 along a row, L2 between rows), in or from the region, fired with the pulse settings in force (the `pulse` width and energy). Spots are counted from the lattice origin, never accumulated.",
    },
    ScanKind {
        name: "raster",
        region: "a closed profile or a list of closed profiles (a profile inside another is a hole)",
        settings: &[
            SCAN_COMMON[0],
            SCAN_COMMON[1],
            SCAN_COMMON[2],
            SCAN_COMMON[3],
            SCAN_COMMON[4],
            SCAN_COMMON[5],
            SCAN_COMMON[6],
            SCAN_COMMON[7],
            SCAN_SETTLE[0],
            SCAN_SETTLE[1],
            SCAN_SETTLE[2],
            SCAN_SETTLE[3],
            SCAN_SETTLE[4],
            SCAN_SETTLE[5],
            set("pitch", L, "Spacing between hatch lines (required)."),
            set(
                "cross",
                PTy::Flag,
                "Cross-hatch: a second set of lines at `angle` + 90°, after the first in every pass (a flag: write `cross`; default off).",
            ),
            set(
                "inset",
                L,
                "Shrink the region by this much from every border first (outer borders move in, holes grow), with the offset machinery (default 0 mm).",
            ),
        ],
        doc: "A hatch fill: parallel lines `pitch` apart clipped to the region, lit at `speed`; with `pulse interval` in force the beam pulses along each line from its start.",
    },
    IMAGE_SCAN,
];

mod image;
use image::IMAGE_SCAN;
pub use image::{IMAGE_DITHERS, IMAGE_MODES};

pub fn scan_kind(name: &str) -> Option<&'static ScanKind> {
    SCAN_KINDS.iter().find(|k| k.name == name)
}

/// The type names usable in annotations.
pub const TYPE_NAMES: &[&str] = &[
    "number",
    "length",
    "time",
    "angle",
    "power",
    "speed",
    "accel",
    "acceleration",
    "jerk",
    "angular_speed",
    "angular_accel",
    "frequency",
    "energy",
    "bool",
    "string",
    "point",
    "profile",
    "list",
];

/// Statement keywords, for completion and docs.
pub const KEYWORDS: &[&str] = &[
    "machine", "limits", "let", "fn", "import", "use", "if", "else", "for", "in", "return",
    "laser", "pulse", "planner", "rotary", "move", "to", "by", "rapid", "at", "follow", "dwell",
    "mcode", "event", "output", "scan", "profile", "true", "false", "and", "or", "not", "closed",
    "cw", "ccw", "on", "off", "interval",
];
