//! Consistent Overhead Byte Stuffing for the camera link: the shared
//! [`slam_core::framing`] stuffing with this link's error type.

use super::WireError;
use slam_core::framing::{self, CobsError};

pub use framing::cobs_max_len as max_encoded_len;

impl From<CobsError> for WireError {
    fn from(e: CobsError) -> Self {
        match e {
            CobsError::BufferTooSmall => WireError::BadLength,
            CobsError::Malformed => WireError::BadCobs,
        }
    }
}

/// Encode `src` into `dst`, returning the encoded length (without a `0x00`
/// delimiter). [`WireError::BadLength`] if `dst` is too short.
pub fn encode(src: &[u8], dst: &mut [u8]) -> Result<usize, WireError> {
    Ok(framing::cobs_encode(src, dst)?)
}

/// Decode `src` (one frame, delimiter already removed) into `dst`,
/// returning the decoded length. [`WireError::BadCobs`] for a zero byte or
/// a code that runs past the end; [`WireError::BadLength`] if `dst` is too
/// short.
pub fn decode(src: &[u8], dst: &mut [u8]) -> Result<usize, WireError> {
    Ok(framing::cobs_decode(src, dst)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_map_to_the_link_errors() {
        let mut dec = [0u8; 16];
        assert_eq!(decode(&[0x05, 1, 2], &mut dec), Err(WireError::BadCobs));
        let mut small = [0u8; 2];
        assert_eq!(encode(&[1, 2, 3], &mut small), Err(WireError::BadLength));
        assert_eq!(decode(&[4, 1, 2, 3], &mut small), Err(WireError::BadLength));
        let n = encode(&[0x11, 0x00], &mut dec).unwrap_or(0);
        assert_eq!(&dec[..n], &[0x02, 0x11, 0x01]);
    }
}
