//! One task per sensor. Each owns its bus and pins (from [`crate::board`]) and publishes
//! readings into its inbox in [`crate::inputs`].
//!
//! The drivers are being written in the `drivers` crate; until they land, each task brings
//! its bus up (so the wiring and the interrupt bindings are checked by the compiler and the
//! pins sit in a defined state) and then parks without publishing. The SLAM tick therefore
//! sees every input as stale, which it counts in `Counters::{flow,gyro,depth}_stale`.
//!
//! Each bus has a single device on it, so the task owns the bus outright. If a second
//! device joins a bus, the bus moves into a `StaticCell<Mutex<..>>` and each driver gets an
//! `I2cDevice`/`SpiDevice` from `embassy-embedded-hal`.

pub mod camera;
pub mod depth;
pub mod flow;
pub mod imu;

/// Parks a placeholder task for good, keeping the hardware it owns alive and configured.
pub(crate) async fn park() -> ! {
    core::future::pending::<()>().await;
    // `pending` never resolves; this only satisfies the `!` return type.
    #[allow(clippy::empty_loop)]
    loop {}
}
