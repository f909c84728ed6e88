//! The pose filter: an extended Kalman filter over the pose and the odometry's own errors.
//!
//! (Being written: this file fixes the public read-out first, so that the simulator, the
//! telemetry and the viewer can be built against it.)

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
pub const POSITION_UNITS_PER_MM: i64 = 16;
/// Heading units of the covariance per radian.
pub const HEADING_UNITS_PER_RAD: i64 = 1 << 16;

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
    /// It disagrees with the prediction beyond the chi-square gate.
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
