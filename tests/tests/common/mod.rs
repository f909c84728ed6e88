//! Shared helpers: the seed scenario and runs of it.

use host_sim::run::{Figures, RunOutput};
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

/// The seed demo's bounds on a tag run, after its first fix: first fix at 12-16 s,
/// 100-220 fixes, the pose within 2 cm and 3.5 degrees of the truth.
pub fn assert_tag_bounds(seed: u64, f: &Figures) {
    let first = f.first_fix_s.unwrap_or(f64::NAN);
    assert!(
        (12.0..=16.0).contains(&first),
        "seed {seed}: first fix at {first} s"
    );
    assert!(
        (100..=220).contains(&f.fixes),
        "seed {seed}: {} fixes",
        f.fixes
    );
    assert!(
        f.errors.max_error_after_first_fix_cm <= 2.0,
        "seed {seed}: {} cm after first fix",
        f.errors.max_error_after_first_fix_cm
    );
    assert!(
        f.errors.max_heading_error_after_first_fix_deg <= 3.5,
        "seed {seed}: {} deg after first fix",
        f.errors.max_heading_error_after_first_fix_deg
    );
}

/// The seeds the sweeps use.
pub const SEEDS: std::ops::RangeInclusive<u64> = 1..=20;
