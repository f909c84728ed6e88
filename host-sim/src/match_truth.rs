//! The scan matches against the truth: how far each match lies from the true pose in the
//! directions it claims to pin, beside the spread it claims there, as `run --json`
//! reports under `match_truth` (modes `match` and `slam`).
//!
//! A match places the robot against the map, so on a world whose map is drawn from a
//! well-placed robot (tags in view) its error is the matcher's own; where the map carries
//! the robot's drift, it is the matcher's and the map's together. Errors are split by
//! direction: along the robot's nose (positive: the match puts the robot further ahead
//! than it is) and across it (positive: further to its right). A match that pins both
//! position directions counts in both; one that pins a line counts in the one its pinned
//! direction lies nearer. The filter takes each match with its spread doubled plus 3 mm
//! and never surer than a cell's quantisation ([`MatchNoise::SEED`]); the share inside
//! three of the surface's own deviations says how honest the surface is.

use serde::Serialize;
use slam_core::estimator::MatchNoise;
use slam_core::matcher::{Match, Pins};

use crate::robot::{wrap_deg, TruePose};
use crate::world::Vec2;

/// One direction's errors, summed over a run's matches.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sums {
    n: u32,
    error: f64,
    error_sq: f64,
    claimed_sq: f64,
    inside_surface: u32,
    inside_filter: u32,
}

impl Sums {
    /// One match's `error` in a direction whose claimed variance is `claimed_var`, both in
    /// the direction's units (millimetres, or degrees for the heading); `widen` turns a
    /// surface deviation into the filter's.
    fn add(&mut self, error: f64, claimed_var: f64, widen: impl Fn(f64) -> f64) {
        let claimed_var = claimed_var.max(0.0);
        let sd = claimed_var.sqrt();
        self.n += 1;
        self.error += error;
        self.error_sq += error * error;
        self.claimed_sq += claimed_var;
        self.inside_surface += u32::from(error.abs() <= 3.0 * sd);
        self.inside_filter += u32::from(error.abs() <= 3.0 * widen(sd));
    }

    fn figures(&self) -> DirectionFigures {
        let n = f64::from(self.n.max(1));
        DirectionFigures {
            matches: self.n,
            mean: self.error / n,
            rms: (self.error_sq / n).sqrt(),
            claimed_rms: (self.claimed_sq / n).sqrt(),
            inside_3_surface_sigma_pct: 100.0 * f64::from(self.inside_surface) / n,
            inside_3_filter_sigma_pct: 100.0 * f64::from(self.inside_filter) / n,
        }
    }
}

/// A run's matches against the truth in one direction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DirectionFigures {
    /// Matches that pinned this direction (and whose tick has a truth).
    pub matches: u32,
    /// Their mean error, signed (millimetres; degrees for the heading).
    pub mean: f64,
    /// Their root-mean-square error.
    pub rms: f64,
    /// The root-mean-square of the deviation each match's surface claimed.
    pub claimed_rms: f64,
    /// Share whose error lies within three deviations of their surface, percent.
    pub inside_3_surface_sigma_pct: f64,
    /// Share within three of the deviations the filter takes them at, percent.
    pub inside_3_filter_sigma_pct: f64,
}

/// A run's matches against the truth ([`MatchTruth::figures`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MatchTruthFigures {
    /// Position along the robot's nose: positive puts it ahead of where it is.
    pub along_mm: DirectionFigures,
    /// Position across the nose: positive puts it to the robot's right.
    pub across_mm: DirectionFigures,
    /// Heading: positive turns it clockwise of the truth.
    pub heading_deg: DirectionFigures,
}

/// The matches of a run, each against the truth of its tick.
#[derive(Clone, Debug, Default)]
pub struct MatchTruth {
    along: Sums,
    across: Sums,
    heading: Sums,
    /// The tick of the last match counted: the core keeps its newest match until the
    /// next, so each is counted once.
    last_tick: Option<u32>,
}

impl MatchTruth {
    /// Counts `m` against `truth`, the true pose at its tick, unless it was counted.
    pub fn add(&mut self, m: &Match, truth: &TruePose) {
        if self.last_tick == Some(m.tick) {
            return;
        }
        self.last_tick = Some(m.tick);
        let noise = MatchNoise::SEED;
        let scale = f64::from(noise.scale_pct) / 100.0;
        let (add_mm, add_deg) = (
            f64::from(noise.position_um) / 1000.0,
            f64::from(noise.heading_mdeg) / 1000.0,
        );
        let error = Vec2::new(
            f64::from(m.pose.x_um) / 1000.0 - truth.x_mm,
            f64::from(m.pose.y_um) / 1000.0 - truth.y_mm,
        );
        let c = &m.covariance;
        let claimed = |u: Vec2| {
            (u.x * u.x * c.xx_um2 as f64
                + 2.0 * u.x * u.y * c.xy_um2 as f64
                + u.y * u.y * c.yy_um2 as f64)
                / 1e6
        };
        let nose = Vec2::heading(truth.heading_deg);
        let right = Vec2::new(nose.y, -nose.x);
        let widen_mm = |sd: f64| scale * sd + add_mm;
        let mut count = |d: Vec2| {
            let claimed_var = claimed(d);
            let (along, across) = (dot(d, nose), dot(d, right));
            // Signed toward the nose, or toward the right.
            let (sums, toward) = if along.abs() >= across.abs() {
                (&mut self.along, along)
            } else {
                (&mut self.across, across)
            };
            sums.add(toward.signum() * dot(error, d), claimed_var, widen_mm);
        };
        match m.pins {
            Pins::All | Pins::PositionOnly => {
                count(nose);
                count(right);
            }
            Pins::AllButAlong(line) | Pins::AcrossOnly(line) => {
                // The line's direction is (sin, cos) clockwise from +y; its normal is
                // pinned.
                let a = Vec2::heading(f64::from(line.to_millidegrees()) / 1000.0);
                count(Vec2::new(a.y, -a.x));
            }
            Pins::HeadingOnly => {}
        }
        if matches!(m.pins, Pins::All | Pins::AllButAlong(_) | Pins::HeadingOnly) {
            let turned = f64::from(m.pose.heading.to_millidegrees()) / 1000.0 - truth.heading_deg;
            let error = wrap_deg(turned);
            self.heading
                .add(error, c.hh_mdeg2 as f64 / 1e6, |sd| scale * sd + add_deg);
        }
    }

    /// The figures so far.
    pub fn figures(&self) -> MatchTruthFigures {
        MatchTruthFigures {
            along_mm: self.along.figures(),
            across_mm: self.across.figures(),
            heading_deg: self.heading.figures(),
        }
    }
}

fn dot(a: Vec2, b: Vec2) -> f64 {
    a.x * b.x + a.y * b.y
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_core::matcher::{MatchCovariance, MatchStats};
    use slam_core::{Angle, Pose};

    fn a_match(tick: u32, x_mm: i32, y_mm: i32, heading_mdeg: i64, pins: Pins) -> Match {
        let pose = Pose::from_mm_mdeg(x_mm, y_mm, heading_mdeg);
        Match {
            tick,
            prediction: pose,
            pose,
            covariance: MatchCovariance {
                xx_um2: 4_000_000,
                yy_um2: 1_000_000,
                hh_mdeg2: 250_000,
                ..MatchCovariance::default()
            },
            pins,
            wide: Angle::from_millidegrees(0),
            best_score: 0,
            worst_score: 0,
            stats: MatchStats::default(),
        }
    }

    fn truth(x_mm: f64, y_mm: f64, heading_deg: f64) -> TruePose {
        TruePose {
            x_mm,
            y_mm,
            heading_deg,
        }
    }

    /// Facing +x, a match 10 mm further along x is 10 mm ahead, and one 5 mm lower in y
    /// is 5 mm to the right; the claimed deviations follow the axes (2 mm along x, 1 mm
    /// along y), and a 10 mm error is outside three of x's.
    #[test]
    fn errors_split_along_and_across_the_nose() {
        let mut t = MatchTruth::default();
        t.add(
            &a_match(1, 1010, 495, 90_000, Pins::PositionOnly),
            &truth(1000.0, 500.0, 90.0),
        );
        let f = t.figures();
        assert_eq!(f.along_mm.matches, 1);
        assert!((f.along_mm.mean - 10.0).abs() < 1e-9, "{f:?}");
        assert!((f.along_mm.claimed_rms - 2.0).abs() < 1e-9, "{f:?}");
        assert_eq!(f.along_mm.inside_3_surface_sigma_pct, 0.0);
        // The filter's view: 2 * 2 + 3 = 7 mm, so 10 mm is inside three of it.
        assert_eq!(f.along_mm.inside_3_filter_sigma_pct, 100.0);
        assert!((f.across_mm.mean - 5.0).abs() < 1e-9, "{f:?}");
        assert!((f.across_mm.claimed_rms - 1.0).abs() < 1e-9, "{f:?}");
        assert_eq!(f.heading_deg.matches, 0, "position only pins no heading");
    }

    /// A match pinning only across a line counts in the one direction, the line's
    /// normal; the same match reported again (the core keeps its newest) counts once.
    #[test]
    fn a_line_pins_its_normal_and_each_match_counts_once() {
        let mut t = MatchTruth::default();
        // Facing +y along a wall that runs along y: the pinned normal is x, across the
        // nose; the match lies 3 mm to the left (-x).
        let m = a_match(
            7,
            997,
            520,
            0,
            Pins::AcrossOnly(Angle::from_millidegrees(0)),
        );
        t.add(&m, &truth(1000.0, 500.0, 0.0));
        t.add(&m, &truth(1000.0, 500.0, 0.0));
        let f = t.figures();
        assert_eq!((f.along_mm.matches, f.across_mm.matches), (0, 1), "{f:?}");
        assert!((f.across_mm.mean + 3.0).abs() < 1e-9, "{f:?}");
    }

    /// The heading's error wraps: a match at 359.5 degrees against a truth at 0.5 is
    /// a degree anticlockwise, not 359 clockwise.
    #[test]
    fn the_heading_error_wraps() {
        let mut t = MatchTruth::default();
        t.add(
            &a_match(3, 0, 0, 359_500, Pins::HeadingOnly),
            &truth(0.0, 0.0, 360.5),
        );
        let f = t.figures();
        assert_eq!(f.heading_deg.matches, 1);
        assert!((f.heading_deg.mean + 1.0).abs() < 1e-6, "{f:?}");
        assert_eq!(f.along_mm.matches + f.across_mm.matches, 0);
    }
}
