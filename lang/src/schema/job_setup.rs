//! Issue 20's job-setup words: where a job's zero is (`planner { origin }`) and the object
//! on a rotary attachment (`rotary { diameter }`).

use super::{L, SettingSpec, set};

/// Job origins of `planner { origin ... }`: the named work offsets G54–G59 too.
pub const JOB_ORIGINS: &[&str] = &[
    "absolute", "current", "g54", "g55", "g56", "g57", "g58", "g59",
];

/// `rotary { ... }`: the object on a rotary attachment.
pub const ROTARY_SETTINGS: &[SettingSpec] = &[set(
    "diameter",
    L,
    "The object's diameter on a machine with a rotary attachment (`kinematics = \"rotary\"`): \
     the recipe's y is the unrolled surface around it, and a chuck turns the object by \
     y / radius (a roller by y / the roller's radius, whatever the object's diameter). \
     Default: the machine file's `[rotary] diameter`. Set it before the first move.",
)];
