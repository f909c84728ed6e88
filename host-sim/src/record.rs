//! What a run leaves behind: a row per tick, the final map and the world it was drawn in.
//!
//! The pictures, the JSON figures and the tests all read this; so does the telemetry
//! viewer, which fills it from a robot's stream instead of from the simulator.

use serde::Serialize;

/// A point on the mat, in millimetres.
pub type PointMm = (f64, f64);

/// One tick of a run, as the chart plots it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TickRecord {
    /// Time since the start, in seconds.
    pub t_s: f64,
    /// The true position, millimetres.
    pub truth_mm: PointMm,
    /// The true heading, degrees clockwise from +y.
    pub truth_heading_deg: f64,
    /// The position the mapper used, millimetres.
    pub estimate_mm: PointMm,
    /// The heading the mapper used, degrees.
    pub estimate_heading_deg: f64,
    /// Share of the grid with a firm belief, percent.
    pub known_pct: f64,
    /// Distance from estimate to truth, centimetres.
    pub error_cm: f64,
    /// Estimate minus truth heading, degrees in [-180, 180).
    pub heading_error_deg: f64,
    /// Share of occupied cells off any real wall or tag, percent.
    pub out_of_place_pct: f64,
    /// Whether a tag fix was taken this tick.
    pub fix_taken: bool,
}

/// The map as it stood at the end: a belief per cell.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapSnapshot {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cell side, millimetres.
    pub cell_mm: f64,
    /// Map x of the grid's lower-left corner, millimetres.
    pub origin_x_mm: f64,
    /// Map y of the grid's lower-left corner, millimetres.
    pub origin_y_mm: f64,
    /// Row-major from the lowest row: `cells[row * width + column]`.
    pub cells: Vec<CellBelief>,
    /// Occupied cells that lie on no real wall or tag (same indexing); empty when the
    /// truth is not known (a real robot's stream).
    pub out_of_place: Vec<bool>,
}

/// What the map believes about one cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum CellBelief {
    /// No firm belief.
    Unknown,
    /// Free.
    Free,
    /// Occupied.
    Occupied,
}

/// The true world, drawn under the map.
#[derive(Clone, Debug, PartialEq, Serialize, Default)]
pub struct WorldOutline {
    /// Wall segments, millimetres.
    pub walls: Vec<(PointMm, PointMm)>,
    /// Tags: id and centre, millimetres.
    pub tags: Vec<(u16, PointMm)>,
}

/// Everything one run produced.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunRecord {
    /// The scenario's name.
    pub scenario: String,
    /// Which pose the mapper used: `truth`, `dead-reckoning` or `tags`.
    pub pose_mode: String,
    /// A row per tick.
    pub ticks: Vec<TickRecord>,
    /// The final map.
    pub map: MapSnapshot,
    /// The world under it.
    pub world: WorldOutline,
}
