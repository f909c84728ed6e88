//! A grid read through a slice, its size erased.
//!
//! The scan matcher reads the map through this: code generic over the grid's size is
//! compiled in the crate that names the size (the firmware, built for size rather than
//! speed), while code that is not is compiled here, at this crate's optimisation.

use super::map::{Evidence, GridGeometry, LogOdds, Occupancy};

/// The cells in use of a grid, row after row, with what they mean and where they lie.
#[derive(Clone, Copy, Debug)]
pub struct GridView<'a> {
    cells: &'a [LogOdds],
    /// Cells from one row to the next.
    stride: usize,
    columns: u32,
    rows: u32,
    evidence: Evidence,
    geometry: GridGeometry,
}

impl<'a> GridView<'a> {
    /// A view of `cells`, `stride` a row, of which the first `columns` x `rows` are in use.
    pub(super) fn new(
        cells: &'a [LogOdds],
        stride: usize,
        (columns, rows): (u32, u32),
        evidence: Evidence,
        geometry: GridGeometry,
    ) -> GridView<'a> {
        GridView {
            cells,
            stride,
            columns,
            rows,
            evidence,
            geometry,
        }
    }

    /// Where the grid lies.
    pub fn geometry(&self) -> &GridGeometry {
        &self.geometry
    }

    /// The log odds of row `row`'s cells in use, lowest x first; empty outside the grid.
    #[inline]
    pub fn row(&self, row: i32) -> &'a [LogOdds] {
        if (row as u32) >= self.rows {
            return &[];
        }
        let start = row as usize * self.stride;
        self.cells
            .get(start..start + self.columns as usize)
            .unwrap_or(&[])
    }

    /// The log odds of `width` cells of row `row` from column `column`, lowest x first;
    /// `None` unless all of them lie in the grid.
    #[inline]
    pub fn run(&self, column: i32, row: i32, width: usize) -> Option<&'a [LogOdds]> {
        let column = u32::try_from(column).ok()?;
        if (row as u32) >= self.rows || column.checked_add(width as u32)? > self.columns {
            return None;
        }
        let start = row as usize * self.stride + column as usize;
        self.cells.get(start..start + width)
    }

    /// The evidence rules its cells follow.
    pub fn evidence(&self) -> &Evidence {
        &self.evidence
    }

    /// What the map believes about a cell; outside the cells in use is unknown, as
    /// [`GridMap::occupancy`](super::GridMap::occupancy).
    #[inline]
    pub fn occupancy(&self, column: i32, row: i32) -> Occupancy {
        if (column as u32) >= self.columns || (row as u32) >= self.rows {
            return Occupancy::Unknown;
        }
        self.cells
            .get(row as usize * self.stride + column as usize)
            .map_or(Occupancy::Unknown, |&l| self.evidence.classify(l))
    }
}
