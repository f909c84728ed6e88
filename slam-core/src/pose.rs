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
        mm_of_um(self.x_um)
    }

    /// Position y rounded to millimetres.
    pub const fn y_mm(&self) -> i32 {
        mm_of_um(self.y_um)
    }

    /// Straight-line distance to `other` in micrometres (integer square root), saturating.
    pub fn distance_um(&self, other: &Pose) -> u32 {
        let dx = (self.x_um as i64) - (other.x_um as i64);
        let dy = (self.y_um as i64) - (other.y_um as i64);
        hypot(dx, dy).min(u32::MAX as u64) as u32
    }
}

/// The rigid motion of the map plane that carries one pose onto another: a turn by the
/// difference of their headings about the first pose's place, then the shift between them.
///
/// A tag fix of an old picture says where the robot was when the picture was taken.
/// Carrying the current pose (and the poses remembered since) by the same motion keeps the
/// odometry travelled since that moment, turned into the fix's heading.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct RigidMotion {
    /// The place turned about, in micrometres: the first pose's (its heading is in `turn`).
    from: (i32, i32),
    /// Where that place goes, in micrometres.
    to: (i32, i32),
    turn: Angle,
    sin: i32,
    cos: i32,
}

impl RigidMotion {
    /// The motion that carries `from` exactly onto `to`.
    pub fn carrying(from: &Pose, to: &Pose) -> RigidMotion {
        let turn = to.heading - from.heading;
        RigidMotion {
            from: (from.x_um, from.y_um),
            to: (to.x_um, to.y_um),
            turn,
            sin: turn.sin(),
            cos: turn.cos(),
        }
    }

    /// `pose` carried by the motion. `from` itself lands exactly on `to`, bit for bit.
    ///
    /// Never inlined: in a loop inside `Slam::step` its state spills to the stack (the M0+
    /// has eight low registers), which doubles its cost.
    #[inline(never)]
    pub fn apply(&self, pose: &Pose) -> Pose {
        let (Some(dx), Some(dy)) = (
            pose.x_um.checked_sub(self.from.0),
            pose.y_um.checked_sub(self.from.1),
        ) else {
            return self.apply_wide(pose);
        };
        if (dx.unsigned_abs() | dy.unsigned_abs()) >= 1 << 30 {
            return self.apply_wide(pose);
        }
        // Turning clockwise (the heading convention) by `t` takes the nose direction
        // (sin h, cos h) to (sin(h + t), cos(h + t)): (x, y) -> (x cos t + y sin t, y cos t - x sin t).
        // The poses a fix carries are ticks apart: 32-bit multiplies, and each sum of two
        // products of lengths under 2^30 fits 31 bits, so adding it to `to` saturating is
        // the clamp.
        let x = mul_q16_32(dx, self.cos) + mul_q16_32(dy, self.sin);
        let y = mul_q16_32(dy, self.cos) - mul_q16_32(dx, self.sin);
        Pose {
            x_um: self.to.0.saturating_add(x),
            y_um: self.to.1.saturating_add(y),
            heading: pose.heading + self.turn,
        }
    }

    /// [`RigidMotion::apply`] for poses a kilometre or more from `from`, in 64 bits.
    #[cold]
    #[inline(never)]
    fn apply_wide(&self, pose: &Pose) -> Pose {
        let dx = pose.x_um as i64 - self.from.0 as i64;
        let dy = pose.y_um as i64 - self.from.1 as i64;
        let x = self.to.0 as i64 + mul_q16(dx, self.cos) + mul_q16(dy, self.sin);
        let y = self.to.1 as i64 + mul_q16(dy, self.cos) - mul_q16(dx, self.sin);
        Pose {
            x_um: x.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            y_um: y.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            heading: pose.heading + self.turn,
        }
    }
}

/// Micrometres to millimetres rounded half away from zero, as `round_div(um, 1000)`, by
/// a multiply: the M0+ has no divider. `floor(n / 1000)` is `floor(n M / 2^38)` for
/// `M = ceil(2^38 / 1000)` and every `n` below `2^32` (`M 1000 - 2^38 = 56`, and `56 n`
/// stays below `2^38`).
const fn mm_of_um(um: i32) -> i32 {
    const M: u32 = 274_877_907;
    let n = um.unsigned_abs() + (UM_PER_MM as u32) / 2;
    let q = (crate::estimator::fixed::wide_mul_unsigned(n, M) >> 38) as i32;
    if um < 0 {
        -q
    } else {
        q
    }
}

/// `a / b` rounded half away from zero; `b` must be positive. The reference
/// [`mm_of_um`] is tested against.
#[cfg(test)]
const fn round_div(a: i64, b: i64) -> i64 {
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
#[cfg(test)]
const fn div_trunc(a: i64, b: i64) -> i64 {
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
///
/// A beam's length (under 16 m) times a sine or cosine (at most 1.0) fits in 32 bits, which
/// the Cortex-M0+ multiplies in one instruction instead of a 64-bit library call. Other
/// 32-bit lengths can take [`mul_q16_32`].
pub(crate) const fn mul_q16(a: i64, b: i32) -> i64 {
    if a > -(1 << 14) && a < (1 << 14) && b >= -(1 << 16) && b <= (1 << 16) {
        ((a as i32 * b + (1 << 15)) >> 16) as i64
    } else {
        (a * b as i64 + (1 << 15)) >> 16
    }
}

/// [`mul_q16`] of a 32-bit `a` (not `i32::MIN`) and a Q16 factor `b` within `+-1.0`,
/// exactly, in two 32-bit multiplies instead of a 64-bit library call: with `a` in halves,
/// `a = hi * 2^16 + lo`, `(a b + 2^15) >> 16 = hi b + ((lo b + 2^15) >> 16)`, and
/// `lo |b|` is below `2^32`.
pub(crate) const fn mul_q16_32(a: i32, b: i32) -> i32 {
    let (hi, lo) = (a >> 16, a as u32 & 0xFFFF);
    let part = lo * b.unsigned_abs();
    let low = if b >= 0 {
        ((part + (1 << 15)) >> 16) as i32
    } else {
        // floor((2^15 - part) / 2^16) = -ceil((part - 2^15) / 2^16).
        -(((part + (1 << 15) - 1) >> 16) as i32)
    };
    // `hi * b` alone can overflow (by one, at -2^15 x -2^16) where the sum does not.
    hi.wrapping_mul(b).wrapping_add(low)
}

/// `sqrt(x^2 + y^2)` rounded down, without overflow for any inputs (saturates at `u64::MAX`).
pub(crate) fn hypot(x: i64, y: i64) -> u64 {
    let (x, y) = (x.unsigned_abs(), y.unsigned_abs());
    if x < 1 << 15 && y < 1 << 15 {
        // Millimetre lengths on the mat: the squares' sum fits 31 bits, and the M0+ takes
        // a 32-bit root several times faster than a 128-bit square and a 64-bit root.
        let (x, y) = (x as u32, y as u32);
        return u64::from(isqrt32(x * x + y * y));
    }
    let (x, y) = (x as u128, y as u128);
    isqrt((x * x + y * y).min(u64::MAX as u128) as u64)
}

/// Integer square roots, rounded down, one per width: `$name(n: $t) -> $t`.
///
/// Bit by bit (two result bits' worth of shifts and one compare per step), with no
/// division: the M0+ has no divide at all, and a library one costs hundreds of cycles. The
/// 32-bit one is several times faster there than the 64-bit one on the same number.
macro_rules! isqrt_fn {
    ($(#[$doc:meta])* $name:ident, $t:ty) => {
        $(#[$doc])*
        pub(crate) const fn $name(n: $t) -> $t {
            let mut rem = n;
            let mut root: $t = 0;
            // The largest power of four not above n.
            let mut bit: $t = if n == 0 {
                0
            } else {
                1 << ((<$t>::BITS - 1 - n.leading_zeros()) & !1)
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
    };
}

isqrt_fn!(
    /// Integer square root of a `u64`, rounded down.
    isqrt,
    u64
);
isqrt_fn!(
    /// [`isqrt`] for 32-bit `n`.
    isqrt32,
    u32
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roots_in_32_bits_match_64() {
        for n in (0..70_000u32).chain([u32::MAX, u32::MAX - 1, 1 << 30, (1 << 31) - 1]) {
            assert_eq!(u64::from(isqrt32(n)), isqrt(u64::from(n)), "{n}");
        }
        let edge = (1 << 15) - 1;
        for (x, y) in [
            (edge, edge),
            (edge + 1, 3),
            (-edge, 0),
            (3, 4),
            (-30_000, 40_000),
        ] {
            // The floor of the root, by its defining inequality: r^2 <= n < (r + 1)^2.
            let (n, r) = ((x * x + y * y) as u64, hypot(x, y));
            assert!(r * r <= n && n < (r + 1) * (r + 1), "({x}, {y}): {r}");
        }
    }

    #[test]
    fn q16_products_match_64_bit_on_both_sides_of_the_32_bit_edge() {
        let one = 1 << 16;
        for a in [
            0i64,
            1,
            -1,
            4_000,
            -4_000,
            (1 << 14) - 1,
            -(1 << 14) + 1,
            1 << 14,
            -(1 << 14),
            1 << 30,
            -(1 << 30),
            123_456_789,
            -987_654_321,
            i32::MAX as i64,
            i32::MIN as i64 + 1,
            i32::MIN as i64,
            1 << 31,
            -(1 << 31) - 1,
        ] {
            for b in [
                0,
                1,
                -1,
                32_768,
                -32_768,
                one,
                -one,
                one + 1,
                -one - 1,
                i32::MAX,
                i32::MIN,
            ] {
                assert_eq!(mul_q16(a, b), (a * b as i64 + (1 << 15)) >> 16, "{a} x {b}");
            }
        }
    }

    #[test]
    fn q16_products_in_32_bits_are_exact() {
        let mut rng = crate::lcg::Lcg::new(0x9E37_79B9_7F4A_7C15u64);
        let mut next = move || rng.next_u64();
        for _ in 0..1_000_000 {
            let r = next();
            // Lengths of every width, factors across +-1.0 with its ends.
            let a = ((r >> 32) as i32 >> (r % 32)).max(i32::MIN + 1);
            let b = match (r >> 8) % 8 {
                0 => 1 << 16,
                1 => -(1 << 16),
                _ => ((r >> 12) % (1 << 17)) as i32 - (1 << 16),
            };
            let want = (a as i64 * b as i64 + (1 << 15)) >> 16;
            assert_eq!(mul_q16_32(a, b) as i64, want, "{a} x {b}");
        }
    }

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
        let mut n = 0x2545_F491u32;
        for k in 0..200_000u32 {
            n = n.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let um = (n as i32) >> (k % 31);
            assert_eq!(mm_of_um(um) as i64, round_div(um as i64, 1000), "{um}");
        }
        for um in [
            0,
            499,
            500,
            -499,
            -500,
            1_499,
            -1_500,
            i32::MAX,
            i32::MIN,
            i32::MIN + 1,
        ] {
            assert_eq!(mm_of_um(um) as i64, round_div(um as i64, 1000), "{um}");
        }
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
    fn rigid_motion_carries_from_onto_to_exactly() {
        let from = Pose {
            x_um: 812_345,
            y_um: -1_234_567,
            heading: Angle::from_bits(0xDEAD_BEEF),
        };
        let to = Pose {
            x_um: 700_001,
            y_um: 1_950_003,
            heading: Angle::from_bits(0x1234_5678),
        };
        assert_eq!(RigidMotion::carrying(&from, &to).apply(&from), to);
        assert_eq!(RigidMotion::carrying(&from, &from).apply(&to), to);
    }

    #[test]
    fn rigid_motion_in_32_bits_matches_64() {
        let mut rng = crate::lcg::Lcg::new(0x2545_F491_4F6C_DD1Du64);
        let mut next = move || rng.next_u64();
        let pose = |r: u64, spread: u32| Pose {
            x_um: (r >> 32) as i32 >> spread,
            y_um: r as i32 >> spread,
            heading: Angle::from_bits((r >> 16) as u32),
        };
        for _ in 0..200_000 {
            // Poses millimetres, metres or kilometres apart, up to the i32 limits.
            let spread = (next() % 24) as u32;
            let (from, to, p) = (pose(next(), spread), pose(next(), 0), pose(next(), spread));
            let motion = RigidMotion::carrying(&from, &to);
            assert_eq!(motion.apply(&p), motion.apply_wide(&p), "{motion:?} {p:?}");
        }
    }

    #[test]
    fn rigid_motion_turns_clockwise_like_headings() {
        // Believed at the origin facing +y, 100 mm up the mat since the picture; the fix
        // says the robot faced +x then. The 100 mm were driven along +x, and it faces +x.
        let then = Pose::from_mm_mdeg(0, 0, 0);
        let now = Pose::from_mm_mdeg(0, 100, 0);
        let fix = Pose::from_mm_mdeg(500, 500, 90_000);
        let carried = RigidMotion::carrying(&then, &fix).apply(&now);
        assert_eq!(carried, Pose::from_mm_mdeg(600, 500, 90_000));
        // A point to the robot's right (+x when facing +y) ends up to its right again (-y
        // when facing +x), and a quarter turn back undoes it.
        let right = Pose::from_mm_mdeg(100, 0, 0);
        let carried = RigidMotion::carrying(&then, &fix).apply(&right);
        assert_eq!(carried, Pose::from_mm_mdeg(500, 400, 90_000));
        let back = RigidMotion::carrying(&fix, &then).apply(&carried);
        assert_eq!(back, right);
    }

    #[test]
    fn rigid_motion_across_north() {
        // Headings either side of 0/360: a 4 degree turn anticlockwise across north.
        let then = Pose::from_mm_mdeg(1000, 1000, 2_000);
        let fix = Pose::from_mm_mdeg(1000, 1000, -2_000);
        let now = Pose::from_mm_mdeg(1000, 1100, 359_000);
        let carried = RigidMotion::carrying(&then, &fix).apply(&now);
        assert_eq!(carried.heading.to_millidegrees(), -5_000);
        // 100 mm along +y, turned 4 degrees anticlockwise: x -6.98 mm, y +99.76 mm.
        assert_eq!((carried.x_mm(), carried.y_mm()), (993, 1100));
        assert!((carried.x_um - 993_024).abs() <= 2, "{carried:?}");
        assert!((carried.y_um - 1_099_756).abs() <= 2, "{carried:?}");
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
