//! `--export-map DIR`: the final map as a ROS map_server pair, read back as a map server
//! reads it and held to the run's own grid.

// Only some of the shared helpers are used here.
#[allow(dead_code)]
mod common;

use common::{host_sim, scratch_dir, seed_path};
use host_sim::record::{CellBelief, MapSnapshot};
use host_sim::{run, PoseMode, Scenario};
use std::path::Path;

/// The prefix of this file's scratch directories.
const SCRATCH: &str = "host-sim-rosmap-";

/// What a map server makes of `DIR/map.yaml` and the image it names.
struct Loaded {
    resolution_m: f64,
    origin: [f64; 3],
    width: usize,
    height: usize,
    /// Row-major from the lowest row, as the grid is.
    cells: Vec<CellBelief>,
}

/// The value of `key: value` in `yaml`, as written by a map saver (one key a line).
fn field<'a>(yaml: &'a str, key: &str) -> &'a str {
    match yaml
        .lines()
        .find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))
    {
        Some(v) => v.trim(),
        None => panic!("no `{key}` in {yaml}"),
    }
}

fn number(text: &str) -> f64 {
    match text.trim().parse() {
        Ok(v) => v,
        Err(e) => panic!("`{text}` is not a number: {e}"),
    }
}

/// Reads the pair as nav2's map server does: the image named by the YAML beside it, each
/// pixel's occupancy `(255 - p) / 255` against the trinary thresholds, the image's bottom
/// row at the origin.
fn load(dir: &Path) -> Loaded {
    let yaml = std::fs::read_to_string(dir.join("map.yaml")).unwrap_or_default();
    assert_eq!(field(&yaml, "mode"), "trinary");
    assert_eq!(field(&yaml, "negate"), "0");
    let occupied = number(field(&yaml, "occupied_thresh"));
    let free = number(field(&yaml, "free_thresh"));
    let origin: Vec<f64> = field(&yaml, "origin")
        .trim_matches(['[', ']'])
        .split(',')
        .map(number)
        .collect();
    let image = std::fs::read(dir.join(field(&yaml, "image"))).unwrap_or_default();
    // "P5\n<w> <h>\n255\n" then the pixels, top row first.
    let mut parts = image.splitn(4, |&b| b == b'\n');
    let magic = parts.next().unwrap_or_default();
    let size = String::from_utf8_lossy(parts.next().unwrap_or_default()).into_owned();
    let depth = parts.next().unwrap_or_default();
    let pixels = parts.next().unwrap_or_default();
    assert_eq!((magic, depth), (&b"P5"[..], &b"255"[..]));
    let mut size = size.split(' ').map(|v| number(v) as usize);
    let (width, height) = (size.next().unwrap_or(0), size.next().unwrap_or(0));
    assert_eq!(pixels.len(), width * height, "one byte a cell");
    let cells = pixels
        .chunks(width)
        .rev()
        .flatten()
        .map(|&p| {
            let occ = (255.0 - f64::from(p)) / 255.0;
            if occ > occupied {
                CellBelief::Occupied
            } else if occ < free {
                CellBelief::Free
            } else {
                CellBelief::Unknown
            }
        })
        .collect();
    Loaded {
        resolution_m: number(field(&yaml, "resolution")),
        origin: [origin[0], origin[1], origin[2]],
        width,
        height,
        cells,
    }
}

fn assert_same(loaded: &Loaded, map: &MapSnapshot) {
    assert_eq!((loaded.width, loaded.height), (map.width, map.height));
    assert!((loaded.resolution_m - map.cell_mm / 1000.0).abs() < 1e-12);
    assert!((loaded.origin[0] - map.origin_x_mm / 1000.0).abs() < 1e-12);
    assert!((loaded.origin[1] - map.origin_y_mm / 1000.0).abs() < 1e-12);
    assert_eq!(loaded.origin[2], 0.0);
    assert_eq!(
        loaded.cells, map.cells,
        "every cell reads back as the grid has it"
    );
}

/// `host-sim ARGS`, which must succeed.
fn succeed(args: &[&str]) {
    let out = host_sim(args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "host-sim {args:?}: {err}");
}

/// The final map of the seed scenario's own run in `mode`, in process.
fn seed_map(mode: PoseMode) -> MapSnapshot {
    let scenario = Scenario::load(&seed_path()).unwrap_or_else(|e| panic!("{e}"));
    match run(&scenario, mode, scenario.seed) {
        Ok(out) => out.record.map,
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn run_exports_its_final_map_as_a_map_server_pair() {
    let tmp = scratch_dir(SCRATCH);
    let dir = tmp.path().join("run");
    let seed = seed_path();
    succeed(&[
        "run",
        seed.to_str().unwrap_or_default(),
        "--pose",
        "truth",
        "--export-map",
        dir.to_str().unwrap_or_default(),
    ]);
    let loaded = load(&dir);
    assert_same(&loaded, &seed_map(PoseMode::Truth));
    // Not a blank page: the walls and the free floor are there.
    let count = |c| loaded.cells.iter().filter(|&&x| x == c).count();
    assert!(count(CellBelief::Occupied) > 100 && count(CellBelief::Free) > 1000);
}

#[test]
fn view_exports_the_robots_map_from_its_telemetry() {
    let tmp = scratch_dir(SCRATCH);
    let dir = tmp.path().join("view");
    let stream = tmp.path().join("stream.bin");
    let seed = seed_path();
    succeed(&[
        "run",
        seed.to_str().unwrap_or_default(),
        "--pose",
        "slam",
        "--telemetry",
        stream.to_str().unwrap_or_default(),
    ]);
    succeed(&[
        "view",
        stream.to_str().unwrap_or_default(),
        "--export-map",
        dir.to_str().unwrap_or_default(),
    ]);
    assert_same(&load(&dir), &seed_map(PoseMode::Slam));
}

#[test]
fn an_export_that_cannot_be_written_says_where() {
    // A file where the directory should be.
    let tmp = scratch_dir(SCRATCH);
    let blocker = tmp.path().join("blocker");
    let _ = std::fs::write(&blocker, b"not a directory");
    let seed = seed_path();
    let out = host_sim(&[
        "run",
        seed.to_str().unwrap_or_default(),
        "--export-map",
        blocker.to_str().unwrap_or_default(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("cannot create") && err.contains("blocker"),
        "{err}"
    );
}
