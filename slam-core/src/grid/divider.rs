//! Floor division by the cell size, by a multiply and a shift.

use super::map::GridGeometry;
use crate::pose::div_floor;

/// Floor division by the cell size by a multiply and a shift: the Cortex-M0+ has no
/// divide instruction, and every beam needs the cells of its ends (each a library division
/// in software without this).
///
/// For `0 <= a < 2^15` (a point up to 32 m from the grid's corner), `floor(a / cell)` is
/// `(a * m) >> s` with `s = 15 + ceil(log2(cell))` and `m = ceil(2^s / cell)`: then
/// `m <= 2^16`, so `a * m` fits 32 bits, and the rounding error `m * cell - 2^s` is below
/// `cell <= 2^(s - 15)`, which keeps the quotient exact over that range (Granlund and
/// Montgomery). Anything else, and cells of 2^16 mm or more, divide.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct CellDivider {
    /// The cell size, millimetres (at least 1).
    pub(super) cell: i64,
    /// `m`, or 0 when the cell is too large for the shortcut.
    multiplier: u32,
    /// `s`.
    shift: u32,
}

impl CellDivider {
    /// Offsets from `0` up to (not including) this take the multiply.
    const LIMIT: i64 = 1 << 15;

    pub(crate) const fn new(cell: i64) -> CellDivider {
        let cell = if cell < 1 { 1 } else { cell };
        if cell >= 1 << 16 {
            return CellDivider {
                cell,
                multiplier: 0,
                shift: 0,
            };
        }
        // ceil(log2(cell)), for cell >= 1.
        let log2 = 64 - (cell - 1).leading_zeros();
        let shift = 15 + log2;
        let multiplier = (1u64 << shift).div_ceil(cell as u64);
        CellDivider {
            cell,
            multiplier: multiplier as u32,
            shift,
        }
    }

    /// `floor(a / cell)`.
    #[inline]
    pub(super) fn floor(&self, a: i64) -> i64 {
        if (0..Self::LIMIT).contains(&a) && self.multiplier != 0 {
            ((a as u32 * self.multiplier) >> self.shift) as i64
        } else {
            div_floor(a, self.cell)
        }
    }

    /// `floor(a / cell)` for `0 <= a < LIMIT` by the multiply; `None` otherwise.
    #[inline]
    pub(crate) fn fast_floor(&self, a: i32) -> Option<i32> {
        // One unsigned comparison takes in `0 <= a < LIMIT`.
        ((a as u32) < Self::LIMIT as u32 && self.multiplier != 0)
            .then(|| ((a as u32 * self.multiplier) >> self.shift) as i32)
    }

    /// `floor(a / cell)` in 32 bits.
    #[inline]
    pub(super) fn floor_i32(&self, a: i32) -> i32 {
        self.fast_floor(a)
            .unwrap_or_else(|| self.floor(i64::from(a)) as i32)
    }

    /// The cell holding map point `p`, as [`GridGeometry::cell_of`].
    #[inline]
    pub(super) fn cell_of(&self, geometry: &GridGeometry, p: (i32, i32)) -> (i32, i32) {
        let axis = |v: i32, origin: i32| match v.checked_sub(origin) {
            Some(offset) => self.floor_i32(offset),
            None => self.floor(i64::from(v) - i64::from(origin)) as i32,
        };
        (
            axis(p.0, geometry.origin_x_mm),
            axis(p.1, geometry.origin_y_mm),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_divider_is_exact() {
        // Every offset the shortcut takes, for every cell size up to 200 mm, and a spread
        // of larger ones up to the shortcut's end; then across the fallback's edges.
        let sizes = (1..=200).chain([255, 256, 257, 1000, 4095, 4096, 12_345, 65_535]);
        for cell in sizes {
            let d = CellDivider::new(cell);
            let step = if cell <= 200 { 1 } else { 7 };
            for a in (0..CellDivider::LIMIT).step_by(step) {
                assert_eq!(d.floor(a), a.div_euclid(cell), "{a} / {cell}");
            }
            for a in [
                -1,
                -cell,
                -cell - 1,
                CellDivider::LIMIT,
                1 << 40,
                -(1 << 40),
            ] {
                assert_eq!(d.floor(a), a.div_euclid(cell), "{a} / {cell}");
            }
            for a in [0, 1, -1, 49, 50, -50, 32_767, 32_768, i32::MAX, i32::MIN] {
                let expect = i64::from(a).div_euclid(cell) as i32;
                assert_eq!(d.floor_i32(a), expect, "{a} / {cell} in 32 bits");
            }
        }
        for cell in [0, -5, 1 << 16, 1 << 20] {
            let d = CellDivider::new(cell);
            assert_eq!(d.floor(12_345), 12_345i64.div_euclid(cell.max(1)));
        }
    }
}
