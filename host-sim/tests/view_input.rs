//! `host-sim view` on input that lies or does not match: a stream that claims an
//! impossible grid is refused fast, in bounded memory, a long run costs each tick only
//! what it changed, and a truth that matches no tick scores nothing.

// `SCORED_FIGURES` serves the other test files.
#[allow(dead_code)]
mod common;

use common::{hello, host_sim, scratch_dir, scratch_file, seed_path};
use host_sim::telemetry::{decode_bytes, TelemetryRecorder, MAX_GRID_SIDE};
use slam_core::{Counters, FixOutcome};
use std::time::{Duration, Instant};
use wire::telemetry::{encode, CellChunk, Hello, MapRows, Message, Tick, MAX_FRAME_LEN};

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-view-input-";

fn tick(n: u32) -> Message {
    Message::Tick(Tick {
        tick: n,
        time_ms: n * 100,
        x_um: 0,
        y_um: 0,
        heading_bits: 0,
        fix: FixOutcome::NotAttempted,
        stale: 0,
        cells_written: 0,
        doubts: 0,
        counters: Counters::default(),
    })
}

/// `message` framed as the robot sends it.
fn frame(message: &Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    match encode(message, &mut buf) {
        Ok(n) => buf.get(..n).unwrap_or_default().to_vec(),
        Err(e) => panic!("cannot encode {message:?}: {e:?}"),
    }
}

/// Runs `view FILE --json` and returns its JSON and how long it took.
fn view_json(path: &std::path::Path) -> (serde_json::Value, Duration) {
    let started = Instant::now();
    let out = host_sim(&["view", path.to_str().unwrap_or_default(), "--json"]);
    let took = started.elapsed();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let json = serde_json::from_slice(&out.stdout).unwrap_or(serde_json::Value::Null);
    (json, took)
}

#[test]
fn a_hello_claiming_a_huge_grid_is_refused_fast() {
    let huge = frame(&Message::Hello(hello(u16::MAX, u16::MAX)));
    assert!(huge.len() <= 50, "{} bytes", huge.len());
    let dir = scratch_dir(SCRATCH);
    let one = scratch_file(&dir, "one-hello.bin", &huge);
    let (json, took) = view_json(&one);
    assert!(took < Duration::from_secs(5), "took {took:?}");
    assert_eq!(json["hellos_refused"]["count"].as_u64(), Some(1), "{json}");
    let why = json["hellos_refused"]["last"].as_str().unwrap_or_default();
    assert!(
        why.contains("65535 x 65535") && why.contains("1024"),
        "{why}"
    );
    assert!(json["grid"].is_null(), "{json}");

    // Fifty of them, with ticks between: still fast, each refused.
    let mut fifty = Vec::new();
    for i in 0..50 {
        fifty.extend(&huge);
        fifty.extend(frame(&tick(i + 1)));
    }
    let many = scratch_file(&dir, "fifty-hellos.bin", &fifty);
    let (json, took) = view_json(&many);
    assert!(took < Duration::from_secs(5), "took {took:?}");
    assert_eq!(json["hellos_refused"]["count"].as_u64(), Some(50), "{json}");
    assert_eq!(json["ticks"].as_u64(), Some(50), "{json}");

    // The text summary says so.
    let out = host_sim(&["view", one.to_str().unwrap_or_default()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("Hellos refused: 1") && text.contains("65535 x 65535"),
        "{text}"
    );
}

#[test]
fn impossible_grids_keep_the_grid_there_is() {
    let mut r = TelemetryRecorder::new();
    r.push(&Message::Hello(hello(4, 3)));
    for bad in [
        hello(MAX_GRID_SIDE + 1, 3),
        hello(4, MAX_GRID_SIDE + 1),
        hello(0, 3),
        Hello {
            cell_mm: 0,
            ..hello(4, 3)
        },
    ] {
        r.push(&Message::Hello(bad));
    }
    assert_eq!(r.hellos_refused(), 4);
    assert_eq!(r.hello().map(|h| (h.width, h.height)), Some((4, 3)));
    assert_eq!(r.beliefs().len(), 12);
    // The largest grid taken is taken.
    r.push(&Message::Hello(hello(MAX_GRID_SIDE, MAX_GRID_SIDE)));
    assert_eq!(r.beliefs().len(), 1024 * 1024);
}

#[test]
fn the_known_share_follows_the_chunks_without_rescanning_the_map() {
    let rows = |first_row, cells: &[i8]| {
        Message::MapRows(MapRows {
            first_row,
            first_column: 0,
            cells: CellChunk::from_slice(cells).unwrap_or_default(),
        })
    };
    // Small: the share tick by tick is the share of the map at that tick.
    let mut r = TelemetryRecorder::new();
    r.push(&Message::Hello(hello(4, 3)));
    r.push(&tick(1));
    r.push(&rows(0, &[100, -100, 0, 0])); // two known
    r.push(&tick(2));
    r.push(&rows(0, &[0, 0, 0, 0, 100, 100, 100, 100])); // two lost, four gained
    r.push(&tick(3));
    // Same grid, thresholds so wide nothing is firm.
    r.push(&Message::Hello(Hello {
        free_below: 120,
        occupied_above: 120,
        ..hello(4, 3)
    }));
    r.push(&tick(4));
    let known: Vec<f64> = r.record("t").ticks.iter().map(|t| t.known_pct).collect();
    let want = [0.0, 200.0 / 12.0, 400.0 / 12.0, 0.0];
    assert!(
        known.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9),
        "{known:?}"
    );

    // Large: the biggest grid a stream may declare, and an hour of ticks each bringing a
    // chunk. Rescanning the map every tick would be 36,000 x 1M cells.
    let mut bytes = frame(&Message::Hello(hello(MAX_GRID_SIDE, MAX_GRID_SIDE)));
    for i in 0..36_000u32 {
        bytes.extend(frame(&tick(i + 1)));
        bytes.extend(frame(&rows((i % 1024) as u16, &[100; 64])));
    }
    let started = Instant::now();
    let recording = decode_bytes(&bytes);
    let took = started.elapsed();
    assert_eq!(recording.recorder.tick_count(), 36_000);
    assert!(took < Duration::from_secs(10), "took {took:?}");
    let last = recording
        .recorder
        .record("big")
        .ticks
        .last()
        .map_or(f64::NAN, |t| t.known_pct);
    let want = 100.0 * (1024.0 * 64.0) / (1024.0 * 1024.0);
    assert!((last - want).abs() < 1e-9, "{last} vs {want}");
}

#[test]
fn a_truth_that_matches_no_tick_scores_nothing() {
    let dir = scratch_dir(SCRATCH);
    let stream = scratch_file(&dir, "seed.bin", b"");
    let out = host_sim(&[
        "run",
        seed_path().to_str().unwrap_or_default(),
        "--telemetry",
        stream.to_str().unwrap_or_default(),
        "--json",
    ]);
    assert_eq!(out.status.code(), Some(0));
    let sample =
        |t_s: f64| format!("{{\"t_s\":{t_s},\"x_mm\":700,\"y_mm\":500,\"heading_deg\":0}}\n");
    let view = |truth: &std::path::Path, json: bool| {
        let mut args = vec![
            "view",
            stream.to_str().unwrap_or_default(),
            "--truth",
            truth.to_str().unwrap_or_default(),
        ];
        if json {
            args.push("--json");
        }
        let out = host_sim(&args);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // Long after the run ends: no tick has a sample near it.
    let late = scratch_file(
        &dir,
        "late.jsonl",
        (sample(5000.0) + &sample(5000.1)).as_bytes(),
    );
    let text = view(&late, false);
    assert!(text.contains("nothing to score against"), "{text}");
    assert!(!text.contains("final error 0.0 cm"), "{text}");
    let json: serde_json::Value = serde_json::from_str(&view(&late, true)).unwrap_or_default();
    assert_eq!(json["truth_samples"].as_u64(), Some(2), "{json}");
    for key in [
        "final_error_cm",
        "max_error_after_first_fix_cm",
        "final_heading_error_deg",
        "max_heading_error_after_first_fix_deg",
        "max_error_cm",
    ] {
        assert!(
            json.get(key).is_some_and(serde_json::Value::is_null),
            "{key} must be there and null: {json}"
        );
    }
    // A matching sample scores, under the same keys.
    let early = scratch_file(&dir, "early.jsonl", (sample(0.0) + &sample(0.1)).as_bytes());
    let scored: serde_json::Value = serde_json::from_str(&view(&early, true)).unwrap_or_default();
    let keys = |v: &serde_json::Value| {
        v.as_object()
            .map(|o| o.keys().cloned().collect::<Vec<_>>())
            .unwrap_or_default()
    };
    assert_eq!(keys(&scored), keys(&json));
    assert!(scored["final_error_cm"].is_f64(), "{scored}");
}

/// A `Filter` for tick `n`: 2 mm and 0.5 degrees of doubt (1 sigma), some calibration.
fn filter(n: u32) -> Message {
    use slam_core::{Calibration, PoseCovariance, TagCounters};
    let rad = 0.5f64.to_radians() * 65536.0;
    Message::Filter(wire::telemetry::FilterState {
        tick: n,
        covariance: PoseCovariance {
            xx: 4 * 256,
            yy: 4 * 256,
            hh: (rad * rad).round() as i64,
            ..PoseCovariance::default()
        },
        calibration: Calibration {
            gyro_scale_ppm: -7000,
            gyro_bias_mdps: 15,
            flow_scale_ppm: 40_000 + n as i32,
        },
        tags: TagCounters {
            used: n,
            gate: 1,
            ..TagCounters::default()
        },
    })
}

#[test]
fn filter_beliefs_join_their_ticks_and_reach_the_summary() {
    let mut bytes = Vec::new();
    bytes.extend(frame(&Message::Hello(Hello {
        localiser: slam_core::Localiser::Filter,
        matching: false,
        ..hello(4, 3)
    })));
    for n in 1..=3 {
        bytes.extend(frame(&tick(n)));
        bytes.extend(frame(&filter(n)));
    }
    // A Filter whose Tick was lost is not pinned on the wrong tick.
    bytes.extend(frame(&filter(7)));
    let recording = decode_bytes(&bytes);
    let record = recording.recorder.record("f");
    let flows: Vec<Option<f64>> = record
        .ticks
        .iter()
        .map(|t| t.belief.map(|b| b.flow_scale_ppm))
        .collect();
    assert_eq!(flows, [Some(40_001.0), Some(40_002.0), Some(40_003.0)]);
    let summary = recording.summary();
    assert_eq!(summary.filters_unmatched, 1);
    assert_eq!(summary.localiser.as_deref(), Some("filter"));
    let e = summary.estimator.expect("estimator figures");
    assert!((e.bound_3sigma_cm - 0.6).abs() < 1e-9, "{e:?}");
    assert!((e.bound_3sigma_heading_deg - 1.5).abs() < 1e-3, "{e:?}");
    assert_eq!(e.tags.used, 3);
    // Without the truth nothing is scored, and JSON says so with nulls.
    assert_eq!(e.inside_3sigma_pct, None);
    let json = serde_json::to_value(&summary).expect("json");
    assert!(json["estimator"]["inside_3sigma_pct"].is_null());
    assert_eq!(json["estimator"]["calibration"]["gyro_bias_mdps"], 15.0);

    // A robot without the filter: no estimator key at all.
    let plain = decode_bytes(&frame(&tick(1)));
    let json = serde_json::to_value(plain.summary()).expect("json");
    assert!(json.get("estimator").is_none());
}
