//! BugBot's world as a file: the scenario TOML that both the simulator and the firmware
//! are built from.
//!
//! [`scenario`] parses and checks the file (the same checks and errors for `host-sim run`
//! and the firmware's build), [`solid`] is its walls and tag cards as geometry, and
//! [`robot`] turns it into what the core and the firmware take: the core's configuration,
//! the start, the tags, the grid's size, the route's legs and the drive. [`codegen`]
//! writes that as Rust constants for the firmware's `build.rs`. No world's numbers are
//! written in `slam-core` or the firmware: they come from here.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod codegen;
pub mod robot;
pub mod scenario;
pub mod shipped;
pub mod solid;

pub use robot::{Leg, RobotWorld, WorldError};
pub use scenario::{Scenario, ScenarioError};
