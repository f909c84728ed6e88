//! Headings as wrapping binary angles, with table sine and integer atan2.
//!
//! A full turn is 2^32, so heading arithmetic wraps for free and never needs
//! a modulo; the M0+ has no FPU, so nothing here touches floating point.
//!
//! Convention (the seed's): a heading is measured from the +y axis (the mat's
//! far wall) clockwise towards +x. Facing `h`, the nose points along
//! `(sin h, cos h)` and the robot's right-hand side along `(cos h, -sin h)`.

use core::ops::{Add, AddAssign, Neg, Sub};

/// `1.0` in the Q16 fixed point that [`Angle::sin`] and [`Angle::cos`] return.
pub const TRIG_ONE: i32 = 1 << 16;

/// Millidegrees in a full turn.
const MDEG_PER_TURN: i64 = 360_000;

/// A wrapping binary angle: `2^32` is one full turn.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Angle(u32);

impl Angle {
    /// Facing +y.
    pub const ZERO: Angle = Angle(0);
    /// A quarter turn, 90 degrees.
    pub const QUARTER_TURN: Angle = Angle(1 << 30);
    /// A half turn, 180 degrees.
    pub const HALF_TURN: Angle = Angle(1 << 31);

    /// The angle whose raw binary value is `bits` (`2^32` per turn).
    pub const fn from_bits(bits: u32) -> Angle {
        Angle(bits)
    }

    /// The raw binary value (`2^32` per turn).
    pub const fn bits(self) -> u32 {
        self.0
    }

    /// The angle as a signed binary value in `[-2^31, 2^31)`: negative is anticlockwise.
    pub const fn signed_bits(self) -> i32 {
        self.0 as i32
    }

    /// An angle given in millidegrees, any sign and any number of turns; rounded to the nearest bit.
    pub const fn from_millidegrees(mdeg: i64) -> Angle {
        let turns = mdeg.rem_euclid(MDEG_PER_TURN);
        let bits = ((turns << 32) + MDEG_PER_TURN / 2) / MDEG_PER_TURN;
        Angle(bits as u32)
    }

    /// The angle in millidegrees, in `[-180000, 180000)`, rounded to nearest.
    pub const fn to_millidegrees(self) -> i32 {
        let signed = self.signed_bits() as i64;
        let scaled = signed * MDEG_PER_TURN + (1 << 31);
        (scaled >> 32) as i32
    }

    /// The angle in microdegrees, in `[-180e6, 180e6)`, rounded to nearest.
    pub const fn to_microdegrees(self) -> i32 {
        let signed = self.signed_bits() as i64;
        let scaled = signed * (MDEG_PER_TURN * 1000) + (1 << 31);
        (scaled >> 32) as i32
    }

    /// Sine in Q16 (`TRIG_ONE` is 1.0); table lookup with linear interpolation, error below 2e-5.
    pub fn sin(self) -> i32 {
        let quadrant = self.0 >> 30;
        let within = self.0 & ((1 << 30) - 1);
        // Mirror the second and fourth quadrants onto the first.
        let x = if quadrant & 1 == 1 {
            (1u32 << 30) - within
        } else {
            within
        };
        let magnitude = quarter_sine(x);
        if quadrant >= 2 {
            -magnitude
        } else {
            magnitude
        }
    }

    /// Cosine in Q16, as `sin(self + 90 degrees)`.
    pub fn cos(self) -> i32 {
        (self + Angle::QUARTER_TURN).sin()
    }

    /// The direction of the vector `(x, y)` in the heading convention: `atan2(x, y)`,
    /// 0 along +y, a quarter turn along +x. `(0, 0)` gives zero.
    ///
    /// Integer CORDIC in vectoring mode: 24 iterations, error below 1e-5 degrees
    /// plus the input's own quantisation.
    pub fn of_vector(x: i64, y: i64) -> Angle {
        if x == 0 && y == 0 {
            return Angle::ZERO;
        }
        // Scale so the larger component sits in [2^28, 2^29): room for the CORDIC gain (1.65).
        // CORDIC measures from its x axis, our +y. Inputs that fit 29 bits (every length
        // on the robot) scale up in 32 bits: a 64-bit variable shift is a library call on
        // the M0+.
        let (mut vx, mut vy) = if x.unsigned_abs() < 1 << 29 && y.unsigned_abs() < 1 << 29 {
            let (vx, vy) = (y as i32, x as i32);
            let big = vx.unsigned_abs().max(vy.unsigned_abs());
            let shift = 29 - (32 - big.leading_zeros());
            (vx << shift, vy << shift)
        } else {
            let (mut vx, mut vy) = (y, x);
            let big = vx.unsigned_abs().max(vy.unsigned_abs());
            let width = 64 - big.leading_zeros() as i32;
            let shift = width - 29;
            if shift > 0 {
                vx >>= shift;
                vy >>= shift;
            } else {
                vx <<= -shift;
                vy <<= -shift;
            }
            (vx as i32, vy as i32)
        };
        // Both now fit 30 bits, and the CORDIC's gain (1.65) keeps them inside 31: the loop
        // runs in 32-bit registers, where the M0+ shifts in one instruction.
        // Rotate into the right half plane first.
        let mut acc: u32 = 0;
        if vx < 0 {
            acc = Angle::HALF_TURN.0;
            vx = -vx;
            vy = -vy;
        }
        for (i, step) in ATAN_TABLE.iter().enumerate() {
            let (dx, dy) = (vy >> i, vx >> i);
            if vy > 0 {
                vx += dx;
                vy -= dy;
                acc = acc.wrapping_add(*step);
            } else {
                vx -= dx;
                vy += dy;
                acc = acc.wrapping_sub(*step);
            }
        }
        Angle(acc)
    }

    /// `self` rotated by `other` with wrap-around.
    pub const fn wrapping_add(self, other: Angle) -> Angle {
        Angle(self.0.wrapping_add(other.0))
    }

    /// The signed difference `self - other` as the shortest turn, in binary units.
    pub const fn diff(self, other: Angle) -> i32 {
        self.0.wrapping_sub(other.0) as i32
    }
}

impl Add for Angle {
    type Output = Angle;
    fn add(self, rhs: Angle) -> Angle {
        Angle(self.0.wrapping_add(rhs.0))
    }
}

impl AddAssign for Angle {
    fn add_assign(&mut self, rhs: Angle) {
        self.0 = self.0.wrapping_add(rhs.0);
    }
}

impl Sub for Angle {
    type Output = Angle;
    fn sub(self, rhs: Angle) -> Angle {
        Angle(self.0.wrapping_sub(rhs.0))
    }
}

impl Neg for Angle {
    type Output = Angle;
    fn neg(self) -> Angle {
        Angle(self.0.wrapping_neg())
    }
}

/// `sin` of `x` quarter-turn units (`2^30` = 90 degrees), `x` in `[0, 2^30]`, in Q16.
fn quarter_sine(x: u32) -> i32 {
    let index = (x >> 22) as usize; // 256 segments
    let frac = ((x >> 6) & 0xFFFF) as i32; // 16 bits within the segment
    let lo = SINE_TABLE.get(index).copied().unwrap_or(TRIG_ONE);
    let hi = SINE_TABLE.get(index + 1).copied().unwrap_or(TRIG_ONE);
    lo + (((hi - lo) * frac + (1 << 15)) >> 16)
}

/// `sin(i / 256 * 90 degrees)` in Q16 for `i` in `0..=256`.
static SINE_TABLE: [i32; 257] = [
    0, 402, 804, 1206, 1608, 2010, 2412, 2814, 3216, 3617, 4019, 4420, 4821, 5222, 5623, 6023,
    6424, 6824, 7224, 7623, 8022, 8421, 8820, 9218, 9616, 10014, 10411, 10808, 11204, 11600, 11996,
    12391, 12785, 13180, 13573, 13966, 14359, 14751, 15143, 15534, 15924, 16314, 16703, 17091,
    17479, 17867, 18253, 18639, 19024, 19409, 19792, 20175, 20557, 20939, 21320, 21699, 22078,
    22457, 22834, 23210, 23586, 23961, 24335, 24708, 25080, 25451, 25821, 26190, 26558, 26925,
    27291, 27656, 28020, 28383, 28745, 29106, 29466, 29824, 30182, 30538, 30893, 31248, 31600,
    31952, 32303, 32652, 33000, 33347, 33692, 34037, 34380, 34721, 35062, 35401, 35738, 36075,
    36410, 36744, 37076, 37407, 37736, 38064, 38391, 38716, 39040, 39362, 39683, 40002, 40320,
    40636, 40951, 41264, 41576, 41886, 42194, 42501, 42806, 43110, 43412, 43713, 44011, 44308,
    44604, 44898, 45190, 45480, 45769, 46056, 46341, 46624, 46906, 47186, 47464, 47741, 48015,
    48288, 48559, 48828, 49095, 49361, 49624, 49886, 50146, 50404, 50660, 50914, 51166, 51417,
    51665, 51911, 52156, 52398, 52639, 52878, 53114, 53349, 53581, 53812, 54040, 54267, 54491,
    54714, 54934, 55152, 55368, 55582, 55794, 56004, 56212, 56418, 56621, 56823, 57022, 57219,
    57414, 57607, 57798, 57986, 58172, 58356, 58538, 58718, 58896, 59071, 59244, 59415, 59583,
    59750, 59914, 60075, 60235, 60392, 60547, 60700, 60851, 60999, 61145, 61288, 61429, 61568,
    61705, 61839, 61971, 62101, 62228, 62353, 62476, 62596, 62714, 62830, 62943, 63054, 63162,
    63268, 63372, 63473, 63572, 63668, 63763, 63854, 63944, 64031, 64115, 64197, 64277, 64354,
    64429, 64501, 64571, 64639, 64704, 64766, 64827, 64884, 64940, 64993, 65043, 65091, 65137,
    65180, 65220, 65259, 65294, 65328, 65358, 65387, 65413, 65436, 65457, 65476, 65492, 65505,
    65516, 65525, 65531, 65535, 65536,
];

/// `atan(2^-i)` in binary angle units (`2^32` per turn), for the CORDIC.
static ATAN_TABLE: [u32; 24] = [
    536870912, 316933406, 167458907, 85004756, 42667331, 21354465, 10679838, 5340245, 2670163,
    1335087, 667544, 333772, 166886, 83443, 41722, 20861, 10430, 5215, 2608, 1304, 652, 326, 163,
    81,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn millidegrees_round_trip() {
        for mdeg in [-179_999, -90_000, -1, 0, 1, 45_000, 90_000, 179_999] {
            assert_eq!(
                Angle::from_millidegrees(mdeg).to_millidegrees() as i64,
                mdeg
            );
        }
        assert_eq!(
            Angle::from_millidegrees(360_000 + 90_000),
            Angle::QUARTER_TURN
        );
        assert_eq!(Angle::from_millidegrees(-270_000), Angle::QUARTER_TURN);
    }

    #[test]
    fn cardinal_sines() {
        assert_eq!(Angle::ZERO.sin(), 0);
        assert_eq!(Angle::QUARTER_TURN.sin(), TRIG_ONE);
        assert_eq!(Angle::HALF_TURN.sin(), 0);
        assert_eq!((-Angle::QUARTER_TURN).sin(), -TRIG_ONE);
        assert_eq!(Angle::ZERO.cos(), TRIG_ONE);
        assert_eq!(Angle::HALF_TURN.cos(), -TRIG_ONE);
    }

    #[test]
    fn vector_directions() {
        assert_eq!(Angle::of_vector(0, 1000).to_millidegrees(), 0);
        assert_eq!(Angle::of_vector(1000, 0).to_millidegrees(), 90_000);
        assert_eq!(Angle::of_vector(0, -1000).to_millidegrees(), -180_000);
        assert_eq!(Angle::of_vector(-1000, 0).to_millidegrees(), -90_000);
        assert_eq!(Angle::of_vector(1000, 1000).to_millidegrees(), 45_000);
        assert_eq!(Angle::of_vector(0, 0), Angle::ZERO);
    }

    #[test]
    fn diff_is_shortest_turn() {
        let a = Angle::from_millidegrees(170_000);
        let b = Angle::from_millidegrees(-170_000);
        assert_eq!(
            Angle::from_bits(a.diff(b) as u32).to_millidegrees(),
            -20_000
        );
    }
}
