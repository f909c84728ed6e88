//! Byte framing shared by every serial link of the robot: COBS stuffing and CRC-16.
//!
//! COBS removes every `0x00` from a frame so `0x00` can end it on the wire, and a
//! receiver that joins mid-stream or meets garbage resynchronises at the next `0x00`.
//! The camera co-processor's link and the telemetry stream both use it.

/// CRC-16/CCITT-FALSE: polynomial `0x1021`, initial `0xFFFF`, MSB first, no final XOR;
/// `b"123456789"` gives `0x29B1`.
///
/// Bit by bit rather than by table: frames are under 150 bytes and the M0+'s flash is
/// better spent elsewhere.
pub const fn crc16(data: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    let mut i = 0;
    while i < data.len() {
        crc ^= (data[i] as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        i += 1;
    }
    crc
}

/// Why COBS could not stuff or un-stuff a frame.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CobsError {
    /// The output buffer is too short.
    BufferTooSmall,
    /// The input holds a `0x00`, or a code runs past its end.
    Malformed,
}

/// Worst-case stuffed length of `len` bytes, without the delimiter.
pub const fn cobs_max_len(len: usize) -> usize {
    len + len / 254 + 1
}

/// Exact stuffed length of `raw`, without the delimiter.
pub fn cobs_len(raw: &[u8]) -> usize {
    let (mut len, mut run) = (1, 0);
    for &b in raw {
        len += 1;
        if b == 0 {
            run = 0;
        } else {
            run += 1;
            if run == 254 {
                len += 1;
                run = 0;
            }
        }
    }
    len
}

/// Stuffs `src` into `dst` (no delimiter written), returning the stuffed length.
pub fn cobs_encode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let (mut code_at, mut out, mut code) = (0usize, 1usize, 1u8);
    for &byte in src {
        if byte == 0 {
            *dst.get_mut(code_at).ok_or(CobsError::BufferTooSmall)? = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            *dst.get_mut(out).ok_or(CobsError::BufferTooSmall)? = byte;
            out += 1;
            code += 1;
            if code == 0xFF {
                *dst.get_mut(code_at).ok_or(CobsError::BufferTooSmall)? = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    *dst.get_mut(code_at).ok_or(CobsError::BufferTooSmall)? = code;
    Ok(out)
}

/// Un-stuffs one frame (delimiter already removed) from `src` into `dst`, returning the
/// frame's length.
pub fn cobs_decode(src: &[u8], dst: &mut [u8]) -> Result<usize, CobsError> {
    let (mut at, mut out) = (0usize, 0usize);
    while at < src.len() {
        let code = src.get(at).copied().ok_or(CobsError::Malformed)?;
        if code == 0 {
            return Err(CobsError::Malformed);
        }
        at += 1;
        let run = usize::from(code - 1);
        let data = src.get(at..at + run).ok_or(CobsError::Malformed)?;
        if data.contains(&0) {
            return Err(CobsError::Malformed);
        }
        dst.get_mut(out..out + run)
            .ok_or(CobsError::BufferTooSmall)?
            .copy_from_slice(data);
        out += run;
        at += run;
        if code != 0xFF && at < src.len() {
            *dst.get_mut(out).ok_or(CobsError::BufferTooSmall)? = 0;
            out += 1;
        }
    }
    Ok(out)
}

/// Un-stuffs one frame in place (the decoded frame is never longer than the stuffed one).
pub fn cobs_decode_in_place(buf: &mut [u8]) -> Result<usize, CobsError> {
    let len = buf.len();
    let (mut read, mut write) = (0, 0);
    while read < len {
        let code = *buf.get(read).ok_or(CobsError::Malformed)? as usize;
        if code == 0 {
            return Err(CobsError::Malformed);
        }
        read += 1;
        let end = read + code - 1;
        if end > len || buf.get(read..end).is_some_and(|d| d.contains(&0)) {
            return Err(CobsError::Malformed);
        }
        buf.copy_within(read..end, write);
        write += end - read;
        read = end;
        if code != 0xFF && read < len {
            *buf.get_mut(write).ok_or(CobsError::Malformed)? = 0;
            write += 1;
        }
    }
    Ok(write)
}

/// What a delimiter ended, in [`FrameCollector::push`].
#[derive(Debug, PartialEq, Eq)]
pub enum Collected<'a> {
    /// A stuffed frame, delimiter removed; the collector is ready for the next one.
    Frame(&'a mut [u8]),
    /// The frame ran past the buffer and was dropped.
    Overlong,
}

/// Splits a byte stream into stuffed frames at each `0x00`, in a fixed buffer of `N` bytes.
///
/// A receiver that joins mid-stream, or meets garbage, loses at most the frame it was in:
/// the next delimiter starts over. Empty frames (`0x00 0x00`) are skipped, so a sender may
/// send a lone delimiter to flush a receiver's partial frame.
#[derive(Clone, Debug)]
pub struct FrameCollector<const N: usize> {
    buf: [u8; N],
    len: usize,
    overflowed: bool,
}

impl<const N: usize> Default for FrameCollector<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FrameCollector<N> {
    /// An empty collector.
    pub const fn new() -> Self {
        FrameCollector {
            buf: [0; N],
            len: 0,
            overflowed: false,
        }
    }

    /// Feeds one byte: `Some` when it is a delimiter ending a non-empty frame.
    pub fn push(&mut self, byte: u8) -> Option<Collected<'_>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
            }
            return None;
        }
        let len = core::mem::replace(&mut self.len, 0);
        if core::mem::replace(&mut self.overflowed, false) {
            return Some(Collected::Overlong);
        }
        match self.buf.get_mut(..len) {
            Some(frame) if !frame.is_empty() => Some(Collected::Frame(frame)),
            _ => None,
        }
    }

    /// Whether bytes of an unfinished frame are waiting for their delimiter.
    pub fn has_partial(&self) -> bool {
        self.len > 0 || self.overflowed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(data: &[u8]) {
        let mut enc = [0u8; 600];
        let n = cobs_encode(data, &mut enc).unwrap();
        assert_eq!(n, cobs_len(data));
        assert!(n <= cobs_max_len(data.len()));
        assert!(!enc[..n].contains(&0));
        let mut dec = [0u8; 600];
        let m = cobs_decode(&enc[..n], &mut dec).unwrap();
        assert_eq!(&dec[..m], data);
        let m = cobs_decode_in_place(&mut enc[..n]).unwrap();
        assert_eq!(&enc[..m], data);
    }

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(&[]), 0xFFFF);
    }

    #[test]
    fn known_vectors() {
        let mut enc = [0u8; 16];
        let n = cobs_encode(&[0x11, 0x22, 0x00, 0x33], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let n = cobs_encode(&[0x00], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01, 0x01]);
        let n = cobs_encode(&[], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01]);
    }

    #[test]
    fn round_trips() {
        round_trip(&[]);
        round_trip(&[0]);
        round_trip(&[0, 0, 0]);
        round_trip(&[1, 2, 0, 3, 0]);
        let long: std::vec::Vec<u8> = (0..520u32).map(|i| (i % 255 + 1) as u8).collect();
        round_trip(&long);
        let mixed: std::vec::Vec<u8> = (0..520u32).map(|i| (i % 7) as u8).collect();
        round_trip(&mixed);
    }

    #[test]
    fn collector_splits_at_delimiters_and_drops_overlong() {
        let mut c: FrameCollector<4> = FrameCollector::new();
        assert_eq!(c.push(0), None, "empty frames are skipped");
        for b in [1, 2, 3] {
            assert_eq!(c.push(b), None);
        }
        assert!(c.has_partial());
        assert_eq!(c.push(0), Some(Collected::Frame(&mut [1, 2, 3])));
        assert!(!c.has_partial());
        for b in [9; 7] {
            assert_eq!(c.push(b), None);
        }
        assert_eq!(c.push(0), Some(Collected::Overlong));
        c.push(5);
        assert_eq!(
            c.push(0),
            Some(Collected::Frame(&mut [5])),
            "recovers after an overlong frame"
        );
    }

    #[test]
    fn malformed_and_short() {
        let mut dec = [0u8; 16];
        assert_eq!(
            cobs_decode(&[0x05, 1, 2], &mut dec),
            Err(CobsError::Malformed)
        );
        assert_eq!(
            cobs_decode(&[0x02, 0x00], &mut dec),
            Err(CobsError::Malformed)
        );
        assert_eq!(
            cobs_decode_in_place(&mut [0x05, 1, 2]),
            Err(CobsError::Malformed)
        );
        assert_eq!(
            cobs_decode_in_place(&mut [0x03, 1, 0]),
            Err(CobsError::Malformed)
        );
        let mut small = [0u8; 2];
        assert_eq!(
            cobs_encode(&[1, 2, 3], &mut small),
            Err(CobsError::BufferTooSmall)
        );
        assert_eq!(
            cobs_decode(&[4, 1, 2, 3], &mut small),
            Err(CobsError::BufferTooSmall)
        );
    }
}
