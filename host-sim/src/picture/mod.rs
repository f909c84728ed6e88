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
//!
//! - `map`: the overhead map;
//! - `chart`: the run over time.

mod chart;
mod map;
#[cfg(test)]
mod tests;

pub use chart::chart_png;
pub use map::map_png;

use std::fmt;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::drawing::DrawingAreaErrorKind;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

use crate::record::RunRecord;

/// The font every label uses, compiled in.
const FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
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

/// One legend swatch.
enum Swatch {
    Cell(RGBColor, Option<RGBColor>),
    Line(RGBColor),
    Tick(RGBColor),
    Tag,
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
