//! The live page's real-browser test: installs Chromium with the project's script, then
//! runs `host-sim/tests/page_browser.rs`, which a bare `cargo test` leaves ignored (as it
//! leaves the emulator's runs to this tool). Here it fails, not skips, when Chromium
//! cannot be installed or started.

use std::process::Command;

use crate::{cargo_test, run_in, workspace_root};

/// Runs `scripts/install-browser.sh` (quiet when Chromium is installed).
pub fn install() -> Result<(), String> {
    let root = workspace_root();
    run_in(
        &root,
        Command::new("bash").arg(root.join("scripts/install-browser.sh")),
    )
}

/// Installs Chromium if missing, then runs the ignored browser test; returns (passed,
/// failed) as cargo counts them. Built with `--workspace`, as the `cargo-tests` stage
/// builds, so that the same features are unified and nothing is compiled again.
pub fn run() -> Result<(u64, u64), String> {
    install()?;
    cargo_test(&[
        "test",
        "--workspace",
        "--release",
        "--test",
        "page_browser",
        "--",
        "--ignored",
    ])
}
