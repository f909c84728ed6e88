//! The guard and the collisions (issue 12), on seeds 1 to 20: the shipped route that runs
//! at a box and a wall stops short of both with the guard and hits both without it, with
//! its map still clean; every other shipped route never comes near enough for the guard
//! to stop it, and never touches a wall.

use host_sim::fault::Fault;
use host_sim::run::{run_with, Guarding, RunOptions};
use host_sim::scenario::SHIPPED;
use host_sim::{Figures, PoseMode, Scenario};
use std::path::Path;
use world::shipped::scenario;

const SEEDS: std::ops::RangeInclusive<u64> = 1..=20;

/// The shipped scenario whose route would run into a box and a wall.
const BLOCKED: &str = "blocked-route.toml";

fn guarded(guarding: Guarding) -> RunOptions<'static> {
    RunOptions {
        guarding,
        ..RunOptions::default()
    }
}

fn figures(scenario: &Scenario, mode: PoseMode, seed: u64, guarding: Guarding) -> Figures {
    match run_with(scenario, mode, seed, guarded(guarding)) {
        Ok(out) => out.figures,
        Err(e) => panic!("{} seed {seed}: {e}", scenario.name),
    }
}

#[test]
fn the_guard_stops_short_of_the_box_and_the_wall_and_the_map_stays_clean() {
    let blocked = scenario(BLOCKED);
    // The filter is what the firmware flies; slam adds matching.
    for mode in [PoseMode::Filter, PoseMode::Slam] {
        for seed in SEEDS {
            let f = figures(&blocked, mode, seed, Guarding::On);
            assert_eq!(f.collisions, 0, "{mode:?} seed {seed}: {f:?}");
            assert_eq!(
                f.guard_stops, 2,
                "{mode:?} seed {seed}: one stop at the box, one at the wall: {f:?}"
            );
            assert!(f.out_of_place <= 1, "{mode:?} seed {seed}: {f:?}");
        }
    }
}

#[test]
fn without_the_guard_the_route_hits_the_box_and_the_wall() {
    let blocked = scenario(BLOCKED);
    for seed in SEEDS {
        let f = figures(&blocked, PoseMode::Filter, seed, Guarding::Off);
        assert_eq!((f.collisions, f.guard_stops), (2, 0), "seed {seed}: {f:?}");
    }
}

#[test]
fn no_other_shipped_route_comes_near_a_wall() {
    for name in SHIPPED.into_iter().filter(|n| *n != BLOCKED) {
        let s = scenario(name);
        // The route steers by the truth, so every pose mode drives it the same way; the
        // guard reads the filter's estimate, as on the robot.
        for seed in SEEDS {
            let f = figures(&s, PoseMode::Filter, seed, Guarding::On);
            assert_eq!((f.collisions, f.guard_stops), (0, 0), "{name} seed {seed}");
        }
    }
}

#[test]
fn a_depth_sensor_that_fails_before_the_box_is_seen_never_lets_the_robot_hit_it() {
    // The sensor fails 2 s into the first spin, before the fan has passed the box, and
    // for a minute: the drive at the box waits until it sees again (off, stuck, garbage:
    // blind), or stops at what a sensor it doubts sees (a range offset, doubted until a
    // tag vouches, which none in the fan ever does). Driven on the map alone, each hit
    // the box and drew a wall across the room.
    let blocked = scenario(BLOCKED);
    for kind in ["off", "stuck", "garbage", "wrong"] {
        let fault: Fault = match format!("depth-{kind}@2/60").parse() {
            Ok(f) => f,
            Err(e) => panic!("{e}"),
        };
        let faults = [fault];
        for seed in SEEDS {
            let options = RunOptions {
                faults: &faults,
                ..guarded(Guarding::On)
            };
            let f = match run_with(&blocked, PoseMode::Filter, seed, options) {
                Ok(out) => out.figures,
                Err(e) => panic!("{kind} seed {seed}: {e}"),
            };
            assert_eq!(
                (f.collisions, f.guard_stops),
                (0, 2),
                "{kind} seed {seed}: {f:?}"
            );
            // No wall across the room; a cell or two where the first tags after the
            // minute's wait and the drive in the dark leave the heading half a degree off
            // for a second (seed 1: 2, off and garbage, since a robot standing holds its
            // heading and the tags then find the drive's error in its position).
            assert!(f.out_of_place <= 2, "{kind} seed {seed}: {f:?}");
        }
    }
}

#[test]
fn a_body_that_meets_a_wall_stops_there_and_counts_one_collision() {
    // The seed mat, driven 30 s straight at the far wall blind: the centre stops one
    // radius short of the wall, and pushing on against it is the same collision.
    let mut s = scenario("seed-mat.toml");
    s.route = vec![host_sim::scenario::RouteStep::Drive {
        seconds: 30.0,
        speed_mm_s: 100.0,
    }];
    s.world.tags.clear();
    let out = match run_with(&s, PoseMode::Truth, 1, guarded(Guarding::Off)) {
        Ok(out) => out,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(out.figures.collisions, 1);
    let Some(last) = out.record.ticks.last() else {
        panic!("no ticks");
    };
    let gap = 2000.0 - last.truth_mm.1;
    assert!((gap - s.robot.radius_mm).abs() < 1.0, "{gap}");
    // With the guard it stops short instead: within the beams' safe distance at 100 mm/s
    // (105 mm) less a tick's travel, or up to a cell (50 mm) earlier by the map, which
    // takes an occupied cell as its centre.
    let guarded = match run_with(&s, PoseMode::Truth, 1, guarded(Guarding::On)) {
        Ok(out) => out,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(
        (guarded.figures.collisions, guarded.figures.guard_stops),
        (0, 1)
    );
    let Some(last) = guarded.record.ticks.last() else {
        panic!("no ticks");
    };
    let gap = 2000.0 - last.truth_mm.1;
    assert!((90.0..=160.0).contains(&gap), "{gap}");
}

#[test]
fn the_body_radius_defaults_to_the_seed_robots_and_is_checked() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-mat.toml");
    let seed = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) => panic!("{e}"),
    };
    let stated = "radius_mm = 60\n";
    assert!(seed.contains(stated));
    let without = seed.replace(stated, "");
    match Scenario::parse(&without) {
        Ok(s) => assert_eq!(s.robot.radius_mm, host_sim::scenario::SEED_RADIUS_MM),
        Err(e) => panic!("a file without robot.radius_mm must load: {e}"),
    }
    for (radius, field) in [
        ("nan", "robot.radius_mm"),
        ("0", "robot.radius_mm"),
        ("-5", "robot.radius_mm"),
        ("inf", "robot.radius_mm"),
        // The start is 500 mm from the near wall: a 600 mm body would be inside it.
        ("600", "start"),
    ] {
        let text = seed.replace(stated, &format!("radius_mm = {radius}\n"));
        match Scenario::parse(&text) {
            Ok(_) => panic!("radius {radius} must be refused"),
            Err(e) => assert!(
                e.to_string().contains(&format!("`{field}`")),
                "radius {radius}: {e}"
            ),
        }
    }
}
