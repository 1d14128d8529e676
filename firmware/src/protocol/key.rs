//! The board's calibration key: 128 bits, written once at production, never a published default.
//!
//! # Life cycle (see docs/rlg-cal.md "Security model")
//! - A board leaves the factory **unprovisioned**: OTP block 0 words 1..=4 read all ones. It
//!   answers every read, but every protected command is refused (`ERR 9`), `unlock` is refused
//!   with `ERR 16 no key provisioned`, and `status` reports `key=unprovisioned`.
//! - Production runs `key provision <32 hex digits>` once: the service writes the key to OTP
//!   through the platform ([`crate::service::ports::Secrets::program_key`]), locks the OTP
//!   block, and from then on `status` reports `key=provisioned`. A second `key provision` is
//!   refused (`ERR 11`) without touching OTP, whatever key it carries.
//! - The comparison with a given key takes the same time whatever bytes differ
//!   ([`Key::matches`]), so timing reveals nothing of the key.
//!
//! 128 bits: with the wrong-key back-off (`super::access`) an attacker gets at most a few
//! thousand guesses a day; 2^128 keys make guessing pointless even if the back-off were gone.

/// A 128-bit key (16 bytes, most significant first as typed in hex).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Key([u8; 16]);

/// Hex digits of a key as typed.
pub const KEY_HEX_DIGITS: usize = 32;

impl core::fmt::Debug for Key {
    /// Never prints the key (answers and logs must not leak it).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("Key(..)")
    }
}

impl Key {
    /// The key of `bytes` (most significant first).
    pub const fn from_bytes(bytes: [u8; 16]) -> Self {
        Self(bytes)
    }

    /// The bytes, most significant first.
    pub const fn to_bytes(&self) -> [u8; 16] {
        self.0
    }

    /// Exactly 32 hex digits (either case, an optional `0x`); `None` for anything else. A key
    /// of all ones is refused: it reads as unprogrammed OTP.
    pub fn parse_hex(text: &str) -> Option<Self> {
        let digits = text.strip_prefix("0x").unwrap_or(text).as_bytes();
        if digits.len() != KEY_HEX_DIGITS {
            return None;
        }
        let mut bytes = [0u8; 16];
        for (byte, pair) in bytes.iter_mut().zip(digits.chunks_exact(2)) {
            let [hi, lo] = pair else {
                return None;
            };
            let hi = (*hi as char).to_digit(16)?;
            let lo = (*lo as char).to_digit(16)?;
            *byte = (hi << 4 | lo) as u8;
        }
        let key = Self(bytes);
        (!key.is_erased()).then_some(key)
    }

    /// The key from the four OTP words as read (word 0 holds bytes 0..4, big-endian, so the
    /// hex text reads in word order); `None` when all four are unprogrammed (all ones).
    pub fn from_otp_words(words: [u32; 4]) -> Option<Self> {
        let mut bytes = [0u8; 16];
        for (chunk, word) in bytes.chunks_exact_mut(4).zip(words) {
            chunk.copy_from_slice(&word.to_be_bytes());
        }
        let key = Self(bytes);
        (!key.is_erased()).then_some(key)
    }

    /// The four OTP words that [`Self::from_otp_words`] reads back as this key.
    pub fn to_otp_words(&self) -> [u32; 4] {
        let mut words = [0u32; 4];
        for (word, chunk) in words.iter_mut().zip(self.0.as_chunks::<4>().0) {
            *word = u32::from_be_bytes(*chunk);
        }
        words
    }

    /// The key as typed (32 lower-case hex digits), for echoing a `key provision` back to the
    /// person who typed it.
    pub fn hex(&self) -> KeyHex<'_> {
        KeyHex(self)
    }

    /// Compares with `given` in time independent of where they differ.
    pub fn matches(&self, given: &Key) -> bool {
        let diff = self
            .0
            .iter()
            .zip(given.0)
            .fold(0u8, |d, (a, b)| d | (a ^ b));
        // Keep the fold from being turned into an early-exit compare.
        core::hint::black_box(diff) == 0
    }

    fn is_erased(&self) -> bool {
        self.0.iter().all(|&b| b == 0xFF)
    }
}

/// [`Key::hex`].
pub struct KeyHex<'a>(&'a Key);

impl core::fmt::Display for KeyHex<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.0 .0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEX: &str = "00112233445566778899aabbccddeeff";

    #[test]
    fn parses_32_hex_digits_only() {
        let k = Key::parse_hex(HEX).unwrap();
        assert_eq!(k.to_bytes()[0], 0x00);
        assert_eq!(k.to_bytes()[15], 0xFF);
        assert_eq!(Key::parse_hex(&HEX.to_uppercase()), Some(k));
        assert_eq!(Key::parse_hex(&format!("0x{HEX}")), Some(k));
        // The old 32-bit development key and anything but 32 digits is no key.
        assert_eq!(Key::parse_hex("c0ffee42"), None);
        assert_eq!(Key::parse_hex(&HEX[1..]), None);
        assert_eq!(Key::parse_hex(&format!("{HEX}0")), None);
        assert_eq!(Key::parse_hex(&HEX.replace('a', "g")), None);
        assert_eq!(Key::parse_hex(&"f".repeat(32)), None, "reads as erased OTP");
    }

    #[test]
    fn otp_words_round_trip_and_erased_words_are_no_key() {
        let k = Key::parse_hex(HEX).unwrap();
        assert_eq!(
            k.to_otp_words(),
            [0x0011_2233, 0x4455_6677, 0x8899_aabb, 0xccdd_eeff]
        );
        assert_eq!(Key::from_otp_words(k.to_otp_words()), Some(k));
        assert_eq!(Key::from_otp_words([u32::MAX; 4]), None);
    }

    #[test]
    fn matches_only_the_same_key_and_debug_hides_it() {
        let k = Key::parse_hex(HEX).unwrap();
        let mut other = k.to_bytes();
        other[15] ^= 1;
        assert!(k.matches(&k));
        assert!(!k.matches(&Key::from_bytes(other)));
        assert_eq!(format!("{k:?}"), "Key(..)");
    }
}
