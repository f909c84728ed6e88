//! The flow sensor's scale from a wall ahead: how fast the wall comes closer against how
//! far the flow says the robot drove.
//!
//! Driving straight at a flat wall, the wall's distance shrinks by the distance driven
//! times the cosine of the angle between the nose and the wall's normal. The fan's eight
//! ends on the wall lie on a line; fitted each tick, the line gives the wall's distance
//! and that cosine. Over a drive, the slope of the distance against the flow's own
//! (nominal) distance is minus the flow's true scale times the cosine: a measurement of
//! the flow sensor's scale error with no map, no tags and no grid cell's coarseness in it.
//! The map only knows a wall to a cell (5 cm), which over a metre's drive is the whole of
//! the seed's 4 % scale error; the ranges know it to millimetres.
//!
//! A tick counts when the caller says the robot drove straight (no turn to speak of) and
//! the ends fit one line closely, the wall within [`MAX_WALL_ANGLE_Q16`] of square; a
//! drive is judged when such ticks stop, if it was long enough.

use crate::angle::Angle;
use crate::frame::{DepthScan, BEAMS};

/// A wall fitted to one scan: where it is and how it faces the nose.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct WallFit {
    /// Its distance from the sensor, along its normal, millimetres.
    pub distance_mm: i32,
    /// The cosine of the angle between the nose and its normal, Q16.
    pub cos_q16: i32,
}

/// A drive's measurement of the flow sensor's scale.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct FlowScale {
    /// The correction to the flow's nominal scale, parts per million: the true
    /// displacement is the nominal one times `1 + scale_ppm / 1e6`.
    pub scale_ppm: i32,
    /// Its standard deviation, parts per million.
    pub sd_ppm: i32,
    /// The drive's nominal length, millimetres.
    pub driven_mm: i32,
    /// The ticks it was judged on.
    pub ticks: u32,
}

/// The fewest ends a wall is fitted to.
const MIN_ENDS: usize = 6;

/// The most the ends may stray from their line, root mean square, millimetres: a flat
/// wall within the sensor's noise at a few metres.
const MAX_STRAY_MM: i64 = 12;

/// How far off square the wall may be: the slope of its line across the nose, Q16 (0.75:
/// 37 degrees). Beyond, the fan's ends are spread along the wall and its distance is
/// poorly known.
pub const MAX_WALL_ANGLE_Q16: i64 = 49_152;

/// How far a wall's distance may move in a tick and still be the same wall, millimetres;
/// and how far the cosine of its angle to the nose from the drive's first tick's, Q16
/// (0.02: a wall turning 11 degrees from square, 1.2 from 20 degrees off).
const MAX_STEP_MM: i64 = 60;
const MAX_TURN_COS_Q16: i64 = 1_311;

/// The fewest ticks and the shortest nominal drive judged.
const MIN_TICKS: u32 = 20;
const MIN_DRIVEN_UM: i64 = 300_000;

/// The least standard deviation a drive is given, ppm; and how much wider than its own
/// scatter says: a tick's distance errs with the ends it happens to catch, and those
/// change slowly along a drive, so neighbouring ticks' errors are not independent.
const MIN_SD_PPM: i64 = 1_500;
const SD_WIDENING: i64 = 2;

/// Fits a wall to `scan`'s ends, each along its beam at `beam_angles` from the nose; `None`
/// unless at least six ends lie on one line close to square to the nose. An end off the
/// line (a tag's card before the wall, a box's edge) is dropped and the rest fitted
/// again, once.
pub fn fit_wall(scan: &DepthScan, beam_angles: &[Angle; BEAMS]) -> Option<WallFit> {
    // The ends in the sensor's frame, Q8 millimetres: x across (right), y along the nose.
    let mut x = [0i64; BEAMS];
    let mut y = [0i64; BEAMS];
    let mut n = 0usize;
    for (range, beam) in scan.ranges_mm.iter().zip(beam_angles) {
        let Some(r) = range else { continue };
        let (sin, cos) = beam.sin_cos();
        x[n] = (i64::from(*r) * i64::from(sin)) >> 8;
        y[n] = (i64::from(*r) * i64::from(cos)) >> 8;
        n += 1;
    }
    for _ in 0..2 {
        if n < MIN_ENDS {
            return None;
        }
        match line(&x[..n], &y[..n])? {
            Line::Fits(fit) => return Some(fit),
            Line::Strays(worst) => {
                // Drop the end furthest off the line.
                x.copy_within(worst + 1..n, worst);
                y.copy_within(worst + 1..n, worst);
                n -= 1;
            }
        }
    }
    None
}

/// A least-squares line through some ends: the wall it is, or the end furthest off it.
enum Line {
    Fits(WallFit),
    Strays(usize),
}

/// `y = a + b x` by least squares through the ends `(x, y)` (Q8 millimetres); `None` if
/// they do not make a line close to square to the nose.
fn line(x: &[i64], y: &[i64]) -> Option<Line> {
    let count = x.len() as i64;
    let mx = x.iter().sum::<i64>() / count;
    let my = y.iter().sum::<i64>() / count;
    let sxx: i64 = x.iter().map(|v| (v - mx) * (v - mx)).sum();
    let sxy: i64 = x.iter().zip(y).map(|(u, v)| (u - mx) * (v - my)).sum();
    if sxx <= 0 {
        return None;
    }
    let b = i64::try_from((i128::from(sxy) << 16) / i128::from(sxx)).ok()?;
    // Each end's stray from the line, squared, Q16; the root mean square within the
    // limit.
    let strays = x.iter().zip(y).map(|(u, v)| {
        let off = v - my - ((b * (u - mx)) >> 16);
        off * off
    });
    let (mut total, mut worst, mut worst_at) = (0i64, -1i64, 0usize);
    for (i, s) in strays.enumerate() {
        total += s;
        if s > worst {
            (worst, worst_at) = (s, i);
        }
    }
    if total > ((MAX_STRAY_MM * MAX_STRAY_MM) << 16) * count {
        return Some(Line::Strays(worst_at));
    }
    if b.abs() > MAX_WALL_ANGLE_Q16 {
        return None;
    }
    // The line's distance from the sensor: its crossing of the nose times the cosine of
    // its slope, cos = 1 / sqrt(1 + b^2).
    let a = my - ((b * mx) >> 16);
    let root = ((1u64 << 32) + (b * b) as u64).isqrt() as i64; // sqrt(1 + b^2), Q16
    let cos_q16 = (1i64 << 32) / root;
    let distance = (a * cos_q16) >> 24;
    if distance <= 0 {
        return None;
    }
    Some(Line::Fits(WallFit {
        distance_mm: i32::try_from(distance).ok()?,
        cos_q16: i32::try_from(cos_q16).ok()?,
    }))
}

/// The drive under way: its ticks' nominal distance driven and wall distance, as sums.
#[derive(Clone, Copy, Debug, Default)]
pub struct WallRate {
    ticks: u32,
    /// The nominal distance driven since the drive began, micrometres.
    driven_um: i64,
    /// The last tick's wall distance, millimetres, and the first tick's cosine, Q16.
    last_mm: i64,
    first_cos: i64,
    /// Sums over the drive's ticks of the driven distance `u` (millimetres), the wall's
    /// distance `v` (millimetres), their squares and product, and the cosines (Q16).
    su: i64,
    sv: i64,
    suu: i64,
    svv: i64,
    suv: i64,
    scos: i64,
}

impl WallRate {
    /// Takes a tick: `forward_um`, the nominal distance the flow says the robot drove
    /// since the last (its calibration not applied), and `wall`, the wall fitted to the
    /// tick's scan if the robot drove straight and one fitted. Returns the drive's
    /// measurement when a drive long enough ends with this tick.
    pub fn tick(&mut self, forward_um: i32, wall: Option<WallFit>) -> Option<FlowScale> {
        let same_wall = |w: &WallFit| {
            self.ticks == 0
                || ((i64::from(w.distance_mm) - self.last_mm).abs() <= MAX_STEP_MM
                    && (i64::from(w.cos_q16) - self.first_cos).abs() <= MAX_TURN_COS_Q16)
        };
        match wall.filter(same_wall) {
            Some(w) => {
                if self.ticks > 0 {
                    self.driven_um += i64::from(forward_um);
                }
                self.add(w);
                None
            }
            None => {
                let judged = self.judge();
                *self = WallRate::default();
                // A wall that jumped starts a drive of its own.
                if let Some(w) = wall {
                    self.add(w);
                }
                judged
            }
        }
    }

    fn add(&mut self, w: WallFit) {
        let u = self.driven_um / 1000;
        let v = i64::from(w.distance_mm);
        if self.ticks == 0 {
            self.first_cos = i64::from(w.cos_q16);
        }
        self.ticks += 1;
        self.last_mm = v;
        self.su += u;
        self.sv += v;
        self.suu += u * u;
        self.svv += v * v;
        self.suv += u * v;
        self.scos += i64::from(w.cos_q16);
    }

    /// The drive so far, judged: the flow's scale from the slope of the wall's distance
    /// against the distance driven, `-(1 + scale) cos`.
    fn judge(&self) -> Option<FlowScale> {
        if self.ticks < MIN_TICKS || self.driven_um.abs() < MIN_DRIVEN_UM {
            return None;
        }
        let n = i128::from(self.ticks);
        let suu = n * i128::from(self.suu) - i128::from(self.su) * i128::from(self.su);
        let suv = n * i128::from(self.suv) - i128::from(self.su) * i128::from(self.sv);
        let svv = n * i128::from(self.svv) - i128::from(self.sv) * i128::from(self.sv);
        if suu <= 0 {
            return None;
        }
        let cos = i128::from(self.scos) / n; // Q16
        if cos <= 0 {
            return None;
        }
        // 1 + scale = -slope / cos, slope = suv / suu: in ppm.
        let ratio_ppm = -suv * 1_000_000 * 65_536 / (suu * cos);
        let scale_ppm = i32::try_from(ratio_ppm - 1_000_000).ok()?;
        // The slope's standard deviation: the scatter about the line over the spread
        // driven, sqrt(rss / (n - 2) / Suu) with rss = (svv - suv^2 / suu) / n.
        let rss_n = svv - suv * suv / suu; // n times the residual sum of squares
        let var_slope_ppm2 = rss_n.max(0) * 1_000_000 * 1_000_000 / ((n - 2) * suu);
        let sd = (u128::try_from(var_slope_ppm2).ok()?.isqrt() as i128) * 65_536 / cos;
        let sd_ppm = (i64::try_from(sd).ok()? * SD_WIDENING).max(MIN_SD_PPM);
        Some(FlowScale {
            scale_ppm,
            sd_ppm: i32::try_from(sd_ppm).ok()?,
            driven_mm: i32::try_from(self.driven_um / 1000).ok()?,
            ticks: self.ticks,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::slam::fan;

    /// The scan of a flat wall `distance` ahead whose normal is `tilt_deg` off the nose.
    fn wall_scan(distance: f64, tilt_deg: f64) -> DepthScan {
        let mut scan = DepthScan::default();
        for (r, beam) in scan.ranges_mm.iter_mut().zip(fan(45_000)) {
            let angle = f64::from(beam.to_millidegrees()) / 1000.0 - tilt_deg;
            *r = Some((distance / angle.to_radians().cos()).round() as u16);
        }
        scan
    }

    #[test]
    fn a_flat_wall_is_fitted_where_it_is() {
        for (distance, tilt) in [(500.0, 0.0), (1500.0, 20.0), (3000.0, -30.0)] {
            let fit = fit_wall(&wall_scan(distance, tilt), &fan(45_000)).unwrap();
            assert!(
                (f64::from(fit.distance_mm) - distance).abs() <= 2.0,
                "{fit:?} for {distance}"
            );
            let cos = f64::from(fit.cos_q16) / 65_536.0;
            assert!(
                (cos - f64::to_radians(tilt).cos()).abs() < 1e-3,
                "{fit:?} for {tilt}"
            );
        }
        // Too far off square, or too few ends: no wall.
        assert_eq!(fit_wall(&wall_scan(1000.0, 45.0), &fan(45_000)), None);
        let mut sparse = wall_scan(1000.0, 0.0);
        sparse.ranges_mm[..3].fill(None);
        assert_eq!(fit_wall(&sparse, &fan(45_000)), None);
        // A card 5 cm before the wall: its end dropped, the wall fitted.
        let mut carded = wall_scan(1000.0, 0.0);
        carded.ranges_mm[3] = Some(950);
        let fit = fit_wall(&carded, &fan(45_000)).unwrap();
        assert!((fit.distance_mm - 1000).abs() <= 2, "{fit:?}");
        // A box taking half the fan: the ends are not one line.
        let mut boxed = wall_scan(1000.0, 0.0);
        boxed.ranges_mm[..4].fill(Some(600));
        assert_eq!(fit_wall(&boxed, &fan(45_000)), None);
    }

    #[test]
    fn a_drive_at_a_wall_measures_the_flow_scale() {
        // The flow reads 4 % short: 8.3 mm a tick nominal for 8.65 true; the wall 20
        // degrees off square.
        let truth = 1.0 / 0.96 - 1.0;
        let mut rate = WallRate::default();
        let mut distance = 1500.0;
        let mut got = None;
        for tick in 0..80 {
            let wall = (tick < 79).then(|| fit_wall(&wall_scan(distance, 20.0), &fan(45_000)));
            got = rate.tick(8_300, wall.flatten());
            distance -= 8.3 * (1.0 + truth) * f64::to_radians(20.0).cos();
        }
        let got = got.unwrap();
        assert!(
            (f64::from(got.scale_ppm) - truth * 1e6).abs() <= 1_000.0,
            "{got:?}"
        );
        assert_eq!(got.ticks, 79);
        // A drive too short says nothing.
        let mut rate = WallRate::default();
        for _ in 0..10 {
            assert_eq!(
                rate.tick(8_300, fit_wall(&wall_scan(1000.0, 0.0), &fan(45_000))),
                None
            );
        }
        assert_eq!(rate.tick(8_300, None), None);
    }
}
