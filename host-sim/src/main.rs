//! `host-sim`: run a scenario and print its figures, or benchmark the simulator and the core.
//!
//! ```text
//! host-sim run <scenario.toml> [--pose truth|dead-reckoning|tags] [--seed N] [--json] [--out DIR]
//! host-sim bench [<scenario.toml>]
//! ```
//! Exit codes: 0 done, 1 the pictures could not be written, 2 bad arguments or scenario.

use host_sim::run::{run, Figures, PoseMode};
use host_sim::{picture, Scenario};
use slam_core::SeedSlam;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

const USAGE: &str = "usage:
  host-sim run <scenario.toml> [--pose truth|dead-reckoning|tags] [--seed N] [--json] [--out DIR]
  host-sim bench [<scenario.toml>]";

/// A failure and the exit code it earns.
struct Failure(u8, String);

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.first().map(String::as_str) {
        Some("run") => cmd_run(&args[1..]),
        Some("bench") => cmd_bench(&args[1..]),
        Some("-h" | "--help") => {
            println!("{USAGE}");
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
    let output = run(&scenario, args.pose, seed).map_err(|e| Failure(2, e.to_string()))?;
    if args.json {
        let json = serde_json::to_string(&output.figures).map_err(|e| Failure(1, e.to_string()))?;
        println!("{json}");
    } else {
        print_summary(&scenario.name, args.pose, seed, &output.figures);
    }
    if let Some(dir) = args.out {
        std::fs::create_dir_all(&dir)
            .map_err(|e| Failure(1, format!("cannot create {}: {e}", dir.display())))?;
        let stem = format!("{}-{}", scenario.name, args.pose.name());
        let map = dir.join(format!("{stem}-map.png"));
        let chart = dir.join(format!("{stem}-chart.png"));
        picture::map_png(&output.record, &map)
            .map_err(|e| Failure(1, format!("{}: {e}", map.display())))?;
        picture::chart_png(&output.record, &chart)
            .map_err(|e| Failure(1, format!("{}: {e}", chart.display())))?;
        if !args.json {
            println!("pictures: {} {}", map.display(), chart.display());
        }
    }
    Ok(())
}

fn print_summary(name: &str, mode: PoseMode, seed: u64, f: &Figures) {
    println!(
        "{name}: pose from {}, seed {seed}: {} ticks, {:.1} s",
        mode.name(),
        f.ticks,
        f.duration_s
    );
    println!(
        "free {}  occupied {}  out of place {}  known {:.1} %",
        f.free, f.occupied, f.out_of_place, f.known_pct
    );
    match f.first_fix_s {
        Some(t) => println!(
            "fixes taken {} (first at {t:.1} s, {} rejected); after the first fix: error <= {:.1} cm, heading <= {:.1} deg",
            f.fixes, f.fixes_rejected, f.max_error_after_first_fix_cm, f.max_heading_error_after_first_fix_deg
        ),
        None => println!("fixes taken 0"),
    }
    println!(
        "final pose error {:.1} cm, heading error {:.1} deg",
        f.final_error_cm, f.final_heading_error_deg
    );
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
    println!("host-sim bench on {} ({} runs, tags):", scenario.name, runs);
    println!("  simulated seconds per wall second: {ratio:.0} (target >= 2000)");
    println!(
        "  host ns per step: {ns_per_step:.0} ({} steps, {} fixes)",
        steps, fixes
    );
    Ok(())
}
