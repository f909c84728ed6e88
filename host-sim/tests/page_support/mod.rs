//! The live page's test driver: the seed run's recorded telemetry, played into a
//! [`PageServer`] at a set pace, with the run's truth beside it as a simulation gives it.

pub mod chromium;

use host_sim::page::PageServer;
use host_sim::run::{run, PoseMode, RunOutput};
use host_sim::truth::TruthSample;
use host_sim::Scenario;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use tempfile::TempDir;
use wire::telemetry::{Message, StreamDecoder};

/// A recorded run: its telemetry as `host-sim run --telemetry` wrote it, and the same
/// run in the library (its map is the one `host-sim run` draws).
pub struct RecordedRun {
    /// The decoded messages, in order.
    pub messages: Vec<Message>,
    /// The run itself.
    pub output: RunOutput,
    /// A scratch directory for the test's files, removed when the run is dropped.
    pub dir: TempDir,
}

impl RecordedRun {
    /// The true pose at each tick, in tick order.
    pub fn truth(&self) -> Vec<TruthSample> {
        self.output.record.truth_samples()
    }

    /// The last tick's number.
    pub fn final_tick(&self) -> u32 {
        self.messages
            .iter()
            .rev()
            .find_map(|m| match m {
                Message::Tick(t) => Some(t.tick),
                _ => None,
            })
            .unwrap_or(0)
    }
}

/// A directory for a test's files, removed when the test ends, passed or failed.
pub fn scratch(name: &str) -> TempDir {
    TempDir::with_prefix(format!("host-sim-page-{name}-")).expect("scratch dir")
}

fn seed_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-mat.toml")
}

/// `host-sim run host-sim/scenarios/seed-mat.toml --pose slam --telemetry FILE`, and the
/// same run in the library.
pub fn record_seed_run(name: &str) -> RecordedRun {
    let dir = scratch(name);
    let file = dir.path().join("seed-slam.bin");
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("run")
        .arg(seed_path())
        .args(["--pose", "slam", "--telemetry"])
        .arg(&file)
        .output()
        .expect("host-sim starts");
    assert!(
        out.status.success(),
        "host-sim run failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&file).expect("the stream was written");
    let scenario = Scenario::load(&seed_path()).expect("seed scenario loads");
    let output = run(&scenario, PoseMode::Slam, scenario.seed).expect("seed runs");
    RecordedRun {
        messages: decode(&bytes),
        output,
        dir,
    }
}

/// Every message of a stream; the stream must be whole.
pub fn decode(bytes: &[u8]) -> Vec<Message> {
    let mut decoder = StreamDecoder::new();
    let mut messages = Vec::new();
    for &b in bytes {
        match decoder.push(b) {
            Some(Ok(m)) => messages.push(m),
            Some(Err(e)) => panic!("bad frame in the recorded stream: {e:?}"),
            None => {}
        }
    }
    messages
}

/// Plays `messages` into `server`, waiting `per_tick` after each `Tick` and pushing the
/// tick's true pose (`truth`, in tick order) after it, as a simulation at a set pace
/// would.
pub fn play(
    server: &mut PageServer,
    messages: &[Message],
    truth: &[TruthSample],
    per_tick: Duration,
) {
    let mut ticks = 0;
    for m in messages {
        server.push(m);
        if let Message::Tick(_) = m {
            if let Some(sample) = truth.get(ticks) {
                server.truth(sample);
            }
            ticks += 1;
            std::thread::sleep(per_tick);
        }
    }
}
