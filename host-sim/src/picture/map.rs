//! The overhead map: the grid's cells, the true walls and tags, both paths and the
//! filter's ellipses, with its legend.

use super::{
    draw_legend, draw_title, font, render, tame, tame_point, title_text, PictureError, Swatch,
    ELLIPSE, EST_PATH, FREE, MAP_SIZE, MAT, MAT_EDGE, MUTED, OCCUPIED, OUT_OF_PLACE, TAG_EDGE,
    TEXT, TRUE_PATH, WALL, WHITE_BG,
};

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::record::{Belief, CellBelief, RunRecord};

/// Where the map picture put the map: data ranges and the plotting area's pixels.
#[derive(Clone, Debug)]
#[cfg_attr(not(test), allow(dead_code))]
pub(super) struct MapGeometry {
    pub(super) x: Range<f64>,
    pub(super) y: Range<f64>,
    pub(super) px_x: Range<i32>,
    pub(super) px_y: Range<i32>,
}

impl MapGeometry {
    /// The pixel a map point (millimetres) lands on.
    #[cfg(test)]
    pub(super) fn to_px(&self, (x, y): (f64, f64)) -> (i32, i32) {
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

pub(super) fn draw_map(record: &RunRecord, path: &Path) -> Result<MapGeometry, PictureError> {
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
