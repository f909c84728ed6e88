//! Helpers shared by host-sim's integration tests.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

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
