//! The lase standard library, embedded in the binary so `lase` works from any directory:
//! machine definitions (TOML), Rhai library modules (`use stdlib::cams`) and process presets
//! (`use stdlib::presets::cam_hardening`). A recipe names a stock machine (`machine xy_table`) or gives a
//! path to its own file, which then takes precedence.

/// The stock machines: name and TOML text.
pub const MACHINES: &[(&str, &str)] = &[
    ("xy_table", include_str!("../machines/xy_table.toml")),
    ("xy_rotary", include_str!("../machines/xy_rotary.toml")),
    ("xyz", include_str!("../machines/xyz.toml")),
    ("notcher", include_str!("../machines/notcher.toml")),
    ("cam_xwb", include_str!("../machines/cam_xwb.toml")),
    ("arm_3r", include_str!("../machines/arm_3r.toml")),
];

/// The TOML text of a stock machine.
pub fn machine(name: &str) -> Option<&'static str> {
    MACHINES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of the stock machines.
pub fn machine_names() -> impl Iterator<Item = &'static str> {
    MACHINES.iter().map(|(n, _)| *n)
}

/// The standard library's Rhai modules (`use stdlib::NAME`): name and source. They run in the
/// same sandbox as user extensions; their doc comments are their reference (`lase doc`).
pub const MODULES: &[(&str, &str)] = &[
    ("cams", include_str!("../lib/cams.rhai")),
    ("patterns", include_str!("../lib/patterns.rhai")),
];

/// The source of a standard library module.
pub fn module(name: &str) -> Option<&'static str> {
    MODULES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of the standard library modules.
pub fn module_names() -> impl Iterator<Item = &'static str> {
    MODULES.iter().map(|(n, _)| *n)
}

/// Process presets (`use stdlib::presets::NAME`): name and TOML text (values with units).
pub const PRESETS: &[(&str, &str)] = &[
    (
        "cam_hardening",
        include_str!("../presets/cam_hardening.toml"),
    ),
    (
        "material_test",
        include_str!("../presets/material_test.toml"),
    ),
    (
        "micro_texturing",
        include_str!("../presets/micro_texturing.toml"),
    ),
    (
        "notch_cutting",
        include_str!("../presets/notch_cutting.toml"),
    ),
];

/// The TOML text of a stock preset.
pub fn preset(name: &str) -> Option<&'static str> {
    PRESETS.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of the stock presets.
pub fn preset_names() -> impl Iterator<Item = &'static str> {
    PRESETS.iter().map(|(n, _)| *n)
}
