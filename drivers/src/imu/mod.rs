//! TDK InvenSense ICM-42688-P gyro (yaw rate only) on I2C.
//!
//! # Why this part
//!
//! The ICM-42688-P is in volume production, cheap on breakout boards, and
//! has among the lowest gyro noise of consumer IMUs (2.8 mdps/sqrt(Hz)) with
//! low bias drift over temperature, which is what dead reckoning on yaw
//! needs. The part of its register map used here sits in one bank, and it
//! speaks I2C at up to 1 MHz; BugBot gives it a bus of its own (I2C1 at
//! 400 kHz, see the firmware's `board.rs`). The MPU-6050
//! family is obsolete; the LSM6DSO would also do (3.8 mdps/sqrt(Hz)) and
//! is the fallback if the ICM-42688-P is out of stock, with a new register
//! module.
//!
//! # Use
//!
//! [`Icm42688::init`] checks WHO_AM_I, soft-resets, sets the gyro full
//! scale and output rate ([`GyroConfig`]), turns the gyro on in low-noise
//! mode and waits for it to settle (about 51 ms). Then calibrate the bias
//! at rest with [`BiasCalibrator`] fed by [`Icm42688::read_gyro_z_raw`],
//! hand the result to [`Icm42688::set_bias`], and read
//! [`Icm42688::read_yaw_rate`].
//!
//! # Sign
//!
//! [`YawRate::rate_mdps`] is positive turning clockwise seen from above,
//! BugBot's heading convention. The chip's Z axis is out of its top face
//! and its rates are right-handed, so with the chip face up a clockwise
//! turn reads negative: [`Mounting::FaceUp`] negates, [`Mounting::FaceDown`]
//! does not.

pub mod register;

mod bias;

pub use bias::{BiasCalibrator, CalibrationStatus, GyroBias};

use embedded_hal_async::delay::DelayNs;
use embedded_hal_async::i2c::I2c;
use register::Register;

/// What can go wrong talking to the ICM-42688-P.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The I2C transaction failed.
    Bus(E),
    /// WHO_AM_I was not 0x47: wrong part or address.
    WrongDevice {
        /// Value read.
        found: u8,
    },
    /// The soft reset did not report completion.
    ResetNotDone,
    /// The gyro returned its "invalid data" value (-32768): not on yet.
    InvalidSample,
}

impl<E> From<E> for Error<E> {
    fn from(e: E) -> Self {
        Error::Bus(e)
    }
}

/// I2C address, set by the AP_AD0 pin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Address {
    /// AP_AD0 low: 0x68.
    #[default]
    Ad0Low,
    /// AP_AD0 high: 0x69.
    Ad0High,
}

impl Address {
    /// 7-bit address.
    pub const fn addr(self) -> u8 {
        match self {
            Address::Ad0Low => 0x68,
            Address::Ad0High => 0x69,
        }
    }
}

/// Gyro full scale. Only ranges that suit a small ground robot: it turns
/// at most a few hundred degrees per second.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FullScale {
    /// +-500 dps, 65.5 counts per dps.
    Dps500,
    /// +-1000 dps, 32.8 counts per dps. Default.
    #[default]
    Dps1000,
}

impl FullScale {
    const fn fs_sel(self) -> u8 {
        match self {
            FullScale::Dps1000 => 0b001,
            FullScale::Dps500 => 0b010,
        }
    }

    /// Raw counts to millidegrees per second, rounded to nearest.
    /// Sensitivities are exact rationals: 32.8 = 328/10 and 65.5 = 131/2.
    pub const fn counts_to_mdps(self, counts: i32) -> i32 {
        let (num, den) = match self {
            FullScale::Dps1000 => (1250, 41),
            FullScale::Dps500 => (2000, 131),
        };
        let n = counts * num;
        let half = if n >= 0 { den / 2 } else { -(den / 2) };
        (n + half) / den
    }
}

/// Gyro output data rate; all at least 200 Hz.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OutputRate {
    /// 200 Hz. Default: the control loop runs at 100 Hz.
    #[default]
    Hz200,
    /// 500 Hz.
    Hz500,
    /// 1 kHz.
    Hz1000,
}

impl OutputRate {
    const fn odr(self) -> u8 {
        match self {
            OutputRate::Hz200 => 0b0111,
            OutputRate::Hz500 => 0b1111,
            OutputRate::Hz1000 => 0b0110,
        }
    }
}

/// How the chip is mounted; see the module doc's "Sign".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mounting {
    /// Chip top face up. Default.
    #[default]
    FaceUp,
    /// Chip top face down.
    FaceDown,
}

/// Gyro set-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GyroConfig {
    /// I2C address.
    pub address: Address,
    /// Full scale.
    pub full_scale: FullScale,
    /// Output data rate.
    pub rate: OutputRate,
    /// Mounting, for the sign.
    pub mounting: Mounting,
}

impl GyroConfig {
    /// GYRO_CONFIG0 value for this configuration.
    pub const fn gyro_config0(&self) -> u8 {
        (self.full_scale.fs_sel() << register::GYRO_FS_SEL_SHIFT) | self.rate.odr()
    }
}

/// Yaw rate, bias-corrected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct YawRate {
    /// Millidegrees per second, positive clockwise seen from above.
    pub rate_mdps: i32,
}

/// ICM-42688-P driver on an async I2C bus.
#[derive(Debug)]
pub struct Icm42688<I2C> {
    i2c: I2C,
    config: GyroConfig,
    bias: GyroBias,
}

impl<I2C: I2c> Icm42688<I2C> {
    /// Wrap the bus; no traffic until [`Icm42688::init`]. Bias starts at zero.
    pub fn new(i2c: I2C, config: GyroConfig) -> Self {
        Icm42688 {
            i2c,
            config,
            bias: GyroBias::ZERO,
        }
    }

    /// Check, reset and configure; see the module doc.
    pub async fn init<D: DelayNs>(&mut self, delay: &mut D) -> Result<(), Error<I2C::Error>> {
        let id = self.read_register(Register::WHO_AM_I).await?;
        if id != register::WHO_AM_I {
            return Err(Error::WrongDevice { found: id });
        }
        self.write_register(Register::DEVICE_CONFIG, register::SOFT_RESET)
            .await?;
        delay.delay_ms(register::SOFT_RESET_WAIT_MS).await;
        let status = self.read_register(Register::INT_STATUS).await?;
        if status & register::INT_STATUS_RESET_DONE == 0 {
            return Err(Error::ResetNotDone);
        }
        self.write_register(Register::GYRO_CONFIG0, self.config.gyro_config0())
            .await?;
        self.write_register(Register::PWR_MGMT0, register::PWR_MGMT0_GYRO_LOW_NOISE)
            .await?;
        delay.delay_ms(register::GYRO_STARTUP_MS).await;
        Ok(())
    }

    /// Raw gyro Z sample, counts, no bias removed and chip-frame sign.
    pub async fn read_gyro_z_raw(&mut self) -> Result<i16, Error<I2C::Error>> {
        let mut bytes = [0u8; 2];
        self.i2c
            .write_read(
                self.config.address.addr(),
                &[Register::GYRO_DATA_Z1.0],
                &mut bytes,
            )
            .await?;
        let raw = i16::from_be_bytes(bytes);
        if raw == register::INVALID_SAMPLE {
            return Err(Error::InvalidSample);
        }
        Ok(raw)
    }

    /// Yaw rate, bias removed, BugBot's sign.
    pub async fn read_yaw_rate(&mut self) -> Result<YawRate, Error<I2C::Error>> {
        let raw = self.read_gyro_z_raw().await?;
        Ok(self.yaw_rate_from_raw(raw))
    }

    /// Convert a raw sample with this driver's bias, scale and mounting.
    pub fn yaw_rate_from_raw(&self, raw: i16) -> YawRate {
        let corrected = i32::from(raw) - i32::from(self.bias.counts());
        let oriented = match self.config.mounting {
            Mounting::FaceUp => -corrected,
            Mounting::FaceDown => corrected,
        };
        YawRate {
            rate_mdps: self.config.full_scale.counts_to_mdps(oriented),
        }
    }

    /// Use `bias` for all following readings.
    pub fn set_bias(&mut self, bias: GyroBias) {
        self.bias = bias;
    }

    /// The bias in use.
    pub fn bias(&self) -> GyroBias {
        self.bias
    }

    /// Read one register.
    pub async fn read_register(&mut self, reg: Register) -> Result<u8, Error<I2C::Error>> {
        let mut value = [0u8];
        self.i2c
            .write_read(self.config.address.addr(), &[reg.0], &mut value)
            .await?;
        let [value] = value;
        Ok(value)
    }

    async fn write_register(&mut self, reg: Register, value: u8) -> Result<(), Error<I2C::Error>> {
        self.i2c
            .write(self.config.address.addr(), &[reg.0, value])
            .await?;
        Ok(())
    }

    /// Give the bus back.
    pub fn destroy(self) -> I2C {
        self.i2c
    }
}
