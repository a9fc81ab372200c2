//! Language reference text rendered from `lase_lang::schema`, the one table of builtin
//! functions, profile kinds and statement settings with their docs. The REPL's `:help` shows
//! it; `lase doc` (the stdlib reference) is meant to render the same topics through
//! [`render`], so the two never disagree.

use lase_lang::schema::{self, Builtin, PTy, ParamSpec, ProfileKind, Ret, SettingSpec};
use lase_lang::units::{self, Dim};
use std::fmt::Write as _;

/// Statement settings lists, by the statement that takes them.
const SETTING_GROUPS: &[(&str, &[SettingSpec], &str)] = &[
    (
        "laser",
        schema::LASER_SETTINGS,
        "`laser { power 40 W, spot 50 um }` sets the beam for what follows; `laser on` / `laser off` light `move ... at` moves.",
    ),
    (
        "follow",
        schema::FOLLOW_SETTINGS,
        "`follow PATH at 20 mm/s { power 60 W }`: rapid to the path's start with the beam off, then trace it lit. The settings apply to this path only.",
    ),
    (
        "pulse",
        schema::PULSE_SETTINGS,
        "`pulse interval 0.2 mm`, `pulse { rate 20 kHz, width 100 ns }`, `pulse off`: pulses by distance (position-synchronized) or by time.",
    ),
    (
        "planner",
        schema::PLANNER_SETTINGS,
        "`planner { ramp scurve, corner 0.01 mm, tolerance 2 um }`: how motion is planned.",
    ),
    (
        "rotary",
        schema::ROTARY_SETTINGS,
        "`rotary { diameter 60 mm }`: the object on a rotary attachment; the recipe's y is its unrolled surface.",
    ),
    (
        "limits",
        schema::LIMIT_SETTINGS,
        "`limits { x: v 200 mm/s, a 2 m/s^2; path: v 50 mm/s }`: tighten axis (or path) limits, never above the machine's.",
    ),
];

/// Statements without settings lists, with one line each.
const STATEMENTS: &[(&str, &str)] = &[
    (
        "machine",
        "`machine xy_table` or `machine \"my.toml\"`: the machine the recipe runs on. Stock machines: STOCK_MACHINES (`lase doc machines`).",
    ),
    (
        "let",
        "`let name = expr`, optionally typed: `let d: length = 2 mm`.",
    ),
    (
        "fn",
        "`fn name(a: length, b) -> profile { ... return expr }`; call with positional or named arguments.",
    ),
    (
        "import",
        "`import \"file.lase\"` brings a file's `let` and `fn` definitions in.",
    ),
    (
        "use",
        "`use \"file.rhai\"`, `use stdlib::cams`, `use stdlib::presets::cam_hardening`: Rhai extension functions or preset values; `lase doc extensions`.",
    ),
    (
        "return",
        "`return expr` ends a `fn` with its value; a `fn` without one returns nothing.",
    ),
    ("if", "`if cond { } else if cond { } else { }`."),
    (
        "for",
        "`for i in 0..n { }`, `0..=n`, `for p in list { }`. The same clause builds a list: `[x * 2 for x in xs if x > 0 mm]` (map and filter in one form; at most 1 000 000 items).",
    ),
    (
        "move",
        "`move to P rapid`, `move to P at 5 mm/s`, `move by V ...`: positioning.",
    ),
    ("dwell", "`dwell 0.5 s`: standstill."),
    (
        "mcode",
        "`mcode 8 \"air assist\"`: a raw M-function (the machine stops for it).",
    ),
    (
        "event",
        "`event swing_right`: a named machine event, translated by the machine file.",
    ),
    (
        "output",
        "`output air on` / `output air off`: a machine file's `[outputs.air]` (air assist, exhaust), written per dialect; the table stops for it only where that controller stops.",
    ),
    (
        "profile",
        "`profile KIND ...`: a profile value; `:help profiles` lists the kinds.",
    ),
];

/// The topics `render` knows, for completion.
pub fn topics() -> Vec<&'static str> {
    let mut t = vec![
        "functions",
        "profiles",
        "settings",
        "statements",
        "units",
        "types",
        "constants",
    ];
    t.extend(schema::BUILTINS.iter().map(|b| b.name));
    t.extend(schema::PROFILE_KINDS.iter().map(|k| k.name));
    t.extend(SETTING_GROUPS.iter().map(|g| g.0));
    t.extend(STATEMENTS.iter().map(|s| s.0));
    t.extend(schema::CONSTANTS.iter().map(|c| c.0));
    t.push("scan");
    t.push("machines");
    t.push("trace");
    t.extend(schema::SCAN_KINDS.iter().map(|k| k.name));
    t.sort_unstable();
    t.dedup();
    t
}

/// The reference text of one topic (`None`: the index), or `None` for an unknown topic.
pub fn render(topic: Option<&str>) -> Option<String> {
    let mut out = String::new();
    let Some(topic) = topic else {
        index(&mut out);
        return Some(out);
    };
    let topic = topic.trim().trim_end_matches("()");
    match topic {
        "functions" | "builtins" | "stdlib" => {
            for b in schema::BUILTINS {
                builtin(&mut out, b);
            }
        }
        "profiles" => {
            for k in schema::PROFILE_KINDS.iter().filter(|k| !k.unsupported) {
                profile_kind(&mut out, k);
            }
        }
        "settings" => {
            for (name, specs, doc) in SETTING_GROUPS {
                settings(&mut out, name, specs, doc);
            }
            scan_kinds(&mut out);
        }
        "scan" | "scan dots" | "scan raster" | "dots" | "raster" => {
            let kind = topic.trim_start_matches("scan").trim();
            if kind.is_empty() {
                wrap(&mut out, SCAN_INTRO, 0);
            }
            for k in schema::SCAN_KINDS
                .iter()
                .filter(|k| kind.is_empty() || k.name == kind)
            {
                scan_kind(&mut out, k);
            }
        }
        "statements" | "keywords" => {
            for (name, doc) in STATEMENTS {
                let _ = writeln!(out, "{name}");
                wrap(&mut out, &statement_doc(doc), 2);
            }
            for (name, _, doc) in SETTING_GROUPS {
                let _ = writeln!(out, "{name}");
                wrap(&mut out, doc, 2);
            }
            let _ = writeln!(out, "scan");
            wrap(&mut out, SCAN_INTRO, 2);
        }
        "units" => units_table(&mut out),
        "types" => {
            let _ = writeln!(
                out,
                "type annotations (`let d: length = 2 mm`, `fn f(a: speed)`):"
            );
            wrap(&mut out, &schema::TYPE_NAMES.join(", "), 2);
        }
        "constants" => {
            for (name, v, doc) in schema::CONSTANTS {
                let _ = writeln!(out, "{name} = {}  {doc}", units::format_number(*v));
            }
        }
        // Every kind of `scan`, or one of them (`scan image`, or `image` alone).
        "scans" => {
            for k in schema::SCAN_KINDS {
                scan_kind(&mut out, k);
            }
        }
        t if schema::scan_kind(t.trim_start_matches("scan ").trim()).is_some() => {
            scan_kind(
                &mut out,
                schema::scan_kind(t.trim_start_matches("scan ").trim()).expect("matched"),
            );
        }
        other => {
            let mut found = false;
            if let Some(b) = schema::builtin(other) {
                builtin(&mut out, b);
                found = true;
            }
            if let Some(k) = schema::profile_kind(other) {
                profile_kind(&mut out, k);
                found = true;
            }
            if let Some((name, specs, doc)) = SETTING_GROUPS.iter().find(|g| g.0 == other) {
                settings(&mut out, name, specs, doc);
                found = true;
            }
            if let Some((name, doc)) = STATEMENTS.iter().find(|s| s.0 == other)
                && !found
            {
                let _ = writeln!(out, "{name}");
                wrap(&mut out, &statement_doc(doc), 2);
                found = true;
            }
            if let Some((name, v, doc)) = schema::CONSTANTS.iter().find(|c| c.0 == other) {
                let _ = writeln!(out, "{name} = {}  {doc}", units::format_number(*v));
                found = true;
            }
            if !found {
                return None;
            }
        }
    }
    Some(out)
}

/// The closest topic to a misspelt one.
pub fn suggest(topic: &str) -> Option<&'static str> {
    units::suggest(topic, topics().into_iter())
}

fn index(out: &mut String) {
    let _ = writeln!(
        out,
        "topics: functions, profiles, settings, statements, units, types, constants"
    );
    let names = |it: &mut dyn Iterator<Item = &'static str>| it.collect::<Vec<_>>().join(", ");
    let _ = writeln!(out, "functions");
    wrap(out, &names(&mut schema::BUILTINS.iter().map(|b| b.name)), 2);
    let _ = writeln!(out, "profiles");
    wrap(
        out,
        &names(
            &mut schema::PROFILE_KINDS
                .iter()
                .filter(|k| !k.unsupported)
                .map(|k| k.name),
        ),
        2,
    );
    let _ = writeln!(out, "statements");
    wrap(
        out,
        &names(
            &mut STATEMENTS
                .iter()
                .map(|s| s.0)
                .chain(SETTING_GROUPS.iter().map(|g| g.0))
                .chain(["scan"]),
        ),
        2,
    );
}

/// `scan`'s one-paragraph summary; each kind's region and settings come from the schema.
const SCAN_INTRO: &str = "Two kinds: `scan dots REGION {...}` fires a dot array (texturing, PROCESS.md §3), `scan raster REGION {...}` fills the region with hatch lines. Rows run along `angle`, each extended by `overscan` so it is passed at `speed`; the pulse settings in force fire the spots. Each kind's own topic lists its settings with their units and defaults.";

/// A statement's line with the stock machine names filled in from the standard library, so
/// the list cannot fall behind `stdlib/machines`.
fn statement_doc(doc: &str) -> String {
    doc.replace(
        "STOCK_MACHINES",
        &lase_stdlib::machine_names().collect::<Vec<_>>().join(", "),
    )
}

/// `scan KIND`: what the region may be, the kind's doc and every setting with its type.
fn scan_kind(out: &mut String, k: &schema::ScanKind) {
    let _ = writeln!(out, "scan {} REGION {{ settings }}", k.name);
    wrap(out, k.doc, 2);
    wrap(out, &format!("REGION: {}.", k.region), 2);
    let w = k.settings.iter().map(|s| s.key.len()).max().unwrap_or(0);
    for s in k.settings {
        let _ = writeln!(out, "  {:<w$}  {}", s.key, ty(s.ty));
        wrap(out, s.doc, w + 6);
    }
}

fn scan_kinds(out: &mut String) {
    for k in schema::SCAN_KINDS {
        scan_kind(out, k);
    }
}

fn ty(t: PTy) -> String {
    t.describe()
}

fn ret(r: Ret) -> String {
    match r {
        Ret::Dim(d) => lase_lang::Ty::Num(d).describe(),
        Ret::Point => "a point".into(),
        Ret::Profile => "a profile".into(),
        Ret::Points => "a list of points".into(),
        Ret::Str => "a string".into(),
        Ret::Profiles => "a list of profiles".into(),
        Ret::SameAsFirst => "the first argument's kind".into(),
        Ret::SqrtOfFirst => "the square root of the first argument's dimension".into(),
    }
}

/// `offset(profile, distance)`, optional parameters in brackets.
pub fn signature(name: &str, params: &[ParamSpec]) -> String {
    let ps: Vec<String> = params
        .iter()
        .map(|p| {
            if p.required {
                p.name.to_string()
            } else {
                format!("[{}]", p.name)
            }
        })
        .collect();
    format!("{name}({})", ps.join(", "))
}

fn params(out: &mut String, params: &[ParamSpec]) {
    let w = params.iter().map(|p| p.name.len()).max().unwrap_or(0);
    for p in params {
        let _ = writeln!(
            out,
            "  {:<w$}  {}{}",
            p.name,
            ty(p.ty),
            if p.required { "" } else { " (optional)" }
        );
    }
}

fn builtin(out: &mut String, b: &Builtin) {
    let _ = writeln!(out, "{} → {}", signature(b.name, b.params), ret(b.ret));
    params(out, b.params);
    wrap(out, b.doc, 2);
}

fn profile_kind(out: &mut String, k: &ProfileKind) {
    let flags = if k.flags.is_empty() {
        String::new()
    } else {
        format!(" [{}]", k.flags.join(" | "))
    };
    let _ = writeln!(out, "profile {}{flags}", signature(k.name, k.params));
    params(out, k.params);
    wrap(out, k.doc, 2);
}

fn settings(out: &mut String, name: &str, specs: &[SettingSpec], doc: &str) {
    let _ = writeln!(out, "{name}");
    wrap(out, doc, 2);
    let w = specs.iter().map(|s| s.key.len()).max().unwrap_or(0);
    for s in specs {
        let _ = writeln!(out, "  {:<w$}  {}", s.key, ty(s.ty));
        wrap(out, s.doc, w + 6);
    }
}

fn units_table(out: &mut String) {
    let _ = writeln!(
        out,
        "numbers carry units; combine them with `/`, `*`, `^` (20 mm/s, 2 m/s^2)"
    );
    let dims = [
        Dim::LENGTH,
        Dim::TIME,
        Dim::ANGLE,
        Dim::POWER,
        Dim::FREQUENCY,
        Dim::ENERGY,
        Dim::ANGULAR_SPEED,
    ];
    for d in dims {
        let names: Vec<&str> = units::unit_names()
            .filter(|n| units::parse_unit(n).is_ok_and(|u| u.dim == d))
            .collect();
        let _ = writeln!(out, "  {:<14} {}", d.name(), names.join(" "));
    }
}

/// Word-wraps `text` at 80 columns with `indent` spaces.
fn wrap(out: &mut String, text: &str, indent: usize) {
    let mut line = String::new();
    for word in text.split_whitespace() {
        if !line.is_empty() && indent + line.len() + 1 + word.len() > 80 {
            let _ = writeln!(out, "{:indent$}{line}", "");
            line.clear();
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        let _ = writeln!(out, "{:indent$}{line}", "");
    }
}

// ---------------------------------------------------------------- stdlib, extensions, `lase doc`

/// What extensions can use inside Rhai (registered in `lase_runtime::ext`), one line each.
const EXTENSION_API: &[(&str, &str)] = &[
    (
        "numbers",
        "plain floats in lase's internal units: mm, s, rad, W (mm/s, ...); `deg(x)` degrees → rad, `to_deg(x)`, `um(x)` µm → mm; math: sin cos tan sqrt abs floor PI() ...",
    ),
    (
        "point",
        "`point(x, y)`, `point(x, y, z)`, `polar(r, a)`; `p.x p.y p.z`; `+ - * /` with numbers; `norm(p)`, `distance(a, b)`, `dot(a, b)`",
    ),
    (
        "profile",
        "`p.length()`, `p.point_at(s)`, `p.tangent_at(s)`, `p.normal_at(s)` (concave side), `p.curvature_at(s)`, `p.offset(d)`, `p.sample(n)` (n points equally spaced by arc length), `p.start()`, `p.end()`, `p.is_closed()`",
    ),
    (
        "constructors",
        "`polyline(points, closed)`, `spline(points, closed)` (interpolating cubic B-spline), `circle(center, r)`",
    ),
    (
        "generators",
        "`polar_profile(|theta| radius, samples)`: a closed spline through r(θ) for θ in [0, 2π); `parametric_profile(|t| point, t0, t1, samples, closed)`",
    ),
    (
        "cam laws",
        "`cam_law(law, u)` → [s, v, a] of \"harmonic\", \"cycloidal\", \"poly345\", \"modified_trapezoid\"; `cam_lift(segments, theta)` → [lift, dlift/dθ, d²lift/dθ²]; `cam_profile(base, segments, samples)`; a segment is `#{kind: \"rise\"|\"dwell\"|\"return\", law, duration (rad), lift (mm)}`",
    ),
    (
        "sandbox",
        "no files, network, processes, clock, `import` or `eval`; per call at most 1 000 000 operations, 24 nested calls, arrays of 100 000 items (nested ones counted), maps of 10 000, strings of 16 KiB; a runaway extension is stopped with a diagnostic at the recipe line that called it",
    ),
];

const EXTENSIONS_INTRO: &str = "`use \"file.rhai\"` makes the module's functions callable from the recipe; `use stdlib::cams`, `use stdlib::patterns` load the standard library's modules; `use stdlib::presets::NAME` (or `use \"file.toml\"`) binds a preset's values as variables, which a later `let` overrides. A Rhai function is callable when a doc comment line declares its signature in recipe types: `/// lase: (theta: angle, rise: length) -> length` (types: number, length, angle, time, speed, power, ..., point, profile, bool, string, list, [T] for a list of T). Arguments cross as floats in the internal unit of their declared dimension (an angle in rad, a length in mm) and the result gets the declared dimension back; the checker checks calls against the signature.";

/// Standard library topics: `extensions`, `stdlib`, `stdlib::cams` (or `cams`), `presets`,
/// `stdlib::presets::NAME`, `machines`.
pub fn stdlib_topic(topic: &str) -> Option<String> {
    let mut out = String::new();
    let topic = topic.trim();
    let module = topic.strip_prefix("stdlib::").unwrap_or(topic);
    if topic == "extensions" || topic == "use" || topic == "rhai" {
        let _ = writeln!(out, "use");
        wrap(&mut out, EXTENSIONS_INTRO, 2);
        let _ = writeln!(out, "inside Rhai");
        for (name, doc) in EXTENSION_API {
            let _ = writeln!(out, "  {name}");
            wrap(&mut out, doc, 4);
        }
    } else if topic == "stdlib" || topic == "modules" {
        for m in lase_stdlib::module_names() {
            out.push_str(&stdlib_topic(m)?);
        }
    } else if let Some(sigs) = lase_runtime::ext::Extensions::stdlib_signatures(module) {
        let _ = writeln!(out, "use stdlib::{module}");
        for s in &sigs {
            let _ = writeln!(out, "  {}", lase_runtime::ext::describe(s));
            wrap(&mut out, &s.doc, 4);
        }
    } else if topic == "presets" {
        for p in lase_stdlib::preset_names() {
            out.push_str(&stdlib_topic(&format!("presets::{p}"))?);
        }
    } else if let Some(name) = module.strip_prefix("presets::") {
        let text = lase_stdlib::preset(name)?;
        let _ = writeln!(out, "use stdlib::presets::{name}");
        if let Some(d) = text.lines().find_map(|l| l.strip_prefix("doc = ")) {
            wrap(&mut out, d.trim().trim_matches('"'), 2);
        }
        // The value lines with their comments, as written.
        let mut in_values = false;
        for line in text.lines() {
            if line.trim() == "[values]" {
                in_values = true;
            } else if in_values && !line.trim().is_empty() && !line.starts_with('#') {
                let _ = writeln!(out, "  {}", line.trim());
            }
        }
    } else if topic == "machines" {
        for m in lase_stdlib::machine_names() {
            let text = lase_stdlib::machine(m)?;
            let desc = text
                .lines()
                .find_map(|l| l.strip_prefix("description = "))
                .unwrap_or("")
                .trim_matches('"');
            let _ = writeln!(out, "  {m:<10} {desc}");
        }
        wrap(
            &mut out,
            "`machine NAME` selects one; `machine \"file.toml\"` takes your own. stdlib/machines/README.md documents every field.",
            2,
        );
    } else if topic == "trace" {
        // The columns of `lase plan --trace` (report::write_trace), issue 15.
        let _ = writeln!(
            out,
            "lase plan FILE --trace OUT.csv [--period 1ms]: one row per period, and one at the cycle's end"
        );
        for (col, doc) in TRACE_COLUMNS {
            let _ = writeln!(out, "  {col:<8} {doc}");
        }
    } else {
        return None;
    }
    Some(out)
}

/// The trace's columns and what each holds.
const TRACE_COLUMNS: &[(&str, &str)] = &[
    ("t", "job time, s"),
    (
        "<axes>",
        "each machine axis by its name, mm (deg for rotary axes)",
    ),
    ("px py pz", "the spot in part coordinates, mm"),
    ("v a", "path speed (mm/s) and acceleration (mm/s^2)"),
    (
        "laser",
        "1 while a lit move runs (the beam of the path), else 0",
    ),
    (
        "power",
        "laser power, W (0 when off; P_set * v / F when coupled to speed)",
    ),
    (
        "pulses",
        "pulses fired at or before t, on the fly and in dot mode alike: a dot-mode window \
         fires at rest with `laser` 0, so its pulses show here, where the spot stands",
    ),
];

/// `lase doc [NAME]`: the language topics of [`render`] and the standard library's.
pub fn lookup(topic: Option<&str>) -> Option<String> {
    match topic {
        None => {
            let mut s = render(None)?;
            let _ = writeln!(
                s,
                "standard library\n  extensions, stdlib::cams, stdlib::patterns, presets, machines"
            );
            Some(s)
        }
        // The statement and the stock machines it can name, with their descriptions.
        Some("machine") => Some(render(Some("machine"))? + stdlib_topic("machines")?.as_str()),
        Some(t) => render(Some(t))
            .or_else(|| stdlib_topic(t))
            .or_else(|| setting_topic(t)),
    }
}

/// A setting by its key alone (`:help standoff`): every statement that takes it, with its doc.
fn setting_topic(key: &str) -> Option<String> {
    use lase_lang::schema;
    let mut tables: Vec<(String, &[schema::SettingSpec])> = vec![
        ("laser".into(), schema::LASER_SETTINGS),
        ("follow".into(), schema::FOLLOW_SETTINGS),
        ("pulse".into(), schema::PULSE_SETTINGS),
        ("planner".into(), schema::PLANNER_SETTINGS),
        ("limits".into(), schema::LIMIT_SETTINGS),
        ("rotary".into(), schema::ROTARY_SETTINGS),
    ];
    for k in schema::SCAN_KINDS {
        tables.push((format!("scan {}", k.name), k.settings));
    }
    let mut out = String::new();
    for (stmt, table) in tables {
        for spec in table.iter().filter(|s| s.key == key) {
            let _ = writeln!(
                out,
                "{stmt} {{ {key} ... }}  ({})\n    {}",
                spec.ty.describe(),
                spec.doc
            );
        }
    }
    (!out.is_empty()).then_some(out)
}

/// The whole reference as Markdown: `docs/reference.md` is this text (a test keeps it so).
pub fn reference_markdown() -> String {
    let mut out = String::from(
        "# lase reference\n\n<!-- Generated from lang/src/schema.rs, lang/src/units.rs and the \
         standard library by `lase doc --markdown`; do not edit. -->\n\nEvery topic is also \
         printed by `lase doc TOPIC` and the REPL's `:help TOPIC`.\n",
    );
    let sections: &[(&str, &str)] = &[
        ("Statements", "statements"),
        ("Statement settings", "settings"),
        ("Functions", "functions"),
        ("Profiles", "profiles"),
        ("Units", "units"),
        ("Types", "types"),
        ("Constants", "constants"),
        ("Extensions (Rhai)", "extensions"),
    ];
    // Every stdlib module gets its section, so a new one cannot be left out.
    let modules: Vec<String> = lase_stdlib::module_names()
        .map(|m| format!("stdlib::{m}"))
        .collect();
    let tail: &[(&str, &str)] = &[
        ("Process presets", "presets"),
        ("Machines", "machines"),
        ("Trace columns", "trace"),
    ];
    let sections = sections
        .iter()
        .map(|&(t, k)| (t, k))
        .chain(modules.iter().map(|m| (m.as_str(), m.as_str())))
        .chain(tail.iter().copied());
    for (title, topic) in sections {
        let body = lookup(Some(topic)).unwrap_or_default();
        let _ = write!(out, "\n## {title}\n\n```text\n{body}```\n");
    }
    out
}
