//! `cargo xtask lint`: formatting, then clippy with `-D warnings` on the host crates and on
//! the firmware for its own target (the root workspace excludes the firmware, so the host
//! clippy never sees it), then the host crates' docs with rustdoc's warnings as errors (a
//! link to an item that moved or is private).

use crate::{cargo, run_cmd, stage};

/// Runs every lint, each as a timed stage, and fails on the first that fails.
pub fn run() -> Result<(), String> {
    stage::timed("fmt", || run_cmd(cargo().args(["fmt", "--all", "--check"])))?;
    stage::timed("clippy-host", || {
        run_cmd(cargo().args([
            "clippy",
            "--workspace",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ]))
    })?;
    stage::timed("clippy-firmware", crate::firmware::clippy)?;
    stage::timed("doc", || {
        run_cmd(
            cargo()
                .args(["doc", "--workspace", "--no-deps"])
                .env("RUSTDOCFLAGS", "-D warnings"),
        )
    })
}
