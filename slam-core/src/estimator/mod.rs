//! The pose filter: an extended Kalman filter over the pose and the odometry's own errors.
//!
//! Six states: the pose (x, y, heading), the gyro's scale and bias and the flow sensor's
//! scale. Each tick the odometry, corrected by the learned calibration, moves the pose
//! ([`crate::odometry`], as in dead reckoning), and the covariance follows it with
//! process noise that grows with the distance driven and the angle turned (a tick without
//! flow is unsure how far the robot went along its nose, not across it). Each tag in a
//! picture is then one range-and-bearing update against its listed place, at the
//! picture's own moment (the pose then, from the history), tested first against a
//! chi-square gate.
//!
//! An extended Kalman filter because the problem is small and nearly linear between
//! ticks: one 6 x 6 covariance, sparse Jacobians, no iterations, a fixed cost per tick
//! and per sighting, which the 10 Hz loop needs. A particle filter would need hundreds
//! of poses to hold the heading to a tenth of a degree; an unscented filter costs 13
//! sigma points per update for nonlinearity a 10 Hz tick barely shows.
//!
//! Fixed point throughout: each state has its own unit (see [`covariance`] and [`units`])
//! so the covariance's entries stay in 64 bits and its products mostly in 64 bits too.
//! The two measurements of a sighting are applied one after the other (range, then
//! bearing given range), which equals the joint update for independent noises and needs
//! only scalar divisions; the sum of their normalised innovations is the joint
//! chi-square statistic the gate tests.

pub mod config;
pub mod covariance;
mod filter;
pub mod fixed;
mod matched;
mod sighting;
mod step_limit;
pub mod units;

pub use config::EstimatorConfig;
pub use filter::Estimator;
pub use matched::{MapUncertainty, MatchCounters, MatchNoise, MATCH_STEP_UM};
pub use step_limit::{TagShare, TAG_STEP_UM};

/// The filter's states, in the covariance's order.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum State {
    /// Position x, in [`units::POSITION_PER_MM`] per millimetre.
    X = 0,
    /// Position y.
    Y = 1,
    /// Heading, in [`units::HEADING_PER_RAD`] per radian, clockwise.
    Heading = 2,
    /// Gyro scale correction, 2^-16 per unit.
    GyroScale = 3,
    /// Gyro bias, 2^-16 rad/s per unit.
    GyroBias = 4,
    /// Flow scale correction, 2^-16 per unit.
    FlowScale = 5,
}

/// The odometry's errors as the filter has learned them: what to add to the nominal
/// calibration.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Calibration {
    /// The gyro's scale correction, parts per million: the true rate is the measured rate
    /// (bias removed) times `1 + gyro_scale_ppm / 1e6`.
    pub gyro_scale_ppm: i32,
    /// The gyro's remaining bias, millidegrees per second, subtracted from each reading.
    pub gyro_bias_mdps: i32,
    /// The flow sensor's scale correction, parts per million: the true displacement is the
    /// nominal one times `1 + flow_scale_ppm / 1e6`.
    pub flow_scale_ppm: i32,
}

/// The pose's covariance, in the filter's own units: position in [`POSITION_UNITS_PER_MM`]
/// per millimetre, heading in [`HEADING_UNITS_PER_RAD`] per radian (clockwise positive,
/// as the heading).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseCovariance {
    /// Variance of x.
    pub xx: i64,
    /// Covariance of x and y.
    pub xy: i64,
    /// Variance of y.
    pub yy: i64,
    /// Covariance of x and the heading.
    pub xh: i64,
    /// Covariance of y and the heading.
    pub yh: i64,
    /// Variance of the heading.
    pub hh: i64,
}

/// Position units of the covariance per millimetre.
pub const POSITION_UNITS_PER_MM: i64 = units::POSITION_PER_MM;
/// Heading units of the covariance per radian.
pub const HEADING_UNITS_PER_RAD: i64 = units::HEADING_PER_RAD;

/// What the filter believes beyond the pose: how sure it is, and the sensors' errors.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// The pose's covariance.
    pub covariance: PoseCovariance,
    /// The learned calibration.
    pub calibration: Calibration,
}

/// Why a tag sighting was not used.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TagRefusal {
    /// Its id is not in the tag map.
    UnknownId,
    /// Its listed place is outside the camera's view from the believed pose.
    Behind,
    /// It was read further away than the camera can.
    TooFar,
    /// The picture is older than the pose history reaches.
    TooOld,
    /// It disagrees with the prediction beyond the chi-square gate, or so far that it is
    /// refused outright: a bearing more than a quarter turn off, a column further off the
    /// picture's centre than the picture is wide.
    Gate,
}

/// Sightings used and refused since start, by cause.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagCounters {
    /// Sightings that updated the filter.
    pub used: u32,
    /// Refused: unknown id.
    pub unknown_id: u32,
    /// Refused: listed place outside the view.
    pub behind: u32,
    /// Refused: beyond the camera's range.
    pub too_far: u32,
    /// Refused: picture older than the history.
    pub too_old: u32,
    /// Refused by the gate.
    pub gate: u32,
}
