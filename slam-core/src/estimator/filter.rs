//! The filter's state and its prediction from odometry.

use super::config::EstimatorConfig;
use super::covariance::{mul_shift, Covariance, Entry, N};
use super::units::{self, square, FINE_SHIFT};
use super::{Calibration, Estimate, PoseCovariance, State, TagCounters};
use crate::frame::GyroRate;
use crate::odometry::{Motion, OdometryConfig};
use crate::pose::Pose;

/// The covariance's floor: no variance ever reaches zero (a filter sure of anything
/// stops listening). Position 1/8 mm, heading 6e-5 rad, calibration one unit.
const FLOOR: [i64; N] = [4, 4, 16, 1, 1, 1];
/// The covariance's ceiling: position 10 m, heading 1 rad, gyro scale 10 %, gyro bias
/// 5 deg/s, flow scale 30 %, each as a standard deviation.
const CEILING: [i64; N] = [
    square(10_000 * units::POSITION_PER_MM),
    square(10_000 * units::POSITION_PER_MM),
    square(units::HEADING_PER_RAD),
    square(6_554),
    square(5_720),
    square(19_661),
];

/// Learned calibration beyond which the sensors are broken, not miscalibrated: gyro
/// scale 10 %, gyro bias 5 deg/s, flow scale 30 %, in fine units.
const CALIBRATION_LIMIT: [i64; 3] = [
    6_554 << FINE_SHIFT,
    5_720 << FINE_SHIFT,
    19_661 << FINE_SHIFT,
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
        };
        e.p.bound(&FLOOR, &CEILING);
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

    /// The odometry's calibration with what has been learned added to `nominal`.
    pub fn odometry(&self, nominal: &OdometryConfig) -> OdometryConfig {
        let c = self.calibration();
        let flow = i64::from(nominal.flow_um_per_count_q16);
        let flow = flow + flow * i64::from(c.flow_scale_ppm) / 1_000_000;
        OdometryConfig {
            flow_um_per_count_q16: flow.clamp(1, i32::MAX as i64) as i32,
            gyro_scale_ppm: nominal.gyro_scale_ppm.saturating_add(c.gyro_scale_ppm),
        }
    }

    /// A gyro reading with the learned bias taken off.
    pub fn unbias(&self, gyro: GyroRate) -> GyroRate {
        GyroRate {
            rate_mdps: gyro
                .rate_mdps
                .saturating_sub(self.calibration().gyro_bias_mdps),
        }
    }

    /// Carries the covariance through one tick's odometry: `before` and `after` are the
    /// poses either side of `motion`, which took `dt_us`; `flow` and `gyro` say whether
    /// each reading was there.
    pub fn predict(
        &mut self,
        before: &Pose,
        after: &Pose,
        motion: &Motion,
        dt_us: u32,
        flow: bool,
        gyro: bool,
    ) {
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
        push((State::X, State::Heading, dy));
        push((State::Y, State::Heading, -dx));
        if flow {
            push((State::X, State::FlowScale, dx));
            push((State::Y, State::FlowScale, dy));
        }
        if gyro {
            push((State::Heading, State::GyroScale, turn));
            push((State::Heading, State::GyroBias, -dt));
        }
        self.p.propagate(d.get(..n).unwrap_or(&[]));
        self.p
            .add_diagonal(self.process_noise(dx, dy, turn, flow, gyro));
        self.p.bound(&FLOOR, &CEILING);
    }

    /// The noise one tick adds, in covariance units.
    fn process_noise(&self, dx: i64, dy: i64, turn: i64, flow: bool, gyro: bool) -> [i64; N] {
        let c = &self.config;
        let distance = crate::pose::hypot(dx, dy) as i64;
        let turn = turn.abs();
        let position = if flow {
            square(units::position_from_um(i64::from(c.position_noise_um)))
                + square(mul_shift(distance, ppm_q16(c.position_noise_ppm), 16))
                + square(
                    units::position_from_um(i64::from(c.position_noise_um_per_rad))
                        .saturating_mul(turn)
                        >> 16,
                )
        } else {
            square(units::position_from_um(i64::from(c.stale_flow_mm) * 1000))
        };
        let heading = if gyro {
            square(units::heading_from_mdeg(i64::from(c.heading_noise_mdeg)))
                + square(mul_shift(turn, ppm_q16(c.heading_noise_ppm), 16))
        } else {
            square(units::heading_from_mdeg(i64::from(c.stale_gyro_mdeg)))
        };
        [
            position,
            position,
            heading,
            square(units::scale_from_ppm(i64::from(c.gyro_scale_walk_ppm))),
            square(units::bias_from_mdps(i64::from(c.gyro_bias_walk_mdps))),
            square(units::scale_from_ppm(i64::from(c.flow_scale_walk_ppm))),
        ]
    }

    /// Adds a correction, in fine units, to the calibration, within its limits.
    pub(super) fn correct_calibration(&mut self, fine: [i64; 3]) {
        for ((c, d), limit) in self.calibration.iter_mut().zip(fine).zip(CALIBRATION_LIMIT) {
            *c = c.saturating_add(d).clamp(-limit, limit);
        }
    }

    /// Keeps the covariance a covariance after an update.
    pub(super) fn bound(&mut self) {
        self.p.bound(&FLOOR, &CEILING);
    }
}

/// Parts per million as a Q16 fraction.
fn ppm_q16(ppm: u32) -> i64 {
    units::scale_from_ppm(i64::from(ppm))
}
