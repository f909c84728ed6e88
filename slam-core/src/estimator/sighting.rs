//! One tag sighting as a range-and-bearing update, gated by chi-square.

use super::covariance::{mul_shift, GAIN_SHIFT, N};
use super::filter::Estimator;
use super::units::{self, square, FINE_SHIFT};
use super::{State, TagRefusal};
use crate::angle::Angle;
use crate::frame::TagDetection;
use crate::pose::{hypot, Pose};
use crate::tagfix::{CameraConfig, KnownTag};

/// A tag nearer than this, millimetres, is treated as this far in the bearing's Jacobian
/// (whose entries grow as one over the range).
const MIN_JACOBIAN_RANGE_MM: i64 = 50;

/// `h a` for a sparse Q16 row `h`.
fn dot(h: &[(State, i64)], a: &[i64; N]) -> i64 {
    h.iter().fold(0i64, |sum, &(j, v)| {
        sum.saturating_add(mul_shift(a[j as usize], v, 16))
    })
}

/// `nu^2 / s` in Q8, saturating.
fn normalised_square_q8(nu: i64, s: i64) -> i64 {
    nu.saturating_mul(nu).saturating_mul(1 << 8) / s.max(1)
}

impl Estimator {
    /// Updates the filter from one detection of `tag` (`None`: an id not in the map),
    /// seen from `then`, the pose believed when the picture was taken (`None`: older
    /// than the history). Returns the corrected pose of that moment, or why the
    /// detection was refused; refusals are counted by cause.
    pub fn sight(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
    ) -> Result<Pose, TagRefusal> {
        let outcome = self.try_sight(detection, tag, camera, then);
        let c = &mut self.counters;
        let counter = match outcome {
            Ok(_) => &mut c.used,
            Err(TagRefusal::UnknownId) => &mut c.unknown_id,
            Err(TagRefusal::Behind) => &mut c.behind,
            Err(TagRefusal::TooFar) => &mut c.too_far,
            Err(TagRefusal::TooOld) => &mut c.too_old,
            Err(TagRefusal::Gate) => &mut c.gate,
        };
        *counter = counter.saturating_add(1);
        outcome
    }

    fn try_sight(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
    ) -> Result<Pose, TagRefusal> {
        let cfg = self.config;
        let tag = tag.ok_or(TagRefusal::UnknownId)?;
        if detection.distance_mm > cfg.max_range_mm {
            return Err(TagRefusal::TooFar);
        }
        let then = then.ok_or(TagRefusal::TooOld)?;

        // Where the tag should be seen from `then`.
        let dx_um = i64::from(tag.x_mm) * 1000 - i64::from(then.x_um);
        let dy_um = i64::from(tag.y_mm) * 1000 - i64::from(then.y_um);
        let range_um = hypot(dx_um, dy_um).min(i64::MAX as u64) as i64;
        let direction = Angle::of_vector(dx_um, dy_um);
        let predicted = direction - then.heading;
        let half_view = Angle::from_millidegrees(i64::from(cfg.half_view_mdeg));
        if predicted.signed_bits().unsigned_abs() > half_view.bits() {
            return Err(TagRefusal::Behind);
        }

        // Innovations: range in position units, bearing in heading units.
        let nu_range = i64::from(detection.distance_mm) * units::POSITION_PER_MM
            - units::position_from_um(range_um);
        let seen = camera.bearing(detection.cx_centipx);
        let nu_bearing = units::heading_from_bits(i64::from(seen.diff(predicted)));

        // Jacobians, Q16: the range falls as the robot moves towards the tag, the bearing
        // turns as it moves across the line of sight and against the heading.
        let (sin, cos) = (i64::from(direction.sin()), i64::from(direction.cos()));
        let range_mm = ((range_um * 1049) >> 20).max(MIN_JACOBIAN_RANGE_MM);
        // d(bearing)/dx is -cos / range: heading units per position unit, 2^16 / 16 per
        // radian per millimetre.
        let across = |trig: i64| (trig << 12) / range_mm;
        let h_range = [(State::X, -sin), (State::Y, -cos)];
        let h_bearing = [
            (State::X, -across(cos)),
            (State::Y, across(sin)),
            (State::Heading, -(1 << 16)),
        ];

        let range_sigma_mm = i64::from(cfg.range_noise_mm)
            + ((range_mm * i64::from(cfg.range_noise_permille) * 1049) >> 20);
        let r_range = square(range_sigma_mm * units::POSITION_PER_MM);
        let r_bearing = square(units::heading_from_mdeg(i64::from(cfg.bearing_noise_mdeg)));

        let a_range = self.p.times_row(&h_range);
        let a_bearing = self.p.times_row(&h_bearing);
        let s_range = dot(&h_range, &a_range).saturating_add(r_range);
        let s_cross = dot(&h_range, &a_bearing);
        let s_bearing = dot(&h_bearing, &a_bearing).saturating_add(r_bearing);
        if s_range <= 0 {
            return Err(TagRefusal::Gate);
        }
        // The bearing given the range: what is left of it once the range is known.
        let c = gain_q16(s_cross, s_range);
        let nu_bearing = nu_bearing.saturating_sub(mul_shift(c, nu_range, 16));
        let s_bearing = s_bearing.saturating_sub(mul_shift(c, s_cross, 16));
        let mut a_given = a_bearing;
        for (a, r) in a_given.iter_mut().zip(a_range) {
            *a = a.saturating_sub(mul_shift(c, r, 16));
        }
        if s_bearing <= 0 {
            return Err(TagRefusal::Gate);
        }
        let chi2 = normalised_square_q8(nu_range, s_range)
            .saturating_add(normalised_square_q8(nu_bearing, s_bearing));
        if chi2 > i64::from(cfg.gate_chi2_q8) {
            return Err(TagRefusal::Gate);
        }

        let mut fine = [0i64; N];
        for (a, s, nu) in [
            (&a_range, s_range, nu_range),
            (&a_given, s_bearing, nu_bearing),
        ] {
            let Some(k) = self.p.update(a, s) else {
                return Err(TagRefusal::Gate);
            };
            for (f, k) in fine.iter_mut().zip(k) {
                *f = f.saturating_add(mul_shift(k, nu, GAIN_SHIFT - FINE_SHIFT));
            }
        }
        self.bound();
        let [fx, fy, fh, gs, gb, fs] = fine;
        self.correct_calibration([gs, gb, fs]);
        let shift = |um: i32, fine: i64| {
            (i64::from(um) + units::um_from_fine_position(fine))
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32
        };
        Ok(Pose {
            x_um: shift(then.x_um, fx),
            y_um: shift(then.y_um, fy),
            heading: then.heading + Angle::from_bits(units::bits_from_fine_heading(fh) as u32),
        })
    }
}

/// `a / s` in Q16, rounded; `s > 0`.
fn gain_q16(a: i64, s: i64) -> i64 {
    let num = a.saturating_mul(1 << 16);
    let half = s / 2;
    if num >= 0 {
        num.saturating_add(half) / s
    } else {
        num.saturating_sub(half) / s
    }
}
