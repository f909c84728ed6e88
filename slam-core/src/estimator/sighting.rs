//! One tag sighting as a range-and-bearing update, gated by chi-square.

use super::covariance::{GAIN_SHIFT, N};
use super::filter::Estimator;
use super::fixed::{fits_i32, mul_q16_unit, mul_shift, mul_shift_each, square, Reciprocal};
use super::step_limit::{share_of_move, TagShare};
use super::units::{self, FINE_SHIFT};
use super::{State, TagRefusal};
use crate::angle::{sin_cos_of_vector, Angle, TRIG_ONE};
use crate::frame::TagDetection;
use crate::pose::{hypot, mul_q16_32, Pose};
use crate::tagfix::{CameraConfig, KnownTag};

/// A tag nearer than this, millimetres, is treated as this far in the bearing's Jacobian
/// (whose entries grow as one over the range).
const MIN_JACOBIAN_RANGE_MM: i64 = 50;

/// A range innovation whose square over its variance is at most this (Q8: 100, ten
/// deviations) agrees with the tag's listed place ([`Estimator::refused_at_its_range`]).
const RANGE_AGREES_CHI2_Q8: i64 = 100 << 8;

/// The gate a doubted camera's sightings are held to ([`Estimator::doubt_camera`]), Q8:
/// 6.0, which 95 % of honest sightings pass (chi-square, 2 degrees of freedom). A camera
/// putting its tags a few pixels aside lies least at the picture's edge, where the lie
/// fits just inside the usual gate once the filter has grown unsure; taken, it draws the
/// filter towards the next.
const DOUBTED_GATE_CHI2_Q8: u32 = 1536;

/// How far past the picture's edge a tag's centre may be read, hundredths of a pixel: a
/// pixel, the detector's noise many times over. A tag is found only whole in the
/// picture, so its centre further out is no reading at all.
const PAST_EDGE_CENTIPX: u64 = 100;

/// Sines (Q16) below this, 0.1, take their angle from [`asin_small`].
const ASIN_SERIES_BELOW: i64 = 6554;

/// `asin(x) = x + x^3 / 6` in Q16 for `|x|` below [`ASIN_SERIES_BELOW`], where every
/// product fits 32 bits and the cube's sixth (below 70) is a multiply by `2^16 / 6`:
/// the M0+ has no divider.
fn asin_small(x: i32) -> i32 {
    let cube = (((x * x) >> 16) * x) >> 16;
    let sixth = (cube.abs() * 10_923) >> 16;
    x + if cube < 0 { -sixth } else { sixth }
}

/// Millimetres to micrometres: one 32-bit multiply for any place within 2 km (a 64-bit
/// multiply is a library call on the M0+), 64 bits past it.
fn um_of_mm(mm: i32) -> i64 {
    mm.checked_mul(1000)
        .map_or_else(|| i64::from(mm) * 1000, i64::from)
}

/// `h a` for a sparse Q16 row `h`.
fn dot(h: &[(State, i32)], a: &[i64; N]) -> i64 {
    h.iter().map(|&(j, v)| mul_q16_unit(a[j as usize], v)).sum()
}

/// `nu^2 / s` in Q8, saturating.
fn normalised_square_q8(nu: i64, s: &Reciprocal) -> i64 {
    if fits_i32(nu) {
        s.times(square(nu), 8)
    } else {
        i64::MAX
    }
}

/// The bearing's `P h^T`: the row across the line of sight's (`across`) over the range,
/// less the heading's column.
#[inline(always)]
fn bearing_p_h(across: &[i64; N], heading: [i64; N], per_range: &Reciprocal) -> [i64; N] {
    let mut a = per_range.times_each(across, 12);
    for (a, h) in a.iter_mut().zip(heading) {
        *a -= h;
    }
    a
}

/// The bearing's row times `a`: the unit row across the line of sight, `h_across`, over
/// the range, less the heading.
#[inline(always)]
fn bearing_of(a: &[i64; N], h_across: &[(State, i32); 2], per_range: &Reciprocal) -> i64 {
    per_range.times(dot(h_across, a), 12) - a[State::Heading as usize]
}

/// A predicted variance of the range, or of the bearing given the range (with their
/// noise; position or heading units squared), past which the sighting's two updates are
/// made in turn and to within a unit ([`Estimator::update_in_turn`]): 2^17, a range unsure
/// by 23 mm, a bearing by 0.3 degrees. Below it the `P h`s are small enough for one pass
/// in Q16.
const IN_TURN_ABOVE: i64 = 1 << 17;

/// Why [`Estimator::sight_fine`] took nothing.
enum NotTaken {
    /// The detection was refused.
    Refused(TagRefusal),
    /// It passed the gate, but its correction might move the position further than
    /// the share's step.
    MayStepFurther,
}

impl From<TagRefusal> for NotTaken {
    fn from(refusal: TagRefusal) -> NotTaken {
        NotTaken::Refused(refusal)
    }
}

impl Estimator {
    /// Whether a sighting of normalised innovation `chi2` (Q8) surely moves the position
    /// no further than `share`'s step: its correction `d` has `d' P^-1 d <= chi2`, so
    /// the position's part is at most `sqrt(chi2 l)` for `l` the largest variance of the
    /// position in any direction, at most the larger variance plus the covariance.
    /// In 32 bits: a variance past 2^20 (6.4 cm) or a chi-square past 16 is not surely
    /// within any share, and below both the product fits.
    #[inline(always)]
    fn surely_within(&self, chi2: i64, share: &TagShare) -> bool {
        let rows = self.p.rows();
        let (xx, yy, xy) = (
            rows[0][0] as u32,
            rows[1][1] as u32,
            rows[0][1].unsigned_abs(),
        );
        let widest = xx.max(yy).saturating_add(xy);
        widest < 1 << 20
            && (0..1 << 12).contains(&chi2)
            && widest * chi2 as u32 <= share.surely_within_q8
    }

    /// The range's update and then the bearing's, each from the covariance the one
    /// before left and each to within a unit
    /// ([`super::covariance::Covariance::update_precise`]): for a
    /// sighting whose range or bearing is so unsure that one pass, which conditions the
    /// bearing on the range through a Q16 ratio and takes each product as a Q16 gain
    /// times a `P h`, would leave the matrix units off where it takes away nearly all of
    /// a large variance. Given the range's `P h` and `1 / s`, the tag's direction, one
    /// over its range and the bearing's noise; returns both gains.
    #[cold]
    #[inline(never)]
    fn update_in_turn(
        &mut self,
        a_range: &[i64; N],
        inv_range: &Reciprocal,
        (sin, cos): (i32, i32),
        per_range: &Reciprocal,
        r_bearing: i64,
    ) -> [[i64; N]; 2] {
        // Each update alone: the pair's second is a zero `P h`, which takes nothing
        // whatever it is divided by.
        let none = [0; N];
        let [k_range, _] = self
            .p
            .update_precise([(a_range, inv_range), (&none, inv_range)]);
        let [_, across] = self.p.times_sight_rows(sin, cos);
        let a = bearing_p_h(&across, self.p.column(State::Heading), per_range);
        let h_across = [(State::X, -cos), (State::Y, sin)];
        let s = bearing_of(&a, &h_across, per_range).saturating_add(r_bearing);
        let k_bearing = match Reciprocal::of(s) {
            Some(inv) => self.p.update_precise([(&a, &inv), (&none, &inv)])[0],
            None => [0; N],
        };
        [k_range, k_bearing]
    }

    /// Holds the sightings that follow to a gate of 6.0 while `doubted` (95 % of honest
    /// sightings pass it): a camera blamed for the pictures the gate refused
    /// ([`crate::camera_check`]) is trusted again only on a sighting that plainly agrees.
    pub fn doubt_camera(&mut self, doubted: bool) {
        self.camera_doubted = doubted;
    }

    /// Whether the last sighting was refused by the gate for its bearing alone: read at
    /// the range its listed place has from the believed position. A heading gone wrong
    /// does that to every tag; a tag moved from its place mostly shows in its range.
    pub fn refused_at_its_range(&self) -> bool {
        self.refused_at_its_range
    }

    /// The bearing (heading units, given the range) and range (position units)
    /// innovations of the last sighting the gate refused.
    pub fn refused_by(&self) -> (i32, i32) {
        self.refused_by
    }

    /// Updates the filter from one detection of `tag` (`None`: an id not in the map),
    /// seen from `then`, the pose believed when the picture was taken (`None`: older
    /// than the history), moving the position at most `share`'s step (`None`: as far as
    /// the update says). Returns the corrected pose of that moment, or why the detection
    /// was refused; refusals are counted by cause.
    ///
    /// Inlined where it is called: the step calls it once a sighting, and a second
    /// call site (a late camera's retry) would otherwise leave it out of line.
    #[inline(always)]
    pub fn sight(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
        share: Option<&TagShare>,
    ) -> Result<Pose, TagRefusal> {
        let outcome = match self.try_sight(detection, tag, camera, then, share) {
            Ok(pose) => Ok(pose),
            Err(NotTaken::Refused(refusal)) => Err(refusal),
            Err(NotTaken::MayStepFurther) => {
                let step_um = share.map_or(u32::MAX, |share| share.step_um);
                self.sight_within(detection, tag, camera, then, step_um)
            }
        };
        self.count(outcome)
    }

    /// [`Estimator::sight`] for a sighting whose correction may be longer than `step_um`:
    /// taken, and if it moved the position further than that, taken back in part. A
    /// share `g` of the Kalman correction (of the pose and the calibration), with the
    /// covariance the Joseph form gives that gain, `P - g (2 - g) K S K'`, which is `P`
    /// moved the share `g (2 - g)` of the way to the full update's: the filter stays as
    /// unsure as the part it took leaves it, and the next pictures bring the rest.
    #[cold]
    #[inline(never)]
    fn sight_within(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
        step_um: u32,
    ) -> Result<Pose, TagRefusal> {
        let (p, calibration) = (self.p, self.calibration);
        let full = match self.try_sight(detection, tag, camera, then, None) {
            Ok(full) => full,
            Err(NotTaken::Refused(refusal)) => return Err(refusal),
            // Not asked for.
            Err(NotTaken::MayStepFurther) => return Err(TagRefusal::Gate),
        };
        let Some(then) = then else {
            return Ok(full);
        };
        let moved = (
            i64::from(full.x_um) - i64::from(then.x_um),
            i64::from(full.y_um) - i64::from(then.y_um),
        );
        let Some(share) = share_of_move(moved, step_um) else {
            return Ok(full);
        };
        let kept = (share * ((2 << 16) - share)) >> 16;
        self.p.move_from(&p, kept);
        for (now, was) in self.calibration.iter_mut().zip(calibration) {
            *now = was + mul_shift(*now - was, share, 16);
        }
        let part = |d: i64| mul_shift(d, share, 16) as i32;
        let turned = i64::from((full.heading - then.heading).signed_bits());
        Ok(Pose {
            x_um: then.x_um.saturating_add(part(moved.0)),
            y_um: then.y_um.saturating_add(part(moved.1)),
            heading: then.heading + Angle::from_bits(part(turned) as u32),
        })
    }

    /// Counts a sighting's outcome by cause, and passes it on.
    #[inline(always)]
    fn count(&mut self, outcome: Result<Pose, TagRefusal>) -> Result<Pose, TagRefusal> {
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

    #[inline(never)]
    fn try_sight(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
        share: Option<&TagShare>,
    ) -> Result<Pose, NotTaken> {
        let (then, fine) = self.sight_fine(detection, tag, camera, then, share)?;
        Ok(self.corrected(&then, fine))
    }

    /// The sighting's update: the filter updated, and the pose `then` it was seen from
    /// with the state's correction in fine units (not yet applied to the pose and the
    /// calibration). With a `share`, a sighting that passed the gate but whose
    /// correction might move the position further than the share's step changes
    /// nothing and says so.
    #[inline(always)]
    fn sight_fine(
        &mut self,
        detection: &TagDetection,
        tag: Option<&KnownTag>,
        camera: &CameraConfig,
        then: Option<Pose>,
        share: Option<&TagShare>,
    ) -> Result<(Pose, [i64; N]), NotTaken> {
        self.refused_at_its_range = false;
        let cfg = self.config;
        let tag = tag.ok_or(TagRefusal::UnknownId)?;
        if detection.distance_mm > cfg.max_range_mm {
            return Err(TagRefusal::TooFar.into());
        }
        let then = then.ok_or(TagRefusal::TooOld)?;

        // Where the tag should be seen from `then`, in position units (a tag within the
        // camera's reach is within 2^15 of them: a 32-bit root).
        let dx_um = um_of_mm(tag.x_mm) - i64::from(then.x_um);
        let dy_um = um_of_mm(tag.y_mm) - i64::from(then.y_um);
        let range = hypot(
            units::position_from_um(dx_um),
            units::position_from_um(dy_um),
        )
        .min(i64::MAX as u64) as i64;
        // Directions as sines and cosines (no CORDIC): the tag's from `then`, and its
        // bearing off the nose, the heading taken off by the angle-difference formulas.
        let clamp = |v: i64| v.clamp(-(i32::MAX as i64), i32::MAX as i64) as i32;
        let (sin, cos) = sin_cos_of_vector(clamp(dx_um), clamp(dy_um));
        let (sin_h, cos_h) = then.heading.sin_cos();
        // Each product rounds, so a sum can reach one unit past 1.0, which the products
        // below take as out of range: held within the unit circle.
        let unit = |v: i32| v.clamp(-TRIG_ONE, TRIG_ONE);
        let sin_b = unit(mul_q16_32(sin, cos_h) - mul_q16_32(cos, sin_h));
        let cos_b = unit(mul_q16_32(cos, cos_h) + mul_q16_32(sin, sin_h));
        if cfg.half_view_mdeg < 180_000 && cos_b < self.view_cos {
            return Err(TagRefusal::Behind.into());
        }

        // Innovations: range in position units, bearing in heading units. The bearing's
        // from the sine of the angle between the ray the camera saw and the predicted one:
        // asin(x) = x + x^3 / 6 to 1e-6 rad below 0.1 (as nearly every innovation is), the
        // angle itself by CORDIC past it; more than a quarter turn off is refused outright.
        let nu_range = i64::from(detection.distance_mm) * units::POSITION_PER_MM - range;
        // A column past the picture's edge (the centre column's own distance from it) is no
        // reading at all: refused outright, as the gate would refuse it, for its column
        // alone (it says nothing of the range, and a column no camera reads is the
        // camera's doing: a leap, [`crate::camera_check`]).
        let off_centre = i64::from(detection.cx_centipx) - i64::from(camera.centre_centipx);
        if off_centre.unsigned_abs()
            > u64::from(camera.centre_centipx.unsigned_abs()) + PAST_EDGE_CENTIPX
        {
            self.refused_at_its_range = true;
            self.refused_by = (i32::MAX, i32::MAX);
            return Err(TagRefusal::Gate.into());
        }
        let (sin_m, cos_m) = camera.ray(detection.cx_centipx);
        let sin_nu = i64::from(mul_q16_32(sin_m, cos_b) - mul_q16_32(cos_m, sin_b));
        let cos_nu = mul_q16_32(cos_m, cos_b) + mul_q16_32(sin_m, sin_b);
        if cos_nu <= 0 {
            self.refused_by = (i32::MAX, clamp(nu_range));
            return Err(TagRefusal::Gate.into());
        }
        let nu_bearing = if sin_nu.abs() < ASIN_SERIES_BELOW {
            i64::from(asin_small(sin_nu as i32))
        } else {
            units::heading_from_bits(i64::from(
                Angle::of_vector(sin_nu, i64::from(cos_nu)).signed_bits(),
            ))
        };

        // Jacobians, Q16: the range falls as the robot moves towards the tag, the bearing
        // turns as it moves across the line of sight and against the heading. The
        // bearing's row is `across / range` times a unit row, minus the heading:
        // d(bearing)/dx is -cos / range, in heading units per position unit 2^16 / 16 per
        // radian per millimetre.
        let range_mm = (range / units::POSITION_PER_MM).clamp(MIN_JACOBIAN_RANGE_MM, 1 << 20);
        let per_range = Reciprocal::of(range_mm).ok_or(TagRefusal::Gate)?;
        let h_range = [(State::X, -sin), (State::Y, -cos)];
        let h_across = [(State::X, -cos), (State::Y, sin)];
        let range_of = |a: &[i64; N]| dot(&h_range, a);

        // Range noise in position units: a constant part and a per-mille part.
        let noise = &self.sighting_noise;
        let range_sigma = noise.range_sigma
            + if noise.range_share_q16 == 0 {
                0
            } else {
                mul_shift(range, noise.range_share_q16, 16)
            };
        let r_range = square(range_sigma);
        // A pixel off the picture's centre spans a smaller angle: the column is
        // `focal tan(bearing)`, so the bearing's noise is the centre's times cos^2 (a
        // Q16 cosine below 1.0 squares in 32 bits).
        let cos_m_abs = cos_m.unsigned_abs();
        let cos2 = if cos_m_abs < 1 << 16 {
            i64::from((cos_m_abs * cos_m_abs) >> 16)
        } else {
            ((u64::from(cos_m_abs) * u64::from(cos_m_abs)) >> 16) as i64
        };
        let r_bearing = square(mul_shift(noise.bearing_sigma, cos2, 16)).max(1);

        let [a_range, across] = self.p.times_sight_rows(sin, cos);
        let a_bearing = bearing_p_h(&across, self.p.column(State::Heading), &per_range);
        let s_range = range_of(&a_range).saturating_add(r_range);
        let s_cross = range_of(&a_bearing);
        let s_bearing = bearing_of(&a_bearing, &h_across, &per_range).saturating_add(r_bearing);
        let Some(inv_range) = Reciprocal::of(s_range) else {
            return Err(TagRefusal::Gate.into());
        };
        // The bearing given the range: what is left of it once the range is known.
        let c = inv_range.times(s_cross, 16);
        let nu_bearing = nu_bearing.saturating_sub(mul_shift(c, nu_range, 16));
        let s_bearing = s_bearing.saturating_sub(mul_shift(c, s_cross, 16));
        let mut a_given = a_bearing;
        for (a, r) in a_given.iter_mut().zip(mul_shift_each(&a_range, c, 16)) {
            *a = a.saturating_sub(r);
        }
        let Some(inv_bearing) = Reciprocal::of(s_bearing) else {
            return Err(TagRefusal::Gate.into());
        };
        let range_chi2 = normalised_square_q8(nu_range, &inv_range);
        let chi2 = range_chi2.saturating_add(normalised_square_q8(nu_bearing, &inv_bearing));
        let gate = match self.camera_doubted {
            true => cfg.gate_chi2_q8.min(DOUBTED_GATE_CHI2_Q8),
            false => cfg.gate_chi2_q8,
        };
        if chi2 > i64::from(gate) && !self.ungated {
            self.refused_at_its_range = range_chi2 <= RANGE_AGREES_CHI2_Q8;
            self.refused_by = (clamp(nu_bearing), clamp(nu_range));
            return Err(TagRefusal::Gate.into());
        }
        if let Some(share) = share {
            if !self.surely_within(chi2, share) {
                return Err(NotTaken::MayStepFurther);
            }
        }
        self.ungated = false;

        let [k_range, k_bearing] = if s_range.max(s_bearing) > IN_TURN_ABOVE {
            self.update_in_turn(&a_range, &inv_range, (sin, cos), &per_range, r_bearing)
        } else {
            self.p
                .update([(&a_range, &inv_range), (&a_given, &inv_bearing)])
        };
        let mut fine = mul_shift_each(&k_range, nu_range, GAIN_SHIFT - FINE_SHIFT);
        let by_bearing = mul_shift_each(&k_bearing, nu_bearing, GAIN_SHIFT - FINE_SHIFT);
        for (f, b) in fine.iter_mut().zip(by_bearing) {
            *f = f.saturating_add(b);
        }
        Ok((then, fine))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn um_of_mm_is_the_64_bit_product() {
        for mm in [
            0,
            1,
            -1,
            2_147_483,
            -2_147_483,
            2_147_484,
            -2_147_484,
            i32::MAX,
            i32::MIN,
        ] {
            assert_eq!(um_of_mm(mm), i64::from(mm) * 1000, "{mm}");
        }
    }

    #[test]
    fn asin_small_is_the_series_divided() {
        for x in -(ASIN_SERIES_BELOW - 1)..ASIN_SERIES_BELOW {
            let want = x + ((((x * x) >> 16) * x) >> 16) / 6;
            assert_eq!(i64::from(asin_small(x as i32)), want, "{x}");
        }
    }
}
