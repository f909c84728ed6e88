//! The filter's state and its prediction from odometry.

use super::config::{self, EstimatorConfig};
use super::covariance::{Covariance, Entry, N};
use super::fixed::{fits_i32, mul_shift, square};
use super::units::{self, FINE_SHIFT};
use super::{Calibration, Estimate, PoseCovariance, State, TagCounters};
use crate::angle::Angle;
use crate::frame::GyroRate;
use crate::odometry::{Motion, OdometryConfig};
use crate::plausible::Known;
use crate::pose::Pose;

/// The covariance's floor: no variance ever reaches zero (a filter sure of anything
/// stops listening). Position 1/8 mm, heading 6e-5 rad, calibration one unit.
const FLOOR: [i32; N] = [4, 4, 16, 1, 1, 1];
/// Calibration beyond which the sensors are broken, not miscalibrated, in covariance
/// units: gyro scale 10 %, gyro bias 5 deg/s, flow scale 30 %. The learned values are held
/// within them, and their standard deviations are no wider.
const GYRO_SCALE_MAX: i32 = 6_554;
const GYRO_BIAS_MAX: i32 = 5_720;
const FLOW_SCALE_MAX: i32 = 19_661;

/// The heading's deviation after [`Estimator::forget_heading`], millidegrees.
pub const FORGOTTEN_HEADING_MDEG: i64 = 2_000;
/// The heading's least deviation after [`Estimator::heading_set_by_walls`], millidegrees:
/// a wall's tilt, fitted twice, errs by a few tenths of a degree.
pub const WALL_TURN_SD_MDEG: i64 = 1_000;
/// The heading's deviation after [`Estimator::heading_pinned_by_walls`], millidegrees:
/// the wall's first ticks' mean and its mean while the robot stood.
pub const WALL_HELD_SD_MDEG: i64 = 500;
/// The position's deviation within which the filter is sure enough of it to forget its
/// heading ([`Estimator::forget_heading`]), millimetres.
pub const SURE_POSITION_MM: i64 = 20;
/// The position's deviation after [`Estimator::forget_position`], millimetres.
pub const FORGOTTEN_POSITION_MM: i64 = 50;
/// The position's deviation within which the filter vouches for a pose to map a scan at
/// when nothing else ties the map to itself ([`Estimator::sure_enough_to_map`]),
/// millimetres: three deviations are 45 mm, inside a 5 cm cell.
pub const MAPPED_POSITION_SD_MM: i64 = 15;
/// The heading's deviation likewise, millidegrees: three deviations, 3 degrees, move a
/// wall a metre away by a cell.
pub const MAPPED_HEADING_SD_MDEG: i64 = 1_000;
/// The heading's deviation within which scans are mapped with matching
/// ([`Estimator::heading_matchable`]), millidegrees: at 5 degrees the truth lies outside
/// the 4 degrees either way the matches search two times in five, and they no longer keep
/// the pose on the map. No shipped world's route comes near it without a fault (4.1
/// degrees at most, room-10m before its first tag).
pub const MATCHED_HEADING_SD_MDEG: i64 = 5_000;
/// Updates after [`Estimator::forget_heading`] that settle the whole matrix.
const SETTLED_FULLY_AFTER_FORGETTING: u8 = 30;

/// The covariance's ceiling, as standard deviations: position 2.5 m, heading 34 degrees
/// (past either the robot is lost, and a linear filter with it), and the calibration's
/// limits. Each fits the matrix's 32 bits.
const CEILING: [i32; N] = [
    40_000 * 40_000,
    40_000 * 40_000,
    39_000 * 39_000,
    GYRO_SCALE_MAX * GYRO_SCALE_MAX,
    GYRO_BIAS_MAX * GYRO_BIAS_MAX,
    FLOW_SCALE_MAX * FLOW_SCALE_MAX,
];

/// The calibration's limits in fine units (each under 2^23).
const CALIBRATION_LIMIT: [i64; 3] = [
    (GYRO_SCALE_MAX as i64) << FINE_SHIFT,
    (GYRO_BIAS_MAX as i64) << FINE_SHIFT,
    (FLOW_SCALE_MAX as i64) << FINE_SHIFT,
];

/// The filter: covariance, learned calibration and counters (the pose itself is the
/// core's, so every pose mode shares the same pose history and mapping).
#[derive(Clone, Debug)]
pub struct Estimator {
    pub(super) config: EstimatorConfig,
    pub(super) p: Covariance,
    /// Gyro scale, gyro bias and flow scale corrections, fine units.
    pub(super) calibration: [i64; 3],
    pub(super) counters: TagCounters,
    /// The process noise's fractions of a unit not yet added, in 1/256 units.
    noise_carry: [u8; N],
    /// The process noise's parts the configuration fixes.
    noise: NoiseParts,
    /// The camera's noise as the configuration fixes it.
    pub(super) sighting_noise: SightingNoise,
    /// The cosine of the camera's half view (Q16), worked out once: a tag's bearing
    /// whose cosine is below it is outside the picture.
    pub(super) view_cos: i32,
    /// Which third of the correlation check [`Estimator::settle_updated`] does next.
    settle_part: u8,
    /// Updates still to be settled in full after [`Estimator::forget_heading`].
    settle_fully: u8,
    /// Whether the next sighting is taken whatever the gate says
    /// ([`Estimator::forget_heading`]).
    pub(super) ungated: bool,
    /// Whether sightings are held to the doubted camera's gate
    /// ([`Estimator::doubt_camera`]).
    pub(super) camera_doubted: bool,
    /// Whether the last sighting was refused by the gate at its range
    /// ([`Estimator::refused_at_its_range`]).
    pub(super) refused_at_its_range: bool,
    /// The last sighting the gate refused: its bearing and range innovations
    /// ([`Estimator::refused_by`]).
    pub(super) refused_by: (i32, i32),
}

impl Estimator {
    /// A filter at the start: the configured initial uncertainty, nothing learned.
    pub fn new(config: EstimatorConfig) -> Estimator {
        let c = &config;
        let pos = square(units::position_from_um(
            i64::from(c.initial_position_mm) * 1000,
        ));
        let p = Covariance::diagonal([
            pos,
            pos,
            square(units::heading_from_mdeg(i64::from(c.initial_heading_mdeg))),
            square(units::scale_from_ppm(i64::from(c.initial_gyro_scale_ppm))),
            square(units::bias_from_mdps(i64::from(c.initial_gyro_bias_mdps))),
            square(units::scale_from_ppm(i64::from(c.initial_flow_scale_ppm))),
        ]);
        let mut e = Estimator {
            config,
            p,
            calibration: [0; 3],
            counters: TagCounters::default(),
            noise_carry: [0; N],
            noise: NoiseParts::of(c),
            sighting_noise: SightingNoise::of(c),
            view_cos: Angle::from_millidegrees(i64::from(c.half_view_mdeg)).cos(),
            settle_part: 0,
            settle_fully: 0,
            ungated: false,
            camera_doubted: false,
            refused_at_its_range: false,
            refused_by: (0, 0),
        };
        e.settle();
        e
    }

    /// The covariance, in state order.
    pub fn covariance(&self) -> &Covariance {
        &self.p
    }

    /// Sightings used and refused since start.
    pub fn counters(&self) -> &TagCounters {
        &self.counters
    }

    /// The learned calibration.
    pub fn calibration(&self) -> Calibration {
        let [gs, gb, fs] = self.calibration;
        Calibration {
            gyro_scale_ppm: units::ppm_from_fine_scale(gs) as i32,
            gyro_bias_mdps: units::mdps_from_fine_bias(gb) as i32,
            flow_scale_ppm: units::ppm_from_fine_scale(fs) as i32,
        }
    }

    /// The read-out: the pose's covariance and the calibration.
    pub fn estimate(&self) -> Estimate {
        let p = &self.p;
        Estimate {
            covariance: PoseCovariance {
                xx: p.get(State::X, State::X),
                xy: p.get(State::X, State::Y),
                yy: p.get(State::Y, State::Y),
                xh: p.get(State::X, State::Heading),
                yh: p.get(State::Y, State::Heading),
                hh: p.get(State::Heading, State::Heading),
            },
            calibration: self.calibration(),
        }
    }

    /// The flow sensor's calibration with the learned scale applied to `nominal`'s.
    pub fn odometry(&self, nominal: &OdometryConfig) -> OdometryConfig {
        let flow = i64::from(nominal.flow_um_per_count_q16);
        let flow = flow + mul_shift(flow, self.calibration[2], 16 + FINE_SHIFT);
        OdometryConfig {
            flow_um_per_count_q16: flow.clamp(1, i32::MAX as i64) as i32,
            ..*nominal
        }
    }

    /// A gyro reading with the learned bias taken off and the learned scale applied (as a
    /// multiply here, not as the odometry's parts per million, which cost a division).
    pub fn correct_gyro(&self, gyro: GyroRate) -> GyroRate {
        let [scale, bias, _] = self.calibration;
        let rate = i64::from(gyro.rate_mdps) - units::mdps_from_fine_bias(bias);
        let rate = rate + mul_shift(rate, scale, 16 + FINE_SHIFT);
        GyroRate {
            rate_mdps: rate.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
        }
    }

    /// Carries the covariance through one tick's odometry: `before` and `after` are the
    /// poses either side of `motion`, which took `dt_us`; `flow` and `gyro` say whether
    /// each reading was integrated, the robot held still that way (no reading, but the
    /// motion known: no more noise than a reading's), or nothing was known.
    /// `guess_bound_mdps` is how far the turn rate integrated can be from the robot's under
    /// its commands (`None`: not known): a tick whose gyro was not read (lost, or a reading
    /// standing in) turned within that of its guess, so its heading noise is at most that
    /// over the tick, where the configured stale noise must cover a turn at full rate (a
    /// reading lost on a straight drive under half a degree, not three).
    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    pub fn predict(
        &mut self,
        before: &Pose,
        after: &Pose,
        motion: &Motion,
        dt_us: u32,
        flow: Known<()>,
        gyro: Known<()>,
        guess_bound_mdps: Option<u32>,
    ) {
        let read = |k: Known<()>| matches!(k, Known::Read(()));
        let (flow_read, gyro_read) = (read(flow), read(gyro));
        let (flow, gyro) = (flow.is_known(), gyro.is_known());
        let dx = units::position_from_um(i64::from(after.x_um) - i64::from(before.x_um));
        let dy = units::position_from_um(i64::from(after.y_um) - i64::from(before.y_um));
        let turn = units::heading_from_bits(motion.turn_bits);
        let dt = units::seconds_q16_from_us(dt_us);
        // The Jacobian's off-diagonal part, Q16 (see the covariance module for why these
        // are the plain displacements).
        let mut d: [Entry; 6] = [(State::X, State::X, 0); 6];
        let mut n = 0;
        let mut push = |e: Entry| {
            if let Some(slot) = d.get_mut(n) {
                *slot = e;
                n += 1;
            }
        };
        let [across_x, across_y] = across_heading(dx, dy);
        push(across_x);
        push(across_y);
        if flow_read {
            push((State::X, State::FlowScale, q16(dx)));
            push((State::Y, State::FlowScale, q16(dy)));
        }
        if gyro_read {
            push((State::Heading, State::GyroScale, q16(turn)));
            push((State::Heading, State::GyroBias, q16(-dt)));
        }
        // The noise in 1/256 units, its fraction carried to the next tick.
        let mut q = self.process_noise_q8(dx, dy, turn, dt_us, flow, gyro, guess_bound_mdps);
        if !flow {
            let across = self.noise.position;
            along_the_nose(
                &mut self.p,
                &mut q,
                across,
                before.heading,
                motion.turn_bits,
            );
        }
        for (q, carry) in q.iter_mut().zip(self.noise_carry.iter_mut()) {
            let total = q.saturating_add(i64::from(*carry));
            *carry = (total & 0xFF) as u8;
            *q = total >> 8;
        }
        self.p.propagate(d.get(..n).unwrap_or(&[]), &q, &CEILING);
        self.bound_variances();
    }

    /// The noise one tick adds, in covariance units times 2^8 (see [`NoiseParts`]): the
    /// parts that do not move with the tick's motion worked out once, at construction.
    #[allow(clippy::too_many_arguments)]
    fn process_noise_q8(
        &self,
        dx: i64,
        dy: i64,
        turn: i64,
        dt_us: u32,
        flow: bool,
        gyro: bool,
        guess_bound_mdps: Option<u32>,
    ) -> [i64; N] {
        let n = &self.noise;
        let turn = turn.abs();
        // A share of the distance or of the turn only when one is configured: the seed's
        // sensors have their scales as states, so neither (a zero share adds zero).
        let position = if flow {
            let by_distance = if n.position_ppm_q16 == 0 {
                0
            } else {
                let distance = crate::pose::hypot(dx, dy).min(i64::MAX as u64) as i64;
                noise_var(mul_shift(distance, n.position_ppm_q16, 8))
            };
            n.position + by_distance + noise_var(mul_shift(n.position_per_rad_q8, turn, 16))
        } else {
            stale_var(n.stale_position_q8, dt_us)
        };
        let heading = if gyro {
            let by_turn = if n.heading_ppm_q16 == 0 {
                0
            } else {
                noise_var(mul_shift(turn, n.heading_ppm_q16, 8))
            };
            n.heading + by_turn
        } else {
            let stale = stale_var(n.stale_heading_q8, dt_us);
            match guess_bound_mdps {
                Some(mdps) => {
                    // The turn over the tick, mdeg: mdps times microseconds times 2^32 / 1e6
                    // (4,295), shifted back; a turn under 2^17 mdps over a minute, below 2^63.
                    let us = u64::from(dt_us.min(60_000_000));
                    let mdeg = (u64::from(mdps.min(1 << 17)) * us * 4_295) >> 32;
                    stale.min(noise_var(units::heading_from_mdeg_frac(mdeg as i64, 8)))
                }
                None => stale,
            }
        };
        let [gyro_scale, gyro_bias, flow_scale] = n.walks;
        [
            position, position, heading, gyro_scale, gyro_bias, flow_scale,
        ]
    }

    /// Forgets what the filter knew of the heading when it is sure of its pose (the
    /// position within `SURE_POSITION_MM`, the heading within
    /// `FORGOTTEN_HEADING_MDEG`) and every sighting has refused it for a while: a pose
    /// held sure against the tags, as after a gyro bias jump no tag saw. The pose's
    /// correlations are dropped and the heading's deviation raised to
    /// `FORGOTTEN_HEADING_MDEG`, and the next sighting is taken past the gate, so that
    /// it turns the robot back (its bearing is far more certain than that heading) and
    /// the correction is not learned as a gyro error; the next updates settle the whole
    /// matrix ([`Estimator::settle`]). A filter already unsure is left alone: its gate is
    /// wide, and sightings still beyond it are likelier garbage, and an update of a wide,
    /// correlated pose goes past what the fixed-point matrix keeps definite. Returns
    /// whether it forgot.
    ///
    /// `driven_um` is the way the pose moved since the sightings began to refuse it (x,
    /// y, micrometres): driven at a heading going wrong, the position went aside of it
    /// by half that way times the heading's error, as the error grew. The position is
    /// tied to the forgotten heading along that way, so that the sighting that turns
    /// the robot back also moves it back aside, where the heading alone would take the
    /// whole bearing and leave the position off, which one tag cannot tell apart.
    pub fn forget_heading(&mut self, driven_um: (i64, i64)) -> bool {
        let position = square(units::position_from_um(SURE_POSITION_MM * 1000));
        let heading = square(units::heading_from_mdeg(FORGOTTEN_HEADING_MDEG));
        let sure = self.p.get(State::X, State::X) <= position
            && self.p.get(State::Y, State::Y) <= position
            && self.p.get(State::Heading, State::Heading) < heading;
        if !sure {
            return false;
        }
        self.p.forget(State::X, 0);
        self.p.forget(State::Y, 0);
        self.p.forget(State::Heading, heading);
        // The position's error is half the way across times the heading's: the
        // Jacobian of a drive's displacement by its heading (as `predict`), halved.
        let tie = across_heading(
            units::position_from_um(driven_um.0) / 2,
            units::position_from_um(driven_um.1) / 2,
        );
        self.p.propagate(&tie, &[0; N], &CEILING);
        self.settle();
        self.settle_fully = SETTLED_FULLY_AFTER_FORGETTING;
        self.ungated = true;
        true
    }

    /// Whether the heading is known well enough for a scan to be mapped at it with
    /// matching (within `MATCHED_HEADING_SD_MDEG`): past that, as after many turns each
    /// taken as a guess, the matches cannot find the heading, and the map is left as it
    /// was until they or a tag have brought it back.
    pub fn heading_matchable(&self) -> bool {
        let heading = square(units::heading_from_mdeg(MATCHED_HEADING_SD_MDEG));
        self.p.get(State::Heading, State::Heading) <= heading
    }

    /// Whether the pose is known well enough for a scan to be mapped at it without
    /// matching (within `MAPPED_POSITION_SD_MM` along each axis and
    /// `MAPPED_HEADING_SD_MDEG`): past that, as in a long while with no tag in sight, a
    /// wall would be drawn where it is not, and the map is left as it was.
    pub fn sure_enough_to_map(&self) -> bool {
        let position = square(units::position_from_um(MAPPED_POSITION_SD_MM * 1000));
        let heading = square(units::heading_from_mdeg(MAPPED_HEADING_SD_MDEG));
        self.p.get(State::X, State::X) <= position
            && self.p.get(State::Y, State::Y) <= position
            && self.p.get(State::Heading, State::Heading) <= heading
    }

    /// Forgets what the filter knew of the position when it is sure of it (within
    /// `SURE_POSITION_MM`) and two tags have refused it together for a while, the depth
    /// sensor not seeing them elsewhere: a position held sure against the tags,
    /// as after the flow lost a few ticks of a drive. The position's correlations are
    /// dropped and its deviation raised to `FORGOTTEN_POSITION_MM`, and the next sighting
    /// is taken past the gate ([`Estimator::forget_heading`] alike). Returns whether it
    /// forgot.
    pub fn forget_position(&mut self) -> bool {
        let sure = square(units::position_from_um(SURE_POSITION_MM * 1000));
        if self.p.get(State::X, State::X) > sure || self.p.get(State::Y, State::Y) > sure {
            return false;
        }
        let forgotten = square(units::position_from_um(FORGOTTEN_POSITION_MM * 1000));
        self.p.forget(State::X, forgotten);
        self.p.forget(State::Y, forgotten);
        self.settle();
        self.settle_fully = SETTLED_FULLY_AFTER_FORGETTING;
        self.ungated = true;
        true
    }

    /// Takes a heading set from outside the filter's updates (the walls' turn in place of
    /// a gyro found lying, [`crate::wall_turn`]): the heading's correlations are dropped
    /// and its deviation raised to at least `WALL_TURN_SD_MDEG`, so that the correction is
    /// not learned as a gyro error and later sightings and matches may still move it.
    pub fn heading_set_by_walls(&mut self) {
        self.p.forget(
            State::Heading,
            square(units::heading_from_mdeg(WALL_TURN_SD_MDEG)),
        );
        self.settle();
    }

    /// Takes a heading the walls pinned while the robot stood (their tilt averaged, the
    /// gyro found lying, [`crate::wall_turn::WallTurn::held`]): its correlations dropped and
    /// its deviation set to `WALL_HELD_SD_MDEG`, narrower than after the first turn back,
    /// so that matches against a map drawn as the gyro's error grew do not pull it off.
    pub fn heading_pinned_by_walls(&mut self) {
        self.p.replace(
            State::Heading,
            square(units::heading_from_mdeg(WALL_HELD_SD_MDEG)),
        );
        self.settle();
    }

    /// Adds a correction, in fine units, to the calibration, within its limits.
    ///
    /// In 32 bits where both fit them (the calibration always does: its limits are under
    /// 2^23), where a sum saturates only far past the limits: the M0+ takes 64-bit sums
    /// and compares in pairs of instructions.
    pub(super) fn correct_calibration(&mut self, fine: [i64; 3]) {
        for ((c, d), limit) in self.calibration.iter_mut().zip(fine).zip(CALIBRATION_LIMIT) {
            *c = if fits_i32(*c) && fits_i32(d) {
                let limit = limit as i32;
                i64::from((*c as i32).saturating_add(d as i32).clamp(-limit, limit))
            } else {
                c.saturating_add(d).clamp(-limit, limit)
            };
        }
    }

    /// Ends an update whose state correction, in fine units, is `fine`: the variances
    /// back within bounds, the calibration corrected, and the pose `then` (the update's
    /// moment) moved by the correction.
    pub(super) fn corrected(&mut self, then: &Pose, fine: [i64; N]) -> Pose {
        self.bound_variances();
        let [fx, fy, fh, gs, gb, fs] = fine;
        self.correct_calibration([gs, gb, fs]);
        Pose {
            x_um: moved_um(then.x_um, fx),
            y_um: moved_um(then.y_um, fy),
            heading: then.heading + Angle::from_bits(units::bits_from_fine_heading(fh) as u32),
        }
    }

    /// Keeps the variances within bounds after an update.
    pub(super) fn bound_variances(&mut self) {
        self.p.bound_variances(&FLOOR, &CEILING);
    }

    /// Ends a tick's updates: variances within bounds and correlations below one, so
    /// that the rounding of many updates never costs the matrix its positive
    /// definiteness.
    pub fn settle(&mut self) {
        self.p.bound(&FLOOR, &CEILING);
    }

    /// [`Estimator::settle`] for a tick that took tag updates, the costliest kind: the
    /// variances within bounds, but the correlations of only a third of the pairs checked,
    /// the thirds in turn, so that each pair is still checked at least every third tick
    /// (and on every tick with no update). The check guards against the rounding of many
    /// updates, which moves a correlation far less in three ticks than its margin.
    pub fn settle_updated(&mut self) {
        if self.settle_fully > 0 {
            self.settle_fully -= 1;
            self.settle();
            return;
        }
        let part = self.settle_part;
        self.settle_part = if part >= 2 { 0 } else { part + 1 };
        self.p.bound_part(&FLOOR, &CEILING, part);
    }
}

/// An unseen tick's position noise (no flow reading: its motion lost or stood in by its
/// command): `q`'s position variances, both the stale figure on the way in, become that
/// figure along the nose (at `heading` turned half the tick's `turn_bits`, the chord's
/// direction) and `across` it (a read tick's own, if smaller), and their covariance is
/// added to `p`: `across I + (stale - across) u u'`, `u = (sin h, cos h)`, in 1/256
/// units. Such a tick does not know how far the robot went, but a two-wheeled robot goes
/// only where its nose points: going aside is its heading's error, which the Jacobian
/// carries. Added before the propagation, the cross term comes out the same (the
/// Jacobian moves no position column), and the sum is definite with the variances.
/// Out of line, for the rare unseen tick.
#[inline(never)]
fn along_the_nose(
    p: &mut Covariance,
    q: &mut [i64; N],
    across: i64,
    heading: Angle,
    turn_bits: i64,
) {
    let heading = crate::odometry::chord_heading(heading, turn_bits);
    let stale = q[State::X as usize];
    let across = across.min(stale);
    let extra = stale - across;
    let (sin, cos) = heading.sin_cos();
    let (sin, cos) = (i64::from(sin), i64::from(cos));
    // `extra` stays below 2^42 (a minute unseen), the products' Q16 within 2^16.
    let share = |a: i64, b: i64| (extra * ((a * b) >> 16)) >> 16;
    q[State::X as usize] = across + share(sin, sin);
    q[State::Y as usize] = across + share(cos, cos);
    p.add_covariance(State::X, State::Y, (share(sin, cos) + 0x80) >> 8);
}

/// `2^32 / STALE_PERIOD_US`: a frame's time as a share of the stale noises' period, Q16,
/// is its microseconds times this, shifted down 16 (a multiply rather than a division).
const STALE_SHARE_PER_US_Q32: u64 = (1 << 32) / config::STALE_PERIOD_US as u64;

/// The variance, in 1/256 units, of a stale input over `dt_us`: its deviation `sigma_q8`
/// (per [`config::STALE_PERIOD_US`]) is a motion unseen, so it grows in proportion to the
/// time. Out of line: it is for the rare stale tick, and inlined twice it costs flash.
#[inline(never)]
fn stale_var(sigma_q8: i64, dt_us: u32) -> i64 {
    // A minute unseen is as good as any longer (the variances' ceiling is far below), and
    // keeps the products small: the share under 2^26, a deviation (under 2^31) by it under
    // 2^57.
    let share_q16 = (u64::from(dt_us.min(60_000_000)) * STALE_SHARE_PER_US_Q32) >> 16;
    let sigma = (sigma_q8.unsigned_abs().min(1 << 31) * share_q16) >> 16;
    noise_var(sigma as i64)
}

/// A standard deviation in 1/256 units squared, in 1/256 units of variance.
fn noise_var(sigma_q8: i64) -> i64 {
    square(sigma_q8) >> 8
}

/// The process noise's parts that the configuration alone fixes, in 1/256 units of
/// variance (standard deviations formed in 1/256 of a unit, so that a fraction of a unit
/// is not rounded away before squaring): worked out once rather than every tick.
#[derive(Clone, Copy, Debug)]
struct NoiseParts {
    /// A tick's own position noise, with flow.
    position: i64,
    /// The position noise per radian turned, as a standard deviation in 1/256 units.
    position_per_rad_q8: i64,
    /// The position noise's share of the distance, Q16.
    position_ppm_q16: i64,
    /// The position noise of a [`config::STALE_PERIOD_US`] without flow, as a standard
    /// deviation in 1/256 units.
    stale_position_q8: i64,
    /// A tick's own heading noise, with the gyro.
    heading: i64,
    /// The heading noise's share of the turn, Q16.
    heading_ppm_q16: i64,
    /// The heading noise of a [`config::STALE_PERIOD_US`] without the gyro, as a standard
    /// deviation in 1/256 units.
    stale_heading_q8: i64,
    /// The random walks of the gyro's scale and bias and of the flow's scale.
    walks: [i64; 3],
}

impl NoiseParts {
    fn of(c: &EstimatorConfig) -> NoiseParts {
        let position_q8 = |um: u32| units::position_from_um_frac(i64::from(um), 8);
        let heading_q8 = |mdeg: u32| units::heading_from_mdeg_frac(i64::from(mdeg), 8);
        let scale_q8 = |ppm: u32| units::scale_from_ppm_frac(i64::from(ppm), 8);
        // Micro-degrees per second to 1/256 bias units (x pi / 180e6 x 2^16 x 2^8, Q16).
        let bias_q8 = |udps: u32| mul_shift(i64::from(udps), 19_190, 16);
        NoiseParts {
            position: noise_var(position_q8(c.position_noise_um)),
            position_per_rad_q8: position_q8(c.position_noise_um_per_rad),
            position_ppm_q16: ppm_q16(c.position_noise_ppm),
            stale_position_q8: position_q8(c.stale_flow_mm.saturating_mul(1000)),
            heading: noise_var(heading_q8(c.heading_noise_mdeg)),
            heading_ppm_q16: ppm_q16(c.heading_noise_ppm),
            stale_heading_q8: heading_q8(c.stale_gyro_mdeg),
            walks: [
                noise_var(scale_q8(c.gyro_scale_walk_ppm)),
                noise_var(bias_q8(c.gyro_bias_walk_udps)),
                noise_var(scale_q8(c.flow_scale_walk_ppm)),
            ],
        }
    }
}

/// A coordinate `um` moved by a correction of `fine` position units, saturating.
#[inline(always)]
fn moved_um(um: i32, fine: i64) -> i32 {
    if fine.unsigned_abs() < 1 << 24 {
        // Within 4 m: `fine 125` fits 32 bits, and the M0+ adds and clamps them in an
        // instruction or two, 64 bits in several.
        um.saturating_add(((fine as i32) * 125 + (1 << 8)) >> 9)
    } else {
        (i64::from(um) + units::um_from_fine_position(fine)).clamp(i32::MIN as i64, i32::MAX as i64)
            as i32
    }
}

/// The camera's noise in the filter's units, worked out once from the configuration.
#[derive(Clone, Copy, Debug)]
pub(super) struct SightingNoise {
    /// The range noise's constant part, position units.
    pub(super) range_sigma: i64,
    /// The range noise's share of the range, Q16 (of the per mille: Q16 of 1/1000 is
    /// 65.536).
    pub(super) range_share_q16: i64,
    /// The bearing noise at the picture's centre, heading units.
    pub(super) bearing_sigma: i64,
}

impl SightingNoise {
    fn of(c: &EstimatorConfig) -> SightingNoise {
        SightingNoise {
            range_sigma: i64::from(c.range_noise_mm) * units::POSITION_PER_MM,
            range_share_q16: mul_shift(i64::from(c.range_noise_permille), 4_294_967, 16),
            bearing_sigma: units::heading_from_mdeg(i64::from(c.bearing_noise_mdeg)),
        }
    }
}

/// Parts per million as a Q16 fraction.
fn ppm_q16(ppm: u32) -> i64 {
    units::scale_from_ppm(i64::from(ppm))
}

/// A Jacobian entry in Q16, saturated to 32 bits.
fn q16(x: i64) -> i32 {
    x.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

/// The Jacobian's entries of a displacement `(dx, dy)` (filter units) by the heading it
/// was made at: how far an error of that heading moves the position, across the way.
fn across_heading(dx: i64, dy: i64) -> [Entry; 2] {
    [
        (State::X, State::Heading, q16(dy)),
        (State::Y, State::Heading, q16(-dx)),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tick without the gyro adds the configured stale heading noise (3 degrees), unless
    /// the commands bound the tick's turn lower: then no more than that turn.
    #[test]
    fn a_lost_gyros_heading_noise_is_at_most_the_turn_the_commands_allow() {
        let added = |bound: Option<u32>| {
            let mut e = Estimator::new(EstimatorConfig::SEED);
            let h0 = e.p.get(State::Heading, State::Heading);
            let still = Pose::default();
            e.predict(
                &still,
                &still,
                &Motion::default(),
                config::STALE_PERIOD_US,
                Known::Read(()),
                Known::Lost,
                bound,
            );
            e.p.get(State::Heading, State::Heading) - h0
        };
        let heading = |mdeg: i64| square(units::heading_from_mdeg(mdeg));
        let stale = heading(i64::from(EstimatorConfig::SEED.stale_gyro_mdeg));
        let near = |v: i64, want: i64| (v - want).abs() <= want / 50 + 2;
        assert!(near(added(None), stale), "{} against {stale}", added(None));
        // Driving straight at 86 mm/s: 4,456 mdps allowed, 446 mdeg over the tick.
        assert!(near(added(Some(4_456)), heading(446)));
        // A turn at full rate allows more than the stale noise, which stands.
        assert_eq!(added(Some(33_568)), added(None));
    }

    /// The heading's variance and the position's along the nose (y, at heading 0) after
    /// one still frame of `dt_us` with neither input.
    fn after_unseen(dt_us: u32) -> (i64, i64) {
        let mut e = Estimator::new(EstimatorConfig::SEED);
        let (h0, y0) = (
            e.p.get(State::Heading, State::Heading),
            e.p.get(State::Y, State::Y),
        );
        let still = Pose::default();
        e.predict(
            &still,
            &still,
            &Motion::default(),
            dt_us,
            Known::Lost,
            Known::Lost,
            None,
        );
        (
            e.p.get(State::Heading, State::Heading) - h0,
            e.p.get(State::Y, State::Y) - y0,
        )
    }

    /// A tick without flow does not know how far the robot went, only that it went where
    /// its nose points: the stale noise lies along the nose, and across it only a read
    /// tick's own, whichever way the robot faces.
    #[test]
    fn an_unseen_ticks_position_noise_lies_along_the_nose() {
        let added = |heading_mdeg: i64| {
            let mut e = Estimator::new(EstimatorConfig::SEED);
            let p0 = e.p;
            let pose = Pose::from_mm_mdeg(0, 0, heading_mdeg);
            let gain = |e: &Estimator, i: State, j: State| e.p.get(i, j) - p0.get(i, j);
            e.predict(
                &pose,
                &pose,
                &Motion::default(),
                config::STALE_PERIOD_US,
                Known::Lost,
                Known::Read(()),
                None,
            );
            (
                gain(&e, State::X, State::X),
                gain(&e, State::Y, State::Y),
                gain(&e, State::X, State::Y),
            )
        };
        let position = |mm: i64| square(units::position_from_um(mm * 1000));
        let stale = position(i64::from(EstimatorConfig::SEED.stale_flow_mm));
        let near = |v: i64, want: i64| (v - want).abs() <= want / 50 + 2;
        // Facing +y (heading 0): unsure along y, not across.
        let (xx, yy, xy) = added(0);
        assert!(near(yy, stale), "{yy} against {stale}");
        assert!(xx * 100 < stale && xy == 0, "{xx} {xy}");
        // Facing +x, the other way round, and backwards the same.
        for heading in [90_000, -90_000] {
            let (xx, yy, _) = added(heading);
            assert!(near(xx, stale) && yy * 100 < stale, "{heading}: {xx} {yy}");
        }
        // Half way between: half each, and the two tied along the nose, whose sign says
        // which diagonal it lies on.
        let (xx, yy, xy) = added(45_000);
        assert!(near(xx, stale / 2) && near(yy, stale / 2), "{xx} {yy}");
        assert!(near(xy, stale / 2), "{xy}");
        let (_, _, xy) = added(135_000);
        assert!(near(-xy, stale / 2), "{xy}");
    }

    #[test]
    fn a_scan_is_mapped_only_while_position_and_heading_are_both_within_their_bounds() {
        let position = |mm: i64| square(units::position_from_um(mm * 1000));
        let heading = |mdeg: i64| square(units::heading_from_mdeg(mdeg));
        let with = |i: State, variance: i64| {
            let mut e = Estimator::new(EstimatorConfig::SEED);
            e.p.replace(i, variance);
            e.sure_enough_to_map()
        };
        assert!(Estimator::new(EstimatorConfig::SEED).sure_enough_to_map());
        for (i, bound) in [
            (State::X, position(MAPPED_POSITION_SD_MM)),
            (State::Y, position(MAPPED_POSITION_SD_MM)),
            (State::Heading, heading(MAPPED_HEADING_SD_MDEG)),
        ] {
            assert!(with(i, bound), "{i:?} at its bound");
            assert!(!with(i, bound + 1), "{i:?} past its bound");
        }
        // A tick without the gyro adds a stale reading's 3 degrees: too unsure to map.
        let (heading_added, _) = after_unseen(config::STALE_PERIOD_US);
        assert!(heading_added > heading(MAPPED_HEADING_SD_MDEG));
    }

    #[test]
    fn with_matching_a_scan_is_mapped_only_while_the_heading_is_within_its_bound() {
        let heading = square(units::heading_from_mdeg(MATCHED_HEADING_SD_MDEG));
        let with = |i: State, variance: i64| {
            let mut e = Estimator::new(EstimatorConfig::SEED);
            e.p.replace(i, variance);
            e.heading_matchable()
        };
        assert!(Estimator::new(EstimatorConfig::SEED).heading_matchable());
        assert!(with(State::Heading, heading));
        assert!(!with(State::Heading, heading + 1));
        // The position is the matches' to find, however unsure.
        assert!(with(State::X, square(units::position_from_um(2_000_000))));
        // One tick without the gyro is not past it; a few are.
        let (one, _) = after_unseen(config::STALE_PERIOD_US);
        assert!(one < heading && 3 * one > heading);
    }

    #[test]
    fn a_filter_sure_of_its_position_forgets_it_and_an_unsure_one_does_not() {
        let mut e = Estimator::new(EstimatorConfig::SEED);
        // A drive along +y: the heading's error moves x.
        let before = Pose::default();
        let after = Pose {
            y_um: 10_000,
            ..before
        };
        let drive = Motion {
            forward_um: 10_000,
            ..Motion::default()
        };
        e.predict(
            &before,
            &after,
            &drive,
            100_000,
            Known::Read(()),
            Known::Read(()),
            None,
        );
        assert_ne!(e.p.get(State::X, State::Heading), 0);
        let heading = e.p.get(State::Heading, State::Heading);
        assert!(e.forget_position());
        let forgotten = square(units::position_from_um(FORGOTTEN_POSITION_MM * 1000));
        assert_eq!(e.p.get(State::X, State::X), forgotten);
        assert_eq!(e.p.get(State::Y, State::Y), forgotten);
        assert_eq!(e.p.get(State::X, State::Heading), 0);
        assert_eq!(e.p.get(State::Heading, State::Heading), heading);
        assert!(e.ungated);
        // Now unsure of it (50 mm): nothing more to forget.
        e.ungated = false;
        assert!(!e.forget_position());
        assert!(!e.ungated);
    }

    /// A heading forgotten after a drive of 300 mm along +y is tied to x, half that way
    /// across times the heading's error (the sign `predict`'s Jacobian gives), and y is
    /// left alone; with no drive, nothing is tied.
    #[test]
    fn a_forgotten_heading_is_tied_to_the_position_across_the_way_driven() {
        let mut still = Estimator::new(EstimatorConfig::SEED);
        assert!(still.forget_heading((0, 0)));
        assert_eq!(still.p.get(State::X, State::Heading), 0);
        assert_eq!(still.p.get(State::Y, State::Heading), 0);

        let mut e = Estimator::new(EstimatorConfig::SEED);
        let (xx, yy) = (e.p.get(State::X, State::X), e.p.get(State::Y, State::Y));
        assert!(e.forget_heading((0, 300_000)));
        let heading = square(units::heading_from_mdeg(FORGOTTEN_HEADING_MDEG));
        assert_eq!(e.p.get(State::Heading, State::Heading), heading);
        assert_eq!(e.p.get(State::Y, State::Heading), 0);
        assert_eq!(e.p.get(State::Y, State::Y), yy);
        // x's error is 150 mm times the heading's (2 degrees): about 5.2 mm, which the
        // variance gains, all of it tied to the heading.
        let tied = e.p.get(State::X, State::Heading);
        assert!(tied > 0, "{tied}");
        let gained = e.p.get(State::X, State::X) - xx;
        let want = square(units::position_from_um(5_236));
        assert!(
            (gained - want).abs() <= want / 50,
            "x gained {gained}, want about {want}"
        );
    }

    #[test]
    fn time_unseen_costs_deviation_in_proportion() {
        let (heading, x) = after_unseen(config::STALE_PERIOD_US);
        assert!(heading > 0 && x > 0);
        // Six times the time unseen (a watchdog reset's), six times the deviation.
        let (heading6, x6) = after_unseen(6 * config::STALE_PERIOD_US);
        let near = |got: i64, want: i64| (got - want).abs() * 50 <= want;
        assert!(near(heading6, 36 * heading), "{heading6} vs 36 x {heading}");
        assert!(near(x6, 36 * x), "{x6} vs 36 x {x}");
    }

    /// The 32-bit shortcuts give the 64-bit sums bit for bit: a coordinate moved by a
    /// correction, and the calibration corrected, both saturating at their limits.
    #[test]
    fn the_32_bit_corrections_are_the_64_bit_ones() {
        let mut rng = crate::lcg::Lcg::new(29);
        for n in 0..200_000u32 {
            let um = ((rng.next_u64() >> 32) as i32) >> (n % 8);
            let fine = (i64::from((rng.next_u64() >> 32) as i32) << 8) >> (n % 40);
            let want = (i64::from(um) + units::um_from_fine_position(fine))
                .clamp(i32::MIN as i64, i32::MAX as i64) as i32;
            assert_eq!(moved_um(um, fine), want, "{um} + {fine}");
        }
        let mut filter = Estimator::new(EstimatorConfig::SEED);
        for n in 0..200_000u32 {
            let d: [i64; 3] = core::array::from_fn(|_| {
                (i64::from((rng.next_u64() >> 32) as i32) << 12) >> (n % 44)
            });
            let mut want = filter.calibration;
            for ((c, d), limit) in want.iter_mut().zip(d).zip(CALIBRATION_LIMIT) {
                *c = c.saturating_add(d).clamp(-limit, limit);
            }
            filter.correct_calibration(d);
            assert_eq!(filter.calibration, want, "{d:?}");
        }
    }
}
