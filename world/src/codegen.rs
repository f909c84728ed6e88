//! The firmware's world as Rust: constants its `build.rs` writes into `$OUT_DIR` for an
//! `include!`.
//!
//! The text names its types bare (`GridGeometry`, `KnownTag`, `Pose`, `Angle`,
//! `OdometryConfig`, `CameraConfig`, `Leg`, `Duration`): the module that includes it
//! imports them. Every number in it comes from [`RobotWorld::of`], the conversion
//! `host-sim` configures its core with.

use crate::robot::{Leg, RobotWorld};
use std::fmt::Write as _;

/// The constants for `world` (built by [`RobotWorld::of`]), with `source` (the file's
/// path as given) in the header comment.
pub fn firmware_constants(world: &RobotWorld, source: &str) -> String {
    let c = &world.config;
    let g = &c.geometry;
    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(format!(
        "// Written by build.rs from {}: the world this image is built for.",
        source.escape_debug()
    ));
    line("/// The world's name, as its file gives it.".into());
    line(format!("pub const NAME: &str = {:?};", world.name));
    line("/// Grid columns: the world's extent plus its margin, at its cell size.".into());
    line(format!(
        "pub const GRID_COLUMNS: usize = {};",
        world.columns
    ));
    line("/// Grid rows.".into());
    line(format!("pub const GRID_ROWS: usize = {};", world.rows));
    line("/// Where the grid lies and its cell size.".into());
    line(format!(
        "pub const GEOMETRY: GridGeometry = GridGeometry {{ cell_mm: {}, origin_x_mm: {}, origin_y_mm: {} }};",
        g.cell_mm, g.origin_x_mm, g.origin_y_mm
    ));
    line("/// The tags whose places the core knows.".into());
    let mut tags = String::new();
    for t in &world.tags {
        let _ = write!(
            tags,
            "KnownTag {{ id: {}, x_mm: {}, y_mm: {} }}, ",
            t.id, t.x_mm, t.y_mm
        );
    }
    line(format!(
        "pub const TAGS: [KnownTag; {}] = [{tags}];",
        world.tags.len()
    ));
    line("/// The start, where the core starts believing the robot is.".into());
    line(format!(
        "pub const START: Pose = Pose {{ x_um: {}, y_um: {}, heading: Angle::from_bits({}) }};",
        world.start.x_um,
        world.start.y_um,
        world.start.heading.bits()
    ));
    line("/// The mapper's range limit, millimetres.".into());
    line(format!(
        "pub const DEPTH_MAX_RANGE_MM: u16 = {};",
        c.depth.max_range_mm
    ));
    let o = &c.odometry;
    line("/// The flow sensor's calibration and place.".into());
    line(format!(
        "pub const ODOMETRY: OdometryConfig = OdometryConfig {{ flow_um_per_count_q16: {}, gyro_scale_ppm: {}, flow_offset_um: [{}, {}] }};",
        o.flow_um_per_count_q16, o.gyro_scale_ppm, o.flow_offset_um[0], o.flow_offset_um[1]
    ));
    line("/// The tag camera's intrinsics.".into());
    line(format!(
        "pub const CAMERA: CameraConfig = CameraConfig {{ focal_centipx: {}, centre_centipx: {} }};",
        c.camera.focal_centipx, c.camera.centre_centipx
    ));
    line("/// The filter refuses tags beyond this, millimetres.".into());
    line(format!(
        "pub const CAMERA_MAX_RANGE_MM: u32 = {};",
        c.estimator.max_range_mm
    ));
    line("/// The filter refuses tags listed further off the camera's axis, millidegrees.".into());
    line(format!(
        "pub const CAMERA_HALF_VIEW_MDEG: u32 = {};",
        c.estimator.half_view_mdeg
    ));
    line("/// Wheel speed at full duty, millimetres per second.".into());
    line(format!(
        "pub const WHEEL_FULL_SPEED_MM_S: i64 = {};",
        world.drive.max_wheel_speed_mm_s
    ));
    line("/// Distance between the wheels, millimetres.".into());
    line(format!(
        "pub const WHEEL_BASE_MM: i64 = {};",
        world.drive.wheel_base_mm
    ));
    line(
        "/// The body's radius about the turning axis, millimetres: what the guard keeps clear."
            .into(),
    );
    line(format!(
        "pub const BODY_RADIUS_MM: u16 = {};",
        world.drive.radius_mm
    ));
    line("/// The route, in order.".into());
    let mut legs = String::new();
    for leg in &world.route {
        let _ = match *leg {
            Leg::Turn { mdeg, rate_mdps } => write!(
                legs,
                "Leg::Turn {{ mdeg: {mdeg}, rate_mdps: {rate_mdps} }}, "
            ),
            Leg::Drive { ms, speed_mm_s } => write!(
                legs,
                "Leg::Drive {{ time: Duration::from_millis({ms}), speed_mm_s: {speed_mm_s} }}, "
            ),
        };
    }
    line(format!(
        "pub const ROUTE: [Leg; {}] = [{legs}];",
        world.route.len()
    ));
    out
}
