//! The cells a segment crosses, in order, each once.

use super::divider::CellDivider;
use super::map::GridGeometry;

/// The cells a segment crosses, in order, each once (Amanatides and Woo, in integers).
///
/// Works in whole millimetres relative to the grid. A segment up to [`SHORT_WALK_MM`] along
/// each axis (every beam the robot casts) walks in 32-bit arithmetic, which the Cortex-M0+
/// does in single instructions; longer ones walk the same way in 64 bits, where every
/// product stays far inside `i64`.
pub enum CellWalk {
    /// Both axes and the cell size under [`SHORT_WALK_MM`].
    Short(Walk<i32>),
    /// Anything longer.
    Long(Walk<i64>),
}

/// Longest extent along either axis (and largest cell) walked in 32 bits: the walk's
/// numbers stay below `cell * extent` (see [`Walk`]), under `2^28` here.
pub const SHORT_WALK_MM: i64 = 1 << 14;

impl CellWalk {
    /// The walk from `from` to `to` (map millimetres) over `geometry`'s cells.
    pub fn new(geometry: &GridGeometry, from: (i32, i32), to: (i32, i32)) -> CellWalk {
        CellWalk::with_divider(
            geometry,
            &CellDivider::new(geometry.cell_mm as i64),
            from,
            to,
        )
    }

    /// [`CellWalk::new`] with the cell size's divider already made.
    pub(super) fn with_divider(
        geometry: &GridGeometry,
        divider: &CellDivider,
        from: (i32, i32),
        to: (i32, i32),
    ) -> CellWalk {
        // A beam: everything in 32 bits from the start (64-bit arithmetic is several
        // instructions per operation on the M0+).
        let (ox, oy) = (geometry.origin_x_mm, geometry.origin_y_mm);
        let short = |v: i32| i64::from(v).abs() < SHORT_WALK_MM;
        if let (Some(fx), Some(fy), Some(tx), Some(ty)) = (
            from.0.checked_sub(ox),
            from.1.checked_sub(oy),
            to.0.checked_sub(ox),
            to.1.checked_sub(oy),
        ) {
            if let (Some(dx), Some(dy)) = (tx.checked_sub(fx), ty.checked_sub(fy)) {
                if short(dx) && short(dy) && divider.cell < SHORT_WALK_MM {
                    return CellWalk::Short(Walk::new(divider, (fx, fy), (tx, ty)));
                }
            }
        }
        let (ox, oy) = (i64::from(ox), i64::from(oy));
        let start = (i64::from(from.0) - ox, i64::from(from.1) - oy);
        let end = (i64::from(to.0) - ox, i64::from(to.1) - oy);
        CellWalk::Long(Walk::new(divider, start, end))
    }
}

impl Iterator for CellWalk {
    type Item = (i32, i32);

    #[inline]
    fn next(&mut self) -> Option<(i32, i32)> {
        match self {
            CellWalk::Short(w) => w.next(),
            CellWalk::Long(w) => w.next(),
        }
    }
}

/// The integers a [`Walk`] compares boundary distances in.
pub trait WalkInt:
    Copy
    + Ord
    + core::ops::Add<Output = Self>
    + core::ops::Sub<Output = Self>
    + core::ops::Mul<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// `v` in this width; only called with values that fit.
    fn narrow(v: i64) -> Self;
    /// `floor(self / cell)`.
    fn cells(self, divider: &CellDivider) -> Self;
    /// A cell index as the grid's `i32` (cells past `i32` wrap: no grid is that large).
    fn index(self) -> i32;
    /// `|self|`, as a count of cell boundaries.
    fn count(self) -> u32;
}

impl WalkInt for i32 {
    const ZERO: i32 = 0;
    const ONE: i32 = 1;
    #[inline]
    fn narrow(v: i64) -> i32 {
        v as i32
    }
    #[inline]
    fn cells(self, divider: &CellDivider) -> i32 {
        divider.floor_i32(self)
    }
    #[inline]
    fn index(self) -> i32 {
        self
    }
    #[inline]
    fn count(self) -> u32 {
        self.unsigned_abs()
    }
}

impl WalkInt for i64 {
    const ZERO: i64 = 0;
    const ONE: i64 = 1;
    #[inline]
    fn narrow(v: i64) -> i64 {
        v
    }
    #[inline]
    fn cells(self, divider: &CellDivider) -> i64 {
        divider.floor(self)
    }
    #[inline]
    fn index(self) -> i32 {
        self as i32
    }
    #[inline]
    fn count(self) -> u32 {
        self.unsigned_abs() as u32
    }
}

/// One walk's state, its boundary distances in `T`.
///
/// The next vertical boundary is `next_column` along the segment and the next horizontal
/// one `next_row` (each scaled by the other axis's extent, so they compare in integers).
/// Only their order matters, so the walk keeps their difference: it stays between
/// `-delta_row` and `delta_column` (each step moves it towards the other side), which
/// bounds it by `cell * max(|dx|, |dy|)`: under `2^28` for a short walk, under `2^50`
/// for any segment between `i32` points over cells under 65 m. Nothing can overflow.
pub struct Walk<T> {
    pub(super) column: i32,
    pub(super) row: i32,
    pub(super) step_column: i32,
    pub(super) step_row: i32,
    /// `next_column - next_row`: a column boundary comes first when negative.
    pub(super) diff: T,
    /// How far apart column boundaries are (`cell * |dy|`).
    pub(super) delta_column: T,
    /// How far apart row boundaries are (`cell * |dx|`).
    pub(super) delta_row: T,
    /// Column boundaries still to cross before the end cell.
    pub(super) columns_left: u32,
    /// Row boundaries still to cross before the end cell.
    pub(super) rows_left: u32,
    started: bool,
}

impl<T: WalkInt> Walk<T> {
    /// The walk from `start` to `end`, millimetres from the grid's corner. The cell size
    /// and the extent along each axis must fit `T`'s products (see [`SHORT_WALK_MM`]).
    fn new(divider: &CellDivider, start: (T, T), end: (T, T)) -> Walk<T> {
        let cell = T::narrow(divider.cell);
        let (fx, fy) = start;
        let (c0, r0) = (fx.cells(divider), fy.cells(divider));
        let (c1, r1) = (end.0.cells(divider), end.1.cells(divider));
        let (dx, dy) = (end.0 - fx, end.1 - fy);
        // Distance from the start to the first boundary crossed along each axis (at most
        // one cell).
        let to_column_edge = if dx > T::ZERO {
            (c0 + T::ONE) * cell - fx
        } else {
            fx - c0 * cell
        };
        let to_row_edge = if dy > T::ZERO {
            (r0 + T::ONE) * cell - fy
        } else {
            fy - r0 * cell
        };
        let abs = |v: T| if v < T::ZERO { T::ZERO - v } else { v };
        let (adx, ady) = (abs(dx), abs(dy));
        Walk {
            column: c0.index(),
            row: r0.index(),
            step_column: if dx > T::ZERO { 1 } else { -1 },
            step_row: if dy > T::ZERO { 1 } else { -1 },
            // With no move along an axis there are no boundaries left on it to cross, and
            // the difference is never consulted.
            diff: if dx == T::ZERO || dy == T::ZERO {
                T::ZERO
            } else {
                to_column_edge * ady - to_row_edge * adx
            },
            delta_column: cell * ady,
            delta_row: cell * adx,
            columns_left: (c1 - c0).count(),
            rows_left: (r1 - r0).count(),
            started: false,
        }
    }
}

/// The axis a walk's step moved along.
enum Axis {
    Column,
    Row,
}

impl<T: WalkInt> Walk<T> {
    /// The cell the walk ends in.
    pub(super) fn end(&self) -> (i32, i32) {
        (
            self.column + self.step_column * self.columns_left as i32,
            self.row + self.step_row * self.rows_left as i32,
        )
    }

    /// Crosses the next boundary: the axis it moved along, or `None` in the end cell.
    #[inline(always)]
    fn advance(&mut self) -> Option<Axis> {
        // Cross whichever boundary comes first along the segment; once one axis has
        // reached the end cell's line only the other may move, so a segment that ends
        // exactly on a corner still ends in its own cell.
        if self.columns_left > 0 && (self.rows_left == 0 || self.diff < T::ZERO) {
            self.columns_left -= 1;
            self.column += self.step_column;
            self.diff = self.diff + self.delta_column;
            Some(Axis::Column)
        } else if self.rows_left > 0 {
            self.rows_left -= 1;
            self.row += self.step_row;
            self.diff = self.diff - self.delta_row;
            Some(Axis::Row)
        } else {
            None
        }
    }
}

impl<T: WalkInt> Iterator for Walk<T> {
    type Item = (i32, i32);

    #[inline]
    fn next(&mut self) -> Option<(i32, i32)> {
        if !self.started {
            self.started = true;
            return Some((self.column, self.row));
        }
        self.advance().map(|_| (self.column, self.row))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::TEST_GEOMETRY as GEO;

    fn walk(from: (i32, i32), to: (i32, i32)) -> std::vec::Vec<(i32, i32)> {
        CellWalk::new(&GEO, from, to).collect()
    }

    #[test]
    fn walk_visits_each_cell_once_and_ends_at_target() {
        let cells = walk((700, 500), (1234, 1987));
        let end = GEO.cell_of(1234, 1987);
        assert_eq!(cells.first(), Some(&GEO.cell_of(700, 500)));
        assert_eq!(cells.last(), Some(&end));
        for pair in cells.windows(2) {
            let d = (pair[1].0 - pair[0].0).abs() + (pair[1].1 - pair[0].1).abs();
            assert_eq!(d, 1, "4-connected steps only: {pair:?}");
        }
        let mut sorted = cells.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), cells.len());
    }

    #[test]
    fn short_walks_in_32_bits_equal_the_64_bit_walk() {
        // A fixed pseudo-random sequence (LCG) of segments up to the 32-bit limit.
        let mut rng = crate::lcg::Lcg::new(0x2545_f491_4f6c_dd1d_u64);
        let mut next = |span: i64| rng.within(span);
        let limit = SHORT_WALK_MM - 1;
        for _ in 0..20_000 {
            let cell = 1 + next(200).abs();
            let start = (next(30_000), next(30_000));
            let end = (start.0 + next(limit), start.1 + next(limit));
            let divider = CellDivider::new(cell);
            let wide: std::vec::Vec<_> = Walk::<i64>::new(&divider, start, end).collect();
            let (start32, end32) = (
                (start.0 as i32, start.1 as i32),
                (end.0 as i32, end.1 as i32),
            );
            let narrow: std::vec::Vec<_> = Walk::<i32>::new(&divider, start32, end32).collect();
            assert_eq!(narrow, wide, "cell {cell} from {start:?} to {end:?}");
        }
        // And the dispatch: a beam takes the 32-bit walk, a segment past the limit does not.
        assert!(matches!(
            CellWalk::new(&GEO, (0, 0), (4000, -3000)),
            CellWalk::Short(_)
        ));
        assert!(matches!(
            CellWalk::new(&GEO, (0, 0), (20_000, 0)),
            CellWalk::Long(_)
        ));
    }

    #[test]
    fn walk_axis_aligned_and_single_cell() {
        assert_eq!(walk((10, 10), (20, 30)), [(3, 3)]);
        assert_eq!(walk((10, 10), (160, 10)), [(3, 3), (4, 3), (5, 3), (6, 3)]);
        assert_eq!(walk((10, 10), (10, -90)), [(3, 3), (3, 2), (3, 1)]);
    }
}
