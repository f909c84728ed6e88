//! What one beam end scores in one cell: occupied, free and unknown cells each have their
//! own score, set apart from the cell's log odds.
//!
//! Summing log odds pulls a match into the wall ahead: the cell behind a wall line
//! saturates while neighbouring beams' free paths lower the one in front, so the sum keeps
//! rising past the wall. A class score is the same in every occupied cell, however sure.

use crate::grid::{GridMap, Occupancy};

/// Scores of a beam end by what the map believes about its cell.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EndpointScores {
    /// An end in an occupied cell: the beam stopped where the map has a wall.
    pub occupied: i16,
    /// An end in a free cell: the beam stopped where the map has seen through.
    pub free: i16,
    /// An end in an unknown cell, or outside the grid.
    pub unknown: i16,
}

impl EndpointScores {
    /// A hit on a wall outweighs two ends in free space; unknown says nothing.
    pub const SEED: EndpointScores = EndpointScores {
        occupied: 4,
        free: -2,
        unknown: 0,
    };

    /// The score of a beam end in cell `(column, row)`.
    #[inline]
    pub fn of<const W: usize, const H: usize>(
        &self,
        map: &GridMap<W, H>,
        column: i32,
        row: i32,
    ) -> i16 {
        match map.occupancy(column, row) {
            Occupancy::Occupied => self.occupied,
            Occupancy::Free => self.free,
            Occupancy::Unknown => self.unknown,
        }
    }

    /// The largest of the three: what a cell can score at most.
    pub fn best(&self) -> i32 {
        i32::from(self.occupied.max(self.free).max(self.unknown))
    }
}

impl Default for EndpointScores {
    fn default() -> Self {
        Self::SEED
    }
}
