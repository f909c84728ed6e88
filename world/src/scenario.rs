//! Scenario files: the world, the start, the sensors, the route and the random seed.
//!
//! Parsed from TOML with `serde`, then checked field by field: every number must be
//! finite and inside a range that makes physical sense, the name must be usable as a file
//! name, the world must lie on its grid's side of the origin, and the start clear of the
//! walls. The error names the field. See the crate documentation for the schema.

use crate::solid::{point_segment_distance, Vec2, World as SolidWorld};
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};
use std::fmt;
use std::io::Read as _;
use std::path::Path;

pub use crate::shipped::SHIPPED;

/// A wall segment, `[[x0, y0], [x1, y1]]` in millimetres.
pub type Segment = [[f64; 2]; 2];

/// A whole scenario.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// A short name, used in titles and in the pictures' file names (so letters, digits,
    /// `-`, `_` and `.` only, not starting with `.`).
    pub name: String,
    /// Seed of the random noise (`--seed` overrides it).
    pub seed: u64,
    /// The mat, its walls and its tags.
    pub world: World,
    /// The robot's true starting pose; the core starts believing it.
    pub start: Start,
    /// The robot's drive, for runs where the firmware commands the motors.
    pub robot: Robot,
    /// Sensor models.
    pub sensors: Sensors,
    /// The grid the core maps into.
    pub grid: Grid,
    /// What the robot does, in order.
    pub route: Vec<RouteStep>,
}

/// The world: walls and tags.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct World {
    /// Every wall and box edge as a segment in millimetres.
    #[serde(deserialize_with = "segments")]
    pub walls: Vec<Segment>,
    /// AprilTags on cards. Optional: a world without tags has none (the core's tag map
    /// is then empty, and only odometry places the robot).
    #[serde(default)]
    pub tags: Vec<Tag>,
    /// An occupied cell whose centre is within this of a wall is "in place", millimetres.
    pub wall_tolerance_mm: f64,
}

/// An AprilTag card standing in the world.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Tag {
    /// The tag's id; the core knows its place.
    pub id: u16,
    /// Centre x, millimetres.
    pub x_mm: f64,
    /// Centre y, millimetres.
    pub y_mm: f64,
    /// Width of the card, millimetres; the depth sensor sees it as a wall.
    pub width_mm: f64,
    /// Direction the printed face points, degrees clockwise from +y (180: towards -y).
    pub facing_deg: f64,
}

/// The robot's start.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Start {
    /// Millimetres.
    pub x_mm: f64,
    /// Millimetres.
    pub y_mm: f64,
    /// Degrees clockwise from +y.
    pub heading_deg: f64,
}

/// The differential drive: how motor duty becomes motion.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Robot {
    /// Wheel speed at full duty, millimetres per second.
    pub max_wheel_speed_mm_s: f64,
    /// Distance between the wheels, millimetres.
    pub wheel_base_mm: f64,
    /// The body's radius about the turning axis, millimetres: the circle that collides
    /// with walls, and what the guard keeps clear of them. Optional: the seed robot's
    /// [`SEED_RADIUS_MM`].
    #[serde(default = "seed_radius_mm")]
    pub radius_mm: f64,
    /// How the wheels slip on the floor. Optional: absent, the robot moves exactly as
    /// commanded.
    #[serde(default)]
    pub slip: Option<Slip>,
}

/// The seed robot's body radius, millimetres (the firmware's `GuardConfig::SEED`).
pub const SEED_RADIUS_MM: f64 = 60.0;

fn seed_radius_mm() -> f64 {
    SEED_RADIUS_MM
}

/// Wheel slip: the robot's true motion differs from what its motors are asked for.
///
/// Two effects, each seeded from its own random stream. Spells of lost speed: at random
/// moments (on average `spells_per_min` a minute) the wheels lose grip for `spell_s`
/// seconds, and the robot moves and turns `speed_loss` slower than commanded. Skid in
/// turns: while it turns, the robot's centre slides over the floor, on average
/// `skid_mm_per_turn` millimetres per full turn, in a direction drawn afresh at the start
/// of each turn, by an amount drawn evenly between none and twice the average. The flow
/// sensor sees the true motion, so slip reaches odometry through the slide (read in a
/// turning frame) and through the flow sensor's offset from the turning axis.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Slip {
    /// How often a spell of lost speed starts, on average, per minute (0: never).
    pub spells_per_min: f64,
    /// How long a spell lasts, seconds.
    pub spell_s: f64,
    /// Share of the commanded speed and turn rate lost during a spell, 0 to 1.
    pub speed_loss: f64,
    /// Average slide of the robot's centre per full turn, millimetres (0: none).
    pub skid_mm_per_turn: f64,
}

/// All sensor models.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    /// The 8-zone time-of-flight depth sensor.
    pub tof: Tof,
    /// The optical-flow sensor.
    pub flow: Flow,
    /// The gyro.
    pub gyro: Gyro,
    /// The tag camera.
    pub camera: Camera,
}

/// Time-of-flight depth sensor: 8 beams at the centres of 8 equal zones across its fan.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Tof {
    /// Width of the fan, degrees (45 for the seed).
    pub fov_deg: f64,
    /// Beyond this, millimetres, a zone reports no target.
    pub max_range_mm: f64,
    /// Standard deviation of range noise, millimetres.
    pub noise_mm: f64,
    /// Chance that a zone has no valid return in a frame, 0 to 1.
    pub dropout: f64,
    /// Range noise that grows with distance: extra standard deviation per metre of range,
    /// millimetres. Optional: 0, the same noise at every range.
    #[serde(default)]
    pub noise_per_m_mm: f64,
    /// Chance, 0 to 1, that a zone whose edges fall on two surfaces at different depths
    /// (a corner's edge, a box in front of a wall) reports a range between the two rather
    /// than its centre's. Optional: 0, a zone reads along its centre line.
    #[serde(default)]
    pub mixed_edge: f64,
    /// Frames the sensor ranges a second, on its own clock (the firmware sets 15, the
    /// VL53L5CX's most at 8x8 zones), 1 to 60: each tick takes the newest frame, as old as
    /// the sensor's clock makes it. Optional: 0, a frame ranged at every tick, at its
    /// moment.
    #[serde(default)]
    pub rate_hz: f64,
}

/// Optical flow, looking at the floor under the robot.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Flow {
    /// What the firmware believes one count is, micrometres (its calibration).
    pub um_per_count: f64,
    /// The sensor's true scale relative to that belief, e.g. -0.03 reads 3 % short.
    pub scale_error: f64,
    /// Standard deviation of noise per 10 ms reading, counts.
    pub noise_counts: f64,
    /// Surface quality reported (0 to 255); below the core's gate the reading is dropped.
    pub quality: u8,
    /// Where the sensor sits from the robot's turning axis, `[forward, right]` in
    /// millimetres. Optional: `[0, 0]`, on the axis. Off the axis, the sensor sees the floor
    /// move under its own position, so a turn on the spot shows as flow.
    #[serde(default, deserialize_with = "pair")]
    pub offset_mm: [f64; 2],
}

/// Gyro, yaw axis.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Gyro {
    /// Bias left after the start-up calibration, degrees per second.
    pub bias_dps: f64,
    /// True scale relative to nominal, e.g. 0.008 reads 0.8 % high.
    pub scale_error: f64,
    /// Standard deviation of noise per 5 ms sample, degrees per second.
    pub noise_dps: f64,
    /// How fast the bias wanders: a random walk whose spread grows by this much per
    /// square root of a second, degrees per second. Optional: 0, a bias that stays put.
    #[serde(default)]
    pub bias_walk_dps_per_sqrt_s: f64,
}

/// The tag camera co-processor.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    /// Picture width, pixels.
    pub width_px: f64,
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Tags further than this are not read, millimetres.
    pub max_range_mm: f64,
    /// Tags seen more than this far off their face normal are not read, degrees.
    pub max_incidence_deg: f64,
    /// Standard deviation of the centre column, pixels.
    pub pixel_noise_px: f64,
    /// Standard deviation of the distance, millimetres.
    pub distance_noise_mm: f64,
    /// How old a picture's tags are when the tick uses them, milliseconds: the camera
    /// reports what it saw from the pose this long before, and the frame carries the age.
    /// Optional: 0 (the picture taken at the tick) when absent.
    #[serde(default)]
    pub latency_ms: f64,
}

/// The core's grid.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    /// Cell side, millimetres.
    pub cell_mm: i32,
    /// Map x of the grid's lower-left corner, millimetres.
    pub origin_x_mm: i32,
    /// Map y of the grid's lower-left corner, millimetres.
    pub origin_y_mm: i32,
    /// The mapper ignores hits at or beyond this range, millimetres (170 cm in the seed).
    pub max_range_mm: u16,
}

/// One step of the route.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "action", rename_all = "snake_case", deny_unknown_fields)]
pub enum RouteStep {
    /// Turn on the spot until the true heading has turned `degrees` (the seed steers by truth).
    Turn {
        /// How far, degrees; positive clockwise.
        degrees: f64,
        /// How fast, degrees per second (positive).
        rate_dps: f64,
    },
    /// Drive straight for a time.
    Drive {
        /// How long, seconds.
        seconds: f64,
        /// How fast, millimetres per second.
        speed_mm_s: f64,
    },
    /// Drive straight for a distance (by truth).
    DriveDistance {
        /// How far, millimetres (positive).
        distance_mm: f64,
        /// How fast, millimetres per second (positive).
        speed_mm_s: f64,
    },
    /// Stand still.
    Wait {
        /// How long, seconds.
        seconds: f64,
    },
}

/// Why a scenario was refused.
#[derive(Debug)]
pub enum ScenarioError {
    /// The file could not be read.
    Io(std::io::Error),
    /// The file is longer than any scenario, in bytes.
    TooLong {
        /// The longest a scenario file may be.
        max: u64,
    },
    /// Not valid TOML, or a field missing or of the wrong type (toml names it).
    Parse(String),
    /// A field whose value makes no sense.
    Invalid {
        /// Dotted path of the field, e.g. `sensors.gyro.noise_dps`.
        field: String,
        /// What is wrong with it.
        problem: String,
    },
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScenarioError::Io(e) => write!(f, "cannot read scenario: {e}"),
            ScenarioError::TooLong { max } => {
                write!(
                    f,
                    "scenario file is longer than {max} bytes: is it a scenario?"
                )
            }
            ScenarioError::Parse(e) => write!(f, "scenario is not valid: {e}"),
            ScenarioError::Invalid { field, problem } => {
                write!(f, "scenario field `{field}`: {problem}")
            }
        }
    }
}

impl std::error::Error for ScenarioError {}

/// `world.walls`, refusing a wall that is not exactly two points of exactly two numbers
/// (a fixed-size array would take the first two and drop the rest without a word).
fn segments<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Segment>, D::Error> {
    let walls = Vec::<Vec<Vec<f64>>>::deserialize(d)?;
    walls
        .iter()
        .enumerate()
        .map(|(i, wall)| match wall.as_slice() {
            [a, b] => match (a.as_slice(), b.as_slice()) {
                ([x0, y0], [x1, y1]) => Ok([[*x0, *y0], [*x1, *y1]]),
                _ => Err(D::Error::custom(format!(
                    "world.walls[{i}]: a point is [x, y], got points of {} and {} numbers",
                    a.len(),
                    b.len()
                ))),
            },
            _ => Err(D::Error::custom(format!(
                "world.walls[{i}]: a wall is two points [[x0, y0], [x1, y1]], got {} points",
                wall.len()
            ))),
        })
        .collect()
}

/// `sensors.flow.offset_mm`, refusing anything but exactly two numbers (see [`segments`]).
fn pair<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    match Vec::<f64>::deserialize(d)?.as_slice() {
        [a, b] => Ok([*a, *b]),
        other => Err(D::Error::custom(format!(
            "sensors.flow.offset_mm is [forward, right], got {} numbers",
            other.len()
        ))),
    }
}

/// Accumulates the first invalid field.
struct Check(Result<(), ScenarioError>);

impl Check {
    fn range(&mut self, field: &str, value: f64, lo: f64, hi: f64) {
        if self.0.is_err() {
            return;
        }
        if !value.is_finite() {
            self.fail(field, format!("must be a finite number, got {value}"));
        } else if value < lo || value > hi {
            self.fail(field, format!("must be between {lo} and {hi}, got {value}"));
        }
    }

    /// `value` must be at least `lo` (a floor above 0 that the core's integer units need).
    fn at_least(&mut self, field: &str, value: f64, lo: f64, hi: f64) {
        self.range(field, value, lo, hi);
    }

    fn positive(&mut self, field: &str, value: f64, hi: f64) {
        self.range(field, value, 0.0, hi);
        if self.0.is_ok() && value <= 0.0 {
            self.fail(field, format!("must be greater than 0, got {value}"));
        }
    }

    fn fail(&mut self, field: &str, problem: String) {
        if self.0.is_ok() {
            self.0 = Err(ScenarioError::Invalid {
                field: field.to_string(),
                problem,
            });
        }
    }
}

/// Longest scenario file, bytes: the shipped ones are a few kilobytes (a longer file, or
/// a device that never ends, is refused after this many bytes).
pub const MAX_SCENARIO_BYTES: u64 = 1 << 20;

/// Largest coordinate or length a scenario may use, millimetres (a 100 m hall).
const MAX_MM: f64 = 100_000.0;

/// Furthest the flow sensor may sit from the turning axis, millimetres: further is off a
/// robot of BugBot's size altogether.
const MAX_FLOW_OFFSET_MM: f64 = 500.0;

/// Largest average slide per full turn, millimetres: a metre a turn is no longer a
/// wheeled robot turning.
const MAX_SKID_MM_PER_TURN: f64 = 1000.0;

/// Longest scenario name, characters.
const MAX_NAME_LEN: usize = 64;

/// Shortest focal length and picture width, pixels: the core takes them in hundredths of
/// a pixel and refuses a focal length that rounds to 0; no real camera is near 1 px.
const MIN_CAMERA_PX: f64 = 1.0;

/// Smallest and largest flow calibration, micrometres per count: the core takes it as a
/// 16.16 fixed-point `i32`, which rounds below the one and overflows above the other.
const MIN_UM_PER_COUNT: f64 = 0.01;
const MAX_UM_PER_COUNT: f64 = 10_000.0;

/// Longest camera latency a scenario may ask for, milliseconds: a second of pictures is
/// well past what the core's pose history places (it refuses them as too old), so
/// longer ones test nothing more.
pub const MAX_CAMERA_LATENCY_MS: f64 = 1000.0;

impl Scenario {
    /// Reads and checks a scenario file.
    pub fn load(path: &Path) -> Result<Scenario, ScenarioError> {
        let max = MAX_SCENARIO_BYTES;
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(max + 1).read_to_end(&mut bytes))
            .map_err(ScenarioError::Io)?;
        if bytes.len() as u64 > max {
            return Err(ScenarioError::TooLong { max });
        }
        let text = String::from_utf8(bytes)
            .map_err(|e| ScenarioError::Parse(format!("not UTF-8: {e}")))?;
        Scenario::parse(&text)
    }

    /// Parses and checks scenario text.
    pub fn parse(text: &str) -> Result<Scenario, ScenarioError> {
        let scenario: Scenario =
            toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Every point the world is placed by, with its field: the walls' ends, the tags'
    /// centres and the start. The grid must hold all of them.
    pub fn placed_points(&self) -> Vec<(String, Vec2)> {
        let walls = self.world.walls.iter().enumerate().flat_map(|(i, w)| {
            w.iter()
                .enumerate()
                .map(move |(j, p)| (format!("world.walls[{i}][{j}]"), Vec2::new(p[0], p[1])))
        });
        let tags = self.world.tags.iter().enumerate().map(|(i, t)| {
            (
                format!("world.tags[{i}] (x_mm, y_mm)"),
                Vec2::new(t.x_mm, t.y_mm),
            )
        });
        let start = std::iter::once((
            "start (x_mm, y_mm)".to_string(),
            Vec2::new(self.start.x_mm, self.start.y_mm),
        ));
        walls.chain(tags).chain(start).collect()
    }

    /// Checks every field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        let mut c = Check(Ok(()));
        check_name(&mut c, &self.name);
        if self.world.walls.is_empty() {
            c.fail("world.walls", "needs at least one wall".into());
        }
        for (i, w) in self.world.walls.iter().enumerate() {
            for (j, p) in w.iter().enumerate() {
                c.range(&format!("world.walls[{i}][{j}][0]"), p[0], -MAX_MM, MAX_MM);
                c.range(&format!("world.walls[{i}][{j}][1]"), p[1], -MAX_MM, MAX_MM);
            }
            if c.0.is_ok() && w[0] == w[1] {
                c.fail(&format!("world.walls[{i}]"), "has zero length".into());
            }
        }
        c.positive(
            "world.wall_tolerance_mm",
            self.world.wall_tolerance_mm,
            1000.0,
        );
        for (i, t) in self.world.tags.iter().enumerate() {
            let f = |name: &str| format!("world.tags[{i}].{name}");
            c.range(&f("x_mm"), t.x_mm, -MAX_MM, MAX_MM);
            c.range(&f("y_mm"), t.y_mm, -MAX_MM, MAX_MM);
            c.positive(&f("width_mm"), t.width_mm, 2000.0);
            c.range(&f("facing_deg"), t.facing_deg, -360.0, 360.0);
            if self.world.tags.iter().take(i).any(|o| o.id == t.id) {
                c.fail(&f("id"), format!("tag id {} appears twice", t.id));
            }
        }
        if self.world.tags.len() > slam_core::tagfix::MAX_KNOWN_TAGS {
            c.fail(
                "world.tags",
                format!("at most {} tags", slam_core::tagfix::MAX_KNOWN_TAGS),
            );
        }
        c.range("start.x_mm", self.start.x_mm, -MAX_MM, MAX_MM);
        c.range("start.y_mm", self.start.y_mm, -MAX_MM, MAX_MM);
        c.range("start.heading_deg", self.start.heading_deg, -360.0, 360.0);

        c.positive(
            "robot.max_wheel_speed_mm_s",
            self.robot.max_wheel_speed_mm_s,
            5000.0,
        );
        c.positive("robot.wheel_base_mm", self.robot.wheel_base_mm, 2000.0);
        c.positive("robot.radius_mm", self.robot.radius_mm, 1000.0);
        if let Some(slip) = &self.robot.slip {
            c.range("robot.slip.spells_per_min", slip.spells_per_min, 0.0, 600.0);
            c.positive("robot.slip.spell_s", slip.spell_s, 60.0);
            c.range("robot.slip.speed_loss", slip.speed_loss, 0.0, 1.0);
            c.range(
                "robot.slip.skid_mm_per_turn",
                slip.skid_mm_per_turn,
                0.0,
                MAX_SKID_MM_PER_TURN,
            );
        }
        let s = &self.sensors;
        c.positive("sensors.tof.fov_deg", s.tof.fov_deg, 180.0);
        c.positive("sensors.tof.max_range_mm", s.tof.max_range_mm, 65_000.0);
        c.range("sensors.tof.noise_mm", s.tof.noise_mm, 0.0, 1000.0);
        c.range("sensors.tof.dropout", s.tof.dropout, 0.0, 1.0);
        c.range(
            "sensors.tof.noise_per_m_mm",
            s.tof.noise_per_m_mm,
            0.0,
            1000.0,
        );
        c.range("sensors.tof.mixed_edge", s.tof.mixed_edge, 0.0, 1.0);
        if s.tof.rate_hz != 0.0 {
            c.range("sensors.tof.rate_hz", s.tof.rate_hz, 1.0, 60.0);
        }
        c.at_least(
            "sensors.flow.um_per_count",
            s.flow.um_per_count,
            MIN_UM_PER_COUNT,
            MAX_UM_PER_COUNT,
        );
        c.range("sensors.flow.scale_error", s.flow.scale_error, -0.5, 0.5);
        c.range("sensors.flow.noise_counts", s.flow.noise_counts, 0.0, 100.0);
        c.range(
            "sensors.flow.offset_mm[0]",
            s.flow.offset_mm[0],
            -MAX_FLOW_OFFSET_MM,
            MAX_FLOW_OFFSET_MM,
        );
        c.range(
            "sensors.flow.offset_mm[1]",
            s.flow.offset_mm[1],
            -MAX_FLOW_OFFSET_MM,
            MAX_FLOW_OFFSET_MM,
        );
        c.range("sensors.gyro.bias_dps", s.gyro.bias_dps, -100.0, 100.0);
        c.range("sensors.gyro.scale_error", s.gyro.scale_error, -0.5, 0.5);
        c.range("sensors.gyro.noise_dps", s.gyro.noise_dps, 0.0, 100.0);
        c.range(
            "sensors.gyro.bias_walk_dps_per_sqrt_s",
            s.gyro.bias_walk_dps_per_sqrt_s,
            0.0,
            10.0,
        );
        c.at_least(
            "sensors.camera.width_px",
            s.camera.width_px,
            MIN_CAMERA_PX,
            10_000.0,
        );
        c.at_least(
            "sensors.camera.focal_px",
            s.camera.focal_px,
            MIN_CAMERA_PX,
            10_000.0,
        );
        c.positive("sensors.camera.fov_deg", s.camera.fov_deg, 179.0);
        c.positive(
            "sensors.camera.max_range_mm",
            s.camera.max_range_mm,
            65_000.0,
        );
        c.positive(
            "sensors.camera.max_incidence_deg",
            s.camera.max_incidence_deg,
            90.0,
        );
        c.range(
            "sensors.camera.pixel_noise_px",
            s.camera.pixel_noise_px,
            0.0,
            100.0,
        );
        c.range(
            "sensors.camera.distance_noise_mm",
            s.camera.distance_noise_mm,
            0.0,
            1000.0,
        );
        c.range(
            "sensors.camera.latency_ms",
            s.camera.latency_ms,
            0.0,
            MAX_CAMERA_LATENCY_MS,
        );

        c.range("grid.cell_mm", self.grid.cell_mm as f64, 5.0, 1000.0);
        c.range(
            "grid.origin_x_mm",
            self.grid.origin_x_mm as f64,
            -MAX_MM,
            MAX_MM,
        );
        c.range(
            "grid.origin_y_mm",
            self.grid.origin_y_mm as f64,
            -MAX_MM,
            MAX_MM,
        );
        if c.0.is_ok() && (self.grid.max_range_mm as i32) <= self.grid.cell_mm {
            c.fail("grid.max_range_mm", "must be longer than one cell".into());
        }
        if c.0.is_ok() {
            self.check_placement(&mut c);
        }

        if self.route.is_empty() {
            c.fail("route", "needs at least one step".into());
        }
        for (i, step) in self.route.iter().enumerate() {
            let f = |name: &str| format!("route[{i}].{name}");
            match step {
                RouteStep::Turn { degrees, rate_dps } => {
                    c.range(&f("degrees"), *degrees, -36_000.0, 36_000.0);
                    c.positive(&f("rate_dps"), *rate_dps, 1000.0);
                }
                RouteStep::Drive {
                    seconds,
                    speed_mm_s,
                } => {
                    c.positive(&f("seconds"), *seconds, 3600.0);
                    c.range(&f("speed_mm_s"), *speed_mm_s, -2000.0, 2000.0);
                }
                RouteStep::DriveDistance {
                    distance_mm,
                    speed_mm_s,
                } => {
                    c.positive(&f("distance_mm"), *distance_mm, MAX_MM);
                    c.positive(&f("speed_mm_s"), *speed_mm_s, 2000.0);
                }
                RouteStep::Wait { seconds } => c.positive(&f("seconds"), *seconds, 3600.0),
            }
        }
        c.0
    }

    /// The world on the grid's side of its origin, and the start clear of every wall by
    /// the walls' tolerance and by the body's radius.
    fn check_placement(&self, c: &mut Check) {
        let (ox, oy) = (self.grid.origin_x_mm, self.grid.origin_y_mm);
        for (field, p) in self.placed_points() {
            if p.x < f64::from(ox) || p.y < f64::from(oy) {
                c.fail(
                    &field,
                    format!(
                        "({}, {}) mm is outside the grid, which starts at grid.origin_x_mm, \
                         grid.origin_y_mm = ({ox}, {oy}) mm",
                        p.x, p.y
                    ),
                );
            }
        }
        let start = Vec2::new(self.start.x_mm, self.start.y_mm);
        let tolerance = self.world.wall_tolerance_mm;
        let radius = self.robot.radius_mm;
        let walls = self.world.walls.len();
        // The world's solid segments are the walls, then a card per tag.
        for (i, w) in SolidWorld::new(self).walls().iter().enumerate() {
            let d = point_segment_distance(start, w.a, w.b);
            let what = || match i.checked_sub(walls) {
                None => format!("world.walls[{i}]"),
                Some(t) => format!("the card of world.tags[{t}]"),
            };
            if d < tolerance {
                let what = what();
                c.fail(
                    "start",
                    format!(
                        "({}, {}) mm is inside {what} ({d:.0} mm from it; walls are \
                         world.wall_tolerance_mm = {tolerance} mm thick)",
                        start.x, start.y
                    ),
                );
            } else if d < radius {
                let what = what();
                c.fail(
                    "start",
                    format!(
                        "({}, {}) mm puts the body into {what} ({d:.0} mm from it, closer \
                         than robot.radius_mm = {radius} mm)",
                        start.x, start.y
                    ),
                );
            }
        }
    }
}

/// The name becomes part of file names (`run --out DIR` writes `DIR/NAME-POSE-map.png`),
/// so it must not leave `DIR`: no separators, no `..`, nothing hidden.
fn check_name(c: &mut Check, name: &str) {
    let plain = |ch: char| ch.is_ascii_alphanumeric() || matches!(ch, '-' | '_' | '.');
    if name.is_empty() || name.chars().count() > MAX_NAME_LEN {
        c.fail("name", format!("must be 1 to {MAX_NAME_LEN} characters"));
    } else if name.starts_with('.') || !name.chars().all(plain) {
        c.fail(
            "name",
            format!(
                "becomes a file name, so letters, digits, '-', '_' and '.' only, not \
                 starting with '.': got `{}`",
                name.escape_default()
            ),
        );
    }
}
