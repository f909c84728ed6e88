//! One task per sensor. Each owns its bus and pins (from [`crate::board`]) and publishes
//! readings into its inbox in [`crate::inputs`].
//!
//! Each task owns its bus. The drivers (`drivers` crate) see only `embedded-hal-async`
//! traits: the flow and IMU buses sit in a `StaticCell<Mutex<..>>` and the driver gets an
//! `embassy-embedded-hal` `SpiDevice`/`I2cDevice`, so a second device can join a bus
//! without touching the first. No sensor fault panics: a bus error, a timeout
//! (`embassy_time::with_timeout`) or an implausible value is counted in
//! [`crate::health::HEALTH`] and the input goes stale, which the SLAM tick counts in
//! `Counters::{flow,gyro,depth}_stale`.
//!
//! The flow, IMU and depth tasks share one loop ([`supervise`]): start the part with a
//! doubling back-off, read it at its rate until too many reads in a row fail, start it
//! again. Each supplies its own start-up attempt, read and timings.

pub mod camera;
pub mod depth;
pub mod flow;
pub mod imu;
pub mod supervise;

/// Parks a placeholder task for good, keeping the hardware it owns alive and configured.
pub(crate) async fn park() -> ! {
    core::future::pending::<()>().await;
    // `pending` never resolves; this only satisfies the `!` return type.
    #[allow(clippy::empty_loop)]
    loop {}
}
