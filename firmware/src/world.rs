//! The world this image is built for: the constants `build.rs` writes from the scenario
//! file that `BUGBOT_WORLD` names (default: the seed mat), checked by the same code and
//! with the same errors as `host-sim run`, and converted by the same code as its core's
//! configuration (the `world` crate). Nothing here is written by hand.

use embassy_time::Duration;
use slam_core::{
    Angle, CameraConfig, GridGeometry, KnownTag, Localiser, MatchingConfig, OdometryConfig, Pose,
    Slam, SlamConfig, TagMap,
};

use crate::motion::Leg;

include!(concat!(env!("OUT_DIR"), "/world.rs"));

/// The core, its grid sized for this world.
pub type WorldSlam = Slam<GRID_COLUMNS, GRID_ROWS>;

/// The core's configuration: the robot's tuning on this world's grid, with its tags and
/// the sensors' calibration from its file (as `world::robot::slam_config` sets them for
/// `host-sim`), the depth beams along the VL53L5CX's zone columns (the drivers' tests
/// hold the seed's fan to it), and the pose corrected by `localiser`; with the `matching`
/// feature the filter also matches each second's scans against the map.
pub fn slam_config(localiser: Localiser) -> SlamConfig {
    let mut config = SlamConfig::on_grid(GEOMETRY, TagMap::new(&TAGS).unwrap_or_default());
    config.depth.beam_angles = slam_core::slam::fan(i64::from(drivers::depth::FOV_MDEG));
    config.depth.max_range_mm = DEPTH_MAX_RANGE_MM;
    config.odometry = ODOMETRY;
    config.camera = CAMERA;
    config.estimator.max_range_mm = CAMERA_MAX_RANGE_MM;
    config.estimator.half_view_mdeg = CAMERA_HALF_VIEW_MDEG;
    config.localiser = localiser;
    config.matching = (cfg!(feature = "matching") && matches!(localiser, Localiser::Filter))
        .then_some(MatchingConfig::SEED);
    config
}
