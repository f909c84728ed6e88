//! Fault counters shared by every task: each task adds to its own counters, telemetry and
//! the once-a-second log read a snapshot.
//!
//! One `AtomicU32` per counter (from `portable-atomic`: the M0+ has no atomic
//! read-modify-write, so `fetch_add` runs in a short critical section). No lock is held
//! across an `await` and no task ever waits on another to count. All counters wrap.
//!
//! The sensor counters are the wire's [`SensorHealth`] field for field, built from the one
//! list in `wire` (`wire::sensor_health_counters!`); the rest are firmware detail that the
//! wire has no field for yet, logged over defmt only.

use portable_atomic::{AtomicU32, Ordering};
use wire::telemetry::SensorHealth;

/// One counter.
pub struct Counter(AtomicU32);

impl Counter {
    /// Zero.
    pub const fn new() -> Self {
        Counter(AtomicU32::new(0))
    }

    /// Adds one, wrapping.
    pub fn bump(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }

    /// Adds `n`, wrapping.
    pub fn add(&self, n: u32) {
        self.0.fetch_add(n, Ordering::Relaxed);
    }

    /// The count so far.
    pub fn get(&self) -> u32 {
        self.0.load(Ordering::Relaxed)
    }
}

/// Builds [`HealthCounters`] from the wire's list of sensor counters (the first list) and
/// the firmware's own (the rest), so a wire counter is added in `wire` alone.
macro_rules! health_counters {
    (
        [$($(#[$wire_doc:meta])* $wire:ident,)*]
        $($(#[$own_doc:meta])* $own:ident,)*
    ) => {
        /// Every fault counter on the robot.
        pub struct HealthCounters {
            $($(#[$wire_doc])* pub $wire: Counter,)*
            $($(#[$own_doc])* pub $own: Counter,)*
        }

        impl HealthCounters {
            /// All zero.
            pub const fn new() -> Self {
                HealthCounters {
                    $($wire: Counter::new(),)*
                    $($own: Counter::new(),)*
                }
            }

            /// The wire's view of the counters, for a telemetry `Health` message.
            pub fn sensor_health(&self) -> SensorHealth {
                SensorHealth {
                    $($wire: self.$wire.get(),)*
                }
            }
        }
    };
}

wire::sensor_health_counters!(
    health_counters,
    /// Gyro samples refused as implausible (the chip's invalid marker, or beyond full scale).
    gyro_implausible,
    /// Bias calibrations restarted because the robot moved during them.
    gyro_calibration_restarts,
    /// Camera frames accepted.
    camera_frames,
    /// Camera detections dropped because the core's tag list was full.
    camera_tags_dropped,
    /// Telemetry frames dropped because the link was behind (queue full).
    telemetry_dropped,
    /// Telemetry frames that could not be encoded or written.
    telemetry_errors,
    /// Telemetry frames written to the USB serial port.
    usb_frames_sent,
    /// Telemetry frames not sent over USB because no host had the device configured (or
    /// the bus was suspended): every frame, while the robot is not plugged into a PC.
    usb_no_host,
    /// Telemetry frames not sent over USB although a host was there: it was not reading
    /// (port not open), so the USB queue was full, or the frames went stale waiting.
    usb_dropped,
    /// Times the motion task stopped the motors because SLAM reports stopped coming.
    motion_halts,
    /// PWM errors setting the motor duty.
    motor_errors,
    /// Drives the guard stopped before an obstacle (each skipped its route leg).
    guard_stops,
);

impl HealthCounters {
    /// One defmt line with the counters the wire does not carry.
    pub fn log_firmware_detail(&self) {
        defmt::info!(
            "health: gyro implausible={=u32} recal={=u32} | camera ok={=u32} tags dropped={=u32} | telemetry dropped={=u32} err={=u32} | usb sent={=u32} no host={=u32} dropped={=u32} | motion halts={=u32} motor err={=u32} guard stops={=u32}",
            self.gyro_implausible.get(),
            self.gyro_calibration_restarts.get(),
            self.camera_frames.get(),
            self.camera_tags_dropped.get(),
            self.telemetry_dropped.get(),
            self.telemetry_errors.get(),
            self.usb_frames_sent.get(),
            self.usb_no_host.get(),
            self.usb_dropped.get(),
            self.motion_halts.get(),
            self.motor_errors.get(),
            self.guard_stops.get(),
        );
    }
}

/// The one set of counters.
pub static HEALTH: HealthCounters = HealthCounters::new();
