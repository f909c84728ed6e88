//! Where the page draws the map: a canvas at a fixed place in the page, a whole number of
//! CSS pixels a cell, so that each cell is a sharp square whose centre a test can find
//! in a screenshot (`host-sim/tests/page_browser.rs` does).

use serde::Serialize;

/// The map canvas's left edge, CSS pixels from the page's.
pub const MAP_LEFT_PX: u32 = 16;
/// The map canvas's top edge, CSS pixels from the page's: below the title and the
/// progress line.
pub const MAP_TOP_PX: u32 = 88;
/// The most CSS pixels the map may take across or down.
pub const MAP_MAX_PX: u32 = 640;
/// The most CSS pixels a cell is drawn across: a small grid is not blown up past it.
pub const MAX_CELL_PX: u32 = 16;

/// The map's place and scale on the page. The page's script places its canvas by it,
/// so that this struct is the one statement of where the map is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct MapLayout {
    /// The canvas's left edge, CSS pixels.
    pub left_px: u32,
    /// The canvas's top edge, CSS pixels.
    pub top_px: u32,
    /// CSS pixels a cell, at least 1.
    pub cell_px: u32,
    /// Columns of the grid: the canvas is `columns * cell_px` wide.
    pub columns: u32,
    /// Rows of the grid: the canvas is `rows * cell_px` high, row 0 at the bottom.
    pub rows: u32,
}

impl MapLayout {
    /// The layout of a `columns` x `rows` grid: as many whole pixels a cell as fit in
    /// [`MAP_MAX_PX`], between 1 and [`MAX_CELL_PX`].
    pub fn for_grid(columns: u16, rows: u16) -> MapLayout {
        let side = u32::from(columns.max(rows)).max(1);
        MapLayout {
            left_px: MAP_LEFT_PX,
            top_px: MAP_TOP_PX,
            cell_px: (MAP_MAX_PX / side).clamp(1, MAX_CELL_PX),
            columns: columns.into(),
            rows: rows.into(),
        }
    }

    /// The CSS pixel (x right, y down from the page's top-left corner) at the centre of
    /// cell `column`, `row` (row 0 the lowest), rounded down.
    pub fn cell_centre_px(&self, column: u32, row: u32) -> (u32, u32) {
        let x = self.left_px + column * self.cell_px + self.cell_px / 2;
        let flipped = self.rows.saturating_sub(1).saturating_sub(row);
        let y = self.top_px + flipped * self.cell_px + self.cell_px / 2;
        (x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_whole_pixels_and_fit() {
        let seed = MapLayout::for_grid(46, 46);
        assert_eq!(seed.cell_px, 13);
        let room = MapLayout::for_grid(206, 206);
        assert_eq!(room.cell_px, 3);
        assert_eq!(MapLayout::for_grid(1024, 10).cell_px, 1);
        assert_eq!(MapLayout::for_grid(2, 3).cell_px, MAX_CELL_PX);
        assert_eq!(MapLayout::for_grid(0, 0).cell_px, MAX_CELL_PX);
        for l in [seed, room] {
            assert!(l.columns * l.cell_px <= MAP_MAX_PX && l.rows * l.cell_px <= MAP_MAX_PX);
        }
    }

    #[test]
    fn row_zero_is_at_the_bottom() {
        let l = MapLayout::for_grid(46, 46);
        assert_eq!(l.cell_centre_px(0, 45), (16 + 6, 88 + 6));
        assert_eq!(l.cell_centre_px(0, 0), (16 + 6, 88 + 45 * 13 + 6));
        assert_eq!(l.cell_centre_px(45, 0).0, 16 + 45 * 13 + 6);
    }
}
