//! The command line: one `clap` parser per subcommand.
//!
//! Every flag keeps the name, meaning and default it had when the arguments were read by
//! hand, so the README's commands and the emulator harness's calls work as written.
//! Usage errors exit with 2, `--help` with 0 (clap's codes, which are also ours).

use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand, ValueHint};
use host_sim::fault::Fault;
use host_sim::live::pace::SPEED_RANGE;
use host_sim::run::PoseMode;
use std::path::PathBuf;

/// The telemetry link's speed, baud: what the firmware sends at
/// (`firmware/src/board.rs`, `TELEMETRY_BAUD`).
pub const TELEMETRY_BAUD: u32 = 921_600;

/// Longest `view --seconds`, seconds (about 32 years): it keeps `Instant::now()` plus the
/// deadline from overflowing, which would panic.
const MAX_VIEW_SECONDS: f64 = 1e9;

/// BugBot's simulated mat and robot: run a scenario, watch a robot's telemetry, replay
/// its inputs, serve the emulator, or benchmark.
///
/// Exit codes: 0 done, 1 the pictures, the stream or the MCAP file could not be written
/// or a live server could not listen (its port in use), 2 bad arguments, scenario or
/// stream, 3 a replay with the robot's settings that differs from the robot's run.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Run a scenario and print its figures; optionally draw its pictures and write the
    /// telemetry stream the robot would send.
    Run(RunArgs),
    /// Decode a telemetry stream (a file, or live from the robot's serial port until end
    /// of file, Ctrl-C or --seconds), print what it held and draw the same two pictures.
    View(ViewArgs),
    /// Step a recorded stream's input frames through the core again: with the robot's own
    /// settings check that the replay is the robot's run bit for bit, with others (--pose)
    /// see what they would have done; print and draw what `view` does.
    Replay(ReplayArgs),
    /// The simulator as the emulated robot's world: JSON lines on stdin and stdout.
    Serve(ServeArgs),
    /// Simulated seconds per wall second on a route, and host nanoseconds per `step`.
    Bench(BenchArgs),
    /// The fault matrix: each sensor failing each way for a stretch of the route, on
    /// several seeds, beside the same runs without the fault.
    Faults(FaultsArgs),
}

/// `host-sim run`.
#[derive(Debug, Args)]
pub struct RunArgs {
    /// The scenario file (TOML).
    #[arg(value_name = "SCENARIO", value_hint = ValueHint::FilePath)]
    pub scenario: PathBuf,
    /// Which pose the mapper uses: the simulator's truth, odometry alone, odometry
    /// corrected by two-tag fixes (the seed's), the filter on every tag sighting (filter:
    /// what the firmware flies), the filter on scan matching alone with no tags (match),
    /// or the filter on tags and scan matching together (slam).
    #[arg(long, value_name = "MODE", default_value = "tags", value_parser = pose_mode())]
    pub pose: PoseMode,
    /// Seed of the noise (default: the scenario's `seed`).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub seed: Option<u64>,
    /// Print the figures as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Drive the route blind: no guard stops a drive before a wall (the body still stops
    /// at one, counted as a collision). Shows what the guard saves.
    #[arg(long)]
    pub no_guard: bool,
    /// Draw DIR/NAME-POSE-map.png and DIR/NAME-POSE-chart.png, and write each tick's
    /// figures as a line of JSON to DIR/NAME-POSE-ticks.jsonl, creating DIR.
    #[arg(long, value_name = "DIR", value_hint = ValueHint::DirPath)]
    pub out: Option<PathBuf>,
    /// Also write the telemetry stream the robot would send on this run.
    #[arg(long, value_name = "FILE", value_hint = ValueHint::FilePath)]
    pub telemetry: Option<PathBuf>,
    /// Write the final map as a ROS map_server pair, DIR/map.pgm and DIR/map.yaml.
    #[arg(long, value_name = "DIR", value_hint = ValueHint::DirPath)]
    pub export_map: Option<PathBuf>,
    /// Make a sensor fail: SENSOR-KIND@START[/DURATION] in seconds, e.g. gyro-stuck@5/3
    /// (sensors depth, flow, gyro, camera; kinds off, stuck, garbage, wrong, slow,
    /// intermittent; without a duration, for good). May be given more than once.
    #[arg(long, value_name = "FAULT")]
    pub fault: Vec<Fault>,
    /// Watching the run live, and recording it for Foxglove.
    #[command(flatten)]
    pub live: LiveArgs,
}

/// `--live` and `--mcap`, on `run` and `view`.
#[derive(Debug, Args)]
pub struct LiveArgs {
    /// Play the run at real speed (a recorded file at the pace its ticks were recorded, a
    /// serial port as it comes) and serve it to the Foxglove app on a WebSocket, and as a
    /// page, on 127.0.0.1.
    #[arg(long)]
    pub live: bool,
    /// The Foxglove WebSocket's port (0: any free port; the port is printed on stderr).
    #[arg(long, value_name = "N", default_value_t = 8765, requires = "live")]
    pub foxglove_port: u16,
    /// The page's port, http://localhost:N/ (0: any free port).
    #[arg(long, value_name = "N", default_value_t = 8080, requires = "live")]
    pub port: u16,
    /// Play this many times faster than real time, 0.1 to 1000 (a recorded file or a
    /// simulated run; a serial port comes at its own pace).
    #[arg(long, value_name = "X", default_value_t = 1.0, requires = "live",
          allow_negative_numbers = true, value_parser = speed_factor)]
    pub speed: f64,
    /// Record the Foxglove channels into FILE (MCAP), to open in Foxglove later; without
    /// --live the run is played as fast as it goes.
    #[arg(long, value_name = "FILE", value_hint = ValueHint::FilePath)]
    pub mcap: Option<PathBuf>,
}

impl LiveArgs {
    /// Whether the run goes through a live session (served, recorded, or both).
    pub fn wanted(&self) -> bool {
        self.live || self.mcap.is_some()
    }
}

/// `--speed`: a factor within [`SPEED_RANGE`].
fn speed_factor(text: &str) -> Result<f64, String> {
    let (low, high) = SPEED_RANGE;
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && (low..=high).contains(&x) => Ok(x),
        _ => Err(format!("wants a factor from {low} to {high}")),
    }
}

/// `host-sim view`.
#[derive(Debug, Args)]
pub struct ViewArgs {
    /// A recorded telemetry file, or the robot's serial device (e.g. /dev/ttyACM0, COM3).
    #[arg(value_name = "SOURCE", value_hint = ValueHint::AnyPath)]
    pub source: PathBuf,
    /// Draw the map and chart into DIR, with each tick's figures in STEM-ticks.jsonl,
    /// creating it.
    #[arg(long, value_name = "DIR", value_hint = ValueHint::DirPath)]
    pub out: Option<PathBuf>,
    /// Serial speed, baud: the firmware's telemetry link runs at 921600.
    #[arg(long, value_name = "N", default_value_t = TELEMETRY_BAUD,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub baud: u32,
    /// Stop reading after this many seconds.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = positive_seconds)]
    pub seconds: Option<f64>,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Score each tick's pose against this truth (a line of JSON per step, as the
    /// emulator's harness writes it).
    #[arg(long, value_name = "TRUTH.jsonl", value_hint = ValueHint::FilePath)]
    pub truth: Option<PathBuf>,
    /// Score the map against this scenario's world, giving `run`'s figures.
    #[arg(long, value_name = "SCENARIO.toml", value_hint = ValueHint::FilePath)]
    pub scenario: Option<PathBuf>,
    /// Write the final map as a ROS map_server pair, DIR/map.pgm and DIR/map.yaml.
    #[arg(long, value_name = "DIR", value_hint = ValueHint::DirPath)]
    pub export_map: Option<PathBuf>,
    /// The firmware's defmt log as text (`cargo xtask emulate`'s out/emulator/defmt.log,
    /// or `probe-rs run ... > robot.log`, followed as it grows): its lines go out on
    /// Foxglove's /log in time order with the ticks. Wants --live or --mcap.
    #[arg(long, value_name = "FILE", value_hint = ValueHint::FilePath)]
    pub log: Option<PathBuf>,
    /// Watching the stream live, and recording it for Foxglove.
    #[command(flatten)]
    pub live: LiveArgs,
}

/// `host-sim replay`.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// A recorded telemetry file with input frames (firmware with `record-inputs`, or
    /// `host-sim run --telemetry`).
    #[arg(value_name = "FILE", value_hint = ValueHint::FilePath)]
    pub file: PathBuf,
    /// The scenario the robot was built for: its grid, tags, sensors' calibration and
    /// start configure the core, and its world scores the map [default:
    /// host-sim/scenarios/seed-mat.toml, the firmware's, from the workspace root or this
    /// crate's source].
    #[arg(long, value_name = "SCENARIO.toml", value_hint = ValueHint::FilePath)]
    pub scenario: Option<PathBuf>,
    /// The localiser to replay with (default: the stream's own, from its `Hello`); truth
    /// is refused, a recording has none.
    #[arg(long, value_name = "MODE", value_parser = pose_mode())]
    pub pose: Option<PoseMode>,
    /// Score each tick's pose against this truth (as `view --truth`).
    #[arg(long, value_name = "TRUTH.jsonl", value_hint = ValueHint::FilePath)]
    pub truth: Option<PathBuf>,
    /// Print the replay and the figures as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Draw the replayed run's map and chart into DIR, with each tick's figures in
    /// STEM-ticks.jsonl, creating it.
    #[arg(long, value_name = "DIR", value_hint = ValueHint::DirPath)]
    pub out: Option<PathBuf>,
}

/// `host-sim serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// The scenario file (TOML).
    #[arg(value_name = "SCENARIO", value_hint = ValueHint::FilePath)]
    pub scenario: PathBuf,
    /// Seed of the noise (default: the scenario's `seed`).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    pub seed: Option<u64>,
}

/// `host-sim bench`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// The scenario to run (relative to the workspace root by default).
    #[arg(value_name = "SCENARIO", value_hint = ValueHint::FilePath,
          default_value = "host-sim/scenarios/seed-mat.toml")]
    pub scenario: PathBuf,
}

/// `host-sim faults`.
#[derive(Debug, Args)]
pub struct FaultsArgs {
    /// The scenario to run.
    #[arg(value_name = "SCENARIO", value_hint = ValueHint::FilePath,
          default_value = "host-sim/scenarios/seed-mat.toml")]
    pub scenario: PathBuf,
    /// Which pose the mapper uses (as `run --pose`): by default the filter without scan
    /// matching (the firmware flies `slam`, the filter with it).
    #[arg(long, value_name = "MODE", default_value = "filter", value_parser = pose_mode())]
    pub pose: PoseMode,
    /// Run seeds 1 to N.
    #[arg(long, value_name = "N", default_value_t = 20,
          value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub seeds: u64,
    /// When each fault starts, seconds into the route.
    #[arg(long, value_name = "S", default_value_t = 5.0, value_parser = fault_seconds)]
    pub start: f64,
    /// How long each fault lasts, seconds.
    #[arg(long, value_name = "S", default_value_t = 3.0, value_parser = fault_seconds)]
    pub duration: f64,
    /// Only this case, SENSOR-KIND (e.g. gyro-off).
    #[arg(long, value_name = "CASE")]
    pub case: Option<String>,
    /// Print the figures as JSON.
    #[arg(long)]
    pub json: bool,
}

/// `faults --start` and `--duration`: finite seconds within an hour.
fn fault_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && (0.0..=3600.0).contains(&s) => Ok(s),
        _ => Err("wants seconds from 0 to 3600".to_string()),
    }
}

/// `--pose`: the six names, listed in `--help` and in the error for any other.
fn pose_mode() -> impl TypedValueParser<Value = PoseMode> {
    PossibleValuesParser::new(PoseMode::ALL.map(PoseMode::name))
        .try_map(|name| name.parse::<PoseMode>())
}

/// `--seconds`: a finite, positive number of seconds below [`MAX_VIEW_SECONDS`].
fn positive_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 && s < MAX_VIEW_SECONDS => Ok(s),
        _ => Err(format!(
            "wants a positive number of seconds below {MAX_VIEW_SECONDS}"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_parsers_are_consistent() {
        Cli::command().debug_assert();
    }
}
