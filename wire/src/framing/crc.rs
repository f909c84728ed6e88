//! The frames' checksum.

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(&[]), 0xFFFF);
    }
}
