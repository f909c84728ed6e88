//! A simulated mat and robot for BugBot: the world, the sensors, the route, and the demo
//! that runs `slam_core`'s `step` on them exactly as the firmware does.
//!
//! # Scenario files
//!
//! A scenario is TOML, in millimetres, degrees and seconds (see
//! `host-sim/scenarios/seed-mat.toml`). Every field is required unless marked optional;
//! unknown fields are refused.
//!
//! | table / field | meaning |
//! |---|---|
//! | `name`, `seed` | a name for titles and the pictures' file names (letters, digits, `-`, `_`, `.`); the noise seed (`--seed` overrides) |
//! | `world.walls` | wall segments `[[x0, y0], [x1, y1]]`: the mat's edges, inner walls, boxes; with the tags and the start, on the grid (from its origin up and right) |
//! | `world.wall_tolerance_mm` | an occupied cell whose centre is this close to a wall is in place |
//! | `[[world.tags]]` `id`, `x_mm`, `y_mm`, `width_mm`, `facing_deg` (optional: a world may have no tags) | an AprilTag card: the depth sensor sees the card, the camera reads the face |
//! | `start` `x_mm`, `y_mm`, `heading_deg` | the true start, clear of every wall by `wall_tolerance_mm` and by `robot.radius_mm`; the core starts believing it |
//! | `robot` `max_wheel_speed_mm_s`, `wheel_base_mm` | the differential drive, when the firmware commands the motors |
//! | `robot` `radius_mm` (optional, the seed robot's 60 when absent) | the body: a circle about the turning axis that stops at a wall it touches (a collision) and that the guard keeps clear; the start must be this far from every wall |
//! | `[robot.slip]` `spells_per_min`, `spell_s`, `speed_loss`, `skid_mm_per_turn` (optional table: no slip when absent) | wheel slip: spells of `spell_s` at random moments in which the robot moves and turns `speed_loss` (0 to 1) slower than commanded; and while turning, the centre slides `skid_mm_per_turn` on average per full turn, each turn in a direction and by an amount (0 to twice the average) of its own |
//! | `sensors.tof` `fov_deg`, `max_range_mm`, `noise_mm`, `dropout` | 8 beams at the centres of 8 equal zones; zones with no return |
//! | `sensors.tof` `noise_per_m_mm` (optional, 0 when absent) | range noise that grows with distance: this much more standard deviation per metre |
//! | `sensors.tof` `mixed_edge` (optional, 0 when absent) | the chance that a zone spanning a step in depth (a box's edge before a wall, over 100 mm apart) reads a range between the two surfaces |
//! | `sensors.tof` `rate_hz` (optional, 0 when absent) | the sensor ranges on its own clock at this rate, 1 to 60 (the firmware sets 15), its first frame at a moment the seed sets: each tick takes the newest frame, ranged from the pose of its moment and told its age, as on the robot; 0 ranges a frame at every tick |
//! | `sensors.flow` `um_per_count`, `scale_error`, `noise_counts`, `quality` | flow counts at 100 Hz; the firmware's calibration, the true scale error, noise per reading, surface quality |
//! | `sensors.flow` `offset_mm` (optional, `[0, 0]` when absent) | where the sensor sits from the turning axis, `[forward, right]`: off the axis a turn on the spot shows as flow |
//! | `sensors.gyro` `bias_dps`, `scale_error`, `noise_dps` | yaw rate at 200 Hz: residual bias, scale error, noise per sample |
//! | `sensors.gyro` `bias_walk_dps_per_sqrt_s` (optional, 0 when absent) | the bias wanders from `bias_dps` as a random walk, spreading this much per square root of a second |
//! | `sensors.camera` `width_px`, `focal_px`, `fov_deg`, `max_range_mm`, `max_incidence_deg`, `pixel_noise_px`, `distance_noise_mm` | tag detections; tags hidden by walls or seen too obliquely are not read |
//! | `sensors.camera` `latency_ms` (optional, 0 when absent) | the tags are read from where the robot was this long before the tick, and the frame says how old they are |
//! | `grid` `cell_mm`, `origin_x_mm`, `origin_y_mm`, `max_range_mm` | the core's grid (the smallest built-in size that holds the world: 46 x 46 or 206 x 206) and the mapper's range limit |
//! | `[[route]]` `action = "turn"`, `degrees`, `rate_dps` | turn on the spot until the true heading has turned that far |
//! | `[[route]]` `action = "drive"`, `seconds`, `speed_mm_s` | drive straight for `int(seconds * 10)` ticks |
//! | `[[route]]` `action = "drive_distance"`, `distance_mm`, `speed_mm_s` | drive straight until that far by truth |
//! | `[[route]]` `action = "wait"`, `seconds` | stand still |
//!
//! The whole route may last at most an hour of simulated time (`run::MAX_RUN_S`): a longer
//! one is refused before the run.
//!
//! A bad value (missing, wrong type, NaN, negative, absurd) is refused with an error that
//! names the field.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod bounded;
pub mod consistency;
pub mod decimated;
pub mod fault;
pub mod fault_matrix;
pub mod floor;
pub mod live;
pub mod match_truth;
pub mod matching;
pub mod page;
pub mod picture;
pub mod record;
pub mod replay;
pub mod robot;
pub mod rosmap;
pub mod route;
pub mod run;
pub use ::world::scenario;
pub mod score;
pub mod serve;
pub mod slip;
pub mod telemetry;
pub mod truth;
pub mod world;

pub use record::RunRecord;
pub use run::{run, Figures, PoseMode};
pub use scenario::{Scenario, ScenarioError};
