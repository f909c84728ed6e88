//! How the core's own types are laid out on the wire.
//!
//! `slam-core` knows nothing of serde: these are serde's "remote" mirrors of its types,
//! field for field and variant for variant. The derive checks each mirror against the
//! core's definition, so a field added to [`Counters`] fails to build here until the
//! mirror (and [`WIRE_VERSION`](super::WIRE_VERSION)) follow.

use serde::{Deserialize, Serialize, Serializer};
use slam_core::{
    Angle, Calibration, Counters, DepthScan, Doubt, DriveCommand, FixOutcome, FixRejection,
    FlowDelta, GyroRate, Localiser, Pose, PoseCovariance, SensorFrame, TagCounters, TagDetection,
    TagDetections, BEAMS, MAX_TAGS,
};

/// [`FixRejection`] on the wire: its variant index as a varint.
#[derive(Serialize, Deserialize)]
#[serde(remote = "FixRejection", rename = "FixRejection")]
pub(crate) enum FixRejectionDef {
    Geometry,
    Gate,
    TooOld,
}

/// [`FixOutcome`] on the wire: its variant index as a varint, then a rejection's reason.
#[derive(Serialize, Deserialize)]
#[serde(remote = "FixOutcome", rename = "FixOutcome")]
pub(crate) enum FixOutcomeDef {
    NotAttempted,
    Taken,
    Rejected(#[serde(with = "FixRejectionDef")] FixRejection),
}

/// [`Counters`] on the wire: every total as a varint, in this order.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Counters", rename = "Counters")]
pub(crate) struct CountersDef {
    ticks: u32,
    fixes_taken: u32,
    fixes_rejected_geometry: u32,
    fixes_rejected_gate: u32,
    fixes_rejected_too_old: u32,
    relocalisations: u32,
    pictures_repeated: u32,
    pictures_leapt: u32,
    pictures_late: u32,
    beams_mapped: u32,
    beams_invalid: u32,
    flow_stale: u32,
    gyro_stale: u32,
    depth_stale: u32,
    gyro_doubted: u32,
    flow_doubted: u32,
    depth_doubted: u32,
    scans_withheld: u32,
}

/// [`Localiser`] on the wire: its variant index as a varint.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Localiser", rename = "Localiser")]
pub(crate) enum LocaliserDef {
    DeadReckoning,
    TwoTagFix,
    Filter,
}

/// [`PoseCovariance`] on the wire: six zigzag varints, in the filter's units.
#[derive(Serialize, Deserialize)]
#[serde(remote = "PoseCovariance", rename = "PoseCovariance")]
pub(crate) struct PoseCovarianceDef {
    xx: i64,
    xy: i64,
    yy: i64,
    xh: i64,
    yh: i64,
    hh: i64,
}

/// [`Calibration`] on the wire: three zigzag varints.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Calibration", rename = "Calibration")]
pub(crate) struct CalibrationDef {
    gyro_scale_ppm: i32,
    gyro_bias_mdps: i32,
    flow_scale_ppm: i32,
}

/// [`TagCounters`] on the wire: six varints.
#[derive(Serialize, Deserialize)]
#[serde(remote = "TagCounters", rename = "TagCounters")]
pub(crate) struct TagCountersDef {
    used: u32,
    unknown_id: u32,
    behind: u32,
    too_far: u32,
    too_old: u32,
    gate: u32,
}

/// Serialises an optional [`Counters`] under the wire's field names, for host-side
/// summaries (`#[serde(serialize_with = "wire::telemetry::serialize_counters")]`).
pub fn serialize_counters<S: Serializer>(
    counters: &Option<Counters>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    #[derive(Serialize)]
    struct AsWire<'a>(#[serde(with = "CountersDef")] &'a Counters);
    counters.as_ref().map(AsWire).serialize(serializer)
}

/// [`FlowDelta`] on the wire: two zigzag varints, flow counts.
#[derive(Serialize, Deserialize)]
#[serde(remote = "FlowDelta", rename = "FlowDelta")]
pub(crate) struct FlowDeltaDef {
    forward_counts: i32,
    right_counts: i32,
}

/// [`GyroRate`] on the wire: one zigzag varint, millidegrees per second.
#[derive(Serialize, Deserialize)]
#[serde(remote = "GyroRate", rename = "GyroRate")]
pub(crate) struct GyroRateDef {
    rate_mdps: i32,
}

/// [`DriveCommand`] on the wire: two zigzag varints, mm/s and millidegrees per second.
#[derive(Serialize, Deserialize)]
#[serde(remote = "DriveCommand", rename = "DriveCommand")]
pub(crate) struct DriveCommandDef {
    speed_mm_s: i32,
    turn_mdps: i32,
}

/// [`DepthScan`] on the wire: [`BEAMS`] optional `u16` ranges, no count (the array is fixed).
#[derive(Serialize, Deserialize)]
#[serde(remote = "DepthScan", rename = "DepthScan")]
pub(crate) struct DepthScanDef {
    ranges_mm: [Option<u16>; BEAMS],
}

/// [`TagDetection`] on the wire: id, centre column, distance.
#[derive(Serialize, Deserialize)]
#[serde(remote = "TagDetection", rename = "TagDetection")]
pub(crate) struct TagDetectionDef {
    id: u16,
    cx_centipx: i32,
    distance_mm: u32,
}

/// [`Angle`] on the wire: its bits, a varint (2^32 per turn).
#[derive(Serialize, Deserialize)]
#[serde(remote = "Angle", rename = "Angle")]
pub(crate) struct AngleDef(#[serde(getter = "angle_bits")] u32);

/// [`Angle::bits`] by reference, as serde's getter wants it.
fn angle_bits(a: &Angle) -> u32 {
    a.bits()
}

impl From<AngleDef> for Angle {
    fn from(a: AngleDef) -> Angle {
        Angle::from_bits(a.0)
    }
}

/// [`Pose`] on the wire: micrometres and the heading's bits.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Pose", rename = "Pose")]
pub(crate) struct PoseDef {
    x_um: i32,
    y_um: i32,
    #[serde(with = "AngleDef")]
    heading: Angle,
}

/// [`SensorFrame`] on the wire: every input of one step, in the core's own units and order.
#[derive(Serialize, Deserialize)]
#[serde(remote = "SensorFrame", rename = "SensorFrame")]
pub(crate) struct SensorFrameDef {
    dt_us: u32,
    #[serde(with = "option_flow")]
    flow: Option<FlowDelta>,
    #[serde(with = "option_gyro")]
    gyro: Option<GyroRate>,
    #[serde(with = "option_depth")]
    depth: Option<DepthScan>,
    depth_age_us: u32,
    #[serde(with = "doubt_code")]
    depth_doubt: Option<Doubt>,
    #[serde(with = "tag_list")]
    tags: TagDetections,
    tags_age_us: u32,
    #[serde(with = "option_pose")]
    external_pose: Option<Pose>,
    #[serde(with = "option_command")]
    commanded: Option<DriveCommand>,
}

/// `Option<T>` of a remote type `T` whose mirror is `$def`: postcard's option byte (0
/// none, 1 some) and then the mirror's layout.
macro_rules! option_of {
    ($module:ident, $ty:ty, $def:literal) => {
        pub(crate) mod $module {
            use super::*;
            use serde::{Deserializer, Serializer};

            #[derive(Serialize)]
            struct Out<'a>(#[serde(with = $def)] &'a $ty);

            #[derive(Deserialize)]
            struct In(#[serde(with = $def)] $ty);

            pub(crate) fn serialize<S: Serializer>(
                value: &Option<$ty>,
                serializer: S,
            ) -> Result<S::Ok, S::Error> {
                value.as_ref().map(Out).serialize(serializer)
            }

            pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
                deserializer: D,
            ) -> Result<Option<$ty>, D::Error> {
                Ok(Option::<In>::deserialize(deserializer)?.map(|In(v)| v))
            }
        }
    };
}

option_of!(option_flow, FlowDelta, "FlowDeltaDef");
option_of!(option_gyro, GyroRate, "GyroRateDef");
option_of!(option_depth, DepthScan, "DepthScanDef");
option_of!(option_pose, Pose, "PoseDef");
option_of!(option_command, DriveCommand, "DriveCommandDef");

/// An optional [`Doubt`] on the wire: one byte, its [`Doubt::code`] or 0 for none; an
/// unknown code is refused as a bad body.
pub(crate) mod doubt_code {
    use super::*;
    use serde::{de::Error, Deserializer, Serializer};

    pub(crate) fn serialize<S: Serializer>(
        doubt: &Option<Doubt>,
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        serializer.serialize_u8(doubt.map_or(0, Doubt::code))
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<Option<Doubt>, D::Error> {
        match u8::deserialize(deserializer)? {
            0 => Ok(None),
            code => Doubt::from_code(code)
                .map(Some)
                .ok_or_else(|| D::Error::custom("unknown doubt code")),
        }
    }
}

/// [`TagDetections`] on the wire: a varint count, at most [`MAX_TAGS`] (a longer list is
/// refused as a bad body), then each detection.
pub(crate) mod tag_list {
    use super::*;
    use serde::ser::SerializeSeq;
    use serde::{Deserializer, Serializer};

    #[derive(Serialize)]
    struct Out<'a>(#[serde(with = "TagDetectionDef")] &'a TagDetection);

    #[derive(Deserialize)]
    struct In(#[serde(with = "TagDetectionDef")] TagDetection);

    pub(crate) fn serialize<S: Serializer>(
        tags: &TagDetections,
        serializer: S,
    ) -> Result<S::Ok, S::Error> {
        let mut seq = serializer.serialize_seq(Some(tags.len()))?;
        for t in tags {
            seq.serialize_element(&Out(t))?;
        }
        seq.end()
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        deserializer: D,
    ) -> Result<TagDetections, D::Error> {
        // heapless refuses a count past its capacity before reading any element.
        let wrapped = heapless::Vec::<In, MAX_TAGS>::deserialize(deserializer)?;
        let mut tags = TagDetections::new();
        for In(t) in wrapped {
            // Same capacity: never refused.
            let _ = tags.push(t);
        }
        Ok(tags)
    }
}
