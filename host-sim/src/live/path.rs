//! A path that stays small however long the run: decimated as it grows.

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

/// Every `stride`-th point pushed, at most [`MAX_PATH_POINTS`] of them (then the stride
/// doubles and every other point is dropped), and always the latest.
#[derive(Clone, Debug, Default)]
pub struct Path {
    kept: Vec<PathPoint>,
    latest: Option<PathPoint>,
    stride: u64,
    pushed: u64,
}

impl Path {
    /// An empty path.
    pub fn new() -> Path {
        Path {
            stride: 1,
            ..Path::default()
        }
    }

    /// Adds the newest point.
    pub fn push(&mut self, p: PathPoint) {
        if self.pushed.is_multiple_of(self.stride.max(1)) {
            if self.kept.len() >= MAX_PATH_POINTS {
                let mut i = 0;
                self.kept.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride = self.stride.saturating_mul(2);
            }
            if self.pushed.is_multiple_of(self.stride.max(1)) {
                self.kept.push(p);
            }
        }
        self.pushed += 1;
        self.latest = Some(p);
    }

    /// The path to draw: the kept points and the latest, if it was not kept.
    pub fn points(&self) -> impl Iterator<Item = &PathPoint> {
        let tail = match (self.kept.last(), &self.latest) {
            (Some(k), Some(l)) if k == l => None,
            (_, l) => l.as_ref(),
        };
        self.kept.iter().chain(tail)
    }

    /// Whether nothing was pushed.
    pub fn is_empty(&self) -> bool {
        self.latest.is_none()
    }
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
        let mut path = Path::new();
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
        let mut path = Path::new();
        for i in 0..10 {
            path.push(at(i));
        }
        assert_eq!(path.points().count(), 10);
    }
}
