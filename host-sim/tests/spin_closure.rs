//! A turn on the spot's closure (`slam_core::spin_closure`) on the simulator's sensors:
//! the first turn of every shipped route that starts with a full turn and has walls
//! within the depth sensor's reach at its ends, heading from dead reckoning, seeds 1 to
//! 20, against the true excess of the turn.

use host_sim::run::slam_config;
use host_sim::{run, PoseMode};
use slam_core::spin_closure::{measure, SpinScan};
use slam_core::Angle;
use world::shipped::scenario;

const WORLDS: [&str; 5] = [
    "tag-free-room",
    "seed-mat-no-tags",
    "two-wall-room",
    "blocked-route",
    "one-tag",
];

/// A heading in the record's degrees (clockwise from +y) as the core's angle.
fn angle(deg: f64) -> Angle {
    Angle::from_millidegrees((deg * 1000.0).round() as i64)
}

/// Unwrapped turn from `a` to `b`, degrees.
fn turned(a: f64, b: f64) -> f64 {
    (b - a + 180.0).rem_euclid(360.0) - 180.0
}

/// Each measured first turn: how far off the truth it was and its own standard
/// deviation, millidegrees.
fn first_turns(name: &str) -> Vec<(f64, f64)> {
    let s = scenario(&format!("{name}.toml"));
    let beams = slam_config(&s).depth.beam_angles;
    (1..=20)
        .map(|seed| {
            let out = run(&s, PoseMode::DeadReckoning, seed)
                .unwrap_or_else(|e| panic!("{name} seed {seed}: {e}"));
            let ticks = &out.record.ticks;
            let start = ticks[0].truth_mm;
            // The turn: every tick until the robot first moves off its start.
            let spin = ticks
                .iter()
                .take_while(|t| (t.truth_mm.0 - start.0).hypot(t.truth_mm.1 - start.1) <= 5.0)
                .count();
            let scans: Vec<SpinScan> = ticks[..spin]
                .iter()
                .zip(&out.frames)
                .map(|(t, f)| {
                    SpinScan::new(
                        angle(t.estimate_heading_deg),
                        &f.depth.map(|d| d.ranges_mm).unwrap_or_default(),
                    )
                })
                .collect();
            let (mut estimated, mut truth) = (0.0, 0.0);
            for w in ticks[..spin].windows(2) {
                estimated += turned(w[0].estimate_heading_deg, w[1].estimate_heading_deg);
                truth += turned(w[0].truth_heading_deg, w[1].truth_heading_deg);
            }
            let excess = (estimated.abs() - truth.abs()) * 1000.0;
            let closure = measure(&scans, &beams)
                .unwrap_or_else(|e| panic!("{name} seed {seed}: {e:?} over {spin} ticks"));
            (
                f64::from(closure.excess_mdeg) - excess,
                f64::from(closure.sd_mdeg),
            )
        })
        .collect()
}

/// Every first turn measured, and the truth within 3 of its own standard deviations on
/// at least 98 of the 100; on the two-wall room and the blocked route, whose turns end
/// facing corners, to under half a degree (a sixth of the seed gyro's 2.9 degrees).
#[test]
fn every_first_turn_measures_its_excess_within_its_own_spread() {
    let mut within = 0;
    let mut turns = 0;
    for name in WORLDS {
        let measured = first_turns(name);
        turns += measured.len();
        within += measured
            .iter()
            .filter(|(off, sd)| off.abs() <= 3.0 * sd)
            .count();
        if matches!(name, "two-wall-room" | "blocked-route") {
            let mut sds: Vec<f64> = measured.iter().map(|m| m.1).collect();
            sds.sort_by(f64::total_cmp);
            assert!(
                sds[sds.len() / 2] <= 500.0,
                "{name}: median sd {} mdeg",
                sds[sds.len() / 2]
            );
        }
    }
    assert!(
        within * 100 >= turns * 98,
        "{within} of {turns} within 3 sd"
    );
}
