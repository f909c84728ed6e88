//! PixArt PMW3901 optical flow sensor on SPI.
//!
//! The sensor looks down at the floor and reports image motion in counts
//! (pixels) since the last read. [`Pmw3901::read`] takes one motion burst,
//! gates it (surface quality, motion flag, outliers) and scales it to
//! micrometres in robot frame with a [`FlowCalibration`].
//!
//! # Bus
//!
//! SPI mode 3 (CPOL 1, CPHA 1), MSB first, at most 2 MHz, one
//! `SpiDevice` with its own chip select. Reads are `[addr]`, a tSRAD wait,
//! then data; writes are `[addr | 0x80, value]`. The waits the datasheet
//! asks for are [`Operation::DelayNs`] steps inside each transaction (see
//! [`register`] for the values), so the bus implementation must honour
//! `DelayNs` operations (embassy's `SpiDevice` does).
//!
//! # Start-up
//!
//! [`Pmw3901::init`]: power-up reset, 5 ms wait, one read of the motion
//! registers 0x02..=0x06, product id check, then the vendor init table with
//! its 100 ms pause. Allow about 120 ms. Reading at 100 Hz or faster keeps
//! deltas well inside 16 bits.

pub mod register;

mod calibration;
mod motion;

pub use calibration::FlowCalibration;
pub use motion::{gate, AxisMap, FlowConfig, FlowReading, FlowSample, MotionBurst, SurfaceCheck};

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::spi::{Operation, SpiDevice};
use register::Register;

/// What can go wrong talking to the PMW3901.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The SPI transaction failed.
    Bus(E),
    /// Product id register did not read 0x49: wrong part or bad wiring.
    WrongProductId {
        /// Value read.
        found: u8,
    },
    /// Inverse product id did not read 0xB6: bus corruption or wrong part.
    WrongInverseProductId {
        /// Value read.
        found: u8,
    },
}

impl<E> From<E> for Error<E> {
    fn from(e: E) -> Self {
        Error::Bus(e)
    }
}

/// Running counts since construction. Counters wrap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowCounters {
    /// Motion bursts read successfully.
    pub reads: u32,
    /// Bursts dropped as outliers.
    pub outliers: u32,
    /// Bursts that failed the surface check.
    pub low_quality: u32,
    /// Failed SPI transactions, in `init` or `read`.
    pub bus_errors: u32,
}

/// PMW3901 driver on an async SPI device.
#[derive(Debug)]
pub struct Pmw3901<SPI> {
    spi: SPI,
    config: FlowConfig,
    counters: FlowCounters,
}

impl<SPI: SpiDevice> Pmw3901<SPI> {
    /// Wrap the device; no bus traffic until [`Pmw3901::init`].
    pub fn new(spi: SPI, config: FlowConfig) -> Self {
        Pmw3901 {
            spi,
            config,
            counters: FlowCounters::default(),
        }
    }

    /// Reset and configure the sensor; see the module doc.
    pub async fn init<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), Error<SPI::Error>> {
        self.write(Register::POWER_UP_RESET.0, register::RESET_COMMAND)
            .await?;
        delay.delay_ms(register::RESET_WAIT_MS).await;
        // The datasheet asks for one read of each motion register after reset.
        for reg in [
            Register::MOTION,
            Register::DELTA_X_L,
            Register::DELTA_X_H,
            Register::DELTA_Y_L,
            Register::DELTA_Y_H,
        ] {
            self.read_register(reg).await?;
        }
        let id = self.read_register(Register::PRODUCT_ID).await?;
        if id != register::PRODUCT_ID {
            return Err(Error::WrongProductId { found: id });
        }
        let inverse = self.read_register(Register::INVERSE_PRODUCT_ID).await?;
        if inverse != register::INVERSE_PRODUCT_ID {
            return Err(Error::WrongInverseProductId { found: inverse });
        }
        for (reg, value) in register::INIT_PART1 {
            self.write(reg, value).await?;
        }
        delay.delay_ms(register::INIT_PAUSE_MS).await;
        for (reg, value) in register::INIT_PART2 {
            self.write(reg, value).await?;
        }
        Ok(())
    }

    /// Read one motion burst and gate it; see [`gate`].
    pub async fn read(&mut self) -> Result<FlowReading, Error<SPI::Error>> {
        let burst = self.read_motion_burst().await?;
        self.counters.reads = self.counters.reads.wrapping_add(1);
        let reading = gate(&burst, &self.config);
        match reading {
            FlowReading::NoSurface { .. } => {
                self.counters.low_quality = self.counters.low_quality.wrapping_add(1);
            }
            FlowReading::Outlier { .. } => {
                self.counters.outliers = self.counters.outliers.wrapping_add(1);
            }
            FlowReading::Motion(_) => {}
        }
        Ok(reading)
    }

    /// Read the raw 12-byte motion burst, ungated.
    pub async fn read_motion_burst(&mut self) -> Result<MotionBurst, Error<SPI::Error>> {
        let mut bytes = [0u8; MotionBurst::LEN];
        let result = self
            .spi
            .transaction(&mut [
                Operation::Write(&[Register::MOTION_BURST.0]),
                Operation::DelayNs(register::T_SRAD_NS),
                Operation::Read(&mut bytes),
            ])
            .await;
        self.count(result)?;
        Ok(MotionBurst::parse(&bytes))
    }

    /// Read one register.
    pub async fn read_register(&mut self, reg: Register) -> Result<u8, Error<SPI::Error>> {
        let mut value = [0u8];
        let result = self
            .spi
            .transaction(&mut [
                Operation::Write(&[reg.0 & !register::WRITE_FLAG]),
                Operation::DelayNs(register::T_SRAD_NS),
                Operation::Read(&mut value),
                Operation::DelayNs(register::T_AFTER_READ_NS),
            ])
            .await;
        self.count(result)?;
        let [value] = value;
        Ok(value)
    }

    async fn write(&mut self, reg: u8, value: u8) -> Result<(), Error<SPI::Error>> {
        let result = self
            .spi
            .transaction(&mut [
                Operation::Write(&[reg | register::WRITE_FLAG, value]),
                Operation::DelayNs(register::T_AFTER_WRITE_NS),
            ])
            .await;
        self.count(result)
    }

    fn count<T>(&mut self, result: Result<T, SPI::Error>) -> Result<T, Error<SPI::Error>> {
        if result.is_err() {
            self.counters.bus_errors = self.counters.bus_errors.wrapping_add(1);
        }
        result.map_err(Error::Bus)
    }

    /// Counters so far.
    pub fn counters(&self) -> FlowCounters {
        self.counters
    }

    /// The gating and scaling in use.
    pub fn config(&self) -> &FlowConfig {
        &self.config
    }

    /// Change gating or scaling (e.g. after a bench calibration).
    pub fn set_config(&mut self, config: FlowConfig) {
        self.config = config;
    }

    /// Give the SPI device back.
    pub fn destroy(self) -> SPI {
        self.spi
    }
}
