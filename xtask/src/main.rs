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
    run_in(&workspace_root(), cmd)
}

/// Runs a command in `dir` and fails if it does. (The firmware builds from `firmware/`, so
/// that cargo reads that crate's own `.cargo/config.toml`.)
pub fn run_in(dir: &std::path::Path, cmd: &mut Command) -> Result<(), String> {
    eprintln!("+ (cd {}) {:?}", dir.display(), cmd);
    let status = cmd
        .current_dir(dir)
        .status()
        .map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{:?} failed: {status}", cmd.get_program()))
    }
}

/// The workspace root: the parent of this crate's manifest directory.
///
/// `cargo run` sets `CARGO_MANIFEST_DIR` for the running binary, and that is preferred to
/// the path compiled in: two checkouts sharing one `CARGO_TARGET_DIR` share one xtask
/// binary, which would otherwise build and test the other checkout.
pub fn workspace_root() -> std::path::PathBuf {
    let here = std::env::var_os("CARGO_MANIFEST_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    here.parent()
        .map_or_else(|| here.clone(), std::path::Path::to_path_buf)
}

fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

/// Every test the project has: the host crates, the emulator's own self-tests (its device
/// models and harness), the firmware build with its flash and RAM budget check, and the
/// firmware itself on the emulated RP2040. Ends with one line totalling the tests, so a
/// reader (or CI) does not have to add up cargo's lines.
fn test(_args: &[String]) -> Result<(), String> {
    let (cargo_passed, cargo_failed) = cargo_test(&["test", "--workspace", "--release"])?;
    let (self_passed, self_failed) = emulate::check_self_tests()?;
    firmware::run(&[])?;
    let (fault_passed, fault_failed) = emulate::check_fault_run()?;
    let (route_passed, route_failed) = emulate::check_route_run()?;
    let passed = cargo_passed + self_passed + fault_passed + route_passed;
    let failed = cargo_failed + self_failed + fault_failed + route_failed;
    println!("tests: {passed} passed, {failed} failed");
    if failed > 0 {
        return Err(format!("{failed} tests failed"));
    }
    Ok(())
}

/// Runs `cargo xtask emulate --json` with `args` in a child and returns its figures.
pub fn emulator_figures(args: &[&str]) -> Result<serde_json::Value, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find xtask itself: {e}"))?;
    let out = Command::new(exe)
        .arg("emulate")
        .arg("--json")
        .args(args)
        .current_dir(workspace_root())
        .stderr(std::process::Stdio::inherit())
        .output()
        .map_err(|e| format!("cannot run the emulator: {e}"))?;
    if !out.status.success() {
        return Err(format!("cargo xtask emulate failed: {}", out.status));
    }
    serde_json::from_slice(&out.stdout)
        .map_err(|e| format!("the emulator's figures are not JSON: {e}"))
}

/// Runs `cargo <args>`, echoing its output, and adds up its `test result:` lines.
fn cargo_test(args: &[&str]) -> Result<(u64, u64), String> {
    use std::io::{BufRead, BufReader};
    use std::process::Stdio;
    let mut cmd = cargo();
    cmd.args(args)
        .current_dir(workspace_root())
        .stdout(Stdio::piped());
    eprintln!("+ {cmd:?}");
    let mut child = cmd
        .spawn()
        .map_err(|e| format!("cannot start cargo: {e}"))?;
    let (mut passed, mut failed) = (0, 0);
    if let Some(out) = child.stdout.take() {
        for line in BufReader::new(out).lines() {
            let line = line.map_err(|e| format!("reading cargo's output: {e}"))?;
            println!("{line}");
            if let Some(rest) = line.strip_prefix("test result: ") {
                passed += count_before(rest, " passed");
                failed += count_before(rest, " failed");
            }
        }
    }
    let status = child
        .wait()
        .map_err(|e| format!("waiting for cargo: {e}"))?;
    if !status.success() {
        return Err(format!(
            "cargo test failed: {status} ({passed} passed, {failed} failed)"
        ));
    }
    Ok((passed, failed))
}

/// The number just before `label` in a line like `ok. 12 passed; 0 failed; ...`.
fn count_before(line: &str, label: &str) -> u64 {
    line.find(label)
        .and_then(|end| line[..end].rsplit([' ', '.']).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

/// The project's speed figures: the simulator's simulated seconds per wall second and
/// host nanoseconds per `step`, then the real firmware's Cortex-M0+ cycles per `step` on
/// the emulator over the seed route (`--host-only` skips the emulator).
fn bench(args: &[String]) -> Result<(), String> {
    run_cmd(cargo().args(["run", "--release", "-p", "host-sim", "--", "bench"]))?;
    if args.iter().any(|a| a == "--host-only") {
        return Ok(());
    }
    let figures = emulator_figures(&["--seconds", "52"])?;
    let e = &figures["emulator"];
    let n = |key: &str| {
        e[key]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.0}"))
    };
    println!("firmware on the emulated RP2040 (whole seed route, 52 simulated s):");
    println!(
        "  M0+ cycles per step: min {} / median {} / p99 {} / max {} (target: map and pose update <= 20000)",
        n("step_cycles_min"),
        n("step_cycles_median"),
        n("step_cycles_p99"),
        n("step_cycles_max")
    );
    println!(
        "  steps over 20000 cycles: {} of {}",
        n("step_cycles_over_budget"),
        n("ticks_seen")
    );
    println!(
        "  beams mapped {}, core 1 load {} % (the depth sensor's driver)",
        figures["view"]["counters"]["beams_mapped"], e["devices"]["core1"]["load_pct"]
    );
    println!(
        "  ticks {}, overruns {}, CPU load {} %, {} simulated s per wall s",
        n("ticks_seen"),
        n("overruns"),
        e["cpu_load_pct"]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.1}")),
        e["sim_per_wall"]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.1}"))
    );
    if figures["view"]["counters"]["beams_mapped"].as_u64() == Some(0) {
        println!("  note: no depth beam was mapped in this run (the depth sensor did not start),");
        println!("  so these cycles are the pose update and tag fix alone");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::count_before;

    #[test]
    fn reads_cargo_result_lines() {
        let line =
            "ok. 12 passed; 3 failed; 0 ignored; 0 measured; 0 filtered out; finished in 0.01s";
        assert_eq!(count_before(line, " passed"), 12);
        assert_eq!(count_before(line, " failed"), 3);
        assert_eq!(count_before("FAILED. 0 passed; 1 failed;", " failed"), 1);
        assert_eq!(count_before("nothing here", " passed"), 0);
    }
}
