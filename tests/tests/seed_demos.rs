//! The seed page's three demos, end to end: the simulated mat and robot driving its route
//! while `slam_core` maps, at a fixed seed and over 20 seeds.

mod common;

use common::{assert_tag_bounds, run_seed, SEEDS};
use host_sim::PoseMode;

const FIXED_SEED: u64 = 1;

/// Demo 1: the mapper takes the true pose. Seed: 0 error, 271 black cells all in place, 83 % of
/// the grid known.
fn check_truth(seed: u64) {
    let f = run_seed(PoseMode::Truth, seed).figures;
    // The pose is the truth, rounded to the core's micrometres and 2^-32 turns: zero to
    // within 10 um and 1e-6 degrees.
    assert!(f.errors.max_error_cm < 1e-3, "seed {seed}: {f:?}");
    assert!(
        f.errors.final_heading_error_deg < 1e-6,
        "seed {seed}: {f:?}"
    );
    assert_eq!(f.out_of_place, 0, "seed {seed}: {f:?}");
    assert!(
        f.known_grid_pct >= 78.0,
        "seed {seed}: known {}",
        f.known_grid_pct
    );
    // The mat itself, its margin left out, is nearly all seen.
    assert!(
        f.known_pct >= 95.0,
        "seed {seed}: mat known {}",
        f.known_pct
    );
    assert!(
        (440..=540).contains(&f.ticks),
        "seed {seed}: {} ticks",
        f.ticks
    );
    assert!(
        f.occupied > 150,
        "seed {seed}: the outline needs black cells: {f:?}"
    );
    assert_eq!(f.fixes, 0);
}

/// Demo 2: odometry alone. Seed: 10.2 cm and 9.1 degrees out at the end, walls out of place.
fn check_dead_reckoning(seed: u64) {
    let f = run_seed(PoseMode::DeadReckoning, seed).figures;
    assert!(
        (5.0..=15.0).contains(&f.errors.final_error_cm),
        "seed {seed}: final error {} cm",
        f.errors.final_error_cm
    );
    assert!(
        (5.0..=13.0).contains(&f.errors.final_heading_error_deg),
        "seed {seed}: final heading error {} deg",
        f.errors.final_heading_error_deg
    );
    assert!(
        f.out_of_place > 0,
        "seed {seed}: a smeared map has cells out of place"
    );
    assert_eq!(f.fixes, 0);
    assert_eq!(f.first_fix_s, None);
}

#[test]
fn truth_at_fixed_seed() {
    check_truth(FIXED_SEED);
}

#[test]
fn truth_over_20_seeds() {
    SEEDS.for_each(check_truth);
}

#[test]
fn dead_reckoning_at_fixed_seed() {
    check_dead_reckoning(FIXED_SEED);
}

#[test]
fn dead_reckoning_over_20_seeds() {
    SEEDS.for_each(check_dead_reckoning);
}

/// Demo 3: two-tag fixes. Seed: first fix at 14 s, 154 fixes, error never past 1.4 cm after
/// it, heading inside 2.8 degrees, every black cell in place.
#[test]
fn tags_over_20_seeds() {
    let mut clean_maps = 0;
    for seed in SEEDS {
        let tags = run_seed(PoseMode::Tags, seed);
        let f = &tags.figures;
        assert_tag_bounds(seed, f);
        clean_maps += usize::from(f.out_of_place == 0);

        // Until the first fix the tag run is the dead-reckoning run, tick for tick.
        let dr = run_seed(PoseMode::DeadReckoning, seed);
        let before: Vec<f64> = tags
            .record
            .ticks
            .iter()
            .take_while(|t| !t.fix_taken)
            .map(|t| t.error_cm)
            .collect();
        let dr_before: Vec<f64> = dr
            .record
            .ticks
            .iter()
            .take(before.len())
            .map(|t| t.error_cm)
            .collect();
        assert!(
            before.len() > 100,
            "seed {seed}: the first fix cannot come before the robot drives"
        );
        assert_eq!(
            before, dr_before,
            "seed {seed}: error curves differ before the first fix"
        );
        // And the fix is what makes the difference.
        assert!(
            dr.figures.errors.final_error_cm > 3.0 * f.errors.final_error_cm.max(1.0),
            "seed {seed}"
        );
    }
    assert!(
        clean_maps >= 19,
        "only {clean_maps} of 20 tag maps have no cell out of place"
    );
}

#[test]
fn tags_at_fixed_seed_keep_the_map_sharp() {
    let tags = run_seed(PoseMode::Tags, FIXED_SEED).figures;
    let truth = run_seed(PoseMode::Truth, FIXED_SEED).figures;
    assert_eq!(tags.out_of_place, 0, "{tags:?}");
    // The map is as complete as the perfect-pose one, within a few percent.
    assert!(
        (tags.known_pct - truth.known_pct).abs() < 3.0,
        "{} vs {}",
        tags.known_pct,
        truth.known_pct
    );
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let a = run_seed(PoseMode::Tags, 7);
    let b = run_seed(PoseMode::Tags, 7);
    assert_eq!(a.figures, b.figures);
    assert_eq!(a.record.ticks, b.record.ticks);
    let c = run_seed(PoseMode::Tags, 8);
    assert_ne!(
        a.record.ticks, c.record.ticks,
        "noise must depend on the seed"
    );
}

#[test]
fn the_firmware_and_the_scenario_agree_on_the_world() {
    let scenario = common::seed_scenario();
    let config = world::shipped::seed_robot().config;
    let start = host_sim::run::to_core_pose(&host_sim::robot::TruePose {
        x_mm: scenario.start.x_mm,
        y_mm: scenario.start.y_mm,
        heading_deg: scenario.start.heading_deg,
    });
    assert_eq!(start, world::shipped::seed_robot().start);
    assert_eq!(
        host_sim::run::slam_config(&scenario),
        config,
        "scenario and SlamConfig::seed_mat differ"
    );
}
