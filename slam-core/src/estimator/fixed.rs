//! The integer arithmetic the filter runs on, shaped for the Cortex-M0+: it multiplies
//! 32 bits by 32 in one instruction and calls a library routine for anything wider, and
//! has no divider at all. Products of operands that fit 32 bits take the fast path; a
//! division happens once per scalar update, as a reciprocal every gain then multiplies by.

/// Whether `x` fits an `i32`: its high word is its low word's sign (a shift and a
/// compare on the M0+, with no constants to hold).
#[inline]
pub const fn fits_i32(x: i64) -> bool {
    x as i32 as i64 == x
}

/// `a * b` for 32-bit `a` and `b`, from four 16 x 16 products: the M0+ multiplies only
/// 32 x 32 to 32 bits, and a 64-bit `*` is a library call several times slower.
#[inline(always)]
pub fn wide_mul(a: i32, b: i32) -> i64 {
    let u = wide_mul_unsigned(a.unsigned_abs(), b.unsigned_abs()) as i64;
    if (a < 0) != (b < 0) {
        -u
    } else {
        u
    }
}

/// `a * b` for unsigned 32-bit `a` and `b` (as [`wide_mul`]).
#[inline(always)]
pub const fn wide_mul_unsigned(a: u32, b: u32) -> u64 {
    let (ah, al) = (a >> 16, a & 0xFFFF);
    let (bh, bl) = (b >> 16, b & 0xFFFF);
    let (mid, mid_carry) = (ah * bl).overflowing_add(al * bh);
    let (low, low_carry) = (al * bl).overflowing_add(mid << 16);
    let high = ah * bh + (mid >> 16) + ((mid_carry as u32) << 16) + low_carry as u32;
    ((high as u64) << 32) | low as u64
}

/// `p / 2^shift` rounded to nearest, for `shift` below 63, worked in 32-bit halves: the
/// M0+ has no 64-bit shifter, and the library's shifts are calls.
#[inline(always)]
pub fn round_shift(p: i64, shift: u32) -> i64 {
    if shift == 0 {
        return p;
    }
    // floor((p + 2^(s-1)) / 2^s) is floor((floor(p / 2^(s-1)) + 1) / 2).
    let s = shift - 1;
    let (hi, lo) = ((p >> 32) as i32, p as u32);
    let q = if s == 0 {
        p
    } else if s < 32 {
        (i64::from(hi >> s) << 32) | i64::from((lo >> s) | ((hi as u32) << (32 - s)))
    } else {
        i64::from(hi >> (s - 32))
    };
    (q + 1) >> 1
}

/// `a * b / 2^shift`, rounded to nearest; saturating.
#[inline]
pub fn mul_shift(a: i64, b: i64, shift: u32) -> i64 {
    if fits_i32(a) && fits_i32(b) && shift < 62 {
        // |a b| <= 2^62: the product and the rounding bias fit.
        round_shift(wide_mul(a as i32, b as i32), shift)
    } else {
        wide_mul_shift(a, b, shift)
    }
}

/// [`mul_shift`] as one shared call rather than inlined: for code run once a match, not
/// every step, where a hundred inlined copies cost flash and save nothing that counts.
#[inline(never)]
pub fn mul_shift_call(a: i64, b: i64, shift: u32) -> i64 {
    mul_shift(a, b, shift)
}

/// `x * v / 2^16` rounded to nearest for a Q16 `v` within 1.0 (a sine or cosine): two
/// 32-bit multiplies when `x` fits 32 bits, the same as [`mul_shift`].
#[inline]
pub fn mul_q16_unit(x: i64, v: i32) -> i64 {
    if fits_i32(x) && v.unsigned_abs() <= 1 << 16 {
        i64::from(crate::pose::mul_q16_32(x as i32, v))
    } else {
        mul_shift(x, i64::from(v), 16)
    }
}

/// `k[i] * x / 2^shift` rounded to nearest for every `i`, the same as [`mul_shift`] on
/// each: in single 32-bit multiplies when every product and its rounding fit 32 bits (a
/// converged filter's gains times an innovation), else by `round_mul_each`.
pub fn mul_shift_each<const L: usize>(k: &[i64; L], x: i64, shift: u32) -> [i64; L] {
    let largest = k.iter().fold(0u64, |m, k| m.max(k.unsigned_abs()));
    let small = largest <= i32::MAX as u64
        && fits_i32(x)
        && (1..31).contains(&shift)
        && wide_mul_unsigned(largest as u32, x.unsigned_abs() as u32)
            + u64::from(1u32 << (shift - 1))
            <= i32::MAX as u64;
    if small {
        let x = x as i32;
        return k.map(|k| i64::from(((k as i32) * x + (1 << (shift - 1))) >> shift));
    }
    if !(fits_i32(x) && (1..62).contains(&shift)) {
        return k.map(|k| mul_shift(k, x, shift));
    }
    round_mul_each(k, x.unsigned_abs() as u32, x < 0, shift, |k| {
        mul_shift(k, x, shift)
    })
}

/// `v[i] * m / 2^shift` rounded half up, with `m` negated when `negative`, for
/// `1 <= shift < 62`; `other` for an entry past 32 bits. The same bits as
/// `round_shift(wide_mul(v, m), shift)` on each: the rounding bias and which half the
/// quotient comes from are worked out once for the vector, and each entry is then one
/// unsigned 32 x 32 product, a 64-bit add and a shift in 32-bit halves (the M0+ has no
/// 64-bit shifter, and the library's shifts are calls).
#[inline(always)]
fn round_mul_each<const L: usize>(
    v: &[i64; L],
    m: u32,
    negative: bool,
    shift: u32,
    other: impl Fn(i64) -> i64,
) -> [i64; L] {
    // Half a unit of the quotient rounds a positive product half up; a negative one,
    // -x / 2^s rounded half up, is -((x + half - 1) >> s). The shift's two cases are
    // separate loops: each then keeps fewer values live than the M0+ has registers.
    let half = half_of_shift(shift);
    if shift < 32 {
        // The bias fits 32 bits: one register, not two.
        let half = half as u32;
        v.map(|v| {
            if !fits_i32(v) {
                return other(v);
            }
            let below = (v < 0) != negative;
            let bias = if below { half - 1 } else { half };
            let p = wide_mul_unsigned((v as i32).unsigned_abs(), m) + u64::from(bias);
            let (hi, lo) = ((p >> 32) as u32, p as u32);
            let q =
                (u64::from(hi >> shift) << 32) | u64::from((lo >> shift) | (hi << (32 - shift)));
            if below {
                -(q as i64)
            } else {
                q as i64
            }
        })
    } else {
        let high_shift = shift - 32;
        v.map(|v| {
            round_mul_one(v, m, negative, half, &other, |hi, _| {
                u64::from(hi >> high_shift)
            })
        })
    }
}

/// One entry of [`round_mul_each`], `quotient` shifting the biased product's halves.
#[inline(always)]
fn round_mul_one(
    v: i64,
    m: u32,
    negative: bool,
    half: u64,
    other: &impl Fn(i64) -> i64,
    quotient: impl Fn(u32, u32) -> u64,
) -> i64 {
    if !fits_i32(v) {
        return other(v);
    }
    let below = (v < 0) != negative;
    let p = wide_mul_unsigned((v as i32).unsigned_abs(), m) + if below { half - 1 } else { half };
    let q = quotient((p >> 32) as u32, p as u32) as i64;
    if below {
        -q
    } else {
        q
    }
}

/// `2^(shift - 1)` for `1 <= shift < 62`, from a 32-bit shift: a 64-bit shift by a
/// variable amount is a library call on the M0+.
#[inline(always)]
fn half_of_shift(shift: u32) -> u64 {
    if shift <= 32 {
        u64::from(1u32 << (shift - 1))
    } else {
        u64::from(1u32 << (shift - 33)) << 32
    }
}

#[cold]
#[inline(never)]
fn wide_mul_shift(a: i64, b: i64, shift: u32) -> i64 {
    round_shift_wide(
        i128::from(a) * i128::from(b),
        i32::try_from(shift).unwrap_or(i32::MAX),
    )
}

/// `p / 2^shift` rounded to nearest (a left shift for a shift below zero), saturating:
/// the slow paths' common last step (out of line: 128-bit shifts are long on the M0+).
#[inline(never)]
fn round_shift_wide(p: i128, shift: i32) -> i64 {
    if shift <= 0 {
        saturate(p.saturating_mul(1i128 << (-shift).min(64)))
    } else if shift >= 127 {
        0
    } else {
        saturate((p + (1i128 << (shift - 1))) >> shift)
    }
}

/// `x * x`, saturating.
#[inline]
pub const fn square(x: i64) -> i64 {
    if fits_i32(x) {
        let a = (x as i32).unsigned_abs();
        wide_mul_unsigned(a, a) as i64
    } else {
        x.saturating_mul(x)
    }
}

fn saturate(x: i128) -> i64 {
    x.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// `1 / s` for a positive `s`, as a 31-bit mantissa and a shift: `x / s` is then one
/// multiply and one shift.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Reciprocal {
    /// About `2^61 / m`, where `s = m * 2^e` with `m` in `[2^30, 2^31)`: in
    /// `(2^30, 2^31)`, within a unit of it.
    inv: i32,
    /// `61 + e`: `x / s = x * inv / 2^shift`.
    shift: i32,
}

/// `(m, e)` with `m = s / 2^e` (rounded down) in `[2^30, 2^31)`, for `s > 0`: by halving
/// steps in 32 bits, where `leading_zeros` and 64-bit shifts are library calls on the M0+.
fn normalise(s: u64) -> (u32, i32) {
    let (hi, lo) = ((s >> 32) as u32, s as u32);
    if hi == 0 && lo < 1 << 31 {
        let (mut m, mut e) = (lo, 0);
        for step in [16, 8, 4, 2, 1] {
            if m < 1 << (31 - step) {
                m <<= step;
                e -= step;
            }
        }
        return (m, e);
    }
    // s >= 2^31: e = (bits of hi) + 1, from 1 to 33.
    let (mut top, mut bits) = (hi, 0u32);
    for step in [16, 8, 4, 2, 1] {
        if top >= 1 << step {
            top >>= step;
            bits += step;
        }
    }
    let e = if hi == 0 { 1 } else { bits + 2 };
    let m = match e {
        1..=31 => (hi << (32 - e)) | (lo >> e),
        32 => hi,
        _ => hi >> (e - 32),
    };
    (m, e as i32)
}

/// `2^30 / d` for `d = 1/2 + i / 512`, `i` from 0 to 256: [`Reciprocal::of`]'s first
/// guesses, worked out at compile time (a kilobyte of flash: one Newton-Raphson step
/// fewer in every division).
static RECIPROCAL_TABLE: [u32; 257] = {
    let mut table = [0u32; 257];
    let mut i = 0;
    while i < 257 {
        // 2^30 / (1/2 + i/512) = 2^39 / (256 + i).
        table[i] = ((1u64 << 39) / (256 + i as u64)) as u32;
        i += 1;
    }
    table
};

/// `2^61 / m` for `m` in `[2^30, 2^31)`, within `2^-17` of it: [`RECIPROCAL_TABLE`]
/// between its points, 2^22 of `m` apart.
fn reciprocal_guess(m: u32) -> u32 {
    let index = ((m >> 22) - 256) as usize;
    let frac = (m >> 6) & 0xFFFF;
    let at = |i: usize| RECIPROCAL_TABLE.get(i).copied().unwrap_or(1 << 30);
    let (lo, hi) = (at(index), at(index + 1));
    // Neighbours differ by under 2^23: cut to 14 bits, times a 16-bit fraction, that
    // fits 30 bits.
    lo - ((((lo - hi) >> 9) * frac) >> 7)
}

impl Reciprocal {
    /// The reciprocal of `s`; `None` unless `s > 0`.
    ///
    /// A table for the first 17 bits, then a Newton-Raphson step of two 32-bit
    /// multiplies: no division (the M0+ has none, and a 64-bit one is a long library
    /// loop).
    pub fn of(s: i64) -> Option<Reciprocal> {
        if s <= 0 {
            return None;
        }
        // s = m 2^e, m in [2^30, 2^31). With d = m / 2^31 in [0.5, 1), 1 / d is x / 2^30:
        // first guessed from the table of 1 / d, linear between its 257 points (within
        // 2^-17), then one step, which squares the error.
        let (m, e) = normalise(s as u64);
        let x = reciprocal_guess(m);
        // e = 1 - d x, in Q40 (the product d x is Q61: m is Q31, x is Q30), under 2^24
        // for a guess within 2^-17; the step x e rounded to nearest, so that the result
        // is within about half a unit of its last place.
        let error = ((1u64 << 61) as i64 - wide_mul_unsigned(m, x) as i64) >> 21;
        let step = (wide_mul_unsigned(x, error.unsigned_abs() as u32) + (1 << 39)) >> 40;
        let x = if error < 0 {
            x - step as u32
        } else {
            x + step as u32
        };
        Some(Reciprocal {
            inv: x.min(i32::MAX as u32) as i32,
            shift: 61 + e,
        })
    }

    /// `x * 2^extra / s`, rounded to nearest; saturating.
    #[inline]
    pub fn times(&self, x: i64, extra: u32) -> i64 {
        let shift = self.shift - extra as i32;
        if fits_i32(x) && (1..62).contains(&shift) {
            // |x inv| < 2^62.
            round_shift(wide_mul(x as i32, self.inv), shift as u32)
        } else {
            self.times_wide(x, shift)
        }
    }

    /// [`Reciprocal::times`] of each entry, the same bits, by `round_mul_each`.
    pub fn times_each<const L: usize>(&self, x: &[i64; L], extra: u32) -> [i64; L] {
        let shift = self.shift - extra as i32;
        if !(1..62).contains(&shift) {
            return x.map(|v| self.times(v, extra));
        }
        round_mul_each(x, self.inv as u32, false, shift as u32, |v| {
            self.times(v, extra)
        })
    }

    /// `a * b / s`, rounded to nearest; saturating.
    #[cold]
    #[inline(never)]
    pub fn times_product(&self, a: i64, b: i64) -> i64 {
        match a.checked_mul(b) {
            Some(p) => self.times(p, 0),
            // Past 64 bits (only a filter lost past its variances' ceilings forms such a
            // product): its top 94 bits, |p| < 2^126, and |q inv| < 2^125.
            None => {
                let q = (i128::from(a) * i128::from(b)) >> 32;
                round_shift_wide(q * i128::from(self.inv), self.shift - 32)
            }
        }
    }

    #[cold]
    #[inline(never)]
    fn times_wide(&self, x: i64, shift: i32) -> i64 {
        round_shift_wide(i128::from(x) * i128::from(self.inv), shift)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mul_shift_rounds_and_saturates() {
        assert_eq!(mul_shift(3, 1 << 16, 16), 3);
        assert_eq!(mul_shift(3, 1 << 15, 16), 2); // 1.5 rounds up
        assert_eq!(mul_shift(-3, 1 << 15, 16), -1); // -1.5 rounds up
        assert_eq!(mul_shift(1 << 40, 1 << 40, 16), i64::MAX);
        assert_eq!(mul_shift(i64::MAX, i64::MAX, 0), i64::MAX);
        assert_eq!(mul_shift(i64::MIN, i64::MAX, 0), i64::MIN);
    }

    #[test]
    fn round_shift_is_the_64_bit_one() {
        let mut x = 0x1234_5678_9ABC_DEF0u64;
        for _ in 0..100_000 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let p = (x as i64) >> (x % 40);
            for shift in [(x >> 40) as u32 % 63, 1, 16, 31, 32, 33, 62] {
                let want = if shift == 0 {
                    p
                } else {
                    ((i128::from(p) + (1 << (shift - 1))) >> shift) as i64
                };
                assert_eq!(round_shift(p, shift), want, "{p} >> {shift}");
            }
        }
        assert_eq!(round_shift(-3, 1), -1);
        assert_eq!(round_shift(3, 1), 2);
        assert_eq!(round_shift(i64::MIN, 62), -2);
    }

    #[test]
    fn the_32_bit_shortcuts_are_mul_shift() {
        let mut rng = 0x0DDB_1A5E_5BAD_5EEDu64;
        let mut next = || {
            rng = rng.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            rng
        };
        for _ in 0..100_000 {
            let r = next();
            let x = (r as i64) >> (r % 50 + 14);
            let v = ((next() >> 40) as i64 % ((1 << 17) + 1)) - (1 << 16);
            assert_eq!(mul_q16_unit(x, v as i32), mul_shift(x, v, 16), "{x} {v}");
            let r = next();
            let k: [i64; 6] = core::array::from_fn(|i| {
                (next() as i64).wrapping_shr((r % 40 + 24 + i as u64 % 3) as u32)
            });
            let x = (next() as i64) >> (r % 56 + 8);
            let shift = (r >> 32) as u32 % 20 + 1;
            let want: [i64; 6] = core::array::from_fn(|i| mul_shift(k[i], x, shift));
            assert_eq!(mul_shift_each(&k, x, shift), want, "{k:?} {x} {shift}");
        }
    }

    #[test]
    fn times_each_is_times_on_each() {
        let mut x = 0x3C6E_F372_FE94_F82Bu64;
        let mut next = || {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            x
        };
        for _ in 0..50_000 {
            let r = next();
            let s = ((r >> 20) % (1 << ((r >> 2) % 60 + 1))) as i64 + 1;
            let inv = Reciprocal::of(s).unwrap();
            let v: [i64; 6] = core::array::from_fn(|i| {
                let w = next() as i64;
                match (r >> (8 + i)) % 8 {
                    0 => w,
                    1 => i64::from(i32::MIN),
                    2 => 0,
                    _ => w >> (32 + (r >> 16) % 31),
                }
            });
            let extra = (r >> 40) as u32 % 40;
            let want: [i64; 6] = core::array::from_fn(|i| inv.times(v[i], extra));
            assert_eq!(inv.times_each(&v, extra), want, "{v:?} / {s} << {extra}");
        }
    }

    /// The mantissa is `2^61 / m` to within about half a unit (the table's guess within
    /// 2^-17, then one step), but where `2^61 / m` is `2^31`, past an `i32`.
    #[test]
    fn reciprocal_mantissa_is_within_half_a_unit() {
        let mut x = 0x2F69_3A1C_5B0E_44D7u64;
        let mantissas = (0..200_000u64).map(|n| match n % 4 {
            0 => (1 << 30) + n,
            1 => (1 << 31) - 1 - n,
            _ => {
                x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                (1 << 30) + (x >> 34)
            }
        });
        for m in mantissas {
            let r = Reciprocal::of(m as i64).unwrap();
            assert_eq!(r.shift, 61, "{m}");
            let want = (1u64 << 61) as f64 / m as f64;
            let error = f64::from(r.inv) - want;
            assert!(
                error.abs() <= 0.55 || (r.inv == i32::MAX && want >= f64::from(i32::MAX)),
                "{m}: {} against {want}",
                r.inv
            );
        }
    }

    #[test]
    fn normalise_is_the_leading_zeros_one() {
        let mut x = 0x5DEE_CE66_D1CE_4E5Bu64;
        for n in 0..200_000u64 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let s = (x >> (n % 64)).max(1) >> 1 | (n & 1);
            let s = s.max(1);
            let width = 64 - s.leading_zeros() as i32;
            let e = width - 31;
            let m = (if e >= 0 { s >> e } else { s << -e }) as u32;
            assert_eq!(normalise(s), (m, e), "{s}");
        }
        for s in [
            1u64,
            2,
            3,
            (1 << 31) - 1,
            1 << 31,
            u32::MAX as u64,
            1 << 32,
            i64::MAX as u64,
        ] {
            let width = 64 - s.leading_zeros() as i32;
            let e = width - 31;
            let m = (if e >= 0 { s >> e } else { s << -e }) as u32;
            assert_eq!(normalise(s), (m, e), "{s}");
        }
    }

    #[test]
    fn half_of_shift_is_the_64_bit_shift() {
        for shift in 1..62 {
            assert_eq!(half_of_shift(shift), 1u64 << (shift - 1), "{shift}");
        }
    }

    #[test]
    fn square_is_the_product() {
        for x in [
            0i64,
            1,
            -1,
            46_341,
            -46_341,
            i32::MAX as i64,
            -(i32::MAX as i64),
            1 << 31,
        ] {
            assert_eq!(square(x), x.saturating_mul(x));
        }
    }

    #[test]
    fn wide_mul_is_the_full_product() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..100_000 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let (a, b) = ((x >> 32) as i32, x as i32);
            assert_eq!(wide_mul(a, b), i64::from(a) * i64::from(b), "{a} x {b}");
            assert_eq!(
                wide_mul_unsigned(a as u32, b as u32),
                u64::from(a as u32) * u64::from(b as u32)
            );
        }
        for (a, b) in [
            (i32::MIN, i32::MIN),
            (i32::MIN, i32::MAX),
            (i32::MAX, i32::MAX),
            (-1, i32::MIN),
        ] {
            assert_eq!(wide_mul(a, b), i64::from(a) * i64::from(b));
        }
        assert_eq!(
            wide_mul_unsigned(u32::MAX, u32::MAX),
            u64::from(u32::MAX) * u64::from(u32::MAX)
        );
    }

    #[test]
    fn reciprocal_divides_to_within_rounding() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..20_000 {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            let s = ((x >> 20) % (1 << ((x >> 2) % 50 + 1))) as i64 + 1;
            let a = ((x >> 7) % (1 << 31)) as i64 - (1 << 30);
            let r = Reciprocal::of(s).unwrap();
            let want = (i128::from(a) << 16) as f64 / s as f64;
            let got = r.times(a, 16) as f64;
            // Within one unit plus the mantissa's 2^-30 relative error.
            assert!(
                (got - want).abs() <= 1.0 + want.abs() * 2e-9,
                "{a} / {s}: {got} vs {want}"
            );
        }
        assert!(Reciprocal::of(0).is_none());
        assert!(Reciprocal::of(-5).is_none());
        assert_eq!(Reciprocal::of(1).unwrap().times(7, 0), 7);
        assert_eq!(Reciprocal::of(i64::MAX).unwrap().times(i64::MAX, 0), 1);
    }
}
