//! Consistent Overhead Byte Stuffing: removes every `0x00` from a frame so
//! `0x00` can mark frame ends on the UART. Encode and decode write into
//! caller-supplied buffers and never panic.

use super::WireError;

/// Worst-case encoded length of `len` bytes (no delimiter): one code byte
/// per started run of 254 bytes, plus the leading code byte.
pub const fn max_encoded_len(len: usize) -> usize {
    len + len / 254 + 1
}

/// Encode `src` into `dst`, returning the encoded length (without a `0x00`
/// delimiter). [`WireError::BadLength`] if `dst` is too short.
pub fn encode(src: &[u8], dst: &mut [u8]) -> Result<usize, WireError> {
    let mut code_at = 0usize;
    let mut out = 1usize;
    let mut code: u8 = 1;
    for &byte in src {
        if byte == 0 {
            *dst.get_mut(code_at).ok_or(WireError::BadLength)? = code;
            code_at = out;
            out += 1;
            code = 1;
        } else {
            *dst.get_mut(out).ok_or(WireError::BadLength)? = byte;
            out += 1;
            code += 1;
            if code == 0xFF {
                *dst.get_mut(code_at).ok_or(WireError::BadLength)? = code;
                code_at = out;
                out += 1;
                code = 1;
            }
        }
    }
    *dst.get_mut(code_at).ok_or(WireError::BadLength)? = code;
    Ok(out)
}

/// Decode `src` (one frame, delimiter already removed) into `dst`,
/// returning the decoded length. [`WireError::BadCobs`] for a zero byte or
/// a code that runs past the end; [`WireError::BadLength`] if `dst` is too
/// short.
pub fn decode(src: &[u8], dst: &mut [u8]) -> Result<usize, WireError> {
    let mut at = 0usize;
    let mut out = 0usize;
    while at < src.len() {
        let code = src.get(at).copied().ok_or(WireError::BadCobs)?;
        if code == 0 {
            return Err(WireError::BadCobs);
        }
        at += 1;
        let run = usize::from(code - 1);
        let data = src.get(at..at + run).ok_or(WireError::BadCobs)?;
        if data.contains(&0) {
            return Err(WireError::BadCobs);
        }
        dst.get_mut(out..out + run)
            .ok_or(WireError::BadLength)?
            .copy_from_slice(data);
        out += run;
        at += run;
        if code != 0xFF && at < src.len() {
            *dst.get_mut(out).ok_or(WireError::BadLength)? = 0;
            out += 1;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip(data: &[u8]) {
        let mut enc = [0u8; 600];
        let n = encode(data, &mut enc).unwrap();
        assert!(n <= max_encoded_len(data.len()));
        assert!(!enc[..n].contains(&0));
        let mut dec = [0u8; 600];
        let m = decode(&enc[..n], &mut dec).unwrap();
        assert_eq!(&dec[..m], data);
    }

    #[test]
    fn known_vectors() {
        let mut enc = [0u8; 16];
        let n = encode(&[0x11, 0x22, 0x00, 0x33], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x03, 0x11, 0x22, 0x02, 0x33]);
        let n = encode(&[0x00], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01, 0x01]);
        let n = encode(&[], &mut enc).unwrap();
        assert_eq!(&enc[..n], &[0x01]);
    }

    #[test]
    fn round_trips() {
        round_trip(&[]);
        round_trip(&[0]);
        round_trip(&[0, 0, 0]);
        round_trip(&[1, 2, 0, 3, 0]);
        let long: Vec<u8> = (0..520u32).map(|i| (i % 255 + 1) as u8).collect();
        round_trip(&long);
        let mixed: Vec<u8> = (0..520u32).map(|i| (i % 7) as u8).collect();
        round_trip(&mixed);
    }

    #[test]
    fn rejects_code_past_end() {
        let mut dec = [0u8; 16];
        assert_eq!(decode(&[0x05, 1, 2], &mut dec), Err(WireError::BadCobs));
        assert_eq!(decode(&[0x02, 0x00], &mut dec), Err(WireError::BadCobs));
    }

    #[test]
    fn small_buffers_are_errors() {
        let mut small = [0u8; 2];
        assert_eq!(encode(&[1, 2, 3], &mut small), Err(WireError::BadLength));
        assert_eq!(decode(&[4, 1, 2, 3], &mut small), Err(WireError::BadLength));
    }
}
