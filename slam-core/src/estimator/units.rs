//! The filter's units and the conversions to and from the core's.
//!
//! Covariance units: position 1/16 mm, heading 2^-16 rad, scales 2^-16, gyro bias
//! 2^-16 rad/s. The calibration's means are kept 256 times finer ("fine" units), so that
//! the small corrections a converged filter makes are not rounded away.

use super::fixed::mul_shift;

/// Position units per millimetre.
pub const POSITION_PER_MM: i64 = 16;
/// Heading units per radian.
pub const HEADING_PER_RAD: i64 = 1 << 16;
/// Fine units per covariance unit, for the calibration's means and for corrections.
pub const FINE_SHIFT: u32 = 8;

/// Millidegrees per heading unit (2^-16 rad): 180,000 / pi / 2^16, Q16.
pub const MDEG_PER_HEADING_Q16: i32 = 57_296;

/// Millidegrees squared per heading unit squared: `MDEG_PER_HEADING_Q16`'s square to the
/// nearest, Q16 (a variance's conversion, without the rounding of the unit's).
pub const MDEG2_PER_HEADING2_Q16: i64 = 50_092;

/// Micrometres to position units (x 0.016, by a Q26 multiply: no division on the M0+).
pub fn position_from_um(um: i64) -> i64 {
    position_from_um_frac(um, 0)
}

/// [`position_from_um`] with `frac` fractional bits (at most 26).
pub fn position_from_um_frac(um: i64, frac: u32) -> i64 {
    mul_shift(um, 1_073_742, 26 - frac)
}

/// A correction in fine position units to micrometres (x 62.5 / 256 = x 125 / 512).
pub fn um_from_fine_position(fine: i64) -> i64 {
    mul_shift(fine, 125, 9)
}

/// A signed binary angle (2^32 per turn) to heading units (x 2 pi / 2^16).
pub fn heading_from_bits(bits: i64) -> i64 {
    mul_shift(bits, 411_775, 32)
}

/// A correction in fine heading units to binary angle units (x 2^8 / (2 pi), Q16).
pub fn bits_from_fine_heading(fine: i64) -> i64 {
    mul_shift(fine, 2_670_177, 16)
}

/// Millidegrees to heading units (x pi / 180000 x 2^16, Q16).
pub fn heading_from_mdeg(mdeg: i64) -> i64 {
    heading_from_mdeg_frac(mdeg, 0)
}

/// [`heading_from_mdeg`] with `frac` fractional bits (at most 16).
pub fn heading_from_mdeg_frac(mdeg: i64, frac: u32) -> i64 {
    mul_shift(mdeg, 74_961, 16 - frac)
}

/// Parts per million to scale units (x 2^16 / 1e6, Q16).
pub fn scale_from_ppm(ppm: i64) -> i64 {
    scale_from_ppm_frac(ppm, 0)
}

/// [`scale_from_ppm`] with `frac` fractional bits (at most 16).
pub fn scale_from_ppm_frac(ppm: i64, frac: u32) -> i64 {
    mul_shift(ppm, 4295, 16 - frac)
}

/// A fine scale (2^-24) to parts per million (x 1e6 / 2^24 = x 15625 / 2^18).
pub fn ppm_from_fine_scale(fine: i64) -> i64 {
    mul_shift(fine, 15_625, 18)
}

/// Millidegrees per second to gyro bias units (x pi / 180000 x 2^16, as headings).
pub fn bias_from_mdps(mdps: i64) -> i64 {
    heading_from_mdeg(mdps)
}

/// A fine gyro bias (2^-24 rad/s) to millidegrees per second (x 180000 / pi / 2^24, Q20).
pub fn mdps_from_fine_bias(fine: i64) -> i64 {
    mul_shift(fine, 3581, 20)
}

/// Microseconds to seconds in Q16.
pub fn seconds_q16_from_us(us: u32) -> i64 {
    mul_shift(i64::from(us), 4295, 16)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions_match_their_definitions() {
        assert_eq!(position_from_um(1000), 16);
        assert_eq!(position_from_um(-62_500), -1000);
        assert_eq!(um_from_fine_position(256), 63); // 62.5 rounded
        assert_eq!(um_from_fine_position(512), 125);
        // Half a turn is pi radians.
        assert_eq!(heading_from_bits(1 << 31), 205_888); // pi * 2^16 = 205887.4
        assert_eq!(heading_from_mdeg(180_000), 205_887);
        // One radian back to bits: 2^32 / (2 pi) = 683565275.6.
        let bits = bits_from_fine_heading(HEADING_PER_RAD << FINE_SHIFT);
        assert!((bits - 683_565_276).abs() < 200, "{bits}");
        assert_eq!(scale_from_ppm(1_000_000), 65_536);
        assert_eq!(ppm_from_fine_scale(1 << 24), 1_000_000);
        // 1 rad/s is 57295.8 mdps.
        assert_eq!(mdps_from_fine_bias(1 << 24), 57_296);
        // Half a turn's heading units back to millidegrees, and a unit's square's.
        let half = heading_from_mdeg(180_000);
        assert!((((half * i64::from(MDEG_PER_HEADING_Q16)) >> 16) - 180_000).abs() <= 1);
        let squared = (half * half * MDEG2_PER_HEADING2_Q16) >> 16;
        assert!((squared - 180_000i64.pow(2)).abs() < 180_000i64.pow(2) / 10_000);
    }
}
