//! A checked view over a decoded (un-stuffed) camera frame.

use super::{WireError, CRC_LEN, DETECTION_LEN, HEADER_LEN, MAX_DETECTIONS};
use crate::framing::crc16;

/// Field offsets inside a decoded frame.
mod field {
    pub const VERSION: usize = 0;
    pub const COUNTER: usize = 1;
    pub const COUNT: usize = 3;
    pub const TAG_ID: usize = 0;
    pub const CX: usize = 2;
    pub const CY: usize = 4;
    pub const DISTANCE: usize = 6;
}

/// A decoded camera frame in a byte buffer.
///
/// Build it with [`Packet::new_checked`]: once the length is checked against
/// the detection count, every accessor is in bounds. Version and CRC are
/// left to [`FrameRepr::parse`](super::FrameRepr::parse), as in smoltcp.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packet<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Packet<T> {
    /// Wrap a buffer without checking it. Accessors may then return
    /// garbage for a short buffer but still never panic.
    pub const fn new_unchecked(buffer: T) -> Self {
        Packet { buffer }
    }

    /// Wrap a buffer and check its length: see [`Packet::check_len`].
    pub fn new_checked(buffer: T) -> Result<Self, WireError> {
        let packet = Self::new_unchecked(buffer);
        packet.check_len()?;
        Ok(packet)
    }

    /// Check that the buffer is exactly as long as its detection count says.
    ///
    /// [`WireError::Truncated`] if shorter than the header plus CRC or than
    /// the count needs, [`WireError::TooManyDetections`] for a count above
    /// [`MAX_DETECTIONS`], [`WireError::BadLength`] for trailing bytes.
    pub fn check_len(&self) -> Result<(), WireError> {
        let len = self.buffer.as_ref().len();
        if len < HEADER_LEN + CRC_LEN {
            return Err(WireError::Truncated);
        }
        let count = usize::from(self.detection_count());
        if count > MAX_DETECTIONS {
            return Err(WireError::TooManyDetections);
        }
        let needed = Self::buffer_len(count);
        if len < needed {
            Err(WireError::Truncated)
        } else if len > needed {
            Err(WireError::BadLength)
        } else {
            Ok(())
        }
    }

    /// Frame length in bytes for `count` detections, CRC included.
    pub const fn buffer_len(count: usize) -> usize {
        HEADER_LEN + count * DETECTION_LEN + CRC_LEN
    }

    /// Give the buffer back.
    pub fn into_inner(self) -> T {
        self.buffer
    }

    fn byte(&self, at: usize) -> u8 {
        self.buffer.as_ref().get(at).copied().unwrap_or(0)
    }

    fn u16_at(&self, at: usize) -> u16 {
        u16::from_le_bytes([self.byte(at), self.byte(at + 1)])
    }

    /// Version byte.
    pub fn version(&self) -> u8 {
        self.byte(field::VERSION)
    }

    /// Frame counter, wraps at 65535.
    pub fn frame_counter(&self) -> u16 {
        self.u16_at(field::COUNTER)
    }

    /// Detection count as sent (checked against [`MAX_DETECTIONS`] by
    /// [`Packet::check_len`]).
    pub fn detection_count(&self) -> u8 {
        self.byte(field::COUNT)
    }

    fn detection_base(index: usize) -> usize {
        HEADER_LEN + index * DETECTION_LEN
    }

    /// Tag id of detection `index`.
    pub fn tag_id(&self, index: usize) -> u16 {
        self.u16_at(Self::detection_base(index) + field::TAG_ID)
    }

    /// Tag centre x of detection `index`, centipixels.
    pub fn cx_centipx(&self, index: usize) -> u16 {
        self.u16_at(Self::detection_base(index) + field::CX)
    }

    /// Tag centre y of detection `index`, centipixels.
    pub fn cy_centipx(&self, index: usize) -> u16 {
        self.u16_at(Self::detection_base(index) + field::CY)
    }

    /// Distance to the tag of detection `index`, millimetres.
    pub fn distance_mm(&self, index: usize) -> u16 {
        self.u16_at(Self::detection_base(index) + field::DISTANCE)
    }

    fn crc_at(&self) -> usize {
        Self::detection_base(usize::from(self.detection_count()))
    }

    /// CRC as sent.
    pub fn crc(&self) -> u16 {
        self.u16_at(self.crc_at())
    }

    /// Whether the sent CRC matches the bytes before it.
    pub fn verify_crc(&self) -> bool {
        let body = self.buffer.as_ref().get(..self.crc_at()).unwrap_or(&[]);
        crc16(body) == self.crc()
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Packet<T> {
    fn set_byte(&mut self, at: usize, value: u8) {
        if let Some(b) = self.buffer.as_mut().get_mut(at) {
            *b = value;
        }
    }

    fn set_u16(&mut self, at: usize, value: u16) {
        let [lo, hi] = value.to_le_bytes();
        self.set_byte(at, lo);
        self.set_byte(at + 1, hi);
    }

    /// Set the version byte.
    pub fn set_version(&mut self, value: u8) {
        self.set_byte(field::VERSION, value);
    }

    /// Set the frame counter.
    pub fn set_frame_counter(&mut self, value: u16) {
        self.set_u16(field::COUNTER, value);
    }

    /// Set the detection count.
    pub fn set_detection_count(&mut self, value: u8) {
        self.set_byte(field::COUNT, value);
    }

    /// Set all fields of detection `index`.
    pub fn set_detection(
        &mut self,
        index: usize,
        tag_id: u16,
        cx_centipx: u16,
        cy_centipx: u16,
        distance_mm: u16,
    ) {
        let base = Self::detection_base(index);
        self.set_u16(base + field::TAG_ID, tag_id);
        self.set_u16(base + field::CX, cx_centipx);
        self.set_u16(base + field::CY, cy_centipx);
        self.set_u16(base + field::DISTANCE, distance_mm);
    }

    /// Compute and write the CRC over everything before it. Call last.
    pub fn fill_crc(&mut self) {
        let at = self.crc_at();
        let crc = crc16(self.buffer.as_ref().get(..at).unwrap_or(&[]));
        self.set_u16(at, crc);
    }
}
