//! How the core's own types are laid out on the wire.
//!
//! `slam-core` knows nothing of serde: these are serde's "remote" mirrors of its types,
//! field for field and variant for variant. The derive checks each mirror against the
//! core's definition, so a field added to [`Counters`] fails to build here until the
//! mirror (and [`WIRE_VERSION`](super::WIRE_VERSION)) follow.

use serde::{Deserialize, Serialize, Serializer};
use slam_core::{
    Calibration, Counters, FixOutcome, FixRejection, Localiser, PoseCovariance, TagCounters,
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
    beams_mapped: u32,
    beams_invalid: u32,
    flow_stale: u32,
    gyro_stale: u32,
    depth_stale: u32,
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
