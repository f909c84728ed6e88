use super::map::draw_map;
use super::*;
use crate::record::{Belief, CellBelief, MapSnapshot, TickRecord, TrueCalibration, WorldOutline};
use std::fs::File;
use tempfile::TempDir;

const N: usize = 46;
const CELL: f64 = 50.0;

/// A directory for a test's pictures, removed when the test ends, passed or failed,
/// unless `BUGBOT_KEEP_PICTURES` is set (to look at them).
fn temp_dir(name: &str) -> TempDir {
    let keep = std::env::var_os("BUGBOT_KEEP_PICTURES").is_some();
    let dir = tempfile::Builder::new()
        .prefix(&format!("bugbot-picture-{name}-"))
        .disable_cleanup(keep)
        .tempdir()
        .expect("temp dir");
    if keep {
        eprintln!("pictures kept in {}", dir.path().display());
    }
    dir
}

/// A 46×46 map with a square ring of occupied cells (columns and rows 2 and 43), a
/// 5×5 patch of free cells, one out-of-place occupied cell, walls along the ring's
/// outer edge, two tags and 100 ticks around a circle.
fn synthetic() -> RunRecord {
    let mut cells = vec![CellBelief::Unknown; N * N];
    let mut out_of_place = vec![false; N * N];
    for i in 2..=43 {
        for (c, r) in [(i, 2), (i, 43), (2, i), (43, i)] {
            cells[r * N + c] = CellBelief::Occupied;
        }
    }
    for r in 5..10 {
        for c in 5..10 {
            cells[r * N + c] = CellBelief::Free;
        }
    }
    cells[30 * N + 20] = CellBelief::Occupied;
    out_of_place[30 * N + 20] = true;
    let ticks = (0..100)
        .map(|i| {
            let t = i as f64 * 0.1;
            let a = t * 0.6;
            let truth = (1150.0 + 400.0 * a.cos(), 1150.0 + 400.0 * a.sin());
            let drift = 3.0 * t;
            TickRecord {
                t_s: t,
                truth_mm: truth,
                truth_heading_deg: a.to_degrees(),
                estimate_mm: (truth.0 + drift, truth.1 - drift * 0.5),
                estimate_heading_deg: a.to_degrees() + 0.3 * t,
                known_pct: 100.0 * (1.0 - (-t / 3.0).exp()),
                error_cm: drift * 1.118 / 10.0,
                heading_error_deg: 0.3 * t * if i % 2 == 0 { 1.0 } else { -1.0 },
                out_of_place_pct: if t > 2.0 { 100.0 / 168.0 } else { 0.0 },
                fix_taken: i % 17 == 0,
                belief: None,
                true_gyro_bias_mdps: f64::NAN,
            }
        })
        .collect();
    RunRecord {
        scenario: "square-room".into(),
        pose_mode: "tags".into(),
        true_calibration: None,
        ticks,
        map: MapSnapshot {
            width: N,
            height: N,
            cell_mm: CELL,
            origin_x_mm: 0.0,
            origin_y_mm: 0.0,
            cells,
            out_of_place,
        },
        world: WorldOutline {
            walls: vec![
                ((100.0, 100.0), (2200.0, 100.0)),
                ((2200.0, 100.0), (2200.0, 2200.0)),
                ((2200.0, 2200.0), (100.0, 2200.0)),
                ((100.0, 2200.0), (100.0, 100.0)),
            ],
            tags: vec![(11, (1150.0, 160.0)), (12, (2140.0, 1150.0))],
        },
    }
}

fn cell_center(col: usize, row: usize) -> (f64, f64) {
    ((col as f64 + 0.5) * CELL, (row as f64 + 0.5) * CELL)
}

/// Decodes an RGB(A) PNG: width, height, bytes per pixel and the pixels.
fn decode(path: &Path) -> (u32, u32, usize, Vec<u8>) {
    let file = std::io::BufReader::new(File::open(path).expect("open png"));
    let mut reader = png::Decoder::new(file).read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut buf).expect("png frame");
    let bpp = info.line_size / info.width as usize;
    buf.truncate(info.buffer_size());
    (info.width, info.height, bpp, buf)
}

fn pixel(img: &(u32, u32, usize, Vec<u8>), (x, y): (i32, i32)) -> [u8; 3] {
    let (w, _, bpp, buf) = img;
    let i = (y as usize * *w as usize + x as usize) * bpp;
    [buf[i], buf[i + 1], buf[i + 2]]
}

#[test]
fn pictures_of_a_synthetic_run() {
    let record = synthetic();
    let tmp = temp_dir("synthetic");
    let dir = tmp.path();
    let map = dir.join("map.png");
    let chart = dir.join("chart.png");
    let geometry = draw_map(&record, &map).expect("map");
    chart_png(&record, &chart).expect("chart");
    assert!(map.is_file() && chart.is_file());

    let img = decode(&map);
    assert_eq!((img.0, img.1), MAP_SIZE);
    // An occupied cell on the ring, away from tags, walls and paths.
    assert_eq!(pixel(&img, geometry.to_px(cell_center(10, 2))), [0, 0, 0]);
    assert_eq!(pixel(&img, geometry.to_px(cell_center(43, 30))), [0, 0, 0]);
    // A free cell.
    assert_eq!(
        pixel(&img, geometry.to_px(cell_center(7, 7))),
        [0x9e, 0xca, 0xe1]
    );
    // An unknown cell shows the mat.
    assert_eq!(
        pixel(&img, geometry.to_px(cell_center(12, 38))),
        [0xef, 0xe6, 0xd2]
    );
    // The out-of-place cell has red in it.
    let (x0, y1) = geometry.to_px((20.0 * CELL, 30.0 * CELL));
    let (x1, y0) = geometry.to_px((21.0 * CELL, 31.0 * CELL));
    let red = (x0..=x1)
        .flat_map(|x| (y0..=y1).map(move |y| (x, y)))
        .any(|p| pixel(&img, p) == [0xe3, 0x1a, 0x1c]);
    assert!(red, "out-of-place cell not outlined in red");

    let img = decode(&chart);
    assert_eq!((img.0, img.1), CHART_SIZE);
}

#[test]
fn a_filter_run_draws_its_bounds_ellipses_and_calibration() {
    let mut record = synthetic();
    record.pose_mode = "slam".into();
    record.true_calibration = Some(TrueCalibration {
        gyro_scale_ppm: -7444.0,
        gyro_bias_mdps: 20.0,
        flow_scale_ppm: 41_667.0,
    });
    for (i, t) in record.ticks.iter_mut().enumerate() {
        let learned = 1.0 - (-(i as f64) / 20.0).exp();
        t.belief = Some(Belief {
            // A 3-sigma ellipse of 90 mm by 60 mm: seen unmagnified, not faint.
            xx_mm2: 900.0,
            xy_mm2: 0.0,
            yy_mm2: 400.0,
            hh_deg2: 0.04,
            gyro_scale_ppm: -7444.0 * learned,
            gyro_bias_mdps: 20.0 * learned,
            flow_scale_ppm: 41_667.0 * learned,
            tags: slam_core::TagCounters::default().into(),
        });
    }
    let tmp = temp_dir("filter");
    let dir = tmp.path();
    let (map, chart) = (dir.join("map.png"), dir.join("chart.png"));
    let geometry = draw_map(&record, &map).expect("map");
    chart_png(&record, &chart).expect("chart");
    assert_eq!(decode(&chart).0, FILTER_CHART_SIZE.0);
    assert_eq!(decode(&chart).1, FILTER_CHART_SIZE.1);
    // The first tick's ellipse: its right-hand end is 90 mm east of the estimate.
    let img = decode(&map);
    let t0 = &record.ticks[0];
    let (x, y) = geometry.to_px((t0.estimate_mm.0 + 90.0, t0.estimate_mm.1));
    let purple = (x - 2..=x + 2)
        .flat_map(|x| (y - 2..=y + 2).map(move |y| (x, y)))
        .any(|p| {
            let [r, g, b] = pixel(&img, p);
            b > g && r > g && g < 0x80
        });
    assert!(purple, "no ellipse where the first should be");
    // Without beliefs: no ellipse, the plain chart.
    record.ticks.iter_mut().for_each(|t| t.belief = None);
    chart_png(&record, &chart).expect("chart");
    assert_eq!(decode(&chart).1, CHART_SIZE.1);
}

#[test]
fn a_grid_larger_than_its_world_is_framed_to_the_world() {
    let tmp = temp_dir("framed");
    let dir = tmp.path();
    let mut record = synthetic();
    const BIG: usize = 206;
    record.map.width = BIG;
    record.map.height = BIG;
    record.map.origin_x_mm = -3000.0;
    record.map.origin_y_mm = -3000.0;
    record.map.cells = vec![CellBelief::Free; BIG * BIG];
    record.map.out_of_place = vec![false; BIG * BIG];
    // The walls span 100-2200 mm: a small margin round them, not the grid's 10 m.
    let g = draw_map(&record, &dir.join("world.png")).expect("map");
    assert!(g.x.start > -500.0 && g.x.end < 3000.0, "{:?}", g.x);
    assert!(g.y.start > -500.0 && g.y.end < 3000.0, "{:?}", g.y);
    // With no world known (a robot's stream), the grid is the frame.
    record.world = WorldOutline::default();
    let g = draw_map(&record, &dir.join("grid.png")).expect("map");
    assert!(g.x.start <= -3000.0 && g.x.end >= 7300.0, "{:?}", g.x);
}

#[test]
fn pictures_of_an_empty_run() {
    let mut record = synthetic();
    record.ticks.clear();
    record.map.cells = vec![CellBelief::Unknown; N * N];
    record.map.out_of_place.clear();
    let tmp = temp_dir("empty");
    let dir = tmp.path();
    map_png(&record, &dir.join("map.png")).expect("map");
    chart_png(&record, &dir.join("chart.png")).expect("chart");
    assert!(dir.join("map.png").is_file() && dir.join("chart.png").is_file());

    // Nothing at all: no map, no world, no ticks, no names.
    let bare = RunRecord {
        scenario: String::new(),
        pose_mode: String::new(),
        true_calibration: None,
        ticks: Vec::new(),
        map: MapSnapshot {
            width: 0,
            height: 0,
            cell_mm: 0.0,
            origin_x_mm: 0.0,
            origin_y_mm: 0.0,
            cells: Vec::new(),
            out_of_place: Vec::new(),
        },
        world: WorldOutline::default(),
    };
    map_png(&bare, &dir.join("bare-map.png")).expect("bare map");
    chart_png(&bare, &dir.join("bare-chart.png")).expect("bare chart");
    assert_eq!(decode(&dir.join("bare-map.png")).0, MAP_SIZE.0);
}

#[test]
fn extreme_values_do_not_panic() {
    let mut record = synthetic();
    record.ticks[3].truth_mm = (1e12, -1e15);
    record.ticks[4].estimate_mm = (f64::INFINITY, 0.0);
    record.ticks[5].error_cm = 1e300;
    record.ticks[6].t_s = -1e20;
    record.ticks[7].known_pct = f64::NAN;
    record.ticks[8].heading_error_deg = -1e9;
    for t in &mut record.ticks {
        t.fix_taken = true;
    }
    // Cells fewer than width × height, and a mask longer than the cells.
    record.map.cells.truncate(100);
    record.map.out_of_place = vec![true; 5000];
    let tmp = temp_dir("extreme");
    let dir = tmp.path();
    map_png(&record, &dir.join("map.png")).expect("map");
    chart_png(&record, &dir.join("chart.png")).expect("chart");

    // One tick only, all at the same spot.
    record.ticks.truncate(1);
    record.map.cell_mm = -5.0;
    map_png(&record, &dir.join("one-map.png")).expect("one map");
    chart_png(&record, &dir.join("one-chart.png")).expect("one chart");
}

#[test]
fn unwritable_path_is_an_error() {
    let record = synthetic();
    let tmp = temp_dir("missing");
    let dir = tmp.path();
    let path = dir.join("no-such-dir").join("map.png");
    let err = map_png(&record, &path).expect_err("should fail");
    assert!(matches!(err, PictureError::Io(_)), "{err}");
    assert!(err.to_string().contains("writing"));
}
