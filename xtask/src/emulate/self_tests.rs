//! The emulator's own self-tests: its device models and harness, run by node.

use std::path::PathBuf;
use std::process::{Command, Stdio};

use super::stderr_fd;
use crate::{run_in, workspace_root};

/// The emulator harness's directory: `tests/emulator`.
pub fn harness_dir() -> PathBuf {
    workspace_root().join("tests/emulator")
}

/// Runs `scripts/install-node.sh` (quiet when node and npm are installed), its report on
/// stderr: stdout must hold only the figures under --json.
fn install_node() -> Result<(), String> {
    let root = workspace_root();
    run_in(
        &root,
        Command::new("bash")
            .arg(root.join("scripts/install-node.sh"))
            .stdout(Stdio::from(stderr_fd()?)),
    )
}

/// Installs node if missing, then the harness's npm dependencies (`rp2040js`) from its
/// lock file, if missing.
pub fn install_harness_dependencies() -> Result<(), String> {
    install_node()?;
    let dir = harness_dir();
    if dir.join("node_modules/rp2040js").is_dir() {
        return Ok(());
    }
    // npm reports on stdout, which must hold only the figures under --json.
    run_in(
        &dir,
        Command::new("npm")
            .arg("ci")
            .stdout(Stdio::from(stderr_fd()?)),
    )
}

/// The emulator's own self-tests, as `cargo xtask test` counts them: the VL53L5CX model
/// against the facts of ST's ULD (`vl53l5cx.mjs --self-test`, which ends with a line
/// `vl53l5cx model self-test: N passed, M failed`) and the harness's camera framing, fault
/// parsing, hardware divider and core 1 (each core dividing on its own divider)
/// (`harness.mjs --self-test`, a line `ok   NAME` or `FAIL NAME` per check).
/// Echoes their output; returns (passed, failed), counted by [`self_test_counts`].
pub fn run() -> Result<(u64, u64), String> {
    install_harness_dependencies()?;
    let dir = harness_dir();
    let (mut passed, mut failed) = (0, 0);
    for script in ["vl53l5cx.mjs", "harness.mjs"] {
        let mut cmd = Command::new("node");
        cmd.arg(dir.join(script)).arg("--self-test");
        eprintln!("+ (cd {}) {cmd:?}", dir.display());
        let out = cmd
            .current_dir(&dir)
            .stderr(Stdio::inherit())
            .output()
            .map_err(|e| format!("{} (for {script})", crate::cannot_start(&cmd, &e)))?;
        let text = String::from_utf8_lossy(&out.stdout);
        print!("{text}");
        let (p, f) = self_test_counts(&text, out.status.success());
        println!(
            "emulator self-test {script}: {p} passed, {f} failed ({})",
            out.status
        );
        passed += p;
        failed += f;
    }
    Ok((passed, failed))
}

/// Passed and failed checks in a self-test's output: its `N passed, M failed` line if it
/// prints one, else its `ok` and `FAIL` lines. A failing exit with no failure counted is
/// one failure more (the script broke before or after its checks), and output with no
/// count at all is one test, passed if the script exited 0.
fn self_test_counts(stdout: &str, exit_ok: bool) -> (u64, u64) {
    let summary = stdout
        .lines()
        .rev()
        .find(|l| l.contains(" passed, ") && l.trim_end().ends_with(" failed"));
    let (passed, failed) = match summary {
        Some(line) => (
            crate::count_before(line, " passed"),
            crate::count_before(line, " failed"),
        ),
        None => stdout.lines().fold((0, 0), |(p, f), line| {
            if line.starts_with("ok ") {
                (p + 1, f)
            } else if line.starts_with("FAIL") {
                (p, f + 1)
            } else {
                (p, f)
            }
        }),
    };
    match (passed + failed, exit_ok) {
        (0, true) => (1, 0),
        (_, false) if failed == 0 => (passed, 1),
        _ => (passed, failed),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn self_tests_are_counted_from_their_output_and_exit() {
        let model = "set-up\nvl53l5cx model self-test: 39 passed, 2 failed\n";
        assert_eq!(self_test_counts(model, false), (39, 2));
        assert_eq!(self_test_counts(model, true), (39, 2));
        let harness = "ok   crc check value\nFAIL fixture crc\nok   fault parse\n";
        assert_eq!(self_test_counts(harness, false), (2, 1));
        // Every line ok but a failing exit: the script broke, one failure.
        assert_eq!(self_test_counts("ok   a\nok   b\n", false), (2, 1));
        assert_eq!(self_test_counts("ok   a\nok   b\n", true), (2, 0));
        // Nothing to count: the self-test is one test, judged by its exit.
        assert_eq!(self_test_counts("", true), (1, 0));
        assert_eq!(self_test_counts("Error: boom\n", false), (0, 1));
    }
}
