//! `--live`, `--speed`, `--foxglove-port` and `--mcap`: clear refusals, and sessions that
//! end cleanly on a stream that is garbage or cut short.

#[allow(dead_code)] // not every helper is used here
mod common;

use common::{host_sim, scratch_dir, seed_path};
use std::net::TcpListener;

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-live-cli-";

fn seed() -> String {
    seed_path().to_str().unwrap_or_default().to_string()
}

#[test]
fn a_port_in_use_is_named() {
    let taken = TcpListener::bind("127.0.0.1:0").expect("a port");
    let port = taken.local_addr().expect("an address").port().to_string();
    let out = host_sim(&[
        "run",
        &seed(),
        "--live",
        "--port",
        "0",
        "--speed",
        "1000",
        "--foxglove-port",
        &port,
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(&format!("127.0.0.1:{port}")), "{err}");
    assert!(err.contains("in use"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "no run when the server cannot listen"
    );
}

#[test]
fn a_page_port_in_use_is_named() {
    let taken = TcpListener::bind("127.0.0.1:0").expect("a port");
    let port = taken.local_addr().expect("an address").port().to_string();
    let out = host_sim(&[
        "run",
        &seed(),
        "--live",
        "--speed",
        "1000",
        "--foxglove-port",
        "0",
        "--port",
        &port,
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(&format!("127.0.0.1:{port}")), "{err}");
    assert!(err.contains("in use"), "{err}");
    assert!(out.stdout.is_empty(), "no run when the page cannot listen");
}

#[test]
fn speeds_out_of_range_and_live_options_without_live_are_refused() {
    for speed in ["0", "0.05", "1001", "-2", "nan", "inf", "fast"] {
        let out = host_sim(&[
            "run",
            &seed(),
            "--live",
            "--port",
            "0",
            "--foxglove-port",
            "0",
            "--speed",
            speed,
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "--speed {speed}: {err}");
        assert!(err.contains("--speed"), "--speed {speed}: {err}");
    }
    for flag in [["--speed", "2"], ["--foxglove-port", "0"], ["--port", "0"]] {
        let out = host_sim(&["run", &seed(), flag[0], flag[1]]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag:?}: {err}");
        assert!(err.contains("--live"), "{flag:?}: {err}");
    }
}

#[test]
fn an_mcap_file_that_cannot_be_written_is_named() {
    let dir = scratch_dir(SCRATCH);
    let path = dir.path().join("no-such-dir").join("run.mcap");
    let path = path.to_str().unwrap_or_default();
    let out = host_sim(&["run", &seed(), "--mcap", path]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(path), "{err}");
}

#[test]
fn garbage_ends_the_session_cleanly() {
    let dir = scratch_dir(SCRATCH);
    let garbage = dir.path().join("garbage.bin");
    let bytes: Vec<u8> = (0..20_000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&garbage, bytes).expect("garbage written");
    let mcap = dir.path().join("garbage.mcap");
    let out = host_sim(&[
        "view",
        garbage.to_str().unwrap_or_default(),
        "--live",
        "--port",
        "0",
        "--foxglove-port",
        "0",
        "--speed",
        "1000",
        "--mcap",
        mcap.to_str().unwrap_or_default(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("no telemetry frames"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // The recording is still a whole MCAP file: the listed tags, and the session's end
    // in its log; no map, no pose.
    let bytes = std::fs::read(&mcap).expect("the MCAP file");
    let topics: Vec<String> = mcap::MessageStream::new(&bytes)
        .expect("an MCAP file")
        .map(|m| m.expect("a good record").channel.topic.clone())
        .collect();
    assert_eq!(topics, ["/tags", "/log"]);
}

#[test]
fn a_stream_cut_short_plays_to_its_end_with_the_usual_summary() {
    let dir = scratch_dir(SCRATCH);
    let telemetry = dir.path().join("seed.bin");
    let out = host_sim(&[
        "run",
        &seed(),
        "--telemetry",
        telemetry.to_str().unwrap_or_default(),
    ]);
    assert!(out.status.success());
    let bytes = std::fs::read(&telemetry).expect("the stream");
    let cut = dir.path().join("cut.bin");
    std::fs::write(&cut, &bytes[..bytes.len() / 2 + 7]).expect("cut written");
    let mcap = dir.path().join("cut.mcap");
    let out = host_sim(&[
        "view",
        cut.to_str().unwrap_or_default(),
        "--live",
        "--port",
        "0",
        "--foxglove-port",
        "0",
        "--speed",
        "1000",
        "--mcap",
        mcap.to_str().unwrap_or_default(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{err}");
    assert!(text.contains("telemetry: firmware"), "{text}");
    assert!(text.contains("cut short"), "{text}");
    let bytes = std::fs::read(&mcap).expect("the MCAP file");
    let poses = mcap::MessageStream::new(&bytes)
        .expect("an MCAP file")
        .filter(|m| m.as_ref().is_ok_and(|m| m.channel.topic == "/pose"))
        .count();
    let ticks: usize = text
        .split(" ticks,")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("the summary's tick count");
    assert!(ticks > 100, "{text}");
    assert_eq!(poses, ticks);
}
