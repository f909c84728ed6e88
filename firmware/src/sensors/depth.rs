//! VL53L5CX depth sensor (I2C0 at 400 kHz, SDA GP4, SCL GP5, LPn GP6, address 0x29):
//! publishes one [`DepthScan`](slam_core::DepthScan) per ranging frame into [`DepthInbox`].
//!
//! # With the `vl53l5cx` feature (on by default: see `Cargo.toml`)
//!
//! The bus layer is ST's Ultra Lite Driver through the `vl53l5cx-uld` crate. Its API is
//! blocking (an I2C transfer, or a firmware upload of about 2 s at 400 kHz, holds the
//! caller), so it runs on the RP2040's **second core** under its own executor
//! (`start_core1`), where it can block without stalling the SLAM loop:
//!
//! - core 1 (`ranging_task`): powers the sensor up through LPn, runs the ULD's `init`
//!   (which uploads the sensor's firmware), sets 8x8 zones at `RANGING_HZ` in continuous
//!   mode, starts ranging, then polls data-ready every `POLL_PERIOD` and hands each
//!   frame's distances and target statuses, with the instant it was seen ready (the SLAM
//!   tick maps the scan at the pose of that moment), to core 0 through `ZONES` (a `Signal`: the
//!   newest frame wins; it is `CriticalSectionRawMutex`-guarded, which on the RP2040 is a
//!   hardware spinlock shared by both cores). A failed start-up is counted in
//!   `depth_start_failures` (a sensor that never
//!   starts shows as that count climbing), a read error in `depth_bus_errors`; start-up
//!   is retried with a doubling back-off, and after
//!   `ERRORS_BEFORE_RESTART` read errors in a row the sensor is power-cycled (LPn) and
//!   started again. The emulator's fault run (`cargo xtask test`) exercises all of this
//!   with the sensor NACKing for 3 s.
//! - core 0 (`depth_task`): waits for each frame with a timeout, reduces it to the core's
//!   8 beams with `drivers::depth::reduce` (middle rows, nearest valid zone per column),
//!   holds it to the frames before over the gyro's own integral (`slam_core::depth_step`:
//!   every range stepping together, a frame given again late) and publishes the scan with
//!   that verdict. No frame within `FRAME_TIMEOUT` once ranging has begun counts a
//!   `depth_timeout` (this also catches a core 1 stuck in a blocking transfer); the depth
//!   input is then stale until frames return.
//!
//! # Without it
//!
//! The bus is brought up, the sensor enabled and nothing is published: the depth input
//! stays stale on every tick (the core counts `depth_stale`) until a bus layer exists.

use embassy_rp::i2c;

use crate::board::{DepthSensorPins, DEPTH_I2C_HZ};
#[cfg(not(feature = "vl53l5cx"))]
use crate::inputs::DepthInbox;
#[cfg(feature = "vl53l5cx")]
use crate::inputs::DepthReading;

#[cfg(feature = "vl53l5cx")]
pub use ranging::{depth_task, start_core1};
#[cfg(not(feature = "vl53l5cx"))]
pub use stale::depth_task;

#[cfg(feature = "vl53l5cx")]
mod ranging {
    use drivers::depth::{reduce, DepthConfig, ZoneResult};
    use embassy_executor::Executor;
    use embassy_rp::gpio::Output;
    use embassy_rp::i2c::{Blocking, I2c};
    use embassy_rp::multicore::{spawn_core1, Stack};
    use embassy_rp::peripherals::I2C0;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::signal::Signal;
    use embassy_time::{with_timeout, Delay, Duration, Instant, Timer};
    use portable_atomic::Ordering;
    use slam_core::depth_step::{DepthSteps, ZoneTurn};
    use slam_core::{Angle, DepthScan};
    use static_cell::StaticCell;
    use vl53l5cx_uld::{RangingMode, Resolution, Vl53l5cx};

    use super::{bus_config, DepthReading, DepthSensorPins};
    use crate::inputs::Inputs;
    use crate::health::HEALTH;
    use crate::sensors::supervise::{Pace, Read, StartFailure, Supervised, Supervisor};

    /// The ULD's calls back into Rust for I2C and delays, for exactly these bus and delay
    /// types. The one place this crate allows `unsafe`: the macro defines the
    /// `#[no_mangle] extern "C"` functions ST's C code links against.
    #[allow(unsafe_code)]
    mod platform {
        use embassy_rp::i2c::{Blocking, I2c};
        use embassy_rp::peripherals::I2C0;
        use embassy_time::Delay;

        vl53l5cx_uld::bind_platform_driver!(I2c<'static, I2C0, Blocking>, Delay);
    }

    /// Frames per second: 15 Hz is the 8x8 maximum, so every 10 Hz SLAM tick sees a new
    /// frame (the newest wins).
    pub const RANGING_HZ: u8 = 15;

    /// No frame for this long, once ranging has started, is a timeout (four frame periods).
    const FRAME_TIMEOUT: Duration = Duration::from_millis(270);

    /// How often core 1 asks the sensor whether a frame is ready (one 4-byte read).
    const POLL_PERIOD: Duration = Duration::from_millis(5);

    /// First wait after a failed start-up; doubled after each failure up to
    /// [`MAX_BACKOFF`].
    const FIRST_BACKOFF: Duration = Duration::from_millis(200);

    /// Longest wait between two start-up attempts.
    const MAX_BACKOFF: Duration = Duration::from_secs(10);

    /// Read errors in a row after which the sensor is power-cycled and started again.
    const ERRORS_BEFORE_RESTART: u32 = 10;

    /// Core 1's start-up and polling: a pause of [`POLL_PERIOD`] before each poll, as a
    /// blocking frame read-out may take longer than a period.
    static SUPERVISOR: Supervisor = Supervisor {
        first_backoff: FIRST_BACKOFF,
        max_backoff: MAX_BACKOFF,
        pace: Pace::After(POLL_PERIOD),
        errors_before_restart: ERRORS_BEFORE_RESTART,
        start_failures: &HEALTH.depth_start_failures,
        bus_errors: &HEALTH.depth_bus_errors,
    };

    /// LPn low this long resets the sensor's I2C interface and firmware state.
    const LPN_OFF: Duration = Duration::from_millis(10);

    /// Core 1's stack, in bytes: the ULD returns a 1.2 KB result struct by value and its
    /// calls nest a few levels. Every emulated run checks that the deepest write stays
    /// within half of it, and `cargo xtask bench` prints how deep that is.
    const CORE1_STACK_BYTES: usize = 4 * 1024;

    /// Zone rows feeding the beams: the two middle rows (see `drivers::depth`).
    const ROWS: DepthConfig = DepthConfig::MIDDLE_ROWS;

    /// The newest frame from core 1, for core 0, with when it was ready. A `Signal`: the
    /// latest frame wins.
    pub static ZONES: Signal<CriticalSectionRawMutex, (ZoneResult, Instant)> = Signal::new();

    static CORE1_STACK: StaticCell<Stack<CORE1_STACK_BYTES>> = StaticCell::new();
    static CORE1_EXECUTOR: StaticCell<Executor> = StaticCell::new();

    type Sensor = Vl53l5cx<I2c<'static, I2C0, Blocking>, Delay, Output<'static>>;

    /// Brings up I2C0 in blocking mode and LPn (low: sensor off) and starts core 1 running
    /// [`ranging_task`]. The bus and pins are core 1's from here on.
    pub fn start_core1(pins: DepthSensorPins) {
        let i2c = I2c::new_blocking(pins.i2c, pins.scl, pins.sda, bus_config());
        // LPn low: the sensor starts powered down; core 1 enables it.
        let lpn = Output::new(pins.lpn, embassy_rp::gpio::Level::Low);
        let stack = CORE1_STACK.init(Stack::new());
        spawn_core1(pins.core1, stack, move || {
            let executor = CORE1_EXECUTOR.init(Executor::new());
            executor.run(|spawner| spawner.spawn(defmt::unwrap!(ranging_task(i2c, lpn))))
        });
    }

    /// Core 1: starts the sensor and hands every frame to core 0, for good.
    #[embassy_executor::task]
    async fn ranging_task(i2c: I2c<'static, I2C0, Blocking>, lpn: Output<'static>) -> ! {
        let mut sensor: Sensor = Vl53l5cx::new(i2c, Delay).with_lpn_pin(lpn);
        SUPERVISOR.run(&mut sensor).await
    }

    /// One start-up attempt; on failure, the step that failed.
    async fn configure(sensor: &mut Sensor) -> Result<(), &'static str> {
        sensor.lpn_disable().map_err(|_| "LPn low")?;
        Timer::after(LPN_OFF).await;
        sensor.lpn_enable().map_err(|_| "LPn high")?;
        Timer::after(LPN_OFF).await;
        sensor.init().map_err(|_| "init (firmware upload)")?;
        sensor
            .set_resolution(Resolution::Res8x8)
            .map_err(|_| "resolution")?;
        sensor
            .set_ranging_frequency_hz(RANGING_HZ)
            .map_err(|_| "frequency")?;
        sensor
            .set_ranging_mode(RangingMode::Continuous)
            .map_err(|_| "ranging mode")?;
        sensor.start_ranging().map_err(|_| "start ranging")
    }

    impl Supervised for Sensor {
        /// Power-cycles the sensor (LPn) and configures it.
        async fn try_start(&mut self) -> Result<(), StartFailure> {
            configure(self).await.map_err(|step| {
                defmt::warn!("depth: start-up failed at {=str}", step);
                StartFailure::Other
            })
        }

        fn started(&self) {
            defmt::info!("depth: VL53L5CX ranging 8x8 at {=u8} Hz", RANGING_HZ);
        }

        /// Asks whether a frame is ready and, if so, hands it to core 0 through [`ZONES`].
        async fn read(&mut self) -> Read {
            let Ok(ready) = self.check_data_ready() else {
                return Read::BusError;
            };
            if !ready {
                return Read::NotReady;
            }
            // The frame ended at most one poll period ago; its read-out takes a few ms more.
            let measured = Instant::now();
            let Ok(data) = self.get_ranging_data() else {
                return Read::BusError;
            };
            // One target per zone (the crate's default), so zone i is entry i; a zone with
            // no target has no valid entry.
            let zones = ZoneResult::from_frame(
                data.distance_mm,
                data.target_status,
                &data.nb_target_detected,
            );
            ZONES.signal((zones, measured));
            Read::Answered
        }

        /// No `stop_ranging` first: the power cycle that follows stops the sensor anyway, and
        /// on a sensor that is not answering the ULD would wait out its 5 s timeout for a
        /// stop that never arrives, delaying the recovery by as much.
        fn lost(&self) {
            defmt::warn!("depth: read errors in a row; power-cycling the sensor");
        }
    }

    /// Core 0: turns each frame from core 1 into a scan for the SLAM tick, held to the
    /// frames before it.
    #[embassy_executor::task]
    pub async fn depth_task(inputs: &'static Inputs) -> ! {
        let mut ranging = false;
        let config = crate::world::slam_config(crate::slam_task::LOCALISER);
        let fan = ZoneTurn::new(&config.depth.beam_angles);
        let mut steps = DepthSteps::default();
        loop {
            match with_timeout(FRAME_TIMEOUT, ZONES.wait()).await {
                Ok((zones, measured)) => {
                    ranging = true;
                    let beams = reduce(&zones, &ROWS);
                    let scan = DepthScan {
                        ranges_mm: beams.range_mm,
                    };
                    if inputs.depth_steps_void.swap(false, Ordering::Relaxed) {
                        steps.forget_steps();
                    }
                    // The gyro's integral now, a few milliseconds after the frame was
                    // seen ready: the heading at its moment.
                    let heading = Angle::from_millidegrees(inputs.yaw.yaw_mdeg());
                    let moment_us = measured.as_micros() as u32;
                    let doubt = config.plausible.as_ref().and_then(|limits| {
                        steps.judge(&scan, moment_us, heading, &fan, limits).err()
                    });
                    inputs.depth.signal(DepthReading {
                        scan,
                        measured,
                        doubt,
                    });
                }
                // Before the first frame the sensor is still starting (about 2 s).
                Err(_) if ranging => HEALTH.depth_timeouts.bump(),
                Err(_) => {}
            }
        }
    }
}

/// I2C0's settings for the depth sensor.
fn bus_config() -> i2c::Config {
    let mut config = i2c::Config::default();
    config.frequency = DEPTH_I2C_HZ;
    config
}

/// The depth task when there is no bus layer.
#[cfg(not(feature = "vl53l5cx"))]
mod stale {
    use embassy_rp::gpio::{Level, Output};
    use embassy_rp::i2c::I2c;

    use super::{bus_config, DepthInbox, DepthSensorPins};
    use crate::Irqs;

    /// Enables the sensor's bus and parks, publishing nothing, so every tick's depth is
    /// stale.
    #[embassy_executor::task]
    pub async fn depth_task(pins: DepthSensorPins, irqs: Irqs, scans: &'static DepthInbox) -> ! {
        let _i2c = I2c::new_async(pins.i2c, pins.scl, pins.sda, irqs, bus_config());
        // LPn high: the sensor answers on I2C.
        let _lpn = Output::new(pins.lpn, Level::High);
        // The second core stays asleep.
        let _core1 = pins.core1;
        let _: &DepthInbox = scans;
        defmt::warn!("depth: built without the `vl53l5cx` feature; depth input stays stale");
        crate::sensors::park().await
    }
}
