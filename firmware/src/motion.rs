//! Motion task: drives the world file's route ([`world::ROUTE`]) through the DRV8833
//! ([`Motors`]), open loop on speed, with turns ended by the integrated gyro, as on the
//! real robot.
//!
//! # Motor model
//!
//! At full duty (1000 per mille) a wheel runs [`world::WHEEL_FULL_SPEED_MM_S`], and the
//! wheels are [`world::WHEEL_BASE_MM`] apart: the world file's `[robot]`, which the
//! simulator and the emulator harness drive with too. Speed is taken as proportional to
//! duty (the DRV8833 in slow decay, see `drivers::motors`), so for a forward speed `v` and
//! a clockwise turn rate `w`, `drive(forward, turn)` gets
//!
//! - `forward = v / full speed * 1000`, and
//! - `turn = (w in rad/s) * (base / 2) / full speed * 1000`,
//!
//! which `drivers::motors::mix` turns into `left = forward + turn`,
//! `right = forward - turn`.
//!
//! # PWM, for whoever reads it back
//!
//! Left motor: PWM slice 5, channel A on GP10 (DRV8833 AIN1), channel B on GP11 (AIN2).
//! Right motor: slice 6, A on GP12 (BIN1), B on GP13 (BIN2). 20 kHz: `TOP` 6249, divider
//! 1, not phase-correct, at 125 MHz. Slow decay: driving forward at `d` per mille holds
//! IN1 at compare `TOP` (always on, bar one count in 6250) and IN2 at
//! `(1000 - d) / 1000 * TOP` (IN2's low share is the drive); reverse swaps the two pins.
//! Coast (stop) is both compares 0. So a wheel's per mille is
//! `1000 * (cc_in1 - cc_in2) / TOP`, positive forward.
//!
//! # Safety
//!
//! The route starts only once the IMU task has calibrated the gyro bias (the robot must
//! stand still ~1.1 s after reset) and a SLAM tick has taken a live gyro reading. While
//! driving, the SLAM loop's reports are the heartbeat: if none arrives for
//! [`SLAM_SILENCE`], the motors coast and the route
//! pauses (a drive's clock stops too) until reports come back; each such halt is counted.
//! A turn that the gyro has not finished within twice its planned time plus two seconds
//! means the gyro is not to be trusted: the route is abandoned and the motors coast.
//!
//! Each report carries the guard's decision (`slam_core::guard`) on the drive this task
//! publishes in [`DRIVE_SPEED_MM_S`]: the leg being driven, or while turning the next
//! drive, so that the first report of a drive has already judged it. A drive the guard
//! stops coasts at once and the route goes on with its next leg (counted in
//! `guard_stops`); turns on the spot sweep nothing new and are never stopped. A guard
//! hold (an input the motion needs is doubted by the core's plausibility checks, or, for
//! a drive, the depth sensor shows nothing ahead as it is) coasts and keeps the leg: a
//! drive's clock and a turn's time limit stop until it lifts. Each hold is logged as it
//! begins, with the input it lacks.

use drivers::motors::{HBridge, MotorConfig, Motors, PerMille};
use embassy_rp::pwm::{self, Pwm, PwmError, PwmOutput};
use embassy_time::{Duration, Instant, Ticker};
use portable_atomic::{AtomicI32, AtomicU32, Ordering};
use slam_core::{Decision, DriveCommand, Input};

use crate::board::{MotorPins, MOTOR_PWM_TOP};
use crate::health::HEALTH;
use crate::inputs::Inputs;
use crate::retained::RoutePoint;
use crate::slam_task::ReportReceiver;
use crate::world::{self, WHEEL_BASE_MM, WHEEL_FULL_SPEED_MM_S};

/// Per mille of full duty for a forward speed, rounded to nearest.
pub const fn forward_permille(speed_mm_s: i64) -> i64 {
    div_round(speed_mm_s * 1000, WHEEL_FULL_SPEED_MM_S)
}

/// Per mille of full duty for a turn rate in millidegrees per second (positive
/// clockwise), rounded to nearest: `rate * pi * base / (360 * full speed)`, with pi as
/// 355/113 (good to 0.1 ppm, far below the model's own error).
pub const fn turn_permille(rate_mdps: i64) -> i64 {
    div_round(
        rate_mdps * 355 * WHEEL_BASE_MM,
        113 * 360 * WHEEL_FULL_SPEED_MM_S,
    )
}

// The model's arithmetic: full speed is full duty.
const _: () = assert!(forward_permille(WHEEL_FULL_SPEED_MM_S) == 1000);

/// `n / d` rounded to nearest, halves away from zero; `d > 0`.
const fn div_round(n: i64, d: i64) -> i64 {
    if n >= 0 {
        (n + d / 2) / d
    } else {
        (n - d / 2) / d
    }
}

/// One leg of the route.
#[derive(Clone, Copy, defmt::Format)]
pub enum Leg {
    /// Turn on the spot by `mdeg` millidegrees (positive clockwise) at `rate_mdps`
    /// (magnitude), ended by the integrated gyro.
    Turn {
        /// Angle to turn, millidegrees.
        mdeg: i64,
        /// Turn rate, millidegrees per second.
        rate_mdps: i64,
    },
    /// Drive straight at `speed_mm_s` for `time`, open loop (0 mm/s: stand still).
    Drive {
        /// How long to drive.
        time: Duration,
        /// Forward speed, millimetres per second.
        speed_mm_s: i64,
    },
}

/// The forward speed of the drive leg being driven, or while turning of the next one,
/// millimetres per second (0: none left): what the SLAM task asks the guard about.
pub static DRIVE_SPEED_MM_S: AtomicI32 = AtomicI32::new(0);

/// What the motors are driven with now (after a hold, a stop or a halt: nothing), for
/// the core to check the gyro against: forward speed in mm/s and turn rate in mdps.
static COMMANDED_SPEED_MM_S: AtomicI32 = AtomicI32::new(0);
static COMMANDED_TURN_MDPS: AtomicI32 = AtomicI32::new(0);

/// What the motors are driven with now, as [`slam_core::SensorFrame::commanded`] wants it.
pub fn commanded() -> DriveCommand {
    DriveCommand {
        speed_mm_s: COMMANDED_SPEED_MM_S.load(Ordering::Relaxed),
        turn_mdps: COMMANDED_TURN_MDPS.load(Ordering::Relaxed),
    }
}

/// Records what the motors are driven with.
fn publish(command: DriveCommand) {
    COMMANDED_SPEED_MM_S.store(command.speed_mm_s, Ordering::Relaxed);
    COMMANDED_TURN_MDPS.store(command.turn_mdps, Ordering::Relaxed);
}

/// Where the route is (a [`RoutePoint`]'s bits): set by this task as it goes, read by the
/// SLAM loop at the end of each tick into the retained state, so that a watchdog reset
/// resumes the route there. `main` sets it to where the route resumes before it starts.
pub static ROUTE_POINT: AtomicU32 = AtomicU32::new(0);

/// Where the route is now.
pub fn route_point() -> RoutePoint {
    RoutePoint(ROUTE_POINT.load(Ordering::Relaxed))
}

/// Records that leg `leg` is `done` in (millidegrees turned or milliseconds driven).
fn reached(leg: usize, done: u32) {
    ROUTE_POINT.store(RoutePoint::new(leg, done).0, Ordering::Relaxed);
}

/// The speed of the first drive leg from `legs` on, millimetres per second; 0 if none.
fn next_drive_speed(legs: &[Leg]) -> i32 {
    legs.iter()
        .find_map(|leg| match *leg {
            Leg::Drive { speed_mm_s, .. } => Some(i32::try_from(speed_mm_s).unwrap_or(0)),
            Leg::Turn { .. } => None,
        })
        .unwrap_or(0)
}

/// Control period: 100 Hz, so a gyro-ended turn overshoots by at most about 0.3 degrees
/// at 31.5 deg/s (plus the gyro's own 5 ms sample period).
const CONTROL_PERIOD: Duration = Duration::from_millis(10);

/// No SLAM report for this long (three ticks) and the motors coast.
pub const SLAM_SILENCE: Duration = Duration::from_millis(300);

/// Extra time a turn may take beyond twice its plan before the gyro is distrusted.
const TURN_GRACE: Duration = Duration::from_secs(2);

type DriveMotors =
    Motors<PwmOutput<'static>, PwmOutput<'static>, PwmOutput<'static>, PwmOutput<'static>>;

/// Owns the motors: waits for the gyro, drives [`world::ROUTE`] from `resume` on (the
/// start, or where a watchdog reset cut it off), then coasts for good.
#[embassy_executor::task]
pub async fn motion_task(
    pins: MotorPins,
    inputs: &'static Inputs,
    mut reports: ReportReceiver,
    resume: RoutePoint,
) -> ! {
    let Some(mut motors) = motors(pins) else {
        defmt::error!("motion: motors did not start; staying put");
        crate::sensors::park().await
    };
    defmt::info!(
        "motion: waiting for the gyro calibration (keep still); route of {=usize} legs in {=str}",
        world::ROUTE.len(),
        world::NAME
    );
    inputs.gyro_ready.wait().await;
    // Then one SLAM tick with the gyro live: the tick in which calibration ended saw
    // samples for only part of its interval, and the core takes their mean rate over the
    // whole of it. Moving then would count the turn's start twice (up to a tick's worth of
    // the turn); standing still one more tick costs 0.1 s. And with the depth sensor
    // ranging (its firmware takes a second or two to load): a first turn on the spot seen
    // whole closes ([`slam_core::slam::first_turn`]), one begun blind does not.
    let mut waited_for_depth = false;
    loop {
        let stale = reports.changed().await.step.stale;
        if !stale.gyro && !stale.depth {
            break;
        }
        if stale.depth && !core::mem::replace(&mut waited_for_depth, true) {
            defmt::info!("motion: waiting for the depth sensor to range");
        }
    }

    let mut pilot = Pilot {
        motors: &mut motors,
        inputs,
        reports: &mut reports,
        last_report: Instant::now(),
        halted: false,
        guard: Decision::Go,
    };
    if resume != RoutePoint::default() {
        defmt::info!(
            "motion: resuming the route at leg {=usize}, {=u32} in",
            resume.leg(),
            resume.done()
        );
    }
    let legs = world::ROUTE.iter().enumerate().skip(resume.leg());
    for (i, leg) in legs {
        defmt::info!("motion: leg {=usize}: {}", i, leg);
        let ahead = world::ROUTE.get(i..).unwrap_or(&[]);
        DRIVE_SPEED_MM_S.store(next_drive_speed(ahead), Ordering::Relaxed);
        // Only the leg a reset cut off starts part done.
        let done = if i == resume.leg() { resume.done() } else { 0 };
        let finished = match *leg {
            Leg::Turn { mdeg, rate_mdps } => pilot.turn(i, mdeg, done, rate_mdps).await,
            Leg::Drive { time, speed_mm_s } => {
                pilot.drive(i, time, done, speed_mm_s).await;
                true
            }
        };
        if !finished {
            defmt::error!("motion: turn not finished in time; gyro distrusted, route abandoned");
            break;
        }
    }
    // Done or abandoned: a reset from here on does not drive it again.
    reached(world::ROUTE.len(), 0);
    pilot.coast();
    defmt::info!("motion: route done, motors coasting");
    crate::sensors::park().await
}

/// Both PWM slices at 20 kHz, split into their four channels, coasting.
fn motors(pins: MotorPins) -> Option<DriveMotors> {
    let mut config = pwm::Config::default();
    config.top = MOTOR_PWM_TOP;
    // Compare 0 on both channels: both inputs low, the bridge coasts.
    config.compare_a = 0;
    config.compare_b = 0;
    let left = Pwm::new_output_ab(
        pins.left_slice,
        pins.left_in1,
        pins.left_in2,
        config.clone(),
    );
    let right = Pwm::new_output_ab(pins.right_slice, pins.right_in1, pins.right_in2, config);
    let (Some(left_in1), Some(left_in2)) = left.split() else {
        return None;
    };
    let (Some(right_in1), Some(right_in2)) = right.split() else {
        return None;
    };
    Motors::new(
        HBridge::new(left_in1, left_in2),
        HBridge::new(right_in1, right_in2),
        MotorConfig::default(),
    )
    .ok()
}

/// The route follower's state between legs.
struct Pilot<'a> {
    motors: &'a mut DriveMotors,
    inputs: &'static Inputs,
    reports: &'a mut ReportReceiver,
    /// When the SLAM loop last reported.
    last_report: Instant,
    /// Whether the motors are coasting because the SLAM loop went quiet.
    halted: bool,
    /// The guard's decision in the newest report.
    guard: Decision,
}

impl Pilot<'_> {
    /// Turns leg `leg`, `mdeg` of which `done` are turned already, at `rate_mdps` until
    /// the gyro says so; `false` if it took too long.
    async fn turn(&mut self, leg: usize, mdeg: i64, done: u32, rate_mdps: i64) -> bool {
        let direction = if mdeg >= 0 { 1 } else { -1 };
        let done = i64::from(done);
        let mdeg = (mdeg.abs() - done).max(0) * direction;
        let command = DriveCommand {
            speed_mm_s: 0,
            turn_mdps: i32::try_from(rate_mdps.abs() * direction).unwrap_or(0),
        };
        let planned_ms = mdeg.abs() * 1000 / rate_mdps.abs().max(1);
        let limit =
            Duration::from_millis(u64::try_from(planned_ms * 2).unwrap_or(u64::MAX)) + TURN_GRACE;
        let start_yaw = self.inputs.yaw.yaw_mdeg();
        let started = Instant::now();
        let mut ticker = Ticker::every(CONTROL_PERIOD);
        let mut held = Duration::from_ticks(0);
        loop {
            let turned = (self.inputs.yaw.yaw_mdeg() - start_yaw) * direction;
            reached(leg, u32::try_from(done + turned).unwrap_or(0));
            if turned >= mdeg.abs() {
                self.coast();
                return true;
            }
            if started.elapsed() > limit + held {
                self.coast();
                return false;
            }
            // Only a doubted gyro holds a turn: a turn on the spot needs no flow.
            let holding = self.guard == Decision::Hold(Input::Gyro);
            if holding {
                self.coast();
            } else {
                self.command(command);
            }
            ticker.next().await;
            if holding {
                held += CONTROL_PERIOD;
            }
            self.listen();
        }
    }

    /// Drives leg `leg` at `speed_mm_s` for `time` of running (halts do not count), `done`
    /// milliseconds of which are driven already, or until the guard stops it.
    async fn drive(&mut self, leg: usize, time: Duration, done: u32, speed_mm_s: i64) {
        let command = DriveCommand {
            speed_mm_s: i32::try_from(speed_mm_s).unwrap_or(0),
            turn_mdps: 0,
        };
        let mut driven = Duration::from_millis(u64::from(done));
        let mut ticker = Ticker::every(CONTROL_PERIOD);
        let mut previous = Instant::now();
        while driven < time {
            self.listen();
            let was_running = match self.guard {
                Decision::Stop(obstacle) => {
                    defmt::warn!("motion: guard stop before {}; leg skipped", obstacle);
                    HEALTH.guard_stops.bump();
                    // Skipped: a reset does not drive the rest of it.
                    reached(leg, u32::MAX);
                    break;
                }
                // The leg's clock stops while an input it needs is doubted.
                Decision::Hold(_) => {
                    self.coast();
                    false
                }
                Decision::Go => {
                    self.command(command);
                    !self.halted
                }
            };
            ticker.next().await;
            let now = Instant::now();
            if was_running {
                driven += now.saturating_duration_since(previous);
                reached(leg, u32::try_from(driven.as_millis()).unwrap_or(u32::MAX));
            }
            previous = now;
        }
        self.coast();
    }

    /// Drives `command` unless the SLAM loop has gone quiet, in which case the motors
    /// coast until it reports again.
    fn command(&mut self, command: DriveCommand) {
        self.listen();
        let silent = self.last_report.elapsed() > SLAM_SILENCE;
        if silent {
            if !self.halted {
                defmt::warn!("motion: SLAM reports stopped; motors coasting");
                HEALTH.motion_halts.bump();
                self.halted = true;
            }
            self.coast();
            return;
        }
        if self.halted {
            defmt::info!("motion: SLAM reports back; resuming");
            self.halted = false;
        }
        let forward = forward_permille(i64::from(command.speed_mm_s));
        let turn = turn_permille(i64::from(command.turn_mdps));
        let forward = PerMille::saturating(i32::try_from(forward).unwrap_or(0));
        let turn = PerMille::saturating(i32::try_from(turn).unwrap_or(0));
        publish(command);
        let result: Result<_, drivers::motors::Error<PwmError>> = self.motors.drive(forward, turn);
        if result.is_err() {
            HEALTH.motor_errors.bump();
        }
    }

    /// Takes the newest SLAM report, if one came: its time and the guard's decision.
    fn listen(&mut self) {
        if let Some(report) = self.reports.try_changed() {
            self.last_report = Instant::now();
            if let Decision::Hold(input) = report.guard {
                if self.guard != report.guard {
                    defmt::warn!("motion: guard holds, {} lacking", input);
                }
            }
            self.guard = report.guard;
        }
    }

    /// Both motors coast.
    fn coast(&mut self) {
        publish(DriveCommand::default());
        if self.motors.stop().is_err() {
            HEALTH.motor_errors.bump();
        }
    }
}
