//! The project's commands: `cargo xtask <test|firmware|emulate|bench>`.

use std::process::{Command, ExitCode};

mod emulate;
mod firmware;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("test") => test(&args[1..]),
        Some("firmware") => firmware::run(&args[1..]),
        Some("emulate") => emulate::run(&args[1..]),
        Some("bench") => bench(&args[1..]),
        _ => {
            eprintln!("usage: cargo xtask <test|firmware|bench> [args]");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs a command from the workspace root and fails if it does.
pub fn run_cmd(cmd: &mut Command) -> Result<(), String> {
    eprintln!("+ {:?}", cmd);
    let status = cmd
        .current_dir(workspace_root())
        .status()
        .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{:?} failed: {status}", cmd.get_program()))
    }
}

/// The workspace root: the parent of this crate's manifest directory.
pub fn workspace_root() -> std::path::PathBuf {
    let here = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

/// Every test the project has: the host crates, then the firmware build with its
/// flash and RAM budget check.
fn test(_args: &[String]) -> Result<(), String> {
    run_cmd(cargo().args(["test", "--workspace", "--release"]))?;
    firmware::run(&[])
}

/// Host benchmarks: simulated seconds per wall second and nanoseconds per `step`.
fn bench(_args: &[String]) -> Result<(), String> {
    run_cmd(cargo().args(["run", "--release", "-p", "host-sim", "--", "bench"]))
}
