//! End to end without the simulator: `Slam<46, 46>` on the seed mat driven round a square
//! with perfect odometry and perfect depth ranges ray-cast by the reference.

mod reference;

use reference::{bits_to_rad, Geometry, RefPose};
use slam_core::{
    DepthScan, FixOutcome, FlowDelta, GyroRate, Occupancy, Pose, SensorFrame, Slam, TagDetection,
};

const DT_US: u32 = 100_000;

/// One tick's inputs: flow counts forward and gyro millidegrees per second.
type Tick = (i32, i32);

/// A square of 1 m sides from (500, 500) mm facing the far wall, clockwise: 1 m forward
/// at 10 mm per tick (100 counts of 100 um), then a right turn of 90 degrees in 10 ticks
/// (90 deg/s), four times: 440 ticks.
fn square_route() -> Vec<Tick> {
    let mut ticks = Vec::new();
    for _ in 0..4 {
        ticks.extend(std::iter::repeat_n((100, 0), 100));
        ticks.extend(std::iter::repeat_n((0, 90_000), 10));
    }
    ticks
}

/// The tag detections a perfect camera at `truth` reports (both tags, if both are in its
/// 120 degree view), quantised to 0.01 px and 1 mm.
fn tags_seen(truth: &RefPose) -> Vec<TagDetection> {
    let (x, y) = (truth.x_um / 1000.0, truth.y_um / 1000.0);
    let mut out = Vec::new();
    for (id, place) in [(11u16, (700.0, 1950.0)), (12, (1500.0, 1950.0))] {
        let s = reference::see(x, y, truth.heading, place);
        if reference::bearing(s.cx_px).abs() > 55f64.to_radians() || s.cx_px.is_nan() {
            return Vec::new();
        }
        let dir = reference::heading_of(place.0 - x, place.1 - y);
        if reference::angle_diff(dir, truth.heading).abs() > 60f64.to_radians() {
            return Vec::new();
        }
        out.push(TagDetection {
            id,
            cx_centipx: (s.cx_px * 100.0).round() as i32,
            distance_mm: s.distance_mm.round() as u32,
        });
    }
    out
}

struct Run {
    slam: Slam<46, 46>,
    truth: RefPose,
    outcomes: Vec<FixOutcome>,
}

fn drive(with_tags: bool) -> Run {
    let start = Pose::from_mm_mdeg(500, 500, 0);
    let mut slam: Slam<46, 46> =
        Slam::new(unchecked(world::shipped::seed_robot().config), start).unwrap();
    assert_eq!(slam.config().localiser, slam_core::Localiser::TwoTagFix);
    let mut truth = RefPose {
        x_um: 500_000.0,
        y_um: 500_000.0,
        heading: 0.0,
    };
    let mut outcomes = Vec::new();
    for (counts, rate) in square_route() {
        truth = reference::odometry_tick(truth, Some((counts, 0)), Some(rate), DT_US, 100.0);
        let ranges_mm = reference::mat_scan(&truth);
        let mut frame = SensorFrame::empty(DT_US);
        frame.flow = Some(FlowDelta {
            forward_counts: counts,
            right_counts: 0,
        });
        frame.gyro = Some(GyroRate { rate_mdps: rate });
        frame.depth = Some(DepthScan { ranges_mm });
        if with_tags {
            frame.tags = tags_seen(&truth).iter().copied().collect();
        }
        let report = slam.step(&frame);
        outcomes.push(report.fix);
        assert_eq!(report.counters.beams_invalid, 0);
    }
    Run {
        slam,
        truth,
        outcomes,
    }
}

/// Every occupied cell's centre lies within 5 cm of a wall (a hit on a wall lands in a cell
/// whose centre is 25 mm from it, plus pose and rounding error), the walls are actually
/// seen (at least 60 occupied cells: the square's four walls span 160 cells), and the space
/// the beams swept is free.
fn check_map(slam: &Slam<46, 46>) {
    let map = slam.map();
    let g = Geometry::SEED;
    let mut occupied = 0;
    for r in 0..46 {
        for c in 0..46 {
            if map.occupancy(c, r) == Occupancy::Occupied {
                occupied += 1;
                let (x, y) = g.centre((c, r));
                let d = reference::distance_to_walls(x, y);
                assert!(
                    d <= 50.0,
                    "occupied cell ({c}, {r}) at ({x}, {y}) mm is {d} mm from the walls"
                );
            }
        }
    }
    assert!(occupied >= 60, "only {occupied} occupied cells");
    let counts = map.counts();
    assert_eq!(counts.occupied, occupied);
    assert!(counts.free >= 100, "only {} free cells", counts.free);
    // Ahead of the first leg, between the route and the far wall.
    let (c, r) = map.geometry().cell_of(500, 1800);
    assert_eq!(map.occupancy(c, r), Occupancy::Free);
    println!("map: {counts:?}");
}

/// Perfect odometry, no tags in view (fixes enabled, nothing to fix from): after the loop
/// the pose is within 1 mm and 0.01 degrees of the reference-integrated pose.
#[test]
fn square_with_perfect_odometry() {
    let run = drive(false);
    assert!(run.outcomes.iter().all(|o| *o == FixOutcome::NotAttempted));
    let p = run.slam.pose();
    let err_um = (p.x_um as f64 - run.truth.x_um).hypot(p.y_um as f64 - run.truth.y_um);
    let err_deg = reference::angle_diff(bits_to_rad(p.heading.bits()), run.truth.heading)
        .to_degrees()
        .abs();
    println!("after the square: {err_um:.1} um, {err_deg:.2e} deg from the reference");
    assert!(
        err_um < 1000.0,
        "pose {p:?} is {err_um} um from the reference"
    );
    assert!(err_deg < 0.01);
    // Back where it started.
    assert!((run.truth.x_um - 500_000.0).abs() < 1.0 && (run.truth.y_um - 500_000.0).abs() < 1.0);
    check_map(&run.slam);
}

/// The same loop with the camera's perfect (quantised) tag sightings: fixes are taken
/// whenever both tags are in view, each leaves the pose within the tag fix's bound of the
/// truth (7 mm, 0.25 degrees; see `tagfix_props.rs`), and the map is as clean.
#[test]
fn square_with_tag_fixes() {
    let run = drive(true);
    let taken = run
        .outcomes
        .iter()
        .filter(|o| **o == FixOutcome::Taken)
        .count();
    assert!(taken >= 50, "only {taken} fixes taken");
    assert!(run
        .outcomes
        .iter()
        .all(|o| matches!(o, FixOutcome::Taken | FixOutcome::NotAttempted)));
    assert_eq!(run.slam.counters().fixes_taken as usize, taken);
    let p = run.slam.pose();
    let err_mm = (p.x_um as f64 - run.truth.x_um).hypot(p.y_um as f64 - run.truth.y_um) / 1000.0;
    let err_deg = reference::angle_diff(bits_to_rad(p.heading.bits()), run.truth.heading)
        .to_degrees()
        .abs();
    println!("with {taken} fixes: {err_mm:.2} mm, {err_deg:.3} deg from the truth");
    assert!(err_mm < 7.0 && err_deg < 0.25);
    check_map(&run.slam);
}

/// `config` without the plausibility checks (`slam_core::plausible`): these inputs are
/// synthetic (constant rates, repeated frames, a robot that never holds), and the checks
/// are not what this file tests.
fn unchecked(config: slam_core::SlamConfig) -> slam_core::SlamConfig {
    slam_core::SlamConfig {
        plausible: None,
        ..config
    }
}
