//! `host-sim`: run a scenario and print its figures, or benchmark the simulator and the core.
//!
//! ```text
//! host-sim run <scenario.toml> [--pose truth|dead-reckoning|tags] [--seed N] [--json] [--out DIR] [--telemetry FILE]
//! host-sim view <FILE | serial device> [--out DIR] [--baud N] [--seconds N] [--json] [--truth FILE] [--scenario FILE]
//! host-sim bench [<scenario.toml>]
//! ```
//! `run --telemetry FILE` also writes the telemetry stream the robot would send on that
//! run; `view` decodes such a stream, from a file or live from the robot's serial port
//! (until end of file, Ctrl-C or `--seconds`), prints what it held and draws the same two
//! pictures. `view --truth FILE` (a line of JSON per step, as the emulator's harness writes
//! it: see `host_sim::truth`) scores each tick's pose against the truth, and
//! `--scenario FILE` the map against that scenario's world, giving `run`'s figures under
//! `run`'s names.
//!
//! Exit codes: 0 done, 1 the pictures or the stream could not be written, 2 bad
//! arguments, scenario or stream.

use host_sim::run::{run, run_with_telemetry, Figures, PoseMode};
use host_sim::telemetry::{Recording, TelemetryWriter};
use host_sim::truth::{parse_truth, TruthSample};
use host_sim::{picture, RunRecord, Scenario};
use slam_core::SeedSlam;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

const USAGE: &str = "usage:
  host-sim run <scenario.toml> [--pose truth|dead-reckoning|tags] [--seed N] [--json] [--out DIR] [--telemetry FILE]
  host-sim view <FILE | serial device> [--out DIR] [--baud N] [--seconds N] [--json]
                [--truth TRUTH.jsonl] [--scenario SCENARIO.toml]
  host-sim serve <scenario.toml> [--seed N]     (JSON lines on stdin/stdout, for the emulator)
  host-sim bench [<scenario.toml>]";

/// `println!` that does not panic when stdout is gone (a closed pipe): output is best effort,
/// the exit code still tells.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

/// A failure and the exit code it earns.
struct Failure(u8, String);

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("run") => cmd_run(&args[1..]),
        Some("view") => cmd_view(&args[1..]),
        Some("serve") => cmd_serve(&args[1..]),
        Some("bench") => cmd_bench(&args[1..]),
        Some("-h" | "--help") => {
            say!("{USAGE}");
            Ok(())
        }
        _ => Err(Failure(2, USAGE.to_string())),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure(code, message)) => {
            eprintln!("host-sim: {message}");
            ExitCode::from(code)
        }
    }
}

struct RunArgs {
    scenario: PathBuf,
    pose: PoseMode,
    seed: Option<u64>,
    json: bool,
    out: Option<PathBuf>,
    telemetry: Option<PathBuf>,
}

fn parse_run_args(args: &[String]) -> Result<RunArgs, Failure> {
    let bad = |m: String| Failure(2, format!("{m}\n{USAGE}"));
    let mut it = args.iter();
    let mut parsed = RunArgs {
        scenario: PathBuf::new(),
        pose: PoseMode::Tags,
        seed: None,
        json: false,
        out: None,
        telemetry: None,
    };
    let mut scenario = None;
    while let Some(arg) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| bad(format!("{name} needs a value")))
        };
        match arg.as_str() {
            "--pose" => parsed.pose = value("--pose")?.parse().map_err(bad)?,
            "--seed" => {
                let v = value("--seed")?;
                parsed.seed = Some(
                    v.parse()
                        .map_err(|_| bad(format!("--seed wants a whole number, got `{v}`")))?,
                );
            }
            "--json" => parsed.json = true,
            "--out" => parsed.out = Some(PathBuf::from(value("--out")?)),
            "--telemetry" => parsed.telemetry = Some(PathBuf::from(value("--telemetry")?)),
            flag if flag.starts_with("--") => return Err(bad(format!("unknown option `{flag}`"))),
            path if scenario.is_none() => scenario = Some(PathBuf::from(path)),
            extra => return Err(bad(format!("unexpected argument `{extra}`"))),
        }
    }
    parsed.scenario = scenario.ok_or_else(|| bad("which scenario? give a scenario file".into()))?;
    Ok(parsed)
}

fn load(path: &Path) -> Result<Scenario, Failure> {
    Scenario::load(path).map_err(|e| Failure(2, format!("{}: {e}", path.display())))
}

fn cmd_run(args: &[String]) -> Result<(), Failure> {
    let args = parse_run_args(args)?;
    let scenario = load(&args.scenario)?;
    let seed = args.seed.unwrap_or(scenario.seed);
    let mut writer = args.telemetry.as_ref().map(|_| TelemetryWriter::new());
    let output = run_with_telemetry(&scenario, args.pose, seed, writer.as_mut())
        .map_err(|e| Failure(2, e.to_string()))?;
    if let (Some(path), Some(writer)) = (&args.telemetry, &writer) {
        std::fs::write(path, writer.bytes())
            .map_err(|e| Failure(1, format!("cannot write {}: {e}", path.display())))?;
    }
    if args.json {
        let json = serde_json::to_string(&output.figures).map_err(|e| Failure(1, e.to_string()))?;
        say!("{json}");
    } else {
        print_summary(&scenario.name, args.pose, seed, &output.figures);
    }
    if let Some(dir) = args.out {
        std::fs::create_dir_all(&dir)
            .map_err(|e| Failure(1, format!("cannot create {}: {e}", dir.display())))?;
        let stem = format!("{}-{}", scenario.name, args.pose.name());
        let (map, chart) = write_pictures(&output.record, &dir, &stem)?;
        if !args.json {
            say!("pictures: {} {}", map.display(), chart.display());
        }
    }
    Ok(())
}

/// Writes `DIR/STEM-map.png` and `DIR/STEM-chart.png`, creating `dir`.
fn write_pictures(
    record: &RunRecord,
    dir: &Path,
    stem: &str,
) -> Result<(PathBuf, PathBuf), Failure> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Failure(1, format!("cannot create {}: {e}", dir.display())))?;
    let map = dir.join(format!("{stem}-map.png"));
    let chart = dir.join(format!("{stem}-chart.png"));
    picture::map_png(record, &map).map_err(|e| Failure(1, format!("{}: {e}", map.display())))?;
    picture::chart_png(record, &chart)
        .map_err(|e| Failure(1, format!("{}: {e}", chart.display())))?;
    Ok((map, chart))
}

struct ViewArgs {
    source: PathBuf,
    out: Option<PathBuf>,
    baud: u32,
    seconds: Option<f64>,
    json: bool,
    truth: Option<PathBuf>,
    scenario: Option<PathBuf>,
}

fn parse_view_args(args: &[String]) -> Result<ViewArgs, Failure> {
    let bad = |m: String| Failure(2, format!("{m}\n{USAGE}"));
    let mut it = args.iter();
    let mut parsed = ViewArgs {
        source: PathBuf::new(),
        out: None,
        baud: 115_200,
        seconds: None,
        json: false,
        truth: None,
        scenario: None,
    };
    let mut source = None;
    while let Some(arg) = it.next() {
        let mut value = |name: &str| {
            it.next()
                .cloned()
                .ok_or_else(|| bad(format!("{name} needs a value")))
        };
        match arg.as_str() {
            "--out" => parsed.out = Some(PathBuf::from(value("--out")?)),
            "--baud" => {
                let v = value("--baud")?;
                parsed.baud = v.parse().ok().filter(|&b| b > 0).ok_or_else(|| {
                    bad(format!("--baud wants a positive whole number, got `{v}`"))
                })?;
            }
            "--seconds" => {
                let v = value("--seconds")?;
                parsed.seconds = Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|s| s.is_finite() && *s > 0.0 && *s < 1e9)
                        .ok_or_else(|| {
                            bad(format!("--seconds wants a positive number, got `{v}`"))
                        })?,
                );
            }
            "--json" => parsed.json = true,
            "--truth" => parsed.truth = Some(PathBuf::from(value("--truth")?)),
            "--scenario" => parsed.scenario = Some(PathBuf::from(value("--scenario")?)),
            flag if flag.starts_with("--") => return Err(bad(format!("unknown option `{flag}`"))),
            path if source.is_none() => source = Some(PathBuf::from(path)),
            extra => return Err(bad(format!("unexpected argument `{extra}`"))),
        }
    }
    parsed.source = source
        .ok_or_else(|| bad("which stream? give a telemetry file or a serial device".into()))?;
    Ok(parsed)
}

/// Whether `path` names a serial device rather than a recorded file.
fn is_serial_device(path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if let Ok(meta) = std::fs::metadata(path) {
            return meta.file_type().is_char_device();
        }
    }
    let name = path.to_string_lossy();
    name.starts_with("/dev/") || name.to_ascii_uppercase().starts_with("COM")
}

/// Decodes a telemetry stream, prints what it held and draws its pictures.
fn cmd_view(args: &[String]) -> Result<(), Failure> {
    let args = parse_view_args(args)?;
    let shown = args.source.display().to_string();
    let stop = Arc::new(AtomicBool::new(false));
    let deadline = args
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s));
    let mut recording = Recording::new();
    if let Some(path) = &args.truth {
        recording.recorder = recording.recorder.with_truth(load_truth(path)?);
    }
    if let Some(path) = &args.scenario {
        let world = host_sim::world::World::new(&load(path)?);
        recording.recorder = recording.recorder.with_world(world);
    }
    let serial = is_serial_device(&args.source);
    let read = if serial {
        // Ctrl-C ends a live view; the pictures are still drawn. If a handler cannot be
        // set, Ctrl-C simply ends the process as usual.
        let flag = Arc::clone(&stop);
        let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
        let mut port = serialport::new(shown.as_str(), args.baud)
            .timeout(Duration::from_millis(200))
            .open()
            .map_err(|e| Failure(2, format!("cannot open serial port {shown}: {e}")))?;
        if !args.json {
            eprintln!(
                "host-sim: reading {shown} at {} baud; Ctrl-C to stop",
                args.baud
            );
        }
        recording.read_from(&mut port, &stop, deadline)
    } else {
        let mut file = std::fs::File::open(&args.source)
            .map_err(|e| Failure(2, format!("cannot read {shown}: {e}")))?;
        recording.read_from(&mut file, &stop, deadline)
    };
    if let Err(e) = read {
        // What came before the error is kept: a robot unplugged mid-run still has a run.
        eprintln!("host-sim: reading {shown} stopped: {e}");
    }
    let summary = recording.summary();
    if summary.frames_ok == 0 {
        return Err(Failure(
            2,
            format!(
                "{shown}: no telemetry frames in it ({} bad frames): is it a BugBot telemetry stream?",
                summary.bad_frames.total()
            ),
        ));
    }
    if args.json {
        let json = serde_json::to_string(&summary).map_err(|e| Failure(1, e.to_string()))?;
        say!("{json}");
    } else {
        say!("{summary}");
        if recording.decoder.has_partial_frame() {
            say!("the stream ends inside a frame (cut short)");
        }
    }
    if let Some(dir) = &args.out {
        let stem = if serial {
            "robot".to_string()
        } else {
            args.source
                .file_stem()
                .map_or("telemetry".to_string(), |s| {
                    s.to_string_lossy().into_owned()
                })
        };
        let record = recording.recorder.record(&stem);
        let (map, chart) = write_pictures(&record, dir, &stem)?;
        if !args.json {
            say!("pictures: {} {}", map.display(), chart.display());
        }
    }
    Ok(())
}

/// Reads a truth file (see `host_sim::truth`); a bad line is named.
fn load_truth(path: &Path) -> Result<Vec<TruthSample>, Failure> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Failure(2, format!("cannot read truth file {}: {e}", path.display())))?;
    parse_truth(&text).map_err(|e| Failure(2, format!("truth file {}: {e}", path.display())))
}

fn print_summary(name: &str, mode: PoseMode, seed: u64, f: &Figures) {
    say!(
        "{name}: pose from {}, seed {seed}: {} ticks, {:.1} s",
        mode.name(),
        f.ticks,
        f.duration_s
    );
    say!(
        "free {}  occupied {}  out of place {}  known {:.1} %",
        f.free,
        f.occupied,
        f.out_of_place,
        f.known_pct
    );
    match f.first_fix_s {
        Some(t) => say!(
            "fixes taken {} (first at {t:.1} s, {} rejected); after the first fix: error <= {:.1} cm, heading <= {:.1} deg",
            f.fixes, f.fixes_rejected, f.max_error_after_first_fix_cm, f.max_heading_error_after_first_fix_deg
        ),
        None => say!("fixes taken 0"),
    }
    say!(
        "final pose error {:.1} cm, heading error {:.1} deg",
        f.final_error_cm,
        f.final_heading_error_deg
    );
}

/// The simulator as the emulated robot's world: see `host_sim::serve`.
fn cmd_serve(args: &[String]) -> Result<(), Failure> {
    let bad = |m: String| Failure(2, format!("{m}\n{USAGE}"));
    let (path, seed) = match args {
        [path] => (path, None),
        [path, flag, n] if flag == "--seed" => (
            path,
            Some(
                n.parse::<u64>()
                    .map_err(|_| bad(format!("--seed wants a whole number, got `{n}`")))?,
            ),
        ),
        _ => return Err(bad("serve takes a scenario and an optional --seed N".into())),
    };
    let scenario = load(Path::new(path))?;
    let stdin = std::io::stdin().lock();
    let stdout = std::io::stdout().lock();
    host_sim::serve::serve(&scenario, seed.unwrap_or(scenario.seed), stdin, stdout)
        .map_err(|e| Failure(1, format!("serve: {e}")))
}

/// Simulated seconds per wall second on the seed route, and host nanoseconds per `step`.
fn cmd_bench(args: &[String]) -> Result<(), Failure> {
    let path = args.first().map_or_else(
        || PathBuf::from("host-sim/scenarios/seed-mat.toml"),
        PathBuf::from,
    );
    let scenario = load(&path)?;
    let runs = 20;
    let started = Instant::now();
    let mut simulated_s = 0.0;
    let mut frames = Vec::new();
    for i in 0..runs {
        let output = run(&scenario, PoseMode::Tags, scenario.seed + i)
            .map_err(|e| Failure(2, e.to_string()))?;
        simulated_s += output.figures.duration_s;
        frames = output.frames;
    }
    let wall_s = started.elapsed().as_secs_f64();
    let ratio = simulated_s / wall_s;

    let config = host_sim::run::slam_config(&scenario);
    let start = host_sim::run::to_core_pose(&host_sim::robot::TruePose {
        x_mm: scenario.start.x_mm,
        y_mm: scenario.start.y_mm,
        heading_deg: scenario.start.heading_deg,
    });
    let replays = 200;
    let mut slam =
        Box::new(SeedSlam::new(config, start).map_err(|e| Failure(2, format!("{e:?}")))?);
    let started = Instant::now();
    let mut fixes = 0;
    for _ in 0..replays {
        slam.reset(start);
        for frame in &frames {
            fixes += u32::from(
                slam.step(std::hint::black_box(frame)).fix == slam_core::FixOutcome::Taken,
            );
        }
    }
    let steps = (replays * frames.len()) as f64;
    let ns_per_step = started.elapsed().as_secs_f64() * 1e9 / steps.max(1.0);
    say!("host-sim bench on {} ({} runs, tags):", scenario.name, runs);
    say!("  simulated seconds per wall second: {ratio:.0} (target >= 2000)");
    say!(
        "  host ns per step: {ns_per_step:.0} ({} steps, {} fixes)",
        steps,
        fixes
    );
    Ok(())
}
