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
use crate::frame::{DepthScan, SensorFrame, BEAMS};
use crate::plausible::Trust;

/// A wall fitted to one scan: where it is and how it faces the nose.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct WallFit {
    /// Its distance from the sensor, along its normal, millimetres.
    pub distance_mm: i32,
    /// The cosine of the angle between the nose and its normal, Q16.
    pub cos_q16: i32,
    /// Its normal's bearing from the nose, clockwise: as the robot turns clockwise, a
    /// wall's tilt falls by as much ([`crate::wall_turn`]).
    pub tilt: Angle,
    /// The ends it was fitted to.
    pub ends: u8,
    /// Their root mean square stray from it, millimetres.
    pub stray_mm: u16,
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

/// A tick drove straight when the gyro turned slower than this, millidegrees a second: a
/// robot holding its course, not one turning.
pub const STRAIGHT_MDPS: u32 = 2_000;

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
    // Within 2^43 (eight ends within 4 m, Q8), so the shift stays in 64 bits.
    let b = sxy.checked_mul(1 << 16)? / sxx;
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
        // The normal (-b, 1): y = a + b x is x sin(tilt) + y cos(tilt) = distance.
        tilt: Angle::of_vector(-b, 1 << 16),
        ends: count as u8,
        // The mean square is within the limit's (Q16), so its root is a few mm.
        stray_mm: (((total / count) as u64).isqrt() >> 8) as u16,
    }))
}

/// The drives judged since start: their measurements taken by the filter, refused
/// (beyond its gate, or moving the pose too far even when believed least), and left
/// aside because it already knew the scale better.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WallCounters {
    /// Measurements the filter took.
    pub taken: u32,
    /// Measurements it refused.
    pub refused: u32,
    /// Measurements it did not need.
    pub known: u32,
}

/// The drive under way: its ticks' nominal distance driven and wall distance, as a
/// running mean and co-moments (Welford's), which stay small where plain sums of
/// squares would not fit 64 bits.
#[derive(Clone, Copy, Debug)]
pub struct WallRate {
    /// The drives judged so far, by outcome.
    pub counters: WallCounters,
    ticks: u32,
    /// The nominal distance driven since the drive began, micrometres.
    driven_um: i64,
    /// The last tick's wall distance, millimetres, and the first tick's cosine, Q16.
    last_mm: i64,
    first_cos: i64,
    /// Means of the distance driven `u` and the wall's distance `v`, Q16 millimetres,
    /// and of the cosines, Q16.
    mean_u: i64,
    mean_v: i64,
    cos_sum: i64,
    /// Co-moments `sum (u - mean u)(v - mean v)` and so on, Q8 square millimetres.
    c_uu: i64,
    c_uv: i64,
    c_vv: i64,
}

impl WallRate {
    /// No drive under way, none judged yet (for a `static`).
    pub const fn new() -> WallRate {
        WallRate {
            counters: WallCounters {
                taken: 0,
                refused: 0,
                known: 0,
            },
            ticks: 0,
            driven_um: 0,
            last_mm: 0,
            first_cos: 0,
            mean_u: 0,
            mean_v: 0,
            cos_sum: 0,
            c_uu: 0,
            c_uv: 0,
            c_vv: 0,
        }
    }
}

impl Default for WallRate {
    fn default() -> WallRate {
        WallRate::new()
    }
}

/// The most ticks one drive takes (a minute): past it the drive is judged and another
/// begins, so that its sums stay within 64 bits.
const MAX_TICKS: u32 = 600;

impl WallRate {
    /// Takes a tick of `frame`, of the inputs `trust` does not doubt: the flow's nominal
    /// distance (`flow_um_per_count_q16`, its calibration not applied) and, driving
    /// straight (the gyro's rate under [`STRAIGHT_MDPS`]), the wall fitted to its scan
    /// (`fitted`: [`fit_wall`] of the frame's scan, asked for only then, so that a caller
    /// that fits it for another check too fits it once); as [`WallRate::tick`].
    pub fn observe(
        &mut self,
        frame: &SensorFrame,
        flow_um_per_count_q16: i32,
        fitted: impl FnOnce() -> Option<WallFit>,
        trust: &Trust,
    ) -> Option<FlowScale> {
        let straight = trust.gyro.is_none()
            && frame
                .gyro
                .is_some_and(|g| g.rate_mdps.unsigned_abs() < STRAIGHT_MDPS);
        let per_count = i64::from(flow_um_per_count_q16);
        let forward = frame
            .flow
            .filter(|_| trust.flow.is_none())
            .map(|f| (i64::from(f.forward_counts) * per_count) >> 16);
        let wall = match (straight, forward, &frame.depth) {
            (true, Some(_), Some(_)) if trust.depth.is_none() => fitted(),
            _ => None,
        };
        let forward_um = forward.map_or(0, |f| f.clamp(i32::MIN.into(), i32::MAX.into()) as i32);
        self.tick(forward_um, wall)
    }

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
            Some(w) if self.ticks < MAX_TICKS => {
                if self.ticks > 0 {
                    self.driven_um += i64::from(forward_um);
                }
                self.add(w);
                None
            }
            _ => {
                let judged = self.judge();
                *self = WallRate {
                    counters: self.counters,
                    ..WallRate::default()
                };
                // A wall that jumped starts a drive of its own.
                if let Some(w) = wall {
                    self.add(w);
                }
                judged
            }
        }
    }

    fn add(&mut self, w: WallFit) {
        if self.ticks == 0 {
            self.first_cos = i64::from(w.cos_q16);
        }
        self.ticks += 1;
        self.last_mm = i64::from(w.distance_mm);
        self.cos_sum += i64::from(w.cos_q16);
        // Within 2^31 mm driven (a minute at the drive's speed is under 2^15), Q16.
        let u = (self.driven_um / 1000).clamp(-(1 << 30), 1 << 30) << 16;
        let v = self.last_mm << 16;
        let n = i64::from(self.ticks);
        let du = u - self.mean_u;
        let dv = v - self.mean_v;
        self.mean_u += du / n;
        self.mean_v += dv / n;
        // Each product of two deviations taken to Q8 first, then back to Q8: a drive of
        // a minute is under 2^15 mm and a wall under 2^12 mm away, so each product is
        // within 2^46 and a minute's sums within 2^47.
        let (eu, ev) = (u - self.mean_u, v - self.mean_v);
        self.c_uu += ((du >> 8) * (eu >> 8)) >> 8;
        self.c_uv += ((du >> 8) * (ev >> 8)) >> 8;
        self.c_vv += ((dv >> 8) * (ev >> 8)) >> 8;
    }

    /// The drive so far, judged: the flow's scale from the slope of the wall's distance
    /// against the distance driven, `-(1 + scale) cos`, and its deviation from the
    /// scatter about that slope.
    fn judge(&self) -> Option<FlowScale> {
        if self.ticks < MIN_TICKS || self.driven_um.abs() < MIN_DRIVEN_UM || self.c_uu <= 0 {
            return None;
        }
        let n = i64::from(self.ticks);
        let cos = self.cos_sum / n; // Q16
        if cos <= 0 {
            return None;
        }
        // The slope, Q20 (a drive so long that the product leaves 64 bits is not judged).
        let slope = self.c_uv.checked_mul(1 << 20)? / self.c_uu;
        // 1 + scale = -slope / cos, Q20, then in ppm.
        let ratio = -slope * (1 << 16) / cos;
        let scale_ppm = ((ratio * 1_000_000) >> 20) - 1_000_000;
        // The scatter about the slope: rss = c_vv - slope c_uv (Q8); the slope's variance
        // rss / ((n - 2) c_uu), in ppm^2 (the Q8s cancel).
        let rss = (self.c_vv - ((slope * (self.c_uv >> 4)) >> 16)).max(0);
        let var_ppm2 = rss.saturating_mul(1_000_000_000_000) / ((n - 2) * self.c_uu);
        let sd = (var_ppm2 as u64).isqrt() as i64 * (1 << 16) / cos;
        let sd_ppm = sd.saturating_mul(SD_WIDENING).max(MIN_SD_PPM);
        Some(FlowScale {
            scale_ppm: i32::try_from(scale_ppm).ok()?,
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
            let tilt_mdeg = f64::from(fit.tilt.to_millidegrees());
            assert!(
                (tilt_mdeg - tilt * 1000.0).abs() < 50.0,
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
