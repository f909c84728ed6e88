//! Helpers shared by host-sim's integration tests.

use slam_core::Localiser;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tempfile::TempDir;
use wire::telemetry::{FirmwareVersion, Hello};

/// A directory for a test's files, named from `prefix`, removed when the test ends,
/// passed or failed.
#[allow(dead_code)] // not every test file writes files
pub fn scratch_dir(prefix: &str) -> TempDir {
    TempDir::with_prefix(prefix).expect("scratch dir")
}

/// A file `name` in `dir` holding `contents`.
#[allow(dead_code)] // not every test file writes files
pub fn scratch_file(dir: &TempDir, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.path().join(name);
    if let Err(e) = std::fs::write(&path, contents) {
        panic!("cannot write {}: {e}", path.display());
    }
    path
}

/// The shipped seed scenario.
pub fn seed_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-mat.toml")
}

/// Runs the `host-sim` binary with `args` and returns what it did.
pub fn host_sim(args: &[&str]) -> Output {
    match Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
    {
        Ok(o) => o,
        Err(e) => panic!("cannot start host-sim: {e}"),
    }
}

/// The figures `host-sim run --json` reports that `host-sim view --truth --scenario --json`
/// reports too, under the same names (`run` adds `ticks` and the rest).
pub const SCORED_FIGURES: [&str; 14] = [
    "known_pct",
    "free",
    "occupied",
    "out_of_place",
    "fixes",
    "first_fix_s",
    "final_error_cm",
    "max_error_after_first_fix_cm",
    "max_error_1s_after_first_fix_cm",
    "final_heading_error_deg",
    "max_heading_error_after_first_fix_deg",
    "max_error_cm",
    "max_heading_error_deg",
    "max_jump_cm",
];

/// A `Hello` for a `width` x `height` grid of 5 cm cells at the origin, with the seed's
/// thresholds: what the stream tests build their maps on.
#[allow(dead_code)] // not every test file builds a stream
pub fn hello(width: u16, height: u16) -> Hello {
    Hello {
        width,
        height,
        cell_mm: 50,
        origin_x_mm: 0,
        origin_y_mm: 0,
        free_below: 16,
        occupied_above: 16,
        firmware: FirmwareVersion::default(),
        localiser: Localiser::TwoTagFix,
        matching: false,
        boot: Default::default(),
    }
}
