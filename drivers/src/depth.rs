//! ST VL53L5CX multizone ranging: reduction of the 8 x 8 zone result to
//! BugBot's 8 range beams.
//!
//! This module is only the pure reduction. The bus layer for the real part
//! (I2C firmware upload, ranging start, result read-out) is ST's Ultra Lite
//! Driver, run by the firmware (`firmware/src/sensors/depth.rs`); it fills a
//! [`ZoneResult`] with [`ZoneResult::from_frame`] and calls [`reduce`]. No ST
//! firmware or configuration tables live in this crate.
//!
//! # Zone order and the mirror
//!
//! The driver reports zones in the sensor's order: zone `row * 8 + col`,
//! with zone 0 at the top-left *as seen by the sensor*, i.e. looking at the
//! sensor's face. With the sensor facing forward on the robot, that view is
//! mirrored left-right relative to the robot's view: sensor column 0 is the
//! robot's rightmost column. So beam `b` (0 = robot's leftmost) is built
//! from sensor column `7 - b`. Rows are not mirrored; row 0 is the top.
//!
//! # Beams
//!
//! The 8 beams split the sensor's 45 degree width ([`FOV_MDEG`]) evenly
//! (5.625 degrees each) and are ordered left (most negative angle, BugBot's
//! angles being clockwise-positive) to right; see [`BEAM_CENTRE_UDEG`]. The
//! SLAM core is configured from the same width (`slam_core::slam::fan`), so
//! the firmware maps each beam along the direction its zones look.
//!
//! Each beam's range is the nearest accepted zone in that column among the
//! rows `first_row..=last_row` of [`DepthConfig`] (default 3 and 4).
//! Nearest, because the map must not miss an obstacle; middle rows only, because the top rows see over low
//! obstacles and the bottom rows see the floor (a sensor 40 mm above the
//! floor meets it about 400 mm away along the bottom edge of row 4, 5.6
//! degrees down; mount it level and pick rows for its height).

/// Zones per side of the square zone array.
pub const ZONES_PER_SIDE: usize = 8;
/// Zones in one result.
pub const ZONE_COUNT: usize = ZONES_PER_SIDE * ZONES_PER_SIDE;
/// Beams produced per result, one per zone column.
pub const BEAM_COUNT: usize = ZONES_PER_SIDE;

/// Target status: range valid.
pub const STATUS_VALID: u8 = 5;
/// Target status: no target detected in the zone.
pub const STATUS_NO_TARGET: u8 = 255;
/// Target status: range valid but the wrap-around check was not performed
/// (lower confidence, accepted).
pub const STATUS_VALID_NO_WRAP_CHECK: u8 = 6;
/// Target status: range valid with a large pulse, possibly merged targets
/// (lower confidence, accepted).
pub const STATUS_VALID_LARGE_PULSE: u8 = 9;

/// Width of the zone array's view side to side, in millidegrees (the
/// datasheet's 45 degree horizontal field of view in 8 x 8 mode).
pub const FOV_MDEG: i32 = 45_000;

/// Beam centre angles in microdegrees, clockwise-positive, beam 0 (the
/// robot's leftmost) first: the centres of [`BEAM_COUNT`] equal slices of
/// [`FOV_MDEG`]. Beam `b` covers `-22.5 + 5.625 b .. -22.5 + 5.625 (b + 1)`
/// degrees.
pub const BEAM_CENTRE_UDEG: [i32; BEAM_COUNT] = {
    let fov_udeg = FOV_MDEG as i64 * 1000;
    let mut out = [0i32; BEAM_COUNT];
    let mut b = 0;
    while b < BEAM_COUNT {
        // Centre of slice b: -w/2 + w * (2b + 1) / (2 * BEAM_COUNT), exact in microdegrees.
        let udeg = -fov_udeg / 2 + fov_udeg * (2 * b as i64 + 1) / (2 * BEAM_COUNT as i64);
        out[b] = udeg as i32;
        b += 1;
    }
    out
};

/// One ranging result as the VL53L5CX reports it in 8 x 8 mode, one target
/// per zone, in the sensor's zone order (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ZoneResult {
    /// Distance per zone, millimetres. Can be negative on the real part
    /// (close targets with poor signal); such zones are dropped.
    pub distance_mm: [i16; ZONE_COUNT],
    /// ST target status per zone; see [`STATUS_VALID`] and friends.
    pub target_status: [u8; ZONE_COUNT],
}

impl ZoneResult {
    /// One target per zone from the driver's frame. A zone whose target count is 0 has no
    /// valid distance or status (the part leaves whatever the buffer held, which ST says
    /// not to read), so its status becomes [`STATUS_NO_TARGET`].
    pub fn from_frame(
        distance_mm: [i16; ZONE_COUNT],
        mut target_status: [u8; ZONE_COUNT],
        nb_target_detected: &[u8; ZONE_COUNT],
    ) -> ZoneResult {
        for (status, &targets) in target_status.iter_mut().zip(nb_target_detected) {
            if targets == 0 {
                *status = STATUS_NO_TARGET;
            }
        }
        ZoneResult {
            distance_mm,
            target_status,
        }
    }
}

/// Which zone rows feed a beam.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DepthConfig {
    /// First row used, 0 = top.
    pub first_row: u8,
    /// Last row used, inclusive. Rows past 7 are ignored.
    pub last_row: u8,
}

impl DepthConfig {
    /// Rows 3 and 4: the two rows either side of the horizon, +-5.6 degrees.
    pub const MIDDLE_ROWS: Self = DepthConfig {
        first_row: 3,
        last_row: 4,
    };
}

impl Default for DepthConfig {
    fn default() -> Self {
        Self::MIDDLE_ROWS
    }
}

/// The reduced scan: one range per beam plus why zones were dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BeamRanges {
    /// Range per beam in millimetres, beam 0 = robot's leftmost. `None`
    /// when no zone in the beam's rows was accepted.
    pub range_mm: [Option<u16>; BEAM_COUNT],
    /// Zones in the used rows dropped for their target status.
    pub dropped_status: u8,
    /// Zones with an accepted status but a distance of zero or below.
    pub dropped_distance: u8,
}

/// Whether a target status is accepted: 5, or the lower-confidence 6 and 9.
pub const fn status_accepted(status: u8) -> bool {
    matches!(
        status,
        STATUS_VALID | STATUS_VALID_NO_WRAP_CHECK | STATUS_VALID_LARGE_PULSE
    )
}

/// Reduce an 8 x 8 result to 8 beams, left to right. See the module doc.
pub fn reduce(result: &ZoneResult, config: &DepthConfig) -> BeamRanges {
    let mut out = BeamRanges::default();
    let last_row = usize::from(config.last_row).min(ZONES_PER_SIDE - 1);
    for (beam, range) in out.range_mm.iter_mut().enumerate() {
        let col = ZONES_PER_SIDE - 1 - beam;
        for row in usize::from(config.first_row)..=last_row {
            let zone = row * ZONES_PER_SIDE + col;
            let (Some(&status), Some(&distance)) =
                (result.target_status.get(zone), result.distance_mm.get(zone))
            else {
                continue;
            };
            if !status_accepted(status) {
                out.dropped_status += 1;
                continue;
            }
            let Ok(distance) = u16::try_from(distance) else {
                out.dropped_distance += 1;
                continue;
            };
            if distance == 0 {
                out.dropped_distance += 1;
                continue;
            }
            *range = Some(range.map_or(distance, |r| r.min(distance)));
        }
    }
    out
}
