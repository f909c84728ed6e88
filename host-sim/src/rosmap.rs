//! The final map as a ROS `map_server` pair, for nav2, RViz and everything else that reads
//! one: `map.pgm`, an 8-bit binary PGM with a pixel per cell, and `map.yaml`, which says
//! how to read it.
//!
//! The YAML gives the cell size in metres (`resolution`), where the image's lower-left
//! pixel lies in the map frame (`origin`: x, y in metres and yaw in radians, REP-103: x
//! east, y north, angles anticlockwise; the core's map has the same axes, so yaw is 0),
//! and the `trinary` thresholds. A reader takes each pixel's occupancy as
//! `(255 - pixel) / 255`: occupied above `occupied_thresh`, free below `free_thresh`,
//! unknown between. Occupied cells are written 0 (black), free ones 254 and unknown ones
//! 205, ROS's own choices, with `free_thresh` just under 205's 0.196 so that unknown stays
//! unknown whichever comparison a reader uses.

use crate::record::{CellBelief, MapSnapshot};
use std::fmt;
use std::path::{Path, PathBuf};

/// Pixel of an occupied cell.
pub const OCCUPIED_PIXEL: u8 = 0;
/// Pixel of a free cell.
pub const FREE_PIXEL: u8 = 254;
/// Pixel of a cell with no firm belief.
pub const UNKNOWN_PIXEL: u8 = 205;
/// Occupancy above which a pixel reads as occupied.
pub const OCCUPIED_THRESH: f64 = 0.65;
/// Occupancy below which a pixel reads as free.
pub const FREE_THRESH: f64 = 0.196;
/// The image's file name, beside the YAML.
pub const IMAGE_NAME: &str = "map.pgm";
/// The YAML's file name.
pub const YAML_NAME: &str = "map.yaml";

/// Why the map could not be written.
#[derive(Debug)]
pub enum ExportError {
    /// The directory could not be created.
    CreateDir(PathBuf, std::io::Error),
    /// A file could not be written.
    Write(PathBuf, std::io::Error),
    /// The map has no cells.
    Empty,
}

impl fmt::Display for ExportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExportError::CreateDir(p, e) => write!(f, "cannot create {}: {e}", p.display()),
            ExportError::Write(p, e) => write!(f, "cannot write {}: {e}", p.display()),
            ExportError::Empty => write!(f, "the map has no cells to export"),
        }
    }
}

impl std::error::Error for ExportError {}

/// The pixel a cell is drawn as.
pub fn pixel(cell: CellBelief) -> u8 {
    match cell {
        CellBelief::Occupied => OCCUPIED_PIXEL,
        CellBelief::Free => FREE_PIXEL,
        CellBelief::Unknown => UNKNOWN_PIXEL,
    }
}

/// The PGM image of `map`: the header, then the rows from the top (the grid's highest
/// row) down, as image files run.
pub fn pgm(map: &MapSnapshot) -> Vec<u8> {
    let mut out = format!("P5\n{} {}\n255\n", map.width, map.height).into_bytes();
    for row in map.cells.chunks(map.width.max(1)).rev() {
        out.extend(row.iter().map(|&c| pixel(c)));
    }
    out
}

/// The YAML that reads [`pgm`]'s image as `map`.
pub fn yaml(map: &MapSnapshot) -> String {
    format!(
        "image: {IMAGE_NAME}\nmode: trinary\nresolution: {}\norigin: [{}, {}, 0.0]\n\
         negate: 0\noccupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n",
        map.cell_mm / 1000.0,
        map.origin_x_mm / 1000.0,
        map.origin_y_mm / 1000.0,
    )
}

/// Writes `dir/map.pgm` and `dir/map.yaml`, creating `dir`; returns the YAML's path (the
/// file a map server is pointed at).
pub fn write(map: &MapSnapshot, dir: &Path) -> Result<PathBuf, ExportError> {
    if map.width == 0 || map.height == 0 || map.cells.len() != map.width * map.height {
        return Err(ExportError::Empty);
    }
    std::fs::create_dir_all(dir).map_err(|e| ExportError::CreateDir(dir.to_path_buf(), e))?;
    let image = dir.join(IMAGE_NAME);
    std::fs::write(&image, pgm(map)).map_err(|e| ExportError::Write(image, e))?;
    let yaml_path = dir.join(YAML_NAME);
    std::fs::write(&yaml_path, yaml(map)).map_err(|e| ExportError::Write(yaml_path.clone(), e))?;
    Ok(yaml_path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> MapSnapshot {
        use CellBelief::*;
        MapSnapshot {
            width: 3,
            height: 2,
            cell_mm: 50.0,
            origin_x_mm: -150.0,
            origin_y_mm: 250.0,
            // Lowest row first.
            cells: vec![Occupied, Free, Unknown, Free, Free, Occupied],
            out_of_place: Vec::new(),
        }
    }

    #[test]
    fn the_image_runs_from_the_top_row_down() {
        let image = pgm(&map());
        let header = b"P5\n3 2\n255\n";
        assert_eq!(&image[..header.len()], header);
        assert_eq!(&image[header.len()..], &[254, 254, 0, 0, 254, 205]);
    }

    #[test]
    fn the_yaml_places_the_lower_left_pixel_in_metres() {
        let text = yaml(&map());
        assert!(text.contains("resolution: 0.05\n"), "{text}");
        assert!(text.contains("origin: [-0.15, 0.25, 0.0]\n"), "{text}");
        assert!(text.contains("image: map.pgm\n") && text.contains("mode: trinary\n"));
    }

    #[test]
    fn each_pixel_reads_back_as_its_cell_by_the_thresholds() {
        for cell in [CellBelief::Occupied, CellBelief::Free, CellBelief::Unknown] {
            let occ = (255.0 - f64::from(pixel(cell))) / 255.0;
            let read = if occ > OCCUPIED_THRESH {
                CellBelief::Occupied
            } else if occ < FREE_THRESH {
                CellBelief::Free
            } else {
                CellBelief::Unknown
            };
            assert_eq!(read, cell);
            // Inclusive comparisons read the same.
            assert!(occ != OCCUPIED_THRESH && occ != FREE_THRESH);
        }
    }

    #[test]
    fn an_empty_map_is_refused() {
        let mut m = map();
        m.cells.clear();
        let tmp = tempfile::TempDir::with_prefix("rosmap-empty-").expect("temp dir");
        let dir = tmp.path().join("map");
        assert!(matches!(write(&m, &dir), Err(ExportError::Empty)));
        assert!(
            !dir.exists(),
            "nothing is created for a map that cannot be written"
        );
    }
}
