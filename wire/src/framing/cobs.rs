//! Consistent Overhead Byte Stuffing: no `0x00` inside a frame, so `0x00` can end it.

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
    fn known_vectors() {
        let mut enc = [0u8; 16];
        let n = cobs_encode(&[0x11, 0x22, 0x00, 0x33], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let n = cobs_encode(&[0x11, 0x00], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x02, 0x11, 0x01]);
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
    fn long_runs_and_zeros() {
        for raw in [
            std::vec![0u8; 5],
            std::vec![7u8; 254],
            std::vec![7u8; 253],
            std::vec![7u8; 255],
            (0..=255u8).cycle().take(600).collect::<std::vec::Vec<u8>>(),
        ] {
            let mut enc = std::vec![0u8; cobs_len(&raw)];
            let n = cobs_encode(&raw, &mut enc).expect("room");
            assert_eq!(n, enc.len());
            assert!(!enc.contains(&0));
            let m = cobs_decode_in_place(&mut enc).expect("decodes");
            assert_eq!(&enc[..m], &raw[..]);
        }
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
