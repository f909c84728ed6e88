//! What the 3D panel draws besides the map: poses in metres, the tags at their listed
//! places, the tags seen this tick, and the filter's 3-sigma ellipse.
//!
//! The map frame is the grid's: x to the right of the mat, y up it, metres (REP-103); the
//! robot's heading, degrees clockwise from +y, is a yaw of 90 degrees minus it.

use crate::record::Belief;
use crate::scenario::Scenario;
use ::foxglove::messages::{
    line_primitive, Color, CubePrimitive, CylinderPrimitive, LinePrimitive, Point3, Pose,
    Quaternion, SceneEntity, SceneUpdate, TextPrimitive, Timestamp, Vector3,
};
use slam_core::{CameraConfig, KnownTag, TagDetection};

/// The frame everything is drawn in.
pub const MAP_FRAME: &str = "map";
/// The robot's frame, placed by the estimated pose.
pub const ROBOT_FRAME: &str = "base_link";

/// A tag card's side as drawn, metres (the seed's cards are 10 cm).
const TAG_SIDE_M: f64 = 0.1;

/// What the viewer knows of the world besides the stream: the tags' listed places and
/// the camera that turns a picture column into a bearing.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The tags the robot was given, at their listed places.
    pub tags: Vec<KnownTag>,
    /// The camera's intrinsics.
    pub camera: CameraConfig,
}

impl Stage {
    /// The robot a scenario describes (as `host-sim run` flies it).
    pub fn of(scenario: &Scenario) -> Stage {
        let config = crate::run::slam_config(scenario);
        Stage {
            tags: config.tags.as_slice().to_vec(),
            camera: config.camera,
        }
    }

    /// The firmware's default world (the seed mat's tags and camera), for a stream
    /// viewed without `--scenario`; a robot built for another world needs its file.
    pub fn firmware() -> Stage {
        Stage {
            tags: world::shipped::seed_robot().tags.to_vec(),
            camera: world::shipped::seed_robot().config.camera,
        }
    }
}

/// A pose in the map frame: millimetres and degrees clockwise from +y, to metres and a
/// rotation about z.
pub fn pose_m(x_mm: f64, y_mm: f64, heading_deg: f64) -> Pose {
    let yaw = (90.0 - heading_deg).to_radians();
    Pose {
        position: Some(Vector3 {
            x: x_mm / 1000.0,
            y: y_mm / 1000.0,
            z: 0.0,
        }),
        orientation: Some(yaw_quaternion(yaw)),
    }
}

/// The rotation by `yaw` radians about z.
pub fn yaw_quaternion(yaw: f64) -> Quaternion {
    Quaternion {
        x: 0.0,
        y: 0.0,
        z: (yaw / 2.0).sin(),
        w: (yaw / 2.0).cos(),
    }
}

fn color(r: f64, g: f64, b: f64, a: f64) -> Option<Color> {
    Some(Color { r, g, b, a })
}

fn point(x_mm: f64, y_mm: f64) -> Point3 {
    Point3 {
        x: x_mm / 1000.0,
        y: y_mm / 1000.0,
        z: 0.0,
    }
}

/// One entity in the map frame, replacing the last one of the same `id`.
fn entity(id: &str, timestamp: Timestamp) -> SceneEntity {
    SceneEntity {
        timestamp: Some(timestamp),
        frame_id: MAP_FRAME.to_string(),
        id: id.to_string(),
        ..SceneEntity::default()
    }
}

/// The tags at their listed places: a card and its id each.
pub fn tags(stage: &Stage, timestamp: Timestamp) -> SceneUpdate {
    let mut e = entity("tags", timestamp);
    for t in &stage.tags {
        let (x, y) = (f64::from(t.x_mm), f64::from(t.y_mm));
        e.cubes.push(CubePrimitive {
            pose: Some(pose_m(x, y, 0.0)),
            size: Some(Vector3 {
                x: TAG_SIDE_M,
                y: TAG_SIDE_M,
                z: 0.02,
            }),
            color: color(0.1, 0.1, 0.1, 1.0),
        });
        e.texts.push(TextPrimitive {
            pose: Some(pose_m(x, y + 80.0, 0.0)),
            billboard: true,
            font_size: 14.0,
            scale_invariant: true,
            color: color(1.0, 1.0, 1.0, 1.0),
            text: format!("tag {}", t.id),
        });
    }
    SceneUpdate {
        entities: vec![e],
        ..SceneUpdate::default()
    }
}

/// Where a sighting puts its tag: `distance_mm` along the camera's bearing to its
/// column, from the robot at `(x_mm, y_mm)` heading `heading_deg`.
pub fn sighted_at(
    camera: &CameraConfig,
    (x_mm, y_mm, heading_deg): (f64, f64, f64),
    d: &TagDetection,
) -> (f64, f64) {
    let offset = f64::from(d.cx_centipx) - f64::from(camera.centre_centipx);
    let bearing = offset.atan2(f64::from(camera.focal_centipx.max(1)));
    let direction = heading_deg.to_radians() + bearing;
    let range = f64::from(d.distance_mm);
    (
        x_mm + range * direction.sin(),
        y_mm + range * direction.cos(),
    )
}

/// The tags seen in the tick's picture: a line from the robot to where each reading
/// puts its tag, and the id there. No sightings gives an empty entity, which clears the
/// last tick's.
pub fn sightings(
    stage: &Stage,
    robot: (f64, f64, f64),
    seen: &[TagDetection],
    timestamp: Timestamp,
) -> SceneUpdate {
    let mut e = entity("sightings", timestamp);
    let mut points = Vec::new();
    for d in seen {
        let (x, y) = sighted_at(&stage.camera, robot, d);
        points.push(point(robot.0, robot.1));
        points.push(point(x, y));
        e.texts.push(TextPrimitive {
            pose: Some(pose_m(x, y - 80.0, 0.0)),
            billboard: true,
            font_size: 12.0,
            scale_invariant: true,
            color: color(1.0, 0.8, 0.0, 1.0),
            text: format!("{} at {} mm", d.id, d.distance_mm),
        });
    }
    if !points.is_empty() {
        e.lines.push(LinePrimitive {
            r#type: line_primitive::Type::LineList as i32,
            thickness: 2.0,
            scale_invariant: true,
            points,
            color: color(1.0, 0.8, 0.0, 1.0),
            ..LinePrimitive::default()
        });
    }
    SceneUpdate {
        entities: vec![e],
        ..SceneUpdate::default()
    }
}

/// The filter's 3-sigma position ellipse round the robot at `(x_mm, y_mm)`: a flat
/// cylinder whose axes are 3 times the roots of the covariance's eigenvalues.
pub fn ellipse(belief: &Belief, (x_mm, y_mm): (f64, f64), timestamp: Timestamp) -> SceneUpdate {
    let (major, minor, angle) = belief.position_axes();
    let mut e = entity("ellipse", timestamp);
    e.cylinders.push(CylinderPrimitive {
        pose: Some(Pose {
            position: Some(Vector3 {
                x: x_mm / 1000.0,
                y: y_mm / 1000.0,
                z: 0.0,
            }),
            orientation: Some(yaw_quaternion(angle)),
        }),
        size: Some(Vector3 {
            x: 2.0 * 3.0 * major.sqrt() / 1000.0,
            y: 2.0 * 3.0 * minor.sqrt() / 1000.0,
            z: 0.002,
        }),
        bottom_scale: 1.0,
        top_scale: 1.0,
        color: color(1.0, 0.3, 0.3, 0.4),
    });
    SceneUpdate {
        entities: vec![e],
        ..SceneUpdate::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headings_turn_into_yaws() {
        // Heading 0 faces +y: a yaw of 90 degrees.
        let q = pose_m(1000.0, 500.0, 0.0).orientation.expect("rotation");
        assert!((q.z - (std::f64::consts::FRAC_PI_4).sin()).abs() < 1e-12);
        let p = pose_m(1000.0, 500.0, 0.0).position.expect("position");
        assert_eq!((p.x, p.y), (1.0, 0.5));
    }

    #[test]
    fn a_tag_straight_ahead_is_seen_ahead() {
        let camera = CameraConfig::SEED;
        let d = TagDetection {
            id: 11,
            cx_centipx: camera.centre_centipx,
            distance_mm: 1000,
        };
        let (x, y) = sighted_at(&camera, (100.0, 200.0, 90.0), &d);
        assert!(
            (x - 1100.0).abs() < 1e-9 && (y - 200.0).abs() < 1e-9,
            "{x} {y}"
        );
        // Right of centre: clockwise of the nose.
        let right = TagDetection {
            cx_centipx: camera.centre_centipx + camera.focal_centipx,
            ..d
        };
        let (x, y) = sighted_at(&camera, (0.0, 0.0, 0.0), &right);
        assert!(x > 0.0 && (x - y).abs() < 1e-9, "{x} {y}");
    }
}
