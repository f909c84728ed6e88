//! PMW3901 register map, init table and SPI timing.

/// A documented PMW3901 register address (7 bits; bit 7 is the write flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Register(pub u8);

impl Register {
    /// Product id, reads [`PRODUCT_ID`].
    pub const PRODUCT_ID: Register = Register(0x00);
    /// Motion status; bit 7 set when motion occurred since the last read.
    pub const MOTION: Register = Register(0x02);
    /// Delta X, low byte.
    pub const DELTA_X_L: Register = Register(0x03);
    /// Delta X, high byte.
    pub const DELTA_X_H: Register = Register(0x04);
    /// Delta Y, low byte.
    pub const DELTA_Y_L: Register = Register(0x05);
    /// Delta Y, high byte.
    pub const DELTA_Y_H: Register = Register(0x06);
    /// Motion burst: 12 bytes from one address, see [`MotionBurst`](super::MotionBurst).
    pub const MOTION_BURST: Register = Register(0x16);
    /// Power-up reset: write [`RESET_COMMAND`].
    pub const POWER_UP_RESET: Register = Register(0x3A);
    /// Inverse product id, reads [`INVERSE_PRODUCT_ID`].
    pub const INVERSE_PRODUCT_ID: Register = Register(0x5F);
}

/// Expected [`Register::PRODUCT_ID`] value.
pub const PRODUCT_ID: u8 = 0x49;
/// Expected [`Register::INVERSE_PRODUCT_ID`] value.
pub const INVERSE_PRODUCT_ID: u8 = 0xB6;
/// Value written to [`Register::POWER_UP_RESET`] to reset the chip.
pub const RESET_COMMAND: u8 = 0x5A;
/// Address bit 7 set = write.
pub const WRITE_FLAG: u8 = 0x80;

/// Bit 7 of the motion register: motion since the last read.
pub const MOTION_FLAG: u8 = 0x80;
/// Shutter upper byte when the shutter is fully open: with low SQUAL, the
/// datasheet's "no surface / too dark" condition.
pub const SHUTTER_UPPER_MAX: u8 = 0x1F;
/// Datasheet SQUAL threshold under which, with the shutter at maximum,
/// deltas must be discarded (bright mode).
pub const SQUAL_MIN_DATASHEET: u8 = 0x19;

/// Wait after power-up reset before any other access, milliseconds.
pub const RESET_WAIT_MS: u32 = 5;
/// Wait between the two halves of the init table, milliseconds.
pub const INIT_PAUSE_MS: u32 = 100;
/// Address-to-data wait on reads (tSRAD), nanoseconds. The datasheet
/// minimum is 35 us; 50 us as the Bitcraze reference driver uses.
pub const T_SRAD_NS: u32 = 50_000;
/// Wait after a register read before the next access (tSRR/tSRW, 20 us
/// minimum), nanoseconds.
pub const T_AFTER_READ_NS: u32 = 20_000;
/// Wait after a register write before the next access (tSWW/tSWR 45 us
/// minimum; the reference driver waits 250 us in all), nanoseconds.
pub const T_AFTER_WRITE_NS: u32 = 200_000;

/// "Performance optimisation" register writes, first half, `(register,
/// value)`; register 0x7F selects a bank and the rest is undocumented
/// vendor tuning. Origin: the fixed sequence of the Bitcraze reference
/// driver (`Bitcraze_PMW3901::initRegisters`, MIT), flown on every Crazyflie
/// Flow deck. PixArt's datasheet sequence adds a few conditional reads and
/// differs in some bank 0x14/0x15 values; switch to it if tracking on
/// BugBot's floors is poor.
pub const INIT_PART1: [(u8, u8); 59] = [
    (0x7F, 0x00),
    (0x61, 0xAD),
    (0x7F, 0x03),
    (0x40, 0x00),
    (0x7F, 0x05),
    (0x41, 0xB3),
    (0x43, 0xF1),
    (0x45, 0x14),
    (0x5B, 0x32),
    (0x5F, 0x34),
    (0x7B, 0x08),
    (0x7F, 0x06),
    (0x44, 0x1B),
    (0x40, 0xBF),
    (0x4E, 0x3F),
    (0x7F, 0x08),
    (0x65, 0x20),
    (0x6A, 0x18),
    (0x7F, 0x09),
    (0x4F, 0xAF),
    (0x5F, 0x40),
    (0x48, 0x80),
    (0x49, 0x80),
    (0x57, 0x77),
    (0x60, 0x78),
    (0x61, 0x78),
    (0x62, 0x08),
    (0x63, 0x50),
    (0x7F, 0x0A),
    (0x45, 0x60),
    (0x7F, 0x00),
    (0x4D, 0x11),
    (0x55, 0x80),
    (0x74, 0x1F),
    (0x75, 0x1F),
    (0x4A, 0x78),
    (0x4B, 0x78),
    (0x44, 0x08),
    (0x45, 0x50),
    (0x64, 0xFF),
    (0x65, 0x1F),
    (0x7F, 0x14),
    (0x65, 0x60),
    (0x66, 0x08),
    (0x63, 0x78),
    (0x7F, 0x15),
    (0x48, 0x58),
    (0x7F, 0x07),
    (0x41, 0x0D),
    (0x43, 0x14),
    (0x4B, 0x0E),
    (0x45, 0x0F),
    (0x44, 0x42),
    (0x4C, 0x80),
    (0x7F, 0x10),
    (0x5B, 0x02),
    (0x7F, 0x07),
    (0x40, 0x41),
    (0x70, 0x00),
];

/// Second half of the init table, written after [`INIT_PAUSE_MS`]; same
/// origin as [`INIT_PART1`]. Ends in bank 0, as normal operation needs.
pub const INIT_PART2: [(u8, u8); 14] = [
    (0x32, 0x44),
    (0x7F, 0x07),
    (0x40, 0x40),
    (0x7F, 0x06),
    (0x62, 0xF0),
    (0x63, 0x00),
    (0x7F, 0x0D),
    (0x48, 0xC0),
    (0x6F, 0xD5),
    (0x7F, 0x00),
    (0x5B, 0xA0),
    (0x4E, 0xA8),
    (0x5A, 0x50),
    (0x40, 0x80),
];
