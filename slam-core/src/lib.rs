//! BugBot's SLAM core: fixed-point pose, log-odds occupancy grid, odometry and the two-tag fix.
//!
//! `no_std`, no allocator, no floating point, no I/O and no clock: the caller passes each
//! tick's time and sensor readings in a [`SensorFrame`] and gets a [`StepReport`] back from
//! [`Slam::step`]. The firmware and the host simulator call exactly that function, so what
//! the tests check is what flies.
//!
//! Units: positions in micrometres (pose) or millimetres (map, ranges), headings as
//! wrapping binary angles ([`Angle`]), log odds in Q4 (a byte a cell, 16 is 1.0).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod angle;
pub mod camera_check;
pub mod commanded;
pub mod depth_step;
pub mod estimator;
pub mod frame;
pub mod grid;
pub mod guard;
pub mod history;
#[cfg(test)]
mod lcg;
pub mod matcher;
pub mod odometry;
pub mod plausible;
pub mod pose;
pub mod slam;
pub mod spin_closure;
pub mod tag_range;
pub mod tagfix;
pub mod wall_rate;
pub mod wall_turn;

pub use angle::Angle;
pub use estimator::{
    Calibration, Estimate, Estimator, EstimatorConfig, PoseCovariance, TagCounters, TagRefusal,
};
pub use frame::{
    DepthScan, DriveCommand, FlowDelta, GyroRate, SensorFrame, TagDetection, TagDetections, BEAMS,
    MAX_TAGS,
};
pub use grid::{Evidence, GridGeometry, GridMap, LogOdds, Occupancy, OccupancyCounts};
pub use guard::{decide, Decision, GuardConfig, Obstacle};
pub use odometry::OdometryConfig;
pub use plausible::{Doubt, Input, PlausibleConfig, Trust};
pub use pose::Pose;
pub use slam::{
    ConfigError, Counters, DepthConfig, Localiser, MatchingConfig, Slam, SlamConfig, Staleness,
    StepReport,
};
pub use tagfix::{CameraConfig, FixConfig, FixOutcome, FixRejection, KnownTag, TagMap};
