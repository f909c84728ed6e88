//! The project's commands: `cargo xtask <test|lint|firmware|emulate|bench|tools>`
//! (`cargo xtask help` lists them, `cargo xtask COMMAND --help` explains each).

use std::process::{Command, ExitCode};

use clap::{Parser, Subcommand};

use emulate::EmulateArgs;
use firmware::FirmwareArgs;

mod browser;
mod emulate;
mod firmware;
mod lint;
mod stage;
mod tools;

/// `cargo xtask`: the project's commands.
#[derive(Parser, Debug)]
#[command(name = "cargo xtask", bin_name = "cargo xtask", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Task,
}

#[derive(Subcommand, Debug)]
enum Task {
    /// Every test the project has: host crates, the live page in headless Chromium, the
    /// emulator's self-tests, the firmware build and budget, and the firmware on the
    /// emulated RP2040.
    Test,
    /// Formatting check, clippy on the host crates, and clippy on the firmware for its
    /// target (`-D warnings` both).
    Lint,
    /// Build the RP2040 firmware, write its UF2 and BIN images, check its flash and RAM.
    Firmware(FirmwareArgs),
    /// Run the real firmware on the rp2040js emulator in the simulator's world.
    Emulate(EmulateArgs),
    /// Every sensor failing every way on the emulated robot (24 runs), one row each.
    EmulateFaults(emulate::fault_matrix::FaultMatrixArgs),
    /// The firmware built for each shipped world and flown through its whole route,
    /// beside host-sim's run of it.
    EmulateWorlds(emulate::worlds::WorldsArgs),
    /// The simulator's and the firmware's speed figures.
    Bench(BenchArgs),
    /// Check that every external program the tests call is installed, and name the
    /// script that installs any that is not.
    Tools,
}

/// `cargo xtask bench`'s options.
#[derive(clap::Args, Debug)]
struct BenchArgs {
    /// Only the simulator's figures; skip the emulator.
    #[arg(long)]
    host_only: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match &cli.command {
        Task::Test => test(),
        Task::Lint => lint::run(),
        Task::Firmware(args) => firmware::run(args),
        Task::Emulate(args) => emulate::run(args),
        Task::EmulateFaults(args) => emulate::fault_matrix::run(args),
        Task::EmulateWorlds(args) => emulate::worlds::run(args),
        Task::Bench(args) => bench(args),
        Task::Tools => tools::check_all(),
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
        .map_err(|e| cannot_start(cmd, &e))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{:?} failed: {status}", cmd.get_program()))
    }
}

/// Why `cmd` did not start, with the script that installs it if the project has one.
pub fn cannot_start(cmd: &Command, e: &std::io::Error) -> String {
    let program = cmd.get_program().to_string_lossy();
    match tools::install_hint(&program) {
        Some(hint) if e.kind() == std::io::ErrorKind::NotFound => {
            format!("cannot start {program}: {e}; {hint}")
        }
        _ => format!("cannot start {program}: {e}"),
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

pub fn cargo() -> Command {
    Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
}

/// Every test the project has: the host crates, the live page in headless Chromium, the
/// emulator's own self-tests (its device models and harness), the firmware build with its
/// flash and RAM budget check, and the firmware itself on the emulated RP2040 (faults, the
/// fault matrix's 24 cases, the seed route, a reset and a room), and the firmware built
/// for every shipped world within its budget. Ends with
/// one line totalling the tests, so a reader (or CI) does not have to add up cargo's lines.
fn test() -> Result<(), String> {
    let (cargo_passed, cargo_failed) = stage::timed("cargo-tests", || {
        cargo_test(&["test", "--workspace", "--release"])
    })?;
    let (browser_passed, browser_failed) = stage::timed("browser", browser::run)?;
    let (self_passed, self_failed) = stage::timed("emulator-self-tests", emulate::self_tests::run)?;
    stage::timed("firmware-build", || firmware::run(&FirmwareArgs::default()))?;
    let (fault_passed, fault_failed) = stage::timed("emulator-faults", emulate::checks::fault_run)?;
    let (matrix_passed, matrix_failed) =
        stage::timed("emulator-fault-matrix", emulate::fault_matrix::ci_run)?;
    let (route_passed, route_failed) = stage::timed("emulator-route", emulate::checks::route_run)?;
    let (reset_passed, reset_failed) = stage::timed("emulator-reset", emulate::checks::reset_run)?;
    // Last, as they leave the firmware built for another world, or with the matcher.
    let (room_passed, room_failed) = stage::timed("emulator-room", emulate::checks::room_run)?;
    let (matching_passed, matching_failed) =
        stage::timed("emulator-matching", emulate::checks::matching_run)?;
    let (largest_passed, largest_failed) =
        stage::timed("emulator-largest-world", emulate::checks::largest_world_run)?;
    let (worlds_passed, worlds_failed) = stage::timed("firmware-worlds", firmware::worlds_run)?;
    let passed = cargo_passed
        + browser_passed
        + self_passed
        + fault_passed
        + matrix_passed
        + route_passed
        + reset_passed
        + room_passed
        + matching_passed
        + largest_passed
        + worlds_passed;
    let failed = cargo_failed
        + browser_failed
        + self_failed
        + fault_failed
        + matrix_failed
        + route_failed
        + reset_failed
        + room_failed
        + matching_failed
        + largest_failed
        + worlds_failed;
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
fn bench(args: &BenchArgs) -> Result<(), String> {
    run_cmd(cargo().args(["run", "--release", "-p", "host-sim", "--", "bench"]))?;
    if args.host_only {
        return Ok(());
    }
    let figures = emulator_figures(&["--seconds", "52"])?;
    let e = &figures["emulator"];
    let n = |key: &str| {
        e[key]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.0}"))
    };
    println!(
        "firmware on the emulated RP2040 (whole seed route, 52 simulated s, localiser {}):",
        figures["view"]["localiser"].as_str().unwrap_or("?")
    );
    println!(
        "  M0+ cycles per step: min {} / median {} / p99 {} / max {} (target: worst step <= 40000)",
        n("step_cycles_min"),
        n("step_cycles_median"),
        n("step_cycles_p99"),
        n("step_cycles_max")
    );
    println!(
        "  steps over 40000 cycles: {} of {}",
        n("step_cycles_over_budget"),
        n("ticks_seen")
    );
    match e["filter_share_pct"].as_f64() {
        Some(share) => println!(
            "  the filter's part: {share:.1} % of all step cycles; per step median {} / p99 {} / max {}, {} in the costliest step ({})",
            n("filter_cycles_median"),
            n("filter_cycles_p99"),
            n("filter_cycles_max"),
            n("filter_cycles_in_worst_step"),
            e["filter_measure"].as_str().unwrap_or("?")
        ),
        None => println!(
            "  the filter's part: not measured ({})",
            e["filter_measure"].as_str().unwrap_or("?")
        ),
    }
    if e["matches"].as_u64().is_some_and(|m| m > 0) {
        println!(
            "  M0+ cycles per match (searched between the steps): median {} / p99 {} / max {} over {} matches (target: <= 2500000)",
            n("match_cycles_median"),
            n("match_cycles_p99"),
            n("match_cycles_max"),
            n("matches")
        );
    }
    println!(
        "  beams mapped {}, core 1 load {} % (the depth sensor's driver)",
        figures["view"]["counters"]["beams_mapped"], e["devices"]["core1"]["load_pct"]
    );
    let stack = |core: &str| {
        let s = &e["stacks"][core];
        format!("{} of {} bytes", s["peak_bytes"], s["size_bytes"])
    };
    println!(
        "  deepest stack writes: core 0 {}, core 1 {} (a floor: read from SRAM after the run)",
        stack("core0"),
        stack("core1")
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
    bench_matching()
}

/// The scan matcher's figures: the firmware (built with `matching`, as by default) over
/// the seed route on the mat without tags.
fn bench_matching() -> Result<(), String> {
    let world = emulate::checks::MATCHING_WORLD;
    let figures = emulator_figures(&[world, "--seconds", "52"])?;
    let (e, v) = (&figures["emulator"], &figures["view"]);
    let n = |key: &str| {
        e[key]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.0}"))
    };
    println!(
        "firmware with the scan matcher alone ({world}, 52 simulated s, localiser {}):",
        v["localiser"].as_str().unwrap_or("?")
    );
    println!(
        "  M0+ cycles per match: median {} / p99 {} / max {} / mean {} over {} matches (target: <= 2500000); {} over",
        n("match_cycles_median"),
        n("match_cycles_p99"),
        n("match_cycles_max"),
        n("match_cycles_mean"),
        n("matches"),
        n("match_cycles_over_budget")
    );
    println!(
        "  M0+ cycles per step, the match left out: median {} / max {} (target: worst step <= 40000)",
        n("step_cycles_median"),
        n("step_cycles_max")
    );
    println!(
        "  core 0 load {} % (target: <= 25 % on average), overruns {}, final error {} cm",
        e["cpu_load_pct"]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.1}")),
        n("overruns"),
        v["final_error_cm"]
            .as_f64()
            .map_or("?".to_string(), |v| format!("{v:.2}"))
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn parses_each_subcommand() {
        let parse = |args: &[&str]| {
            Cli::try_parse_from(std::iter::once("cargo xtask").chain(args.iter().copied()))
        };
        assert!(matches!(parse(&["test"]).unwrap().command, Task::Test));
        assert!(matches!(parse(&["lint"]).unwrap().command, Task::Lint));
        match parse(&["firmware", "--no-default-features"])
            .unwrap()
            .command
        {
            Task::Firmware(a) => assert!(a.no_default_features && !a.check_only),
            other => panic!("{other:?}"),
        }
        match parse(&["emulate", "--seconds", "20", "--json"])
            .unwrap()
            .command
        {
            Task::Emulate(a) => assert!(a.json && a.seconds == "20"),
            other => panic!("{other:?}"),
        }
        match parse(&["bench", "--host-only"]).unwrap().command {
            Task::Bench(a) => assert!(a.host_only),
            other => panic!("{other:?}"),
        }
        // The bad command is named in the error.
        let err = parse(&["frobnicate"]).unwrap_err().to_string();
        assert!(err.contains("frobnicate"), "{err}");
        let err = parse(&["test", "--bogus"]).unwrap_err().to_string();
        assert!(err.contains("--bogus"), "{err}");
    }

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
