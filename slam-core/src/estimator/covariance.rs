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

use super::fixed::{mul_shift, wide_mul, wide_mul_unsigned, Reciprocal};
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

    /// Entry `(i, j)`.
    pub fn get(&self, i: State, j: State) -> i64 {
        i64::from(self.m[i as usize][j as usize])
    }

    /// The whole matrix, rows in state order.
    pub fn rows(&self) -> &[[i32; N]; N] {
        &self.m
    }

    /// `F P F^T + Q` for `F = I + D`, `D` given by its nonzero Q16 entries and `Q` by its
    /// diagonal, as `P + D P + (D P)^T + D P D^T + Q`: `D` has only pose rows, so `D P`
    /// has only those rows and `D P D^T` only their block. Formed in 64 bits; a variance
    /// past its ceiling then scales its row and column down (a congruence, which keeps
    /// the matrix positive definite) before the matrix goes back to 32 bits.
    #[inline(never)]
    pub fn propagate(&mut self, d: &[Entry], noise: &[i64; N], ceiling: &[i32; N]) {
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
    pub fn times_unit_row(&self, h: &[(State, i32)]) -> [i64; N] {
        let mut a = [0i64; N];
        for (out, row) in a.iter_mut().zip(&self.m) {
            *out = h.iter().fold(0i64, |sum, &(j, v)| {
                debug_assert!(v.unsigned_abs() <= 1 << 16);
                sum + i64::from(mul_q16_32(row[j as usize], v))
            });
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
        let gains = |a: &[i64; N], s: &Reciprocal| {
            let mut k = [0i64; N];
            for (k, a) in k.iter_mut().zip(a) {
                *k = s.times(*a, GAIN_SHIFT);
            }
            k
        };
        let (k1, k2) = (gains(a1, s1), gains(a2, s2));
        match (narrow(&k1), narrow(a1), narrow(&k2), narrow(a2)) {
            // A converged filter's products fit 31 bits: one multiply each.
            (Some(k1), Some(a1), Some(k2), Some(a2)) if products_fit_i32(&k1, &a1, &k2, &a2) => {
                for i in 0..N {
                    for j in i..N {
                        let d =
                            (k1[i] * a1[j] + k2[i] * a2[j] + (1 << (GAIN_SHIFT - 1))) >> GAIN_SHIFT;
                        let v = self.m[i][j].saturating_sub(d).max(-i32::MAX);
                        self.m[i][j] = v;
                        self.m[j][i] = v;
                    }
                }
            }
            // A working filter's gains and `P h` fit 32 bits: 32 x 32 multiplies.
            (Some(k1), Some(a1), Some(k2), Some(a2)) => {
                for i in 0..N {
                    for j in i..N {
                        let d = (wide_mul(k1[i], a1[j])
                            + wide_mul(k2[i], a2[j])
                            + (1 << (GAIN_SHIFT - 1)))
                            >> GAIN_SHIFT;
                        let v = clamp32(i64::from(self.m[i][j]) - d);
                        self.m[i][j] = v;
                        self.m[j][i] = v;
                    }
                }
            }
            _ => self.update_wide([(&k1, a1), (&k2, a2)]),
        }
        [k1, k2]
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
    pub fn bound(&mut self, floor: &[i32; N], ceiling: &[i32; N]) {
        for i in 0..N {
            for j in i + 1..N {
                // Variances are positive here: squares compared, 32 x 32 bits.
                let v = self.m[i][j].unsigned_abs();
                let limit =
                    wide_mul_unsigned(self.m[i][i].max(0) as u32, self.m[j][j].max(0) as u32);
                if wide_mul_unsigned(v, v) > limit - (limit >> 9) {
                    for k in [i, j] {
                        let d = self.m[k][k];
                        self.m[k][k] = d.saturating_add((d >> 9) + 1);
                    }
                }
            }
        }
        self.bound_variances(floor, ceiling);
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
