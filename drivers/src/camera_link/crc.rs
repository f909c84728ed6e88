//! CRC-16/CCITT-FALSE, bit at a time: 70-byte frames at 30 Hz do not need
//! a 512-byte table in flash.

/// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final
/// xor. Check value for `b"123456789"` is `0x29B1`.
pub const fn crc16_ccitt_false(data: &[u8]) -> u16 {
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
    fn check_value() {
        assert_eq!(crc16_ccitt_false(b"123456789"), 0x29B1);
    }

    #[test]
    fn empty_is_init() {
        assert_eq!(crc16_ccitt_false(&[]), 0xFFFF);
    }
}
