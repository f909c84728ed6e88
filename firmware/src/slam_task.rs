//! The SLAM loop: a 10 Hz tick that gathers the latest sensor readings into a
//! [`SensorFrame`], runs the core's `step` and the guard, publishes the report, frames
//! this tick's telemetry and feeds the watchdog.
//!
//! # Why the telemetry frames are made here
//!
//! A `MapRows` message needs the grid, and the grid lives in the SLAM state that only this
//! loop touches. Rather than share the 4 KB grid behind a lock (the telemetry task would
//! then hold up the tick, or copy the grid each time), this loop runs the core's
//! [`Streamer`] right after `step`, while it holds the map anyway, and queues each encoded
//! frame (at most [`MAX_FRAME_LEN`] bytes) in [`TELEMETRY_FRAMES`]. The telemetry task only
//! moves bytes to the UART. Encoding costs a few hundred microseconds a tick, and the queue
//! is never waited on: when it is full (the link is behind) a frame is dropped and counted.
//! The simulator calls the same `Streamer`, so it records the same messages (the tick's
//! inputs among them, which `host-sim replay` steps again); today it uses
//! `Schedule::DEFAULT` (one map chunk a tick) where the robot sends two (see
//! [`TELEMETRY_SCHEDULE`]), so only the map sweep's pace differs.

#[cfg(feature = "matching")]
use core::cell::Cell;
use core::mem::MaybeUninit;
use embassy_rp::watchdog::Watchdog;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::watch::{Receiver, Watch};
use embassy_time::{Duration, Instant, Ticker};
use portable_atomic::Ordering;
#[cfg(feature = "matching")]
use static_cell::ConstStaticCell;
#[cfg(feature = "matching")]
use slam_core::slam::first_turn::FirstTurn;
#[cfg(feature = "matching")]
use slam_core::wall_rate::WallRate;
#[cfg(feature = "matching")]
use slam_core::wall_turn::WallTurn;
use slam_core::{Decision, DriveCommand, GuardConfig, Localiser, Pose, SensorFrame, StepReport};
use wire::telemetry::{encode, FirmwareVersion, Message, Schedule, Streamer, MAX_FRAME_LEN};

use crate::health::HEALTH;
use crate::inputs::Inputs;
use crate::retained::{Saved, Start};
use crate::world::{self, WorldSlam};

/// The SLAM period: 10 Hz, the rate the core's odometry and mapping are tuned for.
pub const TICK: Duration = Duration::from_millis(100);

/// Watchdog timeout: five ticks. Four ticks in a row that never finish reset the chip.
pub const WATCHDOG_TIMEOUT: Duration = Duration::from_millis(500);

/// Ticks between two log lines: once a second.
const TICKS_PER_LOG: u32 = 10;

/// Where the robot is placed at power-up: the world file's start.
pub const START_POSE: Pose = world::START;

/// What corrects the pose beyond odometry: the filter, which takes every tag sighting,
/// learns the gyro's and the flow sensor's errors and, with the `matching` feature (on by
/// default), matches the depth scans against the map (`host-sim run --pose slam`; without
/// the feature `--pose filter`). The `two-tag-fix` feature flies the seed's two-tag fix
/// instead (`--pose tags`). The telemetry's `Hello` says which, so the viewer and the
/// emulator checks know.
pub const LOCALISER: Localiser = if cfg!(feature = "two-tag-fix") {
    Localiser::TwoTagFix
} else {
    Localiser::Filter
};

/// The guard's body and timing: the world's body radius, with the beams of the sensor's
/// own fan (as `world::slam_config`'s). Its latency covers a scan up to a frame (67 ms at
/// 15 Hz) old plus the step; its tick is the time until the next decision, a tick plus the
/// motion task's control period within it. See `slam_core::guard`.
const GUARD: GuardConfig = GuardConfig {
    beam_angles: slam_core::slam::fan(drivers::depth::FOV_MDEG as i64),
    radius_mm: world::BODY_RADIUS_MM,
    ..GuardConfig::SEED
};

/// What each tick tells the motion task: the core's report, and the guard's word on the
/// drive the motion task said it is about to make ([`crate::motion::DRIVE_SPEED_MM_S`]).
#[derive(Clone, Copy)]
pub struct TickReport {
    /// The core's report.
    pub step: StepReport,
    /// Whether that drive may go on for the next tick.
    pub guard: Decision,
}

/// How many tasks may follow the reports: the motion task (its heartbeat) and one spare
/// for a planner.
pub const REPORT_READERS: usize = 2;

/// The telemetry schedule at 10 Hz: a `Hello` at the first tick and every 5 s, each
/// tick's raw inputs (with the `record-inputs` feature, on by default, so that the run can
/// be replayed with `host-sim replay`), a `Tick` every tick (and the filter's `Filter`
/// after it), two `MapRows` chunks every tick (the map goes round in a time that grows
/// with the world's grid: 1.2 s for the seed mat's), and a `Health` every second. The wire crate's budget
/// gives the bytes per second; about 7 % of the 921600 baud link.
pub const TELEMETRY_SCHEDULE: Schedule = Schedule {
    hello_every_ticks: 50,
    health_every_ticks: 10,
    map_chunks_per_tick: 2,
    inputs: cfg!(feature = "record-inputs"),
};

/// Readings of the first turn's closure searched before the loop yields to the other
/// tasks (`slam_core::slam::first_turn::FirstTurn::search`): each laid over the turn's
/// start at every slide, as short a piece as a match's, inside the flow task's read
/// timeout.
#[cfg(feature = "matching")]
const FIRST_TURN_PIECES_PER_TURN: usize = 2;

/// Pieces of a scan match searched before the loop yields to the other tasks
/// ([`slam_core::matcher::Matcher::search`]): one is a fraction of a millisecond on the
/// M0+, well inside the flow task's read timeout.
#[cfg(feature = "matching")]
const MATCH_PIECES_PER_TURN: usize = 1;

/// Frames queued for the link: one tick's worth (at most seven) with room to spare.
pub const TELEMETRY_QUEUE: usize = 10;

/// One encoded telemetry frame, delimiter included. `Clone` so the telemetry task can hand
/// a copy to the USB queue as well as write it to the UART.
#[derive(Clone)]
pub struct TelemetryFrame {
    /// Bytes used in `bytes`.
    len: usize,
    bytes: [u8; MAX_FRAME_LEN],
}

impl TelemetryFrame {
    /// The frame's bytes, ready for the wire.
    pub fn as_bytes(&self) -> &[u8] {
        self.bytes.get(..self.len).unwrap_or(&[])
    }
}

/// Encoded frames from this loop to the telemetry task. A `Channel`: every frame matters
/// to the viewer and they must stay in order; the loop only ever `try_send`s.
pub static TELEMETRY_FRAMES: Channel<CriticalSectionRawMutex, TelemetryFrame, TELEMETRY_QUEUE> =
    Channel::new();

/// The firmware version sent in every `Hello`, from `Cargo.toml`.
const FIRMWARE_VERSION: FirmwareVersion = FirmwareVersion {
    major: parse_u8(env!("CARGO_PKG_VERSION_MAJOR")),
    minor: parse_u8(env!("CARGO_PKG_VERSION_MINOR")),
    patch: parse_u8(env!("CARGO_PKG_VERSION_PATCH")),
};

/// Each tick's [`TickReport`]. A `Watch`: one writer (this loop), several readers that
/// each see the newest report and never hold the loop up; a slow reader skips reports.
pub static REPORTS: Watch<CriticalSectionRawMutex, TickReport, REPORT_READERS> = Watch::new();

/// The drive at a wall under way, measuring the flow's scale, and the wall the gyro's turn
/// is held to (`Slam::measure_walls`): beside the core, not in its retained state (a
/// reset loses at most one drive and one wall), and not in the task's own state, whose
/// layout the step inlined in it feels.
#[cfg(feature = "matching")]
static WALLS: embassy_sync::blocking_mutex::Mutex<
    CriticalSectionRawMutex,
    Cell<(WallRate, WallTurn)>,
> = embassy_sync::blocking_mutex::Mutex::new(Cell::new((WallRate::new(), WallTurn::new())));

/// A follower of [`REPORTS`].
pub type ReportReceiver = Receiver<'static, CriticalSectionRawMutex, TickReport, REPORT_READERS>;

/// A new core at the world's start with an empty map, built in `slot`: what the retained
/// state starts as when there is nothing to resume (`crate::retained`). Built in place, as
/// a core larger than the stack (a 10 m room's) could not be built on it and moved.
pub fn fresh_slam(slot: &mut MaybeUninit<WorldSlam>) {
    match WorldSlam::new_in(slot, world::slam_config(LOCALISER), START_POSE) {
        Ok(_) => {}
        // The configuration is fixed at build time and tested on the host: this is a bug.
        Err(e) => defmt::panic!("slam: configuration rejected: {}", e),
    }
}

/// Health of the loop itself; the core keeps its own [`slam_core::Counters`].
#[derive(Clone, Copy, Default, defmt::Format)]
pub struct LoopCounters {
    /// Ticks run.
    pub ticks: u32,
    /// Ticks that started more than one period late; the ticker is then re-phased rather
    /// than run the missed ticks back to back.
    pub overruns: u32,
    /// Worst start lateness since boot, in microseconds.
    pub max_late_us: u32,
    /// Worst time spent in `step` and the guard, in microseconds.
    pub max_step_us: u32,
    /// Worst time from the end of `step` to the end of its scan match, in microseconds,
    /// the other tasks' turns in between included (`matching` feature).
    pub max_match_us: u32,
    /// Worst time spent framing the tick's telemetry, in microseconds.
    pub max_telemetry_us: u32,
    /// Worst time spent closing the retained state after the step, in microseconds.
    pub max_save_us: u32,
}

/// Runs the SLAM loop for good on `saved` (the core, resumed or fresh, as `start` says),
/// feeding `watchdog`.
#[embassy_executor::task]
pub async fn slam_task(
    mut watchdog: Watchdog,
    inputs: &'static Inputs,
    mut saved: Saved,
    start: Start,
) -> ! {
    let boot = start.boot;
    // The run's clock carries on over a resumed reset: the last close before it, plus the
    // watchdog's timeout (it fired that long after the feed that followed the close).
    let run_offset_ms = match start.fresh {
        None => start
            .run_ms
            .saturating_add(WATCHDOG_TIMEOUT.as_millis() as u32),
        Some(_) => 0,
    };
    match start.fresh {
        None => {
            let slam = saved.slam();
            defmt::warn!(
                "slam: restarted after a {}: resumed at tick {=u32}, pose {}, {=u32} beams mapped, route at {} (resume {=u16})",
                boot.cause,
                slam.counters().ticks,
                slam.pose(),
                slam.counters().beams_mapped,
                start.route,
                boot.resumes
            );
        }
        Some(why) => defmt::info!(
            "slam: started after a {}: fresh at the world's start ({})",
            boot.cause,
            why
        ),
    }
    defmt::info!(
        "slam: world {=str}, {=usize} x {=usize} grid, {=usize} bytes of state, start {}",
        world::NAME,
        world::GRID_COLUMNS,
        world::GRID_ROWS,
        core::mem::size_of::<WorldSlam>(),
        START_POSE
    );

    // A debugger halting the core must not trigger a reset.
    watchdog.pause_on_debug(true);
    watchdog.start(WATCHDOG_TIMEOUT);

    let reports = REPORTS.sender();
    let mut streamer =
        Streamer::new(TELEMETRY_SCHEDULE, FIRMWARE_VERSION, LOCALISER)
            .with_matching(world::slam_config(LOCALISER).matching.is_some())
            .with_boot(boot);
    let mut health = LoopCounters::default();
    let mut ticker = Ticker::every(TICK);
    let mut deadline = Instant::now() + TICK;
    let mut previous = Instant::now();
    // A resumed run was blind from the last close until now: the watchdog's timeout, then
    // the boot. Its first frame spans that time with neither flow nor gyro (their first
    // readings cover only the time since the boot), so that the filter widens the pose by the
    // motion it may have missed and the tags in sight can pull it back.
    let mut unseen_us = match start.fresh {
        None => {
            previous = Instant::from_ticks(0);
            micros(WATCHDOG_TIMEOUT)
        }
        Some(_) => 0,
    };
    let mut trust = slam_core::Trust::default();
    let mut gyro_heard = false;
    // The run's first turn, kept until it closes (`Slam::close_first_turn`): beside the
    // core as the walls are, and taken in place, never built on the stack. A resumed run
    // keeps none: its map was laid before the reset.
    #[cfg(feature = "matching")]
    let first_turn = {
        static FIRST_TURN: ConstStaticCell<FirstTurn> = ConstStaticCell::new(FirstTurn::new());
        let first_turn = FIRST_TURN.take();
        if start.fresh.is_none() {
            first_turn.resume();
        }
        first_turn
    };
    // The step leaves its scan match to this loop, which searches it a few headings at a
    // time and lets the sensors' tasks run in between.
    #[cfg(feature = "matching")]
    saved.slam().defer_matching(true);
    loop {
        ticker.next().await;
        let started = Instant::now();

        let late = started.saturating_duration_since(deadline);
        health.max_late_us = health.max_late_us.max(micros(late));
        if late > TICK {
            health.overruns = health.overruns.wrapping_add(1);
            HEALTH.tick_overruns.bump();
            ticker.reset_at(started);
            deadline = started + TICK;
        } else {
            deadline += TICK;
        }

        // dt is the time actually elapsed, so a late tick integrates the right interval.
        let dt_us = micros(started.saturating_duration_since(previous));
        previous = started;

        // Each input: `None` (stale) unless its task published since the last tick.
        let mut frame = SensorFrame::empty(dt_us.saturating_add(unseen_us));
        frame.commanded = Some(crate::motion::commanded());
        frame.flow = inputs.flow.take();
        let gyro = inputs.gyro.take();
        frame.gyro = gyro.map(|g| g.rate);
        // Until the gyro is first heard (its calibration at boot, for which the motion
        // task holds the robot still) no time passes for the core: a heading it could not
        // follow would otherwise widen by a turn it did not make, as host-sim's first
        // frame has no time either. A resumed run's first frame keeps its blind span.
        gyro_heard |= frame.gyro.is_some();
        if !gyro_heard && unseen_us == 0 {
            frame.dt_us = 0;
        }
        // The moment the frame's odometry reaches: the core carries a picture or a scan
        // from its own moment to the frame's pose by the odometry, so their ages count
        // back from the newest gyro sample, which sets the heading, not from the wake-up.
        let odometry_at = gyro.map_or(started, |g| g.newest.min(started));
        if unseen_us > 0 {
            (frame.flow, frame.gyro, unseen_us) = (None, None, 0);
        }
        if let Some(reading) = inputs.depth.try_take() {
            frame.depth = Some(reading.scan);
            // The sensor ranges on its own 15 Hz clock: a scan is up to a frame old, and
            // the core maps it at the pose of that moment.
            frame.depth_age_us = micros(odometry_at.saturating_duration_since(reading.measured));
            frame.depth_doubt = reading.doubt;
        }
        if let Some(picture) = inputs.tags.try_take() {
            frame.tags = picture.tags;
            // How long before the odometry's moment the picture was sent; one sent after
            // it counts as taken at it.
            frame.tags_age_us = micros(odometry_at.saturating_duration_since(picture.sent));
        }

        let trusted_before = trust;
        // Between open and close the retained state is being changed: a reset in there
        // starts fresh rather than resume half a tick.
        saved.open_tick();
        let slam = saved.slam();
        let report = slam.step(&frame);
        let stepped = Instant::now();
        if slam.depth_steps_void() {
            inputs.depth_steps_void.store(true, portable_atomic::Ordering::Relaxed);
        }
        #[cfg(feature = "matching")]
        let report = {
            loop {
                // Every turn ends in a yield, the last one's before the finish.
                let searched = saved.slam().search_match(MATCH_PIECES_PER_TURN);
                embassy_futures::yield_now().await;
                if searched {
                    break;
                }
            }
            let report = saved.slam().finish_match(report);
            // A drive at a wall measures the flow's scale and holds the gyro's turn to
            // the wall's, off the step as the match.
            let (mut walls, mut turn) = WALLS.lock(Cell::get);
            let report = saved
                .slam()
                .measure_walls(&mut walls, &mut turn, &frame, report);
            WALLS.lock(|w| w.set((walls, turn)));
            // The first turn on the spot, drawn again once it closes, off the step too: its
            // closure searched a few readings at a time, as the match is.
            let keeping = first_turn.keeping();
            let report = saved.slam().close_first_turn(first_turn, &frame, report);
            while !first_turn.search(FIRST_TURN_PIECES_PER_TURN) {
                embassy_futures::yield_now().await;
            }
            let report = saved.slam().finish_first_turn(first_turn, report);
            if let (true, Some(outcome)) = (keeping, first_turn.outcome()) {
                defmt::info!("slam: first turn {}", outcome);
            }
            report
        };
        let matched = Instant::now();
        let slam = saved.slam();
        trust = report.trust;
        if trust != trusted_before {
            // Four bits an input, gyro lowest: 0 trusted, else `slam_core::Doubt::code`.
            defmt::warn!("slam: doubted inputs now {=u16:#05x}", trust.packed());
        }
        // The guard, as host-sim's route asks it: this tick's pose, map, scan and trust.
        let command = DriveCommand {
            speed_mm_s: crate::motion::DRIVE_SPEED_MM_S.load(Ordering::Relaxed),
            turn_mdps: 0,
        };
        let decision = slam_core::decide(
            &GUARD,
            &report.pose,
            slam.map(),
            frame.sight(),
            &report.trust,
            command,
        );
        let decided = Instant::now();
        let time_ms = u32::try_from(started.as_millis())
            .unwrap_or(u32::MAX)
            .saturating_add(run_offset_ms);
        saved.close(crate::motion::route_point(), time_ms);
        let slam = saved.slam();
        health.max_step_us = health
            .max_step_us
            .max(micros(
                stepped.saturating_duration_since(started)
                    + decided.saturating_duration_since(matched),
            ));
        health.max_match_us = health
            .max_match_us
            .max(micros(matched.saturating_duration_since(stepped)));
        health.max_save_us = health
            .max_save_us
            .max(micros(Instant::now().saturating_duration_since(decided)));
        health.ticks = health.ticks.wrapping_add(1);

        watchdog.feed(WATCHDOG_TIMEOUT);
        HEALTH.watchdog_feeds.bump();
        reports.send(TickReport {
            step: report,
            guard: decision,
        });

        let framing = Instant::now();
        let sensor_health = HEALTH.sensor_health();
        // The telemetry stamps the tick with the moment its pose is of: the odometry's,
        // a few milliseconds before the wake-up, which in a turn is a visible angle.
        let pose_ms = u32::try_from(odometry_at.as_millis())
            .unwrap_or(u32::MAX)
            .saturating_add(run_offset_ms);
        streamer.tick(
            pose_ms,
            &frame,
            &report,
            slam.tag_counters(),
            slam.map(),
            &sensor_health,
            queue_frame,
        );
        health.max_telemetry_us = health
            .max_telemetry_us
            .max(micros(Instant::now().saturating_duration_since(framing)));

        if health.ticks % TICKS_PER_LOG == 0 {
            log(&report, &health);
        }
    }
}

/// Encodes `message` and queues it for the telemetry task without waiting: a full queue
/// drops the frame (counted), an encoding failure is counted too.
fn queue_frame(message: &Message) {
    let mut frame = TelemetryFrame {
        len: 0,
        bytes: [0; MAX_FRAME_LEN],
    };
    match encode(message, &mut frame.bytes) {
        Ok(len) => {
            frame.len = len;
            if TELEMETRY_FRAMES.try_send(frame).is_err() {
                HEALTH.telemetry_dropped.bump();
            }
        }
        Err(e) => {
            defmt::warn!("slam: telemetry frame not encoded: {}", e);
            HEALTH.telemetry_errors.bump();
        }
    }
}

/// A decimal `u8` at compile time (for the version numbers); 0 if it is not one.
const fn parse_u8(s: &str) -> u8 {
    let bytes = s.as_bytes();
    let mut value: u32 = 0;
    let mut i = 0;
    while i < bytes.len() {
        let digit = bytes[i];
        if !digit.is_ascii_digit() || value > 25 {
            return 0;
        }
        value = value * 10 + (digit - b'0') as u32;
        i += 1;
    }
    if value > 255 {
        0
    } else {
        value as u8
    }
}

/// One line a second: where the robot thinks it is, and how the loop and inputs are doing.
fn log(report: &StepReport, health: &LoopCounters) {
    let c = &report.counters;
    defmt::info!(
        "pose x={=i32}mm y={=i32}mm heading={=i32}mdeg | {} | stale flow={=u32} gyro={=u32} depth={=u32} | fixes taken={=u32} rejected={=u32} | beams={=u32}",
        report.pose.x_mm(),
        report.pose.y_mm(),
        report.pose.heading.to_millidegrees(),
        health,
        c.flow_stale,
        c.gyro_stale,
        c.depth_stale,
        c.fixes_taken,
        c.fixes_rejected_geometry + c.fixes_rejected_gate + c.fixes_rejected_too_old,
        c.beams_mapped,
    );
    defmt::info!("health: {}", HEALTH.sensor_health());
    HEALTH.log_firmware_detail();
}

/// A duration in whole microseconds, saturating at `u32::MAX` (71 minutes).
fn micros(d: Duration) -> u32 {
    u32::try_from(d.as_micros()).unwrap_or(u32::MAX)
}
