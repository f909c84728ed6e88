//! What a step reports: its pose and outcome, and the running totals since start.

use crate::estimator::{Estimate, Estimator};
use crate::plausible::Trust;
use crate::pose::Pose;
use crate::tagfix::FixOutcome;

/// Running totals since start: what the robot reports and the tests check.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Counters {
    /// Steps run.
    pub ticks: u32,
    /// Tag fixes taken.
    pub fixes_taken: u32,
    /// Fixes thrown away because the tags' geometry did not add up.
    pub fixes_rejected_geometry: u32,
    /// Fixes thrown away because they disagreed with the prediction.
    pub fixes_rejected_gate: u32,
    /// Pictures with two known tags not used because they were older than the pose
    /// history reaches.
    pub fixes_rejected_too_old: u32,
    /// Fixes taken against the gate after too many rejections in a row, or (the filter)
    /// times the heading or the position was forgotten for them
    /// ([`crate::Estimator::forget_heading`], [`crate::Estimator::forget_position`]).
    pub relocalisations: u32,
    /// Pictures refused whole for repeating the last one bit for bit
    /// ([`crate::camera_check`]).
    pub pictures_repeated: u32,
    /// Pictures the gate refused whose refusals began with a leap: they do not count
    /// towards forgetting the heading ([`crate::camera_check`]).
    pub pictures_leapt: u32,
    /// Pictures refused whole for repeating one from a few ticks before, or refused
    /// picture after picture and fitting a moment a few ticks older: the camera had
    /// fallen behind, and the pictures after them are taken as that much older
    /// ([`crate::camera_check`]).
    pub pictures_late: u32,
    /// Beams written into the map.
    pub beams_mapped: u32,
    /// Beams with no valid return, skipped.
    pub beams_invalid: u32,
    /// Ticks without a flow reading (position not advanced).
    pub flow_stale: u32,
    /// Ticks without a gyro reading (heading not advanced).
    pub gyro_stale: u32,
    /// Ticks without a depth scan (nothing mapped).
    pub depth_stale: u32,
    /// Ticks the gyro was doubted ([`crate::plausible`]).
    pub gyro_doubted: u32,
    /// Ticks the flow was doubted.
    pub flow_doubted: u32,
    /// Ticks the depth sensor was doubted.
    pub depth_doubted: u32,
    /// Scans not mapped because the pose or the scan could not be vouched for.
    pub scans_withheld: u32,
}

/// Which inputs a tick lacked.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Staleness {
    /// No flow this tick.
    pub flow: bool,
    /// No gyro this tick.
    pub gyro: bool,
    /// No depth scan this tick.
    pub depth: bool,
}

/// What one step did.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StepReport {
    /// The pose the scan was mapped at: the best estimate after this tick.
    pub pose: Pose,
    /// Whether a tag fix was taken, rejected or not tried.
    pub fix: FixOutcome,
    /// Inputs missing this tick.
    pub stale: Staleness,
    /// Inputs doubted after this tick, and why: the motion that needs one holds.
    pub trust: Trust,
    /// Grid cells written this tick.
    pub cells_written: u32,
    /// Totals since start.
    pub counters: Counters,
    /// The filter's belief after this tick ([`Localiser::Filter`] only).
    ///
    /// [`Localiser::Filter`]: super::Localiser::Filter
    pub estimate: Option<Estimate>,
}

impl StepReport {
    /// The report of a step.
    ///
    /// Out of line and not generic: the step is generic over the grid's size, so the
    /// firmware builds it for size, where the 60-byte copy of the counters is a byte-wise
    /// library `memcpy`; built here, for speed, it is a few word loads and stores.
    #[inline(never)]
    pub(super) fn of(
        pose: &Pose,
        fix: FixOutcome,
        stale: Staleness,
        trust: Trust,
        cells_written: u32,
        counters: &Counters,
        filter: Option<&Estimator>,
    ) -> StepReport {
        StepReport {
            pose: *pose,
            fix,
            stale,
            trust,
            cells_written,
            counters: *counters,
            estimate: filter.map(Estimator::estimate),
        }
    }
}
