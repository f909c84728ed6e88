//! `cargo xtask emulate`: the real firmware in the `rp2040js` emulator, living in the
//! simulator's world.
//!
//! Steps: install the harness's npm dependencies from its lock file if they are missing,
//! build the firmware for the scenario's world (`cargo xtask firmware --world SCENARIO`),
//! build `host-sim`, run
//! `tests/emulator/harness.mjs` (which starts `host-sim serve` itself and talks to it over
//! two FIFOs, so the world is read at exactly the simulated instant the firmware asks),
//! then decode the firmware's defmt log ([`defmt_log`], with the table from the ELF; written as text
//! with its times to `defmt.log`) for
//! its own loop counters, and the captured telemetry with `host-sim view`, which prints the figures and
//! draws the pictures into `out/emulator/`. The harness also records the world's true pose
//! at each step (`truth.jsonl`), so `view --truth --scenario` reports the figures
//! `host-sim run` reports, worked out by the same code. Then `host-sim replay` steps the
//! stream's input frames through the core again and compares the result with what the
//! firmware sent, tick for tick. Last, the copy of the telemetry the harness's USB host
//! read over the firmware's CDC ACM serial port is held to the UART's ([`usb_stream`]).
//!
//! [`checks`] holds what `cargo xtask test` requires of such runs, [`self_tests`] runs the
//! harness's own tests.

pub mod checks;
pub mod defmt_log;
pub mod fault_matrix;
pub mod progress;
pub mod self_tests;
pub mod usb_stream;
pub mod worlds;

use std::os::fd::AsFd;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::firmware::{self, FirmwareArgs};
use crate::{run_cmd, run_in, workspace_root};
use defmt_log::LoopCounters;

/// `cargo xtask emulate`'s options.
#[derive(clap::Args, Clone, Debug, PartialEq, Eq)]
pub struct EmulateArgs {
    /// host-sim scenario file: the firmware is built for its world and flies in it
    /// [default: host-sim/scenarios/seed-mat.toml]
    #[arg(value_name = "SCENARIO")]
    pub scenario: Option<PathBuf>,
    /// Simulated seconds to run.
    #[arg(long, value_name = "N", default_value = "60", value_parser = positive_number)]
    pub seconds: String,
    /// The world's noise seed.
    #[arg(long, value_name = "N", default_value = "1", value_parser = positive_number)]
    pub seed: String,
    /// Accepted for symmetry with `host-sim run`; the firmware chooses its own pose
    /// source, so this only labels the output directory.
    #[arg(long, value_name = "MODE")]
    pub pose: Option<String>,
    /// SENSOR-KIND from S seconds on (`NAME@T+S`, or `NAME@T+S/D` for D seconds):
    /// SENSOR one of depth, flow, gyro, camera; KIND one of off, stuck, garbage, wrong,
    /// slow, intermittent (and flow-no-surface); or core0-hang (core 0 stops between two
    /// ticks) or step-hang (inside a SLAM step) once at S seconds, until the watchdog
    /// resets the chip; repeatable.
    #[arg(long = "fault", value_name = "NAME@T+S")]
    pub faults: Vec<String>,
    /// Run without host-sim: the robot stands still on a good surface.
    #[arg(long)]
    pub no_world: bool,
    /// Leave the USB port unplugged: no host enumerates the firmware's device, and the
    /// USB copy of the telemetry is neither recorded nor checked.
    #[arg(long)]
    pub no_usb: bool,
    /// Stop after this many wall-clock seconds.
    #[arg(long, value_name = "S", value_parser = positive_number)]
    pub max_wall: Option<String>,
    /// Print one JSON object: {"emulator": ..., "view": ..., "replay": ..., "usb": ...,
    /// "out_dir": ...}.
    #[arg(long)]
    pub json: bool,
    /// Firmware features to build with (comma-separated), as `cargo xtask firmware -F`.
    #[arg(long, short = 'F', value_name = "LIST")]
    pub features: Vec<String>,
}

/// A positive number, kept as text for the harness's command line.
fn positive_number(text: &str) -> Result<String, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(text.to_string()),
        _ => Err(format!("expected a positive number, got {text:?}")),
    }
}

/// `cargo xtask emulate`.
pub fn run(args: &EmulateArgs) -> Result<(), String> {
    let root = workspace_root();
    // The firmware is built for the world it flies in.
    let firmware_args = FirmwareArgs {
        world: args.scenario.clone(),
        features: args.features.clone(),
        ..FirmwareArgs::default()
    };
    let scenario = firmware_args.world_file();
    let harness_dir = self_tests::harness_dir();
    let out_dir = match &args.pose {
        Some(pose) => root.join("out/emulator").join(pose),
        None => root.join("out/emulator"),
    };
    std::fs::create_dir_all(&out_dir)
        .map_err(|e| format!("cannot create {}: {e}", out_dir.display()))?;

    self_tests::install_harness_dependencies()?;

    let elf = firmware::elf_path();
    let bin = elf.with_extension("bin");
    // With --json, stdout must hold one JSON object; `firmware::run` prints its size
    // table there, so it runs as `xtask firmware` in a child with stdout sent to stderr.
    let built = if args.json {
        firmware_quietly(&scenario, &args.features)
    } else {
        firmware::run(&firmware_args)
    };
    if let Err(e) = built {
        // The budget check fails after a good build; the image is still worth running.
        if elf.is_file() && bin.is_file() {
            eprintln!("xtask emulate: warning: {e}; emulating the image that was built");
        } else {
            return Err(e);
        }
    }

    let host_sim = host_sim_binary();
    run_cmd(crate::cargo().args(["build", "--release", "-p", "host-sim"]))?;

    let telemetry = out_dir.join("telemetry.bin");
    let defmt = out_dir.join("defmt.raw");
    let truth = out_dir.join("truth.jsonl");
    let usb_telemetry = out_dir.join("usb-telemetry.bin");
    let mut harness = Command::new("node");
    harness
        .arg(harness_dir.join("harness.mjs"))
        .arg("--elf")
        .arg(&elf)
        .arg("--bin")
        .arg(&bin)
        .arg("--scenario")
        .arg(&scenario)
        .args(["--seconds", &args.seconds, "--seed", &args.seed])
        .arg("--telemetry")
        .arg(&telemetry)
        .arg("--defmt")
        .arg(&defmt)
        .arg("--json");
    if args.no_world {
        harness.arg("--no-world");
    } else {
        harness
            .arg("--host-sim")
            .arg(&host_sim)
            .arg("--truth")
            .arg(&truth);
    }
    if args.no_usb {
        harness.arg("--no-usb");
    } else {
        harness.arg("--usb-telemetry").arg(&usb_telemetry);
    }
    if let Some(s) = &args.max_wall {
        harness.args(["--max-wall", s]);
    }
    for f in &args.faults {
        harness.args(["--fault", f]);
    }
    // The last run's log goes first, so that the progress bar follows only this one.
    let _ = std::fs::remove_file(&defmt);
    let seconds: f64 = args.seconds.parse().unwrap_or(0.0);
    let progress = progress::Progress::start(&elf, &defmt, seconds);
    let harness_out = capture(&root, &mut harness);
    if let Some(p) = progress {
        p.finish();
    }
    let harness_out = harness_out?;
    let mut emulator: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(harness_out.trim())
            .map_err(|e| format!("the harness's figures are not a JSON object: {e}"))?;

    // The firmware's own view of its loop, from its defmt log.
    let lines = read_defmt_log(&elf, &defmt)?;
    // Beside the capture, as text with the firmware's times: what `host-sim view --log`
    // reads, in the shape `probe-rs run` prints on a robot.
    let defmt_text = out_dir.join("defmt.log");
    std::fs::write(&defmt_text, defmt_log::text(&lines))
        .map_err(|e| format!("cannot write {}: {e}", defmt_text.display()))?;
    if !args.json {
        for line in &lines {
            eprintln!("{line}");
        }
    }
    let counters = LoopCounters::last_in(&lines)
        .map_err(|e| format!("the firmware's defmt log {}: {e}", defmt.display()))?;
    defmt_log::add_figures(&mut emulator, &lines, counters);
    let usb_json = if args.no_usb {
        serde_json::Value::Null
    } else {
        usb_stream::check(&telemetry, &usb_telemetry, &lines)?
    };
    let emulator_json = serde_json::Value::Object(emulator);

    let mut view = Command::new(&host_sim);
    view.arg("view").arg(&telemetry).arg("--out").arg(&out_dir);
    if !args.no_world {
        // Scored as `host-sim run` scores the simulator: pose against the truth, map
        // against the scenario's world.
        view.arg("--truth")
            .arg(&truth)
            .arg("--scenario")
            .arg(&scenario);
    }
    if args.json {
        view.arg("--json");
    }
    // A failing view must not hide the emulator's own figures.
    let view_out = capture(&root, &mut view);

    // The stream's inputs stepped again on the host with the firmware's own settings: the
    // replay must be the firmware's run, bit for bit (`checks` holds it to that).
    let mut replay = Command::new(&host_sim);
    replay
        .arg("replay")
        .arg(&telemetry)
        .arg("--scenario")
        .arg(&scenario)
        .arg("--json");
    let replay_json = replay_summary(&root, &mut replay);

    if args.json {
        let view_json = match &view_out {
            Ok(text) if text.trim_start().starts_with('{') => text.trim().to_string(),
            Ok(text) => json_string(text.trim()),
            Err(e) => format!("{{\"error\":{}}}", json_string(e)),
        };
        println!(
            "{{\"emulator\":{emulator_json},\"view\":{view_json},\"replay\":{replay_json},\"usb\":{usb_json},\"out_dir\":{}}}",
            json_string(&out_dir.display().to_string())
        );
    } else {
        println!("emulator: {emulator_json}");
        match view_out {
            Ok(text) => println!("{}", text.trim_end()),
            Err(e) => eprintln!("xtask emulate: host-sim view failed: {e}"),
        }
        println!("replay: {replay_json}");
        if !args.no_usb {
            println!("usb: {usb_json}");
        }
        println!("pictures and raw streams in {}", out_dir.display());
        if !args.no_usb {
            usb_stream::verdict(&emulator_json["usb"], &usb_json)?;
        }
    }
    Ok(())
}

/// `host-sim replay --json`'s `replay` object, whatever its exit code (a replay that
/// differs exits 3 and still reports where); `{"error": ...}` when there is none.
fn replay_summary(dir: &Path, cmd: &mut Command) -> serde_json::Value {
    eprintln!("+ {:?}", cmd);
    let error = |e: String| serde_json::json!({ "error": e });
    match cmd.current_dir(dir).stderr(Stdio::inherit()).output() {
        Ok(out) => match serde_json::from_slice::<serde_json::Value>(&out.stdout) {
            Ok(v) if v["replay"].is_object() => v["replay"].clone(),
            _ => error(format!("host-sim replay gave no figures: {}", out.status)),
        },
        Err(e) => error(crate::cannot_start(cmd, &e)),
    }
}

/// Decodes the harness's raw defmt capture with the table in the firmware's ELF.
fn read_defmt_log(elf: &Path, log: &Path) -> Result<Vec<defmt_log::LogLine>, String> {
    let read = |p: &Path| std::fs::read(p).map_err(|e| format!("cannot read {}: {e}", p.display()));
    defmt_log::decode(&read(elf)?, &read(log)?).map_err(|e| {
        format!(
            "the firmware's defmt log {} (decoded with {}): {e}",
            log.display(),
            elf.display()
        )
    })
}

/// `cargo xtask firmware --world WORLD` (this very binary), its stdout redirected to
/// stderr.
fn firmware_quietly(world: &Path, features: &[String]) -> Result<(), String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find xtask itself: {e}"))?;
    let mut build = Command::new(exe);
    build.arg("firmware").arg("--world").arg(world);
    for list in features {
        build.arg("--features").arg(list);
    }
    run_in(&workspace_root(), build.stdout(Stdio::from(stderr_fd()?)))
}

/// A copy of this process's stderr, to send a child's stdout there.
pub(crate) fn stderr_fd() -> Result<std::os::fd::OwnedFd, String> {
    std::io::stderr()
        .as_fd()
        .try_clone_to_owned()
        .map_err(|e| format!("cannot duplicate stderr: {e}"))
}

/// The `host-sim` binary cargo builds: under `CARGO_TARGET_DIR` if set, else `target/`.
pub fn host_sim_binary() -> PathBuf {
    let root = workspace_root();
    std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| root.join("target"), |d| root.join(d))
        .join("release/host-sim")
}

/// Runs `cmd` from `dir`, stderr passed through, and returns its stdout.
pub fn capture(dir: &Path, cmd: &mut Command) -> Result<String, String> {
    eprintln!("+ {:?}", cmd);
    let output = cmd
        .current_dir(dir)
        .stderr(Stdio::inherit())
        .output()
        .map_err(|e| crate::cannot_start(cmd, &e))?;
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    if output.status.success() {
        Ok(stdout)
    } else {
        Err(format!(
            "{:?} failed: {}{}",
            cmd.get_program(),
            output.status,
            if stdout.is_empty() {
                String::new()
            } else {
                format!("\n{stdout}")
            }
        ))
    }
}

/// `text` as a JSON string literal.
fn json_string(text: &str) -> String {
    serde_json::Value::String(text.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(clap::Parser)]
    struct Cli {
        #[command(flatten)]
        args: EmulateArgs,
    }

    fn parse(a: &[&str]) -> Result<EmulateArgs, clap::Error> {
        Cli::try_parse_from(std::iter::once("emulate").chain(a.iter().copied())).map(|c| c.args)
    }

    #[test]
    fn parses_scenario_and_options() {
        let a = parse(&[
            "s.toml",
            "--seconds",
            "5",
            "--fault",
            "depth-nack@T+3",
            "--fault",
            "gyro-nack@T+1/2",
            "--json",
            "--max-wall",
            "30",
        ])
        .unwrap();
        assert_eq!(a.scenario, Some(PathBuf::from("s.toml")));
        assert_eq!(a.seconds, "5");
        assert_eq!(a.seed, "1");
        assert_eq!(a.faults, ["depth-nack@T+3", "gyro-nack@T+1/2"]);
        assert_eq!(a.max_wall.as_deref(), Some("30"));
        assert!(a.json && !a.no_world && !a.no_usb);
        assert!(parse(&["--no-usb"]).unwrap().no_usb);
        let d = parse(&["--no-world"]).unwrap();
        assert_eq!((d.scenario, d.seconds.as_str()), (None, "60"));
        assert!(d.no_world);
    }

    #[test]
    fn rejects_bad_numbers_and_extra_arguments() {
        assert!(parse(&["--seconds", "-1"]).is_err());
        assert!(parse(&["--seed", "nan"]).is_err());
        assert!(parse(&["a.toml", "b.toml"]).is_err());
        assert!(parse(&["--bogus"]).is_err());
    }

    #[test]
    fn json_strings_are_escaped() {
        assert_eq!(json_string("a\"b\\c\n"), "\"a\\\"b\\\\c\\n\"");
    }
}
