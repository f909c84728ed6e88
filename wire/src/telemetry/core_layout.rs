//! How the core's own types are laid out on the wire.
//!
//! `slam-core` knows nothing of serde: these are serde's "remote" mirrors of its types,
//! field for field and variant for variant. The derive checks each mirror against the
//! core's definition, so a field added to [`Counters`] fails to build here until the
//! mirror (and [`WIRE_VERSION`](super::WIRE_VERSION)) follow.

use serde::{Deserialize, Serialize, Serializer};
use slam_core::{Counters, FixOutcome, FixRejection};

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
