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

    /// `(self.sin(), self.cos())`, bit for bit, with the quadrant worked out once: the
    /// cosine's mirrored argument is the sine's complement, its sign negative in the
    /// second and third quadrants.
    pub fn sin_cos(self) -> (i32, i32) {
        let quadrant = self.0 >> 30;
        let within = self.0 & ((1 << 30) - 1);
        let other = (1u32 << 30) - within;
        let (x_sin, x_cos) = if quadrant & 1 == 1 {
            (other, within)
        } else {
            (within, other)
        };
        let (sin, cos) = (quarter_sine(x_sin), quarter_sine(x_cos));
        (
            if quadrant >= 2 { -sin } else { sin },
            if quadrant == 1 || quadrant == 2 {
                -cos
            } else {
                cos
            },
        )
    }

    /// The direction of the vector `(x, y)` in the heading convention: `atan2(x, y)`,
    /// 0 along +y, a quarter turn along +x. `(0, 0)` gives zero.
    ///
    /// Integer CORDIC in vectoring mode: 24 iterations, error below 1e-5 degrees
    /// plus the input's own quantisation.
    pub fn of_vector(x: i64, y: i64) -> Angle {
        if let (Ok(x), Ok(y)) = (i32::try_from(x), i32::try_from(y)) {
            return Angle::of_vector32(x, y);
        }
        // Scale so the larger component sits in [2^28, 2^29): room for the CORDIC gain
        // (1.65). Only lengths beyond 32 bits come here: a 64-bit variable shift is a
        // library call on the M0+. CORDIC measures from its x axis, our +y.
        let (mut vx, mut vy) = (y, x);
        let big = vx.unsigned_abs().max(vy.unsigned_abs());
        let shift = (64 - big.leading_zeros()) - 29;
        vx >>= shift;
        vy >>= shift;
        cordic(vx as i32, vy as i32)
    }

    /// [`Angle::of_vector`] of 32-bit components, all in 32-bit registers.
    fn of_vector32(x: i32, y: i32) -> Angle {
        if x == 0 && y == 0 {
            return Angle::ZERO;
        }
        // The larger component scaled to [2^28, 2^29], as in `of_vector`; CORDIC's x
        // axis is our +y.
        let (vx, vy) = (y, x);
        let big = vx.unsigned_abs().max(vy.unsigned_abs());
        let width = bit_width(big);
        if width > 29 {
            cordic(vx >> (width - 29), vy >> (width - 29))
        } else {
            cordic(vx << (29 - width), vy << (29 - width))
        }
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

/// A signed turn of `bits` binary units (2^32 a turn, as [`Angle::diff`] gives it), in
/// millidegrees, rounded down.
pub fn mdeg_of_bits(bits: i32) -> i64 {
    (i64::from(bits) * 360_000) >> 32
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

/// `(sin, cos)` in Q16 of the direction of `(x, y)`: those of [`Angle::of_vector`]`(x, y)`,
/// without the angle, as `(x, y) / |(x, y)|`. `(0, 0)` gives `(0, TRIG_ONE)`, as zero does.
///
/// For a caller that only wants a direction (a camera ray from its pixel column): no
/// CORDIC and no division, a few multiplies and a table of inverse square roots, several
/// times cheaper on the M0+ than `of_vector` then `sin` and `cos`. Error below 2e-5 while
/// both components are within `2^15` in magnitude, where the scaling below is exact; larger
/// ones are first cut to 15 bits, which adds up to 6.2e-5 more.
pub fn sin_cos_of_vector(x: i32, y: i32) -> (i32, i32) {
    let big = x.unsigned_abs().max(y.unsigned_abs());
    if big == 0 {
        return (0, TRIG_ONE);
    }
    // Scaled so the larger magnitude sits in [2^14, 2^15): the squares' sum fits 31 bits.
    // Cutting towards zero keeps every magnitude below 2^15.
    let width = bit_width(big);
    let (a, b) = if width > 15 {
        let cut = |v: i32| {
            let m = (v.unsigned_abs() >> (width - 15)) as i32;
            if v < 0 {
                -m
            } else {
                m
            }
        };
        (cut(x), cut(y))
    } else {
        (x << (15 - width), y << (15 - width))
    };
    // In [2^28, 2^31); times an even power of two, `m / 2^30` lands in [1, 4).
    let m = (a * a) as u32 + (b * b) as u32;
    let (normal, doubled) = if m < 1 << 30 { (m << 2, 1) } else { (m, 0) };
    let root = inverse_root(normal);
    // v / sqrt(m) = v * 2^doubled * root / 2^39, so in Q16 a shift by 23 - doubled: the
    // root's top 16 bits and its low 8 in two products, each of which fits 31 bits.
    let shift = 15 - doubled;
    let half = 1 << (shift - 1);
    let (whole, frac) = (root >> 8, root & 0xFF);
    let unit = |v: i32| (v * whole + ((v * frac) >> 8) + half) >> shift;
    (unit(a), unit(b))
}

/// The bits `n` takes, `32 - n.leading_zeros()`, by halving steps: a count of leading
/// zeros is a library call on the M0+.
fn bit_width(n: u32) -> u32 {
    let (mut top, mut width) = (n, 0);
    for step in [16, 8, 4, 2, 1] {
        if top >= 1 << step {
            top >>= step;
            width += step;
        }
    }
    width + top
}

/// `2^24 / sqrt(n / 2^30)` for `n` in `[2^30, 2^32)`, in `[2^23, 2^24]`: a table with linear
/// interpolation, 128 segments over each octave (error below 6e-6 of the value).
fn inverse_root(n: u32) -> i32 {
    // The segment, and 12 bits of the way along it.
    let (index, frac) = if n < 1 << 31 {
        (((n - (1 << 30)) >> 23) as usize, (n >> 11) & 0xFFF)
    } else {
        (128 + ((n - (1 << 31)) >> 24) as usize, (n >> 12) & 0xFFF)
    };
    let at = |i: usize| INVERSE_ROOT_TABLE.get(i).map_or(1 << 23, |&v| v as i32);
    let (lo, hi) = (at(index), at(index + 1));
    // Neighbours differ by at most 2^16: the product fits.
    lo - (((lo - hi) * frac as i32 + (1 << 11)) >> 12)
}

/// `round(2^24 / sqrt(x))` for `x = 1 + i / 128` (`i <= 128`) and `x = i / 64`
/// (`i >= 128`), that is over `[1, 4]`; generated at compile time by integer roots.
static INVERSE_ROOT_TABLE: [u32; 257] = {
    let mut table = [0u32; 257];
    let mut i = 0;
    while i < 257 {
        // round(sqrt(v)) = ceil(floor(sqrt(4 v)) / 2), with v = 2^48 / x.
        let four_v = if i <= 128 {
            (1u64 << 57) / (128 + i as u64)
        } else {
            (1u64 << 56) / i as u64
        };
        table[i] = crate::pose::isqrt(four_v).div_ceil(2) as u32;
        i += 1;
    }
    table
};

/// A direction with its sine and cosine, for a caller that needs all three.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Direction {
    /// The direction as an angle.
    pub angle: Angle,
    /// Its sine in Q16 (`TRIG_ONE` is 1.0).
    pub sin: i32,
    /// Its cosine in Q16.
    pub cos: i32,
}

impl Direction {
    /// The direction of `(x, y)`, as [`Angle::of_vector`] has it (`(0, 0)` is zero), with
    /// [`sin_cos_of_vector`]'s sine and cosine; the angle from those by a table of
    /// arcsines. No CORDIC and no division: a fraction of `of_vector`'s cycles on the M0+.
    ///
    /// The angle is within 2e-3 degrees of `atan2(x, y)` while both components are within
    /// `2^15` (the sine and cosine's error, through an arcsine's slope of at most 1.42, and
    /// the table's own), 6e-3 degrees for larger ones (cut to 15 bits first): coarser than
    /// `of_vector`'s 1.5e-5 degrees, for a caller whose inputs are no finer (the tag fix's
    /// 15-bit baselines resolve 2.5e-3 degrees).
    pub fn of_vector(x: i32, y: i32) -> Direction {
        let (sin, cos) = sin_cos_of_vector(x, y);
        // Within the octant either side of the y axis the angle is asin(|sin|), in the
        // octants either side of the x axis a quarter turn less asin(|cos|): so the
        // table's argument stays below 1/sqrt(2), where the arcsine is gentle.
        let (s, c) = (sin.unsigned_abs(), cos.unsigned_abs());
        let first = if s <= c {
            arcsine(s)
        } else {
            Angle::QUARTER_TURN.0 - arcsine(c)
        };
        // Then into the quadrant of (sin, cos).
        let half = if cos < 0 {
            Angle::HALF_TURN.0 - first
        } else {
            first
        };
        let angle = if sin < 0 {
            Angle(half).neg()
        } else {
            Angle(half)
        };
        Direction { angle, sin, cos }
    }
}

/// `asin(u / 2^16)` in binary angle units, for `u` at most `46342` (just over `2^16 / sqrt(2)`):
/// a table with linear interpolation (error below 3.9e-6 rad).
fn arcsine(u: u32) -> u32 {
    let (index, frac) = ((u >> 8) as usize, u & 0xFF);
    let at = |i: usize| {
        ARCSINE_TABLE
            .get(i)
            .copied()
            .unwrap_or(Angle::QUARTER_TURN.0 / 2)
    };
    let (lo, hi) = (at(index), at(index + 1));
    // Neighbours differ by under 2^22: the product fits.
    lo + (((hi - lo) * frac + (1 << 7)) >> 8)
}

/// `asin(i / 256)` in binary angle units for `i` in `0..=182` (to just past 1/sqrt(2)),
/// generated at compile time by the CORDIC on `(i, sqrt(256^2 - i^2))`; the first is zero
/// exactly (where the CORDIC leaves a residual of 51 units), so that the axes are exact.
static ARCSINE_TABLE: [u32; 183] = {
    let mut table = [0u32; 183];
    let mut i = 1;
    while i < 183 {
        // Scaled by 2^20: both components below 2^28, as the CORDIC wants.
        let x = (i as u64) << 20;
        let y = crate::pose::isqrt((1u64 << 56) - x * x);
        table[i] = cordic(y as i32, x as i32).0;
        i += 1;
    }
    table
};

/// The angle of `(vx, vy)` from CORDIC's x axis, both components at most `2^29` in
/// magnitude (the gain, 1.65, then keeps them inside 31 bits): the loop runs in 32-bit
/// registers, where the M0+ shifts in one instruction. `const`, for the arcsine table.
const fn cordic(mut vx: i32, mut vy: i32) -> Angle {
    // Rotate into the right half plane first.
    let mut acc: u32 = 0;
    if vx < 0 {
        acc = Angle::HALF_TURN.0;
        vx = -vx;
        vy = -vy;
    }
    let mut i = 0;
    while i < ATAN_TABLE.len() {
        let (dx, dy) = (vy >> i, vx >> i);
        if vy > 0 {
            vx += dx;
            vy -= dy;
            acc = acc.wrapping_add(ATAN_TABLE[i]);
        } else {
            vx -= dx;
            vy += dy;
            acc = acc.wrapping_sub(ATAN_TABLE[i]);
        }
        i += 1;
    }
    Angle(acc)
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
const ATAN_TABLE: [u32; 24] = [
    536870912, 316933406, 167458907, 85004756, 42667331, 21354465, 10679838, 5340245, 2670163,
    1335087, 667544, 333772, 166886, 83443, 41722, 20861, 10430, 5215, 2608, 1304, 652, 326, 163,
    81,
];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_is_the_sine_and_the_cosine() {
        let edges = [
            0,
            1,
            (1 << 30) - 1,
            1 << 30,
            (1 << 30) + 1,
            1 << 31,
            3 << 30,
            u32::MAX,
        ];
        let steps = (0..1u32 << 20).map(|k| k << 12 | (k.wrapping_mul(2_654_435_761) >> 20));
        for bits in edges.into_iter().chain(steps) {
            let a = Angle::from_bits(bits);
            assert_eq!(a.sin_cos(), (a.sin(), a.cos()), "{bits}");
        }
    }

    #[test]
    fn bit_width_is_the_leading_zeros_one() {
        let mut n = 0x9E37_79B9u32;
        for k in 0..100_000u32 {
            n = n.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let v = n >> (k % 32);
            assert_eq!(bit_width(v), 32 - v.leading_zeros(), "{v}");
        }
        for v in [0, 1, 2, 3, u32::MAX, 1 << 31, (1 << 31) - 1] {
            assert_eq!(bit_width(v), 32 - v.leading_zeros(), "{v}");
        }
    }

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
