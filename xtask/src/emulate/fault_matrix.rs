//! `cargo xtask emulate-faults`: every sensor failing every way on the emulated robot.
//!
//! Each case flies the seed route with one fault (the device model fails from 5 s for
//! 3 s, as `host-sim faults` does it) and stops 2 s after the sensor returns; a run with no
//! fault is the baseline. Per case: whether the firmware kept running (no HardFault, 0
//! overruns), the black cells out of place the fault added, and the position error 2 s
//! after the sensor returned beside the baseline's.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use serde_json::Value;

/// The sensors, as `--fault` and host-sim name them.
pub const SENSORS: [&str; 4] = ["depth", "flow", "gyro", "camera"];
/// The ways each fails.
pub const KINDS: [&str; 6] = ["off", "stuck", "garbage", "wrong", "slow", "intermittent"];
/// The fault's start and length, seconds; the run ends 2 s after it.
const FAULT: &str = "@T+5/3";
const SECONDS: &str = "10";
/// The bound on the error the fault may add 2 s after the sensor returns, cm.
const ADDED_ERROR_CM: f64 = 1.0;

/// `cargo xtask emulate-faults`'s options.
#[derive(clap::Args, Debug)]
pub struct FaultMatrixArgs {
    /// The world's noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Emulator runs at once.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=8))]
    jobs: u32,
    /// Only these cases (`SENSOR-KIND`, repeatable); all 24 without it.
    #[arg(long = "case", value_name = "SENSOR-KIND", value_parser = case_name)]
    cases: Vec<String>,
}

/// A case named as `--fault` names it.
fn case_name(text: &str) -> Result<String, String> {
    let known = SENSORS
        .iter()
        .any(|s| KINDS.iter().any(|k| text == format!("{s}-{k}")));
    if known {
        Ok(text.to_string())
    } else {
        Err(format!(
            "want SENSOR-KIND, SENSOR one of {} and KIND one of {}",
            SENSORS.join(", "),
            KINDS.join(", ")
        ))
    }
}

/// What one run showed.
#[derive(Debug)]
struct Outcome {
    stop_reason: String,
    overruns: f64,
    out_of_place: f64,
    error_cm: f64,
}

impl Outcome {
    fn of(figures: &Value) -> Outcome {
        let (e, v) = (&figures["emulator"], &figures["view"]);
        let num = |x: &Value| x.as_f64().unwrap_or(f64::NAN);
        let error_mm = (num(&e["truth"]["x_mm"]) - num(&v["final_pose"]["x_um"]) / 1000.0)
            .hypot(num(&e["truth"]["y_mm"]) - num(&v["final_pose"]["y_um"]) / 1000.0);
        Outcome {
            stop_reason: e["stop_reason"].as_str().unwrap_or("?").to_string(),
            overruns: num(&e["overruns"]),
            out_of_place: num(&v["out_of_place"]),
            error_cm: error_mm / 10.0,
        }
    }

    fn kept_running(&self) -> bool {
        self.stop_reason == "time" && self.overruns == 0.0
    }
}

/// One emulator run of the seed route with `faults` (none for the baseline).
fn fly(label: &str, seed: &str, faults: &[String]) -> Result<Outcome, String> {
    let mut args = vec![
        "--seconds",
        SECONDS,
        "--seed",
        seed,
        "--pose",
        label,
        "--no-usb",
    ];
    for f in faults {
        args.extend(["--fault", f.as_str()]);
    }
    crate::emulator_figures(&args).map(|f| Outcome::of(&f))
}

/// Runs the matrix and prints one row a case; fails if any run stopped early or overran.
pub fn run(args: &FaultMatrixArgs) -> Result<(), String> {
    let cases: Vec<String> = if args.cases.is_empty() {
        SENSORS
            .iter()
            .flat_map(|s| KINDS.iter().map(move |k| format!("{s}-{k}")))
            .collect()
    } else {
        args.cases.clone()
    };
    let seed = args.seed.to_string();
    // The firmware is built once, by the baseline, before the runs share its image.
    let baseline = fly("faults/none", &seed, &[])?;
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<(usize, Result<Outcome, String>)>> = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..args.jobs {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = cases.get(i) else { break };
                let outcome = fly(
                    &format!("faults/{case}"),
                    &seed,
                    &[format!("{case}{FAULT}")],
                );
                if let Ok(mut r) = results.lock() {
                    r.push((i, outcome));
                }
            });
        }
    });
    let mut results = results
        .into_inner()
        .map_err(|_| "a fault run panicked".to_string())?;
    results.sort_by_key(|(i, _)| *i);

    println!("emulator fault matrix: seed route, seed {seed}, fault from 5 s for 3 s, figures 2 s after it ends");
    println!(
        "baseline (no fault): {} overruns, {} black cells out of place, error {:.2} cm",
        baseline.overruns, baseline.out_of_place, baseline.error_cm
    );
    println!("| case | ran on, 0 overruns | cells out of place added | error 2 s after (baseline {:.2} cm) | targets |", baseline.error_cm);
    println!("|---|---|---|---|---|");
    let mut broken = Vec::new();
    for (i, outcome) in results {
        let case = &cases[i];
        match outcome {
            Ok(o) => {
                let added = o.out_of_place - baseline.out_of_place;
                let met = o.kept_running()
                    && added <= 0.0
                    && o.error_cm - baseline.error_cm <= ADDED_ERROR_CM;
                println!(
                    "| {case} | {} ({}, {} overruns) | {added:+} | {:.2} cm | {} |",
                    if o.kept_running() { "yes" } else { "NO" },
                    o.stop_reason,
                    o.overruns,
                    o.error_cm,
                    if met { "met" } else { "missed" }
                );
                if !o.kept_running() {
                    broken.push(case.clone());
                }
            }
            Err(e) => {
                println!("| {case} | run failed: {e} | - | - | missed |");
                broken.push(case.clone());
            }
        }
    }
    if broken.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "the firmware stopped or overran under: {}",
            broken.join(", ")
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_the_sensors_by_the_kinds() {
        assert_eq!(case_name("gyro-stuck").as_deref(), Ok("gyro-stuck"));
        assert_eq!(
            case_name("camera-intermittent").as_deref(),
            Ok("camera-intermittent")
        );
        assert!(case_name("gyro-sideways").is_err());
        assert!(
            case_name("depth-nack").is_err(),
            "the matrix names kinds as host-sim does"
        );
    }
}
