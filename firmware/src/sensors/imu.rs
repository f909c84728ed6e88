//! IMU task (ICM-42688-P on I2C1, 200 Hz): calibrates the gyro bias at rest, then adds
//! each bias-corrected yaw-rate sample to [`GyroInbox`](crate::inputs::GyroInbox) (the SLAM tick takes their mean)
//! and integrates them into [`YawIntegrator`](crate::inputs::YawIntegrator) for the motion task.
//!
//! Bus: I2C1 at 400 kHz, SDA GP2, SCL GP3, the IMU at 7-bit address 0x68 (AP_AD0 low).
//! The task owns the bus; the driver gets an `embassy-embedded-hal` `I2cDevice` on it, so
//! it sees only the `embedded-hal-async` trait and a second part on I2C1 could join.
//! Every access is a `write_read` (never a `transaction`), which the emulator handles.
//!
//! # Boot: stand still for a second
//!
//! After reset the robot must stand still for about 1.1 s: the driver's start-up takes
//! about 51 ms, then 200 samples (1 s at 200 Hz) go into a [`BiasCalibrator`]. If their
//! spread says the robot moved, the calibration starts over (counted), so a robot picked
//! up at boot just calibrates later. Until it is done the gyro input is stale and the
//! motion task does not start.
//!
//! The data-ready line (GP7) is not used: the driver does not route data-ready to INT1,
//! so a 200 Hz [`Ticker`] at the chip's output rate paces the reads instead.

use drivers::imu::{BiasCalibrator, CalibrationStatus, Error as ImuError, GyroConfig, Icm42688};
use embassy_embedded_hal::shared_bus::asynch::i2c::I2cDevice;
use embassy_rp::gpio::{Input, Pull};
use embassy_rp::i2c::{self, Async, I2c};
use embassy_rp::peripherals::I2C1;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::{with_timeout, Delay, Duration, Instant, Ticker};
use slam_core::GyroRate;
use static_cell::StaticCell;

use crate::board::{ImuPins, IMU_I2C_HZ};
use crate::health::HEALTH;
use crate::inputs::Inputs;
use crate::sensors::supervise::{Pace, Read, StartFailure, Supervised, Supervisor};
use crate::Irqs;

/// Sample period: the gyro's 200 Hz output data rate.
const SAMPLE_PERIOD: Duration = Duration::from_millis(5);

/// Samples in a bias calibration: one second at rest.
const CALIBRATION_SAMPLES: u32 = 200;

/// Largest spread of the calibration samples, counts squared (see [`BiasCalibrator`]).
const CALIBRATION_MAX_VARIANCE: u32 = 25;

/// Longest one sample read may take (about 0.1 ms at 400 kHz).
const READ_TIMEOUT: Duration = Duration::from_millis(3);

/// Longest the start-up sequence may take (about 51 ms of datasheet waits).
const INIT_TIMEOUT: Duration = Duration::from_millis(500);

/// First wait after a failed start-up; doubled after each failure up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_millis(100);

/// Longest wait between two start-up attempts.
const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// Bus failures in a row after which the IMU is started up again (keeping its bias).
const ERRORS_BEFORE_RESTART: u32 = 20;

/// The IMU's start-up and samples: one every [`SAMPLE_PERIOD`], on a fixed grid.
static SUPERVISOR: Supervisor = Supervisor {
    first_backoff: FIRST_BACKOFF,
    max_backoff: MAX_BACKOFF,
    pace: Pace::Every(SAMPLE_PERIOD),
    errors_before_restart: ERRORS_BEFORE_RESTART,
    start_failures: &HEALTH.gyro_start_failures,
    bus_errors: &HEALTH.gyro_bus_errors,
};

/// A rate at or beyond this is implausible (90 % of the +-1000 dps full scale: the reading
/// is saturated or corrupt, and BugBot never turns faster than a few hundred degrees per
/// second). Dropped and counted.
const MAX_PLAUSIBLE_RATE_MDPS: i32 = 900_000;

/// Longest gap bridged when integrating yaw, in microseconds. After a longer outage the
/// turn in between is unknown; integrating the next rate over it would invent a turn.
const MAX_INTEGRATION_GAP_US: u32 = 50_000;

type ImuBus = Mutex<NoopRawMutex, I2c<'static, I2C1, Async>>;

static BUS: StaticCell<ImuBus> = StaticCell::new();

type Imu = Icm42688<I2cDevice<'static, NoopRawMutex, I2c<'static, I2C1, Async>>>;

/// Runs the IMU for good: start-up, bias calibration at rest, then 200 Hz samples.
#[embassy_executor::task]
pub async fn imu_task(pins: ImuPins, irqs: Irqs, inputs: &'static Inputs) -> ! {
    let mut config = i2c::Config::default();
    config.frequency = IMU_I2C_HZ;
    let bus = BUS.init(Mutex::new(I2c::new_async(
        pins.i2c, pins.scl, pins.sda, irqs, config,
    )));
    let imu = Icm42688::new(I2cDevice::new(bus), GyroConfig::default());
    // Held as a plain input so the line has a defined state; see the module doc.
    let _data_ready = Input::new(pins.int, Pull::None);
    let mut part = ImuPart {
        imu,
        inputs,
        last_sample: Instant::now(),
    };

    // Calibrated once: a restart keeps the bias.
    SUPERVISOR.start(&mut part).await;
    calibrate(&mut part.imu).await;
    inputs.gyro_ready.signal(());
    loop {
        SUPERVISOR.read_until_lost(&mut part).await;
        SUPERVISOR.start(&mut part).await;
    }
}

/// Estimates the gyro bias from [`CALIBRATION_SAMPLES`] samples at rest and hands it to
/// the driver; starts over whenever the robot moved. Failed reads are skipped.
async fn calibrate(imu: &mut Imu) {
    defmt::info!("imu: calibrating gyro bias; keep the robot still");
    let mut calibrator = BiasCalibrator::new(CALIBRATION_SAMPLES, CALIBRATION_MAX_VARIANCE);
    let mut ticker = Ticker::every(SAMPLE_PERIOD);
    loop {
        ticker.next().await;
        let raw = match with_timeout(READ_TIMEOUT, imu.read_gyro_z_raw()).await {
            Ok(Ok(raw)) => raw,
            Ok(Err(e)) => {
                count_read_error(&e);
                continue;
            }
            Err(_) => {
                HEALTH.gyro_bus_errors.bump();
                continue;
            }
        };
        match calibrator.push(raw) {
            CalibrationStatus::NeedMore { .. } => {}
            CalibrationStatus::TooNoisy { variance_counts2 } => {
                defmt::warn!(
                    "imu: robot moved during calibration (variance {=u32}); again",
                    variance_counts2
                );
                HEALTH.gyro_calibration_restarts.bump();
                calibrator.reset();
            }
            CalibrationStatus::Done(bias) => {
                defmt::info!("imu: gyro bias {=i16} counts", bias.counts());
                imu.set_bias(bias);
                return;
            }
        }
    }
}

/// The IMU and where its samples go.
struct ImuPart {
    imu: Imu,
    inputs: &'static Inputs,
    /// When the last good sample was taken, for the yaw integral's time step.
    last_sample: Instant,
}

impl Supervised for ImuPart {
    async fn try_start(&mut self) -> Result<(), StartFailure> {
        match with_timeout(INIT_TIMEOUT, self.imu.init(&mut Delay)).await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => {
                defmt::warn!("imu: start-up failed: {}", e);
                Err(match e {
                    ImuError::Bus(_) => StartFailure::Bus,
                    _ => StartFailure::Other,
                })
            }
            Err(_) => {
                defmt::warn!("imu: start-up timed out");
                Err(StartFailure::Bus)
            }
        }
    }

    fn started(&self) {
        defmt::info!("imu: ICM-42688-P running at 200 Hz");
    }

    fn reads_begin(&mut self) {
        self.last_sample = Instant::now();
    }

    /// One sample into the gyro inbox and the yaw integral.
    async fn read(&mut self) -> Read {
        let rate = match with_timeout(READ_TIMEOUT, self.imu.read_yaw_rate()).await {
            Ok(Ok(rate)) => rate,
            Ok(Err(ImuError::InvalidSample)) => {
                HEALTH.gyro_implausible.bump();
                return Read::Failed;
            }
            Ok(Err(_)) | Err(_) => return Read::BusError,
        };
        if rate.rate_mdps.unsigned_abs() >= MAX_PLAUSIBLE_RATE_MDPS.unsigned_abs() {
            HEALTH.gyro_implausible.bump();
            return Read::Answered;
        }
        let now = Instant::now();
        let gap_us = u32::try_from(now.saturating_duration_since(self.last_sample).as_micros())
            .unwrap_or(u32::MAX);
        self.last_sample = now;
        let rate = GyroRate {
            rate_mdps: rate.rate_mdps,
        };
        self.inputs.gyro.add(rate, now);
        self.inputs
            .yaw
            .integrate(rate, gap_us.min(MAX_INTEGRATION_GAP_US));
        Read::Answered
    }

    fn lost(&self) {
        defmt::warn!(
            "imu: {=u32} bus failures in a row; restarting",
            ERRORS_BEFORE_RESTART
        );
    }
}

/// Counts a failed read: the chip's "invalid sample" marker is implausible, anything else
/// a bus error.
fn count_read_error<E>(e: &ImuError<E>) {
    match e {
        ImuError::InvalidSample => HEALTH.gyro_implausible.bump(),
        _ => HEALTH.gyro_bus_errors.bump(),
    }
}
