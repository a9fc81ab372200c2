//! The lase standard library, embedded in the binary so `lase` works from any directory:
//! machine definitions (TOML). A recipe names a stock machine (`machine xy_table`) or gives a
//! path to its own file, which then takes precedence.

/// The stock machines: name and TOML text.
pub const MACHINES: &[(&str, &str)] = &[
    ("xy_table", include_str!("../machines/xy_table.toml")),
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
