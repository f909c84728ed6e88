//! A path of bounded length for the live page: however long the run, it keeps at most
//! [`MAX_PATH_POINTS`] points spread evenly along it.

use crate::decimated::Decimated;
use serde::Serialize;

/// The most points a path keeps. At a tick every 100 ms that is every tick of the
/// first 100 s, then every other, and so on; the page draws a line through them.
pub const MAX_PATH_POINTS: usize = 1000;

/// A point of a path, millimetres on the map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PathPoint {
    /// Map x, millimetres.
    pub x_mm: f64,
    /// Map y, millimetres.
    pub y_mm: f64,
}

/// A path of at most [`MAX_PATH_POINTS`] points (and the newest), evenly spread; points
/// that are not finite are left out.
#[derive(Clone, Debug)]
pub struct DecimatedPath(Decimated<PathPoint>);

impl Default for DecimatedPath {
    fn default() -> DecimatedPath {
        DecimatedPath::new()
    }
}

impl DecimatedPath {
    /// An empty path.
    pub fn new() -> DecimatedPath {
        DecimatedPath(Decimated::new(MAX_PATH_POINTS))
    }

    /// Adds the next point. Points that are not finite are ignored.
    pub fn push(&mut self, point: PathPoint) {
        if point.x_mm.is_finite() && point.y_mm.is_finite() {
            self.0.push(point);
        }
    }

    /// The kept points, then the newest one if it was not kept: at most
    /// [`MAX_PATH_POINTS`] + 1.
    pub fn points(&self) -> Vec<PathPoint> {
        self.0.points().copied().collect()
    }

    /// The newest point, if any.
    pub fn newest(&self) -> Option<PathPoint> {
        self.0.newest()
    }

    /// Forgets every point (a robot that restarted begins a new path).
    pub fn clear(&mut self) {
        self.0.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(i: usize) -> PathPoint {
        PathPoint {
            x_mm: i as f64,
            y_mm: 0.0,
        }
    }

    #[test]
    fn a_short_path_keeps_every_point() {
        let mut path = DecimatedPath::new();
        (0..10).for_each(|i| path.push(p(i)));
        assert_eq!(path.points(), (0..10).map(p).collect::<Vec<_>>());
    }

    #[test]
    fn a_long_path_stays_bounded_evenly_spread_and_ends_at_the_newest_point() {
        let mut path = DecimatedPath::new();
        let n = 100 * MAX_PATH_POINTS + 7;
        (0..n).for_each(|i| path.push(p(i)));
        let points = path.points();
        assert!(points.len() <= MAX_PATH_POINTS + 1, "{}", points.len());
        assert!(points.len() >= MAX_PATH_POINTS / 2, "{}", points.len());
        assert_eq!(points.first(), Some(&p(0)));
        assert_eq!(points.last(), Some(&p(n - 1)));
        // Evenly spread: every gap between kept points (the newest aside) is the stride.
        let xs: Vec<f64> = points.iter().map(|q| q.x_mm).collect();
        let gaps: Vec<f64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
        let stride = gaps[0];
        assert!(
            gaps[..gaps.len() - 1].iter().all(|&g| g == stride),
            "{gaps:?}"
        );
    }

    #[test]
    fn points_that_are_not_finite_are_ignored_and_clear_forgets() {
        let mut path = DecimatedPath::new();
        path.push(PathPoint {
            x_mm: f64::NAN,
            y_mm: 0.0,
        });
        path.push(PathPoint {
            x_mm: 1.0,
            y_mm: f64::INFINITY,
        });
        assert!(path.points().is_empty() && path.newest().is_none());
        path.push(p(3));
        assert_eq!(path.points(), vec![p(3)]);
        path.clear();
        assert!(path.points().is_empty());
    }
}
