//! The robot's latest map, rebuilt from its `Hello` and `MapRows`, as a `foxglove.Grid`.

use crate::telemetry::MAX_GRID_SIDE;
use ::foxglove::messages::{packed_element_field::NumericType, Grid, PackedElementField};
use ::foxglove::messages::{Pose, Quaternion, Timestamp, Vector2, Vector3};
use wire::telemetry::{Hello, MapRows};

/// The name of the grid's one field: the chance that a cell is occupied, 0 to 1.
pub const PROBABILITY_FIELD: &str = "probability";

/// Bytes per cell in the grid's data: one little-endian `f32`.
pub const CELL_BYTES: usize = 4;

/// The chance that a cell is occupied, from its telemetry byte.
///
/// A cell byte is the cell's log odds in sixteenths (see `wire::telemetry::CellScale`),
/// so the probability is the logistic of a sixteenth of it: 0 (never seen) is 0.5, and
/// the robot's thresholds for free and occupied (17 by default) are about 0.26 and 0.74.
pub fn probability(cell: i8) -> f32 {
    let log_odds = f64::from(cell) / 16.0;
    (1.0 / (1.0 + (-log_odds).exp())) as f32
}

/// The latest map: the grid a `Hello` declares and the cells its chunks have filled.
#[derive(Clone, Debug, Default)]
pub struct LatestMap {
    hello: Option<Hello>,
    cells: Vec<i8>,
    /// Whether a chunk changed the map since [`LatestMap::grid`] was last asked.
    changed: bool,
}

impl LatestMap {
    /// No map yet.
    pub fn new() -> LatestMap {
        LatestMap::default()
    }

    /// Takes a `Hello`: a new grid (size, cell or origin) starts empty; an impossible one
    /// (as `host-sim view` refuses it) is ignored.
    pub fn hello(&mut self, h: &Hello) {
        if h.width == 0
            || h.height == 0
            || h.width > MAX_GRID_SIDE
            || h.height > MAX_GRID_SIDE
            || h.cell_mm < 1
        {
            return;
        }
        let shape = |h: &Hello| (h.width, h.height, h.cell_mm, h.origin_x_mm, h.origin_y_mm);
        if self.hello.as_ref().map(shape) != Some(shape(h)) {
            self.cells = vec![0; usize::from(h.width) * usize::from(h.height)];
            self.changed = true;
        }
        self.hello = Some(*h);
    }

    /// Places a chunk of cells; one outside the grid, or before any `Hello`, is dropped.
    pub fn rows(&mut self, r: &MapRows) {
        let Some(h) = self.hello else { return };
        let cells = r.cells.as_slice();
        if let Some(slot) = r.slot_in(&mut self.cells, usize::from(h.width)) {
            if slot != cells {
                slot.copy_from_slice(cells);
                self.changed = true;
            }
        }
    }

    /// Whether the map changed since the last [`LatestMap::grid`].
    pub fn changed(&self) -> bool {
        self.changed
    }

    /// The latest `Hello` taken.
    pub fn hello_taken(&self) -> Option<&Hello> {
        self.hello.as_ref()
    }

    /// The map as a `foxglove.Grid` in the `frame` frame, metres, stamped `timestamp`;
    /// `None` before a `Hello`.
    pub fn grid(&mut self, frame: &str, timestamp: Timestamp) -> Option<Grid> {
        let h = self.hello?;
        self.changed = false;
        let mut data = Vec::with_capacity(self.cells.len() * CELL_BYTES);
        for &c in &self.cells {
            data.extend_from_slice(&probability(c).to_le_bytes());
        }
        let cell_m = f64::from(h.cell_mm) / 1000.0;
        Some(Grid {
            timestamp: Some(timestamp),
            frame_id: frame.to_string(),
            pose: Some(Pose {
                position: Some(Vector3 {
                    x: f64::from(h.origin_x_mm) / 1000.0,
                    y: f64::from(h.origin_y_mm) / 1000.0,
                    z: 0.0,
                }),
                orientation: Some(Quaternion {
                    x: 0.0,
                    y: 0.0,
                    z: 0.0,
                    w: 1.0,
                }),
            }),
            column_count: u32::from(h.width),
            cell_size: Some(Vector2 {
                x: cell_m,
                y: cell_m,
            }),
            row_stride: u32::from(h.width) * CELL_BYTES as u32,
            cell_stride: CELL_BYTES as u32,
            fields: vec![PackedElementField {
                name: PROBABILITY_FIELD.to_string(),
                offset: 0,
                r#type: NumericType::Float32 as i32,
            }],
            data: data.into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_core::Localiser;
    use wire::telemetry::{CellChunk, FirmwareVersion};

    fn hello(width: u16, height: u16) -> Hello {
        Hello {
            width,
            height,
            cell_mm: 50,
            origin_x_mm: -150,
            origin_y_mm: -100,
            free_below: 16,
            occupied_above: 16,
            firmware: FirmwareVersion::default(),
            localiser: Localiser::Filter,
            matching: false,
            boot: Default::default(),
        }
    }

    fn rows(first_row: u16, first_column: u16, cells: &[i8]) -> MapRows {
        let mut chunk = CellChunk::new();
        for &c in cells {
            let _ = chunk.push(c);
        }
        MapRows {
            first_row,
            first_column,
            cells: chunk,
        }
    }

    #[test]
    fn probabilities_keep_the_beliefs() {
        assert_eq!(probability(0), 0.5);
        assert!(probability(17) > 0.73 && probability(16) < 0.74);
        assert!(probability(-17) < 0.27);
        assert!(probability(i8::MIN) > 0.0 && probability(i8::MAX) < 1.0);
    }

    #[test]
    fn chunks_land_where_they_belong_and_strays_are_dropped() {
        let mut map = LatestMap::new();
        assert!(map.grid("map", Timestamp::new(0, 0)).is_none());
        map.rows(&rows(0, 0, &[100]));
        map.hello(&hello(3, 2));
        map.rows(&rows(1, 1, &[100, -100]));
        map.rows(&rows(1, 2, &[1, 2]));
        map.rows(&rows(0, 3, &[1]));
        assert!(map.changed());
        let grid = map.grid("map", Timestamp::new(0, 0)).expect("a grid");
        assert!(!map.changed());
        assert_eq!(
            (grid.column_count, grid.row_stride, grid.cell_stride),
            (3, 12, 4)
        );
        let cells: Vec<f32> = grid
            .data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let expected: Vec<f32> = [0, 0, 0, 0, 100, -100].map(probability).to_vec();
        assert_eq!(cells, expected);
        let origin = grid.pose.and_then(|p| p.position).expect("origin");
        assert_eq!((origin.x, origin.y), (-0.15, -0.1));
        // An impossible grid is ignored; the map stays.
        map.hello(&hello(0, 5));
        map.hello(&hello(2000, 5));
        assert_eq!(map.hello_taken().map(|h| h.width), Some(3));
    }
}
