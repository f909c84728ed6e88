//! What a [`Slam`](super::Slam) is built with: the depth sensor's fan, the map, the tags,
//! the localiser and the filter, and why a configuration is refused.

use crate::angle::Angle;
use crate::estimator::{EstimatorConfig, MatchNoise};
use crate::frame::BEAMS;
use crate::grid::{Evidence, GridGeometry};
use crate::matcher::{Matcher, MatcherConfig};
use crate::odometry::OdometryConfig;
use crate::plausible::PlausibleConfig;
use crate::tagfix::{CameraConfig, FixConfig, TagMap};

/// The depth sensor's fan and the mapper's range limit.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DepthConfig {
    /// Direction of each beam relative to the nose, left to right.
    pub beam_angles: [Angle; BEAMS],
    /// Ranges at or beyond this, in millimetres, mark no hit (the seed's 170 cm).
    pub max_range_mm: u16,
}

impl DepthConfig {
    /// Eight beams at the centres of eight equal zones across a 45 degree fan, 170 cm limit.
    pub const SEED: DepthConfig = DepthConfig {
        beam_angles: fan(45_000),
        max_range_mm: 1700,
    };
}

/// Beam centres of `BEAMS` equal zones across a fan `width_mdeg` wide, centred on the nose.
pub const fn fan(width_mdeg: i64) -> [Angle; BEAMS] {
    let mut out = [Angle::ZERO; BEAMS];
    let mut i = 0;
    while i < BEAMS {
        // Centre of zone i: -w/2 + w * (2i + 1) / (2 * BEAMS).
        let mdeg = -width_mdeg / 2 + width_mdeg * (2 * i as i64 + 1) / (2 * BEAMS as i64);
        out[i] = Angle::from_millidegrees(mdeg);
        i += 1;
    }
    out
}

/// Everything the core needs to know about the robot and its world, fixed at start.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlamConfig {
    /// Where the grid lies and how big its cells are.
    pub geometry: GridGeometry,
    /// Evidence per beam.
    pub evidence: Evidence,
    /// The depth fan.
    pub depth: DepthConfig,
    /// Odometry calibration.
    pub odometry: OdometryConfig,
    /// Camera intrinsics for tag bearings.
    pub camera: CameraConfig,
    /// Tags whose places are known.
    pub tags: TagMap,
    /// How the pose is corrected beyond odometry.
    pub localiser: Localiser,
    /// When a two-tag fix is believed ([`Localiser::TwoTagFix`]).
    pub fix: FixConfig,
    /// The filter's noise model and gate ([`Localiser::Filter`]).
    pub estimator: EstimatorConfig,
    /// Scan-to-map matching as a filter update ([`Localiser::Filter`] only); `None`: off.
    pub matching: Option<MatchingConfig>,
    /// What the inputs are held to before the pose and the map believe them; `None`:
    /// every reading is believed (for tests of the odometry and the filter alone).
    pub plausible: Option<PlausibleConfig>,
}

/// The matcher and what the filter adds to its matches' spread.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MatchingConfig {
    /// The search.
    pub matcher: MatcherConfig,
    /// The filter's view of a match.
    pub noise: MatchNoise,
}

impl MatchingConfig {
    /// The seed's matcher and noise.
    pub const SEED: MatchingConfig = MatchingConfig {
        matcher: MatcherConfig::SEED,
        noise: MatchNoise::SEED,
    };
}

/// What corrects the pose that odometry predicts.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Localiser {
    /// Nothing: dead reckoning.
    DeadReckoning,
    /// The seed's fix: the pose is replaced by the one two known tags in one picture give.
    TwoTagFix,
    /// The filter: every tag sighting updates the pose in proportion to its certainty.
    Filter,
}

/// A configuration the core refuses.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// Cells must be at least 1 mm.
    CellSize,
    /// Evidence must have `hit > 0 > miss`, positive thresholds below a positive clamp.
    Evidence,
    /// The camera's focal length must be positive.
    FocalLength,
    /// The depth sensor's range limit must be longer than a cell.
    MaxRange,
    /// Matching needs the filter, a window the matcher can search, and the core built
    /// with its `matching` feature.
    Matching,
}

impl SlamConfig {
    /// The robot's own sensors and tuning on a world's grid, with the tags whose places
    /// it knows: the two-tag fix as localiser, no matching. The world's numbers (grid,
    /// tags, start, route) are not the core's: the `world` crate reads them from a
    /// scenario file and overrides the sensors' calibration from it too.
    pub const fn on_grid(geometry: GridGeometry, tags: TagMap) -> SlamConfig {
        SlamConfig {
            geometry,
            evidence: Evidence::SEED,
            depth: DepthConfig::SEED,
            odometry: OdometryConfig::NOMINAL,
            camera: CameraConfig::SEED,
            tags,
            localiser: Localiser::TwoTagFix,
            fix: FixConfig::SEED,
            estimator: EstimatorConfig::SEED,
            matching: None,
            plausible: Some(PlausibleConfig::SEED),
        }
    }

    /// Checks the numbers the core divides by or relies on.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.geometry.cell_mm < 1 {
            return Err(ConfigError::CellSize);
        }
        let e = &self.evidence;
        if !(e.hit > 0 && e.miss < 0 && e.free_below > 0 && e.occupied_above > 0 && e.clamp > 0) {
            return Err(ConfigError::Evidence);
        }
        if e.free_below >= e.clamp || e.occupied_above >= e.clamp {
            return Err(ConfigError::Evidence);
        }
        if self.camera.focal_centipx <= 0 {
            return Err(ConfigError::FocalLength);
        }
        if (self.depth.max_range_mm as i32) <= self.geometry.cell_mm {
            return Err(ConfigError::MaxRange);
        }
        if let Some(m) = &self.matching {
            if self.localiser != Localiser::Filter || !cfg!(feature = "matching") {
                return Err(ConfigError::Matching);
            }
            Matcher::new(m.matcher, self.geometry.cell_mm).map_err(|_| ConfigError::Matching)?;
        }
        Ok(())
    }
}
