//! The route: steps such as "turn a full circle", "drive 7 s", run tick by tick.
//!
//! As in the seed, the route steers by the true heading and position, so every pose
//! mode drives the same path and only the mapper's pose differs, unless the guard stops a
//! drive: it reads the mapper's belief (see `run`), and a drive it stops is skipped
//! ([`Route::skip`]).

use crate::robot::{wrap_deg, Command, TruePose};
use crate::scenario::RouteStep;

/// How many ticks of `tick_s` the route takes by its own numbers: a turn at its rate, a
/// drive or wait for its whole ticks, a distance at its speed, and every step at least
/// one tick. The run steers by truth, which follows the commands exactly, so this is what
/// the run takes to within a tick a step.
pub fn planned_ticks(steps: &[RouteStep], tick_s: f64) -> u64 {
    let ticks = |x: f64| (x - 1e-9).ceil().max(1.0) as u64;
    steps
        .iter()
        .map(|step| match step {
            RouteStep::Turn { degrees, rate_dps } => ticks(degrees.abs() / (rate_dps * tick_s)),
            RouteStep::Drive { seconds, .. } | RouteStep::Wait { seconds } => {
                (seconds / tick_s + 1e-9).floor().max(1.0) as u64
            }
            RouteStep::DriveDistance {
                distance_mm,
                speed_mm_s,
            } => ticks(distance_mm / (speed_mm_s.abs() * tick_s)),
        })
        .fold(0, u64::saturating_add)
}

/// Where the route is.
pub struct Route {
    steps: Vec<RouteStep>,
    index: usize,
    /// Progress in the current step: degrees turned, ticks driven or millimetres covered.
    progress: f64,
    last: Option<TruePose>,
    /// Whether the current tick's step was skipped or held, so the tick counts for no
    /// step.
    skipped: bool,
}

impl Route {
    /// A route at its first step.
    pub fn new(steps: &[RouteStep]) -> Route {
        Route {
            steps: steps.to_vec(),
            index: 0,
            progress: 0.0,
            last: None,
            skipped: false,
        }
    }

    /// Gives up the current step (the guard stopped it): the robot stands this tick,
    /// which counts for no step, and the next step starts at the next tick.
    pub fn skip(&mut self) {
        if self.index < self.steps.len() {
            self.index += 1;
            self.progress = 0.0;
            self.skipped = true;
        }
    }

    /// Holds the current step (an input its motion needs is doubted): the robot stands
    /// this tick, which counts for no step, and the step goes on where it was.
    pub fn hold(&mut self) {
        self.skipped = true;
    }

    /// What the motors should do now; `None` once the route is done.
    pub fn command(&self) -> Option<Command> {
        Some(match self.steps.get(self.index)? {
            RouteStep::Turn { degrees, rate_dps } => Command {
                speed_mm_s: 0.0,
                turn_dps: rate_dps.copysign(*degrees),
            },
            RouteStep::Drive { speed_mm_s, .. } | RouteStep::DriveDistance { speed_mm_s, .. } => {
                Command {
                    speed_mm_s: *speed_mm_s,
                    turn_dps: 0.0,
                }
            }
            RouteStep::Wait { .. } => Command::default(),
        })
    }

    /// Called after each tick's motion with the true pose; moves on when a step is done.
    pub fn after_tick(&mut self, truth: TruePose, tick_s: f64) {
        let last = self.last.replace(truth).unwrap_or(truth);
        if std::mem::take(&mut self.skipped) {
            return;
        }
        let Some(step) = self.steps.get(self.index) else {
            return;
        };
        let done = match step {
            RouteStep::Turn { degrees, .. } => {
                self.progress += wrap_deg(truth.heading_deg - last.heading_deg).abs();
                self.progress >= degrees.abs()
            }
            RouteStep::Drive { seconds, .. } | RouteStep::Wait { seconds } => {
                self.progress += 1.0;
                // The seed drives `int(seconds * 10)` ticks.
                self.progress >= (seconds / tick_s + 1e-9).floor().max(1.0)
            }
            RouteStep::DriveDistance { distance_mm, .. } => {
                self.progress += (truth.x_mm - last.x_mm).hypot(truth.y_mm - last.y_mm);
                self.progress >= *distance_mm
            }
        };
        if done {
            self.index += 1;
            self.progress = 0.0;
        }
    }

    /// Called once before the first tick with the starting pose.
    pub fn start(&mut self, truth: TruePose) {
        self.last = Some(truth);
    }
}
