//! The telemetry stream end to end: the simulator writes what the robot would send, the
//! viewer reads it back and gets the run's own pose and map.

mod common;

use common::{host_sim, seed_path, SCORED_FIGURES};
use host_sim::run::{run, PoseMode, RunOutput};
use host_sim::telemetry::decode_bytes;
use host_sim::Scenario;
use std::path::{Path, PathBuf};
use tempfile::TempDir;

/// A directory for a test's files, removed when the test ends, passed or failed.
fn scratch(name: &str) -> TempDir {
    TempDir::with_prefix(format!("host-sim-telemetry-{name}-")).expect("scratch dir")
}

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap_or_default()
}

/// Runs the seed scenario with `--telemetry` and returns the stream's bytes.
fn recorded_stream(dir: &Path) -> Vec<u8> {
    let file = dir.join("seed.bin");
    let out = host_sim(&[
        "run",
        path_str(&seed_path()),
        "--pose",
        "tags",
        "--telemetry",
        path_str(&file),
        "--json",
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read(&file).unwrap_or_default()
}

#[test]
fn the_viewer_gets_the_run_back() {
    let tmp = scratch("roundtrip");
    let dir = tmp.path();
    let bytes = recorded_stream(dir);
    assert!(!bytes.is_empty(), "no stream written");

    // The same run in the library, for the figures to hold the stream to.
    let scenario = Scenario::load(&seed_path()).expect("seed scenario loads");
    let output = run(&scenario, PoseMode::Tags, scenario.seed).expect("seed runs");
    let run_ticks = output.record.ticks.len();
    let last = output.record.ticks.last().expect("ticks");

    let recording = decode_bytes(&bytes);
    let stats = *recording.decoder.stats();
    assert_eq!(stats.bad_frames.total(), 0, "{stats:?}");
    assert!(!recording.decoder.has_partial_frame());
    let recorder = &recording.recorder;
    assert_eq!(recorder.tick_count(), run_ticks);

    let tick = recorder.last_tick().expect("a tick");
    assert!((f64::from(tick.x_um) - last.estimate_mm.0 * 1000.0).abs() <= 1.0);
    assert!((f64::from(tick.y_um) - last.estimate_mm.1 * 1000.0).abs() <= 1.0);
    let heading = f64::from(tick.pose().heading.to_microdegrees()) / 1e6;
    assert!((heading - last.estimate_heading_deg).abs() < 1e-6);

    // The map rebuilt from MapRows is the run's final map, belief for belief.
    let record = recorder.record("seed");
    assert_eq!(
        (record.map.width, record.map.height),
        (output.record.map.width, output.record.map.height)
    );
    assert_eq!(record.map.cells, output.record.map.cells);
    assert_eq!(record.map.cell_mm, output.record.map.cell_mm);
    assert_eq!(record.map.origin_x_mm, output.record.map.origin_x_mm);

    // Without the world the share out of place is unknown; with it, the last tick carries
    // the final map's, as `run`'s last tick does (the map picture's title shows it).
    assert!(record
        .ticks
        .last()
        .is_some_and(|t| t.out_of_place_pct.is_nan()));
    let mut scored = decode_bytes(&bytes);
    scored.recorder = scored
        .recorder
        .with_world(host_sim::world::World::new(&scenario));
    let scored = scored.recorder.record("seed");
    let (ours, theirs) = (
        scored.ticks.last().map_or(f64::NAN, |t| t.out_of_place_pct),
        last.out_of_place_pct,
    );
    assert!((ours - theirs).abs() < 1e-9, "{ours} vs {theirs}");

    // Fix markers and the known share tick by tick: the share lags the robot's by at most
    // one map sweep, and ends equal.
    let fixes = |r: &host_sim::RunRecord| r.ticks.iter().filter(|t| t.fix_taken).count();
    assert_eq!(fixes(&record), fixes(&output.record));
    assert!(record.ticks.iter().all(|t| t.truth_mm.0.is_nan()));
    let summary = recording.summary();
    assert_eq!(summary.fixes as u32, output.figures.fixes);
    assert_eq!(
        summary.counters.map(|c| c.fixes_taken),
        Some(output.figures.fixes)
    );
    assert!(summary.health.is_some());
    // The text summary carries the counters the JSON does, the too-old rejections too.
    let text = summary.to_string();
    let too_old = summary
        .counters
        .map_or(u32::MAX, |c| c.fixes_rejected_too_old);
    assert!(
        text.contains(&format!("/ {too_old} too old rejected")),
        "{text}"
    );

    // The command line agrees and draws both pictures.
    let pictures = dir.join("pictures");
    let file = dir.join("seed.bin");
    let out = host_sim(&[
        "view",
        path_str(&file),
        "--out",
        path_str(&pictures),
        "--json",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"));
    let json: serde_json::Value =
        serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    assert_eq!(json["ticks"].as_u64(), Some(run_ticks as u64), "{json}");
    assert_eq!(json["bad_frames"]["total"].as_u64(), Some(0), "{json}");
    for name in ["seed-map.png", "seed-chart.png"] {
        let len = std::fs::metadata(pictures.join(name)).map_or(0, |m| m.len());
        assert!(len > 1000, "{name}: {len} bytes");
    }
    // And a line of JSON per tick, in order.
    let ticks = std::fs::read_to_string(pictures.join("seed-ticks.jsonl")).unwrap_or_default();
    let times: Vec<f64> = ticks
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap_or_default()["t_s"]
                .as_f64()
                .unwrap_or(f64::NAN)
        })
        .collect();
    assert_eq!(times.len(), run_ticks, "{}", ticks.len());
    assert!(times.windows(2).all(|w| w[0] < w[1]), "{times:?}");
}

#[test]
fn garbage_in_the_stream_costs_only_its_own_frames() {
    let tmp = scratch("garbage");
    let dir = tmp.path();
    let bytes = recorded_stream(dir);
    let clean = decode_bytes(&bytes);
    let clean_frames = clean.decoder.stats().frames_ok;

    // Split into frames, then: noise between every 50th pair, and every 100th frame
    // with a flipped bit (each costs exactly that frame).
    let frames: Vec<&[u8]> = bytes.split_inclusive(|&b| b == 0).collect();
    assert_eq!(frames.len() as u32, clean_frames);
    let mut dirty = Vec::new();
    let (mut noisy, mut flipped) = (0u32, 0u32);
    for (i, frame) in frames.iter().enumerate() {
        if i % 100 == 7 && frame.len() > 4 {
            let mut f = frame.to_vec();
            f[2] ^= 0x10;
            if f[2] == 0 {
                f[2] = 0x55;
            }
            dirty.extend(f);
            flipped += 1;
        } else {
            dirty.extend_from_slice(frame);
        }
        if i % 50 == 3 {
            // Noise ending in a delimiter: one bad frame, the next frame untouched.
            dirty.extend([0x13, 0x37, 0xFF, 0xB1, 0x02, 0x00]);
            noisy += 1;
        }
    }
    let recording = decode_bytes(&dirty);
    let stats = *recording.decoder.stats();
    assert_eq!(stats.frames_ok, clean_frames - flipped, "{stats:?}");
    assert_eq!(stats.bad_frames.total(), flipped + noisy, "{stats:?}");

    // The CLI reads it too, reports the bad frames and still draws.
    let file = dir.join("dirty.bin");
    std::fs::write(&file, &dirty).ok();
    let out = host_sim(&["view", path_str(&file), "--out", path_str(dir)]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains(&format!("{} bad", flipped + noisy)), "{text}");
    assert!(dir.join("dirty-map.png").is_file());
}

#[test]
fn bad_input_is_refused_cleanly() {
    let tmp = scratch("bad");
    let dir = tmp.path();
    let junk = dir.join("junk.bin");
    let noise: Vec<u8> = (0..20_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&junk, noise).ok();
    let empty = dir.join("empty.bin");
    std::fs::write(&empty, b"").ok();
    let missing = dir.join("missing.bin");
    for (args, what) in [
        (vec!["view", path_str(&junk)], "no telemetry frames"),
        (vec!["view", path_str(&empty)], "no telemetry frames"),
        (vec!["view", path_str(&missing)], "cannot read"),
        (vec!["view"], "<SOURCE>"),
        (vec!["view", path_str(&junk), "--baud", "fast"], "--baud"),
        (
            vec!["view", path_str(&junk), "--seconds", "-1"],
            "--seconds",
        ),
        (
            vec!["view", path_str(&junk), "--frobnicate"],
            "--frobnicate",
        ),
        (vec!["view", "/dev/no-such-tty"], "serial port"),
    ] {
        let out = host_sim(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(what), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn a_late_viewer_waits_for_hello_and_refuses_chunks_off_the_grid() {
    use host_sim::telemetry::TelemetryRecorder;
    use wire::telemetry::{CellChunk, MapRows, Message};
    let rows = |first_row, first_column, n: usize| {
        Message::MapRows(MapRows {
            first_row,
            first_column,
            cells: CellChunk::from_slice(&vec![100i8; n]).unwrap_or_default(),
        })
    };
    let mut r = TelemetryRecorder::new();
    r.push(&rows(0, 0, 8)); // before any Hello: nowhere to put it
    assert!(r.beliefs().is_empty());
    r.push(&Message::Hello(common::hello(4, 3)));
    r.push(&rows(1, 0, 8)); // rows 1 and 2: fits exactly
    r.push(&rows(2, 0, 5)); // one cell past the end
    r.push(&rows(0, 4, 1)); // column past the width
    r.push(&rows(u16::MAX, u16::MAX, 128));
    let summary = r.summary(&Default::default());
    assert_eq!((summary.map_rows, summary.map_rows_refused), (1, 4));
    assert_eq!((summary.occupied, summary.free), (8, 0));
    let record = r.record("late");
    assert_eq!(record.map.cells.len(), 12);
    assert!(record.ticks.is_empty());
}

/// The seed scenario run in `mode`, and its own truth written to `dir/truth.jsonl`, one
/// line per tick as the emulator's harness writes it (the lines are returned too).
fn seed_run_with_truth(dir: &Path, mode: PoseMode) -> (RunOutput, PathBuf, Vec<String>) {
    let scenario = Scenario::load(&seed_path()).expect("seed scenario loads");
    let output = run(&scenario, mode, scenario.seed).expect("seed runs");
    let lines: Vec<String> = output
        .record
        .ticks
        .iter()
        .map(|t| {
            serde_json::json!({
                "t_s": t.t_s,
                "x_mm": t.truth_mm.0,
                "y_mm": t.truth_mm.1,
                "heading_deg": t.truth_heading_deg,
            })
            .to_string()
        })
        .collect();
    let truth = dir.join("truth.jsonl");
    std::fs::write(&truth, lines.join("\n") + "\n").ok();
    (output, truth, lines)
}

fn view_json(args: &[&str]) -> serde_json::Value {
    let out = host_sim(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{args:?}: {err}");
    serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null)
}

#[test]
fn view_with_the_truth_scores_a_run_as_run_does() {
    let tmp = scratch("truth");
    let dir = tmp.path();
    recorded_stream(dir);
    let stream = dir.join("seed.bin");
    let (output, truth, lines) = seed_run_with_truth(dir, PoseMode::Tags);

    let v = view_json(&[
        "view",
        path_str(&stream),
        "--truth",
        path_str(&truth),
        "--scenario",
        path_str(&seed_path()),
        "--json",
    ]);
    let sim = serde_json::to_value(&output.figures).unwrap_or_default();
    for key in SCORED_FIGURES {
        let (a, b) = (v[key].as_f64(), sim[key].as_f64());
        assert!(
            matches!((a, b), (Some(a), Some(b)) if (a - b).abs() < 1e-6),
            "{key}: view {:?}, run {:?}",
            v[key],
            sim[key]
        );
    }
    assert_eq!(v["ticks_without_truth"].as_u64(), Some(0), "{v}");
    assert_eq!(v["route_start_s"].as_f64(), Some(0.0), "{v}");
    // The keys CI reads are still there.
    assert_eq!(v["bad_frames"]["total"].as_u64(), Some(0), "{v}");
    assert!(v["health"].is_object() && v["counters"].is_object() && v["final_pose"].is_object());

    // A lost truth line costs its tick's score, counted; the rest still scores.
    let mut gappy = lines.clone();
    gappy.remove(100);
    std::fs::write(&truth, gappy.join("\n")).ok();
    let v = view_json(&[
        "view",
        path_str(&stream),
        "--truth",
        path_str(&truth),
        "--json",
    ]);
    assert_eq!(v["ticks_without_truth"].as_u64(), Some(1), "{v}");
    assert_eq!(v["truth_samples"].as_u64(), Some(lines.len() as u64 - 1));
    assert!(
        v["out_of_place"].is_null(),
        "no world, no out-of-place count: {v}"
    );
    assert!(v["max_error_cm"].as_f64().is_some_and(|e| e > 0.0), "{v}");

    // Without --truth, no pose score at all.
    let v = view_json(&["view", path_str(&stream), "--json"]);
    assert!(v.get("max_error_cm").is_none(), "{v}");
}

#[test]
fn a_bad_truth_file_is_refused_naming_the_line() {
    let tmp = scratch("badtruth");
    let dir = tmp.path();
    recorded_stream(dir);
    let stream = dir.join("seed.bin");
    let good = "{\"t_s\":0.1,\"x_mm\":700,\"y_mm\":500,\"heading_deg\":0}";
    let truth = dir.join("truth.jsonl");
    for (text, what) in [
        (
            format!("{good}\n{good}\n{{\"t_s\":0.3,\"x_mm\":700}}\n"),
            "line 3",
        ),
        (format!("{good}\n\n{good}\n[1,2]\n"), "line 4"),
        (format!("{good}\nnot a sample\n"), "line 2"),
        (
            format!("{good}\n{}\n", good.replace("0.1", "0.05")),
            "time order",
        ),
    ] {
        std::fs::write(&truth, &text).ok();
        let out = host_sim(&["view", path_str(&stream), "--truth", path_str(&truth)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{text}: {err}");
        assert!(
            err.contains(what) && err.contains("truth.jsonl"),
            "{text}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            out.stdout.is_empty(),
            "{text}: no figures from a bad truth file"
        );
    }
    let missing = dir.join("missing.jsonl");
    let out = host_sim(&["view", path_str(&stream), "--truth", path_str(&missing)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot read truth file"));
    let out = host_sim(&["view", path_str(&stream), "--scenario", "/nonexistent.toml"]);
    assert_eq!(out.status.code(), Some(2));
}

/// Whether `a` and `b` have the same shape and values, numbers within 1e-9 of each other.
fn same_json(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= 1e-9 * x.abs().max(1.0),
            _ => false,
        },
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same_json(v, w)))
        }
        _ => a == b,
    }
}

#[test]
fn the_filters_figures_survive_the_telemetry() {
    // `run --pose filter` (the firmware's) and `view --truth --scenario` of its stream give the same
    // `estimator` object: covariance, calibration and tags travel whole.
    let tmp = scratch("slam");
    let dir = tmp.path();
    let stream = dir.join("slam.bin");
    let out = host_sim(&[
        "run",
        path_str(&seed_path()),
        "--pose",
        "filter",
        "--telemetry",
        path_str(&stream),
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(0));
    let sim: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    let (_, truth, _) = seed_run_with_truth(dir, PoseMode::Filter);
    let v = view_json(&[
        "view",
        path_str(&stream),
        "--truth",
        path_str(&truth),
        "--scenario",
        path_str(&seed_path()),
        "--json",
        "--out",
        path_str(dir),
    ]);
    assert_eq!(v["localiser"], "filter", "{v}");
    assert_eq!(v["filters_unmatched"], 0, "{v}");
    let (e, s) = (&v["estimator"], &sim["estimator"]);
    assert!(s.is_object(), "run --pose filter has an estimator: {sim}");
    // The same keys and values; errors scored from the truth file's text may differ in
    // the last digits.
    assert!(same_json(e, s), "view {e}\nrun {s}");
    assert!(dir.join("slam-chart.png").is_file());
}
