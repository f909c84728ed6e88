//! What a run leaves behind: a row per tick, the final map and the world it was drawn in.
//!
//! The pictures, the JSON figures and the tests all read this; so does the telemetry
//! viewer, which fills it from a robot's stream instead of from the simulator.

use crate::consistency::TagFigures;
use crate::robot::wrap_deg;
use crate::scenario::Scenario;
use crate::truth::TruthSample;
use crate::world::World;
use serde::Serialize;
use slam_core::estimator::{HEADING_UNITS_PER_RAD, POSITION_UNITS_PER_MM};
use slam_core::{Estimate, Occupancy, TagCounters};

/// A point on the mat, in millimetres.
pub type PointMm = (f64, f64);

/// One tick of a run, as the chart plots it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TickRecord {
    /// Time since the start, in seconds.
    pub t_s: f64,
    /// The true position, millimetres.
    pub truth_mm: PointMm,
    /// The true heading, degrees clockwise from +y.
    pub truth_heading_deg: f64,
    /// The position the mapper used, millimetres.
    pub estimate_mm: PointMm,
    /// The heading the mapper used, degrees.
    pub estimate_heading_deg: f64,
    /// Share of the grid with a firm belief, percent.
    pub known_pct: f64,
    /// Distance from estimate to truth, centimetres.
    pub error_cm: f64,
    /// Estimate minus truth heading, degrees in [-180, 180).
    pub heading_error_deg: f64,
    /// Share of occupied cells off any real wall or tag, percent.
    pub out_of_place_pct: f64,
    /// Whether a tag fix was taken this tick.
    pub fix_taken: bool,
    /// What the filter believed after this tick; `None` when the run has no filter.
    pub belief: Option<Belief>,
    /// The gyro's true bias at this tick, millidegrees per second (it may wander); NaN
    /// when unknown.
    pub true_gyro_bias_mdps: f64,
}

/// The filter's belief at one tick, in the units the pictures and the figures use.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Belief {
    /// Variance of x, mm².
    pub xx_mm2: f64,
    /// Covariance of x and y, mm².
    pub xy_mm2: f64,
    /// Variance of y, mm².
    pub yy_mm2: f64,
    /// Variance of the heading, deg².
    pub hh_deg2: f64,
    /// The learned gyro scale correction, ppm.
    pub gyro_scale_ppm: f64,
    /// The learned gyro bias, millidegrees per second.
    pub gyro_bias_mdps: f64,
    /// The learned flow scale correction, ppm.
    pub flow_scale_ppm: f64,
    /// Tag sightings used and refused since start.
    pub tags: TagFigures,
}

impl Belief {
    /// The core's estimate in these units (position 1/16 mm, heading 2^-16 rad).
    pub fn new(e: &Estimate, tags: TagCounters) -> Belief {
        let pos = (POSITION_UNITS_PER_MM * POSITION_UNITS_PER_MM) as f64;
        let rad = HEADING_UNITS_PER_RAD as f64;
        let c = &e.covariance;
        Belief {
            xx_mm2: c.xx as f64 / pos,
            xy_mm2: c.xy as f64 / pos,
            yy_mm2: c.yy as f64 / pos,
            hh_deg2: c.hh as f64 / (rad * rad) * (180.0 / std::f64::consts::PI).powi(2),
            gyro_scale_ppm: f64::from(e.calibration.gyro_scale_ppm),
            gyro_bias_mdps: f64::from(e.calibration.gyro_bias_mdps),
            flow_scale_ppm: f64::from(e.calibration.flow_scale_ppm),
            tags: tags.into(),
        }
    }

    /// The position covariance's principal axes: the larger and smaller eigenvalues (mm²)
    /// and the larger one's direction, radians anticlockwise from +x. A covariance that
    /// is not positive semi-definite gives a negative smaller eigenvalue, clamped to 0.
    pub fn position_axes(&self) -> (f64, f64, f64) {
        let (a, b, c) = (self.xx_mm2, self.xy_mm2, self.yy_mm2);
        let mean = (a + c) / 2.0;
        let spread = ((a - c) / 2.0).hypot(b);
        let angle = 0.5 * (2.0 * b).atan2(a - c);
        ((mean + spread).max(0.0), (mean - spread).max(0.0), angle)
    }

    /// 3 sigma of the position along its worst direction, centimetres: 3 times the root
    /// of the covariance's larger eigenvalue.
    pub fn bound_3sigma_cm(&self) -> f64 {
        3.0 * self.position_axes().0.sqrt() / 10.0
    }

    /// 3 sigma of the heading, degrees.
    pub fn bound_3sigma_heading_deg(&self) -> f64 {
        3.0 * self.hh_deg2.max(0.0).sqrt()
    }
}

/// The corrections a perfect filter would learn on a scenario: what its sensors' errors
/// are, as the filter's [`slam_core::Calibration`] states them (the chart draws them
/// dashed under the learned ones).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TrueCalibration {
    /// The gyro reads `(1 + e)` times the true rate: the correction is `-e / (1 + e)`, ppm.
    pub gyro_scale_ppm: f64,
    /// The gyro's bias, millidegrees per second.
    pub gyro_bias_mdps: f64,
    /// The flow sensor reads `(1 + e)` times the true distance: the correction is
    /// `-e / (1 + e)`, ppm.
    pub flow_scale_ppm: f64,
}

impl TrueCalibration {
    /// The corrections for `scenario`'s sensors.
    pub fn of(scenario: &Scenario) -> TrueCalibration {
        let correction = |e: f64| -e / (1.0 + e) * 1e6;
        let (g, f) = (&scenario.sensors.gyro, &scenario.sensors.flow);
        TrueCalibration {
            gyro_scale_ppm: correction(g.scale_error),
            gyro_bias_mdps: g.bias_dps * 1000.0,
            flow_scale_ppm: correction(f.scale_error),
        }
    }
}

impl TickRecord {
    /// A tick as the mapper saw it: every truth and error field NaN until
    /// [`TickRecord::set_truth`] (the pictures leave NaN out).
    pub fn estimated(
        t_s: f64,
        estimate_mm: PointMm,
        estimate_heading_deg: f64,
        known_pct: f64,
        fix_taken: bool,
    ) -> TickRecord {
        TickRecord {
            t_s,
            truth_mm: (f64::NAN, f64::NAN),
            truth_heading_deg: f64::NAN,
            estimate_mm,
            estimate_heading_deg,
            known_pct,
            error_cm: f64::NAN,
            heading_error_deg: f64::NAN,
            out_of_place_pct: f64::NAN,
            fix_taken,
            belief: None,
            true_gyro_bias_mdps: f64::NAN,
        }
    }

    /// Records the true pose (`heading_deg` clockwise from +y, any number of turns) and
    /// the estimate's errors against it. The one place a tick's errors are worked out, so
    /// that `host-sim run` and `host-sim view --truth` score a pose alike.
    pub fn set_truth(&mut self, truth_mm: PointMm, heading_deg: f64) {
        let (ex, ey) = self.estimate_mm;
        self.truth_mm = truth_mm;
        self.truth_heading_deg = wrap_deg(heading_deg);
        self.error_cm = (ex - truth_mm.0).hypot(ey - truth_mm.1) / 10.0;
        self.heading_error_deg = wrap_deg(self.estimate_heading_deg - heading_deg);
    }
}

/// The map as it stood at the end: a belief per cell.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MapSnapshot {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cell side, millimetres.
    pub cell_mm: f64,
    /// Map x of the grid's lower-left corner, millimetres.
    pub origin_x_mm: f64,
    /// Map y of the grid's lower-left corner, millimetres.
    pub origin_y_mm: f64,
    /// Row-major from the lowest row: `cells[row * width + column]`.
    pub cells: Vec<CellBelief>,
    /// Occupied cells that lie on no real wall or tag (same indexing); empty when the
    /// truth is not known (a real robot's stream).
    pub out_of_place: Vec<bool>,
}

/// What the map believes about one cell.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum CellBelief {
    /// No firm belief.
    Unknown,
    /// Free.
    Free,
    /// Occupied.
    Occupied,
}

impl From<Occupancy> for CellBelief {
    fn from(o: Occupancy) -> CellBelief {
        match o {
            Occupancy::Free => CellBelief::Free,
            Occupancy::Occupied => CellBelief::Occupied,
            Occupancy::Unknown => CellBelief::Unknown,
        }
    }
}

/// The true world, drawn under the map.
#[derive(Clone, Debug, PartialEq, Serialize, Default)]
pub struct WorldOutline {
    /// Wall segments, millimetres.
    pub walls: Vec<(PointMm, PointMm)>,
    /// Tags: id and centre, millimetres.
    pub tags: Vec<(u16, PointMm)>,
}

impl WorldOutline {
    /// The walls (tag cards left out: they are drawn as tags) and tags of `world`.
    pub fn of(world: &World) -> WorldOutline {
        WorldOutline {
            walls: world
                .walls()
                .iter()
                .filter(|w| w.tag.is_none())
                .map(|w| ((w.a.x, w.a.y), (w.b.x, w.b.y)))
                .collect(),
            tags: world
                .tags()
                .iter()
                .map(|t| (t.id, (t.centre.x, t.centre.y)))
                .collect(),
        }
    }
}

/// Everything one run produced.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RunRecord {
    /// The scenario's name.
    pub scenario: String,
    /// Which pose the mapper used: a `--pose` name.
    pub pose_mode: String,
    /// The corrections the filter should learn, when the scenario is known.
    pub true_calibration: Option<TrueCalibration>,
    /// A row per tick.
    pub ticks: Vec<TickRecord>,
    /// The final map.
    pub map: MapSnapshot,
    /// The world under it.
    pub world: WorldOutline,
}

impl RunRecord {
    /// The true pose at each tick, in tick order, as the emulator's harness records it.
    pub fn truth_samples(&self) -> Vec<TruthSample> {
        self.ticks
            .iter()
            .map(|t| TruthSample {
                t_s: t.t_s,
                x_mm: t.truth_mm.0,
                y_mm: t.truth_mm.1,
                heading_deg: t.truth_heading_deg,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heading_error(estimate_deg: f64, truth_deg: f64) -> f64 {
        let mut t = TickRecord::estimated(0.0, (0.0, 0.0), estimate_deg, 0.0, false);
        t.set_truth((0.0, 0.0), truth_deg);
        t.heading_error_deg
    }

    #[test]
    fn heading_errors_wrap_across_north() {
        // 1 degree is 2 degrees clockwise of 359, not 358 anticlockwise.
        assert!((heading_error(1.0, 359.0) - 2.0).abs() < 1e-9);
        assert!((heading_error(-179.0, 179.0) - 2.0).abs() < 1e-9);
        // The harness's truth is unwrapped: three turns and a bit.
        assert!((heading_error(-8.94, 1072.0) - -0.94).abs() < 1e-9);
        assert!((heading_error(10.0, 10.0)).abs() < 1e-9);
    }

    fn belief(xx: f64, xy: f64, yy: f64, hh_deg2: f64) -> Belief {
        Belief {
            xx_mm2: xx,
            xy_mm2: xy,
            yy_mm2: yy,
            hh_deg2,
            gyro_scale_ppm: 0.0,
            gyro_bias_mdps: 0.0,
            flow_scale_ppm: 0.0,
            tags: TagCounters::default().into(),
        }
    }

    #[test]
    fn a_belief_from_the_cores_units() {
        use slam_core::{Calibration, PoseCovariance};
        // 4 mm² is 4 * 256 in (1/16 mm)²; (1 degree)² in (2^-16 rad)².
        let rad_per_deg = std::f64::consts::PI / 180.0;
        let e = Estimate {
            covariance: PoseCovariance {
                xx: 4 * 256,
                xy: -256,
                yy: 9 * 256,
                hh: (rad_per_deg * 65536.0).powi(2).round() as i64,
                ..PoseCovariance::default()
            },
            calibration: Calibration {
                gyro_scale_ppm: -7444,
                gyro_bias_mdps: 20,
                flow_scale_ppm: 41_667,
            },
        };
        let b = Belief::new(&e, TagCounters::default());
        assert_eq!((b.xx_mm2, b.xy_mm2, b.yy_mm2), (4.0, -1.0, 9.0));
        assert!((b.hh_deg2 - 1.0).abs() < 1e-4, "{}", b.hh_deg2);
        assert!((b.bound_3sigma_heading_deg() - 3.0).abs() < 1e-4);
        assert_eq!(
            (b.gyro_scale_ppm, b.gyro_bias_mdps, b.flow_scale_ppm),
            (-7444.0, 20.0, 41_667.0)
        );
    }

    #[test]
    fn the_bound_is_the_worst_direction() {
        // Axis-aligned: the larger variance rules.
        let b = belief(100.0, 0.0, 400.0, 0.0);
        assert!((b.bound_3sigma_cm() - 3.0 * 20.0 / 10.0).abs() < 1e-9);
        let (big, small, angle) = b.position_axes();
        assert_eq!((big, small), (400.0, 100.0));
        assert!((angle.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        // Correlated: eigenvalues of [[5, 4], [4, 5]] are 9 and 1, along the diagonal.
        let (big, small, angle) = belief(5.0, 4.0, 5.0, 0.0).position_axes();
        assert!((big - 9.0).abs() < 1e-9 && (small - 1.0).abs() < 1e-9);
        assert!((angle - std::f64::consts::FRAC_PI_4).abs() < 1e-9);
        // Not positive definite: the smaller axis clamps to 0, nothing is NaN.
        let (_, small, _) = belief(1.0, 5.0, 1.0, -1.0).position_axes();
        assert_eq!(small, 0.0);
        assert_eq!(belief(1.0, 5.0, 1.0, -1.0).bound_3sigma_heading_deg(), 0.0);
    }

    #[test]
    fn true_corrections_undo_the_seeds_errors() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenarios/seed-mat.toml");
        let seed = Scenario::load(std::path::Path::new(path)).expect("the seed scenario");
        let t = TrueCalibration::of(&seed);
        // The flow reads 4 % short, the gyro 0.75 % long, with a 0.02 deg/s bias.
        assert!((t.flow_scale_ppm - 41_666.67).abs() < 0.01, "{t:?}");
        assert!((t.gyro_scale_ppm - -7_444.17).abs() < 0.01, "{t:?}");
        assert!((t.gyro_bias_mdps - 20.0).abs() < 1e-9, "{t:?}");
        // Corrected reading = true: (1 + e)(1 + c) = 1.
        let g = &seed.sensors.gyro;
        assert!(((1.0 + g.scale_error) * (1.0 + t.gyro_scale_ppm / 1e6) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn truth_fills_the_errors_and_the_wrapped_heading() {
        let mut t = TickRecord::estimated(1.0, (703.0, 504.0), 0.0, 5.0, true);
        assert!(t.error_cm.is_nan() && t.truth_mm.0.is_nan());
        t.set_truth((700.0, 500.0), 370.0);
        assert!((t.error_cm - 0.5).abs() < 1e-9);
        assert!((t.truth_heading_deg - 10.0).abs() < 1e-9);
        assert!((t.heading_error_deg - -10.0).abs() < 1e-9);
    }
}
