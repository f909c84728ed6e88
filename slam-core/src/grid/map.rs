//! The grid: its cells' log odds, where it lies, and what it believes about each cell.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;

use super::divider::CellDivider;
use super::view::GridView;

/// Log odds in Q4 fixed point, one byte a cell: 16 is a log-odds of 1.0.
///
/// One byte halves every world's grid, which is what lets a 10 m room fit the robot's RAM.
pub type LogOdds = i8;

/// One log-odds unit (1.0) in [`LogOdds`].
pub const LOG_ODDS_ONE: LogOdds = 16;

/// How much one beam says about a cell, and when a cell counts as known.
///
/// The defaults are the seed's: +0.85 where a beam stops, -0.4 where it passes,
/// clamped to about +-8, free below about -1 and occupied above about +1.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Evidence {
    /// Added to the cell where a beam stops (positive).
    pub hit: LogOdds,
    /// Added to each cell a beam passes through (negative).
    pub miss: LogOdds,
    /// Cells saturate at `+-clamp` (positive, so its negation is a cell too).
    pub clamp: LogOdds,
    /// A cell below `-free_below` is free; above `occupied_above` it is occupied.
    pub free_below: LogOdds,
    /// See `free_below`.
    pub occupied_above: LogOdds,
}

impl Evidence {
    /// The seed's evidence in Q4.
    ///
    /// What a cell believes depends only on how hit, miss, clamp and thresholds compare,
    /// so these integers are chosen for their ratios to each other (+15 : -7 against the
    /// seed's 0.85 : -0.4, thresholds at 17) rather than each rounded alone to sixteenths
    /// (+14, -6, 16), which would turn a cell hit once free only at the sixth miss, not the
    /// fifth. The clamp goes as far as a byte does. `tests/evidence_beliefs.rs` holds them
    /// to the seed's beliefs.
    pub const SEED: Evidence = Evidence {
        hit: 15,
        miss: -7,
        clamp: 127,
        free_below: 17,
        occupied_above: 17,
    };
}

impl Evidence {
    /// What a cell whose log odds are `l` is believed to be.
    #[inline]
    pub fn classify(&self, l: LogOdds) -> Occupancy {
        if l < -self.free_below {
            Occupancy::Free
        } else if l > self.occupied_above {
            Occupancy::Occupied
        } else {
            Occupancy::Unknown
        }
    }
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
/// A byte a cell: the seed's mat is `GridMap<46, 46>` (5 cm cells, 15 cm margin); a 10 m
/// room at 5 cm is `GridMap<206, 206>`. Sized by const generics so there is no allocator.
#[derive(Clone, PartialEq, Eq, Debug)]
pub struct GridMap<const W: usize, const H: usize> {
    pub(super) geometry: GridGeometry,
    pub(super) evidence: Evidence,
    /// Divides by the cell size without dividing, for every beam's cells.
    pub(super) divider: CellDivider,
    /// Each cell value after one more beam passed through it, indexed by the value's byte:
    /// the beam walk looks a cell's next value up, for any evidence, in one load and one
    /// register (an add and a clamp by values would take two of the M0+'s few).
    pub(super) after_miss: [LogOdds; 256],
    /// Columns and rows in use, at most `W` and `H` ([`GridMap::limit_to`]).
    pub(super) columns: u32,
    pub(super) rows: u32,
    pub(super) cells: [[LogOdds; W]; H],
}

/// Builds only while [`GridMap::new_in`] writes every field: a field added to the map
/// stops the build here until it is written there too.
#[allow(dead_code)]
fn written_by_new_in<const W: usize, const H: usize>(g: GridMap<W, H>) {
    let GridMap {
        geometry: _,
        evidence: _,
        divider: _,
        after_miss: _,
        columns: _,
        rows: _,
        cells: _,
    } = g;
}

/// [`GridMap::after_miss`] for `evidence`: each byte's cell plus the miss, within the clamp.
const fn after_miss(evidence: &Evidence) -> [LogOdds; 256] {
    let (miss, clamp) = (evidence.miss as i32, evidence.clamp as i32);
    let mut table = [0; 256];
    let mut byte = 0;
    while byte < 256 {
        let next = byte as u8 as LogOdds as i32 + miss;
        table[byte] = if next < -clamp {
            -clamp
        } else if next > clamp {
            clamp
        } else {
            next
        } as LogOdds;
        byte += 1;
    }
    table
}

impl<const W: usize, const H: usize> GridMap<W, H> {
    /// Columns in the grid.
    pub const WIDTH: usize = W;
    /// Rows in the grid.
    pub const HEIGHT: usize = H;

    /// An empty (all unknown) grid.
    pub fn new(geometry: GridGeometry, evidence: Evidence) -> Self {
        let mut slot = MaybeUninit::uninit();
        Self::new_in(&mut slot, geometry, evidence);
        // SAFETY: `new_in` wrote every field.
        #[allow(unsafe_code)]
        unsafe {
            slot.assume_init()
        }
    }

    /// [`GridMap::new`] built in `slot`: its cells are cleared in place, never passed
    /// whole through the stack.
    #[allow(unsafe_code)]
    pub fn new_in(
        slot: &mut MaybeUninit<Self>,
        geometry: GridGeometry,
        evidence: Evidence,
    ) -> &mut Self {
        let g = slot.as_mut_ptr();
        // SAFETY: every field of `*g` is written once, through raw pointers into `slot`
        // (no reference to the unwritten whole is made); the check beside the struct names
        // them. A cell is a byte of log odds, for which zero is a valid value (unknown).
        unsafe {
            addr_of_mut!((*g).geometry).write(geometry);
            addr_of_mut!((*g).evidence).write(evidence);
            addr_of_mut!((*g).divider).write(CellDivider::new(geometry.cell_mm as i64));
            addr_of_mut!((*g).after_miss).write(after_miss(&evidence));
            addr_of_mut!((*g).columns).write(W as u32);
            addr_of_mut!((*g).rows).write(H as u32);
            addr_of_mut!((*g).cells).write_bytes(0, 1);
            slot.assume_init_mut()
        }
    }

    /// Maps only the first `columns` x `rows` cells (at most the grid's own): the rest
    /// stay unknown and count as outside. A grid built larger than its world (the
    /// simulator's, sized to hold any shipped world) then maps exactly as the robot's,
    /// built to the world's size, does, beams leaving it included.
    pub fn limit_to(&mut self, columns: usize, rows: usize) {
        self.columns = columns.min(W) as u32;
        self.rows = rows.min(H) as u32;
    }

    /// Columns and rows in use.
    pub fn extent(&self) -> (usize, usize) {
        (self.columns as usize, self.rows as usize)
    }

    /// Whether `(column, row)` is a cell in use: one unsigned comparison per axis rejects
    /// negatives too.
    #[inline(always)]
    pub(super) fn inside(&self, column: i32, row: i32) -> bool {
        (column as u32) < self.columns && (row as u32) < self.rows
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
    #[inline]
    pub fn log_odds(&self, column: i32, row: i32) -> Option<LogOdds> {
        if !self.inside(column, row) {
            return None;
        }
        let row = self.cells.get(row as usize)?;
        row.get(column as usize).copied()
    }

    /// What the map believes about a cell; outside the grid is unknown.
    #[inline]
    pub fn occupancy(&self, column: i32, row: i32) -> Occupancy {
        self.log_odds(column, row)
            .map_or(Occupancy::Unknown, |l| self.evidence.classify(l))
    }

    /// The cells in use through a slice, the grid's size erased ([`GridView`]).
    pub fn view(&self) -> GridView<'_> {
        GridView::new(
            self.cells.as_flattened(),
            W,
            (self.columns, self.rows),
            self.evidence,
            self.geometry,
        )
    }

    /// Every row of raw log odds, lowest y first: for telemetry and pictures. Cells beyond
    /// the [`GridMap::extent`] are unknown.
    pub fn rows(&self) -> &[[LogOdds; W]; H] {
        &self.cells
    }

    /// Counts cells by belief.
    pub fn counts(&self) -> OccupancyCounts {
        let mut counts = OccupancyCounts::default();
        let (columns, rows) = self.extent();
        for row in self.cells.iter().take(rows) {
            for &l in row.iter().take(columns) {
                match self.evidence.classify(l) {
                    Occupancy::Free => counts.free += 1,
                    Occupancy::Occupied => counts.occupied += 1,
                    Occupancy::Unknown => counts.unknown += 1,
                }
            }
        }
        counts
    }

    /// Adds `amount` to a cell, saturating at the clamp; cells outside the grid are ignored.
    /// Returns whether the cell was inside.
    #[inline]
    pub fn add(&mut self, column: i32, row: i32, amount: LogOdds) -> bool {
        // The sum in 32 bits cannot overflow, and the clamp (at most `i8::MAX`) brings it
        // back into a cell.
        if !self.inside(column, row) {
            return false;
        }
        let Some(cell) = self
            .cells
            .get_mut(row as usize)
            .and_then(|r| r.get_mut(column as usize))
        else {
            return false;
        };
        let clamp = i32::from(self.evidence.clamp);
        *cell = (i32::from(*cell) + i32::from(amount))
            .max(-clamp)
            .min(clamp) as LogOdds;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::TEST_GEOMETRY as GEO;

    #[test]
    fn cells_saturate_and_classify() {
        let mut g: GridMap<4, 4> = GridMap::new(GEO, Evidence::SEED);
        for _ in 0..100 {
            g.add(1, 1, Evidence::SEED.hit);
            g.add(2, 2, Evidence::SEED.miss);
        }
        assert_eq!(g.log_odds(1, 1), Some(Evidence::SEED.clamp));
        assert_eq!(g.log_odds(2, 2), Some(-Evidence::SEED.clamp));
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
}
