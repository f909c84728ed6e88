//! The coarse level of the search: for each beam end at one heading, the block of cells
//! that every translation of the window can draw its score from, and their maximum.
//!
//! Cartographer prunes its search with grids max-pooled over growing blocks. Here the
//! translation window (a few centimetres) is about one 5 cm cell wide, so every end's
//! window falls in a block of `FOOTPRINT` x `FOOTPRINT` cells: its maximum bounds what any
//! translation can score (the max-pool over the window), and the fine level spreads the
//! block's scores over the translations instead of looking each one up again. A pooled
//! copy of the whole grid would cost as much RAM as the grid (83 KB in a 10 m room) and be
//! stale after every tick.
//!
//! An end scores the bilinear interpolation of its four nearest cells' scores (as Hector's
//! map access): with 5 cm cells and 1 cm steps, a nearest-cell score is flat over a cell
//! and the surface a plateau that pins nothing finer than the cell.

use super::divide::Divider;
use super::runs::RunTable;
use super::score::ScoreTable;
use crate::grid::GridView;

/// Most cells a window may span along each axis, the interpolation's neighbour included.
pub const FOOTPRINT: usize = 4;

/// The translation window as the footprints see it: the cell, the step and where the
/// translations cross cell lines, all in millimetres.
#[derive(Clone, Copy, Debug)]
pub(super) struct Window {
    /// Floor division by the cell.
    pub divider: Divider,
    /// The cell's side.
    pub cell: i32,
    /// One translation step.
    pub step: i32,
    /// The translations along an axis in runs between cell lines.
    pub runs: RunTable,
}

impl Window {
    /// The window of `side` steps of `step` millimetres on `cell` millimetre cells; `None`
    /// if a step is longer than a cell or the window spans more than [`FOOTPRINT`] cells
    /// with the interpolation's neighbour, wherever it starts in a cell.
    pub fn new(side: usize, step: i32, cell: i32) -> Option<Window> {
        let span = (side as i32 - 1).checked_mul(step)?;
        if step < 1
            || step > cell
            || cell > i32::from(u16::MAX)
            || span > (FOOTPRINT as i32 - 2) * cell
        {
            return None;
        }
        Some(Window {
            divider: Divider::new(cell)?,
            cell,
            step,
            runs: RunTable::new(side, step, cell)?,
        })
    }
}

/// The cells one beam end can draw from over the translation window, with their scores.
///
/// The block is [`FOOTPRINT`] cells a side wherever the window starts in a cell, and kept
/// from one heading to the next: half a degree moves an end a metre away by 9 mm, so the
/// block usually starts at the same cell, and then is not looked up again.
///
/// 160 of these are kept beside the map, so the small fields are halfwords, laid out
/// (`repr(C)`) first, where the M0+'s loads reach them with an immediate offset.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(super) struct Footprint {
    /// How far past the block's first column's centre the window's lowest translation
    /// puts the end, millimetres (`0..cell`; [`Window::new`] takes cells that fit).
    pub within_x: u16,
    /// The same along y, past the first row's centre.
    pub within_y: u16,
    /// The largest score in the block: what any translation can give this end (a score
    /// is a halfword, [`ScoreTable::of`]).
    pub max: i16,
    /// Whether any cell of the block scores: an end among unknown cells adds nothing at
    /// any translation, and is skipped.
    pub scores_any: bool,
    /// Whether a block has been looked up, at `corner`. A flag rather than an `Option`, so
    /// that an empty footprint is all zero bits and 160 of them are cleared, not copied.
    looked_up: bool,
    /// The block's lower-left cell, `(column, row)`.
    corner: (i32, i32),
    /// Score of each cell of the block, `[row][column]` from the block's lower-left.
    /// Words, not halfwords: the M0+ loads a signed halfword only from a register offset,
    /// and the spread reads these for every end at every heading.
    pub scores: [[i32; FOOTPRINT]; FOOTPRINT],
}

impl Footprint {
    /// A footprint with nothing in it, to fill.
    pub const EMPTY: Footprint = Footprint {
        within_x: 0,
        within_y: 0,
        max: 0,
        scores_any: false,
        looked_up: false,
        corner: (0, 0),
        scores: [[0; FOOTPRINT]; FOOTPRINT],
    };

    /// Places this for an end at grid-relative `(x, y)` millimetres (from the grid's
    /// corner) when the window's lowest translation is applied, and looks the block up
    /// if it starts at another cell than last time. Returns the cells looked up.
    #[inline]
    pub fn fill(
        &mut self,
        map: &GridView,
        scores: &ScoreTable,
        low: (i32, i32),
        window: &Window,
    ) -> u32 {
        let half = window.cell / 2;
        // From the cells' centres: the cell whose centre is below and to the left.
        let (column, within_x) = window.divider.div_rem(low.0 - half);
        let (row, within_y) = window.divider.div_rem(low.1 - half);
        // Remainders of the cell, which fits a halfword.
        self.within_x = within_x as u16;
        self.within_y = within_y as u16;
        if self.looked_up && self.corner == (column, row) {
            return 0;
        }
        self.look_up(map, scores, column, row);
        (FOOTPRINT * FOOTPRINT) as u32
    }

    /// Looks up the block whose lower-left cell is `(column, row)`. Not inlined into the
    /// loop over the ends: inlined, the loop keeps a pointer to each field on the stack.
    #[inline(never)]
    fn look_up(&mut self, map: &GridView, scores: &ScoreTable, column: i32, row: i32) {
        let mut max = i32::MIN;
        let mut any = 0;
        for (r, out) in (row..).zip(self.scores.iter_mut()) {
            if let Some(cells) = map.run(column, r, FOOTPRINT) {
                for (slot, &l) in out.iter_mut().zip(cells) {
                    let s = i32::from(scores.of(l));
                    *slot = s;
                    max = max.max(s);
                    any |= s;
                }
            } else {
                // Across the grid's edge: cell by cell, unknown outside.
                let cells = map.row(r);
                for (c, slot) in (column..).zip(out.iter_mut()) {
                    let s = usize::try_from(c)
                        .ok()
                        .and_then(|i| cells.get(i))
                        .map_or(scores.unknown, |&l| scores.of(l));
                    let s = i32::from(s);
                    *slot = s;
                    max = max.max(s);
                    any |= s;
                }
            }
        }
        self.looked_up = true;
        self.corner = (column, row);
        // The largest of sixteen halfword scores.
        self.max = max as i16;
        self.scores_any = any != 0;
    }
}
