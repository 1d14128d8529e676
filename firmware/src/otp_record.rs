//! The board's identity in OTP: the layout, reading it back, and provisioning the key, as plain
//! logic over a small trait ([`OtpCells`]) that the board implements on the flash controller
//! (`board::otp`) and the tests on a fake that can fail at any word.
//!
//! # Layout (OTP blocks of 8 words at 0x1FFF_7800, lock bytes at 0x1FFF_7A00, RM0090 3.7.6)
//!
//! | where | what |
//! |---|---|
//! | block 0, word 0 | the gyro's serial number, programmed by the production jig over SWD before anything else |
//! | block b (0..[`KEY_BLOCKS`]), words 1..=4 | a key record: the 128-bit key, big-endian words |
//! | block b, word 5 | its check word: the CRC-32 of the key's 16 bytes |
//!
//! A bit of OTP goes from 1 to 0 once; a block is frozen by writing its lock byte to 0.
//!
//! # Why a check word, and why more than one block
//! Programming stops part way on a power cut or a controller error. Without a check the next
//! boot would read whatever words were programmed as a key nobody knows (the rest all ones),
//! and the board could never be unlocked nor provisioned again. With the check word written
//! last, a record is a key only if all five words are there and agree; anything else in a
//! block's key words makes that block *spent*: it is skipped, and the next provisioning uses
//! the next blank block. [`KEY_BLOCKS`] blocks allow three failed attempts.
//!
//! # Provisioning ([`provision`])
//! Refused (nothing written) when the serial number is not programmed (all ones or 0: boards
//! sharing serial 0 would defeat the check that a calibration record belongs to this gyro),
//! when a key is already there, or when every key block is spent or locked. Otherwise: the
//! first blank block's key words, then its check word, read back and compared; only then is the
//! block locked (and block 0 too, freezing the serial number). A failure at any word leaves a
//! spent block that reads as no key.

use crate::protocol::key::Key;
use crate::storage::crc::crc32;

/// Blocks that may hold a key record: the first provisioning and three retries.
pub const KEY_BLOCKS: u32 = 4;
/// The serial number's word (block 0).
const SERIAL_WORD: u32 = 0;
/// The key record's first word, and its check word.
const KEY_WORD: u32 = 1;
const CHECK_WORD: u32 = 5;
/// An unprogrammed OTP word.
pub const BLANK: u32 = u32::MAX;

/// The flash controller reported an error programming OTP (the word may be partly programmed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OtpWriteError;

/// The OTP area, word by word.
pub trait OtpCells {
    /// Word `word` of block `block` as read now.
    fn read(&self, block: u32, word: u32) -> u32;
    /// Whether `block` is locked.
    fn locked(&self, block: u32) -> bool;
    /// Programs one word (bits can only go from 1 to 0). `Err`: the controller reported an
    /// error (the word may be partly programmed).
    fn program(&mut self, block: u32, word: u32, value: u32) -> Result<(), OtpWriteError>;
    /// Locks `block` for good.
    fn lock(&mut self, block: u32) -> Result<(), OtpWriteError>;
}

/// Why the key could not be provisioned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProvisionError {
    /// Nothing written: the serial number is not programmed, a key is already there, or no key
    /// block is left.
    NotPossible,
    /// A word did not program or read back: that block is spent (reads as no key); the next
    /// provisioning uses the next block.
    Failed,
}

/// The check word of a key record.
pub fn check_word(key_words: [u32; 4]) -> u32 {
    let mut bytes = [0u8; 16];
    for (chunk, word) in bytes.chunks_exact_mut(4).zip(key_words) {
        chunk.copy_from_slice(&word.to_be_bytes());
    }
    crc32(&bytes)
}

/// The serial number: `None` when not programmed (all ones) or 0.
pub fn serial(cells: &impl OtpCells) -> Option<u32> {
    let word = cells.read(0, SERIAL_WORD);
    (word != BLANK && word != 0).then_some(word)
}

fn record(cells: &impl OtpCells, block: u32) -> [u32; 5] {
    core::array::from_fn(|i| cells.read(block, KEY_WORD + i as u32))
}

/// The key: the first block whose record is complete and checks.
pub fn key(cells: &impl OtpCells) -> Option<Key> {
    (0..KEY_BLOCKS).find_map(|block| {
        let [k0, k1, k2, k3, check] = record(cells, block);
        let words = [k0, k1, k2, k3];
        (check == check_word(words))
            .then(|| Key::from_otp_words(words))
            .flatten()
    })
}

/// The block the next provisioning would use (see the module docs), or why there is none.
pub fn next_block(cells: &impl OtpCells) -> Result<u32, ProvisionError> {
    if serial(cells).is_none() || key(cells).is_some() {
        return Err(ProvisionError::NotPossible);
    }
    (0..KEY_BLOCKS)
        .find(|&b| !cells.locked(b) && record(cells, b) == [BLANK; 5])
        .ok_or(ProvisionError::NotPossible)
}

/// Writes `key` (see the module docs): key words, check word, read back, lock.
pub fn provision(cells: &mut impl OtpCells, key: &Key) -> Result<(), ProvisionError> {
    let block = next_block(cells)?;
    let words = key.to_otp_words();
    for (i, &word) in words.iter().enumerate() {
        cells
            .program(block, KEY_WORD + i as u32, word)
            .map_err(|OtpWriteError| ProvisionError::Failed)?;
    }
    cells
        .program(block, CHECK_WORD, check_word(words))
        .map_err(|OtpWriteError| ProvisionError::Failed)?;
    match self::key(cells) {
        Some(k) if k.matches(key) => {}
        _ => return Err(ProvisionError::Failed),
    }
    // The key is good: the locks only freeze it (a failure here leaves a working key).
    let _ = cells.lock(block);
    if block != 0 && !cells.locked(0) {
        let _ = cells.lock(0);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// OTP in RAM; programming fails (leaving the word half-programmed) at the `fail_at`-th
    /// programming operation.
    #[derive(Clone)]
    struct FakeOtp {
        words: [[u32; 8]; 16],
        locks: [bool; 16],
        programmed: u32,
        fail_at: Option<u32>,
    }

    impl FakeOtp {
        fn with_serial(serial: u32) -> Self {
            let mut otp = Self {
                words: [[BLANK; 8]; 16],
                locks: [false; 16],
                programmed: 0,
                fail_at: None,
            };
            otp.words[0][0] = serial;
            otp
        }
    }

    impl OtpCells for FakeOtp {
        fn read(&self, block: u32, word: u32) -> u32 {
            self.words[block as usize][word as usize]
        }
        fn locked(&self, block: u32) -> bool {
            self.locks[block as usize]
        }
        fn program(&mut self, block: u32, word: u32, value: u32) -> Result<(), OtpWriteError> {
            assert!(!self.locks[block as usize], "programming a locked block");
            let n = self.programmed;
            self.programmed += 1;
            let cell = &mut self.words[block as usize][word as usize];
            if self.fail_at == Some(n) {
                // Half the bits made it.
                *cell &= value | 0xFFFF_0000;
                return Err(OtpWriteError);
            }
            *cell &= value;
            Ok(())
        }
        fn lock(&mut self, block: u32) -> Result<(), OtpWriteError> {
            self.locks[block as usize] = true;
            Ok(())
        }
    }

    fn key(n: u8) -> Key {
        Key::from_bytes([n; 16])
    }

    #[test]
    fn provisioning_writes_a_checked_record_and_locks_it() {
        let mut otp = FakeOtp::with_serial(1234);
        assert_eq!(serial(&otp), Some(1234));
        assert_eq!(super::key(&otp), None);
        provision(&mut otp, &key(7)).unwrap();
        assert!(super::key(&otp).unwrap().matches(&key(7)));
        assert!(otp.locks[0]);
        assert_eq!(otp.words[0][0], 1234);
        // A second provisioning is refused and writes nothing.
        let before = otp.programmed;
        assert_eq!(
            provision(&mut otp, &key(9)),
            Err(ProvisionError::NotPossible)
        );
        assert_eq!(otp.programmed, before);
    }

    /// Refused without a serial number (unprogrammed, or 0): nothing written.
    #[test]
    fn no_serial_no_key() {
        for serial in [BLANK, 0] {
            let mut otp = FakeOtp::with_serial(serial);
            assert_eq!(
                provision(&mut otp, &key(7)),
                Err(ProvisionError::NotPossible)
            );
            assert_eq!(otp.programmed, 0);
            assert!(!otp.locks.iter().any(|&l| l));
        }
    }

    /// A failure at any of the five words: no key reads back (never a partial key), nothing is
    /// locked, and the next provisioning, in the next block, works; after three failures the
    /// fourth block still works, after four nothing is left.
    #[test]
    fn a_failure_part_way_leaves_a_spent_block_and_the_next_attempt_works() {
        for fail_at in 0..5 {
            let mut otp = FakeOtp::with_serial(99);
            otp.fail_at = Some(fail_at);
            assert_eq!(provision(&mut otp, &key(3)), Err(ProvisionError::Failed));
            assert_eq!(super::key(&otp), None, "failed at word {fail_at}");
            assert!(!otp.locks.iter().any(|&l| l));
            assert_eq!(next_block(&otp), Ok(1));
            otp.fail_at = None;
            provision(&mut otp, &key(4)).unwrap();
            assert!(super::key(&otp).unwrap().matches(&key(4)));
            assert!(otp.locks[1] && otp.locks[0]);
        }
        let mut otp = FakeOtp::with_serial(99);
        for attempt in 0..KEY_BLOCKS {
            otp.fail_at = Some(otp.programmed + 2);
            assert_eq!(
                provision(&mut otp, &key(5)),
                Err(ProvisionError::Failed),
                "{attempt}"
            );
        }
        assert_eq!(next_block(&otp), Err(ProvisionError::NotPossible));
        assert_eq!(super::key(&otp), None);
    }

    /// The record written by the previous layout (four words, no check word: a key that cannot
    /// be told from a partial one) does not read as a key.
    #[test]
    fn a_record_without_its_check_word_is_no_key() {
        let mut otp = FakeOtp::with_serial(5);
        for (i, w) in key(8).to_otp_words().into_iter().enumerate() {
            otp.words[0][1 + i] = w;
        }
        assert_eq!(super::key(&otp), None);
        assert_eq!(next_block(&otp), Ok(1));
    }
}
