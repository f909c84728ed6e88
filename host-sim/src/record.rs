//! What a run leaves behind: a row per tick, the final map and the world it was drawn in.
//!
//! The pictures, the JSON figures and the tests all read this; so does the telemetry
//! viewer, which fills it from a robot's stream instead of from the simulator.

use crate::robot::wrap_deg;
use crate::world::World;
use serde::Serialize;
use slam_core::Occupancy;

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

impl TickRecord {
    /// A tick as the mapper saw it: every truth and error field NaN until
    /// [`TickRecord::set_truth`] (the pictures leave NaN out).
    pub fn estimated(
        t_s: f64,
        estimate_mm: PointMm,
        estimate_heading_deg: f64,
        known_pct: f64,
        fix_taken: bool,
    ) -> TickRecord {
        TickRecord {
            t_s,
            truth_mm: (f64::NAN, f64::NAN),
            truth_heading_deg: f64::NAN,
            estimate_mm,
            estimate_heading_deg,
            known_pct,
            error_cm: f64::NAN,
            heading_error_deg: f64::NAN,
            out_of_place_pct: f64::NAN,
            fix_taken,
        }
    }

    /// Records the true pose (`heading_deg` clockwise from +y, any number of turns) and
    /// the estimate's errors against it. The one place a tick's errors are worked out, so
    /// that `host-sim run` and `host-sim view --truth` score a pose alike.
    pub fn set_truth(&mut self, truth_mm: PointMm, heading_deg: f64) {
        let (ex, ey) = self.estimate_mm;
        self.truth_mm = truth_mm;
        self.truth_heading_deg = wrap_deg(heading_deg);
        self.error_cm = (ex - truth_mm.0).hypot(ey - truth_mm.1) / 10.0;
        self.heading_error_deg = wrap_deg(self.estimate_heading_deg - heading_deg);
    }
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

impl From<Occupancy> for CellBelief {
    fn from(o: Occupancy) -> CellBelief {
        match o {
            Occupancy::Free => CellBelief::Free,
            Occupancy::Occupied => CellBelief::Occupied,
            Occupancy::Unknown => CellBelief::Unknown,
        }
    }
}

/// The true world, drawn under the map.
#[derive(Clone, Debug, PartialEq, Serialize, Default)]
pub struct WorldOutline {
    /// Wall segments, millimetres.
    pub walls: Vec<(PointMm, PointMm)>,
    /// Tags: id and centre, millimetres.
    pub tags: Vec<(u16, PointMm)>,
}

impl WorldOutline {
    /// The walls (tag cards left out: they are drawn as tags) and tags of `world`.
    pub fn of(world: &World) -> WorldOutline {
        WorldOutline {
            walls: world
                .walls()
                .iter()
                .filter(|w| w.tag.is_none())
                .map(|w| ((w.a.x, w.a.y), (w.b.x, w.b.y)))
                .collect(),
            tags: world
                .tags()
                .iter()
                .map(|t| (t.id, (t.centre.x, t.centre.y)))
                .collect(),
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    fn heading_error(estimate_deg: f64, truth_deg: f64) -> f64 {
        let mut t = TickRecord::estimated(0.0, (0.0, 0.0), estimate_deg, 0.0, false);
        t.set_truth((0.0, 0.0), truth_deg);
        t.heading_error_deg
    }

    #[test]
    fn heading_errors_wrap_across_north() {
        // 1 degree is 2 degrees clockwise of 359, not 358 anticlockwise.
        assert!((heading_error(1.0, 359.0) - 2.0).abs() < 1e-9);
        assert!((heading_error(-179.0, 179.0) - 2.0).abs() < 1e-9);
        // The harness's truth is unwrapped: three turns and a bit.
        assert!((heading_error(-8.94, 1072.0) - -0.94).abs() < 1e-9);
        assert!((heading_error(10.0, 10.0)).abs() < 1e-9);
    }

    #[test]
    fn truth_fills_the_errors_and_the_wrapped_heading() {
        let mut t = TickRecord::estimated(1.0, (703.0, 504.0), 0.0, 5.0, true);
        assert!(t.error_cm.is_nan() && t.truth_mm.0.is_nan());
        t.set_truth((700.0, 500.0), 370.0);
        assert!((t.error_cm - 0.5).abs() < 1e-9);
        assert!((t.truth_heading_deg - 10.0).abs() < 1e-9);
        assert!((t.heading_error_deg - -10.0).abs() < 1e-9);
    }
}
