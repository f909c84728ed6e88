//! Why a received frame was dropped, and the counts a decoder keeps: one taxonomy for
//! every link, so the camera's decoder, the telemetry's and the host's viewer count alike.

use serde::ser::{Serialize, SerializeStruct, Serializer};

/// Why a received frame was dropped, at the layer that caught it.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// No delimiter within the longest frame the link allows.
    Overlong,
    /// The COBS codes do not add up.
    Cobs,
    /// Shorter than the link's smallest frame, or than its own header says.
    TooShort,
    /// The CRC does not match: a flipped bit, a dropped byte, or two frames run together.
    Crc,
    /// Another layout's version byte.
    Version,
    /// The bytes are not a valid message: bytes left over, a count or a value out of range.
    Body,
}

/// Dropped frames by [`FrameError`]. Counters wrap.
///
/// Serialised (for the host's summaries) with their `total` first.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BadFrames {
    /// [`FrameError::Overlong`] frames.
    pub overlong: u32,
    /// [`FrameError::Cobs`] frames.
    pub bad_cobs: u32,
    /// [`FrameError::TooShort`] frames.
    pub too_short: u32,
    /// [`FrameError::Crc`] frames.
    pub bad_crc: u32,
    /// [`FrameError::Version`] frames.
    pub bad_version: u32,
    /// [`FrameError::Body`] frames.
    pub bad_body: u32,
}

impl BadFrames {
    /// None dropped.
    pub const fn new() -> BadFrames {
        BadFrames {
            overlong: 0,
            bad_cobs: 0,
            too_short: 0,
            bad_crc: 0,
            bad_version: 0,
            bad_body: 0,
        }
    }

    /// Counts one dropped frame.
    pub fn count(&mut self, error: FrameError) {
        let counter = match error {
            FrameError::Overlong => &mut self.overlong,
            FrameError::Cobs => &mut self.bad_cobs,
            FrameError::TooShort => &mut self.too_short,
            FrameError::Crc => &mut self.bad_crc,
            FrameError::Version => &mut self.bad_version,
            FrameError::Body => &mut self.bad_body,
        };
        *counter = counter.wrapping_add(1);
    }

    /// Dropped frames of every kind.
    pub fn total(&self) -> u32 {
        self.overlong
            .wrapping_add(self.bad_cobs)
            .wrapping_add(self.too_short)
            .wrapping_add(self.bad_crc)
            .wrapping_add(self.bad_version)
            .wrapping_add(self.bad_body)
    }
}

impl Serialize for BadFrames {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut s = serializer.serialize_struct("BadFrames", 7)?;
        s.serialize_field("total", &self.total())?;
        s.serialize_field("overlong", &self.overlong)?;
        s.serialize_field("bad_cobs", &self.bad_cobs)?;
        s.serialize_field("too_short", &self.too_short)?;
        s.serialize_field("bad_crc", &self.bad_crc)?;
        s.serialize_field("bad_version", &self.bad_version)?;
        s.serialize_field("bad_body", &self.bad_body)?;
        s.end()
    }
}

/// A decoder's counts: frames returned and frames dropped. Counters wrap.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default, serde::Serialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Good frames returned.
    pub frames_ok: u32,
    /// Frames dropped, by kind.
    pub bad_frames: BadFrames,
}

impl DecoderStats {
    /// Nothing decoded yet.
    pub const fn new() -> DecoderStats {
        DecoderStats {
            frames_ok: 0,
            bad_frames: BadFrames::new(),
        }
    }

    /// Counts one frame's outcome.
    pub fn count<T>(&mut self, outcome: &Result<T, FrameError>) {
        match outcome {
            Ok(_) => self.frames_ok = self.frames_ok.wrapping_add(1),
            Err(e) => self.bad_frames.count(*e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_counts_once_and_the_total_wraps() {
        let mut stats = DecoderStats::new();
        for e in [
            FrameError::Overlong,
            FrameError::Cobs,
            FrameError::TooShort,
            FrameError::Crc,
            FrameError::Version,
            FrameError::Body,
        ] {
            stats.count::<()>(&Err(e));
        }
        stats.count(&Ok(()));
        assert_eq!(stats.frames_ok, 1);
        assert_eq!(stats.bad_frames.total(), 6);
        stats.bad_frames.bad_body = u32::MAX;
        assert_eq!(
            stats.bad_frames.total(),
            4,
            "five ones and u32::MAX wrap to four"
        );
    }
}
