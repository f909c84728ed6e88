//! The scenarios shipped in `host-sim/scenarios/`: their names, and the seed mat's text
//! built in, for the tests of the core and the simulator that fly the seed's world.

use crate::robot::RobotWorld;
use crate::scenario::Scenario;

/// The scenario files shipped in `host-sim/scenarios/`, by file name: what a test that
/// holds "every shipped scenario" to something goes through (a test checks that the list
/// and the directory agree).
pub const SHIPPED: [&str; 9] = [
    "seed-mat.toml",
    "seed-mat-rough.toml",
    "one-tag.toml",
    "two-wall-room.toml",
    "room-10m.toml",
    "seed-mat-no-tags.toml",
    "tag-free-room.toml",
    "corridor.toml",
    "blocked-route.toml",
];

/// The directory the shipped scenarios live in.
pub fn directory() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("host-sim")
        .join("scenarios")
}

/// The shipped scenario file `name` (one of [`SHIPPED`]), for tests. A shipped file that
/// does not load is a broken checkout, not input, so it panics naming the file.
pub fn scenario(name: &str) -> Scenario {
    let path = directory().join(name);
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("{}: {e}", path.display()),
    }
}

/// `host-sim/scenarios/seed-mat.toml`, built in.
pub const SEED_MAT_TOML: &str = include_str!("../../host-sim/scenarios/seed-mat.toml");

/// The seed mat's scenario. The file is built in and a test holds it valid, so a failure
/// here is a broken checkout, not input.
pub fn seed_mat() -> Scenario {
    match Scenario::parse(SEED_MAT_TOML) {
        Ok(s) => s,
        Err(e) => panic!("host-sim/scenarios/seed-mat.toml: {e}"),
    }
}

/// The seed mat as the robot is built for it (see [`seed_mat`]).
pub fn seed_robot() -> RobotWorld {
    match RobotWorld::of(&seed_mat()) {
        Ok(w) => w,
        Err(e) => panic!("host-sim/scenarios/seed-mat.toml: {e}"),
    }
}
