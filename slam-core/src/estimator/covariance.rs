//! The filter's covariance: a symmetric 6 x 6 matrix of integers, each state in its own
//! unit so that every entry of a working filter sits well inside 40 bits.
//!
//! Jacobians are Q16 numbers. The units are chosen so that each partial derivative the
//! filter needs is a plain length or angle in those units: the heading unit is 2^-16 rad,
//! so the derivative of x by the heading, `dy` in position units per radian, is `dy` in
//! Q16 position units per heading unit.

use super::State;

/// Number of states: x, y, heading, gyro scale, gyro bias, flow scale.
pub const N: usize = 6;

/// One nonzero entry of a sparse Q16 matrix: row, column, value.
pub type Entry = (State, State, i64);

/// Fractional bits of a scalar update's gain.
pub const GAIN_SHIFT: u32 = 16;

/// `a * b >> shift`, rounded, in 64 bits when the product fits (always, in a filter that
/// has not diverged) and in 128 bits when it does not; saturating.
pub fn mul_shift(a: i64, b: i64, shift: u32) -> i64 {
    match a.checked_mul(b) {
        Some(p) => {
            let half = (1i64 << shift) >> 1;
            match p.checked_add(half) {
                Some(q) => q >> shift,
                None => p >> shift,
            }
        }
        None => wide_mul_shift(a, b, shift),
    }
}

#[cold]
fn wide_mul_shift(a: i64, b: i64, shift: u32) -> i64 {
    let p = (i128::from(a) * i128::from(b) + ((1i128 << shift) >> 1)) >> shift;
    p.clamp(i64::MIN as i128, i64::MAX as i128) as i64
}

/// A symmetric positive definite matrix in integers.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Covariance {
    m: [[i64; N]; N],
}

impl Covariance {
    /// A diagonal covariance.
    pub fn diagonal(variances: [i64; N]) -> Covariance {
        let mut m = [[0; N]; N];
        for (i, v) in variances.iter().enumerate() {
            m[i][i] = *v;
        }
        Covariance { m }
    }

    /// Entry `(i, j)`.
    pub fn get(&self, i: State, j: State) -> i64 {
        self.m[i as usize][j as usize]
    }

    /// The whole matrix, rows in state order.
    pub fn rows(&self) -> &[[i64; N]; N] {
        &self.m
    }

    /// `F P F^T` for `F = I + D`, `D` given by its nonzero Q16 entries: the rows of `D`
    /// are added into `P` (`(I + D) P`), then its columns (`... (I + D)^T`).
    pub fn propagate(&mut self, d: &[Entry]) {
        // (I + D) P: row i gains v times row k of P as it was.
        let before = self.m;
        for &(i, k, v) in d {
            let (i, k) = (i as usize, k as usize);
            for j in 0..N {
                self.m[i][j] = self.m[i][j].saturating_add(mul_shift(before[k][j], v, 16));
            }
        }
        // ... (I + D)^T: column j gains v times column k.
        let mid = self.m;
        for &(j, k, v) in d {
            let (j, k) = (j as usize, k as usize);
            for i in 0..N {
                self.m[i][j] = self.m[i][j].saturating_add(mul_shift(mid[i][k], v, 16));
            }
        }
        self.symmetrise();
    }

    /// Adds process noise to the diagonal.
    pub fn add_diagonal(&mut self, q: [i64; N]) {
        for (i, q) in q.iter().enumerate() {
            self.m[i][i] = self.m[i][i].saturating_add(*q);
        }
    }

    /// `P h^T` for a sparse Q16 row `h`.
    pub fn times_row(&self, h: &[(State, i64)]) -> [i64; N] {
        let mut a = [0i64; N];
        for (i, out) in a.iter_mut().enumerate() {
            let mut sum = 0i64;
            for &(j, v) in h {
                sum = sum.saturating_add(mul_shift(self.m[i][j as usize], v, 16));
            }
            *out = sum;
        }
        a
    }

    /// The scalar update `P - a a^T / s` with `a = P h^T` and `s = h a + r`, given `a` and
    /// `s`. Returns the gain `a / s` (Q[`GAIN_SHIFT`]); `None`, and no change, if `s` is
    /// not positive.
    pub fn update(&mut self, a: &[i64; N], s: i64) -> Option<[i64; N]> {
        if s <= 0 {
            return None;
        }
        let mut k = [0i64; N];
        for (k, a) in k.iter_mut().zip(a) {
            *k = gain(*a, s);
        }
        for i in 0..N {
            for j in i..N {
                let v = self.m[i][j].saturating_sub(mul_shift(k[i], a[j], GAIN_SHIFT));
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
        Some(k)
    }

    /// Keeps the matrix a covariance through rounding: each variance between its floor and
    /// its ceiling (a variance past its ceiling scales its row and column down, a
    /// congruence that keeps the matrix positive definite), each correlation below one.
    pub fn bound(&mut self, floor: &[i64; N], ceiling: &[i64; N]) {
        for i in 0..N {
            if self.m[i][i] > ceiling[i] {
                // Scale row and column i by c = sqrt(ceiling / P_ii), in Q16.
                let c = (isqrt_u64(((ceiling[i] as u64) << 32) / (self.m[i][i] as u64))) as i64;
                for j in 0..N {
                    if j != i {
                        let v = mul_shift(self.m[i][j], c, 16);
                        self.m[i][j] = v;
                        self.m[j][i] = v;
                    }
                }
                self.m[i][i] = ceiling[i];
            }
            if self.m[i][i] < floor[i] {
                self.m[i][i] = floor[i];
            }
        }
        for i in 0..N {
            for j in i + 1..N {
                // |P_ij| < sqrt(P_ii P_jj), kept a little under: 0.999.
                let limit = (isqrt_u64((self.m[i][i] as u64).saturating_mul(self.m[j][j] as u64))
                    as i64)
                    .saturating_mul(1023)
                    >> 10;
                let v = self.m[i][j].clamp(-limit, limit);
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }

    fn symmetrise(&mut self) {
        for i in 0..N {
            for j in i + 1..N {
                let (a, b) = (self.m[i][j], self.m[j][i]);
                let v = (a >> 1) + (b >> 1) + (a & b & 1);
                self.m[i][j] = v;
                self.m[j][i] = v;
            }
        }
    }
}

/// `a / s` in Q[`GAIN_SHIFT`], rounded to nearest; `s > 0`.
fn gain(a: i64, s: i64) -> i64 {
    match a.checked_mul(1 << GAIN_SHIFT) {
        Some(num) => {
            let half = s / 2;
            if num >= 0 {
                num.saturating_add(half) / s
            } else {
                num.saturating_sub(half) / s
            }
        }
        None => {
            let q = (i128::from(a) << GAIN_SHIFT) / i128::from(s);
            q.clamp(i64::MIN as i128, i64::MAX as i128) as i64
        }
    }
}

/// Floor of the square root.
pub fn isqrt_u64(n: u64) -> u64 {
    if n < 2 {
        return n;
    }
    // Bit by bit: no division, no floats.
    let mut x = n;
    let mut result = 0u64;
    let mut bit = 1u64 << ((63 - n.leading_zeros()) & !1);
    while bit != 0 {
        if x >= result + bit {
            x -= result + bit;
            result = (result >> 1) + bit;
        } else {
            result >>= 1;
        }
        bit >>= 2;
    }
    result
}
