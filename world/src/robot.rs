//! A scenario as the robot is built for it: the core's configuration, the start, the
//! grid's size, the route's legs and the drive, all in the core's integer units.
//!
//! `host-sim` configures its core with [`slam_config`] and the firmware's `build.rs` writes
//! a [`RobotWorld`] into constants ([`crate::codegen`]), so both fly the same numbers.

use crate::scenario::{RouteStep, Scenario};
use slam_core::{
    Angle, CameraConfig, DepthConfig, GridGeometry, KnownTag, OdometryConfig, Pose, SlamConfig,
    TagMap,
};
use std::fmt;

/// Most cells a side of the grid may have: the telemetry's `Hello` carries the size in a
/// `u16`, and a side this long is far past any RAM the robot has.
pub const MAX_GRID_SIDE: usize = 4096;

/// Why a valid scenario cannot be built into the robot.
#[derive(Debug, Clone, PartialEq)]
pub enum WorldError {
    /// The grid the world needs is longer a side than [`MAX_GRID_SIDE`].
    GridTooLarge {
        /// Columns needed.
        columns: usize,
        /// Rows needed.
        rows: usize,
    },
    /// The drive's numbers round to 0 mm, and the firmware divides by them.
    Drive,
    /// A route step whose time in milliseconds does not fit the firmware's clock.
    RouteStep {
        /// The step's index in `route`.
        index: usize,
    },
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WorldError::GridTooLarge { columns, rows } => write!(
                f,
                "the world needs a {columns} x {rows} grid, more than {MAX_GRID_SIDE} cells a \
                 side: raise grid.cell_mm or shrink the world"
            ),
            WorldError::Drive => write!(
                f,
                "scenario fields `robot.max_wheel_speed_mm_s` and `robot.wheel_base_mm`: \
                 must be at least 1 mm for the firmware"
            ),
            WorldError::RouteStep { index } => {
                write!(f, "scenario field `route[{index}]`: its time does not fit")
            }
        }
    }
}

impl std::error::Error for WorldError {}

/// One leg of the route as the firmware drives it: turns ended by its gyro, everything
/// else by its clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Leg {
    /// Turn on the spot by `mdeg` (positive clockwise) at `rate_mdps` (magnitude).
    Turn {
        /// Angle to turn, millidegrees.
        mdeg: i64,
        /// Turn rate, millidegrees per second.
        rate_mdps: i64,
    },
    /// Drive straight at `speed_mm_s` for `ms` (0 mm/s: stand still).
    Drive {
        /// How long, milliseconds.
        ms: u64,
        /// Forward speed, millimetres per second.
        speed_mm_s: i64,
    },
}

/// The differential drive: how duty becomes speed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Drive {
    /// Wheel speed at full duty, millimetres per second.
    pub max_wheel_speed_mm_s: i64,
    /// Distance between the wheels, millimetres.
    pub wheel_base_mm: i64,
    /// The body's radius about the turning axis, millimetres, rounded up.
    pub radius_mm: u16,
}

/// Everything the robot is built with for one world.
#[derive(Clone, Debug, PartialEq)]
pub struct RobotWorld {
    /// The scenario's name.
    pub name: String,
    /// The core's configuration (the two-tag fix as its localiser; the caller picks).
    pub config: SlamConfig,
    /// The tags in the core's map, in the file's order.
    pub tags: Vec<KnownTag>,
    /// Where the robot starts, and the core starts believing it is.
    pub start: Pose,
    /// Grid columns: see [`grid_size`].
    pub columns: usize,
    /// Grid rows.
    pub rows: usize,
    /// The route.
    pub route: Vec<Leg>,
    /// The drive.
    pub drive: Drive,
}

impl RobotWorld {
    /// The robot's build of a checked scenario (as [`Scenario::load`] gives it).
    pub fn of(s: &Scenario) -> Result<RobotWorld, WorldError> {
        let (columns, rows) = grid_size(s);
        if columns > MAX_GRID_SIDE || rows > MAX_GRID_SIDE {
            return Err(WorldError::GridTooLarge { columns, rows });
        }
        let drive = Drive {
            max_wheel_speed_mm_s: s.robot.max_wheel_speed_mm_s.round() as i64,
            wheel_base_mm: s.robot.wheel_base_mm.round() as i64,
            radius_mm: s.robot.radius_mm.ceil().clamp(0.0, f64::from(u16::MAX)) as u16,
        };
        if drive.max_wheel_speed_mm_s < 1 || drive.wheel_base_mm < 1 {
            return Err(WorldError::Drive);
        }
        Ok(RobotWorld {
            name: s.name.clone(),
            config: slam_config(s),
            tags: known_tags(s),
            start: start_pose(s),
            columns,
            rows,
            route: route_legs(s)?,
            drive,
        })
    }
}

impl RobotWorld {
    /// Bytes the core's grid takes: a log-odds value a cell.
    pub fn map_bytes(&self) -> usize {
        self.columns * self.rows * std::mem::size_of::<slam_core::LogOdds>()
    }
}

/// The tags in the core's units.
pub fn known_tags(s: &Scenario) -> Vec<KnownTag> {
    s.world
        .tags
        .iter()
        .map(|t| KnownTag {
            id: t.id,
            x_mm: t.x_mm.round() as i32,
            y_mm: t.y_mm.round() as i32,
        })
        .collect()
}

/// The start in the core's units.
pub fn start_pose(s: &Scenario) -> Pose {
    core_pose(s.start.x_mm, s.start.y_mm, s.start.heading_deg)
}

/// A pose in millimetres and degrees in the core's integer units.
pub fn core_pose(x_mm: f64, y_mm: f64, heading_deg: f64) -> Pose {
    Pose {
        x_um: (x_mm * 1000.0).round() as i32,
        y_um: (y_mm * 1000.0).round() as i32,
        heading: Angle::from_millidegrees((heading_deg * 1000.0).round() as i64),
    }
}

/// The core's configuration for a scenario: the robot's own tuning
/// ([`SlamConfig::on_grid`]) with the world's grid and tags and the scenario's sensors.
pub fn slam_config(s: &Scenario) -> SlamConfig {
    let geometry = GridGeometry {
        cell_mm: s.grid.cell_mm,
        origin_x_mm: s.grid.origin_x_mm,
        origin_y_mm: s.grid.origin_y_mm,
    };
    let mut config = SlamConfig::on_grid(geometry, TagMap::new(&known_tags(s)).unwrap_or_default());
    config.depth = DepthConfig {
        beam_angles: slam_core::slam::fan((s.sensors.tof.fov_deg * 1000.0).round() as i64),
        max_range_mm: s.grid.max_range_mm,
    };
    config.odometry = OdometryConfig {
        flow_um_per_count_q16: (s.sensors.flow.um_per_count * 65536.0).round() as i32,
        gyro_scale_ppm: 0,
        flow_offset_um: s
            .sensors
            .flow
            .offset_mm
            .map(|mm| (mm * 1000.0).round() as i32),
    };
    config.camera = CameraConfig {
        focal_centipx: (s.sensors.camera.focal_px * 100.0).round() as i32,
        centre_centipx: (s.sensors.camera.width_px * 50.0).round() as i32,
    };
    // The filter refuses what this camera cannot see: beyond its range, or a tag whose
    // listed place is outside its view (with 10 degrees for the pose's own error).
    config.estimator.max_range_mm = s.sensors.camera.max_range_mm.round() as u32;
    config.estimator.half_view_mdeg = (s.sensors.camera.fov_deg * 500.0 + 10_000.0).round() as u32;
    config
}

/// The grid a world needs, (columns, rows): from the grid's origin to as far past the
/// furthest wall, tag or start as the origin lies before the nearest, at the world's cell
/// size. A world framed by its origin with a margin gets the same margin on the far side.
pub fn grid_size(s: &Scenario) -> (usize, usize) {
    let cell = f64::from(s.grid.cell_mm.max(1));
    let points = s.placed_points();
    let side = |origin: i32, of: fn(&(String, crate::solid::Vec2)) -> f64| {
        let (lo, hi) = points
            .iter()
            .map(of)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        let origin = f64::from(origin);
        let margin = (lo - origin).max(0.0);
        let cells = ((hi - origin + margin) / cell).ceil();
        // Validation keeps every point on the grid's side of the origin and within
        // 100 m of it, so this is finite and small; at least one cell past the furthest.
        (cells.max(((hi - origin) / cell).floor() + 1.0)).max(1.0) as usize
    };
    (
        side(s.grid.origin_x_mm, |p| p.1.x),
        side(s.grid.origin_y_mm, |p| p.1.y),
    )
}

/// The route as the firmware drives it: a drive over a distance becomes a drive for the
/// time it takes at its speed, a wait a drive at 0 mm/s.
pub fn route_legs(s: &Scenario) -> Result<Vec<Leg>, WorldError> {
    let ms = |index: usize, seconds: f64| {
        let ms = (seconds * 1000.0).round();
        if ms.is_finite() && (0.0..=u32::MAX as f64).contains(&ms) {
            Ok(ms as u64)
        } else {
            Err(WorldError::RouteStep { index })
        }
    };
    s.route
        .iter()
        .enumerate()
        .map(|(i, step)| match *step {
            RouteStep::Turn { degrees, rate_dps } => Ok(Leg::Turn {
                mdeg: (degrees * 1000.0).round() as i64,
                rate_mdps: (rate_dps * 1000.0).round() as i64,
            }),
            RouteStep::Drive {
                seconds,
                speed_mm_s,
            } => Ok(Leg::Drive {
                ms: ms(i, seconds)?,
                speed_mm_s: speed_mm_s.round() as i64,
            }),
            RouteStep::DriveDistance {
                distance_mm,
                speed_mm_s,
            } => Ok(Leg::Drive {
                ms: ms(i, distance_mm / speed_mm_s)?,
                speed_mm_s: speed_mm_s.round() as i64,
            }),
            RouteStep::Wait { seconds } => Ok(Leg::Drive {
                ms: ms(i, seconds)?,
                speed_mm_s: 0,
            }),
        })
        .collect()
}
