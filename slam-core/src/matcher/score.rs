//! What one beam end scores in one cell: occupied, free and unknown cells each have their
//! own score, set apart from the cell's log odds.
//!
//! Summing log odds pulls a match into the wall ahead: the cell behind a wall line
//! saturates while neighbouring beams' free paths lower the one in front, so the sum keeps
//! rising past the wall. A class score is the same in every occupied cell, however sure.

use crate::grid::{Evidence, LogOdds, Occupancy};

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

    /// The largest of the three: what a cell can score at most.
    pub fn best(&self) -> i32 {
        i32::from(self.occupied.max(self.free).max(self.unknown))
    }
}

/// The score of an end in a cell of each log-odds byte, for one map's evidence: one load
/// a cell instead of two compares and a branch.
#[derive(Clone, Copy, Debug)]
pub(super) struct ScoreTable {
    by_byte: [i16; 256],
    /// An end outside the grid.
    pub unknown: i16,
}

impl ScoreTable {
    /// The table of `scores` under `evidence`.
    pub fn new(scores: &EndpointScores, evidence: &Evidence) -> ScoreTable {
        let mut by_byte = [0i16; 256];
        for (byte, s) in by_byte.iter_mut().enumerate() {
            *s = match evidence.classify(byte as u8 as LogOdds) {
                Occupancy::Occupied => scores.occupied,
                Occupancy::Free => scores.free,
                Occupancy::Unknown => scores.unknown,
            };
        }
        ScoreTable {
            by_byte,
            unknown: scores.unknown,
        }
    }

    /// The score of an end in a cell whose log odds are `l`.
    #[inline]
    pub fn of(&self, l: LogOdds) -> i16 {
        self.by_byte[usize::from(l as u8)]
    }
}

impl Default for EndpointScores {
    fn default() -> Self {
        Self::SEED
    }
}
