//! Byte framing shared by every serial link of the robot: COBS stuffing, CRC-16, the
//! collector that splits a byte stream at its delimiters, and the decoders' statistics.
//!
//! COBS removes every `0x00` from a frame so `0x00` can end it on the wire, and a
//! receiver that joins mid-stream or meets garbage resynchronises at the next `0x00`.
//! The camera co-processor's link and the telemetry stream both use it.

mod cobs;
mod collector;
mod crc;
mod stats;

pub use cobs::{cobs_decode, cobs_decode_in_place, cobs_encode, cobs_len, cobs_max_len, CobsError};
pub use collector::{Collected, FrameCollector};
pub use crc::crc16;
pub use stats::{BadFrames, DecoderStats, FrameError};
