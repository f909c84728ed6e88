//! The SLAM loop: a 10 Hz tick that gathers the latest sensor readings into a
//! [`SensorFrame`], runs the core's `step`, publishes the report and feeds the watchdog.

use embassy_rp::peripherals::WATCHDOG;
use embassy_rp::watchdog::{ResetReason, Watchdog};
use embassy_rp::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::watch::{Receiver, Watch};
use embassy_time::{Duration, Instant, Ticker};
use slam_core::{Pose, SeedSlam, SensorFrame, SlamConfig, StepReport};
use static_cell::StaticCell;

use crate::inputs::Inputs;

/// The SLAM period: 10 Hz, the rate the core's odometry and mapping are tuned for.
pub const TICK: Duration = Duration::from_millis(100);

/// Watchdog timeout: five ticks. Four ticks in a row that never finish reset the chip.
pub const WATCHDOG_TIMEOUT: Duration = Duration::from_millis(500);

/// Ticks between two log lines: once a second.
const TICKS_PER_LOG: u32 = 10;

/// Where the robot is placed at power-up: the seed's start, (70, 50) cm facing the far wall
/// where tags 11 and 12 hang (the simulator's scenario is tested to agree).
pub const START_POSE: Pose = SlamConfig::SEED_START;

/// How many tasks may follow the reports: telemetry now, a motion planner later.
pub const REPORT_READERS: usize = 2;

/// Each tick's [`StepReport`]. A `Watch`: one writer (this loop), several readers that
/// each see the newest report and never hold the loop up; a slow reader skips reports.
pub static REPORTS: Watch<CriticalSectionRawMutex, StepReport, REPORT_READERS> = Watch::new();

/// A follower of [`REPORTS`].
pub type ReportReceiver = Receiver<'static, CriticalSectionRawMutex, StepReport, REPORT_READERS>;

/// The SLAM state. It holds the whole grid (4.2 KB for the seed mat's 46 x 46, 83 KB for
/// a 10 m room), so it lives in a static, not in the task's future or on the stack.
///
/// `Slam::new` returns the state by value, so it is built on the stack once at start and
/// moved in; the core offers only `reset` in place. A `const fn` constructor (or one that
/// fills a `&mut MaybeUninit<Slam>`) would let a big grid start life in `.bss`.
static SLAM: StaticCell<SeedSlam> = StaticCell::new();

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
    /// Worst time spent in `step`, in microseconds.
    pub max_step_us: u32,
}

/// Runs the SLAM loop for good.
#[embassy_executor::task]
pub async fn slam_task(watchdog: Peri<'static, WATCHDOG>, inputs: &'static Inputs) -> ! {
    let mut watchdog = Watchdog::new(watchdog);
    match watchdog.reset_reason() {
        Some(ResetReason::TimedOut) => defmt::warn!("slam: last reset was a watchdog timeout"),
        Some(ResetReason::Forced) => defmt::info!("slam: last reset was forced"),
        None => {}
    }

    let slam = match SeedSlam::new(SlamConfig::seed_mat(), START_POSE) {
        Ok(slam) => SLAM.init(slam),
        // The configuration is fixed at build time and tested on the host: this is a bug.
        Err(e) => defmt::panic!("slam: configuration rejected: {}", e),
    };
    defmt::info!(
        "slam: {=usize} bytes of state, start {}",
        core::mem::size_of::<SeedSlam>(),
        START_POSE
    );

    // A debugger halting the core must not trigger a reset.
    watchdog.pause_on_debug(true);
    watchdog.start(WATCHDOG_TIMEOUT);

    let reports = REPORTS.sender();
    let mut health = LoopCounters::default();
    let mut ticker = Ticker::every(TICK);
    let mut deadline = Instant::now() + TICK;
    let mut previous = Instant::now();

    loop {
        ticker.next().await;
        let started = Instant::now();

        let late = started.saturating_duration_since(deadline);
        health.max_late_us = health.max_late_us.max(micros(late));
        if late > TICK {
            health.overruns = health.overruns.wrapping_add(1);
            ticker.reset_at(started);
            deadline = started + TICK;
        } else {
            deadline += TICK;
        }

        // dt is the time actually elapsed, so a late tick integrates the right interval.
        let dt_us = micros(started.saturating_duration_since(previous));
        previous = started;

        // Each input: `None` (stale) unless its task published since the last tick.
        let mut frame = SensorFrame::empty(dt_us);
        frame.flow = inputs.flow.take();
        frame.gyro = inputs.gyro.take();
        frame.depth = inputs.depth.try_take();
        if let Some(tags) = inputs.tags.try_take() {
            frame.tags = tags;
        }

        let report = slam.step(&frame);
        health.max_step_us = health
            .max_step_us
            .max(micros(Instant::now().saturating_duration_since(started)));
        health.ticks = health.ticks.wrapping_add(1);

        watchdog.feed(WATCHDOG_TIMEOUT);
        reports.send(report);

        if health.ticks % TICKS_PER_LOG == 0 {
            log(&report, &health);
        }
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
        c.fixes_rejected_geometry + c.fixes_rejected_gate,
        c.beams_mapped,
    );
}

/// A duration in whole microseconds, saturating at `u32::MAX` (71 minutes).
fn micros(d: Duration) -> u32 {
    u32::try_from(d.as_micros()).unwrap_or(u32::MAX)
}
