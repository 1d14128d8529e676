//! The MCU's internal flash (the calibration area) as an `embedded-storage` NOR flash, with
//! power-cut injection at any byte.
//!
//! # Model
//!
//! [`SimFlash`] is `sector_count` sectors of `SECTOR_BYTES` each (a const generic, because
//! `NorFlash::ERASE_SIZE` is a constant). The default, [`CalibrationFlash`], is the STM32F405's
//! last two 128 KiB sectors (sectors 10 and 11), addressed from offset 0.
//!
//! - `READ_SIZE = 1`; `WRITE_SIZE = 4`: word programming (the F405's x32 parallelism at 2.7 to
//!   3.6 V); `ERASE_SIZE = SECTOR_BYTES`.
//! - NOR semantics: erased bytes read `0xFF`; programming can only clear bits. With
//!   `MULTIWRITE = false` (the default), programming a word whose new value needs a 0 -> 1
//!   transition fails with [`FlashError::Programming`] at that word (earlier words of the same
//!   write stay programmed), like a programming-sequence error; writing a word again with only
//!   further 0s is allowed and counted in [`FlashStats::words_rewritten`], so tests can insist
//!   on write-once. With `MULTIWRITE = true` the result is the AND of old and new data and the
//!   type implements [`MultiwriteNorFlash`].
//! - Alignment and bounds are checked with `embedded-storage`'s own helpers and reported as
//!   [`NorFlashErrorKind::NotAligned`] / [`NorFlashErrorKind::OutOfBounds`].
//!
//! # Power cuts
//!
//! After [`SimFlash::arm_power_cut`] the flash dies at a chosen point (the idea of
//! sequential-storage's mock flash, which counts bytes until a shut-off):
//!
//! - [`PowerCut::AfterBytes`]`(n)`: power dies when `n` more bytes have been programmed, counted
//!   across writes in programming order (erases do not count). Words wholly before byte `n` are
//!   programmed; if `n` falls inside a word, that word receives a seeded random subset of its
//!   intended bit clears (each with probability 1/2); nothing after it changes. If `n` falls on a
//!   word boundary no word is partial. The operation that reaches `n` returns
//!   [`FlashError::PowerCut`], even if it had just finished its last word (the CPU died before
//!   seeing the result).
//! - [`PowerCut::InErase`]: the `erases_before + 1`-th sector erase from now is interrupted and
//!   leaves the sector as [`EraseCut`] says: an erased prefix with the rest unchanged, a seeded
//!   random prefix, or (the physically likelier picture, since a sector erases as a whole) each
//!   programmed bit of the sector found erased with probability 1/2.
//!
//! After a cut every operation (reads included) fails with [`FlashError::PowerCut`] until
//! [`SimFlash::power_on`], the reboot.
//!
//! ```
//! use embedded_storage::nor_flash::{NorFlash, ReadNorFlash};
//! use hal_sim::flash::{CalibrationFlash, FlashError, PowerCut};
//!
//! let mut flash = CalibrationFlash::default();
//! flash.arm_power_cut(PowerCut::AfterBytes(8));
//! assert_eq!(flash.write(0, &[0x42; 12]), Err(FlashError::PowerCut));
//! flash.power_on();
//! let mut record = [0; 12];
//! flash.read(0, &mut record).unwrap();
//! assert_eq!(record, [0x42, 0x42, 0x42, 0x42, 0x42, 0x42, 0x42, 0x42, 0xFF, 0xFF, 0xFF, 0xFF]);
//! ```
//!
//! Also: erase counts per sector (wear), bytes programmed, an estimate of the time the CPU would
//! stall ([`FlashStats::busy_s`], typical datasheet times), snapshot/restore of the contents and
//! byte corruption for tests.
//!
//! # Limits
//!
//! - No read disturb, retention loss, endurance limit (10 k cycles on the F405) or ECC (the F4 has
//!   none); wear is counted, not enforced.
//! - Real STM32F4 hardware does not reject a 0 -> 1 programming attempt; it programs what it can
//!   (AND) and the result is not guaranteed. The strict default turns that into an error.
//! - Timing is bookkeeping only: operations complete instantly in simulated time.

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, MultiwriteNorFlash, NorFlash, NorFlashError,
    NorFlashErrorKind, ReadNorFlash,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// 128 KiB: the F405's large sectors (5 to 11).
pub const SECTOR_128K_BYTES: usize = 128 * 1024;

/// The calibration area: two 128 KiB sectors, strict write semantics.
pub type CalibrationFlash = SimFlash<SECTOR_128K_BYTES, false>;

/// Typical durations from the STM32F405 datasheet (x32 parallelism), for [`FlashStats::busy_s`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlashTiming {
    /// Programming one 32-bit word (s): 16 us typical.
    pub word_program_s: f64,
    /// Erasing one sector (s): 1 s typical for 128 KiB.
    pub sector_erase_s: f64,
}

impl Default for FlashTiming {
    fn default() -> Self {
        Self {
            word_program_s: 16e-6,
            sector_erase_s: 1.0,
        }
    }
}

/// How an interrupted sector erase leaves the sector.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EraseCut {
    /// The first `erased_bytes` bytes of the sector are erased, the rest unchanged.
    Prefix {
        /// Bytes erased from the sector's start (capped at the sector size).
        erased_bytes: usize,
    },
    /// A seeded random prefix is erased, the rest unchanged.
    RandomPrefix,
    /// Every programmed (0) bit of the sector is found erased with probability 1/2, seeded.
    WeakBits,
}

/// When the power dies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerCut {
    /// When this many more bytes have been programmed.
    AfterBytes(usize),
    /// During the sector erase that follows `erases_before` complete sector erases.
    InErase {
        /// Sector erases completed first (0: the next erase is cut).
        erases_before: u32,
        /// What the cut erase leaves in its sector.
        cut: EraseCut,
    },
}

/// Errors of the simulated flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashError {
    /// Offset or length not a multiple of the read/write/erase size.
    NotAligned,
    /// Range outside the flash.
    OutOfBounds,
    /// Programming the word at `offset` would need a 0 -> 1 transition.
    Programming {
        /// Byte offset of the refused word from the flash's start (word-aligned).
        offset: u32,
    },
    /// The power is off (cut during this or an earlier operation).
    PowerCut,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::Programming { .. } | Self::PowerCut => NorFlashErrorKind::Other,
        }
    }
}

impl From<NorFlashErrorKind> for FlashError {
    fn from(kind: NorFlashErrorKind) -> Self {
        match kind {
            NorFlashErrorKind::NotAligned => Self::NotAligned,
            _ => Self::OutOfBounds,
        }
    }
}

/// Usage counters.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FlashStats {
    /// Erases started per sector (interrupted ones included).
    pub erases_per_sector: Vec<u32>,
    /// Bytes of completely programmed words.
    pub bytes_programmed: u64,
    /// Words programmed while not fully erased (allowed only when no bit goes 0 -> 1).
    pub words_rewritten: u64,
    /// Power cuts that happened.
    pub power_cuts: u32,
    /// Estimated time the CPU would have stalled (s).
    pub busy_s: f64,
}

/// Simulated NOR flash of `SECTOR_BYTES`-byte sectors; `MULTIWRITE` selects AND semantics.
#[derive(Clone, Debug)]
pub struct SimFlash<const SECTOR_BYTES: usize = SECTOR_128K_BYTES, const MULTIWRITE: bool = false> {
    data: Vec<u8>,
    stats: FlashStats,
    timing: FlashTiming,
    rng: ChaCha8Rng,
    armed: Option<PowerCut>,
    powered: bool,
}

impl Default for CalibrationFlash {
    fn default() -> Self {
        Self::new(2, 0)
    }
}

const WORD: usize = 4;

impl<const SECTOR_BYTES: usize, const MULTIWRITE: bool> SimFlash<SECTOR_BYTES, MULTIWRITE> {
    /// `sector_count` erased sectors; `seed` drives the partial-word and erase-cut randomness.
    pub fn new(sector_count: usize, seed: u64) -> Self {
        assert!(SECTOR_BYTES > 0 && SECTOR_BYTES.is_multiple_of(WORD));
        Self {
            data: vec![0xFF; sector_count * SECTOR_BYTES],
            stats: FlashStats {
                erases_per_sector: vec![0; sector_count],
                ..FlashStats::default()
            },
            timing: FlashTiming::default(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            armed: None,
            powered: true,
        }
    }

    /// Replace the timing used for [`FlashStats::busy_s`].
    pub fn with_timing(mut self, timing: FlashTiming) -> Self {
        self.timing = timing;
        self
    }

    /// Arm a power cut (replaces any armed one).
    pub fn arm_power_cut(&mut self, cut: PowerCut) {
        self.armed = Some(cut);
    }

    /// Disarm without cutting.
    pub fn disarm_power_cut(&mut self) {
        self.armed = None;
    }

    /// Is the power on?
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// Cut the power now, between operations (nothing is in progress, so nothing is damaged).
    pub fn power_off(&mut self) {
        self.cut_power();
    }

    /// Reboot after a cut: operations work again; contents stay as the cut left them.
    pub fn power_on(&mut self) {
        self.powered = true;
    }

    /// Usage counters.
    pub fn stats(&self) -> &FlashStats {
        &self.stats
    }

    /// The raw contents (no power check: a debugger's view).
    pub fn contents(&self) -> &[u8] {
        &self.data
    }

    /// A copy of the contents.
    pub fn snapshot(&self) -> Vec<u8> {
        self.data.clone()
    }

    /// Put back contents from [`Self::snapshot`]. Panics on a length mismatch.
    pub fn restore(&mut self, image: &[u8]) {
        assert_eq!(image.len(), self.data.len(), "image length mismatch");
        self.data.copy_from_slice(image);
    }

    /// Flip the bits of `xor_mask` in the byte at `offset` (bit rot, for tests).
    pub fn corrupt(&mut self, offset: usize, xor_mask: u8) {
        self.data[offset] ^= xor_mask;
    }

    fn ensure_powered(&self) -> Result<(), FlashError> {
        if self.powered {
            Ok(())
        } else {
            Err(FlashError::PowerCut)
        }
    }

    fn cut_power(&mut self) -> FlashError {
        self.powered = false;
        self.armed = None;
        self.stats.power_cuts += 1;
        FlashError::PowerCut
    }

    /// Program one word at `offset`, honouring an armed byte-count power cut.
    fn program_word(&mut self, offset: usize, new: [u8; WORD]) -> Result<(), FlashError> {
        let old: [u8; WORD] = self.data[offset..offset + WORD].try_into().unwrap();
        let (old_word, new_word) = (u32::from_le_bytes(old), u32::from_le_bytes(new));
        if !MULTIWRITE && new_word & !old_word != 0 {
            return Err(FlashError::Programming {
                offset: offset as u32,
            });
        }
        if let Some(PowerCut::AfterBytes(budget)) = self.armed {
            if budget < WORD {
                // The cut falls inside this word (budget 0: armed right before it).
                if budget > 0 {
                    let applied_clears = old_word & !new_word & self.rng.random::<u32>();
                    self.data[offset..offset + WORD]
                        .copy_from_slice(&(old_word & !applied_clears).to_le_bytes());
                }
                return Err(self.cut_power());
            }
            self.armed = Some(PowerCut::AfterBytes(budget - WORD));
        }
        let result = old_word & new_word;
        if old_word != u32::MAX {
            self.stats.words_rewritten += 1;
        }
        self.data[offset..offset + WORD].copy_from_slice(&result.to_le_bytes());
        self.stats.bytes_programmed += WORD as u64;
        self.stats.busy_s += self.timing.word_program_s;
        if self.armed == Some(PowerCut::AfterBytes(0)) {
            return Err(self.cut_power());
        }
        Ok(())
    }

    /// Erase one sector, or interrupt it if an erase cut is due.
    fn erase_sector(&mut self, sector: usize) -> Result<(), FlashError> {
        self.stats.erases_per_sector[sector] += 1;
        self.stats.busy_s += self.timing.sector_erase_s;
        let range = sector * SECTOR_BYTES..(sector + 1) * SECTOR_BYTES;
        match self.armed {
            Some(PowerCut::InErase {
                erases_before: 0,
                cut,
            }) => {
                self.interrupted_erase(range, cut);
                return Err(self.cut_power());
            }
            Some(PowerCut::InErase { erases_before, cut }) => {
                self.armed = Some(PowerCut::InErase {
                    erases_before: erases_before - 1,
                    cut,
                })
            }
            _ => {}
        }
        self.data[range].fill(0xFF);
        Ok(())
    }

    fn interrupted_erase(&mut self, range: core::ops::Range<usize>, cut: EraseCut) {
        let sector = &mut self.data[range];
        match cut {
            EraseCut::Prefix { erased_bytes } => {
                sector[..erased_bytes.min(SECTOR_BYTES)].fill(0xFF);
            }
            EraseCut::RandomPrefix => {
                let erased_bytes = self.rng.random_range(0..=SECTOR_BYTES);
                sector[..erased_bytes].fill(0xFF);
            }
            EraseCut::WeakBits => {
                for byte in sector {
                    *byte |= self.rng.random::<u8>();
                }
            }
        }
    }
}

impl<const S: usize, const M: bool> ErrorType for SimFlash<S, M> {
    type Error = FlashError;
}

impl<const S: usize, const M: bool> ReadNorFlash for SimFlash<S, M> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        self.ensure_powered()?;
        check_read(self, offset, bytes.len())?;
        let start = offset as usize;
        bytes.copy_from_slice(&self.data[start..start + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.data.len()
    }
}

impl<const S: usize, const M: bool> NorFlash for SimFlash<S, M> {
    const WRITE_SIZE: usize = WORD;
    const ERASE_SIZE: usize = S;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        self.ensure_powered()?;
        check_erase(self, from, to)?;
        for sector in from as usize / S..to as usize / S {
            self.erase_sector(sector)?;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        self.ensure_powered()?;
        check_write(self, offset, bytes.len())?;
        for (i, word) in bytes.chunks_exact(WORD).enumerate() {
            self.program_word(offset as usize + i * WORD, word.try_into().unwrap())?;
        }
        Ok(())
    }
}

impl<const S: usize> MultiwriteNorFlash for SimFlash<S, true> {}
