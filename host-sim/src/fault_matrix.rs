//! The fault matrix: every sensor failing every way ([`crate::fault`]), each run beside
//! the same seed without the fault, with the figures the fault issue names.
//!
//! For one case and one seed: whether the run panicked, the black cells out of place it
//! added over the run without the fault, the position error 2 s after the sensor came
//! back beside the unfaulted run's at the same tick, and the time to recover: from the
//! sensor's return to the first tick from which the error stays within
//! [`RECOVERED_CM`] of the unfaulted run's, or below it, to the end. A run that ends up
//! surer than the one without the fault (its route held a few seconds, so its turns and
//! tags come at other ticks) has not failed to recover; the error 2 s after the return
//! is likewise counted only above the unfaulted run's.

use std::panic::{catch_unwind, AssertUnwindSafe};

use serde::Serialize;

use crate::fault::{Fault, Kind, Sensor};
use crate::run::{run_with, PoseMode, RunOptions, RunOutput, TICK_S};
use crate::scenario::Scenario;

/// How close to the unfaulted run's error a run must come back, centimetres.
pub const RECOVERED_CM: f64 = 1.0;
/// When the error after the return is read, seconds after it.
pub const SETTLE_S: f64 = 2.0;

/// Where and how long each case's fault strikes.
#[derive(Clone, Copy, Debug)]
pub struct Window {
    /// Seconds into the run.
    pub start_s: f64,
    /// Seconds it lasts.
    pub duration_s: f64,
}

/// One case over its seeds.
#[derive(Clone, Debug, Serialize)]
pub struct CaseFigures {
    /// `SENSOR-KIND`.
    pub case: String,
    /// Seeds run.
    pub seeds: u32,
    /// Seeds whose run panicked.
    pub panics: u32,
    /// Most black cells out of place the fault added (over the run without it), any seed.
    pub out_of_place_added: i64,
    /// Largest excess of the position error 2 s after the return over the unfaulted
    /// run's, any seed, cm.
    pub excess_error_cm: f64,
    /// Longest time to recover, any seed, s; `None` when some seed never recovered.
    pub recover_s: Option<f64>,
}

impl CaseFigures {
    /// Whether the case meets the fault issue's targets: no panic, no cell out of place
    /// added, within [`RECOVERED_CM`] 2 s after the return, recovered within 2 s.
    pub fn meets_targets(&self) -> bool {
        self.panics == 0
            && self.out_of_place_added <= 0
            && self.excess_error_cm <= RECOVERED_CM
            && self.recover_s.is_some_and(|s| s < SETTLE_S)
    }
}

/// Why the matrix could not run.
#[derive(Debug)]
pub enum MatrixError {
    /// The unfaulted run failed (its grid or route), as `host-sim run` says.
    Baseline(String),
}

impl std::fmt::Display for MatrixError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MatrixError::Baseline(e) => write!(f, "the run without faults failed: {e}"),
        }
    }
}

impl std::error::Error for MatrixError {}

/// Runs all 24 cases (or those `only` names, as `SENSOR-KIND`) on `seeds`.
pub fn run_matrix(
    scenario: &Scenario,
    mode: PoseMode,
    seeds: &[u64],
    window: Window,
    only: Option<&str>,
) -> Result<Vec<CaseFigures>, MatrixError> {
    let mut baselines = Vec::new();
    for &seed in seeds {
        let out = run_with(scenario, mode, seed, RunOptions::default())
            .map_err(|e| MatrixError::Baseline(e.to_string()))?;
        baselines.push(out);
    }
    let mut cases = Vec::new();
    for sensor in Sensor::ALL {
        for kind in Kind::ALL {
            let name = format!("{}-{}", sensor.name(), kind.name());
            if only.is_some_and(|o| o != name) {
                continue;
            }
            let fault = Fault {
                sensor,
                kind,
                start_s: window.start_s,
                duration_s: Some(window.duration_s),
            };
            cases.push(run_case(scenario, mode, seeds, &baselines, fault, name));
        }
    }
    Ok(cases)
}

fn run_case(
    scenario: &Scenario,
    mode: PoseMode,
    seeds: &[u64],
    baselines: &[RunOutput],
    fault: Fault,
    name: String,
) -> CaseFigures {
    let mut figures = CaseFigures {
        case: name,
        seeds: 0,
        panics: 0,
        out_of_place_added: 0,
        excess_error_cm: 0.0,
        recover_s: Some(0.0),
    };
    let back_s = fault.end_s().unwrap_or(f64::INFINITY);
    for (&seed, base) in seeds.iter().zip(baselines) {
        figures.seeds += 1;
        let faults = [fault];
        let options = RunOptions {
            faults: &faults,
            ..RunOptions::default()
        };
        let out = catch_unwind(AssertUnwindSafe(|| run_with(scenario, mode, seed, options)));
        let Ok(Ok(out)) = out else {
            figures.panics += 1;
            continue;
        };
        let added = i64::from(out.figures.out_of_place) - i64::from(base.figures.out_of_place);
        figures.out_of_place_added = figures.out_of_place_added.max(added);
        let error =
            |o: &RunOutput, i: usize| o.record.ticks.get(i).map_or(f64::NAN, |t| t.error_cm);
        let tick_of = |t_s: f64| (t_s / TICK_S).round() as usize;
        let settle = tick_of(back_s + SETTLE_S);
        let excess = error(&out, settle) - error(base, settle);
        // A run too short to read counts as not recovered.
        figures.excess_error_cm = figures.excess_error_cm.max(if excess.is_nan() {
            f64::INFINITY
        } else {
            excess
        });
        let n = out.record.ticks.len().min(base.record.ticks.len());
        let from = tick_of(back_s).min(n);
        // The first tick from which the error stays close to the unfaulted run's.
        let mut recovered_at = None;
        for i in (from..n).rev() {
            if error(&out, i) - error(base, i) > RECOVERED_CM {
                break;
            }
            recovered_at = Some(i);
        }
        figures.recover_s = match (figures.recover_s, recovered_at) {
            (Some(worst), Some(i)) => Some(worst.max((i - from) as f64 * TICK_S)),
            _ => None,
        };
    }
    figures
}

/// The matrix as a Markdown table, the README's form.
pub fn table(cases: &[CaseFigures]) -> String {
    let mut s = String::from(
        "| case | seeds | panics | cells out of place added | error 2 s after return, over the run without the fault | time to recover |\n|---|---|---|---|---|---|\n",
    );
    for c in cases {
        let recover = c
            .recover_s
            .map_or("never".to_string(), |t| format!("{t:.1} s"));
        s.push_str(&format!(
            "| {} | {} | {} | {} | {:+.1} cm | {} |\n",
            c.case, c.seeds, c.panics, c.out_of_place_added, c.excess_error_cm, recover
        ));
    }
    s
}
