//! The log-odds occupancy grid: fixed point, saturating, sized at compile time.
//!
//! - `map`: the grid itself, where it lies, what a cell's log odds mean, and counts;
//! - `ray`: writing a depth beam into the grid, free along it and occupied where it stopped;
//! - `walk`: the cells a segment crosses, in order, each once;
//! - `divider`: floor division by the cell size without a divide instruction;
//! - `view`: a grid read through a slice, its size erased (for the scan matcher).

mod divider;
mod map;
mod ray;
mod view;
mod walk;

pub use divider::CellDivider;
pub use map::{Evidence, GridGeometry, GridMap, LogOdds, Occupancy, OccupancyCounts, LOG_ODDS_ONE};
pub use ray::{BeamOrigin, BeamWriter};
pub use view::GridView;
pub use walk::{CellWalk, Walk, WalkInt, SHORT_WALK_MM};

/// The seed's grid geometry (5 cm cells, 15 cm margin), for the tests of every part.
#[cfg(test)]
const TEST_GEOMETRY: GridGeometry = GridGeometry {
    cell_mm: 50,
    origin_x_mm: -150,
    origin_y_mm: -150,
};
