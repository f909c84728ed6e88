//! The fault matrix on the seed mat (issue 14): every sensor failing every way for 3 s,
//! 5 s into the route, on seeds 1 to 20, beside the same runs without the fault.

use host_sim::fault_matrix::{run_matrix, table, CaseFigures, Window};
use host_sim::run::PoseMode;

const WINDOW: Window = Window {
    start_s: 5.0,
    duration_s: 3.0,
};

fn matrix() -> Vec<CaseFigures> {
    let scenario = world::shipped::scenario("seed-mat.toml");
    let seeds: Vec<u64> = (1..=20).collect();
    run_matrix(&scenario, PoseMode::Filter, &seeds, WINDOW, None).expect("matrix")
}

#[test]
fn every_case_runs_on_every_seed_without_a_panic() {
    let cases = matrix();
    assert_eq!(cases.len(), 24, "4 sensors x 6 kinds");
    for c in &cases {
        assert_eq!((c.seeds, c.panics), (20, 0), "{}", table(&cases));
    }
    // The faults reach the core: losing the gyro mid-turn must show.
    let gyro_off = cases
        .iter()
        .find(|c| c.case == "gyro-off")
        .expect("gyro-off");
    assert!(!gyro_off.meets_targets(), "{}", table(&cases));
}

#[test]
#[ignore = "issue 14's targets: the robot does not yet stop trusting a failed input"]
fn every_case_keeps_the_map_and_recovers() {
    let cases = matrix();
    let missed: Vec<&str> = cases
        .iter()
        .filter(|c| !c.meets_targets())
        .map(|c| c.case.as_str())
        .collect();
    assert!(missed.is_empty(), "missed: {missed:?}\n{}", table(&cases));
}
