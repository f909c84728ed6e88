//! The live page in a real browser: headless Chromium loads it while the seed run's
//! recorded stream plays, and the screenshot's map agrees, cell for cell, with the PNG
//! map `host-sim run` draws of the same run.
//!
//! Ignored under a bare `cargo test`, as the emulator's runs are left to `cargo xtask`:
//! `cargo xtask test` installs Chromium (`scripts/install-browser.sh`) and runs it with
//! `--ignored`, and there it fails, not skips, when Chromium cannot be started. By hand:
//! `cargo test -p host-sim --release --test page_browser -- --ignored`.

mod page_support;

use host_sim::page::{MapLayout, PageServer};
use host_sim::picture::map_png;
use host_sim::record::{CellBelief, WorldOutline};
use page_support::chromium::{Chromium, Page, WINDOW};
use page_support::{play, record_seed_run};
use slam_core::Localiser;
use std::collections::BTreeSet;
use std::path::Path;
use std::time::{Duration, Instant};
use wire::telemetry::{CellChunk, FirmwareVersion, Hello, MapRows, Message, MAX_CHUNK_CELLS};

/// The PNG map's colours (`host-sim/src/picture.rs`), which the page draws cells in.
const MAT: [u8; 3] = [0xef, 0xe6, 0xd2];
const FREE: [u8; 3] = [0x9e, 0xca, 0xe1];
const OCCUPIED: [u8; 3] = [0, 0, 0];
/// The PNG map's grid edge, a line one pixel wide round the grid.
const MAT_EDGE: [u8; 3] = [0xb8, 0xab, 0x8c];
/// The page's estimated path and tags.
const ESTIMATE: [u8; 3] = [0xf0, 0x6a, 0x14];
const TAG: [u8; 3] = [0x33, 0x33, 0x33];
/// The PNG map's title band and legend band, pixels: the grid lies between them.
const PNG_TITLE_PX: u32 = 62;
const PNG_LEGEND_PX: u32 = 86;

/// Time per tick while playing: the seed route's 52 simulated seconds in about 5 s.
const PER_TICK: Duration = Duration::from_millis(10);

/// A decoded PNG.
struct Image {
    width: u32,
    height: u32,
    bytes_per_pixel: usize,
    pixels: Vec<u8>,
}

impl Image {
    fn decode(bytes: &[u8]) -> Image {
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().expect("png header");
        let mut pixels = vec![0; reader.output_buffer_size().expect("png size")];
        let info = reader.next_frame(&mut pixels).expect("png frame");
        assert_eq!(info.bit_depth, png::BitDepth::Eight, "8-bit PNG");
        pixels.truncate(info.buffer_size());
        Image {
            width: info.width,
            height: info.height,
            bytes_per_pixel: info.line_size / info.width as usize,
            pixels,
        }
    }

    fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        let i = (y as usize * self.width as usize + x as usize) * self.bytes_per_pixel;
        match self.pixels.get(i..i + 3) {
            Some(p) => [p[0], p[1], p[2]],
            None => panic!(
                "pixel ({x}, {y}) outside a {}x{} image",
                self.width, self.height
            ),
        }
    }
}

/// A cell's colour read back; `None` for anything but the three cell colours.
fn belief_of(rgb: [u8; 3]) -> Option<CellBelief> {
    match rgb {
        MAT => Some(CellBelief::Unknown),
        FREE => Some(CellBelief::Free),
        OCCUPIED => Some(CellBelief::Occupied),
        _ => None,
    }
}

/// The PNG map's grid: the box its edge line draws, pixels (left, top, right, bottom).
fn png_grid_box(img: &Image) -> (u32, u32, u32, u32) {
    let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
    for y in PNG_TITLE_PX..img.height - PNG_LEGEND_PX {
        for x in 0..img.width {
            if img.pixel(x, y) == MAT_EDGE {
                (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
            }
        }
    }
    assert!(x1 > x0 && y1 > y0, "no grid edge in the PNG map");
    (x0, y0, x1, y1)
}

/// Waits until `expression` is neither false nor null; one that throws (the page is still
/// loading) is tried again.
fn wait_for(page: &mut Page, what: &str, expression: &str, until: Duration) -> serde_json::Value {
    let deadline = Instant::now() + until;
    loop {
        let last = match page.eval(expression) {
            Ok(v) if v.as_bool() != Some(false) && !v.is_null() => return v,
            Ok(v) => v.to_string(),
            Err(e) => e,
        };
        assert!(
            Instant::now() < deadline,
            "{what}: not within {until:?} (last: {last})"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn save(dir: &Path, name: &str, bytes: &[u8]) {
    let _ = std::fs::write(dir.join(name), bytes);
}

#[test]
#[ignore = "needs Chromium: `cargo xtask test` installs it and runs this"]
fn the_page_draws_the_runs_map_in_a_real_browser() {
    let mut run = record_seed_run("browser");
    // BUGBOT_KEEP_PICTURES keeps the screenshots and the PNG to look at, as the
    // pictures' own tests do.
    run.dir
        .disable_cleanup(std::env::var_os("BUGBOT_KEEP_PICTURES").is_some());
    let final_tick = run.final_tick();
    let truth = run.truth();
    let mut server = PageServer::bind("127.0.0.1:0".parse().expect("address")).expect("bind");
    server.world(&run.output.record.world);
    let url = server.url();

    let chromium = match Chromium::launch() {
        Ok(c) => c,
        Err(e) => panic!("headless Chromium could not be started: {e}"),
    };
    let mut page = chromium.open(&url).expect("the page opens");
    // Loaded, polling, nothing to draw yet.
    wait_for(
        &mut page,
        "the page loads and polls",
        "document.readyState === 'complete' && document.body.dataset.version !== undefined",
        Duration::from_secs(20),
    );

    // Play the stream while the page watches, and note the ticks it shows meanwhile.
    let messages = run.messages.clone();
    let player = std::thread::spawn(move || {
        play(&mut server, &messages, &truth, PER_TICK);
        server
    });
    let mut seen = BTreeSet::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let tick = page.eval("document.body.dataset.tick").expect("tick");
        if let Some(t) = tick.as_str().and_then(|t| t.parse::<u32>().ok()) {
            seen.insert(t);
            if t == final_tick && player.is_finished() {
                break;
            }
        }
        assert!(
            Instant::now() < deadline,
            "the page never showed tick {final_tick}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let server = player.join().expect("the player ends");
    let live: Vec<_> = seen.iter().filter(|&&t| t < final_tick).collect();
    assert!(
        live.len() >= 3,
        "the page showed only ticks {seen:?} while the stream played"
    );
    // Once more after the stream's final map, so the page holds the last state.
    let version = server.state_json();
    let version: serde_json::Value = serde_json::from_str(&version).expect("state");
    wait_for(
        &mut page,
        "the page draws the final state",
        &format!("document.body.dataset.version === '{}'", version["version"]),
        Duration::from_secs(10),
    );
    page.settle().expect("painted");

    let progress = page
        .eval("document.getElementById('progress').textContent")
        .expect("progress");
    let progress = progress.as_str().unwrap_or_default();
    assert!(
        progress.contains(&format!("tick {final_tick}")) && progress.contains("stale inputs"),
        "{progress}"
    );

    // The map canvas is where the layout says.
    let map = &run.output.record.map;
    let layout = MapLayout::for_grid(map.width as u16, map.height as u16);
    let rect = page
        .eval("(r => [r.left, r.top, r.width, r.height])(document.getElementById('map').getBoundingClientRect())")
        .expect("canvas rect");
    let rect: Vec<f64> = rect
        .as_array()
        .map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
        .unwrap_or_default();
    let want = [
        layout.left_px,
        layout.top_px,
        layout.columns * layout.cell_px,
        layout.rows * layout.cell_px,
    ]
    .map(f64::from);
    assert_eq!(rect, want, "the map canvas is not where the layout puts it");

    // With the paths and tags: the estimate ends at its pose, the tags are drawn.
    let full_png = page.screenshot().expect("screenshot");
    save(run.dir.path(), "page.png", &full_png);
    let full = Image::decode(&full_png);
    assert_eq!((full.width, full.height), WINDOW, "screenshot size");
    let grid = run.output.record.map.clone();
    let to_px = |(x, y): (f64, f64)| {
        let cp = f64::from(layout.cell_px);
        (
            (f64::from(layout.left_px) + (x - grid.origin_x_mm) / grid.cell_mm * cp).round() as u32,
            (f64::from(layout.top_px) + f64::from(layout.rows) * cp
                - (y - grid.origin_y_mm) / grid.cell_mm * cp)
                .round() as u32,
        )
    };
    let last = run.output.record.ticks.last().expect("ticks");
    let (ex, ey) = to_px(last.estimate_mm);
    let near = |img: &Image, (x, y): (u32, u32), rgb: [u8; 3]| {
        (x - 1..=x + 1).any(|x| (y - 1..=y + 1).any(|y| img.pixel(x, y) == rgb))
    };
    assert!(
        near(&full, (ex, ey), ESTIMATE),
        "no estimate at its final pose"
    );
    for (id, centre) in &run.output.record.world.tags {
        assert!(near(&full, to_px(*centre), TAG), "tag {id} not drawn");
    }

    // The map alone (the page's own switch hides the paths, tags and walls).
    page.eval("document.getElementById('show-overlay').click()")
        .expect("switch");
    page.settle().expect("painted");
    let shot_png = page.screenshot().expect("screenshot");
    save(run.dir.path(), "page-map.png", &shot_png);
    let shot = Image::decode(&shot_png);

    // The PNG map of the same run, its cells alone (no paths, walls or tags over them).
    let mut cells_only = run.output.record.clone();
    cells_only.ticks.clear();
    cells_only.world = WorldOutline::default();
    let png_path = run.dir.path().join("run-map.png");
    map_png(&cells_only, &png_path).expect("PNG map");
    let reference = Image::decode(&std::fs::read(&png_path).expect("PNG map read"));
    let (x0, y0, x1, y1) = png_grid_box(&reference);
    let (w, h) = (map.width as u32, map.height as u32);

    let mut disagreements = Vec::new();
    let mut counts = [0usize; 3];
    for row in 0..h {
        for col in 0..w {
            let (px, py) = layout.cell_centre_px(col, row);
            let on_page = belief_of(shot.pixel(px, py));
            let rx = f64::from(x0) + (f64::from(col) + 0.5) * f64::from(x1 - x0) / f64::from(w);
            let ry = f64::from(y1) - (f64::from(row) + 0.5) * f64::from(y1 - y0) / f64::from(h);
            let in_png = belief_of(reference.pixel(rx as u32, ry as u32));
            let in_run = map.cells.get((row * w + col) as usize).copied();
            if on_page != in_png || in_png != in_run {
                disagreements.push((col, row, on_page, in_png, in_run));
            }
            if let Some(b) = in_run {
                counts[b as usize] += 1;
            }
        }
    }
    eprintln!(
        "page vs PNG map: {} cells ({} unknown, {} free, {} occupied), {} disagree; screenshots in {}",
        w * h,
        counts[0],
        counts[1],
        counts[2],
        disagreements.len(),
        run.dir.path().display()
    );
    assert!(
        counts[1] > 100 && counts[2] > 50,
        "too few known cells to compare: {counts:?}"
    );
    // Every cell must agree: both draw each cell as a filled square many pixels across
    // (the page a whole number of them), only each centre is sampled, and the paths,
    // walls and tags are off in both, so no edge or antialiasing is ever read.
    assert!(
        disagreements.is_empty(),
        "cells that disagree (column, row, page, PNG, run): {disagreements:?}"
    );
}

/// The belief a synthetic map gives cell `column`, `row`: a pattern that tells rows,
/// columns and their directions apart.
fn pattern(column: u32, row: u32) -> CellBelief {
    match (column * 7 + row * 13 + column * row) % 5 {
        0 | 1 => CellBelief::Free,
        2 => CellBelief::Occupied,
        _ => CellBelief::Unknown,
    }
}

#[test]
#[ignore = "needs Chromium: `cargo xtask test` installs it and runs this"]
fn the_largest_shipped_grid_is_drawn_cell_for_cell() {
    // The 206 x 206 grid of room-10m and the other large scenarios: 3 pixels a cell.
    let (w, h) = (206u32, 206u32);
    let mut server = PageServer::bind("127.0.0.1:0".parse().expect("address")).expect("bind");
    let hello = Hello {
        width: w as u16,
        height: h as u16,
        cell_mm: 50,
        origin_x_mm: -150,
        origin_y_mm: -150,
        free_below: 16,
        occupied_above: 16,
        firmware: FirmwareVersion::default(),
        localiser: Localiser::Filter,
        matching: false,
        boot: Default::default(),
    };
    server.push(&Message::Hello(hello));
    let cells: Vec<i8> = (0..h)
        .flat_map(|row| (0..w).map(move |col| (col, row)))
        .map(|(col, row)| match pattern(col, row) {
            CellBelief::Free => -100,
            CellBelief::Occupied => 100,
            CellBelief::Unknown => 0,
        })
        .collect();
    for (i, chunk) in cells.chunks(MAX_CHUNK_CELLS).enumerate() {
        let start = (i * MAX_CHUNK_CELLS) as u32;
        let mut run = CellChunk::new();
        chunk.iter().for_each(|&c| {
            let _ = run.push(c);
        });
        server.push(&Message::MapRows(MapRows {
            first_row: (start / w) as u16,
            first_column: (start % w) as u16,
            cells: run,
        }));
    }
    let version: serde_json::Value = serde_json::from_str(&server.state_json()).expect("state");

    let chromium = match Chromium::launch() {
        Ok(c) => c,
        Err(e) => panic!("headless Chromium could not be started: {e}"),
    };
    let mut page = chromium.open(&server.url()).expect("the page opens");
    wait_for(
        &mut page,
        "the page draws the map",
        &format!("document.body.dataset.version === '{}'", version["version"]),
        Duration::from_secs(20),
    );
    page.eval("document.getElementById('show-overlay').click()")
        .expect("switch");
    page.settle().expect("painted");
    let shot = Image::decode(&page.screenshot().expect("screenshot"));
    let layout = MapLayout::for_grid(w as u16, h as u16);
    assert_eq!(layout.cell_px, 3);
    let wrong: Vec<_> = (0..h)
        .flat_map(|row| (0..w).map(move |col| (col, row)))
        .filter_map(|(col, row)| {
            let (x, y) = layout.cell_centre_px(col, row);
            let drawn = belief_of(shot.pixel(x, y));
            (drawn != Some(pattern(col, row))).then_some((col, row, drawn))
        })
        .collect();
    assert!(
        wrong.is_empty(),
        "{} of {} cells drawn wrong, the first: {:?}",
        wrong.len(),
        w * h,
        &wrong[..wrong.len().min(10)]
    );
}
