//! The parsed camera frame and its encoder.

use super::{
    Packet, WireError, MAX_CX_CENTIPX, MAX_CY_CENTIPX, MAX_DETECTIONS, MAX_FRAME_LEN, VERSION,
};
use crate::framing::{cobs_encode, cobs_max_len};

/// One AprilTag seen by the camera.
///
/// Fields are private so a detection outside the image cannot be built:
/// use [`TagDetection::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TagDetection {
    tag_id: u16,
    cx_centipx: u16,
    cy_centipx: u16,
    distance_mm: u16,
}

impl TagDetection {
    /// A detection; [`WireError::ValueOutOfRange`] if the centre is outside
    /// the 320 x 240 px image (`cx > 32000` or `cy > 24000` centipixels).
    pub const fn new(
        tag_id: u16,
        cx_centipx: u16,
        cy_centipx: u16,
        distance_mm: u16,
    ) -> Result<Self, WireError> {
        if cx_centipx > MAX_CX_CENTIPX || cy_centipx > MAX_CY_CENTIPX {
            return Err(WireError::ValueOutOfRange);
        }
        Ok(TagDetection {
            tag_id,
            cx_centipx,
            cy_centipx,
            distance_mm,
        })
    }

    /// AprilTag 36h11 id.
    pub const fn tag_id(&self) -> u16 {
        self.tag_id
    }

    /// Tag centre x, centipixels from the image's left edge.
    pub const fn cx_centipx(&self) -> u16 {
        self.cx_centipx
    }

    /// Tag centre y, centipixels from the image's top edge.
    pub const fn cy_centipx(&self) -> u16 {
        self.cy_centipx
    }

    /// Distance from the camera to the tag, millimetres (from apparent size).
    pub const fn distance_mm(&self) -> u16 {
        self.distance_mm
    }
}

/// A whole camera frame: counter plus up to [`MAX_DETECTIONS`] detections.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameRepr {
    /// Frame counter from the camera; a gap means frames were lost.
    pub frame_counter: u16,
    detections: [TagDetection; MAX_DETECTIONS],
    count: u8,
}

impl FrameRepr {
    /// An empty frame with the given counter.
    pub const fn new(frame_counter: u16) -> Self {
        FrameRepr {
            frame_counter,
            detections: [TagDetection {
                tag_id: 0,
                cx_centipx: 0,
                cy_centipx: 0,
                distance_mm: 0,
            }; MAX_DETECTIONS],
            count: 0,
        }
    }

    /// Add a detection; [`WireError::TooManyDetections`] when full.
    pub fn push(&mut self, detection: TagDetection) -> Result<(), WireError> {
        let slot = self
            .detections
            .get_mut(usize::from(self.count))
            .ok_or(WireError::TooManyDetections)?;
        *slot = detection;
        self.count += 1;
        Ok(())
    }

    /// The detections, in the order sent.
    pub fn detections(&self) -> &[TagDetection] {
        self.detections
            .get(..usize::from(self.count))
            .unwrap_or(&[])
    }

    /// Parse a length-checked packet: checks version, CRC and ranges.
    pub fn parse<T: AsRef<[u8]>>(packet: &Packet<T>) -> Result<Self, WireError> {
        packet.check_len()?;
        if packet.version() != VERSION {
            return Err(WireError::BadVersion);
        }
        if !packet.verify_crc() {
            return Err(WireError::BadCrc);
        }
        let mut repr = FrameRepr::new(packet.frame_counter());
        for i in 0..usize::from(packet.detection_count()) {
            repr.push(TagDetection::new(
                packet.tag_id(i),
                packet.cx_centipx(i),
                packet.cy_centipx(i),
                packet.distance_mm(i),
            )?)?;
        }
        Ok(repr)
    }

    /// Decoded length of this frame, CRC included.
    pub fn buffer_len(&self) -> usize {
        Packet::<&[u8]>::buffer_len(usize::from(self.count))
    }

    /// Bytes this frame takes on the line: its COBS bytes and the delimiter, as
    /// [`encode_frame`] writes them. A receiver that knows when the last arrived knows
    /// from this when the first was sent.
    pub fn wire_len(&self) -> usize {
        // Exact: COBS adds its one byte to any frame under 254 bytes, and a frame is at
        // most `MAX_FRAME_LEN`.
        cobs_max_len(self.buffer_len()) + 1
    }

    /// Write this frame into a packet of exactly [`FrameRepr::buffer_len`]
    /// bytes, CRC last.
    pub fn emit<T: AsRef<[u8]> + AsMut<[u8]>>(&self, packet: &mut Packet<T>) {
        packet.set_version(VERSION);
        packet.set_frame_counter(self.frame_counter);
        packet.set_detection_count(self.count);
        for (i, d) in self.detections().iter().enumerate() {
            packet.set_detection(i, d.tag_id, d.cx_centipx, d.cy_centipx, d.distance_mm);
        }
        packet.fill_crc();
    }
}

/// Encode `frame` for the UART: COBS bytes followed by the `0x00`
/// delimiter. Returns the number of bytes written to `out`;
/// [`WireError::BadLength`] if `out` is shorter than
/// [`MAX_ENCODED_LEN`](super::MAX_ENCODED_LEN) + 1 would need.
pub fn encode_frame(frame: &FrameRepr, out: &mut [u8]) -> Result<usize, WireError> {
    let mut raw = [0u8; MAX_FRAME_LEN];
    let len = frame.buffer_len();
    let body = raw.get_mut(..len).ok_or(WireError::BadLength)?;
    frame.emit(&mut Packet::new_unchecked(&mut *body));
    let n = cobs_encode(body, out)?;
    *out.get_mut(n).ok_or(WireError::BadLength)? = 0;
    Ok(n + 1)
}
