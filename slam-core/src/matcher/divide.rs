//! Floor division by a number fixed for a whole search (a cell's side, a halving), without
//! a divide: the M0+ has none, and the library's takes a hundred cycles or more, which the
//! search would pay several times per beam end and heading. Small offsets take the grid's
//! own shortcut (one multiply and a shift); larger ones a wide multiply by the reciprocal,
//! which gives the quotient or one less, and one compare puts it right.

use crate::estimator::fixed::wide_mul_unsigned;
use crate::grid::CellDivider;

/// Floor division by a divisor fixed for the whole search, without a divide.
#[derive(Clone, Copy, Debug)]
pub(super) struct Divider {
    divisor: i32,
    /// `floor((2^32 - 1) / divisor)`.
    reciprocal: u32,
    /// The grid's multiply and shift, for offsets below 2^15.
    small: CellDivider,
}

impl Divider {
    /// A divider by `divisor`; `None` unless `divisor > 0`.
    pub fn new(divisor: i32) -> Option<Divider> {
        let d = u32::try_from(divisor).ok().filter(|&d| d > 0)?;
        Some(Divider {
            divisor,
            reciprocal: u32::MAX / d,
            small: CellDivider::new(i64::from(divisor)),
        })
    }

    /// `(floor(u / divisor), u mod divisor)`, the remainder in `0..divisor`: what
    /// `div_euclid` and `rem_euclid` give.
    #[inline(always)]
    pub fn div_rem(&self, u: i32) -> (i32, i32) {
        match self.small.fast_floor(u) {
            Some(q) => (q, u - q * self.divisor),
            None => self.div_rem_wide(u),
        }
    }

    /// [`Divider::div_rem`] past the shortcut's range.
    #[inline(never)]
    fn div_rem_wide(&self, u: i32) -> (i32, i32) {
        let Ok(t) = u32::try_from(u) else {
            return (u.div_euclid(self.divisor), u.rem_euclid(self.divisor));
        };
        let d = self.divisor as u32;
        // q is floor(t / d) or one less: the reciprocal is within 1 of 2^32 / d, so
        // t * reciprocal / 2^32 falls short of t / d by less than t / 2^32 + 1 / d.
        let q = (wide_mul_unsigned(t, self.reciprocal) >> 32) as u32;
        let r = t - q * d;
        if r >= d {
            ((q + 1) as i32, (r - d) as i32)
        } else {
            (q as i32, r as i32)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Divider;

    #[test]
    fn it_floors_as_div_euclid() {
        for cell in [1, 3, 7, 50, 64, 100, 1000, 65_536] {
            let Some(d) = Divider::new(cell) else {
                panic!("cell {cell} refused");
            };
            let edges = [
                0,
                1,
                cell - 1,
                cell,
                cell + 1,
                i32::MAX,
                i32::MAX - 1,
                -1,
                -cell,
                i32::MIN,
            ];
            let spread = (-20_000..20_000).step_by(7);
            for u in edges.into_iter().chain(spread) {
                assert_eq!(
                    d.div_rem(u),
                    (u.div_euclid(cell), u.rem_euclid(cell)),
                    "{u} / {cell}"
                );
            }
        }
        assert!(Divider::new(0).is_none());
        assert!(Divider::new(-50).is_none());
    }
}
