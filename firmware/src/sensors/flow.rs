//! PMW3901 optical flow task (SPI0 with DMA, 100 Hz): adds each good motion read to
//! [`FlowInbox`]; the SLAM tick takes the sum.
//!
//! Bus: SPI0, mode 3 (CPOL 1, CPHA 1), 2 MHz, MSB first; SCK GP18, MOSI GP19, MISO GP16,
//! chip select GP17 driven as a GPIO (active low). The bus sits in a `Mutex` and the
//! driver gets an `embassy-embedded-hal` `SpiDevice`, so it sees only the
//! `embedded-hal-async` trait, and a second device on SPI0 would get its own `SpiDevice`.
//! That `SpiDevice` also carries out the driver's `DelayNs` steps (the datasheet's tSRAD)
//! inside a transaction, with chip select held.

use drivers::flow::{Error as FlowError, FlowCalibration, FlowConfig, FlowReading, Pmw3901};
use embassy_embedded_hal::shared_bus::asynch::spi::SpiDevice;
use embassy_rp::gpio::{Level, Output};
use embassy_rp::peripherals::SPI0;
use embassy_rp::spi::{self, Async, Phase, Polarity, Spi};
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::mutex::Mutex;
use embassy_time::{with_timeout, Delay, Duration};
use slam_core::FlowDelta;
use static_cell::StaticCell;

use crate::board::{FlowSensorPins, FLOW_SPI_HZ};
use crate::health::HEALTH;
use crate::inputs::FlowInbox;
use crate::sensors::supervise::{Pace, Read, StartFailure, Supervised, Supervisor};
use crate::Irqs;

/// Read period: 100 Hz keeps each read's delta far inside the driver's outlier limit.
const READ_PERIOD: Duration = Duration::from_millis(10);

/// Longest a motion burst read may take (it needs about 0.1 ms at 2 MHz).
const READ_TIMEOUT: Duration = Duration::from_millis(5);

/// Longest the start-up sequence may take (about 120 ms of datasheet waits).
const INIT_TIMEOUT: Duration = Duration::from_millis(500);

/// First wait after a failed start-up; doubled after each failure up to [`MAX_BACKOFF`].
const FIRST_BACKOFF: Duration = Duration::from_millis(100);

/// Longest wait between two start-up attempts.
const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// Bus errors or timeouts in a row after which the sensor is started up again (it may
/// have lost power or been unplugged).
const ERRORS_BEFORE_RESTART: u32 = 10;

/// The sensor's start-up and reads: one read every [`READ_PERIOD`], on a fixed grid.
static SUPERVISOR: Supervisor = Supervisor {
    first_backoff: FIRST_BACKOFF,
    max_backoff: MAX_BACKOFF,
    pace: Pace::Every(READ_PERIOD),
    errors_before_restart: ERRORS_BEFORE_RESTART,
    start_failures: &HEALTH.flow_start_failures,
    bus_errors: &HEALTH.flow_bus_errors,
};

/// Counts to micrometres as the core sees it (`OdometryConfig::NOMINAL`, 100 um per
/// count). The core scales counts itself; the driver's scale only fills `FlowSample`'s
/// micrometre fields, which nothing here uses, so the two are kept equal to avoid
/// confusion.
const CALIBRATION: FlowCalibration = FlowCalibration::from_um_per_count_q16(100 << 16);

/// SPI0, shared through a mutex (one user today, the PMW3901).
type FlowBus = Mutex<NoopRawMutex, Spi<'static, SPI0, Async>>;

static BUS: StaticCell<FlowBus> = StaticCell::new();

type Sensor = Pmw3901<SpiDevice<'static, NoopRawMutex, Spi<'static, SPI0, Async>, Output<'static>>>;

/// Runs the flow sensor for good: start-up with retries, then a read every 10 ms.
///
/// Each read ends one of four ways: good motion is added to `motion`; no surface,
/// an outlier, a bus error or a timeout is counted in [`HEALTH`] and poisons the current
/// SLAM tick's flow (stale). After [`ERRORS_BEFORE_RESTART`] bus failures in a row the
/// sensor is started up again.
#[embassy_executor::task]
pub async fn flow_task(pins: FlowSensorPins, irqs: Irqs, motion: &'static FlowInbox) -> ! {
    let mut config = spi::Config::default();
    config.frequency = FLOW_SPI_HZ;
    // SPI mode 3: clock idles high, data captured on the rising (second) edge.
    config.polarity = Polarity::IdleHigh;
    config.phase = Phase::CaptureOnSecondTransition;
    let spi = Spi::new(
        pins.spi,
        pins.sck,
        pins.mosi,
        pins.miso,
        pins.tx_dma,
        pins.rx_dma,
        irqs,
        config,
    );
    let bus = BUS.init(Mutex::new(spi));
    let cs = Output::new(pins.cs, Level::High);
    let sensor = Pmw3901::new(SpiDevice::new(bus, cs), FlowConfig::new(CALIBRATION));
    SUPERVISOR.run(&mut FlowPart { sensor, motion }).await
}

/// The sensor and the inbox its motion goes to.
struct FlowPart {
    sensor: Sensor,
    motion: &'static FlowInbox,
}

impl Supervised for FlowPart {
    async fn try_start(&mut self) -> Result<(), StartFailure> {
        match with_timeout(INIT_TIMEOUT, self.sensor.init(&mut Delay)).await {
            Ok(Ok(())) => Ok(()),
            Ok(Err(e)) => {
                defmt::warn!("flow: start-up failed: {}", e);
                Err(match e {
                    FlowError::Bus(_) => StartFailure::Bus,
                    _ => StartFailure::Other,
                })
            }
            Err(_) => {
                defmt::warn!("flow: start-up timed out");
                Err(StartFailure::Bus)
            }
        }
    }

    fn started(&self) {
        defmt::info!("flow: PMW3901 running at 100 Hz");
    }

    async fn read(&mut self) -> Read {
        let Ok(Ok(reading)) = with_timeout(READ_TIMEOUT, self.sensor.read()).await else {
            self.motion.poison();
            return Read::BusError;
        };
        match reading {
            FlowReading::Motion(sample) => self.motion.add(FlowDelta {
                forward_counts: i32::from(sample.forward_counts),
                right_counts: i32::from(sample.right_counts),
            }),
            FlowReading::NoSurface { .. } => {
                HEALTH.flow_no_surface.bump();
                self.motion.poison();
            }
            FlowReading::Outlier { .. } => {
                HEALTH.flow_outliers.bump();
                self.motion.poison();
            }
        }
        Read::Answered
    }

    fn lost(&self) {
        defmt::warn!(
            "flow: {=u32} bus failures in a row; restarting",
            ERRORS_BEFORE_RESTART
        );
    }
}
