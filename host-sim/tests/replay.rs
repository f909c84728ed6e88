//! `host-sim replay`: a simulated run recorded with `run --telemetry` replays bit for bit,
//! another localiser on the same inputs gives that localiser's run, and streams without
//! inputs or with lying ones are refused or reported, never a panic.

#[allow(dead_code)]
mod common;

use common::{host_sim, scratch_dir, scratch_file, seed_path};
use host_sim::replay::{replay, ReplayError};
use host_sim::run::run_with_telemetry;
use host_sim::telemetry::{decode_bytes, TelemetryWriter};
use host_sim::{PoseMode, Scenario};
use wire::telemetry::{encode, Message, StreamDecoder, Tick, MAX_FRAME_LEN};

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-replay-";

fn seed() -> Scenario {
    match Scenario::load(&seed_path()) {
        Ok(s) => s,
        Err(e) => panic!("seed scenario: {e}"),
    }
}

/// The stream `host-sim run --pose MODE --telemetry` writes on the seed.
fn recorded(scenario: &Scenario, mode: PoseMode) -> Vec<u8> {
    let mut writer = TelemetryWriter::new(mode);
    if let Err(e) = run_with_telemetry(scenario, mode, scenario.seed, Some(&mut writer)) {
        panic!("run: {e}");
    }
    writer.bytes().to_vec()
}

fn messages(bytes: &[u8]) -> Vec<Message> {
    StreamDecoder::new().feed(bytes).flatten().collect()
}

fn framed(messages: &[Message]) -> Vec<u8> {
    let mut out = Vec::new();
    for m in messages {
        let mut buf = [0u8; MAX_FRAME_LEN];
        match encode(m, &mut buf) {
            Ok(n) => out.extend_from_slice(&buf[..n]),
            Err(e) => panic!("encode: {e:?}"),
        }
    }
    out
}

fn ticks(bytes: &[u8]) -> Vec<Tick> {
    messages(bytes)
        .into_iter()
        .filter_map(|m| match m {
            Message::Tick(t) => Some(t),
            _ => None,
        })
        .collect()
}

#[test]
fn a_simulated_run_replays_bit_for_bit() {
    let scenario = seed();
    for mode in [PoseMode::Filter, PoseMode::Tags] {
        let bytes = recorded(&scenario, mode);
        let r = match replay(&scenario, &bytes, None) {
            Ok(r) => r,
            Err(e) => panic!("{mode:?}: {e}"),
        };
        let s = &r.summary;
        assert!(s.robot_settings, "{mode:?}");
        assert_eq!(s.pose, mode.name());
        let b = s.bit_for_bit.clone().unwrap_or_default();
        assert_eq!(b.first_difference, None, "{mode:?}");
        let n = ticks(&bytes).len() as u32;
        assert!(n > 400, "{n} ticks");
        assert_eq!((s.steps, b.ticks), (n, n), "{mode:?}");
        let filters = if mode == PoseMode::Filter { n } else { 0 };
        assert_eq!(b.filters, filters, "{mode:?}");
        assert!(b.map_chunks >= n, "{mode:?}: {} chunks", b.map_chunks);
        assert!(b.identical());
        // The replayed stream is the recorded one, message for message.
        assert_eq!(messages(&r.stream), messages(&bytes), "{mode:?}");
        let (a, z) = (decode_bytes(&bytes), decode_bytes(&r.stream));
        assert_eq!(a.recorder.beliefs(), z.recorder.beliefs());
    }
}

#[test]
fn another_localiser_replays_to_its_own_run() {
    let scenario = seed();
    // The claim this relies on: the simulated inputs do not depend on the pose mode (the
    // route steers by the truth), apart from the truth handed in with `--pose truth`.
    let frames = |mode| match host_sim::run(&scenario, mode, scenario.seed) {
        Ok(o) => o.frames,
        Err(e) => panic!("run: {e}"),
    };
    assert_eq!(frames(PoseMode::Slam), frames(PoseMode::DeadReckoning));
    assert_eq!(frames(PoseMode::Tags), frames(PoseMode::DeadReckoning));

    let from_slam = recorded(&scenario, PoseMode::Slam);
    let r = match replay(&scenario, &from_slam, Some(PoseMode::DeadReckoning)) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    assert!(!r.summary.robot_settings);
    assert_eq!(r.summary.bit_for_bit, None, "no robot to compare with");
    let dead_reckoning = recorded(&scenario, PoseMode::DeadReckoning);
    assert_eq!(ticks(&r.stream), ticks(&dead_reckoning));
    let (a, z) = (decode_bytes(&dead_reckoning), decode_bytes(&r.stream));
    assert_eq!(a.recorder.beliefs(), z.recorder.beliefs());

    // And through the command line: the figures `run --pose dead-reckoning` gives.
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "slam.bin", &from_slam);
    let out = host_sim(&[
        "replay",
        &path.to_string_lossy(),
        "--pose",
        "dead-reckoning",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let replayed: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    let out = host_sim(&[
        "run",
        &seed_path().to_string_lossy(),
        "--pose",
        "dead-reckoning",
        "--json",
    ]);
    let run: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    let view = &replayed["view"];
    assert_eq!(view["localiser"], "dead-reckoning");
    for key in ["free", "occupied", "out_of_place", "fixes", "ticks"] {
        assert!(!run[key].is_null(), "{key}");
        assert_eq!(view[key], run[key], "{key}");
    }
    let pct = |v: &serde_json::Value| v["known_pct"].as_f64().unwrap_or(f64::NAN);
    assert!((pct(view) - pct(&run)).abs() < 1e-9);
}

#[test]
fn the_command_line_reports_bit_for_bit() {
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "tags.bin", recorded(&seed(), PoseMode::Tags));
    let out = host_sim(&["replay", &path.to_string_lossy(), "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    assert_eq!(v["replay"]["robot_settings"], true);
    assert_eq!(
        v["replay"]["bit_for_bit"]["first_difference"],
        serde_json::Value::Null
    );
    assert_eq!(v["view"]["localiser"], "tags");
    let out = host_sim(&["replay", &path.to_string_lossy()]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("all equal"), "{text}");
}

#[test]
fn a_stream_without_inputs_is_a_clear_error() {
    let bytes = recorded(&seed(), PoseMode::Tags);
    let without: Vec<Message> = messages(&bytes)
        .into_iter()
        .filter(|m| !matches!(m, Message::Inputs(_)))
        .collect();
    let bytes = framed(&without);
    assert!(matches!(
        replay(&seed(), &bytes, None),
        Err(ReplayError::NoInputs { frames_ok }) if frames_ok > 0
    ));
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "no-inputs.bin", &bytes);
    let out = host_sim(&["replay", &path.to_string_lossy()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("no input frames") && err.contains("record-inputs"),
        "{err}"
    );
    // Nothing at all, and --pose truth, are refused as cleanly.
    assert!(matches!(
        replay(&seed(), &[], None),
        Err(ReplayError::NoInputs { frames_ok: 0 })
    ));
    let full = recorded(&seed(), PoseMode::Tags);
    assert_eq!(
        replay(&seed(), &full, Some(PoseMode::Truth)).err(),
        Some(ReplayError::Truth)
    );
}

#[test]
fn a_stream_too_long_to_hold_is_refused_without_reading_it_all() {
    // An endless device: read up to the bound, then refused with the reason.
    let out = host_sim(&["replay", "/dev/zero"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/dev/zero") && err.contains("MiB"), "{err}");
}

#[test]
fn a_stream_that_lies_is_reported_not_a_panic() {
    let scenario = seed();
    let all = messages(&recorded(&scenario, PoseMode::Filter));
    let is_inputs = |m: &Message, n: u32| matches!(m, Message::Inputs(i) if i.tick == n);

    // Tick 100's inputs lost: stepped on, the gap counted and named.
    let lost: Vec<Message> = all.iter().filter(|m| !is_inputs(m, 100)).cloned().collect();
    let r = match replay(&scenario, &framed(&lost), None) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(r.summary.missing_inputs, 1);
    let d = r.summary.bit_for_bit.and_then(|b| b.first_difference);
    assert_eq!(
        d.as_ref().map(|d| (d.tick, d.field.as_str())),
        Some((100, "inputs"))
    );
    let dir = scratch_dir(SCRATCH);
    let path = scratch_file(&dir, "lost.bin", framed(&lost));
    let out = host_sim(&["replay", &path.to_string_lossy()]);
    assert_eq!(out.status.code(), Some(3), "a replay that differs fails");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("first difference at tick 100: inputs"),
        "{text}"
    );

    // Tick 50's inputs sent again after tick 60's: skipped as out of order.
    let mut late = all.clone();
    if let Some(again) = all.iter().find(|m| is_inputs(m, 50)).cloned() {
        let at = late.iter().position(|m| is_inputs(m, 60)).unwrap_or(0);
        late.insert(at + 1, again);
    }
    let r = match replay(&scenario, &framed(&late), None) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    assert_eq!(r.summary.skipped_out_of_order, 1);
    assert_eq!(r.summary.bit_for_bit.and_then(|b| b.first_difference), None);

    // A sensor reading changed in flight: the first tick it moves is named.
    let mut bent = all.clone();
    for m in bent.iter_mut() {
        if let Message::Inputs(i) = m {
            if i.tick == 200 {
                i.frame.gyro = i.frame.gyro.map(|mut g| {
                    g.rate_mdps += 5_000;
                    g
                });
            }
        }
    }
    let r = match replay(&scenario, &framed(&bent), None) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    };
    let d = r.summary.bit_for_bit.and_then(|b| b.first_difference);
    assert_eq!(d.map(|d| d.tick), Some(200));

    // Damaged bytes: counted, never a panic.
    let mut bytes = framed(&all);
    for (k, b) in bytes.iter_mut().enumerate() {
        if k % 997 == 500 {
            *b ^= 0x5A;
        }
    }
    match replay(&scenario, &bytes, None) {
        Ok(r) => assert!(r.summary.bad_frames > 0),
        Err(e) => panic!("{e}"),
    }
}
