//! The robot's pose in the map frame, in integers.

use crate::angle::Angle;

/// Micrometres in a millimetre.
pub const UM_PER_MM: i32 = 1000;

/// Where the robot is and which way it faces, in the map frame.
///
/// Position is in micrometres so that a tick's odometry (a few millimetres) is
/// integrated without rounding drift; `i32` still spans +-2 km.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// Position along the mat's x axis, in micrometres.
    pub x_um: i32,
    /// Position along the mat's y axis (towards the far wall), in micrometres.
    pub y_um: i32,
    /// Heading, clockwise from +y.
    pub heading: Angle,
}

impl Pose {
    /// A pose from millimetres and millidegrees, the units of configuration files.
    pub const fn from_mm_mdeg(x_mm: i32, y_mm: i32, heading_mdeg: i64) -> Pose {
        Pose {
            x_um: x_mm.saturating_mul(UM_PER_MM),
            y_um: y_mm.saturating_mul(UM_PER_MM),
            heading: Angle::from_millidegrees(heading_mdeg),
        }
    }

    /// Position x rounded to millimetres.
    pub const fn x_mm(&self) -> i32 {
        round_div(self.x_um as i64, UM_PER_MM as i64) as i32
    }

    /// Position y rounded to millimetres.
    pub const fn y_mm(&self) -> i32 {
        round_div(self.y_um as i64, UM_PER_MM as i64) as i32
    }

    /// Straight-line distance to `other` in micrometres (integer square root), saturating.
    pub fn distance_um(&self, other: &Pose) -> u32 {
        let dx = (self.x_um as i64) - (other.x_um as i64);
        let dy = (self.y_um as i64) - (other.y_um as i64);
        hypot(dx, dy).min(u32::MAX as u64) as u32
    }
}

/// `a / b` rounded half away from zero; `b` must be positive.
pub(crate) const fn round_div(a: i64, b: i64) -> i64 {
    if a >= 0 {
        div_trunc(a + b / 2, b)
    } else {
        div_trunc(a - b / 2, b)
    }
}

/// Whether `x` fits in an `i32`.
const fn fits_i32(x: i64) -> bool {
    x >= i32::MIN as i64 && x <= i32::MAX as i64
}

/// `a / b` truncated toward zero; `b` must be positive.
///
/// In 32 bits whenever both fit, as they do for every length on the robot: the
/// Cortex-M0+ has no divide instruction, and its software 64-bit division costs several
/// times the 32-bit one (which the RP2040's hardware divider can also serve).
pub(crate) const fn div_trunc(a: i64, b: i64) -> i64 {
    if fits_i32(a) && fits_i32(b) {
        (a as i32 / b as i32) as i64
    } else {
        a / b
    }
}

/// `a / b` rounded toward negative infinity; `b` must be positive. 32-bit when both fit,
/// as [`div_trunc`].
pub(crate) const fn div_floor(a: i64, b: i64) -> i64 {
    if fits_i32(a) && fits_i32(b) {
        (a as i32).div_euclid(b as i32) as i64
    } else {
        a.div_euclid(b)
    }
}

/// `a * b >> 16` rounded to nearest, in 64 bits: multiplies a length by a Q16 factor.
pub(crate) const fn mul_q16(a: i64, b: i32) -> i64 {
    (a * b as i64 + (1 << 15)) >> 16
}

/// `sqrt(x^2 + y^2)` rounded down, without overflow for any inputs (saturates at `u64::MAX`).
pub(crate) fn hypot(x: i64, y: i64) -> u64 {
    let (x, y) = (x.unsigned_abs() as u128, y.unsigned_abs() as u128);
    isqrt((x * x + y * y).min(u64::MAX as u128) as u64)
}

/// Integer square root, rounded down.
///
/// Bit by bit (two result bits' worth of shifts and one compare per step), with no
/// division: the M0+ has no 64-bit divide, and a library one costs hundreds of cycles.
pub(crate) fn isqrt(n: u64) -> u64 {
    let mut rem = n;
    let mut root = 0u64;
    // The largest power of four not above n.
    let mut bit = if n == 0 {
        0
    } else {
        1u64 << ((63 - n.leading_zeros()) & !1)
    };
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn divisions_match_64_bit_on_both_sides_of_the_32_bit_edge() {
        let edge = i32::MAX as i64;
        let numerators = [
            0,
            1,
            -1,
            49,
            -49,
            50,
            -50,
            51,
            -51,
            999_499,
            -999_500,
            edge,
            edge + 1,
            -edge - 1,
            -edge - 2,
            i64::MAX / 3,
            i64::MIN / 3,
        ];
        for a in numerators {
            for b in [1i64, 2, 50, 1000, edge, edge + 7] {
                assert_eq!(div_trunc(a, b), a / b, "{a} / {b}");
                assert_eq!(div_floor(a, b), a.div_euclid(b), "{a} floor/ {b}");
            }
        }
        assert_eq!(round_div(-1_500, 1_000), -2);
        assert_eq!(round_div(1_499, 1_000), 1);
    }

    #[test]
    fn isqrt_exact_and_floor() {
        for n in [
            0u64,
            1,
            2,
            3,
            4,
            15,
            16,
            17,
            1 << 40,
            (1 << 40) + 1,
            u32::MAX as u64,
            (1 << 62) - 1,
            u64::MAX - 1,
            u64::MAX,
        ] {
            let r = isqrt(n) as u128;
            let n = n as u128;
            assert!(r * r <= n && (r + 1) * (r + 1) > n, "isqrt({n}) = {r}");
        }
        for n in 0..100_000u64 {
            let r = isqrt(n);
            assert!(r * r <= n && (r + 1) * (r + 1) > n, "isqrt({n}) = {r}");
        }
    }

    #[test]
    fn millimetre_rounding() {
        let p = Pose {
            x_um: 1500,
            y_um: -1500,
            heading: Angle::ZERO,
        };
        assert_eq!((p.x_mm(), p.y_mm()), (2, -2));
        assert_eq!(
            Pose::from_mm_mdeg(700, 500, 0).distance_um(&Pose::from_mm_mdeg(1000, 900, 0)),
            500_000
        );
    }
}
