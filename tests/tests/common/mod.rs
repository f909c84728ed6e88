//! Shared helpers: the seed scenario and runs of it.

use host_sim::run::RunOutput;
use host_sim::{run, PoseMode, Scenario};
use std::path::PathBuf;

/// The seed's world and route, as shipped.
pub fn seed_scenario() -> Scenario {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../host-sim/scenarios/seed-mat.toml");
    match Scenario::load(&path) {
        Ok(s) => s,
        Err(e) => panic!("the shipped scenario must load: {e}"),
    }
}

/// One run of the seed scenario.
pub fn run_seed(mode: PoseMode, seed: u64) -> RunOutput {
    match run(&seed_scenario(), mode, seed) {
        Ok(o) => o,
        Err(e) => panic!("seed scenario must run: {e}"),
    }
}

/// The seeds the sweeps use.
pub const SEEDS: std::ops::RangeInclusive<u64> = 1..=20;
