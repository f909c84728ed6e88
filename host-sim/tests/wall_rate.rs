//! The flow sensor's scale from a wall ahead (`slam_core::wall_rate`) on the simulator's
//! sensors: every straight drive at a wall of the shipped worlds that have one within
//! reach, seeds 1 to 20, against the true scale error.

use host_sim::run::slam_config;
use host_sim::{run, PoseMode};
use slam_core::wall_rate::{fit_wall, FlowScale, WallRate};
use slam_core::Trust;
use world::shipped::scenario;

/// Every shipped world.
const WORLDS: [&str; 9] = [
    "seed-mat",
    "seed-mat-no-tags",
    "seed-mat-rough",
    "one-tag",
    "two-wall-room",
    "room-10m",
    "blocked-route",
    "tag-free-room",
    "corridor",
];

/// Those whose drives end at a wall within a couple of metres, square to them: the
/// scale to half a percent there.
const NEAR_WALLS: [&str; 4] = [
    "seed-mat-no-tags",
    "two-wall-room",
    "room-10m",
    "blocked-route",
];

/// Each world's drives judged over seeds 1 to 20, and the true correction, ppm.
fn drives(name: &str) -> (Vec<FlowScale>, f64) {
    let s = scenario(&format!("{name}.toml"));
    let config = slam_config(&s);
    let truth = (1.0 / (1.0 + s.sensors.flow.scale_error) - 1.0) * 1e6;
    let mut judged = Vec::new();
    for seed in 1..=20 {
        let out = run(&s, PoseMode::DeadReckoning, seed)
            .unwrap_or_else(|e| panic!("{name} seed {seed}: {e}"));
        let mut rate = WallRate::default();
        for f in &out.frames {
            judged.extend(rate.observe(
                f,
                config.odometry.flow_um_per_count_q16,
                || {
                    f.depth
                        .as_ref()
                        .and_then(|s| fit_wall(s, &config.depth.beam_angles))
                },
                &Trust::default(),
            ));
        }
    }
    (judged, truth)
}

/// Over every world's drives, the truth within 3 of their own standard deviations on at
/// least 97 % of them; where the walls ahead are near and square, to half a percent rms
/// of the true 4.17 % (a tenth of the error), every run giving at least one drive.
#[test]
fn a_drive_at_a_wall_measures_the_flow_scale_within_its_own_spread() {
    let (mut within, mut all) = (0, 0);
    for name in WORLDS {
        let (judged, truth) = drives(name);
        let offs: Vec<f64> = judged
            .iter()
            .map(|d| f64::from(d.scale_ppm) - truth)
            .collect();
        within += judged
            .iter()
            .zip(&offs)
            .filter(|(d, o)| o.abs() <= 3.0 * f64::from(d.sd_ppm))
            .count();
        all += judged.len();
        if NEAR_WALLS.contains(&name) {
            assert!(
                judged.len() >= 20,
                "{name}: {} drives over 20 runs",
                judged.len()
            );
            let rms = (offs.iter().map(|o| o * o).sum::<f64>() / offs.len() as f64).sqrt();
            assert!(
                rms <= 5_000.0,
                "{name}: rms {rms:.0} ppm over {} drives",
                judged.len()
            );
        }
    }
    assert!(
        within * 100 >= all * 97,
        "{within} of {all} drives within 3 sd"
    );
}
