//! The chart over time: the known floor, the errors against their bounds and the
//! calibration the filter learned, a panel each.

use super::{
    draw_legend, draw_title, font, render, tame, title_text, PictureError, Swatch, BOUND_BAND,
    CALIBRATION_LINE, CHART_SIZE, EST_PATH, FILTER_CHART_SIZE, FIX_MARK, GRID_LINE, HEADING_LINE,
    KNOWN_LINE, MUTED, OUT_OF_PLACE, TEXT, TRUTH_DASH,
};

use std::ops::Range;
use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::record::{Belief, RunRecord, TickRecord, TrueCalibration};

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
