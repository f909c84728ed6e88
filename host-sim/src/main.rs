//! `host-sim`: run a scenario and print its figures, watch a robot's telemetry, serve the
//! emulator, or benchmark the simulator and the core. `host-sim --help` and
//! `host-sim SUBCOMMAND --help` list the options (see `cli.rs`).
//!
//! `run --telemetry FILE` also writes the telemetry stream the robot would send on that
//! run; `view` decodes such a stream, from a file or live from the robot's serial port
//! (until end of file, Ctrl-C or `--seconds`), prints what it held and draws the same two
//! pictures. `view --truth FILE` (a line of JSON per step, as the emulator's harness writes
//! it: see `host_sim::truth`) scores each tick's pose against the truth, and
//! `--scenario FILE` the map against that scenario's world, giving `run`'s figures under
//! `run`'s names.
//!
//! `replay FILE` steps a recorded stream's input frames through the core again (see
//! `host_sim::replay`): with the robot's own settings it checks the replay against what the
//! robot sent, bit for bit; with `--pose` it shows what another localiser would have done.
//!
//! `--live` (on `run` and `view`) plays the run at its pace and serves it to the Foxglove
//! app on a WebSocket, `--mcap FILE` records the same channels (see `host_sim::live`).
//!
//! Exit codes: 0 done, 1 the pictures, the stream or the MCAP file could not be written
//! or a live server could not listen (its port in use), 2 bad arguments, scenario or
//! stream, 3 a replay with the robot's settings that differs from the robot's run.

mod cli;

use clap::Parser;
use cli::{
    BenchArgs, Cli, Command, FaultsArgs, LiveArgs, ReplayArgs, RunArgs, ServeArgs, ViewArgs,
};
use host_sim::fault_matrix::{run_matrix, table, Window};
use host_sim::live::foxglove::{FoxgloveSink, Outputs};
use host_sim::live::log::FirmwareLog;
use host_sim::live::pace::Pace;
use host_sim::live::scene::Stage;
use host_sim::live::{Feed, LiveSink};
use host_sim::page::PageServer;
use host_sim::record::{TrueCalibration, WorldOutline};
use host_sim::run::GRID_SIDES;
use host_sim::run::{run, run_with, Figures, Guarding, PoseMode, RunOptions, TICK_S};
use host_sim::telemetry::estimator_line;
use host_sim::telemetry::{Recording, TelemetryWriter};
use host_sim::truth::{parse_truth, TruthSample};
use host_sim::{bounded, picture, RunRecord, Scenario};
use slam_core::Slam;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            // `--help` and `--version` land here too, with exit code 0 and stdout.
            let _ = e.print();
            return ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2));
        }
    };
    let result = match cli.command {
        Command::Run(args) => cmd_run(args),
        Command::View(args) => cmd_view(args),
        Command::Replay(args) => cmd_replay(args),
        Command::Serve(args) => cmd_serve(args),
        Command::Bench(args) => cmd_bench(args),
        Command::Faults(args) => cmd_faults(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure(code, message)) => {
            eprintln!("host-sim: {message}");
            ExitCode::from(code)
        }
    }
}

fn load(path: &Path) -> Result<Scenario, Failure> {
    Scenario::load(path).map_err(|e| Failure(2, format!("{}: {e}", path.display())))
}

fn cmd_run(args: RunArgs) -> Result<(), Failure> {
    let scenario = load(&args.scenario)?;
    let seed = args.seed.unwrap_or(scenario.seed);
    // A live session plays the run's telemetry stream, so it needs one too.
    let mut writer =
        (args.telemetry.is_some() || args.live.wanted()).then(|| TelemetryWriter::new(args.pose));
    // The servers listen before the run, so a port in use is said at once.
    let mut session = if args.live.wanted() {
        let world = WorldOutline::of(&host_sim::world::World::new(&scenario));
        Some(LiveSession::start(
            &args.live,
            Stage::of(&scenario),
            Some(&world),
        )?)
    } else {
        None
    };
    let guarding = if args.no_guard {
        Guarding::Off
    } else {
        Guarding::On
    };
    let options = RunOptions {
        guarding,
        telemetry: writer.as_mut(),
        faults: &args.fault,
        ..RunOptions::default()
    };
    let output = run_with(&scenario, args.pose, seed, options)
        .map_err(|e| Failure(2, format!("{}: {e}", args.scenario.display())))?;
    if let (Some(path), Some(writer)) = (&args.telemetry, &writer) {
        std::fs::write(path, writer.bytes())
            .map_err(|e| Failure(1, format!("cannot write {}: {e}", path.display())))?;
    }
    if let (Some(session), Some(writer)) = (session.as_mut(), &writer) {
        let truth = output.record.truth_samples();
        let stop = stop_on_ctrl_c();
        let pace = args.live.live.then(|| Pace::new(args.live.speed));
        let mut recording = Recording::new();
        let mut feed = session.feed(pace, Some(&truth), None);
        // Reading from memory cannot fail.
        let _ = host_sim::live::play(&mut recording, &mut writer.bytes(), &stop, None, &mut feed);
        feed.finish().map_err(|e| Failure(1, e.to_string()))?;
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
    if let Some(dir) = &args.export_map {
        export_map(&output.record, dir, args.json)?;
    }
    Ok(())
}

/// Writes the final map of `record` as `DIR/map.pgm` and `DIR/map.yaml`.
fn export_map(record: &RunRecord, dir: &Path, quiet: bool) -> Result<(), Failure> {
    let yaml = host_sim::rosmap::write(&record.map, dir).map_err(|e| Failure(1, e.to_string()))?;
    if !quiet {
        say!("ROS map: {}", yaml.display());
    }
    Ok(())
}

/// Writes `DIR/STEM-map.png`, `DIR/STEM-chart.png` and `DIR/STEM-ticks.jsonl` (a line of
/// JSON per tick: the chart's figures, for a script to read), creating `dir`.
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
    let ticks = dir.join(format!("{stem}-ticks.jsonl"));
    write_ticks(record, &ticks).map_err(|e| Failure(1, format!("{}: {e}", ticks.display())))?;
    Ok((map, chart))
}

/// Writes each of `record`'s ticks as one line of JSON.
fn write_ticks(record: &RunRecord, path: &Path) -> std::io::Result<()> {
    use std::io::Write;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    for tick in &record.ticks {
        serde_json::to_writer(&mut out, tick)?;
        out.write_all(b"\n")?;
    }
    out.flush()
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

/// A live session's sinks: the Foxglove channels (served, recorded or both) and the page.
struct LiveSession {
    foxglove: FoxgloveSink,
    /// The zero-install page, with `--live`.
    page: Option<PageServer>,
}

impl LiveSession {
    /// Starts what `live` asks for and says on stderr where it listens, a line per server
    /// (`... on ws://127.0.0.1:PORT`, which tests parse for `--foxglove-port 0`). The
    /// page draws `world`'s walls and tags when the world is known.
    fn start(
        live: &LiveArgs,
        stage: Stage,
        world: Option<&WorldOutline>,
    ) -> Result<LiveSession, Failure> {
        let outputs = Outputs {
            websocket_port: live.live.then_some(live.foxglove_port),
            mcap: live.mcap.clone(),
        };
        let foxglove = FoxgloveSink::new(stage, &outputs).map_err(|e| Failure(1, e.to_string()))?;
        if let Some(port) = foxglove.websocket_port() {
            eprintln!(
                "host-sim: Foxglove WebSocket on ws://127.0.0.1:{port} (in the Foxglove app: Open connection, Foxglove WebSocket)"
            );
        }
        let page = if live.live {
            let mut page = PageServer::bind(SocketAddr::from(([127, 0, 0, 1], live.port)))
                .map_err(|e| Failure(1, e.to_string()))?;
            if let Some(world) = world {
                page.world(world);
            }
            eprintln!("host-sim: live page on {}", page.url());
            Some(page)
        } else {
            None
        };
        Ok(LiveSession { foxglove, page })
    }

    /// The feed that plays into every sink, with the firmware's log when given.
    fn feed<'a>(
        &'a mut self,
        pace: Option<Pace>,
        truth: Option<&'a [TruthSample]>,
        log: Option<&'a mut FirmwareLog>,
    ) -> Feed<'a> {
        let mut sinks: Vec<&mut dyn LiveSink> = vec![&mut self.foxglove];
        if let Some(page) = &mut self.page {
            sinks.push(page);
        }
        Feed {
            sinks,
            pace,
            truth,
            log,
        }
    }
}

/// A flag that Ctrl-C sets: a live session or a serial port then stops, and the summary
/// and pictures still come. If a handler cannot be set, Ctrl-C ends the process as usual.
fn stop_on_ctrl_c() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    stop
}

/// Says on stderr how much of the firmware's log went out, when some of it did not.
fn report_firmware_log(log: &FirmwareLog, path: &Path) {
    if log.skipped() > 0 {
        eprintln!(
            "host-sim: {}: {} lines skipped (not `TIME [LEVEL] message`, or longer than {} bytes); {} published on /log",
            path.display(),
            log.skipped(),
            host_sim::live::log::MAX_LINE_BYTES,
            log.published()
        );
    }
    if log.truncated() {
        eprintln!(
            "host-sim: {}: read no further than {} bytes",
            path.display(),
            host_sim::live::log::MAX_LOG_BYTES
        );
    }
}

/// Decodes a telemetry stream, prints what it held and draws its pictures.
fn cmd_view(args: ViewArgs) -> Result<(), Failure> {
    let shown = args.source.display().to_string();
    let serial = is_serial_device(&args.source);
    let stop = if serial || args.live.live {
        stop_on_ctrl_c()
    } else {
        Arc::new(AtomicBool::new(false))
    };
    let deadline = args
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s));
    let mut recording = Recording::new();
    let truth = match &args.truth {
        Some(path) => Some(load_truth(path)?),
        None => None,
    };
    if let Some(truth) = &truth {
        recording.recorder = recording.recorder.with_truth(truth.clone());
    }
    let mut stage = Stage::firmware();
    let mut outline = None;
    if let Some(path) = &args.scenario {
        let scenario = load(path)?;
        let world = host_sim::world::World::new(&scenario);
        outline = Some(WorldOutline::of(&world));
        recording.recorder = recording
            .recorder
            .with_world(world)
            .with_true_calibration(TrueCalibration::of(&scenario));
        stage = Stage::of(&scenario);
    }
    let mut firmware_log = match &args.log {
        Some(_) if !args.live.wanted() => {
            return Err(Failure(
                2,
                "--log goes out on Foxglove's /log: it wants --live or --mcap".to_string(),
            ))
        }
        Some(path) => Some(
            FirmwareLog::open(path)
                .map_err(|e| Failure(2, format!("cannot read {}: {e}", path.display())))?,
        ),
        None => None,
    };
    let mut session = if args.live.wanted() {
        Some(LiveSession::start(&args.live, stage, outline.as_ref())?)
    } else {
        None
    };
    // A file plays at its recorded pace when watched; a port comes at its own.
    let pace = (args.live.live && !serial).then(|| Pace::new(args.live.speed));
    let mut feed = session
        .as_mut()
        .map(|s| s.feed(pace, truth.as_deref(), firmware_log.as_mut()));
    let mut read_from = |recording: &mut Recording, source: &mut dyn std::io::Read| match &mut feed
    {
        Some(feed) => host_sim::live::play(recording, source, &stop, deadline, feed),
        None => recording.read_from(source, &stop, deadline),
    };
    let read = if serial {
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
        read_from(&mut recording, &mut port)
    } else {
        let mut file = std::fs::File::open(&args.source)
            .map_err(|e| Failure(2, format!("cannot read {shown}: {e}")))?;
        read_from(&mut recording, &mut file)
    };
    if let Err(e) = read {
        // What came before the error is kept: a robot unplugged mid-run still has a run.
        eprintln!("host-sim: reading {shown} stopped: {e}");
    }
    if let Some(feed) = &mut feed {
        feed.finish().map_err(|e| Failure(1, e.to_string()))?;
    }
    drop(feed);
    if let (Some(log), Some(path)) = (&firmware_log, &args.log) {
        report_firmware_log(log, path);
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
    if let Some(dir) = &args.export_map {
        export_map(&recording.recorder.record("robot"), dir, args.json)?;
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

/// The scenario the firmware is built for: from the workspace root when run there, else
/// from this crate's source tree.
fn firmware_scenario() -> PathBuf {
    let relative = Path::new("host-sim/scenarios/seed-mat.toml");
    if relative.is_file() {
        relative.to_path_buf()
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios/seed-mat.toml")
    }
}

/// Replays a recorded stream's inputs, compares, prints and draws as `view` does.
fn cmd_replay(args: ReplayArgs) -> Result<(), Failure> {
    let shown = args.file.display().to_string();
    let scenario = load(&args.scenario.unwrap_or_else(firmware_scenario))?;
    let bytes = read_recording("stream", &args.file)?;
    let replayed = host_sim::replay::replay(&scenario, &bytes, args.pose)
        .map_err(|e| Failure(2, format!("{shown}: {e}")))?;
    let mut recording = Recording::new();
    if let Some(path) = &args.truth {
        recording.recorder = recording.recorder.with_truth(load_truth(path)?);
    }
    recording.recorder = recording
        .recorder
        .with_world(host_sim::world::World::new(&scenario))
        .with_true_calibration(TrueCalibration::of(&scenario));
    recording.feed(&replayed.stream);
    let summary = recording.summary();
    let r = &replayed.summary;
    if args.json {
        #[derive(serde::Serialize)]
        struct Out<'a> {
            replay: &'a host_sim::replay::ReplaySummary,
            view: &'a host_sim::telemetry::Summary,
        }
        let json = serde_json::to_string(&Out {
            replay: r,
            view: &summary,
        })
        .map_err(|e| Failure(1, e.to_string()))?;
        say!("{json}");
    } else {
        say!("{r}");
        say!("{summary}");
    }
    if let Some(dir) = &args.out {
        let stem = format!(
            "{}-replay-{}",
            args.file.file_stem().map_or("telemetry".to_string(), |s| s
                .to_string_lossy()
                .into_owned()),
            r.pose
        );
        let record = recording.recorder.record(&stem);
        let (map, chart) = write_pictures(&record, dir, &stem)?;
        if !args.json {
            say!("pictures: {} {}", map.display(), chart.display());
        }
    }
    match &r.bit_for_bit {
        Some(b) if !b.identical() => Err(Failure(
            3,
            format!("{shown}: the replay with the robot's settings is not the robot's run"),
        )),
        _ => Ok(()),
    }
}

/// Reads a truth file (see `host_sim::truth`); a bad line is named.
fn load_truth(path: &Path) -> Result<Vec<TruthSample>, Failure> {
    let bytes = read_recording("truth file", path)?;
    let text = String::from_utf8(bytes)
        .map_err(|e| Failure(2, format!("truth file {}: not UTF-8: {e}", path.display())))?;
    parse_truth(&text).map_err(|e| Failure(2, format!("truth file {}: {e}", path.display())))
}

/// A recorded stream or truth file (`what`), whole, if it is no longer than
/// [`bounded::MAX_RECORDING_BYTES`].
fn read_recording(what: &str, path: &Path) -> Result<Vec<u8>, Failure> {
    let max = bounded::MAX_RECORDING_BYTES;
    bounded::read(path, max)
        .map_err(|e| Failure(2, format!("cannot read {what} {}: {e}", path.display())))?
        .ok_or_else(|| {
            Failure(
                2,
                format!(
                    "{what} {}: longer than {} MiB, more than this tool reads",
                    path.display(),
                    max >> 20
                ),
            )
        })
}

fn print_summary(name: &str, mode: PoseMode, seed: u64, f: &Figures) {
    say!(
        "{name}: pose from {}, seed {seed}: {} ticks, {:.1} s",
        mode.name(),
        f.ticks,
        f.duration_s
    );
    say!(
        "free {}  occupied {}  out of place {}  known {:.1} % of the floor ({:.1} % of the grid)",
        f.free,
        f.occupied,
        f.out_of_place,
        f.known_pct,
        f.known_grid_pct
    );
    say!("collisions {}  guard stops {}", f.collisions, f.guard_stops);
    match f.first_fix_s {
        Some(t) => say!(
            "fixes taken {} (first at {t:.1} s, {} rejected); after the first fix: error <= {:.1} cm, heading <= {:.1} deg",
            f.fixes, f.fixes_rejected, f.errors.max_error_after_first_fix_cm, f.errors.max_heading_error_after_first_fix_deg
        ),
        None => say!("fixes taken 0"),
    }
    say!(
        "final pose error {:.1} cm, heading error {:.1} deg",
        f.errors.final_error_cm,
        f.errors.final_heading_error_deg
    );
    if let Some(e) = &f.estimator {
        say!("{}", estimator_line(e));
    }
    if let Some(t) = f.route_cut_at_s {
        say!(
            "the route was cut at {t:.1} s, before its end: a run lasts at most {} s",
            host_sim::run::MAX_RUN_S
        );
    }
}

/// The simulator as the emulated robot's world: see `host_sim::serve`.
fn cmd_serve(args: ServeArgs) -> Result<(), Failure> {
    let scenario = load(&args.scenario)?;
    let stdin = std::io::stdin().lock();
    let stdout = std::io::stdout().lock();
    host_sim::serve::serve(&scenario, args.seed.unwrap_or(scenario.seed), stdin, stdout)
        .map_err(|e| Failure(1, format!("serve: {e}")))
}

/// Simulated seconds per wall second on the seed route, and host nanoseconds per `step`.
fn cmd_faults(args: FaultsArgs) -> Result<(), Failure> {
    let scenario = load(&args.scenario)?;
    let seeds: Vec<u64> = (1..=args.seeds).collect();
    let window = Window {
        start_s: args.start,
        duration_s: args.duration.max(TICK_S),
    };
    let cases = run_matrix(&scenario, args.pose, &seeds, window, args.case.as_deref())
        .map_err(|e| Failure(2, format!("{}: {e}", args.scenario.display())))?;
    if cases.is_empty() {
        return Err(Failure(
            2,
            "no such case: want SENSOR-KIND, e.g. gyro-off (sensors depth, flow, gyro, camera; kinds off, stuck, garbage, wrong, slow, intermittent)".into(),
        ));
    }
    if args.json {
        let json = serde_json::to_string(&cases).map_err(|e| Failure(1, e.to_string()))?;
        say!("{json}");
    } else {
        say!(
            "{}, pose {}, seeds 1-{}, each fault from {} s for {} s:",
            scenario.name,
            args.pose.name(),
            args.seeds,
            window.start_s,
            window.duration_s
        );
        say!("{}", table(&cases));
        let met = cases.iter().filter(|c| c.meets_targets()).count();
        say!("{met} of {} cases meet the targets", cases.len());
    }
    Ok(())
}

fn cmd_bench(args: BenchArgs) -> Result<(), Failure> {
    let scenario = load(&args.scenario)?;
    let runs = 20;
    let started = Instant::now();
    let mut simulated_s = 0.0;
    let mut frames = Vec::new();
    for i in 0..runs {
        let output = run(&scenario, PoseMode::Tags, scenario.seed + i)
            .map_err(|e| Failure(2, format!("{}: {e}", args.scenario.display())))?;
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
    // The smallest grid built in: the bench's figures are the seed's.
    let mut slam = Box::new(
        Slam::<{ GRID_SIDES[0] }, { GRID_SIDES[0] }>::new(config, start).map_err(|e| {
            let e = host_sim::run::RunError::Config(e);
            Failure(2, format!("{}: {e}", args.scenario.display()))
        })?,
    );
    let started = Instant::now();
    let mut fixes = 0;
    for _ in 0..replays {
        slam.reset(start);
        let mut walls = slam_core::wall_rate::WallRate::default();
        let mut turn = slam_core::wall_turn::WallTurn::default();
        let mut first_turn = Box::new(slam_core::slam::first_turn::FirstTurn::new());
        for frame in &frames {
            let report = slam.step(std::hint::black_box(frame));
            let report = slam.measure_walls(&mut walls, &mut turn, frame, report);
            let report = slam.close_first_turn(&mut first_turn, frame, report);
            fixes += u32::from(report.fix == slam_core::FixOutcome::Taken);
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
