//! Streaming decoder: UART bytes in, frames out.

use super::{FrameRepr, Packet, WireError, MAX_ENCODED_LEN, MAX_FRAME_LEN};
use crate::framing::{cobs_decode, Collected, DecoderStats, FrameCollector, FrameError};

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
            stats: DecoderStats::new(),
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Feed one byte; returns a frame when this byte completes a good one.
    pub fn push(&mut self, byte: u8) -> Option<FrameRepr> {
        let result = match self.frames.push(byte)? {
            Collected::Overlong => Err(FrameError::Overlong),
            Collected::Frame(encoded) => Self::decode(encoded).map_err(FrameError::from),
        };
        self.stats.count(&result);
        result.ok()
    }

    fn decode(encoded: &[u8]) -> Result<FrameRepr, WireError> {
        let mut raw = [0u8; MAX_FRAME_LEN];
        // More decoded bytes than any frame holds is `BadLength`.
        let n = cobs_decode(encoded, &mut raw)?;
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
