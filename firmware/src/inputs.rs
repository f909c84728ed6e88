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
//!   so a scan is mapped once and a tick with no new scan sees `None`.
//!
//! In every case "nothing since the last tick" comes out as `None`, which is exactly what
//! [`slam_core::SensorFrame`] calls stale. Until the drivers are wired, no task writes
//! here, so every input is stale on every tick and the core counts it.
//!
//! All four use `CriticalSectionRawMutex` so that a driver may later publish from an
//! interrupt executor or the second core without changing this file.

use core::cell::Cell;

use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use slam_core::{DepthScan, FlowDelta, GyroRate, TagDetections};

/// Optical flow summed since the SLAM tick last took it.
pub struct FlowInbox(Mutex<CriticalSectionRawMutex, Cell<Option<FlowDelta>>>);

impl FlowInbox {
    /// An empty inbox.
    pub const fn new() -> Self {
        FlowInbox(Mutex::new(Cell::new(None)))
    }

    #[expect(
        dead_code,
        reason = "the flow task calls it once the PMW3901 driver is wired"
    )]
    /// Adds one sensor read's motion (saturating: a flow sensor cannot move 2^31 counts in
    /// a tick, so saturation means a fault the core's gates will see, not a wrap).
    pub fn add(&self, delta: FlowDelta) {
        self.0.lock(|sum| {
            let old = sum.get().unwrap_or_default();
            sum.set(Some(FlowDelta {
                forward_counts: old.forward_counts.saturating_add(delta.forward_counts),
                right_counts: old.right_counts.saturating_add(delta.right_counts),
            }));
        });
    }

    /// The motion since the last call, or `None` (stale) if no reading arrived.
    pub fn take(&self) -> Option<FlowDelta> {
        self.0.lock(Cell::take)
    }
}

/// Sum and count of yaw-rate samples, for a mean over the tick.
#[derive(Clone, Copy, Default)]
struct RateSum {
    /// Sum of samples, in millidegrees per second.
    total_mdps: i64,
    /// Number of samples summed.
    samples: u32,
}

/// Gyro yaw-rate samples averaged since the SLAM tick last took them.
pub struct GyroInbox(Mutex<CriticalSectionRawMutex, Cell<Option<RateSum>>>);

impl GyroInbox {
    /// An empty inbox.
    pub const fn new() -> Self {
        GyroInbox(Mutex::new(Cell::new(None)))
    }

    #[expect(
        dead_code,
        reason = "the IMU task calls it once the IMU driver is wired"
    )]
    /// Adds one bias-corrected yaw-rate sample.
    pub fn add(&self, rate: GyroRate) {
        self.0.lock(|sum| {
            let old = sum.get().unwrap_or_default();
            sum.set(Some(RateSum {
                total_mdps: old.total_mdps.saturating_add(rate.rate_mdps as i64),
                samples: old.samples.saturating_add(1),
            }));
        });
    }

    /// The mean rate since the last call, or `None` (stale) if no sample arrived.
    pub fn take(&self) -> Option<GyroRate> {
        let sum = self.0.lock(Cell::take)?;
        if sum.samples == 0 {
            return None;
        }
        let mean = sum.total_mdps / sum.samples as i64;
        Some(GyroRate {
            rate_mdps: mean.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        })
    }
}

/// The newest depth scan not yet mapped.
pub type DepthInbox = Signal<CriticalSectionRawMutex, DepthScan>;

/// The tags in the camera's newest picture not yet used.
pub type TagInbox = Signal<CriticalSectionRawMutex, TagDetections>;

/// Every input of the SLAM tick, one inbox per sensor.
pub struct Inputs {
    /// Written by [`crate::sensors::flow`].
    pub flow: FlowInbox,
    /// Written by [`crate::sensors::imu`].
    pub gyro: GyroInbox,
    /// Written by [`crate::sensors::depth`].
    pub depth: DepthInbox,
    /// Written by [`crate::sensors::camera`].
    pub tags: TagInbox,
}

impl Inputs {
    /// All inboxes empty: every input stale.
    pub const fn new() -> Self {
        Inputs {
            flow: FlowInbox::new(),
            gyro: GyroInbox::new(),
            depth: Signal::new(),
            tags: Signal::new(),
        }
    }
}

/// The one set of inboxes. A `static` of `Sync` embassy-sync primitives, not `static mut`.
pub static INPUTS: Inputs = Inputs::new();
