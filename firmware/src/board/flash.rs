//! The internal flash as an `embedded_storage` NOR flash, for the calibration sectors 10 and 11.
//!
//! Offsets are from 0x0800_0000 (capacity 1 MiB), so the store uses
//! `Geometry::F405_SECTORS_10_11`. Reads may cover the whole flash; erase and program are
//! refused outside 0x000C_0000..0x0010_0000 (the two 128 KiB sectors `memory.x` keeps free of
//! code), so no bug in the store can erase the firmware.
//!
//! # Registers (RM0090 3.5-3.9)
//! - Unlock: `KEYR <- 0x4567_0123, 0xCDEF_89AB`; lock again (`CR.LOCK`) after every operation,
//!   also after an error, so a wild write cannot program flash.
//! - `CR.PSIZE = 10` (x32): needs VDD 2.7-3.6 V; a 128 KiB erase takes 1 s typical, 2 s maximum
//!   (x8 would double it). Programming one word: 16 us typical.
//! - Erase: `CR = PSIZE | SER | SNB`, then `STRT`; program: `CR = PSIZE | PG`, then one 32-bit
//!   store to the address. Both: wait while `SR.BSY`, then check `SR` (`OPERR`, `WRPERR`, `PGAERR`,
//!   `PGPERR`, `PGSERR`) -> [`FlashError`], clear the flags (write 1).
//! - After an erase or program, the ART data cache may hold the old contents of those addresses:
//!   it is reset before anything reads them back, in four separate writes, because `DCRST` may
//!   be written only while the data cache is disabled (RM0090 3.9.1, FLASH_ACR): `DCEN = 0`,
//!   `DCRST = 1`, `DCRST = 0`, `DCEN = 1`.
//!
//! # The stall
//! The F405 has a single flash bank. While `BSY` is set, every instruction fetch and data read
//! from flash waits: the CPU, and every interrupt handler (they all live in flash), stop for up
//! to 2 s per sector erase and ~16-100 us per word. Turnarounds are missed, the USART overruns,
//! the encoder count goes on in hardware unobserved. Hence the store runs only from the main loop
//! with the readout paused (`storage::ReadoutPaused`, see `app`), and the watchdog timeout is
//! longer than the worst erase (see `watchdog`). Polling `BSY` from flash code is fine: the
//! poll itself is what stalls.

use embedded_storage::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

use super::pac;

/// First byte of the flash.
const FLASH_BASE: u32 = 0x0800_0000;
/// The writable window: sectors 10 and 11.
const WRITABLE: core::ops::Range<u32> = 0x000C_0000..0x0010_0000;
const SECTOR_BYTES: u32 = 128 * 1024;
const FIRST_SECTOR: u32 = 10;

const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
// FLASH_SR
const SR_EOP: u32 = 1 << 0;
const SR_OPERR: u32 = 1 << 1;
const SR_WRPERR: u32 = 1 << 4;
const SR_PGAERR: u32 = 1 << 5;
const SR_PGPERR: u32 = 1 << 6;
const SR_PGSERR: u32 = 1 << 7;
const SR_ERRORS: u32 = SR_OPERR | SR_WRPERR | SR_PGAERR | SR_PGPERR | SR_PGSERR;
const SR_BSY: u32 = 1 << 16;
// FLASH_CR
const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_PSIZE_X32: u32 = 0b10 << 8;
const CR_PSIZE_X8: u32 = 0b00 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
// FLASH_ACR
const ACR_DCEN: u32 = 1 << 10;
const ACR_DCRST: u32 = 1 << 12;

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// Outside the flash (read) or outside sectors 10-11 (erase, program).
    OutOfBounds,
    /// Offset or length not a multiple of the erase or write size.
    NotAligned,
    /// The controller reported an error: the `FLASH_SR` error bits.
    Controller(u32),
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            Self::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            Self::NotAligned => NorFlashErrorKind::NotAligned,
            Self::Controller(_) => NorFlashErrorKind::Other,
        }
    }
}

/// The flash (owns the flash interface registers).
pub struct InternalFlash {
    regs: pac::FLASH,
}

impl InternalFlash {
    /// Takes the flash interface; it is unlocked only for a write or an erase.
    pub fn new(regs: pac::FLASH) -> Self {
        Self { regs }
    }

    fn unlock(&mut self) {
        if self.regs.cr().read().bits() & CR_LOCK != 0 {
            self.regs.keyr().write(|w| unsafe { w.bits(KEY1) });
            self.regs.keyr().write(|w| unsafe { w.bits(KEY2) });
        }
        // Stale flags of an earlier operation would read as this one's errors.
        self.regs
            .sr()
            .write(|w| unsafe { w.bits(SR_ERRORS | SR_EOP) });
    }

    fn lock(&mut self) {
        self.regs.cr().write(|w| unsafe { w.bits(CR_LOCK) });
        // The data cache reset, DCRST written only with the cache disabled (module docs).
        let acr = self.regs.acr().read().bits() & !ACR_DCRST;
        let off = acr & !ACR_DCEN;
        for step in [off, off | ACR_DCRST, off, acr] {
            self.regs.acr().write(|w| unsafe { w.bits(step) });
        }
    }

    /// Waits for the end of the operation (the CPU stalls here) and collects its errors.
    fn finish(&mut self) -> Result<(), FlashError> {
        while self.regs.sr().read().bits() & SR_BSY != 0 {}
        let sr = self.regs.sr().read().bits();
        self.regs
            .sr()
            .write(|w| unsafe { w.bits(SR_ERRORS | SR_EOP) });
        match sr & SR_ERRORS {
            0 => Ok(()),
            errors => Err(FlashError::Controller(errors)),
        }
    }

    /// Runs `op` unlocked, locking again whatever happens.
    fn unlocked<T>(
        &mut self,
        op: impl FnOnce(&mut Self) -> Result<T, FlashError>,
    ) -> Result<T, FlashError> {
        self.unlock();
        let result = op(self);
        self.lock();
        result
    }

    fn erase_sector(&mut self, sector: u32) -> Result<(), FlashError> {
        let cr = CR_PSIZE_X32 | CR_SER | (sector << 3);
        self.regs.cr().write(|w| unsafe { w.bits(cr) });
        self.regs.cr().write(|w| unsafe { w.bits(cr | CR_STRT) });
        self.finish()
    }

    fn program_word(&mut self, offset: u32, word: u32) -> Result<(), FlashError> {
        self.regs
            .cr()
            .write(|w| unsafe { w.bits(CR_PSIZE_X32 | CR_PG) });
        // SAFETY: an aligned word inside sectors 10-11 (checked by the caller), PG set.
        unsafe { ((FLASH_BASE + offset) as *mut u32).write_volatile(word) };
        let result = self.finish();
        self.regs.cr().write(|w| unsafe { w.bits(0) });
        result
    }

    /// Programs one word of OTP block `block` (16 blocks of 8 words at 0x1FFF_7800). Each bit
    /// can only go from 1 to 0, once (RM0090 3.7.6); the caller (`crate::otp_record`) decides
    /// what and in which order.
    pub fn program_otp_word(
        &mut self,
        block: u32,
        word: u32,
        value: u32,
    ) -> Result<(), FlashError> {
        if block >= OTP_BLOCKS || word as usize >= OTP_BLOCK_WORDS {
            return Err(FlashError::OutOfBounds);
        }
        let address = OTP_BASE + 32 * block + 4 * word;
        self.unlocked(|f| {
            f.regs
                .cr()
                .write(|w| unsafe { w.bits(CR_PSIZE_X32 | CR_PG) });
            // SAFETY: an aligned word of OTP block `block` (checked above), PG set.
            unsafe { (address as *mut u32).write_volatile(value) };
            let result = f.finish();
            f.regs.cr().write(|w| unsafe { w.bits(0) });
            result
        })
    }

    /// Writes OTP block `block`'s lock byte (0x1FFF_7A00 + block) to 0x00: no word of the block
    /// can be programmed again (RM0090 3.7.6).
    pub fn lock_otp_block(&mut self, block: u32) -> Result<(), FlashError> {
        if block >= OTP_BLOCKS {
            return Err(FlashError::OutOfBounds);
        }
        self.unlocked(|f| {
            f.regs
                .cr()
                .write(|w| unsafe { w.bits(CR_PSIZE_X8 | CR_PG) });
            // SAFETY: the lock byte of block `block`, PG set with byte parallelism.
            unsafe { ((OTP_LOCK_BASE + block) as *mut u8).write_volatile(0x00) };
            let result = f.finish();
            f.regs.cr().write(|w| unsafe { w.bits(0) });
            result
        })
    }
}

/// The OTP area: 16 blocks of 32 bytes, then 16 lock bytes.
pub(super) const OTP_BASE: u32 = 0x1FFF_7800;
pub(super) const OTP_LOCK_BASE: u32 = 0x1FFF_7A00;
const OTP_BLOCKS: u32 = 16;
const OTP_BLOCK_WORDS: usize = 8;

fn writable(from: u32, len: u32) -> Result<(), FlashError> {
    let end = from.checked_add(len).ok_or(FlashError::OutOfBounds)?;
    if from < WRITABLE.start || end > WRITABLE.end {
        return Err(FlashError::OutOfBounds);
    }
    Ok(())
}

impl ErrorType for InternalFlash {
    type Error = FlashError;
}

impl ReadNorFlash for InternalFlash {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let end = offset as usize + bytes.len();
        if end > self.capacity() {
            return Err(FlashError::OutOfBounds);
        }
        for (i, b) in bytes.iter_mut().enumerate() {
            // SAFETY: inside the 1 MiB flash, which is always readable.
            *b = unsafe { ((FLASH_BASE + offset) as *const u8).add(i).read_volatile() };
        }
        Ok(())
    }

    fn capacity(&self) -> usize {
        1024 * 1024
    }
}

impl NorFlash for InternalFlash {
    const WRITE_SIZE: usize = 4;
    /// Sectors 10 and 11 are 128 KiB (the only ones this driver erases).
    const ERASE_SIZE: usize = SECTOR_BYTES as usize;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        if !from.is_multiple_of(SECTOR_BYTES) || !to.is_multiple_of(SECTOR_BYTES) || to < from {
            return Err(FlashError::NotAligned);
        }
        writable(from, to - from)?;
        self.unlocked(|f| {
            (from..to)
                .step_by(SECTOR_BYTES as usize)
                .try_for_each(|at| {
                    f.erase_sector(FIRST_SECTOR + (at - WRITABLE.start) / SECTOR_BYTES)
                })
        })
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        if !offset.is_multiple_of(4) || !bytes.len().is_multiple_of(4) {
            return Err(FlashError::NotAligned);
        }
        writable(offset, bytes.len() as u32)?;
        self.unlocked(|f| {
            bytes.chunks_exact(4).enumerate().try_for_each(|(i, w)| {
                let word = match *w {
                    [b0, b1, b2, b3] => u32::from_le_bytes([b0, b1, b2, b3]),
                    // chunks_exact(4): every chunk is four bytes.
                    _ => return Err(FlashError::NotAligned),
                };
                f.program_word(offset + 4 * i as u32, word)
            })
        })
    }
}
