//! The tag camera's UART link: the frame format that the OpenMV co-processor
//! (`drivers/camera/openmv_tags.py`) sends and BugBot decodes.
//!
//! # Wire format (defined here)
//!
//! Each frame is COBS-encoded and followed by one `0x00` delimiter, so a
//! receiver that starts mid-stream (or sees line noise) resynchronises at
//! the next `0x00`. Decoded, a frame is (all multi-byte fields little-endian):
//!
//! | offset | size | field |
//! | --- | --- | --- |
//! | 0 | 1 | version, [`VERSION`] |
//! | 1 | 2 | frame counter, wraps at 65535 |
//! | 3 | 1 | detection count `n`, at most [`MAX_DETECTIONS`] |
//! | 4 + 8 i | 2 | tag id (AprilTag 36h11 id) |
//! | 6 + 8 i | 2 | tag centre x, centipixels, `0..=32000` (320 px image) |
//! | 8 + 8 i | 2 | tag centre y, centipixels, `0..=24000` (240 px image) |
//! | 10 + 8 i | 2 | distance to the tag, millimetres |
//! | 4 + 8 n | 2 | CRC-16/CCITT-FALSE ([`crc16`](crate::framing::crc16)) over every byte before it |
//!
//! Pixel x runs from the image's left (the robot's left, camera facing
//! forward, not mirrored) to its right; y runs top to bottom.
//!
//! # Layers (the smoltcp way)
//!
//! - [`crate::framing`]: byte stuffing and the CRC, shared with the telemetry.
//! - [`Packet`]: a checked view over decoded bytes; after
//!   [`Packet::new_checked`] no accessor can panic.
//! - [`FrameRepr`]: the parsed high-level frame, with `parse` and `emit`.
//! - [`FrameDecoder`]: a fixed-buffer stream decoder fed UART bytes, counting what it
//!   drops in the shared [`DecoderStats`](crate::framing::DecoderStats).

mod decoder;
mod packet;
mod repr;

pub use decoder::{FrameDecoder, Frames};
pub use packet::Packet;
pub use repr::{encode_frame, FrameRepr, TagDetection};

use crate::framing::{cobs_max_len, CobsError, FrameError};

/// The only frame version this crate understands.
pub const VERSION: u8 = 1;
/// Most detections a frame may carry.
pub const MAX_DETECTIONS: usize = 8;
/// Bytes before the first detection: version, counter, count.
pub const HEADER_LEN: usize = 4;
/// Bytes per detection record.
pub const DETECTION_LEN: usize = 8;
/// Bytes of the trailing CRC.
pub const CRC_LEN: usize = 2;
/// Longest decoded frame, in bytes (8 detections).
pub const MAX_FRAME_LEN: usize = HEADER_LEN + MAX_DETECTIONS * DETECTION_LEN + CRC_LEN;
/// Longest COBS-encoded frame, without its `0x00` delimiter.
pub const MAX_ENCODED_LEN: usize = cobs_max_len(MAX_FRAME_LEN);
/// Largest tag centre x, centipixels (320 px wide image).
pub const MAX_CX_CENTIPX: u16 = 32_000;
/// Largest tag centre y, centipixels (240 px high image).
pub const MAX_CY_CENTIPX: u16 = 24_000;

/// Why a frame was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireError {
    /// Fewer bytes than the header, or than the detection count needs.
    Truncated,
    /// More bytes than the detection count says (or an output buffer of the
    /// wrong size).
    BadLength,
    /// Detection count above [`MAX_DETECTIONS`].
    TooManyDetections,
    /// The CRC does not match the bytes.
    BadCrc,
    /// Version byte other than [`VERSION`].
    BadVersion,
    /// COBS stuffing is inconsistent (a code byte points past the end).
    BadCobs,
    /// A centre coordinate outside the image.
    ValueOutOfRange,
}

impl From<CobsError> for WireError {
    fn from(e: CobsError) -> Self {
        match e {
            CobsError::BufferTooSmall => WireError::BadLength,
            CobsError::Malformed => WireError::BadCobs,
        }
    }
}

/// The shared class each rejection is counted under: a frame too long for its count,
/// too many detections or a centre outside the image are all a bad body.
impl From<WireError> for FrameError {
    fn from(e: WireError) -> Self {
        match e {
            WireError::Truncated => FrameError::TooShort,
            WireError::BadLength | WireError::TooManyDetections | WireError::ValueOutOfRange => {
                FrameError::Body
            }
            WireError::BadCrc => FrameError::Crc,
            WireError::BadVersion => FrameError::Version,
            WireError::BadCobs => FrameError::Cobs,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::framing::{cobs_decode, cobs_encode};

    #[test]
    fn cobs_errors_map_to_the_link_errors() {
        let mut dec = [0u8; 16];
        let decode =
            |src: &[u8], dst: &mut [u8]| -> Result<usize, WireError> { Ok(cobs_decode(src, dst)?) };
        assert_eq!(decode(&[0x05, 1, 2], &mut dec), Err(WireError::BadCobs));
        let mut small = [0u8; 2];
        assert_eq!(decode(&[4, 1, 2, 3], &mut small), Err(WireError::BadLength));
        assert_eq!(
            cobs_encode(&[1, 2, 3], &mut small).map_err(WireError::from),
            Err(WireError::BadLength)
        );
    }
}
