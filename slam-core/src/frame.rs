//! What one 100 ms tick hands the core: the latest reading of each sensor, or none.
//!
//! `None` means stale: the sensor errored, stalled or was gated out this tick.
//! The core runs with what it has and counts what was missing.

/// Number of depth beams: the ToF sensor's 8 zone columns across its 45 degree fan.
pub const BEAMS: usize = 8;

/// Most tag detections one frame can carry.
pub const MAX_TAGS: usize = 8;

/// Optical flow accumulated over the tick, in sensor counts, robot frame.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FlowDelta {
    /// Displacement towards the robot's nose, in flow counts.
    pub forward_counts: i32,
    /// Displacement towards the robot's right, in flow counts.
    pub right_counts: i32,
}

/// The gyro's yaw rate averaged over the tick, bias already removed.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GyroRate {
    /// Yaw rate in millidegrees per second; positive turns clockwise seen from above.
    pub rate_mdps: i32,
}

/// One depth scan: a range per beam, left (most anticlockwise) to right.
///
/// Word-aligned, so that a copy is word loads and stores: the M0+'s library copy of a
/// halfword-aligned array goes halfword by halfword.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(align(4))]
pub struct DepthScan {
    /// Range along each beam in millimetres; `None` where the zone had no valid return.
    pub ranges_mm: [Option<u16>; BEAMS],
}

/// What the motors are asked for: the guard judges the one about to be driven, the
/// plausibility checks the one that was ([`SensorFrame::commanded`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveCommand {
    /// Forward speed, millimetres per second (negative: backwards).
    pub speed_mm_s: i32,
    /// Turn rate, millidegrees per second, positive clockwise.
    pub turn_mdps: i32,
}

/// One AprilTag the camera read.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagDetection {
    /// The tag's id (tag36h11).
    pub id: u16,
    /// Column of the tag's centre in the picture, in hundredths of a pixel.
    pub cx_centipx: i32,
    /// Distance from the camera to the tag, in millimetres.
    pub distance_mm: u32,
}

/// Up to [`MAX_TAGS`] detections, without an allocator; `push` hands back a detection that
/// does not fit.
pub type TagDetections = heapless::Vec<TagDetection, MAX_TAGS>;

/// Everything one tick of the core needs; built by the firmware or the simulator.
#[derive(Clone, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorFrame {
    /// Time since the previous frame, in microseconds.
    pub dt_us: u32,
    /// Flow since the previous frame, or `None` if the flow sensor was stale or gated out.
    pub flow: Option<FlowDelta>,
    /// Mean yaw rate since the previous frame, or `None` if the gyro was stale.
    pub gyro: Option<GyroRate>,
    /// This tick's depth scan, or `None` if there was no new one.
    pub depth: Option<DepthScan>,
    /// How long before this tick's instant the scan was measured, in microseconds (0: at
    /// the tick). The sensor keeps its own frame rate, and a scan 60 ms old taken while
    /// turning at 30 degrees a second lands 2 degrees off; the core maps it at the pose of
    /// its moment, and counts a scan older than its pose history as stale.
    pub depth_age_us: u32,
    /// What the depth sensor's task made of the scan against the frames before it
    /// ([`crate::depth_step`]): `None` when they agree or nobody held it to them.
    pub depth_doubt: Option<crate::Doubt>,
    /// Tags the camera read in its newest picture (empty when none, or stale).
    pub tags: TagDetections,
    /// How long before this tick's instant that picture was taken, in microseconds (0: at
    /// the tick). The camera keeps its own schedule; the core places the fix at that moment
    /// and carries it forward by the odometry since, and refuses pictures older than its
    /// pose history ([`crate::history::HISTORY_LEN`] ticks).
    pub tags_age_us: u32,
    /// A pose from outside (a lab's overhead camera, the simulator's truth): when present it
    /// replaces odometry and tag fixes, and the scan is mapped at it.
    pub external_pose: Option<crate::Pose>,
    /// What the motors were driven with as this frame's interval ended (after the guard:
    /// a held or stopped motion is the zero command), or `None` if the caller does not
    /// say; the gyro is then not checked against it ([`crate::commanded`]).
    pub commanded: Option<DriveCommand>,
}

impl SensorFrame {
    /// A frame in which every input is stale.
    pub const fn empty(dt_us: u32) -> SensorFrame {
        SensorFrame {
            dt_us,
            flow: None,
            gyro: None,
            depth: None,
            depth_age_us: 0,
            depth_doubt: None,
            tags: TagDetections::new(),
            tags_age_us: 0,
            external_pose: None,
            commanded: None,
        }
    }

    /// What the depth sensor saw ahead this tick, for the guard ([`crate::decide`]): its
    /// scan, unless there is none or the sensor's task found it shows nothing as it is:
    /// the frame before again bit for bit, a range the sensor cannot read, or every range
    /// stepped off where it was ([`crate::Doubt::Stuck`], [`crate::Doubt::Impossible`],
    /// [`crate::Doubt::Jump`]). A late frame ([`crate::Doubt::Late`]) still shows what
    /// was there.
    pub fn sight(&self) -> Option<&DepthScan> {
        use crate::Doubt::{Impossible, Jump, Stuck};
        match self.depth_doubt {
            Some(Stuck | Impossible | Jump) => None,
            _ => self.depth.as_ref(),
        }
    }
}
