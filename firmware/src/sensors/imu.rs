//! IMU task (I2C1, data-ready on GP7): adds each bias-corrected yaw-rate sample to
//! [`GyroInbox`]; the SLAM tick takes their mean.

use embassy_rp::gpio::{Input, Pull};
use embassy_rp::i2c::{self, I2c};

use crate::board::{ImuPins, IMU_I2C_HZ};
use crate::inputs::GyroInbox;
use crate::Irqs;

/// Runs the IMU.
///
/// Placeholder until the `drivers` crate's IMU driver lands: the bus is up, nothing is
/// published, so every tick's gyro is stale.
///
/// Wiring the driver: `drivers::imu::Icm42688::new(i2c, GyroConfig)` then
/// `init(&mut embassy_time::Delay)`, estimate the bias while standing still at start
/// (`drivers::imu` bias helpers, then `set_bias`), then loop on `int.wait_for_high()` (or
/// a `Ticker` at the gyro's output rate), `read_yaw_rate()` and `rates.add(..)` it in
/// millidegrees per second, positive clockwise seen from above.
#[embassy_executor::task]
pub async fn imu_task(pins: ImuPins, irqs: Irqs, rates: &'static GyroInbox) -> ! {
    let mut config = i2c::Config::default();
    config.frequency = IMU_I2C_HZ;
    let _i2c = I2c::new_async(pins.i2c, pins.scl, pins.sda, irqs, config);
    let _int = Input::new(pins.int, Pull::None);
    let _ = rates;
    defmt::warn!("imu: IMU driver not wired; gyro input stays stale");
    super::park().await
}
