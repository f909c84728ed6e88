//! ICM-42688-P register map (user bank 0) and bit fields.

/// A bank-0 register address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Register(pub u8);

impl Register {
    /// DEVICE_CONFIG: bit 0 starts a soft reset.
    pub const DEVICE_CONFIG: Register = Register(0x11);
    /// GYRO_DATA_Z1: gyro Z high byte; Z0 (low byte) follows at 0x2A.
    pub const GYRO_DATA_Z1: Register = Register(0x29);
    /// INT_STATUS: reset-done and data-ready flags, cleared on read.
    pub const INT_STATUS: Register = Register(0x2D);
    /// PWR_MGMT0: gyro and accel power modes.
    pub const PWR_MGMT0: Register = Register(0x4E);
    /// GYRO_CONFIG0: full scale (bits 7:5) and output data rate (bits 3:0).
    pub const GYRO_CONFIG0: Register = Register(0x4F);
    /// WHO_AM_I: reads [`WHO_AM_I`].
    pub const WHO_AM_I: Register = Register(0x75);
}

/// Expected WHO_AM_I value for the ICM-42688-P.
pub const WHO_AM_I: u8 = 0x47;
/// DEVICE_CONFIG value that starts a soft reset.
pub const SOFT_RESET: u8 = 0x01;
/// INT_STATUS bit set once a soft reset has completed.
pub const INT_STATUS_RESET_DONE: u8 = 1 << 4;
/// PWR_MGMT0 value: gyro in low-noise mode (bits 3:2 = 0b11), accel off
/// (bits 1:0 = 0), temperature sensor on (bit 5 = 0).
pub const PWR_MGMT0_GYRO_LOW_NOISE: u8 = 0b11 << 2;
/// Shift of GYRO_FS_SEL in GYRO_CONFIG0.
pub const GYRO_FS_SEL_SHIFT: u8 = 5;
/// Value of a data register when the sample is invalid (sensor off or not
/// yet settled).
pub const INVALID_SAMPLE: i16 = i16::MIN;

/// Wait after a soft reset before any register access, milliseconds.
pub const SOFT_RESET_WAIT_MS: u32 = 1;
/// Wait after turning the gyro on before its data is valid, milliseconds
/// (start-up time is 30 ms typical; 50 ms leaves margin).
pub const GYRO_STARTUP_MS: u32 = 50;
