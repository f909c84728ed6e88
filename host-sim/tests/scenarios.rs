//! The shipped scenarios, a world without tags, the robot's failings as scenario options,
//! and the run's largest heading error.

mod common;

use common::{host_sim, scratch_dir, scratch_file, seed_path, SCORED_FIGURES};
use host_sim::scenario::SHIPPED;
use host_sim::{run, Figures, PoseMode, Scenario};
use std::path::{Path, PathBuf};

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-scenarios-";

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenarios")
        .join(name)
}

fn load(name: &str) -> Scenario {
    match Scenario::load(&shipped(name)) {
        Ok(s) => s,
        Err(e) => panic!("{name} must load: {e}"),
    }
}

fn figures(scenario: &Scenario, mode: PoseMode) -> Figures {
    match run(scenario, mode, 1) {
        Ok(out) => out.figures,
        Err(e) => panic!("{}: {e}", scenario.name),
    }
}

fn seed_text() -> String {
    std::fs::read_to_string(seed_path()).unwrap_or_default()
}

/// `host-sim run FILE --json` with `extra` arguments: the exit code, stdout and stderr.
fn run_cli(path: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec!["run", path.to_str().unwrap_or_default(), "--json"];
    args.extend_from_slice(extra);
    let out = host_sim(&args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn the_shipped_list_is_the_directory_and_every_one_loads() {
    let mut listed: Vec<String> = SHIPPED.iter().map(|s| s.to_string()).collect();
    let mut found: Vec<String> = std::fs::read_dir(shipped(""))
        .map(|dir| {
            dir.filter_map(Result::ok)
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".toml"))
                .collect()
        })
        .unwrap_or_default();
    listed.sort();
    found.sort();
    assert_eq!(listed, found);
    for name in SHIPPED {
        let s = load(name);
        assert_eq!(
            format!("{}.toml", s.name),
            name,
            "a scenario is named as its file"
        );
    }
}

#[test]
fn a_file_longer_than_any_scenario_is_refused_unread() {
    let (code, out, err) = run_cli(Path::new("/dev/zero"), &[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("longer than") && out.is_empty(), "{err}");
}

#[test]
fn a_world_may_have_no_tags() {
    let tagless: String = seed_text()
        .split("[[world.tags]]")
        .enumerate()
        .map(|(i, part)| match i {
            0 => part.to_string(),
            // Drop each tag's five lines, keep what follows them.
            _ => part
                .split_once("\n\n")
                .map_or("", |(_, rest)| rest)
                .to_string(),
        })
        .collect();
    assert!(!tagless.contains("tags") && tagless.contains("[start]"));
    let scenario = match Scenario::parse(&tagless) {
        Ok(s) => s,
        Err(e) => panic!("a world without tags must load: {e}"),
    };
    assert!(scenario.world.tags.is_empty());
    let f = figures(&scenario, PoseMode::Tags);
    assert_eq!((f.ticks, f.fixes, f.first_fix_s), (485, 0, None), "{f:?}");
    assert!(f.occupied > 100, "the core maps: {f:?}");
    // The command line takes it too.
    let dir = scratch_dir(SCRATCH);
    let (code, out, err) = run_cli(&scratch_file(&dir, "tagless.toml", &tagless), &[]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap_or_default();
    assert_eq!(v["fixes"].as_u64(), Some(0), "{v}");
}

#[test]
fn one_tag_never_gives_the_two_tag_fix() {
    let s = load("one-tag.toml");
    assert_eq!(s.world.tags.len(), 1);
    assert_eq!(s.world.tags[0].id, 11);
    let tags = figures(&s, PoseMode::Tags);
    let dr = figures(&s, PoseMode::DeadReckoning);
    assert_eq!(tags.fixes, 0, "{tags:?}");
    assert_eq!(tags, dr, "with one tag, `tags` is dead reckoning");
}

#[test]
fn the_two_wall_room_has_its_tags_come_and_go() {
    let s = load("two-wall-room.toml");
    let facings: Vec<f64> = s.world.tags.iter().map(|t| t.facing_deg).collect();
    assert!(
        facings.windows(2).any(|w| w[0] != w[1]),
        "tags on two different walls: {facings:?}"
    );
    let truth = figures(&s, PoseMode::Truth);
    assert!(truth.duration_s >= 90.0, "{truth:?}");
    assert_eq!(truth.out_of_place, 0, "the grid covers the room: {truth:?}");
    let tags = figures(&s, PoseMode::Tags);
    // No tag is in view at the start; both are at some point; not all the way round.
    let first = tags.first_fix_s.unwrap_or(0.0);
    assert!(first > 10.0, "{tags:?}");
    assert!(
        tags.fixes > 10 && (tags.fixes as usize) < tags.ticks / 2,
        "{tags:?}"
    );
}

/// The true path of a run of `scenario` on seed 1, one point a tick, millimetres.
fn true_path(scenario: &Scenario) -> Vec<(f64, f64, f64)> {
    match run(scenario, PoseMode::Truth, 1) {
        Ok(out) => out
            .record
            .ticks
            .iter()
            .map(|t| (t.t_s, t.truth_mm.0, t.truth_mm.1))
            .collect(),
        Err(e) => panic!("{}: {e}", scenario.name),
    }
}

/// The extent of a scenario's walls, `(x, y)` millimetres.
fn extent(scenario: &Scenario) -> (f64, f64) {
    let points = || scenario.world.walls.iter().flatten();
    let span = |axis: usize| {
        let lo = points().map(|p| p[axis]).fold(f64::INFINITY, f64::min);
        let hi = points().map(|p| p[axis]).fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    };
    (span(0), span(1))
}

#[test]
fn the_seed_mat_without_tags_is_the_seed_mat_without_its_tags() {
    let seed = load("seed-mat.toml");
    let mut bare = load("seed-mat-no-tags.toml");
    assert!(bare.world.tags.is_empty());
    bare.name = seed.name.clone();
    bare.world.tags = seed.world.tags.clone();
    assert_eq!(bare, seed, "only the tags differ");
}

#[test]
fn the_tag_free_room_is_a_room_with_inner_walls_driven_round_twice() {
    let s = load("tag-free-room.toml");
    assert!(s.world.tags.is_empty());
    let (w, h) = extent(&s);
    assert!(w >= 3000.0 && h >= 3000.0, "at least 3 m x 3 m: {w} x {h}");
    assert!(s.world.walls.len() > 4, "inner walls or boxes");
    let path = true_path(&s);
    let duration = path.last().map_or(0.0, |p| p.0);
    assert!(duration >= 180.0, "at least 3 minutes: {duration} s");
    // The same places twice: most of the second half of the run passes within 10 cm of
    // where the robot was in the first half.
    let (first, second) = path.split_at(path.len() / 2);
    let revisits = second
        .iter()
        .filter(|p| first.iter().any(|q| (p.1 - q.1).hypot(p.2 - q.2) < 100.0))
        .count();
    assert!(
        revisits * 10 >= second.len() * 8,
        "{revisits} of {}",
        second.len()
    );
    // Nothing but the depth sensor's own failings puts a cell out of place.
    let truth = figures(&s, PoseMode::Truth);
    assert!(
        truth.out_of_place * 100 <= truth.occupied,
        "with the true pose, at most 1 % out of place: {truth:?}"
    );
}

#[test]
fn the_corridor_has_a_stretch_where_only_the_side_walls_are_seen() {
    let s = load("corridor.toml");
    assert!(s.world.tags.is_empty());
    let (long, wide) = extent(&s);
    assert!(
        wide <= 1500.0 && long > wide,
        "a corridor along x: {long} x {wide} mm"
    );
    // Somewhere on the route both end walls are beyond the sensor's range, so nothing
    // says how far along the corridor the robot is.
    let reach = s.sensors.tof.max_range_mm;
    let blind = true_path(&s)
        .iter()
        .filter(|&&(_, x, _)| x > reach && long - x > reach)
        .count();
    assert!(blind >= 100, "{blind} ticks with no end wall in range");
    let truth = figures(&s, PoseMode::Truth);
    assert_eq!(truth.out_of_place, 0, "{truth:?}");
}

#[test]
fn the_rough_mat_is_the_seed_mat_with_the_failings() {
    let seed = load("seed-mat.toml");
    let rough = load("seed-mat-rough.toml");
    assert_eq!(rough.world, seed.world);
    assert_eq!(rough.route, seed.route);
    assert!(rough.robot.slip.is_some());
    assert_ne!(rough.sensors.flow.offset_mm, [0.0, 0.0]);
    assert!(rough.sensors.gyro.bias_walk_dps_per_sqrt_s > 0.0);
    // Only the failings differ.
    let mut plain = rough.clone();
    plain.name = seed.name.clone();
    plain.robot.slip = None;
    plain.sensors.flow.offset_mm = [0.0, 0.0];
    plain.sensors.gyro.bias_walk_dps_per_sqrt_s = 0.0;
    assert_eq!(plain, seed);
    let truth = figures(&rough, PoseMode::Truth);
    assert_eq!(truth.out_of_place, 0, "{truth:?}");
    let dr = figures(&rough, PoseMode::DeadReckoning);
    let seed_dr = figures(&seed, PoseMode::DeadReckoning);
    // The failings change what the robot reads (the sensor's swing in each turn is taken
    // off by the core, which is told where the sensor sits; slip and the wandering bias
    // are not).
    assert_ne!(
        dr.errors.max_error_cm, seed_dr.errors.max_error_cm,
        "{dr:?}"
    );
    // The filter holds the rough mat to the 2 cm and 1.5 degrees.
    let slam = figures(&rough, PoseMode::Slam);
    assert!(slam.errors.max_error_cm <= 2.0, "{slam:?}");
    assert!(slam.errors.max_heading_error_deg <= 1.5, "{slam:?}");
    assert_eq!(slam.out_of_place, 0, "{slam:?}");
}

#[test]
fn bad_failings_are_refused_by_name() {
    let dir = scratch_dir(SCRATCH);
    let seed = seed_text();
    let slip = "wheel_base_mm = 100\n\n[robot.slip]\nspells_per_min = 4\nspell_s = 0.4\n\
                speed_loss = 0.3\nskid_mm_per_turn = 5\n";
    for (name, text, field) in [
        (
            "offset3.toml",
            seed.replace("quality = 120", "quality = 120\noffset_mm = [1, 2, 3]"),
            "offset_mm",
        ),
        (
            "offset_far.toml",
            seed.replace("quality = 120", "quality = 120\noffset_mm = [0, 900]"),
            "sensors.flow.offset_mm[1]",
        ),
        (
            "walk.toml",
            seed.replace(
                "noise_dps = 0.1",
                "noise_dps = 0.1\nbias_walk_dps_per_sqrt_s = -1",
            ),
            "sensors.gyro.bias_walk_dps_per_sqrt_s",
        ),
        (
            "loss.toml",
            seed.replace("wheel_base_mm = 100\n", &slip.replace("0.3", "1.5")),
            "robot.slip.speed_loss",
        ),
        (
            "spell.toml",
            seed.replace("wheel_base_mm = 100\n", &slip.replace("0.4", "0")),
            "robot.slip.spell_s",
        ),
        (
            "skid.toml",
            seed.replace("wheel_base_mm = 100\n", &slip.replace("= 5", "= nan")),
            "robot.slip.skid_mm_per_turn",
        ),
        (
            "range_noise.toml",
            seed.replace("dropout = 0.02", "dropout = 0.02\nnoise_per_m_mm = -1"),
            "sensors.tof.noise_per_m_mm",
        ),
        (
            "mixed.toml",
            seed.replace("dropout = 0.02", "dropout = 0.02\nmixed_edge = 2"),
            "sensors.tof.mixed_edge",
        ),
        (
            "rate_slow.toml",
            seed.replace("dropout = 0.02", "dropout = 0.02\nrate_hz = 0.5"),
            "sensors.tof.rate_hz",
        ),
        (
            "rate_nan.toml",
            seed.replace("dropout = 0.02", "dropout = 0.02\nrate_hz = nan"),
            "sensors.tof.rate_hz",
        ),
        (
            "slip_missing.toml",
            seed.replace(
                "wheel_base_mm = 100\n",
                &slip.replace("spells_per_min = 4\n", ""),
            ),
            "spells_per_min",
        ),
    ] {
        assert_ne!(text, seed, "{name}: the replacement must apply");
        let (code, out, err) = run_cli(&scratch_file(&dir, name, &text), &[]);
        assert_eq!(code, Some(2), "{name}: {err}");
        assert!(err.contains(field), "{name}: should name `{field}`: {err}");
        assert!(!err.contains("panicked") && out.is_empty(), "{name}: {err}");
    }
    // The same table, well formed, runs.
    let good = seed.replace("wheel_base_mm = 100\n", slip);
    let (code, _, err) = run_cli(&scratch_file(&dir, "slip.toml", &good), &[]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn the_largest_heading_error_covers_the_whole_run() {
    let (code, out, err) = run_cli(&seed_path(), &["--pose", "tags"]);
    assert_eq!(code, Some(0), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap_or_default();
    let get = |key: &str| match v[key].as_f64() {
        Some(x) => x,
        None => panic!("no `{key}` in {v}"),
    };
    for key in SCORED_FIGURES {
        assert!(v.get(key).is_some(), "no `{key}` in {v}");
    }
    let max = get("max_heading_error_deg");
    // Before the first fix the seed route drifts further than after it.
    assert!(max >= get("max_heading_error_after_first_fix_deg"), "{v}");
    assert!(max >= get("final_heading_error_deg"), "{v}");
    assert!(max > 2.0 && max < 20.0, "{v}");
    // With the true pose there is none to speak of.
    let truth = figures(&load("seed-mat.toml"), PoseMode::Truth);
    assert!(truth.errors.max_heading_error_deg < 1e-3, "{truth:?}");
}
