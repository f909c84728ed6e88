//! The demo command line: figures as JSON, and clear refusals of bad input.

mod common;

use common::{host_sim, scratch_dir, scratch_file, seed_path, SCORED_FIGURES};

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-cli-";

fn seed_text() -> String {
    std::fs::read_to_string(seed_path()).unwrap_or_default()
}

/// Runs a scenario that must be refused: exit code 2, no panic, and `field` named.
fn refused(name: &str, text: &str, field: &str) {
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, name, text);
    let out = host_sim(&["run", path.to_str().unwrap_or_default(), "--json"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{name}: {err}");
    assert!(
        err.contains(field),
        "{name}: error should name `{field}`: {err}"
    );
    assert!(!err.contains("panicked"), "{name}: {err}");
    assert!(
        out.stdout.is_empty(),
        "{name}: no figures for a bad scenario"
    );
}

#[test]
fn json_has_every_figure() {
    let out = host_sim(&[
        "run",
        seed_path().to_str().unwrap_or_default(),
        "--pose",
        "tags",
        "--seed",
        "3",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = match serde_json::from_slice(&out.stdout) {
        Ok(v) => v,
        Err(e) => panic!("not JSON: {e}: {}", String::from_utf8_lossy(&out.stdout)),
    };
    for key in ["ticks"].into_iter().chain(SCORED_FIGURES) {
        assert!(v.get(key).is_some(), "missing `{key}` in {v}");
    }
    assert!(v["ticks"].as_u64().unwrap_or(0) > 400);
    let dr = host_sim(&[
        "run",
        seed_path().to_str().unwrap_or_default(),
        "--pose",
        "dead-reckoning",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&dr.stdout).unwrap_or_default();
    assert!(v["first_fix_s"].is_null(), "no fix without tags: {v}");
}

#[test]
fn summary_reads_like_the_seed() {
    let out = host_sim(&[
        "run",
        seed_path().to_str().unwrap_or_default(),
        "--pose",
        "truth",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("free ") && text.contains("occupied ") && text.contains("out of place 0"),
        "{text}"
    );
}

#[test]
fn bad_arguments_are_refused() {
    for args in [
        vec!["run"],
        vec!["run", "x.toml", "--pose", "sideways"],
        vec!["run", "x.toml", "--seed", "-1"],
        vec!["run", "x.toml", "--seed"],
        vec!["fly"],
    ] {
        let out = host_sim(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    }
    let out = host_sim(&["run", "/nonexistent/scenario.toml"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read"));
}

#[test]
fn every_subcommand_has_help() {
    for args in [
        vec!["--help"],
        vec!["run", "--help"],
        vec!["view", "--help"],
        vec!["serve", "--help"],
        vec!["bench", "--help"],
        vec!["help", "run"],
    ] {
        let out = host_sim(&args);
        let text = String::from_utf8_lossy(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {text}");
        assert!(text.contains("Usage: host-sim"), "{args:?}: {text}");
    }
    // The defaults are the ones the README and the firmware assume.
    let view = host_sim(&["view", "--help"]);
    let text = String::from_utf8_lossy(&view.stdout);
    assert!(text.contains("[default: 921600]"), "{text}");
    let run = host_sim(&["run", "--help"]);
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(text.contains("[default: tags]"), "{text}");
}

#[test]
fn an_unknown_subcommand_is_named() {
    let out = host_sim(&["frobnicate"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("frobnicate"), "{err}");
}

#[test]
fn an_unknown_option_is_named() {
    for sub in ["run", "view", "serve", "bench"] {
        let out = host_sim(&[sub, "x.toml", "--frobnicate"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{sub}: {err}");
        assert!(err.contains("--frobnicate"), "{sub}: {err}");
    }
    // A bad value names its option and the value.
    let out = host_sim(&["run", "x.toml", "--pose", "sideways"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--pose") && err.contains("sideways"), "{err}");
    for bad in ["0", "-5", "nan", "inf"] {
        let out = host_sim(&["view", "x.bin", "--seconds", bad]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("--seconds"), "{bad}: {err}");
    }
    let out = host_sim(&["view", "x.bin", "--baud", "0"]);
    assert_eq!(out.status.code(), Some(2));
}

#[test]
fn missing_field_is_named() {
    refused(
        "missing.toml",
        &seed_text().replace("noise_dps = 0.1\n", ""),
        "noise_dps",
    );
}

#[test]
fn wrong_type_is_named() {
    refused(
        "type.toml",
        &seed_text().replace("noise_mm = 5", "noise_mm = \"five\""),
        "noise_mm",
    );
}

#[test]
fn nan_is_refused() {
    refused(
        "nan.toml",
        &seed_text().replace("bias_dps = 0.02", "bias_dps = nan"),
        "sensors.gyro.bias_dps",
    );
}

#[test]
fn negative_and_absurd_values_are_refused() {
    refused(
        "neg.toml",
        &seed_text().replace("max_range_mm = 1500", "max_range_mm = -1500"),
        "sensors.camera.max_range_mm",
    );
    refused(
        "rate.toml",
        &seed_text().replacen("rate_dps = 31.5", "rate_dps = 0", 1),
        "route[0].rate_dps",
    );
    refused(
        "drop.toml",
        &seed_text().replace("dropout = 0.02", "dropout = 7"),
        "sensors.tof.dropout",
    );
    refused(
        "wall.toml",
        &seed_text().replace("[[0, 0], [2000, 0]]", "[[0, 0], [1e300, 0]]"),
        "world.walls[0][1][0]",
    );
    refused(
        "cell.toml",
        &seed_text().replace("cell_mm = 50", "cell_mm = 0"),
        "grid.cell_mm",
    );
    refused(
        "dup.toml",
        &seed_text().replace("id = 12", "id = 11"),
        "world.tags[1].id",
    );
    refused(
        "unknown.toml",
        &seed_text().replace("seed = 1", "seed = 1\ncolour = \"red\""),
        "colour",
    );
}

#[test]
fn garbage_file_is_refused() {
    refused(
        "garbage.toml",
        "\u{0}\u{1}not toml at all [[[",
        "scenario is not valid",
    );
}

#[test]
fn camera_latency_is_checked() {
    let with = |value: &str| {
        seed_text().replace(
            "distance_noise_mm = 2\n",
            &format!("distance_noise_mm = 2\nlatency_ms = {value}\n"),
        )
    };
    refused("latency-neg.toml", &with("-5"), "sensors.camera.latency_ms");
    refused(
        "latency-big.toml",
        &with("5000"),
        "sensors.camera.latency_ms",
    );
    refused(
        "latency-nan.toml",
        &with("nan"),
        "sensors.camera.latency_ms",
    );
    refused("latency-text.toml", &with("\"slow\""), "latency_ms");
    // A good value runs.
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "latency-ok.toml", with("100"));
    let out = host_sim(&["run", path.to_str().unwrap_or_default(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_name_that_would_leave_the_out_dir_is_refused() {
    let dir = scratch_dir(SCRATCH);
    for (file, name) in [
        ("name-abs.toml", "/abs/x"),
        ("name-up.toml", "../../x"),
        ("name-sep.toml", "a/b"),
        ("name-hidden.toml", ".x"),
        ("name-empty.toml", ""),
    ] {
        let text = seed_text().replace("name = \"seed-mat\"", &format!("name = \"{name}\""));
        let path = scratch_file(&dir, file, &text);
        let out_dir = path.with_file_name(format!("{file}-out"));
        let out = host_sim(&[
            "run",
            path.to_str().unwrap_or_default(),
            "--out",
            out_dir.to_str().unwrap_or_default(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains("field `name`"), "{name}: {err}");
        assert!(!out_dir.exists(), "{name}: nothing is written");
    }
}

#[test]
fn the_world_must_lie_on_its_grid() {
    // Origins past the world: every wall is below and left of the grid.
    refused(
        "origin-x.toml",
        &seed_text().replace("origin_x_mm = -150", "origin_x_mm = 99000"),
        "world.walls[0][0]",
    );
    refused(
        "origin-xy.toml",
        &seed_text()
            .replace("origin_x_mm = -150", "origin_x_mm = 99000")
            .replace("origin_y_mm = -150", "origin_y_mm = 99000"),
        "grid.origin_x_mm",
    );
    refused(
        "tag-outside.toml",
        &seed_text().replace("x_mm = 1500", "x_mm = -500"),
        "world.tags[1]",
    );
    refused(
        "start-outside.toml",
        &seed_text().replace("x_mm = 700\ny_mm = 500", "x_mm = 700\ny_mm = -900"),
        "start",
    );
    // Past the far side of the largest grid: the furthest point is named.
    refused(
        "wall-far.toml",
        &seed_text().replace("[[0, 0], [2000, 0]]", "[[0, 0], [20000, 0]]"),
        "world.walls[0][1]",
    );
    refused(
        "start-far.toml",
        &seed_text().replace("x_mm = 700\ny_mm = 500", "x_mm = 700\ny_mm = 50000"),
        "start",
    );
}

#[test]
fn the_start_inside_a_wall_is_refused() {
    refused(
        "start-wall.toml",
        &seed_text().replace("x_mm = 700\ny_mm = 500", "x_mm = 700\ny_mm = 10"),
        "world.walls[0]",
    );
    refused(
        "start-card.toml",
        &seed_text().replace("x_mm = 700\ny_mm = 500", "x_mm = 1500\ny_mm = 1930"),
        "world.tags[1]",
    );
}

#[test]
fn a_wall_is_two_points_of_two_numbers() {
    refused(
        "wall-three-points.toml",
        &seed_text().replace("[[0, 0], [2000, 0]]", "[[0, 0], [2000, 0], [5, 5]]"),
        "world.walls[0]: a wall is two points",
    );
    refused(
        "wall-three-numbers.toml",
        &seed_text().replace("[[2000, 0], [2000, 2000]]", "[[2000, 0, 7], [2000, 2000]]"),
        "world.walls[1]: a point is [x, y]",
    );
    refused(
        "wall-one-point.toml",
        &seed_text().replace("[[2000, 0], [2000, 2000]]", "[[2000, 0]]"),
        "world.walls[1]",
    );
}

#[test]
fn numbers_the_core_checks_are_checked_first() {
    refused(
        "focal.toml",
        &seed_text().replace("focal_px = 92.4", "focal_px = 0.001"),
        "sensors.camera.focal_px",
    );
    refused(
        "width.toml",
        &seed_text().replace("width_px = 320", "width_px = 0.001"),
        "sensors.camera.width_px",
    );
    refused(
        "flow-small.toml",
        &seed_text().replace("um_per_count = 100", "um_per_count = 0.000001"),
        "sensors.flow.um_per_count",
    );
    refused(
        "flow-big.toml",
        &seed_text().replace("um_per_count = 100", "um_per_count = 50000"),
        "sensors.flow.um_per_count",
    );
}

#[test]
fn a_route_longer_than_a_run_is_refused_before_it_runs() {
    let text = seed_text().replace("seconds = 7", "seconds = 3000");
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "route-long.toml", &text);
    let started = std::time::Instant::now();
    let out = host_sim(&["run", path.to_str().unwrap_or_default(), "--json"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("field `route`") && err.contains("6034.") && err.contains("3600 s"),
        "{err}"
    );
    assert!(err.contains("route-long.toml"), "the file is named: {err}");
    assert!(out.stdout.is_empty());
    assert!(started.elapsed() < std::time::Duration::from_secs(5));
    // The seed's own route is planned to the tick it runs.
    let scenario = host_sim::Scenario::load(&seed_path()).expect("seed scenario loads");
    assert_eq!(host_sim::route::planned_ticks(&scenario.route, 0.1), 485);
}

#[test]
fn a_fault_is_injected_or_its_error_names_what_is_wrong() {
    let seed = seed_path();
    let seed = seed.to_str().expect("utf-8 path");
    for (bad, want) in [
        ("lidar-off@1", "unknown sensor `lidar`"),
        ("gyro-sideways@1", "unknown fault kind `sideways`"),
        ("gyro-off@-1/2", "bad fault time"),
        ("gyro-off", "SENSOR-KIND@START"),
    ] {
        let out = host_sim(&["run", seed, "--fault", bad]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(
            err.contains("--fault") && err.contains(want),
            "{bad}: {err}"
        );
    }
    // The gyro lost for most of the first turn: the route holds while it is out (so the
    // fault reached the core), and the pose and the map are kept.
    let json = |args: &[&str]| -> serde_json::Value {
        let out = host_sim(args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("json")
    };
    let healthy = json(&["run", seed, "--pose", "filter", "--json"]);
    let faulty = json(&[
        "run",
        seed,
        "--pose",
        "filter",
        "--json",
        "--fault",
        "gyro-off@1/8",
    ]);
    let figure = |v: &serde_json::Value, name: &str| v[name].as_f64().unwrap_or(f64::NAN);
    let held = figure(&faulty, "held_ticks");
    assert!((80.0..=90.0).contains(&held), "{faulty}");
    assert!(healthy.get("held_ticks").is_none(), "{healthy}");
    let heading = |v: &serde_json::Value| figure(v, "max_heading_error_deg");
    assert!(
        heading(&faulty) < heading(&healthy) + 1.0,
        "{faulty} vs {healthy}"
    );
    assert_eq!(faulty["out_of_place"], healthy["out_of_place"]);
}
