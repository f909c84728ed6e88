//! A path that stays small however long the run: decimated as it grows.

use crate::decimated::Decimated;

/// A point of a path: the map position, millimetres, and the heading, degrees clockwise
/// from +y.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// Millimetres.
    pub x_mm: f64,
    /// Millimetres.
    pub y_mm: f64,
    /// Degrees clockwise from +y.
    pub heading_deg: f64,
}

/// The most points a path keeps: at 10 Hz a whole hour decimates to every 8th tick.
pub const MAX_PATH_POINTS: usize = 4096;

/// A path of at most [`MAX_PATH_POINTS`] points (and the latest), evenly spread.
pub type Path = Decimated<PathPoint>;

/// An empty path.
pub fn new_path() -> Path {
    Decimated::new(MAX_PATH_POINTS)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(i: usize) -> PathPoint {
        PathPoint {
            x_mm: i as f64,
            y_mm: 0.0,
            heading_deg: 0.0,
        }
    }

    #[test]
    fn a_long_path_is_capped_and_ends_at_the_latest_point() {
        let mut path = new_path();
        assert!(path.is_empty());
        for i in 0..36_000 {
            path.push(at(i));
        }
        let points: Vec<_> = path.points().collect();
        assert!(points.len() <= MAX_PATH_POINTS + 1, "{}", points.len());
        assert!(points.len() > MAX_PATH_POINTS / 2);
        assert_eq!(points.first().map(|p| p.x_mm), Some(0.0));
        assert_eq!(points.last().map(|p| p.x_mm), Some(35_999.0));
        // Evenly spaced: the stride is a power of two.
        let gaps: Vec<f64> = points.windows(2).map(|w| w[1].x_mm - w[0].x_mm).collect();
        let stride = gaps[0];
        assert!(
            gaps[..gaps.len() - 1].iter().all(|&g| g == stride),
            "{gaps:?}"
        );
    }

    #[test]
    fn a_short_path_keeps_every_point() {
        let mut path = new_path();
        for i in 0..10 {
            path.push(at(i));
        }
        assert_eq!(path.points().count(), 10);
    }
}
