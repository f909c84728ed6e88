//! The hand-over points between the sensor tasks (writers) and the SLAM tick (the reader).
//!
//! Each input gets the embassy-sync tool that matches its meaning:
//!
//! - **Flow** and **gyro** are *integrated* over the tick: every sample matters, and the
//!   tick wants their sum (flow) or mean (gyro) since it last looked. They sit in a blocking
//!   [`Mutex`] round a `Cell` accumulator: the sensor task adds, the tick takes and clears,
//!   each inside a short critical section. A `Signal` would drop all but the last sample
//!   between two ticks; a `Channel` would need sizing for the worst burst and a drain loop.
//! - **Depth** and **camera tags** are *snapshots*: a newer scan or picture supersedes the
//!   older one, so a [`Signal`] ("the latest value wins") fits. The tick uses `try_take`,
//!   so a scan is mapped once and a tick with no new scan sees `None`. A picture carries
//!   the instant its frame arrived ([`TagPicture`]): the camera keeps its own schedule, so
//!   the tick tells the core how old the tags are.
//!
//! The gyro's mean comes with the instant its newest sample was read ([`GyroMean`]): the
//! samples are read on the IMU's own 200 Hz grid, so the tick's odometry reaches that
//! instant, a few milliseconds before the tick wakes, and the tick counts the tags' and
//! the scan's ages back from it (the core carries a sighting from its moment to the
//! frame's pose by the odometry, which must end where the ages start).
//!
//! In every case "nothing since the last tick" comes out as `None`, which is exactly what
//! [`slam_core::SensorFrame`] calls stale, and the core counts it. Flow is also stale when
//! any read in the tick failed ([`FlowInbox::poison`]): a sum missing a read is wrong. A
//! lost gyro sample does not poison the tick: the mean of the others is still the mean.
//!
//! Besides the tick's inputs, the gyro's own integral ([`YawIntegrator`]) and a
//! "calibrated" signal go to the motion task.
//!
//! All four use `CriticalSectionRawMutex` so that a driver may later publish from an
//! interrupt executor or the second core without changing this file.

use core::cell::Cell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use embassy_time::Instant;
use portable_atomic::AtomicBool;
use slam_core::{DepthScan, Doubt, FlowDelta, GyroRate, TagDetections};

/// Flow since the tick last looked: the sum of good reads, and whether a read failed.
#[derive(Clone, Copy, Default)]
struct FlowSum {
    /// Sum of the good reads, or `None` if none arrived.
    sum: Option<FlowDelta>,
    /// A read failed (bus error, timeout, no surface, outlier) since the tick last looked.
    poisoned: bool,
}

/// Optical flow summed since the SLAM tick last took it.
///
/// A failed read *poisons* the tick: its motion is lost, so the sum of the other reads
/// would understate the tick's travel. The whole tick's flow is then stale, which the core
/// counts (`flow_stale`) and which matches the simulator's model (a tick with a bad
/// surface has no flow at all).
pub struct FlowInbox(Mutex<CriticalSectionRawMutex, Cell<FlowSum>>);

impl FlowInbox {
    /// An empty inbox.
    pub const fn new() -> Self {
        FlowInbox(Mutex::new(Cell::new(FlowSum {
            sum: None,
            poisoned: false,
        })))
    }

    /// Adds one sensor read's motion (saturating: a flow sensor cannot move 2^31 counts in
    /// a tick, so saturation means a fault the core's gates will see, not a wrap).
    pub fn add(&self, delta: FlowDelta) {
        self.0.lock(|state| {
            let mut s = state.get();
            let old = s.sum.unwrap_or_default();
            s.sum = Some(FlowDelta {
                forward_counts: old.forward_counts.saturating_add(delta.forward_counts),
                right_counts: old.right_counts.saturating_add(delta.right_counts),
            });
            state.set(s);
        });
    }

    /// Marks this tick's flow as unusable: a read was lost.
    pub fn poison(&self) {
        self.0.lock(|state| {
            let mut s = state.get();
            s.poisoned = true;
            state.set(s);
        });
    }

    /// The motion since the last call, or `None` (stale) if no reading arrived or one
    /// failed.
    pub fn take(&self) -> Option<FlowDelta> {
        let s = self.0.lock(Cell::take);
        if s.poisoned {
            None
        } else {
            s.sum
        }
    }
}

/// Sum and count of yaw-rate samples, for a mean over the tick.
#[derive(Clone, Copy)]
struct RateSum {
    /// Sum of samples, in millidegrees per second.
    total_mdps: i64,
    /// Number of samples summed.
    samples: u32,
    /// When the newest sample was read.
    newest: Instant,
}

/// The gyro's mean rate over a tick and the instant its newest sample was read: the
/// moment the tick's odometry reaches.
#[derive(Clone, Copy)]
pub struct GyroMean {
    /// The mean of the tick's samples.
    pub rate: GyroRate,
    /// When the newest of them was read.
    pub newest: Instant,
}

/// Gyro yaw-rate samples averaged since the SLAM tick last took them.
pub struct GyroInbox(Mutex<CriticalSectionRawMutex, Cell<Option<RateSum>>>);

impl GyroInbox {
    /// An empty inbox.
    pub const fn new() -> Self {
        GyroInbox(Mutex::new(Cell::new(None)))
    }

    /// Adds one bias-corrected yaw-rate sample, read at `at`.
    pub fn add(&self, rate: GyroRate, at: Instant) {
        self.0.lock(|sum| {
            let (total_mdps, samples) = sum.get().map_or((0, 0), |s| (s.total_mdps, s.samples));
            sum.set(Some(RateSum {
                total_mdps: total_mdps.saturating_add(rate.rate_mdps as i64),
                samples: samples.saturating_add(1),
                newest: at,
            }));
        });
    }

    /// The mean rate since the last call and when its newest sample was read, or `None`
    /// (stale) if no sample arrived.
    pub fn take(&self) -> Option<GyroMean> {
        let sum = self.0.lock(Cell::take)?;
        if sum.samples == 0 {
            return None;
        }
        let mean = sum.total_mdps / sum.samples as i64;
        Some(GyroMean {
            rate: GyroRate {
                rate_mdps: mean.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            },
            newest: sum.newest,
        })
    }
}

/// The robot's heading as the gyro alone integrates it, for the motion task's turns.
///
/// Kept apart from the SLAM pose on purpose: turns are ended by the gyro, as on the real
/// robot, and must not jump when a tag fix corrects the pose. In nanodegrees
/// (millidegrees per second times microseconds), so integration never rounds; an `i64`
/// holds 9 x 10^9 degrees of turning.
pub struct YawIntegrator(Mutex<CriticalSectionRawMutex, Cell<i64>>);

impl YawIntegrator {
    /// Zero yaw.
    pub const fn new() -> Self {
        YawIntegrator(Mutex::new(Cell::new(0)))
    }

    /// Integrates `rate` over `dt_us` microseconds.
    pub fn integrate(&self, rate: GyroRate, dt_us: u32) {
        let step = i64::from(rate.rate_mdps) * i64::from(dt_us);
        self.0.lock(|yaw| yaw.set(yaw.get().saturating_add(step)));
    }

    /// Turned since start, in millidegrees, positive clockwise seen from above.
    pub fn yaw_mdeg(&self) -> i64 {
        self.0.lock(Cell::get) / 1_000_000
    }
}

/// The newest depth scan not yet mapped.
pub type DepthInbox = Signal<CriticalSectionRawMutex, DepthReading>;

/// One depth scan and when the sensor had it ready.
#[derive(Clone, Copy)]
pub struct DepthReading {
    /// The 8 beams.
    pub scan: DepthScan,
    /// When core 1 saw the sensor's data-ready flag (polled every 5 ms, so up to 5 ms
    /// after the frame ended): the SLAM tick sets the frame's `depth_age_us` from it.
    pub measured: Instant,
    /// What the depth task made of the scan against the frames before it
    /// (`slam_core::depth_step`): the frame's `depth_doubt`.
    pub doubt: Option<Doubt>,
}

/// One camera picture's tags and when they reached the robot.
#[derive(Clone)]
pub struct TagPicture {
    /// The tags read (empty: none in view).
    pub tags: TagDetections,
    /// When the co-processor began sending the picture's frame: its arrival at the camera
    /// task less its time on the line. Up to a tick before the SLAM tick that uses it,
    /// which sets the frame's `tags_age_us` from it.
    pub sent: Instant,
}

/// The camera's newest picture not yet used.
pub type TagInbox = Signal<CriticalSectionRawMutex, TagPicture>;

/// Every input of the SLAM tick, one inbox per sensor, plus the gyro's own yaw for the
/// motion task.
pub struct Inputs {
    /// Written by [`crate::sensors::flow`].
    pub flow: FlowInbox,
    /// Written by [`crate::sensors::imu`].
    pub gyro: GyroInbox,
    /// Written by [`crate::sensors::depth`].
    pub depth: DepthInbox,
    /// Written by [`crate::sensors::camera`].
    pub tags: TagInbox,
    /// Written by [`crate::sensors::imu`], read by [`crate::motion`].
    pub yaw: YawIntegrator,
    /// Raised once by [`crate::sensors::imu`] when the gyro bias is calibrated and yaw
    /// integration has begun; [`crate::motion`] waits for it before moving.
    pub gyro_ready: Signal<CriticalSectionRawMutex, ()>,
    /// Raised by the SLAM tick when what the depth frames' steps summed to is to be
    /// forgotten (`Slam::depth_steps_void`: a tag vouched for the ranges, or the gyro is
    /// doubted), taken by [`crate::sensors::depth`].
    pub depth_steps_void: AtomicBool,
}

impl Inputs {
    /// All inboxes empty: every input stale.
    pub const fn new() -> Self {
        Inputs {
            flow: FlowInbox::new(),
            gyro: GyroInbox::new(),
            depth: Signal::new(),
            tags: Signal::new(),
            yaw: YawIntegrator::new(),
            gyro_ready: Signal::new(),
            depth_steps_void: AtomicBool::new(false),
        }
    }
}

/// The one set of inboxes. A `static` of `Sync` embassy-sync primitives, not `static mut`.
pub static INPUTS: Inputs = Inputs::new();
