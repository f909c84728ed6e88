//! The coarse level of the search: for each beam end at one heading, the few cells that
//! every translation of the window can draw its score from, looked up once, and their
//! maximum.
//!
//! Cartographer prunes its search with grids max-pooled over growing blocks. Here the
//! translation window (a few centimetres) is about one 5 cm cell wide, so every end's
//! window falls in a block of at most `FOOTPRINT` x `FOOTPRINT` cells: those are looked up
//! once per end and heading, their maximum bounds what any translation can score (the
//! max-pool over the window), and the fine level spreads the same lookups over the
//! translations instead of looking each one up again. A pooled copy of the whole grid would
//! cost as much RAM as the grid (83 KB in a 10 m room) and be stale after every tick.
//!
//! An end scores the bilinear interpolation of its four nearest cells' scores (as Hector's
//! map access): with 5 cm cells and 1 cm steps, a nearest-cell score is flat over a cell
//! and the surface a plateau that pins nothing finer than the cell.

use super::divide::Divider;
use super::score::ScoreTable;
use crate::grid::GridView;

/// Most cells a window may span along each axis, the interpolation's neighbour included.
pub const FOOTPRINT: usize = 4;

/// Where each translation step puts an end along one axis: the block cell below it and
/// how far past that cell's centre, in millimetres (`0..cell`).
#[derive(Clone, Copy, Debug)]
pub(super) struct Steps<const SIDE: usize> {
    pub cell: [u8; SIDE],
    pub past: [i16; SIDE],
}

/// The cells one beam end can draw from over the translation window, with their scores.
#[derive(Clone, Copy, Debug)]
pub(super) struct Footprint<const SIDE: usize> {
    /// Score of each cell of the block, `[row][column]` from the block's lower-left.
    pub scores: [[i16; FOOTPRINT]; FOOTPRINT],
    /// For each translation step along x, where the end lands.
    pub x: Steps<SIDE>,
    /// For each translation step along y, where the end lands.
    pub y: Steps<SIDE>,
    /// The largest score in the block: what any translation can give this end.
    pub max: i16,
    /// Whether any cell of the block scores: an end among unknown cells adds nothing at
    /// any translation, and is skipped.
    pub scores_any: bool,
    /// Cells looked up.
    pub lookups: u32,
}

impl<const SIDE: usize> Footprint<SIDE> {
    /// A footprint with nothing in it, to fill.
    pub const EMPTY: Footprint<SIDE> = Footprint {
        scores: [[0; FOOTPRINT]; FOOTPRINT],
        x: Steps {
            cell: [0; SIDE],
            past: [0; SIDE],
        },
        y: Steps {
            cell: [0; SIDE],
            past: [0; SIDE],
        },
        max: 0,
        scores_any: false,
        lookups: 0,
    };

    /// Fills this with the block for an end at grid-relative `(x, y)` millimetres (from
    /// the grid's corner) when the window's lowest translation is applied, stepping
    /// `step_mm` `SIDE - 1` times along each axis. `false` if the window spans more than
    /// [`FOOTPRINT`] cells. Filled in place: a footprint returned by value is copied
    /// byte by byte on the M0+, several times over.
    #[inline]
    pub fn fill(
        &mut self,
        map: &GridView,
        scores: &ScoreTable,
        low: (i32, i32),
        step_mm: i32,
        divider: &Divider,
    ) -> bool {
        let cell = divider.divisor();
        // From the cells' centres: the cell whose centre is below and to the left.
        let (first_column, within_x) = divider.div_rem(low.0 - cell / 2);
        let (first_row, within_y) = divider.div_rem(low.1 - cell / 2);
        let Some(columns) = steps(&mut self.x, within_x, step_mm, cell) else {
            return false;
        };
        let Some(rows) = steps(&mut self.y, within_y, step_mm, cell) else {
            return false;
        };
        let mut max = i16::MIN;
        let mut any = false;
        for (r, row) in self.scores.iter_mut().enumerate().take(rows) {
            let cells = map.row(first_row + r as i32);
            for (c, slot) in row.iter_mut().enumerate().take(columns) {
                let s = usize::try_from(first_column + c as i32)
                    .ok()
                    .and_then(|i| cells.get(i))
                    .map_or(scores.unknown, |&l| scores.of(l));
                *slot = s;
                max = max.max(s);
                any |= s != 0;
            }
        }
        self.max = max;
        self.scores_any = any;
        self.lookups = (rows * columns) as u32;
        true
    }
}

/// Fills `out` for `SIDE` steps of `step_mm` from `within` millimetres past the first
/// cell centre's line (`0..cell`): for each step the cell below, counted from the first,
/// and how far past its centre. Returns how many cells the interpolation needs (one past
/// the last), or `None` past [`FOOTPRINT`] or if a step is longer than a cell.
#[inline]
fn steps<const SIDE: usize>(
    out: &mut Steps<SIDE>,
    mut within: i32,
    step_mm: i32,
    cell: i32,
) -> Option<usize> {
    if step_mm > cell {
        return None;
    }
    let mut index = 0u8;
    for (slot, past) in out.cell.iter_mut().zip(out.past.iter_mut()) {
        // At most one cell a step: a compare, where a loop would be compiled to a divide.
        if within >= cell {
            within -= cell;
            index += 1;
        }
        *slot = index;
        *past = within as i16;
        within += step_mm;
    }
    let cells = usize::from(index) + 2;
    (cells <= FOOTPRINT).then_some(cells)
}
