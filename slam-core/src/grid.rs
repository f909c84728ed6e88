//! The log-odds occupancy grid: fixed point, saturating, sized at compile time.

use crate::pose::div_floor;

/// Log odds in Q8 fixed point: 256 is a log-odds of 1.0.
pub type LogOdds = i16;

/// One log-odds unit (1.0) in [`LogOdds`].
pub const LOG_ODDS_ONE: LogOdds = 256;

/// How much one beam says about a cell, and when a cell counts as known.
///
/// The defaults are the seed's: +0.85 where a beam stops, -0.4 where it passes,
/// clamped to +-8, free below -1 and occupied above +1.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Evidence {
    /// Added to the cell where a beam stops (positive).
    pub hit: LogOdds,
    /// Added to each cell a beam passes through (negative).
    pub miss: LogOdds,
    /// Cells saturate at `+-clamp`.
    pub clamp: LogOdds,
    /// A cell below `-free_below` is free; above `occupied_above` it is occupied.
    pub free_below: LogOdds,
    /// See `free_below`.
    pub occupied_above: LogOdds,
}

impl Evidence {
    /// The seed's evidence in Q8: +0.85 -> 218, -0.4 -> -102, +-8 -> +-2048, +-1 -> +-256.
    pub const SEED: Evidence = Evidence {
        hit: 218,
        miss: -102,
        clamp: 8 * LOG_ODDS_ONE,
        free_below: LOG_ODDS_ONE,
        occupied_above: LOG_ODDS_ONE,
    };
}

impl Default for Evidence {
    fn default() -> Self {
        Evidence::SEED
    }
}

/// What the map believes about a cell.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Occupancy {
    /// No opinion yet, or not enough evidence either way.
    Unknown,
    /// Beams have passed through it.
    Free,
    /// Beams have stopped in it.
    Occupied,
}

/// Where the grid lies in the map frame.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridGeometry {
    /// Side of one square cell, in millimetres (> 0).
    pub cell_mm: i32,
    /// Map-frame x of the grid's lower-left corner, in millimetres.
    pub origin_x_mm: i32,
    /// Map-frame y of the grid's lower-left corner, in millimetres.
    pub origin_y_mm: i32,
}

impl GridGeometry {
    /// The cell `(column, row)` holding map point `(x_mm, y_mm)`; may lie outside the grid.
    pub fn cell_of(&self, x_mm: i32, y_mm: i32) -> (i32, i32) {
        (
            (x_mm - self.origin_x_mm).div_euclid(self.cell_mm),
            (y_mm - self.origin_y_mm).div_euclid(self.cell_mm),
        )
    }

    /// Map-frame centre of cell `(column, row)`, in millimetres (rounded down to whole mm).
    pub fn centre_of(&self, column: i32, row: i32) -> (i32, i32) {
        (
            self.origin_x_mm + column * self.cell_mm + self.cell_mm / 2,
            self.origin_y_mm + row * self.cell_mm + self.cell_mm / 2,
        )
    }
}

/// Counts of the grid's cells by what the map believes.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OccupancyCounts {
    /// Cells believed free.
    pub free: u32,
    /// Cells believed occupied.
    pub occupied: u32,
    /// Cells with no firm belief.
    pub unknown: u32,
}

/// A `W` x `H` log-odds grid; row 0 is the lowest y, column 0 the lowest x.
///
/// The seed's mat is `GridMap<46, 46>` (5 cm cells, 15 cm margin, 4.2 KB); a 10 m room at
/// 5 cm is `GridMap<206, 206>` (83 KB). Sized by const generics so there is no allocator.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct GridMap<const W: usize, const H: usize> {
    geometry: GridGeometry,
    evidence: Evidence,
    cells: [[LogOdds; W]; H],
}

impl<const W: usize, const H: usize> GridMap<W, H> {
    /// Columns in the grid.
    pub const WIDTH: usize = W;
    /// Rows in the grid.
    pub const HEIGHT: usize = H;

    /// An empty (all unknown) grid.
    pub const fn new(geometry: GridGeometry, evidence: Evidence) -> Self {
        GridMap {
            geometry,
            evidence,
            cells: [[0; W]; H],
        }
    }

    /// Forgets everything: every cell back to unknown.
    pub fn clear(&mut self) {
        for row in self.cells.iter_mut() {
            row.fill(0);
        }
    }

    /// Where the grid lies.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// The evidence rules in use.
    pub fn evidence(&self) -> &Evidence {
        &self.evidence
    }

    /// The log odds of a cell, or `None` outside the grid.
    pub fn log_odds(&self, column: i32, row: i32) -> Option<LogOdds> {
        let row = self.cells.get(usize::try_from(row).ok()?)?;
        row.get(usize::try_from(column).ok()?).copied()
    }

    /// What the map believes about a cell; outside the grid is unknown.
    pub fn occupancy(&self, column: i32, row: i32) -> Occupancy {
        self.log_odds(column, row)
            .map_or(Occupancy::Unknown, |l| self.classify(l))
    }

    fn classify(&self, l: LogOdds) -> Occupancy {
        if l < -self.evidence.free_below {
            Occupancy::Free
        } else if l > self.evidence.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }

    /// Every row of raw log odds, lowest y first: for telemetry and pictures.
    pub fn rows(&self) -> &[[LogOdds; W]; H] {
        &self.cells
    }

    /// Counts cells by belief.
    pub fn counts(&self) -> OccupancyCounts {
        let mut counts = OccupancyCounts::default();
        for &l in self.cells.iter().flatten() {
            match self.classify(l) {
                Occupancy::Free => counts.free += 1,
                Occupancy::Occupied => counts.occupied += 1,
                Occupancy::Unknown => counts.unknown += 1,
            }
        }
        counts
    }

    /// Adds `amount` to a cell, saturating at the clamp; cells outside the grid are ignored.
    /// Returns whether the cell was inside.
    #[inline]
    pub fn add(&mut self, column: i32, row: i32, amount: LogOdds) -> bool {
        // One unsigned comparison per axis rejects negatives too; the sum in 32 bits cannot
        // overflow, and the clamp (at most `i16::MAX`) brings it back into a cell.
        let (Ok(column), Ok(row)) = (usize::try_from(column), usize::try_from(row)) else {
            return false;
        };
        let Some(cell) = self.cells.get_mut(row).and_then(|r| r.get_mut(column)) else {
            return false;
        };
        let clamp = i32::from(self.evidence.clamp);
        *cell = (i32::from(*cell) + i32::from(amount)).max(-clamp).min(clamp) as LogOdds;
        true
    }

    /// Marks `cells` free but for `spared`; returns how many were inside the grid.
    #[inline]
    fn mark_free(
        &mut self,
        cells: impl Iterator<Item = (i32, i32)>,
        spared: Option<(i32, i32)>,
    ) -> u32 {
        let miss = self.evidence.miss;
        let mut written = 0;
        for cell in cells {
            if Some(cell) != spared && self.add(cell.0, cell.1, miss) {
                written += 1;
            }
        }
        written
    }

    /// Writes one beam: free along it, occupied where it stopped.
    ///
    /// `from` is the sensor's position and `to` where the beam stopped, both map millimetres.
    /// Cells from the sensor's cell to the cell of `free_end` are marked free once each
    /// (integer grid traversal: every cell the segment crosses, none twice); the cell of `to`
    /// is marked occupied when `hit` is set and is never also marked free. Cells outside
    /// the grid are skipped. Returns the number of cells written.
    pub fn insert_beam(
        &mut self,
        from: (i32, i32),
        free_end: (i32, i32),
        to: (i32, i32),
        hit: bool,
    ) -> u32 {
        let hit_cell = self.geometry.cell_of(to.0, to.1);
        // One loop per walk width, so the step's width is not decided again per cell.
        let mut written = match CellWalk::new(&self.geometry, from, free_end) {
            CellWalk::Short(walk) => self.mark_free(walk, hit.then_some(hit_cell)),
            CellWalk::Long(walk) => self.mark_free(walk, hit.then_some(hit_cell)),
        };
        if hit && self.add(hit_cell.0, hit_cell.1, self.evidence.hit) {
            written += 1;
        }
        written
    }
}

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
/// boundary distances stay below `(extent + cell) * extent`, which is under `2^29` here.
pub const SHORT_WALK_MM: i64 = 1 << 14;

impl CellWalk {
    /// The walk from `from` to `to` (map millimetres) over `geometry`'s cells.
    pub fn new(geometry: &GridGeometry, from: (i32, i32), to: (i32, i32)) -> CellWalk {
        let cell = (geometry.cell_mm as i64).max(1);
        let start = (
            from.0 as i64 - geometry.origin_x_mm as i64,
            from.1 as i64 - geometry.origin_y_mm as i64,
        );
        let end = (
            to.0 as i64 - geometry.origin_x_mm as i64,
            to.1 as i64 - geometry.origin_y_mm as i64,
        );
        let short = |v: i64| v.abs() < SHORT_WALK_MM;
        if short(end.0 - start.0) && short(end.1 - start.1) && short(cell) {
            CellWalk::Short(Walk::new(cell, start, end))
        } else {
            CellWalk::Long(Walk::new(cell, start, end))
        }
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

/// The integers a [`Walk`] accumulates boundary distances in.
pub trait WalkInt: Copy + Ord + core::ops::Mul<Output = Self> {
    /// Larger than any distance reached: the boundary along an axis the segment does not
    /// move on.
    const NEVER: Self;
    /// `self + other`, stopping at [`WalkInt::NEVER`].
    fn add_capped(self, other: Self) -> Self;
    /// `v` in this width; only called with values that fit.
    fn narrow(v: i64) -> Self;
}

impl WalkInt for i32 {
    const NEVER: i32 = i32::MAX;
    #[inline]
    fn add_capped(self, other: i32) -> i32 {
        self.saturating_add(other)
    }
    #[inline]
    fn narrow(v: i64) -> i32 {
        v as i32
    }
}

impl WalkInt for i64 {
    const NEVER: i64 = i64::MAX;
    #[inline]
    fn add_capped(self, other: i64) -> i64 {
        self.saturating_add(other)
    }
    #[inline]
    fn narrow(v: i64) -> i64 {
        v
    }
}

/// One walk's state, its boundary distances in `T`.
pub struct Walk<T> {
    column: i32,
    row: i32,
    step_column: i32,
    step_row: i32,
    /// Distance to the next vertical boundary, scaled by `|dy|` (compared against `next_row`).
    next_column: T,
    /// Distance to the next horizontal boundary, scaled by `|dx|`.
    next_row: T,
    delta_column: T,
    delta_row: T,
    /// Column boundaries still to cross before the end cell.
    columns_left: u32,
    /// Row boundaries still to cross before the end cell.
    rows_left: u32,
    started: bool,
}

impl<T: WalkInt> Walk<T> {
    /// The walk from `start` to `end`, millimetres from the grid's corner. The cell size
    /// and the extent along each axis must fit `T`'s products (see [`SHORT_WALK_MM`]).
    fn new(cell: i64, start: (i64, i64), end: (i64, i64)) -> Walk<T> {
        let (fx, fy) = start;
        let (c0, r0) = (div_floor(fx, cell), div_floor(fy, cell));
        let (c1, r1) = (div_floor(end.0, cell), div_floor(end.1, cell));
        let (dx, dy) = (end.0 - fx, end.1 - fy);
        // Distance from the start to the first boundary crossed along each axis (at most
        // one cell).
        let to_column_edge = if dx > 0 {
            (c0 + 1) * cell - fx
        } else {
            fx - c0 * cell
        };
        let to_row_edge = if dy > 0 {
            (r0 + 1) * cell - fy
        } else {
            fy - r0 * cell
        };
        let (adx, ady) = (T::narrow(dx.abs()), T::narrow(dy.abs()));
        let cell = T::narrow(cell);
        Walk {
            column: c0 as i32,
            row: r0 as i32,
            step_column: if dx > 0 { 1 } else { -1 },
            step_row: if dy > 0 { 1 } else { -1 },
            // A boundary along an axis the segment does not move on is never reached.
            next_column: if dx == 0 {
                T::NEVER
            } else {
                T::narrow(to_column_edge) * ady
            },
            next_row: if dy == 0 {
                T::NEVER
            } else {
                T::narrow(to_row_edge) * adx
            },
            delta_column: cell * ady,
            delta_row: cell * adx,
            columns_left: (c1 - c0).unsigned_abs() as u32,
            rows_left: (r1 - r0).unsigned_abs() as u32,
            started: false,
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
        if self.columns_left == 0 && self.rows_left == 0 {
            return None;
        }
        // Cross whichever boundary comes first along the segment; once one axis has
        // reached the end cell's line only the other may move, so a segment that ends
        // exactly on a corner still ends in its own cell.
        let column_first = self.next_column < self.next_row;
        if self.rows_left == 0 || (self.columns_left > 0 && column_first) {
            self.columns_left -= 1;
            self.column += self.step_column;
            self.next_column = self.next_column.add_capped(self.delta_column);
        } else {
            self.rows_left -= 1;
            self.row += self.step_row;
            self.next_row = self.next_row.add_capped(self.delta_row);
        }
        Some((self.column, self.row))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GEO: GridGeometry = GridGeometry {
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
    };

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
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = |span: i64| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) as i64).rem_euclid(2 * span + 1) - span
        };
        let limit = SHORT_WALK_MM - 1;
        for _ in 0..20_000 {
            let cell = 1 + next(200).abs();
            let start = (next(30_000), next(30_000));
            let end = (start.0 + next(limit), start.1 + next(limit));
            let wide: std::vec::Vec<_> = Walk::<i64>::new(cell, start, end).collect();
            let narrow: std::vec::Vec<_> = Walk::<i32>::new(cell, start, end).collect();
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

    #[test]
    fn cells_saturate_and_classify() {
        let mut g: GridMap<4, 4> = GridMap::new(GEO, Evidence::SEED);
        for _ in 0..100 {
            g.add(1, 1, Evidence::SEED.hit);
            g.add(2, 2, Evidence::SEED.miss);
        }
        assert_eq!(g.log_odds(1, 1), Some(2048));
        assert_eq!(g.log_odds(2, 2), Some(-2048));
        assert_eq!(g.occupancy(1, 1), Occupancy::Occupied);
        assert_eq!(g.occupancy(2, 2), Occupancy::Free);
        assert_eq!(g.occupancy(0, 0), Occupancy::Unknown);
        assert!(!g.add(-1, 0, 5));
        assert!(!g.add(0, 4, 5));
        assert_eq!(
            g.counts(),
            OccupancyCounts {
                free: 1,
                occupied: 1,
                unknown: 14
            }
        );
    }

    #[test]
    fn beam_marks_free_then_hit_and_clips() {
        let mut g: GridMap<46, 46> = GridMap::new(GEO, Evidence::SEED);
        // From (700, 500) straight up to the far wall at 2000 mm.
        let n = g.insert_beam((700, 500), (700, 1950), (700, 2000), true);
        let (c, r) = GEO.cell_of(700, 2000);
        assert_eq!(g.log_odds(c, r), Some(218));
        assert_eq!(g.log_odds(c, r - 1), Some(-102));
        assert_eq!(n, 31);
        // A beam leaving the grid entirely is clipped, not a panic.
        let n = g.insert_beam((700, 500), (700, 90_000), (700, 100_000), true);
        assert!(n > 0 && n < 60);
    }
}
