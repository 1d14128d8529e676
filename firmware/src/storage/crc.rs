//! CRC-32/ISO-HDLC (the zlib/Ethernet CRC): reflected polynomial 0xEDB88320, initial value and
//! final XOR 0xFFFF_FFFF; check value `crc32(b"123456789") == 0xCBF4_3926`.
//!
//! Half-byte table (16 words, built at compile time): two lookups per byte, 64 bytes of flash
//! instead of the 1 KiB of a byte table. A 56-byte record body costs about 112 lookups.

/// The reflected CRC-32 polynomial.
const POLYNOMIAL: u32 = 0xEDB8_8320;

/// CRC of each half-byte value, for the reflected (LSB-first) register.
#[allow(
    clippy::indexing_slicing,
    reason = "evaluated at compile time: an index out of range would fail the build"
)]
const NIBBLE_TABLE: [u32; 16] = {
    let mut table = [0u32; 16];
    let mut nibble = 0;
    while nibble < 16 {
        let mut crc = nibble as u32;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ POLYNOMIAL
            } else {
                crc >> 1
            };
            bit += 1;
        }
        table[nibble] = crc;
        nibble += 1;
    }
    table
};

/// A running CRC-32, for data read in pieces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc32 {
    register: u32,
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// Nothing fed yet (register 0xFFFF_FFFF).
    pub const fn new() -> Self {
        Self {
            register: 0xFFFF_FFFF,
        }
    }

    /// Feeds `bytes` (in order).
    #[allow(
        clippy::indexing_slicing,
        reason = "the index is masked to 0..=15, the table has 16 entries"
    )]
    pub fn update(&mut self, bytes: &[u8]) {
        let mut crc = self.register;
        for &byte in bytes {
            crc ^= byte as u32;
            crc = (crc >> 4) ^ NIBBLE_TABLE[(crc & 0xF) as usize];
            crc = (crc >> 4) ^ NIBBLE_TABLE[(crc & 0xF) as usize];
        }
        self.register = crc;
    }

    /// The CRC of everything fed so far.
    pub const fn finish(&self) -> u32 {
        !self.register
    }
}

/// CRC-32/ISO-HDLC of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = Crc32::new();
    crc.update(bytes);
    crc.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn pieces_equal_whole() {
        let data: [u8; 61] = core::array::from_fn(|i| (i * 37 + 11) as u8);
        let mut crc = Crc32::new();
        crc.update(&data[..13]);
        crc.update(&data[13..]);
        assert_eq!(crc.finish(), crc32(&data));
    }

    #[test]
    fn matches_bitwise_reference() {
        fn bitwise(bytes: &[u8]) -> u32 {
            let mut crc = 0xFFFF_FFFFu32;
            for &byte in bytes {
                crc ^= byte as u32;
                for _ in 0..8 {
                    crc = if crc & 1 != 0 {
                        (crc >> 1) ^ POLYNOMIAL
                    } else {
                        crc >> 1
                    };
                }
            }
            !crc
        }
        let data: [u8; 256] = core::array::from_fn(|i| i as u8);
        for len in 0..data.len() {
            assert_eq!(crc32(&data[..len]), bitwise(&data[..len]));
        }
    }
}
