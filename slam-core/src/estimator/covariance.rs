//! The filter's covariance: a symmetric 6 x 6 matrix of 32-bit integers, each state in its
//! own unit (see [`super::units`]) so that every entry of a working filter fits, and the
//! products the filter forms are the M0+'s 32 x 32 multiplies.
//!
//! Jacobians are Q16 numbers. The units are chosen so that each partial derivative the
//! filter needs is a plain length or angle in those units: the heading unit is 2^-16 rad,
//! so the derivative of x by the heading, `dy` in position units per radian, is `dy` in
//! Q16 position units per heading unit.

// Symmetric updates index rows and columns together: plain index loops read best.
#![allow(clippy::needless_range_loop)]

use super::fixed::{mul_shift, round_shift, wide_mul, wide_mul_unsigned, Reciprocal};
use super::State;
use crate::pose::{isqrt, mul_q16_32};

/// Number of states: x, y, heading, gyro scale, gyro bias, flow scale.
pub const N: usize = 6;

/// One nonzero entry of a sparse Q16 matrix: row, column, value.
pub type Entry = (State, State, i32);

/// Fractional bits of a scalar update's gain.
pub const GAIN_SHIFT: u32 = 16;

/// A symmetric positive definite matrix in integers.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Covariance {
    m: [[i32; N]; N],
}

/// The vector in 32 bits, if every entry fits.
fn narrow(v: &[i64; N]) -> Option<[i32; N]> {
    let mut out = [0i32; N];
    for (o, x) in out.iter_mut().zip(v) {
        *o = i32::try_from(*x).ok()?;
    }
    Some(out)
}

/// The largest magnitude in `v`.
fn max_abs(v: &[i32; N]) -> u32 {
    v.iter().fold(0, |m, x| m.max(x.unsigned_abs()))
}

/// Whether every `k1[i] a1[j] + k2[i] a2[j]`, rounded, fits an `i32`: then the update's
/// products are the M0+'s single-cycle multiplies, and its result the same bit for bit.
fn products_fit_i32(k1: &[i32; N], a1: &[i32; N], k2: &[i32; N], a2: &[i32; N]) -> bool {
    let bound = wide_mul_unsigned(max_abs(k1), max_abs(a1))
        + wide_mul_unsigned(max_abs(k2), max_abs(a2))
        + (1 << (GAIN_SHIFT - 1));
    bound <= i32::MAX as u64
}

/// Whether every rounded `(k1[i] a1[j] + k2[i] a2[j]) / 2^16` fits an `i32`: then
/// [`Covariance::update_by_rows`] gives it exactly.
fn update_fits_i32(k1: &[i32; N], a1: &[i32; N], k2: &[i32; N], a2: &[i32; N]) -> bool {
    let bound = wide_mul_unsigned(max_abs(k1), max_abs(a1))
        + wide_mul_unsigned(max_abs(k2), max_abs(a2))
        + (1 << (GAIN_SHIFT - 1));
    bound < 1 << (31 + GAIN_SHIFT)
}

/// Whether `|x1| + |x2|` is below `2^16 - 1`: then each sum of their products with
/// 16-bit halves, and the rounding bias, fits 31 bits.
#[inline(always)]
fn short_pair(x1: i32, x2: i32) -> bool {
    x1.unsigned_abs().saturating_add(x2.unsigned_abs()) < (1 << 16) - 1
}

/// A vector in 16-bit halves, `x = hi 2^16 + lo`, `|hi| <= 2^15`, and `lo` within
/// `[-2^15, 2^15)` (a gain's, `low_up == false`) or `(-2^15, 2^15]` (a `P h`'s): every
/// product of two halves then fits 31 bits, and so does the sum of two products of low
/// halves and the rounding bias.
struct Halves {
    hi: [i32; N],
    lo: [i32; N],
}

impl Halves {
    fn of(v: &[i32; N], low_up: bool) -> Halves {
        let mut h = Halves {
            hi: [0; N],
            lo: [0; N],
        };
        for ((hi, lo), &x) in h.hi.iter_mut().zip(h.lo.iter_mut()).zip(v) {
            [*hi, *lo] = halves(x, low_up);
        }
        h
    }
}

/// `x` as `[hi, lo]` of [`Halves`].
fn halves(x: i32, low_up: bool) -> [i32; 2] {
    let low = x & 0xFFFF;
    let carry = if low_up {
        low > 1 << 15
    } else {
        low >= 1 << 15
    };
    [
        (x >> 16) + i32::from(carry),
        if carry { low - (1 << 16) } else { low },
    ]
}

/// `x` clamped into an `i32`, short of `i32::MIN` (whose negation would not fit).
fn clamp32(x: i64) -> i32 {
    x.clamp(-(i32::MAX as i64), i32::MAX as i64) as i32
}

impl Covariance {
    /// A diagonal covariance (variances clamped to 32 bits).
    pub fn diagonal(variances: [i64; N]) -> Covariance {
        let mut m = [[0; N]; N];
        for (i, v) in variances.iter().enumerate() {
            m[i][i] = clamp32(*v);
        }
        Covariance { m }
    }

    /// Adds `v` to the covariance of `i` with `j` (saturating): the cross term of a
    /// noise whose variances are added with it, without which the sum may not be definite.
    pub fn add_covariance(&mut self, i: State, j: State, v: i64) {
        let (i, j) = (i as usize, j as usize);
        let next = clamp32(i64::from(self.m[i][j]) + v);
        self.m[i][j] = next;
        self.m[j][i] = next;
    }

    /// Entry `(i, j)`.
    pub fn get(&self, i: State, j: State) -> i64 {
        i64::from(self.m[i as usize][j as usize])
    }

    /// This matrix, an update of `before`, kept only `share` (Q16, within 1.0) of the way
    /// from `before`: `before + share (self - before)`, entry by entry. Between two
    /// positive definite matrices, so positive definite itself, and symmetric.
    pub fn move_from(&mut self, before: &Covariance, share: i64) {
        for (row, was) in self.m.iter_mut().zip(&before.m) {
            for (m, &w) in row.iter_mut().zip(was) {
                let moved = mul_shift(i64::from(*m) - i64::from(w), share, 16);
                *m = clamp32(i64::from(w) + moved);
            }
        }
    }

    /// The whole matrix, rows in state order.
    pub fn rows(&self) -> &[[i32; N]; N] {
        &self.m
    }

    /// `F P F^T + Q` for `F = I + D`, `D` given by its nonzero Q16 entries and `Q` by its
    /// diagonal, as `P + D P + (D P)^T + D P D^T + Q`: `D` has only pose rows, so `D P`
    /// has only those rows and `D P D^T` only their block. Formed in 32 bits where the
    /// sizes of `P`, `D` and `Q` prove nothing overflows, in 64 bits otherwise; a variance
    /// past its ceiling then scales its row and column down (a congruence, which keeps
    /// the matrix positive definite) before the matrix goes back to 32 bits.
    #[inline(never)]
    pub fn propagate(&mut self, d: &[Entry], noise: &[i64; N], ceiling: &[i32; N]) {
        if self.propagate_narrow(d, noise, ceiling) {
            return;
        }
        // A tick's Jacobian entries are a tick's displacement and turn: within 1.0 in
        // Q16 at any speed the robot drives, two 32-bit multiplies each.
        let next = if d.iter().all(|&(_, _, v)| v.unsigned_abs() <= 1 << 16) {
            self.propagated(
                d,
                |p, v| i64::from(mul_q16_32(p, v)),
                |p, v| i64::from(mul_q16_32(clamp32(p), v)),
            )
        } else {
            self.propagated(
                d,
                |p, v| mul_shift(i64::from(p), i64::from(v), 16),
                |p, v| mul_shift(p, i64::from(v), 16),
            )
        };
        self.settle_propagated(next, noise, ceiling);
    }

    /// `P + D P + (D P)^T + D P D^T + Q` in place, in 32 bits, the same as the 64-bit
    /// sum, when that provably fits and no variance passes its ceiling: `D` at most two
    /// entries a row, each within 1.0 and in a pose row, `|P| < 2^27` and
    /// `0 <= Q < 2^29` (the sum is then below `9 |P| + Q + 10`). Only the pose rows and
    /// columns and the diagonal change. Returns false, with `P` untouched, otherwise.
    fn propagate_narrow(&mut self, d: &[Entry], noise: &[i64; N], ceiling: &[i32; N]) -> bool {
        const POSE: usize = 3;
        let mut per_row = [0u8; POSE];
        for &(i, _, v) in d {
            let Some(count) = per_row.get_mut(i as usize) else {
                return false;
            };
            *count += 1;
            if *count > 2 || v.unsigned_abs() > 1 << 16 {
                return false;
            }
        }
        // The matrix is symmetric: its upper triangle bounds it.
        let mut largest = 0u32;
        for i in 0..N {
            for j in i..N {
                largest |= self.m[i][j].unsigned_abs();
            }
        }
        if largest >= 1 << 27 {
            return false;
        }
        let mut q = [0i32; N];
        for (q, &n) in q.iter_mut().zip(noise) {
            match i32::try_from(n) {
                Ok(n) if (0..1 << 29).contains(&n) => *q = n,
                _ => return false,
            }
        }
        let m = &mut self.m;
        let mut dp = [[0i32; N]; POSE];
        for &(i, k, v) in d {
            let (i, k) = (i as usize, k as usize);
            for (out, &p) in dp[i].iter_mut().zip(&m[k]) {
                *out += mul_q16_32(p, v);
            }
        }
        // The pose block's change, upper triangle: `D P + (D P)^T + D P D^T`.
        let mut block = [[0i32; POSE]; POSE];
        for i in 0..POSE {
            for j in i..POSE {
                block[i][j] = dp[i][j] + dp[j][i];
            }
        }
        for &(j, k, v) in d {
            let (j, k) = (j as usize, k as usize);
            for i in 0..=j {
                block[i][j] += mul_q16_32(dp[i][k], v);
            }
        }
        for i in 0..N {
            let change = if i < POSE { block[i][i] } else { 0 };
            if m[i][i] + q[i] + change > ceiling[i] {
                return false;
            }
        }
        for i in 0..N {
            m[i][i] += q[i];
        }
        for i in 0..POSE {
            for j in i..N {
                let v = m[i][j] + if j < POSE { block[i][j] } else { dp[i][j] };
                m[i][j] = v;
                m[j][i] = v;
            }
        }
        true
    }

    /// The 64-bit sum's noise, ceilings and narrowing back to 32 bits.
    #[cold]
    fn settle_propagated(&mut self, next: [[i64; N]; N], noise: &[i64; N], ceiling: &[i32; N]) {
        let mut scale = [0i64; N];
        let mut any = false;
        for i in 0..N {
            let v = next[i][i].saturating_add(noise[i]).max(1);
            scale[i] = if v > i64::from(ceiling[i]) {
                any = true;
                // sqrt(ceiling / v) in Q16.
                let ratio = (u128::from(ceiling[i].max(0) as u32) << 32) / v as u128;
                isqrt(ratio.min(u64::MAX as u128) as u64) as i64
            } else {
                1 << 16
            };
        }
        for i in 0..N {
            for j in i..N {
                let mut v = next[i][j];
                if i == j {
                    v = v.saturating_add(noise[i]);
                }
                if any {
                    v = mul_shift(mul_shift(v, scale[i], 16), scale[j], 16);
                }
                let v = if i == j {
                    v.min(i64::from(ceiling[i]))
                } else {
                    v
                };
                let v = clamp32(v);
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }

    /// The upper triangle of `P + D P + (D P)^T + D P D^T`, in 64 bits; `mul(p, v)` is
    /// `p v / 2^16` for an entry of `P`, `mul_wide` the same for one of `D P`.
    fn propagated(
        &self,
        d: &[Entry],
        mul: impl Fn(i32, i32) -> i64,
        mul_wide: impl Fn(i64, i32) -> i64,
    ) -> [[i64; N]; N] {
        let mut dp = [[0i64; N]; N];
        for &(i, k, v) in d {
            let (i, k) = (i as usize, k as usize);
            for (out, p) in dp[i].iter_mut().zip(self.m[k]) {
                *out += mul(p, v);
            }
        }
        let mut next = [[0i64; N]; N];
        for i in 0..N {
            for j in i..N {
                let mut v = i64::from(self.m[i][j]) + dp[i][j] + dp[j][i];
                for &(r, k, q) in d {
                    if r as usize == j {
                        v += mul_wide(dp[i][k as usize], q);
                    }
                }
                next[i][j] = v;
            }
        }
        next
    }

    /// `P h^T` for a sparse Q16 row `h` whose entries are within 1.0 (a direction's sine
    /// and cosine, which is all its callers pass): two 32-bit multiplies a product.
    #[inline(never)]
    pub fn times_unit_row<const K: usize>(&self, h: &[(State, i32); K]) -> [i64; N] {
        let mut a = [0i64; N];
        for (out, row) in a.iter_mut().zip(&self.m) {
            *out = h.iter().fold(0i64, |sum, &(j, v)| {
                debug_assert!(v.unsigned_abs() <= 1 << 16);
                sum + i64::from(mul_q16_32(row[j as usize], v))
            });
        }
        a
    }

    /// `P h^T` for the two rows `(-sin, -cos)` and `(-cos, sin)` over x and y (a tag's
    /// range and the unit row across its line of sight), the same as two
    /// [`Covariance::times_unit_row`]s: in one pass, each row's x and y entries read once.
    #[inline(never)]
    pub fn times_sight_rows(&self, sin: i32, cos: i32) -> [[i64; N]; 2] {
        let (x, y) = (State::X as usize, State::Y as usize);
        let mut a = [[0i64; N]; 2];
        for (i, row) in self.m.iter().enumerate() {
            let (px, py) = (row[x], row[y]);
            a[0][i] = i64::from(mul_q16_32(px, -sin)) + i64::from(mul_q16_32(py, -cos));
            a[1][i] = i64::from(mul_q16_32(px, -cos)) + i64::from(mul_q16_32(py, sin));
        }
        a
    }

    /// Column `j`.
    pub fn column(&self, j: State) -> [i64; N] {
        let mut c = [0i64; N];
        for (c, row) in c.iter_mut().zip(&self.m) {
            *c = i64::from(row[j as usize]);
        }
        c
    }

    /// Two scalar updates at once, `P - a1 a1^T / s1 - a2 a2^T / s2`, where each `a` is
    /// `P h^T` and each `s` is `h a + r` for its measurement, the second's already
    /// conditioned on the first (so the pair is the sequential update, in one pass over
    /// the matrix). Given each `a` and `1 / s`; returns each gain `a / s`
    /// (Q[`GAIN_SHIFT`]).
    #[inline(never)]
    pub fn update(&mut self, updates: [(&[i64; N], &Reciprocal); 2]) -> [[i64; N]; 2] {
        let [(a1, s1), (a2, s2)] = updates;
        let (k1, k2) = (s1.times_each(a1, GAIN_SHIFT), s2.times_each(a2, GAIN_SHIFT));
        match (narrow(&k1), narrow(a1), narrow(&k2), narrow(a2)) {
            // A converged filter's products fit 31 bits: one multiply each.
            (Some(k1), Some(a1), Some(k2), Some(a2)) if products_fit_i32(&k1, &a1, &k2, &a2) => {
                self.update_narrow([(&k1, &a1), (&k2, &a2)])
            }
            // Larger ones whose result fits 32 bits: two single-cycle multiplies a product
            // in a row whose gains are short (a sighting's mostly are), four otherwise.
            (Some(k1), Some(a1), Some(k2), Some(a2)) if update_fits_i32(&k1, &a1, &k2, &a2) => {
                self.update_by_rows([(&k1, &a1), (&k2, &a2)])
            }
            // A working filter's gains and `P h` fit 32 bits: 32 x 32 multiplies.
            (Some(k1), Some(a1), Some(k2), Some(a2)) => self.update_32x32([(&k1, &a1), (&k2, &a2)]),
            _ => self.update_wide([(&k1, a1), (&k2, a2)]),
        }
        [k1, k2]
    }

    /// [`Covariance::update`] to within a unit however large the `a`s: each product
    /// `a_i a_j / s` is there a Q16 gain times an `a`, and a gain is up to `2^-17` off,
    /// which times an `a` past 2^16 is more than a unit. Where an update takes away
    /// nearly all of a large variance (a sighting with the heading barely known, after a
    /// stale gyro or a forgotten heading) such units leave the matrix indefinite; here an
    /// `a` past 2^16 has its gains worked out to as many more bits as it needs. Called
    /// where the `P h`s may be that large; the converged filter's updates, the step's
    /// worst case, call `update` and pay nothing for the check.
    #[inline(never)]
    pub fn update_precise(&mut self, updates: [(&[i64; N], &Reciprocal); 2]) -> [[i64; N]; 2] {
        let [(a1, _), (a2, _)] = updates;
        match (narrow(a1), narrow(a2)) {
            (Some(n1), Some(n2)) if max_abs(&n1).max(max_abs(&n2)) > 1 << GAIN_SHIFT => {
                self.update_fine(updates, [&n1, &n2])
            }
            (Some(_), Some(_)) => self.update(updates),
            _ => self.update_exact(updates),
        }
    }

    /// [`Covariance::update`]'s `P - k1 a1^T - k2 a2^T` where every product and their
    /// rounded sum fit 32 bits ([`products_fit_i32`]).
    fn update_narrow(&mut self, updates: [(&[i32; N], &[i32; N]); 2]) {
        let [(k1, a1), (k2, a2)] = updates;
        for i in 0..N {
            for j in i..N {
                let d = (k1[i] * a1[j] + k2[i] * a2[j] + (1 << (GAIN_SHIFT - 1))) >> GAIN_SHIFT;
                let v = self.m[i][j].saturating_sub(d).max(-i32::MAX);
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }

    /// [`Covariance::update`]'s `P - k1 a1^T - k2 a2^T` where each rounded sum fits 32
    /// bits ([`update_fits_i32`]), row by row from the `P h`s' [`Halves`]: `x (hi 2^16 +
    /// lo)` summed over both updates and rounded is `sum x hi + (sum x lo + 2^15) / 2^16`,
    /// the high sum wrapping as the whole does not. A row whose two gains are short
    /// ([`short_pair`]) takes them whole, two multiplies a product; a row with a long
    /// gain splits it too, `hi hi 2^16 + (hi lo + lo hi) + (lo lo + 2^15) / 2^16`, four.
    /// Only the last term is shifted, and it is exact in 32 bits.
    fn update_by_rows(&mut self, updates: [(&[i32; N], &[i32; N]); 2]) {
        let [(k1, a1), (k2, a2)] = updates;
        let (a1, a2) = (Halves::of(a1, true), Halves::of(a2, true));
        for i in 0..N {
            let (x1, x2) = (k1[i], k2[i]);
            if short_pair(x1, x2) {
                for j in i..N {
                    let high = x1
                        .wrapping_mul(a1.hi[j])
                        .wrapping_add(x2.wrapping_mul(a2.hi[j]));
                    let low = x1 * a1.lo[j] + x2 * a2.lo[j] + (1 << (GAIN_SHIFT - 1));
                    let d = high.wrapping_add(low >> GAIN_SHIFT);
                    self.subtract(i, j, d);
                }
            } else {
                let ([h1, l1], [h2, l2]) = (halves(x1, false), halves(x2, false));
                for j in i..N {
                    let high = (h1 * a1.hi[j]).wrapping_add(h2 * a2.hi[j]);
                    let middle = (h1 * a1.lo[j])
                        .wrapping_add(l1 * a1.hi[j])
                        .wrapping_add(h2 * a2.lo[j])
                        .wrapping_add(l2 * a2.hi[j]);
                    let low = l1 * a1.lo[j] + l2 * a2.lo[j] + (1 << (GAIN_SHIFT - 1));
                    let d = (high << 16)
                        .wrapping_add(middle)
                        .wrapping_add(low >> GAIN_SHIFT);
                    self.subtract(i, j, d);
                }
            }
        }
    }

    /// Takes `d` off entry `(i, j)` and its mirror, held short of `i32::MIN`.
    #[inline(always)]
    fn subtract(&mut self, i: usize, j: usize, d: i32) {
        let v = self.m[i][j].saturating_sub(d).max(-i32::MAX);
        self.m[i][j] = v;
        self.m[j][i] = v;
    }

    /// [`Covariance::update`]'s `P - k1 a1^T - k2 a2^T` for 32-bit gains and `P h`.
    fn update_32x32(&mut self, updates: [(&[i32; N], &[i32; N]); 2]) {
        let [(k1, a1), (k2, a2)] = updates;
        for i in 0..N {
            for j in i..N {
                let d = (wide_mul(k1[i], a1[j]) + wide_mul(k2[i], a2[j]) + (1 << (GAIN_SHIFT - 1)))
                    >> GAIN_SHIFT;
                let v = clamp32(i64::from(self.m[i][j]) - d);
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }

    /// [`Covariance::update`] for an `a` past 2^16 but within 32 bits: the gains to a
    /// `2^shift` at least four times the largest `a`, so that each one's rounding is under
    /// an eighth of a unit of its products, which are then 32 x 32 multiplies. Returns
    /// the gains rounded to Q16, as `update` does. A gain past 32 bits at that shift
    /// takes the products whole ([`Covariance::update_exact`]).
    #[cold]
    #[inline(never)]
    fn update_fine(
        &mut self,
        updates: [(&[i64; N], &Reciprocal); 2],
        a: [&[i32; N]; 2],
    ) -> [[i64; N]; 2] {
        let [(a1, s1), (a2, s2)] = updates;
        let largest = max_abs(a[0]).max(max_abs(a[1]));
        // largest < 2^bits, bits from 18 to 32: a shift from 19 to 34.
        let shift = 34 - largest.leading_zeros();
        let (f1, f2) = (s1.times_each(a1, shift), s2.times_each(a2, shift));
        let (Some(k1), Some(k2)) = (narrow(&f1), narrow(&f2)) else {
            return self.update_exact(updates);
        };
        for i in 0..N {
            for j in i..N {
                let p = wide_mul(k1[i], a[0][j]).saturating_add(wide_mul(k2[i], a[1][j]));
                let v = clamp32(i64::from(self.m[i][j]).saturating_sub(round_shift(p, shift)));
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
        let q16 = |f: [i64; N]| f.map(|k| round_shift(k, shift - GAIN_SHIFT));
        [q16(f1), q16(f2)]
    }

    /// [`Covariance::update`]'s `P - a1 a1^T / s1 - a2 a2^T / s2` from each product
    /// `a_i a_j` whole, divided once: for an `a` past 32 bits, where a gain times it is
    /// far past the products' 64 bits (only a filter lost far past the variances'
    /// ceilings has one). Returns the gains in Q16, as `update` does.
    #[cold]
    #[inline(never)]
    fn update_exact(&mut self, updates: [(&[i64; N], &Reciprocal); 2]) -> [[i64; N]; 2] {
        for i in 0..N {
            for j in i..N {
                let d = updates.iter().fold(0i64, |d, (a, s)| {
                    d.saturating_add(s.times_product(a[i], a[j]))
                });
                let v = clamp32(i64::from(self.m[i][j]).saturating_sub(d));
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
        updates.map(|(a, s)| s.times_each(a, GAIN_SHIFT))
    }

    #[cold]
    #[inline(never)]
    fn update_wide(&mut self, updates: [(&[i64; N], &[i64; N]); 2]) {
        for i in 0..N {
            for j in i..N {
                let d = updates.iter().fold(0i64, |d, (k, a)| {
                    d.saturating_add(mul_shift(k[i], a[j], GAIN_SHIFT))
                });
                let v = clamp32(i64::from(self.m[i][j]).saturating_sub(d));
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }

    /// Keeps each variance between its floor and its ceiling: one past its ceiling scales
    /// its row and column down, a congruence that keeps the matrix positive definite.
    pub fn bound_variances(&mut self, floor: &[i32; N], ceiling: &[i32; N]) {
        for i in 0..N {
            if self.m[i][i] > ceiling[i] {
                self.scale_down(i, ceiling[i]);
            }
            if self.m[i][i] < floor[i] {
                self.m[i][i] = floor[i];
            }
        }
    }

    /// [`Covariance::bound_variances`], and each correlation kept below one by about
    /// 2^-10, against the rounding of many updates. A pair too closely correlated has both
    /// its variances raised by 2^-9 rather than its covariance cut: adding to the diagonal
    /// keeps a positive definite matrix so (and makes a nearly indefinite one definite),
    /// where cutting one entry of a nearly singular matrix can break it.
    #[inline]
    pub fn bound(&mut self, floor: &[i32; N], ceiling: &[i32; N]) {
        self.bound_pairs(floor, ceiling, None);
    }

    /// [`Covariance::bound`] with the correlation check on one third of the pairs only,
    /// `part` (0, 1 or 2) choosing which: the pairs taken in turn, row by row, every third
    /// from the `part`-th. Three calls with the three parts check every pair once.
    #[inline]
    pub fn bound_part(&mut self, floor: &[i32; N], ceiling: &[i32; N], part: u8) {
        self.bound_pairs(floor, ceiling, Some(part));
    }

    /// [`Covariance::bound`] on every pair (`part == None`) or on one third of them.
    #[inline(never)]
    fn bound_pairs(&mut self, floor: &[i32; N], ceiling: &[i32; N], part: Option<u8>) {
        // Counts 0, 1, 2, 0, ... along the pairs (no `%`: the M0+ has no divider).
        let mut turn = 0u8;
        for i in 0..N {
            for j in i + 1..N {
                let mine = part.is_none_or(|p| p == turn);
                turn = if turn == 2 { 0 } else { turn + 1 };
                if !mine {
                    continue;
                }
                // Variances are positive here: squares compared, unless the covariance
                // is below `m (1 - 2^-8)` for the smaller variance `m`, which needs no
                // product: its square is then below `m^2 (1 - 2^-9)`, and so below the
                // limit.
                let v = self.m[i][j].unsigned_abs();
                let (a, b) = (self.m[i][i].max(0) as u32, self.m[j][j].max(0) as u32);
                let m = a.min(b);
                if v < m - (m >> 8) {
                    continue;
                }
                // A converged filter's entries are under 2^16: the squares fit 32 bits.
                let too_close = if (a | b | v) < 1 << 16 {
                    let limit = a * b;
                    v * v > limit - (limit >> 9)
                } else {
                    let limit = wide_mul_unsigned(a, b);
                    wide_mul_unsigned(v, v) > limit - (limit >> 9)
                };
                if too_close {
                    for k in [i, j] {
                        let d = self.m[k][k];
                        self.m[k][k] = d.saturating_add((d >> 9) + 1);
                    }
                }
            }
        }
        self.bound_variances(floor, ceiling);
    }

    /// Forgets state `i`'s correlations and raises its variance to at least `variance`
    /// (clamped to 32 bits). Positive definite still: the matrix is then block diagonal,
    /// state `i` alone and the rest (a principal submatrix of a definite matrix).
    pub fn forget(&mut self, i: State, variance: i64) {
        let i = i as usize;
        for j in 0..N {
            if j != i {
                self.m[i][j] = 0;
                self.m[j][i] = 0;
            }
        }
        self.m[i][i] = self.m[i][i].max(clamp32(variance));
    }

    /// Forgets state `i`'s correlations and sets its variance to `variance` (clamped to
    /// 32 bits, at least 1): definite still, as after [`Covariance::forget`].
    pub fn replace(&mut self, i: State, variance: i64) {
        self.forget(i, 0);
        self.m[i as usize][i as usize] = clamp32(variance).max(1);
    }

    /// Scales row and column `i` by `sqrt(ceiling / P_ii)` so that `P_ii` is `ceiling`.
    #[cold]
    fn scale_down(&mut self, i: usize, ceiling: i32) {
        let ratio =
            (u64::from(ceiling.max(0) as u32) << 32) / u64::from(self.m[i][i].max(1) as u32);
        let c = isqrt(ratio) as i64; // Q16, below 1
        for j in 0..N {
            if j != i {
                let v = clamp32(mul_shift(i64::from(self.m[i][j]), c, 16));
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
        self.m[i][i] = ceiling;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lcg::Lcg;

    /// A random symmetric matrix with entries up to `2^bits`, a predict-shaped `D` and a
    /// noise diagonal.
    fn case(rng: &mut Lcg, bits: u32) -> (Covariance, [Entry; 6], [i64; N]) {
        let mut m = [[0i32; N]; N];
        for i in 0..N {
            for j in i..N {
                let v = rng.within((1 << bits) - 1) as i32;
                m[i][j] = if i == j { v.abs() } else { v };
                m[j][i] = m[i][j];
            }
        }
        let mut q = || rng.within(1 << 16) as i32;
        let d = [
            (State::X, State::Heading, q()),
            (State::Y, State::Heading, q()),
            (State::X, State::FlowScale, q()),
            (State::Y, State::FlowScale, q()),
            (State::Heading, State::GyroScale, q()),
            (State::Heading, State::GyroBias, q()),
        ];
        let noise = core::array::from_fn(|_| rng.within(1 << 28).abs());
        (Covariance { m }, d, noise)
    }

    #[test]
    fn narrow_propagation_is_the_wide_one_bit_for_bit() {
        let mut rng = Lcg::new(17);
        let mut narrow_taken = 0;
        for n in 0..20_000 {
            // Mostly no ceiling; every fourth case one that some variances pass.
            let ceiling = if n % 4 == 3 {
                [1 << 26; N]
            } else {
                [i32::MAX; N]
            };
            let bits = 10 + (n % 19) as u32;
            let (p, d, noise) = case(&mut rng, bits);
            let used = &d[..2 + n % 5];
            let mut wide = p;
            let next = wide.propagated(
                used,
                |p, v| i64::from(mul_q16_32(p, v)),
                |p, v| i64::from(mul_q16_32(clamp32(p), v)),
            );
            wide.settle_propagated(next, &noise, &ceiling);
            let mut fast = p;
            fast.propagate(used, &noise, &ceiling);
            assert_eq!(fast, wide, "case {n}");
            let mut narrow = p;
            narrow_taken += usize::from(narrow.propagate_narrow(used, &noise, &ceiling));
        }
        assert!(narrow_taken > 10_000, "{narrow_taken}");
    }

    /// [`Covariance::bound`]'s correlation check as first written: every pair past half
    /// the smaller variance compared by 64-bit squares.
    fn bound_reference(p: &mut Covariance, floor: &[i32; N], ceiling: &[i32; N]) {
        for i in 0..N {
            for j in i + 1..N {
                let v = p.m[i][j].unsigned_abs();
                let (a, b) = (p.m[i][i].max(0) as u32, p.m[j][j].max(0) as u32);
                if v <= a.min(b) >> 1 {
                    continue;
                }
                let limit = u64::from(a) * u64::from(b);
                if u64::from(v) * u64::from(v) > limit - (limit >> 9) {
                    for k in [i, j] {
                        let d = p.m[k][k];
                        p.m[k][k] = d.saturating_add((d >> 9) + 1);
                    }
                }
            }
        }
        p.bound_variances(floor, ceiling);
    }

    #[test]
    fn bound_is_the_64_bit_check() {
        let mut rng = Lcg::new(23);
        let floor = [4, 4, 16, 1, 1, 1];
        let ceiling = [1 << 30; N];
        let mut raised = 0;
        for n in 0..50_000 {
            // Variances of every size, covariances near the limit of each pair.
            let mut m = [[0i32; N]; N];
            for i in 0..N {
                m[i][i] = rng.within(1 << (4 + (n + i) % 27)).abs() as i32;
            }
            if n % 3 == 0 {
                // Equal variances, where the smaller one alone decides.
                let v = m[0][0];
                for i in 0..N {
                    m[i][i] = v + (rng.within(2) as i32).max(-v);
                }
            }
            for i in 0..N {
                for j in i + 1..N {
                    let limit = ((m[i][i] as f64) * (m[j][j] as f64)).sqrt();
                    let r = 1.0 - (rng.within(1 << 12).abs() as f64) / f64::from(1 << (6 + n % 8));
                    let v =
                        ((limit * r) as i32).wrapping_mul(if rng.within(1) < 0 { -1 } else { 1 });
                    m[i][j] = v;
                    m[j][i] = v;
                }
            }
            let mut fast = Covariance { m };
            fast.bound(&floor, &ceiling);
            let mut slow = Covariance { m };
            bound_reference(&mut slow, &floor, &ceiling);
            assert_eq!(fast, slow, "case {n}");
            raised += usize::from(fast.m != m);
        }
        assert!(raised > 1_000, "{raised}");
    }

    #[test]
    fn the_three_parts_check_every_pair_once() {
        let floor = [1; N];
        let ceiling = [i32::MAX; N];
        // One pair at a time past the limit: exactly one of the three parts raises it.
        for i in 0..N {
            for j in i + 1..N {
                let mut m = [[0i32; N]; N];
                for k in 0..N {
                    m[k][k] = 1000;
                }
                m[i][j] = 1000;
                m[j][i] = 1000;
                let mut full = Covariance { m };
                full.bound(&floor, &ceiling);
                assert_ne!(full.m, m, "({i}, {j})");
                let raised: std::vec::Vec<u8> = (0..3)
                    .filter(|&part| {
                        let mut p = Covariance { m };
                        p.bound_part(&floor, &ceiling, part);
                        assert!(p == full || p.m == m, "({i}, {j}) part {part}");
                        p == full
                    })
                    .collect();
                assert_eq!(raised.len(), 1, "({i}, {j}): {raised:?}");
            }
        }
    }

    #[test]
    fn update_in_32_bits_is_the_32x32_one_bit_for_bit() {
        let mut rng = Lcg::new(5);
        let mut narrow_taken = 0;
        for n in 0..20_000 {
            let bits = 8 + (n % 16) as u32;
            let (p, _, _) = case(&mut rng, 20 + (n % 11) as u32);
            let mut vector =
                || -> [i32; N] { core::array::from_fn(|_| rng.within(1 << bits) as i32) };
            let (k1, a1, k2, a2) = (vector(), vector(), vector(), vector());
            if !products_fit_i32(&k1, &a1, &k2, &a2) {
                continue;
            }
            narrow_taken += 1;
            let mut fast = p;
            fast.update_narrow([(&k1, &a1), (&k2, &a2)]);
            let mut wide = p;
            wide.update_32x32([(&k1, &a1), (&k2, &a2)]);
            assert_eq!(fast, wide, "case {n}");
        }
        assert!(narrow_taken > 5_000, "{narrow_taken}");
    }

    /// A share of the way from one matrix to another: none of it is the first, all of
    /// it the second, a share between is each entry that far along, and symmetric.
    #[test]
    fn move_from_goes_the_share_of_the_way() {
        let mut rng = Lcg::new(17);
        for _ in 0..2_000 {
            let (before, _, _) = case(&mut rng, 30);
            let (after, _, _) = case(&mut rng, 30);
            let share = rng.within(1 << 16).abs();
            for (s, want) in [(0, before), (1 << 16, after)] {
                let mut moved = after;
                moved.move_from(&before, s);
                assert_eq!(moved, want);
            }
            let mut moved = after;
            moved.move_from(&before, share);
            for i in 0..N {
                for j in 0..N {
                    let (b, a) = (f64::from(before.m[i][j]), f64::from(after.m[i][j]));
                    let want = b + (a - b) * share as f64 / 65_536.0;
                    assert!((f64::from(moved.m[i][j]) - want).abs() <= 0.5 + 1e-9);
                    assert_eq!(moved.m[i][j], moved.m[j][i]);
                }
            }
        }
    }

    #[test]
    fn update_by_rows_is_the_32x32_one_bit_for_bit() {
        let mut rng = Lcg::new(9);
        let edges = [
            0,
            1,
            -1,
            1 << 15,
            -(1 << 15),
            (1 << 15) + 1,
            (1 << 16) - (1 << 15),
            0x7FFF_8000,
            -0x7FFF_8000,
            i32::MAX,
            -i32::MAX,
            i32::MIN,
        ];
        let (mut taken, mut rows) = (0, [0; 2]);
        for n in 0..40_000 {
            let bits = 8 + (n % 24) as u32;
            let (p, _, _) = case(&mut rng, 20 + (n % 11) as u32);
            let mut vector = || -> [i32; N] {
                core::array::from_fn(|_| {
                    let r = rng.within(1 << bits) as i32;
                    if r % 7 == 0 {
                        edges[r.unsigned_abs() as usize % edges.len()]
                    } else {
                        r
                    }
                })
            };
            let (mut k1, a1, mut k2, a2) = (vector(), vector(), vector(), vector());
            // Some rows' gains short, the rest as drawn: both kinds of row in one update.
            let short_rows = rng.within(1 << N) as u32;
            for i in (0..N).filter(|i| short_rows & (1 << i) != 0) {
                k1[i] >>= 17;
                k2[i] >>= 17;
            }
            if !update_fits_i32(&k1, &a1, &k2, &a2) {
                continue;
            }
            taken += 1;
            for i in 0..N {
                rows[usize::from(short_pair(k1[i], k2[i]))] += 1;
            }
            let mut fast = p;
            fast.update_by_rows([(&k1, &a1), (&k2, &a2)]);
            let mut wide = p;
            wide.update_32x32([(&k1, &a1), (&k2, &a2)]);
            assert_eq!(fast, wide, "case {n}");
        }
        assert!(taken > 10_000, "{taken}");
        assert!(
            rows.iter().all(|&r| r > 10_000),
            "long and short rows {rows:?}"
        );
    }

    /// `P - a1 a1^T / s1 - a2 a2^T / s2` in `f64`, against `update_precise` on the same `a`s
    /// and `s`s: every entry within a unit (and the reciprocal's 2^-30 of what is taken
    /// away), however large the `a`s. Gains rounded to Q16 are up to 2^-17 off, which
    /// times an `a` of 2^28 is a thousand units.
    #[test]
    fn an_update_of_a_large_variance_is_within_a_unit_of_the_exact_one() {
        let mut rng = Lcg::new(23);
        let mut fine = 0;
        for n in 0..20_000 {
            let (p, _, _) = case(&mut rng, 20);
            let big = 8 + (n % 24) as u32;
            let a1: [i64; N] = core::array::from_fn(|i| {
                let bits = if i == 2 { big } else { 12 };
                rng.within((1 << bits) - 1)
            });
            let a2: [i64; N] = core::array::from_fn(|_| rng.within((1 << 14) - 1));
            // Each `s` at least its largest `a`: a variance's share taken, as a real one.
            let largest = |a: &[i64; N]| a.iter().map(|x| x.abs()).max().unwrap_or(0);
            let s1 = largest(&a1) + rng.within(1 << 10).abs() + 1;
            let s2 = largest(&a2) + rng.within(1 << 10).abs() + 1;
            fine += usize::from(largest(&a1) > 1 << GAIN_SHIFT);
            let (r1, r2) = (Reciprocal::of(s1).unwrap(), Reciprocal::of(s2).unwrap());
            let mut q = p;
            q.update_precise([(&a1, &r1), (&a2, &r2)]);
            for i in 0..N {
                for j in 0..N {
                    let taken = (a1[i] as f64) * (a1[j] as f64) / s1 as f64
                        + (a2[i] as f64) * (a2[j] as f64) / s2 as f64;
                    let want = f64::from(p.m[i][j]) - taken;
                    let got = f64::from(q.m[i][j]);
                    assert!(
                        (got - want).abs() <= 1.0 + taken.abs() / f64::from(1 << 30),
                        "case {n} ({i}, {j}): {got} against {want}"
                    );
                }
            }
        }
        assert!(fine > 10_000, "{fine}");
    }
}
