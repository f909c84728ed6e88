//! Splitting a byte stream into stuffed frames at each `0x00`.

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
}
