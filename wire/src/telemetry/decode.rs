//! The receiving side: bytes in, messages out.

use super::{Message, MAX_FRAME_LEN, WIRE_VERSION};
use crate::framing::{
    cobs_decode_in_place, crc16, Collected, DecoderStats, FrameCollector, FrameError,
};

/// Bytes in, messages out, with a fixed buffer of one frame.
///
/// Bytes gather until a `0x00`; then the frame is un-stuffed, checked and parsed. A bad
/// frame (garbage, a dropped byte, a viewer joining mid-frame) is counted and the decoder
/// starts over at the next `0x00`. Empty frames are skipped silently.
#[derive(Clone, Debug)]
pub struct StreamDecoder {
    frames: FrameCollector<{ MAX_FRAME_LEN - 1 }>,
    stats: DecoderStats,
}

impl Default for StreamDecoder {
    fn default() -> Self {
        StreamDecoder::new()
    }
}

impl StreamDecoder {
    /// A decoder waiting for its first frame.
    pub const fn new() -> StreamDecoder {
        StreamDecoder {
            frames: FrameCollector::new(),
            stats: DecoderStats::new(),
        }
    }

    /// Counts so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Whether bytes of an unfinished frame are waiting for their delimiter (at the end of
    /// a recording: a frame cut short).
    pub fn has_partial_frame(&self) -> bool {
        self.frames.has_partial()
    }

    /// Feeds one byte: `Some` when it ends a frame (a message, or why the frame was
    /// dropped, already counted), `None` otherwise.
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        let result = match self.frames.push(byte)? {
            Collected::Overlong => Err(FrameError::Overlong),
            Collected::Frame(encoded) => Self::parse(encoded),
        };
        self.stats.count(&result);
        Some(result)
    }

    /// Feeds a run of bytes; the iterator yields each frame they end.
    pub fn feed<'d, 'b>(&'d mut self, bytes: &'b [u8]) -> Frames<'d, 'b> {
        Frames {
            decoder: self,
            bytes: bytes.iter(),
        }
    }

    fn parse(encoded: &mut [u8]) -> Result<Message, FrameError> {
        let n = cobs_decode_in_place(encoded).map_err(|_| FrameError::Cobs)?;
        let raw = encoded.get(..n).ok_or(FrameError::Cobs)?;
        if raw.len() < 3 {
            return Err(FrameError::TooShort);
        }
        let (checked, crc) = raw.split_at(raw.len() - 2);
        let sent = u16::from_le_bytes([
            *crc.first().ok_or(FrameError::TooShort)?,
            *crc.get(1).ok_or(FrameError::TooShort)?,
        ]);
        if crc16(checked) != sent {
            return Err(FrameError::Crc);
        }
        let (version, body) = checked.split_first().ok_or(FrameError::TooShort)?;
        if *version != WIRE_VERSION {
            return Err(FrameError::Version);
        }
        match postcard::take_from_bytes::<Message>(body) {
            Ok((message, [])) => Ok(message),
            _ => Err(FrameError::Body),
        }
    }
}

/// The frames a run of bytes ends: see [`StreamDecoder::feed`].
pub struct Frames<'d, 'b> {
    decoder: &'d mut StreamDecoder,
    bytes: core::slice::Iter<'b, u8>,
}

impl Iterator for Frames<'_, '_> {
    type Item = Result<Message, FrameError>;
    fn next(&mut self) -> Option<Self::Item> {
        for &b in self.bytes.by_ref() {
            if let Some(r) = self.decoder.push(b) {
                return Some(r);
            }
        }
        None
    }
}
