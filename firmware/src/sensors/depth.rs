//! VL53L5CX depth sensor task (I2C0): publishes one [`DepthScan`](slam_core::DepthScan) per
//! ranging frame into [`DepthInbox`].

use embassy_rp::gpio::{Level, Output};
use embassy_rp::i2c::{self, I2c};

use crate::board::{DepthSensorPins, DEPTH_I2C_HZ};
use crate::inputs::DepthInbox;
use crate::Irqs;

/// Runs the depth sensor.
///
/// Placeholder until the `drivers` crate's VL53L5CX driver lands: the bus is up and the
/// sensor enabled, but nothing is published, so every tick's depth is stale.
///
/// Wiring the driver: `drivers::depth` has the zone reduction (`reduce` of a `ZoneResult`
/// to the core's 8 beams) but not yet the bus layer. That layer takes `i2c` (an
/// `embedded-hal-async` `I2c`), uploads the sensor's firmware, starts 8x8 ranging at
/// 10 Hz or faster; for each frame, `reduce` it and call `scans.signal(scan)`, a zone
/// without a valid target being `None`. A bus error restarts the sensor, never panics.
#[embassy_executor::task]
pub async fn depth_task(pins: DepthSensorPins, irqs: Irqs, scans: &'static DepthInbox) -> ! {
    let mut config = i2c::Config::default();
    config.frequency = DEPTH_I2C_HZ;
    let _i2c = I2c::new_async(pins.i2c, pins.scl, pins.sda, irqs, config);
    // LPn high: the sensor answers on I2C.
    let _lpn = Output::new(pins.lpn, Level::High);
    let _ = scans;
    defmt::warn!("depth: VL53L5CX driver not wired; depth input stays stale");
    super::park().await
}
