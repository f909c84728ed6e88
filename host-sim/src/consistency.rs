//! How well the filter knows its own error: its 3-sigma bounds against the true error, the
//! calibration it learned and what it made of the tags, as `run --json` and
//! `view --truth --json` report them under `estimator`.
//!
//! Worked out once, from a run's ticks, so that the simulator's run and a robot's telemetry
//! (scored against the emulator's truth) are judged by the same code.

use crate::record::{Belief, TickRecord, TrueCalibration};
use serde::Serialize;
use slam_core::TagCounters;

/// The filter's figures over a run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct EstimatorFigures {
    /// 3 sigma of the position at the end, along its worst direction, centimetres.
    pub bound_3sigma_cm: f64,
    /// 3 sigma of the heading at the end, degrees.
    pub bound_3sigma_heading_deg: f64,
    /// Share of the ticks scored whose true position error lies inside that tick's
    /// position bound, percent; `None` without a truth.
    pub inside_3sigma_pct: Option<f64>,
    /// Likewise for the heading error and the heading bound, percent.
    pub inside_3sigma_heading_pct: Option<f64>,
    /// Median of every tick's position bound, centimetres.
    pub median_bound_cm: f64,
    /// Median of every scored tick's true position error, centimetres; `None` without a
    /// truth. The issue asks for `median_bound_cm <= 4 * median_error_cm`.
    pub median_error_cm: Option<f64>,
    /// Ticks with a belief and a truth: the ones the shares count.
    pub ticks_scored: usize,
    /// The calibration learned by the end.
    pub calibration: CalibrationFigures,
    /// The corrections a perfect filter would have learned; known in the simulator, and
    /// in the viewer given the scenario.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub true_calibration: Option<TrueCalibration>,
    /// Tag sightings used and refused by the end.
    pub tags: TagFigures,
}

/// The learned calibration, as the core states it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CalibrationFigures {
    /// Gyro scale correction, ppm: true rate = (measured - bias) * (1 + ppm / 1e6).
    pub gyro_scale_ppm: f64,
    /// Gyro bias, millidegrees per second.
    pub gyro_bias_mdps: f64,
    /// Flow scale correction, ppm: true distance = nominal * (1 + ppm / 1e6).
    pub flow_scale_ppm: f64,
}

/// The tag sightings, used and refused by cause.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TagFigures {
    /// Sightings that updated the filter.
    pub used: u32,
    /// Sightings refused, by cause.
    pub refused: RefusedTags,
}

/// Refused sightings by cause (the core's [`TagCounters`] under their own names).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RefusedTags {
    /// Ids not in the tag map.
    pub unknown_id: u32,
    /// Listed place outside the view from the believed pose.
    pub behind: u32,
    /// Read further away than the camera can.
    pub too_far: u32,
    /// Pictures older than the pose history.
    pub too_old: u32,
    /// Refused by the chi-square gate.
    pub gate: u32,
}

impl From<TagCounters> for TagFigures {
    fn from(t: TagCounters) -> TagFigures {
        TagFigures {
            used: t.used,
            refused: RefusedTags {
                unknown_id: t.unknown_id,
                behind: t.behind,
                too_far: t.too_far,
                too_old: t.too_old,
                gate: t.gate,
            },
        }
    }
}

/// The filter's figures for `ticks`, in time order; `None` when no tick has a belief (the
/// run did not fly the filter). Ticks without a truth (NaN errors) count towards the
/// bounds but not the shares or the median error.
pub fn estimator_figures(
    ticks: &[TickRecord],
    true_calibration: Option<TrueCalibration>,
) -> Option<EstimatorFigures> {
    let last: &Belief = ticks.iter().rev().find_map(|t| t.belief.as_ref())?;
    let mut bounds = Vec::new();
    let mut errors = Vec::new();
    let (mut inside, mut inside_heading) = (0usize, 0usize);
    for (t, b) in ticks.iter().filter_map(|t| Some((t, t.belief?))) {
        let bound = b.bound_3sigma_cm();
        bounds.push(bound);
        if scored(t) {
            errors.push(t.error_cm);
            inside += usize::from(t.error_cm <= bound);
            inside_heading +=
                usize::from(t.heading_error_deg.abs() <= b.bound_3sigma_heading_deg());
        }
    }
    let scored = errors.len();
    let share = |n: usize| (scored > 0).then(|| 100.0 * n as f64 / scored as f64);
    Some(EstimatorFigures {
        bound_3sigma_cm: last.bound_3sigma_cm(),
        bound_3sigma_heading_deg: last.bound_3sigma_heading_deg(),
        inside_3sigma_pct: share(inside),
        inside_3sigma_heading_pct: share(inside_heading),
        median_bound_cm: median(&mut bounds).unwrap_or(f64::NAN),
        median_error_cm: median(&mut errors),
        ticks_scored: scored,
        calibration: CalibrationFigures {
            gyro_scale_ppm: last.gyro_scale_ppm,
            gyro_bias_mdps: last.gyro_bias_mdps,
            flow_scale_ppm: last.flow_scale_ppm,
        },
        true_calibration,
        tags: last.tags,
    })
}

/// Each scored tick's 3-sigma position bound and true position error, centimetres: the
/// ticks with a belief and a truth, which the shares and the median error count. Pooled
/// over many runs, the medians of the two judge the bound as the issue asks ("its median
/// is at most 4 times the median true error") over a scenario rather than one seed.
pub fn scored_bounds(ticks: &[TickRecord]) -> impl Iterator<Item = (f64, f64)> + '_ {
    ticks
        .iter()
        .filter(|t| scored(t))
        .filter_map(|t| Some((t.belief?.bound_3sigma_cm(), t.error_cm)))
}

/// Whether a tick has a truth to score against.
fn scored(t: &TickRecord) -> bool {
    t.error_cm.is_finite() && t.heading_error_deg.is_finite()
}

/// The median of `values` (the mean of the middle two for an even count); `None` when
/// empty. NaN sorts last.
pub fn median(values: &mut [f64]) -> Option<f64> {
    values.sort_by(|a, b| a.total_cmp(b));
    let n = values.len();
    match n {
        0 => None,
        _ if n % 2 == 1 => values.get(n / 2).copied(),
        _ => Some((values.get(n / 2 - 1)? + values.get(n / 2)?) / 2.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tick `error_cm` from the truth and `heading_error_deg` off, whose filter believes
    /// a round 3-sigma position bound of `bound_cm` and heading bound of `bound_deg`.
    fn tick(error_cm: f64, heading_error_deg: f64, bound: Option<(f64, f64)>) -> TickRecord {
        let mut t = TickRecord::estimated(0.0, (0.0, 0.0), heading_error_deg, 0.0, false);
        if error_cm.is_finite() {
            t.set_truth((error_cm * 10.0, 0.0), 0.0);
        }
        t.belief = bound.map(|(cm, deg)| Belief {
            // sigma = bound / 3, in mm, squared.
            xx_mm2: (cm * 10.0 / 3.0).powi(2),
            xy_mm2: 0.0,
            yy_mm2: 1.0,
            hh_deg2: (deg / 3.0).powi(2),
            gyro_scale_ppm: -7000.0,
            gyro_bias_mdps: 18.0,
            flow_scale_ppm: 41_000.0,
            tags: TagCounters {
                used: 9,
                gate: 2,
                ..TagCounters::default()
            }
            .into(),
        });
        t
    }

    #[test]
    fn no_belief_no_figures() {
        assert_eq!(estimator_figures(&[tick(1.0, 1.0, None)], None), None);
        assert_eq!(estimator_figures(&[], None), None);
    }

    #[test]
    fn shares_and_medians() {
        let ticks = [
            tick(0.5, 0.1, Some((1.0, 0.5))),      // inside both
            tick(1.5, 0.1, Some((1.0, 0.5))),      // position outside
            tick(0.2, -0.9, Some((2.0, 0.5))),     // heading outside
            tick(0.1, 0.0, Some((3.0, 1.0))),      // inside both
            tick(f64::NAN, 0.0, Some((4.0, 1.0))), // no truth: a bound, not scored
            tick(9.0, 9.0, None),                  // no belief: left out
        ];
        let f = estimator_figures(&ticks, None).expect("figures");
        assert_eq!(f.ticks_scored, 4);
        assert_eq!(f.inside_3sigma_pct, Some(75.0));
        assert_eq!(f.inside_3sigma_heading_pct, Some(75.0));
        assert!((f.bound_3sigma_cm - 4.0).abs() < 1e-9);
        assert!((f.bound_3sigma_heading_deg - 1.0).abs() < 1e-9);
        // Bounds 1, 1, 2, 3, 4: median 2. Errors 0.1, 0.2, 0.5, 1.5: median 0.35.
        assert!((f.median_bound_cm - 2.0).abs() < 1e-9);
        assert!((f.median_error_cm.unwrap_or(0.0) - 0.35).abs() < 1e-9);
        // The same four ticks, bound beside error.
        let pairs: Vec<(f64, f64)> = scored_bounds(&ticks).collect();
        assert_eq!(pairs.len(), 4);
        let (mut b, mut e): (Vec<f64>, Vec<f64>) = pairs.into_iter().unzip();
        assert_eq!(median(&mut b), Some(1.5));
        assert!((median(&mut e).unwrap_or(0.0) - 0.35).abs() < 1e-9);
        assert_eq!(f.calibration.flow_scale_ppm, 41_000.0);
        assert_eq!((f.tags.used, f.tags.refused.gate), (9, 2));
    }

    #[test]
    fn without_truth_the_shares_are_unknown() {
        let f = estimator_figures(&[tick(f64::NAN, 0.0, Some((1.0, 1.0)))], None).expect("figures");
        assert_eq!(f.ticks_scored, 0);
        assert_eq!((f.inside_3sigma_pct, f.median_error_cm), (None, None));
        let json = serde_json::to_value(f).expect("json");
        assert!(json["inside_3sigma_pct"].is_null());
        assert!(json.get("true_calibration").is_none());
        assert_eq!(json["tags"]["refused"]["gate"], 2);
    }
}
