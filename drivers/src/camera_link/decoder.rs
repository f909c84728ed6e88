//! Streaming decoder: UART bytes in, frames out.

use super::{cobs, FrameRepr, Packet, WireError, MAX_ENCODED_LEN, MAX_FRAME_LEN};
use slam_core::framing::{Collected, FrameCollector};

/// Frames rejected by kind, and frames accepted. Counters wrap.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Frames parsed and returned.
    pub frames_ok: u32,
    /// Frames longer than [`MAX_ENCODED_LEN`] before their delimiter.
    pub overlong: u32,
    /// Frames with inconsistent COBS stuffing.
    pub bad_cobs: u32,
    /// [`WireError::Truncated`] frames.
    pub truncated: u32,
    /// [`WireError::BadLength`] frames.
    pub bad_length: u32,
    /// [`WireError::TooManyDetections`] frames.
    pub too_many_detections: u32,
    /// [`WireError::BadCrc`] frames.
    pub bad_crc: u32,
    /// [`WireError::BadVersion`] frames.
    pub bad_version: u32,
    /// [`WireError::ValueOutOfRange`] frames.
    pub value_out_of_range: u32,
}

impl DecoderStats {
    fn count(&mut self, error: WireError) {
        let counter = match error {
            WireError::Truncated => &mut self.truncated,
            WireError::BadLength => &mut self.bad_length,
            WireError::TooManyDetections => &mut self.too_many_detections,
            WireError::BadCrc => &mut self.bad_crc,
            WireError::BadVersion => &mut self.bad_version,
            WireError::BadCobs => &mut self.bad_cobs,
            WireError::ValueOutOfRange => &mut self.value_out_of_range,
        };
        *counter = counter.wrapping_add(1);
    }

    /// All rejected frames, of every kind.
    pub fn rejected(&self) -> u32 {
        self.overlong
            .wrapping_add(self.bad_cobs)
            .wrapping_add(self.truncated)
            .wrapping_add(self.bad_length)
            .wrapping_add(self.too_many_detections)
            .wrapping_add(self.bad_crc)
            .wrapping_add(self.bad_version)
            .wrapping_add(self.value_out_of_range)
    }
}

/// Fixed-buffer frame decoder for the camera UART.
///
/// Bytes accumulate until a `0x00` delimiter, then the frame is un-stuffed
/// and parsed. Anything wrong (garbage, a frame cut by a dropped byte, an
/// overlong run) is counted in [`DecoderStats`] and the decoder starts over
/// at the next delimiter. Empty frames (`0x00 0x00`) are ignored, so a
/// sender may prefix a delimiter to flush a receiver's partial frame.
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    frames: FrameCollector<MAX_ENCODED_LEN>,
    stats: DecoderStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        FrameDecoder {
            frames: FrameCollector::new(),
            stats: DecoderStats {
                frames_ok: 0,
                overlong: 0,
                bad_cobs: 0,
                truncated: 0,
                bad_length: 0,
                too_many_detections: 0,
                bad_crc: 0,
                bad_version: 0,
                value_out_of_range: 0,
            },
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> DecoderStats {
        self.stats
    }

    /// Feed one byte; returns a frame when this byte completes a good one.
    pub fn push(&mut self, byte: u8) -> Option<FrameRepr> {
        let encoded = match self.frames.push(byte)? {
            Collected::Overlong => {
                self.stats.overlong = self.stats.overlong.wrapping_add(1);
                return None;
            }
            Collected::Frame(encoded) => encoded,
        };
        match Self::decode(encoded) {
            Ok(frame) => {
                self.stats.frames_ok = self.stats.frames_ok.wrapping_add(1);
                Some(frame)
            }
            Err(error) => {
                self.stats.count(error);
                None
            }
        }
    }

    fn decode(encoded: &[u8]) -> Result<FrameRepr, WireError> {
        let mut raw = [0u8; MAX_FRAME_LEN];
        // More decoded bytes than any frame holds is `BadLength`.
        let n = cobs::decode(encoded, &mut raw)?;
        let packet = Packet::new_checked(raw.get(..n).unwrap_or(&[]))?;
        FrameRepr::parse(&packet)
    }

    /// Feed a slice of UART bytes; iterate to get the good frames in it.
    /// Bytes left unconsumed when the iterator is dropped are discarded
    /// (iterate to the end to keep them all).
    pub fn feed<'a>(&'a mut self, bytes: &'a [u8]) -> Frames<'a> {
        Frames {
            decoder: self,
            bytes: bytes.iter(),
        }
    }
}

/// Good frames found in one [`FrameDecoder::feed`] slice.
pub struct Frames<'a> {
    decoder: &'a mut FrameDecoder,
    bytes: core::slice::Iter<'a, u8>,
}

impl Iterator for Frames<'_> {
    type Item = FrameRepr;

    fn next(&mut self) -> Option<FrameRepr> {
        for &byte in self.bytes.by_ref() {
            if let Some(frame) = self.decoder.push(byte) {
                return Some(frame);
            }
        }
        None
    }
}
