//! Motion burst parsing and quality gating: pure, so testable without a bus.

use super::register::{MOTION_FLAG, SHUTTER_UPPER_MAX, SQUAL_MIN_DATASHEET};
use super::FlowCalibration;

/// The 12 bytes of one motion burst (register 0x16), in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionBurst {
    /// Motion register; bit 7 = motion since the last read.
    pub motion: u8,
    /// Observation register (0xBF when the chip is running normally).
    pub observation: u8,
    /// Image motion along the sensor's X axis, counts.
    pub delta_x: i16,
    /// Image motion along the sensor's Y axis, counts.
    pub delta_y: i16,
    /// Surface quality: number of features seen, 0..=255.
    pub squal: u8,
    /// Sum of raw pixel data.
    pub raw_data_sum: u8,
    /// Brightest raw pixel.
    pub max_raw: u8,
    /// Darkest raw pixel.
    pub min_raw: u8,
    /// Shutter time, upper 5 bits used.
    pub shutter_upper: u8,
    /// Shutter time, lower byte.
    pub shutter_lower: u8,
}

impl MotionBurst {
    /// Bytes in a burst.
    pub const LEN: usize = 12;

    /// Parse the burst bytes (any 12 bytes are a valid burst).
    pub const fn parse(b: &[u8; Self::LEN]) -> Self {
        MotionBurst {
            motion: b[0],
            observation: b[1],
            delta_x: i16::from_le_bytes([b[2], b[3]]),
            delta_y: i16::from_le_bytes([b[4], b[5]]),
            squal: b[6],
            raw_data_sum: b[7],
            max_raw: b[8],
            min_raw: b[9],
            shutter_upper: b[10],
            shutter_lower: b[11],
        }
    }

    /// Whether the motion flag (bit 7 of the motion register) is set.
    pub const fn has_motion(&self) -> bool {
        self.motion & MOTION_FLAG != 0
    }
}

/// How sensor axes map to the robot frame.
///
/// Default mounting: the sensor looks down at the floor from the chassis
/// centre, with its +Y axis along the robot's forward axis and +X to the
/// robot's right, so `right = delta_x` and `forward = delta_y` (identity).
/// Verify on the bench: push the robot forward 100 mm and expect positive
/// `forward_counts`, slide it right and expect positive `right_counts`; set
/// the flags below if not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisMap {
    /// Sensor X is robot forward and sensor Y is robot right.
    pub swap_xy: bool,
    /// Negate the robot-right axis (after any swap).
    pub negate_right: bool,
    /// Negate the robot-forward axis (after any swap).
    pub negate_forward: bool,
}

impl AxisMap {
    /// `(right, forward)` in robot frame from sensor deltas.
    pub const fn apply(&self, delta_x: i16, delta_y: i16) -> (i16, i16) {
        let (r, f) = if self.swap_xy {
            (delta_y, delta_x)
        } else {
            (delta_x, delta_y)
        };
        let r = if self.negate_right {
            r.saturating_neg()
        } else {
            r
        };
        let f = if self.negate_forward {
            f.saturating_neg()
        } else {
            f
        };
        (r, f)
    }
}

/// When a burst counts as "no usable surface".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SurfaceCheck {
    /// The datasheet rule: SQUAL below the minimum *and* the shutter upper
    /// byte at its maximum (0x1F): dark or featureless floor. Default.
    #[default]
    SqualAndShutter,
    /// SQUAL below the minimum alone: stricter.
    SqualOnly,
}

/// Gating and scaling for flow readings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowConfig {
    /// Counts to micrometres.
    pub calibration: FlowCalibration,
    /// Sensor axes to robot axes.
    pub axes: AxisMap,
    /// SQUAL below this fails the surface check (datasheet: 0x19).
    pub min_squal: u8,
    /// Which surface check to apply.
    pub surface_check: SurfaceCheck,
    /// A delta of at least this many counts on either axis is an outlier
    /// (at 100 Hz, 100 counts at 80 mm height is over 17 m/s).
    pub outlier_counts: u16,
}

impl FlowConfig {
    /// Datasheet gating (SQUAL 0x19 with full shutter), 100-count outlier
    /// limit, default axes, and the given calibration.
    pub const fn new(calibration: FlowCalibration) -> Self {
        FlowConfig {
            calibration,
            axes: AxisMap {
                swap_xy: false,
                negate_right: false,
                negate_forward: false,
            },
            min_squal: SQUAL_MIN_DATASHEET,
            surface_check: SurfaceCheck::SqualAndShutter,
            outlier_counts: 100,
        }
    }
}

/// Accepted motion in robot frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowSample {
    /// Robot motion to the right, counts.
    pub right_counts: i16,
    /// Robot motion forward, counts.
    pub forward_counts: i16,
    /// Robot motion to the right, micrometres.
    pub right_um: i32,
    /// Robot motion forward, micrometres.
    pub forward_um: i32,
    /// Surface quality of this burst.
    pub squal: u8,
}

/// Outcome of one read. Only bus failures are errors; everything the
/// sensor may legitimately say is one of these.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlowReading {
    /// Trusted motion; all zero when the motion flag was clear.
    Motion(FlowSample),
    /// The surface check failed: deltas are not trustworthy.
    NoSurface {
        /// Surface quality read.
        squal: u8,
        /// Shutter upper byte read.
        shutter_upper: u8,
    },
    /// A delta at or above the outlier limit; dropped.
    Outlier {
        /// Robot-right delta, counts.
        right_counts: i16,
        /// Robot-forward delta, counts.
        forward_counts: i16,
    },
}

/// Gate and scale one burst: surface check, then motion flag, then outlier.
pub fn gate(burst: &MotionBurst, config: &FlowConfig) -> FlowReading {
    let low_squal = burst.squal < config.min_squal;
    let dark = burst.shutter_upper & SHUTTER_UPPER_MAX == SHUTTER_UPPER_MAX;
    let no_surface = match config.surface_check {
        SurfaceCheck::SqualAndShutter => low_squal && dark,
        SurfaceCheck::SqualOnly => low_squal,
    };
    if no_surface {
        return FlowReading::NoSurface {
            squal: burst.squal,
            shutter_upper: burst.shutter_upper,
        };
    }
    if !burst.has_motion() {
        return FlowReading::Motion(FlowSample {
            squal: burst.squal,
            ..FlowSample::default()
        });
    }
    let (right, forward) = config.axes.apply(burst.delta_x, burst.delta_y);
    if right.unsigned_abs() >= config.outlier_counts
        || forward.unsigned_abs() >= config.outlier_counts
    {
        return FlowReading::Outlier {
            right_counts: right,
            forward_counts: forward,
        };
    }
    FlowReading::Motion(FlowSample {
        right_counts: right,
        forward_counts: forward,
        right_um: config.calibration.counts_to_um(right),
        forward_um: config.calibration.counts_to_um(forward),
        squal: burst.squal,
    })
}
