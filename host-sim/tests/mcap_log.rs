//! `host-sim view STREAM --log LOG --mcap FILE`: the firmware's log lines on `/log`, read
//! back with the `mcap` crate and held against the `/pose` messages' times.

#[allow(dead_code)] // not every helper is used here
mod common;

use common::{host_sim, scratch_dir, seed_path};
use foxglove::messages::{log::Level, Log};
use foxglove::Decode;

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-mcap-log-";

fn text(path: &std::path::Path) -> &str {
    path.to_str().unwrap_or_default()
}

/// A message of the recording, in file order: a pose's time, or a firmware log line.
#[derive(Debug)]
enum Seen {
    Pose(u64),
    Line { time: u64, level: i32, text: String },
}

#[test]
fn the_firmware_log_goes_out_on_log_in_time_order_with_the_ticks() {
    let dir = scratch_dir(SCRATCH);
    let (stream, log, mcap) = (
        dir.path().join("seed.bin"),
        dir.path().join("robot.log"),
        dir.path().join("log.mcap"),
    );
    let run = host_sim(&["run", text(&seed_path()), "--telemetry", text(&stream)]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // Ticks come every 100 ms from 0: each line falls before the first tick at or after
    // it, the last one after every tick.
    let lines = "0.000 [INFO ] BugBot firmware 0.1.0\n\
                 0.250 [WARN ] depth: 7 read errors\n\
                 this is not a log line\n\
                 0.260 a println without a level\n\
                 \u{1b}[2m1.000\u{1b}[0m [ERROR] motor: stalled\n\
                 1.050 DEBUG bare level\n\
                 3600.000 [INFO ] after the end";
    std::fs::write(&log, lines).expect("the log writes");

    let out = host_sim(&[
        "view",
        text(&stream),
        "--log",
        text(&log),
        "--mcap",
        text(&mcap),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("1 lines skipped"), "{stderr}");

    let bytes = std::fs::read(&mcap).expect("the MCAP file");
    let mut seen = Vec::new();
    for m in mcap::MessageStream::new(&bytes).expect("an MCAP file") {
        let m = m.expect("a good record");
        match m.channel.topic.as_str() {
            "/pose" => seen.push(Seen::Pose(m.log_time)),
            "/log" => {
                let log = Log::decode(&*m.data).expect("a foxglove.Log");
                if log.name == "firmware" {
                    let stamp = log.timestamp.expect("a timestamp");
                    let ns = u64::from(stamp.sec()) * 1_000_000_000 + u64::from(stamp.nsec());
                    assert_eq!(ns, m.log_time, "{}", log.message);
                    seen.push(Seen::Line {
                        time: m.log_time,
                        level: log.level,
                        text: log.message,
                    });
                } else {
                    assert_eq!(log.name, "host-sim");
                }
            }
            _ => {}
        }
    }

    let got: Vec<(i32, &str)> = seen
        .iter()
        .filter_map(|s| match s {
            Seen::Line { level, text, .. } => Some((*level, text.as_str())),
            Seen::Pose(_) => None,
        })
        .collect();
    assert_eq!(
        got,
        [
            (Level::Info as i32, "BugBot firmware 0.1.0"),
            (Level::Warning as i32, "depth: 7 read errors"),
            (Level::Unknown as i32, "a println without a level"),
            (Level::Error as i32, "motor: stalled"),
            (Level::Debug as i32, "bare level"),
            (Level::Info as i32, "after the end"),
        ]
    );

    // Each line comes after every pose earlier than it and right before the first pose
    // at or after it; times are the first pose's plus the line's milliseconds.
    let first_pose = seen
        .iter()
        .find_map(|s| match s {
            Seen::Pose(t) => Some(*t),
            Seen::Line { .. } => None,
        })
        .expect("poses");
    let poses = seen.iter().filter(|s| matches!(s, Seen::Pose(_))).count();
    assert!(poses > 20, "{poses} poses");
    let mut last_pose = None;
    let mut placed = 0;
    for (i, s) in seen.iter().enumerate() {
        match s {
            Seen::Pose(t) => last_pose = Some(*t),
            Seen::Line { time, text, .. } => {
                placed += 1;
                if let Some(before) = last_pose {
                    assert!(before < *time, "{text}: a pose at or after it came first");
                }
                let next = seen[i..].iter().find_map(|s| match s {
                    Seen::Pose(t) => Some(*t),
                    Seen::Line { .. } => None,
                });
                match next {
                    Some(next) => assert!(next >= *time, "{text}: the next pose is earlier"),
                    None => assert_eq!(text, "after the end"),
                }
            }
        }
    }
    assert_eq!(placed, 6);
    let times: Vec<u64> = seen
        .iter()
        .filter_map(|s| match s {
            Seen::Line { time, .. } => Some((time - first_pose) / 1_000_000),
            Seen::Pose(_) => None,
        })
        .collect();
    assert_eq!(times, [0, 250, 260, 1000, 1050, 3_600_000]);
}

#[test]
fn log_without_live_or_mcap_is_refused_and_a_missing_log_named() {
    let dir = scratch_dir(SCRATCH);
    let stream = dir.path().join("refused.bin");
    let run = host_sim(&["run", text(&seed_path()), "--telemetry", text(&stream)]);
    assert!(run.status.success());
    let out = host_sim(&["view", text(&stream), "--log", "/dev/null"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--live or --mcap"));
    let missing = dir.path().join("no-such.log");
    let out = host_sim(&[
        "view",
        text(&stream),
        "--log",
        text(&missing),
        "--mcap",
        text(&dir.path().join("refused.mcap")),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no-such.log"));
}
