//! Fault counters shared by every task: each task adds to its own counters, telemetry and
//! the once-a-second log read a snapshot.
//!
//! One `AtomicU32` per counter (from `portable-atomic`: the M0+ has no atomic
//! read-modify-write, so `fetch_add` runs in a short critical section). No lock is held
//! across an `await` and no task ever waits on another to count. All counters wrap.
//!
//! The first twelve are the wire's [`SensorHealth`] field for field (the wire calls the
//! init failures start failures); the rest are firmware detail that the wire has no field
//! for yet, logged over defmt only.

use portable_atomic::{AtomicU32, Ordering};
use slam_core::telemetry::SensorHealth;

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

/// Every fault counter on the robot.
pub struct HealthCounters {
    /// Depth frames that did not arrive in time.
    pub depth_timeouts: Counter,
    /// I2C errors talking to the depth sensor.
    pub depth_bus_errors: Counter,
    /// Flow reads whose surface check failed (the tick's flow went stale).
    pub flow_no_surface: Counter,
    /// Flow reads dropped as outliers (the tick's flow went stale).
    pub flow_outliers: Counter,
    /// SPI errors and timeouts talking to the flow sensor, in start-up or reads.
    pub flow_bus_errors: Counter,
    /// I2C errors and timeouts talking to the IMU (the wire calls it the gyro).
    pub gyro_bus_errors: Counter,
    /// Camera link frames that failed COBS, CRC or parsing, plus UART receive errors.
    pub camera_bad_frames: Counter,
    /// SLAM ticks that started more than one period late.
    pub tick_overruns: Counter,
    /// Times the SLAM loop fed the hardware watchdog.
    pub watchdog_feeds: Counter,

    /// Depth sensor start-ups that failed (power-up, firmware upload or configuration);
    /// each is retried after a back-off.
    pub depth_init_failures: Counter,
    /// Flow sensor start-ups that failed (any reason); each is retried after a back-off.
    pub flow_init_failures: Counter,
    /// IMU start-ups that failed (any reason); each is retried after a back-off.
    pub gyro_init_failures: Counter,
    /// Gyro samples refused as implausible (the chip's invalid marker, or beyond full scale).
    pub gyro_implausible: Counter,
    /// Bias calibrations restarted because the robot moved during them.
    pub gyro_calibration_restarts: Counter,
    /// Camera frames accepted.
    pub camera_frames: Counter,
    /// Camera detections dropped because the core's tag list was full.
    pub camera_tags_dropped: Counter,
    /// Telemetry frames dropped because the link was behind (queue full).
    pub telemetry_dropped: Counter,
    /// Telemetry frames that could not be encoded or written.
    pub telemetry_errors: Counter,
    /// Telemetry frames written to the USB serial port.
    pub usb_frames_sent: Counter,
    /// Telemetry frames not sent over USB because no host had the device configured (or
    /// the bus was suspended): every frame, while the robot is not plugged into a PC.
    pub usb_no_host: Counter,
    /// Telemetry frames not sent over USB although a host was there: it was not reading
    /// (port not open), so the USB queue was full, or the frames went stale waiting.
    pub usb_dropped: Counter,
    /// Times the motion task stopped the motors because SLAM reports stopped coming.
    pub motion_halts: Counter,
    /// PWM errors setting the motor duty.
    pub motor_errors: Counter,
}

impl HealthCounters {
    /// All zero.
    pub const fn new() -> Self {
        HealthCounters {
            depth_timeouts: Counter::new(),
            depth_bus_errors: Counter::new(),
            flow_no_surface: Counter::new(),
            flow_outliers: Counter::new(),
            flow_bus_errors: Counter::new(),
            gyro_bus_errors: Counter::new(),
            camera_bad_frames: Counter::new(),
            tick_overruns: Counter::new(),
            watchdog_feeds: Counter::new(),
            depth_init_failures: Counter::new(),
            flow_init_failures: Counter::new(),
            gyro_init_failures: Counter::new(),
            gyro_implausible: Counter::new(),
            gyro_calibration_restarts: Counter::new(),
            camera_frames: Counter::new(),
            camera_tags_dropped: Counter::new(),
            telemetry_dropped: Counter::new(),
            telemetry_errors: Counter::new(),
            usb_frames_sent: Counter::new(),
            usb_no_host: Counter::new(),
            usb_dropped: Counter::new(),
            motion_halts: Counter::new(),
            motor_errors: Counter::new(),
        }
    }

    /// The wire's view of the counters, for a telemetry `Health` message.
    pub fn sensor_health(&self) -> SensorHealth {
        SensorHealth {
            depth_timeouts: self.depth_timeouts.get(),
            depth_bus_errors: self.depth_bus_errors.get(),
            flow_no_surface: self.flow_no_surface.get(),
            flow_outliers: self.flow_outliers.get(),
            flow_bus_errors: self.flow_bus_errors.get(),
            gyro_bus_errors: self.gyro_bus_errors.get(),
            camera_bad_frames: self.camera_bad_frames.get(),
            tick_overruns: self.tick_overruns.get(),
            watchdog_feeds: self.watchdog_feeds.get(),
            depth_start_failures: self.depth_init_failures.get(),
            flow_start_failures: self.flow_init_failures.get(),
            gyro_start_failures: self.gyro_init_failures.get(),
        }
    }

    /// One defmt line with the counters the wire does not carry.
    pub fn log_firmware_detail(&self) {
        defmt::info!(
            "health: gyro implausible={=u32} recal={=u32} | camera ok={=u32} tags dropped={=u32} | telemetry dropped={=u32} err={=u32} | usb sent={=u32} no host={=u32} dropped={=u32} | motion halts={=u32} motor err={=u32}",
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
        );
    }
}

/// The one set of counters.
pub static HEALTH: HealthCounters = HealthCounters::new();
