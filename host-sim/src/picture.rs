//! The two pictures a run leaves behind: the overhead map and the chart over time.
//!
//! Both are drawn from a [`RunRecord`] alone with `plotters` into an RGB buffer, which
//! the `png` crate then writes out. The labels use DejaVu Sans, shipped in
//! `host-sim/assets/` (licence beside it) and compiled in, so no system font library is
//! needed.
//!
//! The map follows the usual occupancy-grid colours: the mat's beige for unknown cells,
//! light blue for free, black for occupied, with occupied cells that lie on no real wall
//! or tag outlined in red; the true walls and tags, the true path (green) and the
//! estimated path (orange) are drawn over it. A run with the filter adds its 3-sigma
//! position ellipse along the estimated path every second, and the chart its bounds and
//! the calibration it learned.

use std::fmt;
use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::drawing::DrawingAreaErrorKind;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

use crate::record::{Belief, CellBelief, RunRecord, TickRecord, TrueCalibration};

/// The font every label uses, compiled in.
const FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// The family name it is registered under (plotters' own default, so every text works).
const FONT: &str = "sans-serif";

/// Size of the map picture, pixels.
const MAP_SIZE: (u32, u32) = (760, 800);
/// Size of the chart picture, pixels.
const CHART_SIZE: (u32, u32) = (800, 820);
/// The chart of a run with the filter: three calibration panels more.
const FILTER_CHART_SIZE: (u32, u32) = (800, 1280);

/// Coordinates beyond this (in millimetres, seconds or chart units) are clamped, so that
/// extreme values still give a picture.
const LIMIT: f64 = 1e9;

const WHITE_BG: RGBColor = RGBColor(255, 255, 255);
/// The mat, and so every unknown cell.
const MAT: RGBColor = RGBColor(0xef, 0xe6, 0xd2);
const MAT_EDGE: RGBColor = RGBColor(0xb8, 0xab, 0x8c);
const FREE: RGBColor = RGBColor(0x9e, 0xca, 0xe1);
const OCCUPIED: RGBColor = RGBColor(0, 0, 0);
const OUT_OF_PLACE: RGBColor = RGBColor(0xe3, 0x1a, 0x1c);
const WALL: RGBColor = RGBColor(0x6b, 0x8e, 0x6b);
const TAG_EDGE: RGBColor = RGBColor(0x33, 0x33, 0x33);
const TRUE_PATH: RGBColor = RGBColor(0x1a, 0x98, 0x50);
const EST_PATH: RGBColor = RGBColor(0xf0, 0x6a, 0x14);
const TEXT: RGBColor = RGBColor(0x22, 0x22, 0x22);
const MUTED: RGBColor = RGBColor(0x66, 0x66, 0x66);
const GRID_LINE: RGBColor = RGBColor(0xdd, 0xdd, 0xdd);
const FIX_MARK: RGBColor = RGBColor(0x75, 0x4f, 0xb8);
const KNOWN_LINE: RGBColor = RGBColor(0x21, 0x66, 0xac);
const HEADING_LINE: RGBColor = RGBColor(0x8c, 0x51, 0x0a);
const ELLIPSE: RGBColor = RGBColor(0x6a, 0x3d, 0x9a);
const CALIBRATION_LINE: RGBColor = RGBColor(0x1b, 0x9e, 0x77);
const TRUTH_DASH: RGBColor = RGBColor(0x44, 0x44, 0x44);
/// The shade under an error line, up to the filter's 3-sigma bound.
const BOUND_BAND: RGBColor = RGBColor(0xfd, 0xd0, 0xa2);

/// Why a picture could not be made.
#[derive(Debug)]
pub enum PictureError {
    /// The drawing backend failed (plotters' error, boxed).
    Drawing(Box<dyn std::error::Error + Send + Sync + 'static>),
    /// The PNG encoder failed.
    Encode(png::EncodingError),
    /// Creating or writing the file failed.
    Io(std::io::Error),
    /// The compiled-in font could not be read.
    Font,
}

impl fmt::Display for PictureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PictureError::Drawing(e) => write!(f, "drawing the picture failed: {e}"),
            PictureError::Encode(e) => write!(f, "encoding the PNG failed: {e}"),
            PictureError::Io(e) => write!(f, "writing the picture failed: {e}"),
            PictureError::Font => write!(f, "the built-in font could not be loaded"),
        }
    }
}

impl std::error::Error for PictureError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PictureError::Drawing(e) => Some(e.as_ref()),
            PictureError::Encode(e) => Some(e),
            PictureError::Io(e) => Some(e),
            PictureError::Font => None,
        }
    }
}

impl<E: std::error::Error + Send + Sync + 'static> From<DrawingAreaErrorKind<E>> for PictureError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        PictureError::Drawing(Box::new(e))
    }
}

impl From<std::io::Error> for PictureError {
    fn from(e: std::io::Error) -> Self {
        PictureError::Io(e)
    }
}

impl From<png::EncodingError> for PictureError {
    fn from(e: png::EncodingError) -> Self {
        PictureError::Encode(e)
    }
}

/// Registers the compiled-in font once per process.
fn ensure_font() -> Result<(), PictureError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok()
            && register_font(FONT, FontStyle::Bold, FONT_BYTES).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(PictureError::Font)
    }
}

fn font(size: f64, color: RGBColor) -> TextStyle<'static> {
    TextStyle {
        font: (FONT, size).into_font(),
        color: color.to_backend_color(),
        pos: Pos::new(HPos::Left, VPos::Top),
    }
}

/// Draws into an RGB buffer of `size` with `draw`, then writes it to `path` as a PNG.
fn render<T>(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<T, PictureError>,
) -> Result<T, PictureError> {
    ensure_font()?;
    let mut buf = vec![255u8; size.0 as usize * size.1 as usize * 3];
    let out = {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE_BG)?;
        let out = draw(&root)?;
        root.present()?;
        out
    };
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, size.0, size.1);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::High);
        let mut writer = encoder.write_header()?;
        writer.write_image_data(&buf)?;
        writer.finish()?;
    }
    std::fs::write(path, bytes)?;
    Ok(out)
}

/// A value made safe to draw: clamped to ±[`LIMIT`], `None` when not a number.
fn tame(v: f64) -> Option<f64> {
    if v.is_nan() {
        None
    } else {
        Some(v.clamp(-LIMIT, LIMIT))
    }
}

fn tame_point((x, y): (f64, f64)) -> Option<(f64, f64)> {
    Some((tame(x)?, tame(y)?))
}

/// The title line shared by both pictures.
fn title_text(what: &str, record: &RunRecord) -> String {
    let scenario = if record.scenario.is_empty() {
        "(unnamed)"
    } else {
        record.scenario.as_str()
    };
    let pose = if record.pose_mode.is_empty() {
        "?"
    } else {
        record.pose_mode.as_str()
    };
    format!("{what} — scenario: {scenario} · pose: {pose}")
}

/// Where the map picture put the map: data ranges and the plotting area's pixels.
#[derive(Clone, Debug)]
#[cfg_attr(not(test), allow(dead_code))]
struct MapGeometry {
    x: Range<f64>,
    y: Range<f64>,
    px_x: Range<i32>,
    px_y: Range<i32>,
}

impl MapGeometry {
    /// The pixel a map point (millimetres) lands on.
    #[cfg(test)]
    fn to_px(&self, (x, y): (f64, f64)) -> (i32, i32) {
        let fx = (x - self.x.start) / (self.x.end - self.x.start);
        let fy = (y - self.y.start) / (self.y.end - self.y.start);
        let w = f64::from(self.px_x.end - self.px_x.start);
        let h = f64::from(self.px_y.end - self.px_y.start);
        (
            self.px_x.start + (fx * w).round() as i32,
            self.px_y.end - (fy * h).round() as i32,
        )
    }
}

/// The grid's extent in millimetres, if it is drawable.
fn grid_extent(record: &RunRecord) -> Option<(f64, f64, f64, f64, f64)> {
    let m = &record.map;
    let cell = tame(m.cell_mm)?;
    let (ox, oy) = tame_point((m.origin_x_mm, m.origin_y_mm))?;
    if m.width == 0 || m.height == 0 || cell <= 0.0 || m.cells.is_empty() {
        return None;
    }
    let x1 = tame(ox + cell * m.width as f64)?;
    let y1 = tame(oy + cell * m.height as f64)?;
    Some((ox, oy, x1, y1, cell))
}

/// Everything that should be in view: the world (walls and tags) and both paths, or the
/// grid when the world is not known. A grid larger than its world is cut to it.
fn map_extent(record: &RunRecord) -> (Range<f64>, Range<f64>) {
    let mut pts: Vec<(f64, f64)> = Vec::new();
    if record.world.walls.is_empty() {
        if let Some((x0, y0, x1, y1, _)) = grid_extent(record) {
            pts.push((x0, y0));
            pts.push((x1, y1));
        }
    }
    for (a, b) in &record.world.walls {
        pts.extend(tame_point(*a));
        pts.extend(tame_point(*b));
    }
    pts.extend(record.world.tags.iter().filter_map(|(_, c)| tame_point(*c)));
    for t in &record.ticks {
        pts.extend(tame_point(t.truth_mm));
        pts.extend(tame_point(t.estimate_mm));
    }
    if pts.is_empty() {
        return (0.0..1000.0, 0.0..1000.0);
    }
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    (x0..x1, y0..y1)
}

/// Pads the extent by a margin and widens one side so a millimetre is as many pixels
/// across as up.
fn fit_aspect(x: Range<f64>, y: Range<f64>, px_w: f64, px_h: f64) -> (Range<f64>, Range<f64>) {
    let span = (x.end - x.start).max(y.end - y.start).max(100.0);
    let pad = span * 0.04;
    let (mut x0, mut x1) = (x.start - pad, x.end + pad);
    let (mut y0, mut y1) = (y.start - pad, y.end + pad);
    let (w, h) = ((x1 - x0).max(1.0), (y1 - y0).max(1.0));
    let (px_w, px_h) = (px_w.max(1.0), px_h.max(1.0));
    // millimetres per pixel, the larger of the two directions
    let scale = (w / px_w).max(h / px_h);
    let (want_w, want_h) = (scale * px_w, scale * px_h);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    x0 = cx - want_w / 2.0;
    x1 = cx + want_w / 2.0;
    y0 = cy - want_h / 2.0;
    y1 = cy + want_h / 2.0;
    (x0..x1, y0..y1)
}

/// Draws the overhead map of `record` to `path` as a PNG.
///
/// Unknown cells in the mat's beige, free cells light blue, occupied cells black (red
/// outline when out of place); the true walls and tags over them; the true path in
/// green and the estimated path in orange; a legend beneath.
pub fn map_png(record: &RunRecord, path: &Path) -> Result<(), PictureError> {
    draw_map(record, path).map(|_| ())
}

fn draw_map(record: &RunRecord, path: &Path) -> Result<MapGeometry, PictureError> {
    render(path, MAP_SIZE, |root| {
        let (top, rest) = root.split_vertically(62);
        let (body, legend) = rest.split_vertically(MAP_SIZE.1 - 62 - 86);
        draw_title(&top, &title_text("Map", record), &map_subtitle(record))?;
        let geometry = draw_map_body(record, &body)?;
        let mm_per_px = (geometry.x.end - geometry.x.start)
            / f64::from((geometry.px_x.end - geometry.px_x.start).max(1));
        draw_map_legend(&legend, ellipse_scale(record, mm_per_px))?;
        Ok(geometry)
    })
}

/// The ticks that get an ellipse: the first with a belief in each whole second, with its
/// estimated position.
fn ellipse_ticks(record: &RunRecord) -> impl Iterator<Item = ((f64, f64), Belief)> + '_ {
    let mut last_second = None;
    record.ticks.iter().filter_map(move |t| {
        let belief = t.belief?;
        let centre = tame_point(t.estimate_mm)?;
        let second = tame(t.t_s)?.floor() as i64;
        if last_second == Some(second) {
            return None;
        }
        last_second = Some(second);
        Some((centre, belief))
    })
}

/// Ellipses drawn wider than this across the map (the first seconds, before any tag) are
/// drawn faint, so that they do not hide the path, pixels of semi-major axis.
const ELLIPSE_FAINT_PX: f64 = 40.0;

/// How much the ellipses are magnified: the smallest of 1, 2, 5, 10, ... that draws the
/// median one at least a few pixels across. `None` without ellipses.
fn ellipse_scale(record: &RunRecord, mm_per_px: f64) -> Option<f64> {
    let mut majors: Vec<f64> = ellipse_ticks(record)
        .map(|(_, b)| 3.0 * b.position_axes().0.sqrt() / mm_per_px.max(1e-9))
        .filter(|a| a.is_finite())
        .collect();
    if majors.is_empty() {
        return None;
    }
    majors.sort_by(|a, b| a.total_cmp(b));
    let median_px = majors[majors.len() / 2];
    let scale = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]
        .into_iter()
        .find(|k| median_px * k >= 5.0)
        .unwrap_or(1000.0);
    Some(scale)
}

/// The outline of `belief`'s 3-sigma position ellipse round `centre`, magnified `scale`
/// times, millimetres.
fn ellipse_points(centre: (f64, f64), belief: &Belief, scale: f64) -> Vec<(f64, f64)> {
    let (big, small, angle) = belief.position_axes();
    let (a, b) = (3.0 * big.sqrt() * scale, 3.0 * small.sqrt() * scale);
    let (sin, cos) = angle.sin_cos();
    (0..=36)
        .filter_map(|i| {
            let th = f64::from(i) * std::f64::consts::TAU / 36.0;
            let (u, v) = (a * th.cos(), b * th.sin());
            tame_point((centre.0 + u * cos - v * sin, centre.1 + u * sin + v * cos))
        })
        .collect()
}

fn map_subtitle(record: &RunRecord) -> String {
    let m = &record.map;
    let cells = if grid_extent(record).is_some() {
        format!("{}×{} cells of {:.0} mm", m.width, m.height, m.cell_mm)
    } else {
        "no map".to_string()
    };
    match record.ticks.last() {
        Some(t) => format!(
            "{cells} · after {:.1} s: known {:.0}%, error {:.1} cm, heading error {:.1}°, out of place {:.1}%",
            t.t_s, t.known_pct, t.error_cm, t.heading_error_deg, t.out_of_place_pct
        ),
        None => format!("{cells} · no ticks recorded"),
    }
}

fn draw_title<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    subtitle: &str,
) -> Result<(), PictureError>
where
    DB::ErrorType: 'static,
{
    let (w, _) = area.dim_in_pixel();
    let center = Pos::new(HPos::Center, VPos::Top);
    area.draw(&Text::new(
        title.to_string(),
        (w as i32 / 2, 12),
        font(22.0, TEXT).pos(center),
    ))?;
    area.draw(&Text::new(
        subtitle.to_string(),
        (w as i32 / 2, 40),
        font(14.0, MUTED).pos(center),
    ))?;
    Ok(())
}

fn draw_map_body<DB: DrawingBackend>(
    record: &RunRecord,
    area: &DrawingArea<DB, Shift>,
) -> Result<MapGeometry, PictureError>
where
    DB::ErrorType: 'static,
{
    let (ex, ey) = map_extent(record);
    let build = |x: Range<f64>, y: Range<f64>| {
        ChartBuilder::on(area)
            .margin_left(8)
            .margin_right(24)
            .margin_top(6)
            .margin_bottom(4)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(x, y)
    };
    // Build once to learn the plotting area's size, then again with matching ranges.
    let probe = build(ex.clone(), ey.clone())?;
    let (px_x, px_y) = probe.plotting_area().get_pixel_range();
    drop(probe);
    let (rx, ry) = fit_aspect(
        ex,
        ey,
        f64::from(px_x.end - px_x.start),
        f64::from(px_y.end - px_y.start),
    );
    let mut chart = build(rx.clone(), ry.clone())?;
    chart.plotting_area().fill(&MAT)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x (mm)")
        .y_desc("y (mm)")
        .x_labels(8)
        .y_labels(8)
        .label_style(font(12.0, TEXT))
        .axis_desc_style(font(14.0, TEXT))
        .x_label_formatter(&|v| format!("{v:.0}"))
        .y_label_formatter(&|v| format!("{v:.0}"))
        .draw()?;

    let plot = chart.plotting_area();
    let (ppx_x, ppx_y) = plot.get_pixel_range();
    let mm_per_px = (rx.end - rx.start) / f64::from((ppx_x.end - ppx_x.start).max(1));

    if let Some((x0, y0, x1, y1, cell)) = grid_extent(record) {
        let m = &record.map;
        let count = m.cells.len().min(m.width.saturating_mul(m.height));
        // A rectangle per run of equal cells along a row.
        for row in 0..m.height {
            let start = row * m.width;
            if start >= count {
                break;
            }
            let end = (start + m.width).min(count);
            let cy0 = y0 + cell * row as f64;
            let mut col = 0;
            while start + col < end {
                let belief = m.cells[start + col];
                let mut run = 1;
                while start + col + run < end && m.cells[start + col + run] == belief {
                    run += 1;
                }
                let color = match belief {
                    CellBelief::Unknown => None,
                    CellBelief::Free => Some(FREE),
                    CellBelief::Occupied => Some(OCCUPIED),
                };
                if let Some(color) = color {
                    let cx0 = x0 + cell * col as f64;
                    plot.draw(&Rectangle::new(
                        [(cx0, cy0 + cell), (cx0 + cell * run as f64, cy0)],
                        color.filled(),
                    ))?;
                }
                col += run;
            }
        }
        // Out-of-place occupied cells: a red outline (wholly red once cells get small).
        let cell_px = cell / mm_per_px;
        let stroke = ((cell_px / 5.0).round() as u32).clamp(1, 3);
        let n = count.min(m.out_of_place.len());
        for i in (0..n).filter(|&i| m.out_of_place[i] && m.cells[i] == CellBelief::Occupied) {
            let (col, row) = ((i % m.width) as f64, (i / m.width) as f64);
            let (cx0, cy0) = (x0 + cell * col, y0 + cell * row);
            let corners = [(cx0, cy0 + cell), (cx0 + cell, cy0)];
            if cell_px < 4.0 {
                plot.draw(&Rectangle::new(corners, OUT_OF_PLACE.filled()))?;
            } else {
                plot.draw(&Rectangle::new(corners, OUT_OF_PLACE.stroke_width(stroke)))?;
            }
        }
        // The grid's edge.
        plot.draw(&PathElement::new(
            vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)],
            MAT_EDGE.stroke_width(1),
        ))?;
    }

    // True walls.
    for (a, b) in &record.world.walls {
        if let (Some(a), Some(b)) = (tame_point(*a), tame_point(*b)) {
            plot.draw(&PathElement::new(vec![a, b], WALL.mix(0.9).stroke_width(2)))?;
        }
    }

    // Paths, truth under estimate.
    let truth: Vec<(f64, f64)> = record
        .ticks
        .iter()
        .filter_map(|t| tame_point(t.truth_mm))
        .collect();
    let estimate: Vec<(f64, f64)> = record
        .ticks
        .iter()
        .filter_map(|t| tame_point(t.estimate_mm))
        .collect();
    for (pts, color, start_r) in [(&truth, TRUE_PATH, 7), (&estimate, EST_PATH, 4)] {
        if pts.len() > 1 {
            plot.draw(&PathElement::new(pts.clone(), color.stroke_width(2)))?;
        }
        if let Some(&first) = pts.first() {
            plot.draw(&Circle::new(first, start_r, color.stroke_width(2)))?;
        }
        if let Some(&last) = pts.last() {
            plot.draw(&Circle::new(last, 4, color.filled()))?;
        }
    }

    // The filter's 3-sigma position ellipse every second, magnified to be seen.
    if let Some(scale) = ellipse_scale(record, mm_per_px) {
        for (centre, belief) in ellipse_ticks(record) {
            let outline = ellipse_points(centre, &belief, scale);
            let major_px = 3.0 * belief.position_axes().0.sqrt() * scale / mm_per_px;
            let alpha = if major_px > ELLIPSE_FAINT_PX {
                0.2
            } else {
                0.85
            };
            if outline.len() > 2 {
                plot.draw(&PathElement::new(
                    outline,
                    ELLIPSE.mix(alpha).stroke_width(1),
                ))?;
            }
        }
    }

    // Tags on top, labelled.
    for (id, c) in &record.world.tags {
        if let Some(c) = tame_point(*c) {
            let label = id.to_string();
            let marker = EmptyElement::at(c)
                + Rectangle::new([(-6, -6), (6, 6)], WHITE_BG.filled())
                + Rectangle::new([(-6, -6), (6, 6)], TAG_EDGE.stroke_width(2))
                + Rectangle::new([(-2, -2), (2, 2)], TAG_EDGE.filled())
                + Rectangle::new(
                    [(7, -27), (13 + 9 * label.chars().count() as i32, -13)],
                    WHITE_BG.mix(0.85).filled(),
                )
                + Text::new(label, (10, -22), font(14.0, TEXT));
            plot.draw(&marker)?;
        }
    }

    Ok(MapGeometry {
        x: rx,
        y: ry,
        px_x: ppx_x,
        px_y: ppx_y,
    })
}

/// One legend swatch.
enum Swatch {
    Cell(RGBColor, Option<RGBColor>),
    Line(RGBColor),
    Tick(RGBColor),
    Tag,
}

fn draw_map_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    ellipse_scale: Option<f64>,
) -> Result<(), PictureError>
where
    DB::ErrorType: 'static,
{
    let entries = [
        (Swatch::Cell(MAT, Some(MAT_EDGE)), "unknown"),
        (Swatch::Cell(FREE, None), "free"),
        (Swatch::Cell(OCCUPIED, None), "occupied"),
        (
            Swatch::Cell(OCCUPIED, Some(OUT_OF_PLACE)),
            "occupied, out of place",
        ),
        (Swatch::Line(WALL), "true wall"),
        (Swatch::Tag, "tag"),
        (Swatch::Line(TRUE_PATH), "true path"),
        (Swatch::Line(EST_PATH), "estimated path"),
    ];
    draw_legend(area, &entries, 4, 72)?;
    let (w, _) = area.dim_in_pixel();
    let note = match ellipse_scale {
        Some(k) if k > 1.0 => format!(
            "○ start   ● end   of each path   ·   purple: the filter's 3σ position ellipse each second, drawn ×{k:.0} (faint when large)"
        ),
        Some(_) => "○ start   ● end   of each path   ·   purple: the filter's 3σ position ellipse each second".to_string(),
        None => "○ start   ● end   of each path".to_string(),
    };
    area.draw(&Text::new(
        note,
        (w as i32 / 2, 74),
        font(12.0, MUTED).pos(Pos::new(HPos::Center, VPos::Center)),
    ))?;
    Ok(())
}

fn draw_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[(Swatch, &str)],
    per_row: usize,
    left: i32,
) -> Result<(), PictureError>
where
    DB::ErrorType: 'static,
{
    let (w, _) = area.dim_in_pixel();
    let per_row = per_row.max(1);
    let col_w = (w as i32 - left - 10) / per_row as i32;
    let label = font(14.0, TEXT).pos(Pos::new(HPos::Left, VPos::Center));
    for (i, (swatch, text)) in entries.iter().enumerate() {
        let x = left + col_w * (i % per_row) as i32;
        let y = 22 + 26 * (i / per_row) as i32;
        match swatch {
            Swatch::Cell(fill, edge) => {
                area.draw(&Rectangle::new(
                    [(x, y - 7), (x + 14, y + 7)],
                    fill.filled(),
                ))?;
                if let Some(edge) = edge {
                    area.draw(&Rectangle::new(
                        [(x, y - 7), (x + 14, y + 7)],
                        edge.stroke_width(2),
                    ))?;
                }
            }
            Swatch::Line(color) => {
                area.draw(&PathElement::new(
                    vec![(x - 3, y), (x + 17, y)],
                    color.stroke_width(2),
                ))?;
            }
            Swatch::Tick(color) => {
                area.draw(&Rectangle::new(
                    [(x + 6, y - 6), (x + 8, y + 6)],
                    color.filled(),
                ))?;
            }
            Swatch::Tag => {
                area.draw(&Rectangle::new(
                    [(x + 1, y - 6), (x + 13, y + 6)],
                    WHITE_BG.filled(),
                ))?;
                area.draw(&Rectangle::new(
                    [(x + 1, y - 6), (x + 13, y + 6)],
                    TAG_EDGE.stroke_width(2),
                ))?;
                area.draw(&Rectangle::new(
                    [(x + 5, y - 2), (x + 9, y + 2)],
                    TAG_EDGE.filled(),
                ))?;
            }
        }
        area.draw(&Text::new(text.to_string(), (x + 22, y), label.clone()))?;
    }
    Ok(())
}

/// One panel of the chart.
struct Panel {
    name: &'static str,
    color: RGBColor,
    value: fn(&TickRecord) -> f64,
    /// A fixed top for the y axis (percent panels), or `None` to fit the data.
    fixed_top: Option<f64>,
    /// The smallest top when fitting the data.
    min_top: f64,
    /// The filter's 3-sigma bound on the value, shaded from 0 up to it (NaN: none).
    bound: Option<fn(&TickRecord) -> f64>,
    /// The value a perfect filter would learn, dashed across the panel.
    truth: Option<fn(&TrueCalibration) -> f64>,
    /// The same tick by tick, where it changes (a wandering bias): dashed instead of
    /// `truth` when the ticks have it.
    true_series: Option<fn(&TickRecord) -> f64>,
}

/// A belief's field, or NaN without one.
fn belief_or_nan(t: &TickRecord, f: fn(&Belief) -> f64) -> f64 {
    t.belief.as_ref().map_or(f64::NAN, f)
}

/// The panels every chart has.
const PANELS: [Panel; 4] = [
    Panel {
        name: "known cells (%)",
        color: KNOWN_LINE,
        value: |t| t.known_pct,
        fixed_top: Some(100.0),
        min_top: 100.0,
        bound: None,
        truth: None,
        true_series: None,
    },
    Panel {
        name: "pose error (cm)",
        color: EST_PATH,
        value: |t| t.error_cm,
        fixed_top: None,
        min_top: 1.0,
        bound: Some(|t| belief_or_nan(t, Belief::bound_3sigma_cm)),
        truth: None,
        true_series: None,
    },
    Panel {
        name: "heading error, absolute (deg)",
        color: HEADING_LINE,
        value: |t| t.heading_error_deg.abs(),
        fixed_top: None,
        min_top: 1.0,
        bound: Some(|t| belief_or_nan(t, Belief::bound_3sigma_heading_deg)),
        truth: None,
        true_series: None,
    },
    Panel {
        name: "walls out of place (% of occupied)",
        color: OUT_OF_PLACE,
        value: |t| t.out_of_place_pct,
        fixed_top: None,
        min_top: 1.0,
        bound: None,
        truth: None,
        true_series: None,
    },
];

/// The panels a run with the filter adds: the calibration it learned, against the truth.
const FILTER_PANELS: [Panel; 3] = [
    Panel {
        name: "learned gyro scale correction (ppm)",
        color: CALIBRATION_LINE,
        value: |t| belief_or_nan(t, |b| b.gyro_scale_ppm),
        fixed_top: None,
        min_top: 1.0,
        bound: None,
        truth: Some(|c| c.gyro_scale_ppm),
        true_series: None,
    },
    Panel {
        name: "learned gyro bias (mdps)",
        color: CALIBRATION_LINE,
        value: |t| belief_or_nan(t, |b| b.gyro_bias_mdps),
        fixed_top: None,
        min_top: 1.0,
        bound: None,
        truth: Some(|c| c.gyro_bias_mdps),
        true_series: Some(|t| t.true_gyro_bias_mdps),
    },
    Panel {
        name: "learned flow scale correction (ppm)",
        color: CALIBRATION_LINE,
        value: |t| belief_or_nan(t, |b| b.flow_scale_ppm),
        fixed_top: None,
        min_top: 1.0,
        bound: None,
        truth: Some(|c| c.flow_scale_ppm),
        true_series: None,
    },
];

/// Whether any tick has the filter's belief.
fn has_filter(record: &RunRecord) -> bool {
    record.ticks.iter().any(|t| t.belief.is_some())
}

/// The chart's panels for `record`, top to bottom.
fn panels(record: &RunRecord) -> Vec<&'static Panel> {
    let mut out: Vec<&'static Panel> = PANELS.iter().collect();
    if has_filter(record) {
        out.extend(FILTER_PANELS.iter());
    }
    out
}

/// The chart's y range for one panel: its values, its bounds and its truth.
fn panel_range(panel: &Panel, ticks: &[TickRecord], truth: Option<&TrueCalibration>) -> Range<f64> {
    let bounds = ticks
        .iter()
        .filter_map(|t| tame(panel.bound.map_or(f64::NAN, |b| b(t))));
    let true_value = panel.truth.zip(truth).and_then(|(f, c)| tame(f(c)));
    let true_series = ticks
        .iter()
        .filter_map(|t| tame(panel.true_series.map_or(f64::NAN, |f| f(t))));
    let values = ticks
        .iter()
        .filter_map(|t| tame((panel.value)(t)))
        .chain(bounds)
        .chain(true_value)
        .chain(true_series);
    let (lo, hi) = values.fold((0.0f64, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let top = match panel.fixed_top {
        Some(top) => top.max(hi),
        None => (hi * 1.1).max(panel.min_top),
    };
    let bottom = if lo < 0.0 { lo * 1.1 } else { 0.0 };
    if top - bottom > 0.0 {
        bottom..top
    } else {
        bottom..bottom + 1.0
    }
}

/// Draws the chart over time of `record` to `path` as a PNG.
///
/// Four stacked panels sharing the time axis (seconds): known cells (%), pose error
/// (cm), absolute heading error (degrees) and walls out of place (%). Ticks where a tag
/// fix was taken are marked along the bottom of every panel.
pub fn chart_png(record: &RunRecord, path: &Path) -> Result<(), PictureError> {
    let filter = has_filter(record);
    let (size, legend_h) = if filter {
        (FILTER_CHART_SIZE, 66)
    } else {
        (CHART_SIZE, 40)
    };
    render(path, size, |root| {
        let (top, rest) = root.split_vertically(62);
        let (body, legend) = rest.split_vertically(size.1 - 62 - legend_h);
        draw_title(
            &top,
            &title_text("Over time", record),
            &chart_subtitle(record),
        )?;
        draw_chart_body(record, &body)?;
        let mut entries = vec![
            (
                Swatch::Tick(FIX_MARK),
                if filter {
                    "tag update taken (marks along each panel's foot)"
                } else {
                    "tag fix taken (marked along the foot of each panel)"
                },
            ),
            (
                Swatch::Line(HEADING_LINE),
                "heading error is |estimate − truth|, in degrees",
            ),
        ];
        if filter {
            entries.push((
                Swatch::Cell(BOUND_BAND, None),
                "the filter's 3σ bound: the error should stay in it",
            ));
            entries.push((
                Swatch::Line(TRUTH_DASH),
                "dashed: the correction the scenario's sensors need",
            ));
        }
        draw_legend(&legend, &entries, 2, 80).map(|_| ())
    })
}

fn chart_subtitle(record: &RunRecord) -> String {
    let fixes = record.ticks.iter().filter(|t| t.fix_taken).count();
    match (record.ticks.first(), record.ticks.last()) {
        (Some(a), Some(b)) => format!(
            "{} ticks from {:.1} s to {:.1} s · {} tag fixes",
            record.ticks.len(),
            a.t_s,
            b.t_s,
            fixes
        ),
        _ => "no ticks recorded".to_string(),
    }
}

fn draw_chart_body<DB: DrawingBackend>(
    record: &RunRecord,
    area: &DrawingArea<DB, Shift>,
) -> Result<(), PictureError>
where
    DB::ErrorType: 'static,
{
    let ticks = &record.ticks;
    let times: Vec<f64> = ticks.iter().filter_map(|t| tame(t.t_s)).collect();
    let t0 = times.iter().copied().fold(f64::MAX, f64::min);
    let t1 = times.iter().copied().fold(f64::MIN, f64::max);
    let x_range = if times.is_empty() {
        0.0..1.0
    } else if t1 > t0 {
        t0..t1
    } else {
        t0..t0 + 1.0
    };

    let (_, h) = area.dim_in_pixel();
    let bottom_extra = 44;
    let panels = panels(record);
    let panel_h = (h.saturating_sub(bottom_extra) / panels.len() as u32).max(1);
    let truth = record.true_calibration.as_ref();
    let mut rest = area.clone();
    for (i, panel) in panels.iter().enumerate() {
        let last = i + 1 == panels.len();
        let (cell, below) = if last {
            (rest.clone(), rest.clone())
        } else {
            rest.split_vertically(panel_h)
        };
        rest = below;
        let y_range = panel_range(panel, ticks, truth);
        let mut chart = ChartBuilder::on(&cell)
            .margin_left(8)
            .margin_right(24)
            .margin_top(22)
            .margin_bottom(if last { 4 } else { 6 })
            .x_label_area_size(if last { 44 } else { 0 })
            .y_label_area_size(64)
            .build_cartesian_2d(x_range.clone(), y_range.clone())?;
        chart.plotting_area().fill(&RGBColor(0xfb, 0xfa, 0xf6))?;
        let mut mesh = chart.configure_mesh();
        mesh.light_line_style(TRANSPARENT)
            .bold_line_style(GRID_LINE.stroke_width(1))
            .x_labels(10)
            .y_labels(5)
            .label_style(font(12.0, TEXT))
            .axis_desc_style(font(14.0, TEXT))
            .y_label_formatter(&|v| short_number(*v));
        if last {
            mesh.x_desc("time (s)")
                .x_label_formatter(&|v| short_number(*v));
        } else {
            mesh.x_label_formatter(&|_| String::new());
        }
        mesh.draw()?;

        // The panel's name above its top-left corner.
        let (px, _) = chart.plotting_area().get_pixel_range();
        let (cx, cy) = cell.get_base_pixel();
        let label_pos = (px.start - cx, 3);
        let _ = cy;
        cell.draw(&Text::new(
            panel.name.to_string(),
            label_pos,
            font(14.0, panel.color),
        ))?;

        // The 3-sigma bound, shaded from the foot up, broken where there is none.
        if let Some(bound) = panel.bound {
            for seg in segments_of(ticks, bound) {
                let mut outline = seg.clone();
                outline.extend(seg.iter().rev().map(|&(x, _)| (x, y_range.start.max(0.0))));
                chart
                    .plotting_area()
                    .draw(&Polygon::new(outline, BOUND_BAND.filled()))?;
            }
        }
        // The truth, dashed: tick by tick where the ticks have it, else across.
        let true_segments = panel
            .true_series
            .map_or_else(Vec::new, |f| segments_of(ticks, f));
        for seg in &true_segments {
            chart.draw_series(DashedLineSeries::new(
                seg.iter().copied(),
                8,
                5,
                TRUTH_DASH.stroke_width(2),
            ))?;
        }
        let constant = panel.truth.zip(truth).and_then(|(f, c)| tame(f(c)));
        if let Some(value) = constant.filter(|_| true_segments.is_empty()) {
            chart.draw_series(DashedLineSeries::new(
                [(x_range.start, value), (x_range.end, value)],
                8,
                5,
                TRUTH_DASH.stroke_width(2),
            ))?;
        }

        // Fix marks along the foot.
        let foot = y_range.start;
        let mark = (y_range.end - y_range.start) * 0.08;
        chart.draw_series(
            ticks
                .iter()
                .filter(|t| t.fix_taken)
                .filter_map(|t| tame(t.t_s))
                .map(|t| {
                    PathElement::new(vec![(t, foot), (t, foot + mark)], FIX_MARK.stroke_width(2))
                }),
        )?;

        // The series itself, broken where a value is missing.
        for seg in segments_of(ticks, panel.value) {
            if seg.len() == 1 {
                chart.draw_series(std::iter::once(Circle::new(
                    seg[0],
                    2,
                    panel.color.filled(),
                )))?;
            } else {
                chart.draw_series(LineSeries::new(seg, panel.color.stroke_width(2)))?;
            }
        }
        if ticks.is_empty() {
            let (px_x, px_y) = chart.plotting_area().get_pixel_range();
            let (bx, by) = cell.get_base_pixel();
            cell.draw(&Text::new(
                "no ticks recorded",
                (
                    (px_x.start + px_x.end) / 2 - bx,
                    (px_y.start + px_y.end) / 2 - by,
                ),
                font(14.0, MUTED).pos(Pos::new(HPos::Center, VPos::Center)),
            ))?;
        }
    }
    Ok(())
}

/// `value` over time as runs of drawable points, broken where it is missing.
fn segments_of(ticks: &[TickRecord], value: fn(&TickRecord) -> f64) -> Vec<Vec<(f64, f64)>> {
    let mut segment: Vec<(f64, f64)> = Vec::new();
    let mut segments: Vec<Vec<(f64, f64)>> = Vec::new();
    for t in ticks {
        match (tame(t.t_s), tame(value(t))) {
            (Some(x), Some(y)) => segment.push((x, y)),
            _ => {
                if !segment.is_empty() {
                    segments.push(std::mem::take(&mut segment));
                }
            }
        }
    }
    if !segment.is_empty() {
        segments.push(segment);
    }
    segments
}

/// An axis number without needless digits.
fn short_number(v: f64) -> String {
    let a = v.abs();
    if a >= 1e6 {
        format!("{v:.1e}")
    } else if a >= 100.0 || a == 0.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        format!("{v:.2}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{MapSnapshot, WorldOutline};
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
}
