//! The sensor fault counters: listed once, in wire order, for the wire's [`SensorHealth`]
//! and for the firmware's atomic counters alike.

use serde::{Deserialize, Serialize};

/// Hands a macro the sensor health counters, in wire order, each as its doc comment and
/// field name: `$callback! { [ $( #[doc = ...] name, )* ] extra tokens }`.
///
/// [`SensorHealth`] is built from this list, and so are the firmware's atomic counters
/// (with its own counters passed as the extra tokens), so a counter is added with one edit
/// here. Adding one changes the `Health` layout: bump
/// [`WIRE_VERSION`](crate::telemetry::WIRE_VERSION) with it.
#[macro_export]
macro_rules! sensor_health_counters {
    ($callback:ident $(, $($extra:tt)*)?) => {
        $callback! {
            [
                /// Depth scans that did not arrive in time.
                depth_timeouts,
                /// I2C errors talking to the depth sensor.
                depth_bus_errors,
                /// Flow readings dropped because the surface quality was too low.
                flow_no_surface,
                /// Flow readings dropped as implausible.
                flow_outliers,
                /// SPI errors and timeouts talking to the flow sensor, in start-up or reads.
                flow_bus_errors,
                /// I2C errors and timeouts talking to the gyro (the IMU).
                gyro_bus_errors,
                /// Camera link frames that failed COBS, CRC or parsing, plus UART receive
                /// errors.
                camera_bad_frames,
                /// SLAM ticks that started more than one period late.
                tick_overruns,
                /// Times the watchdog was fed.
                watchdog_feeds,
                /// Depth sensor start-ups that failed (power-up, firmware upload or
                /// configuration); each is retried after a back-off. Climbing with no depth
                /// scans ever arriving: the sensor never started.
                depth_start_failures,
                /// Flow sensor start-ups that failed; each is retried after a back-off.
                flow_start_failures,
                /// Gyro start-ups that failed; each is retried after a back-off.
                gyro_start_failures,
            ]
            $($($extra)*)?
        }
    };
}

macro_rules! sensor_health {
    ([$($(#[$doc:meta])* $name:ident,)*]) => {
        /// Per-sensor fault counters since start, filled in by the firmware's tasks: the
        /// `Health` message, each a `u32` varint in this order.
        ///
        /// All wrap at `u32::MAX`. A counter that climbs says which wire to check.
        #[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Serialize, Deserialize)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub struct SensorHealth {
            $($(#[$doc])* pub $name: u32,)*
        }
    };
}

sensor_health_counters!(sensor_health);
