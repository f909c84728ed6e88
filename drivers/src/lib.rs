//! BugBot's part drivers: `no_std`, over the `embedded-hal` 1.0 traits (the async ones,
//! `embedded-hal-async`, for the buses).
//!
//! One module per part. Each bus driver is generic over its bus trait, owns
//! the bus until [`destroy`](flow::Pmw3901::destroy) hands it back, and
//! reports failures as an `Error<E>` enum that carries the bus error inside.
//! Nothing here reads a clock or allocates: delays are passed in, storage is
//! fixed-size, and the hot paths use integer or fixed-point maths only
//! (the RP2040's Cortex-M0+ has no FPU).
//!
//! | module | part | bus |
//! | --- | --- | --- |
//! | [`flow`] | PixArt PMW3901 optical flow | SPI mode 3, `SpiDevice` |
//! | [`imu`] | TDK InvenSense ICM-42688-P gyro | I2C, `I2c` |
//! | [`depth`] | ST VL53L5CX 8x8 zone reduction | none: a pure function of a frame |
//! | [`motors`] | DRV8833 dual H-bridge | 4 PWM channels, `SetDutyCycle` |
//!
//! The VL53L5CX's bus side is not here: ST's Ultra Lite Driver (C, blocking, through the
//! `vl53l5cx-uld` crate) talks to it in the firmware, and [`depth`] reduces the frames it
//! reads.
//!
//! Robot-frame conventions shared by all modules: `forward` is the robot's
//! nose, `right` its right-hand side; headings and yaw rates are positive
//! clockwise seen from above (heading 0 faces +y); beam and pixel orders
//! run from the robot's left to its right.
//!
//! The tag camera's UART frames are wire, not a part: they live in the `wire` crate
//! (`wire::camera_link`).
//!
//! Enable the `defmt` feature for `defmt::Format` on every public type.
#![cfg_attr(not(test), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod depth;
pub mod flow;
pub mod imu;
pub mod motors;
