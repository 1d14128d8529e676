//! OTP: the board's identity, written once at production: the serial number (block 0 word 0,
//! by the production jig over SWD) and the 128-bit calibration key (by the firmware itself on
//! `key provision`). The layout, the check word that makes a half-written key read as no key,
//! the spare blocks and the provisioning order are plain logic in [`crate::otp_record`]; this
//! file gives it the cells ([`crate::otp_record::OtpCells`]): reads of the OTP area, and the
//! flash controller's word programming and block locking ([`super::flash`]).
//!
//! The key is read once at boot ([`read`]); provisioning takes effect at once (the service
//! keeps the key it wrote).
//!
//! QEMU (feature `qemu`) does not map the OTP area (a read faults) and its flash controller
//! ignores writes, so that build models the OTP blocks in RAM, as a board leaves the jig: serial
//! number [`QEMU_SERIAL`] programmed, no key. A `key provision` there lasts until the emulator
//! exits, like every other QEMU state.

#[cfg(feature = "qemu")]
use crate::otp_record::KEY_BLOCKS;
use crate::otp_record::{self, OtpCells, OtpWriteError, ProvisionError};
use crate::protocol::key::Key;
use crate::protocol::link::KeyWriteError;

/// The OTP cells of this build.
struct Cells;

#[cfg(not(feature = "qemu"))]
impl OtpCells for Cells {
    fn read(&self, block: u32, word: u32) -> u32 {
        let address = super::flash::OTP_BASE + 32 * block + 4 * word;
        // SAFETY: the OTP area is always readable on the F405 (callers stay inside it).
        unsafe { (address as *const u32).read_volatile() }
    }

    fn locked(&self, block: u32) -> bool {
        // SAFETY: the lock bytes are always readable.
        unsafe { ((super::flash::OTP_LOCK_BASE + block) as *const u8).read_volatile() == 0 }
    }

    fn program(&mut self, block: u32, word: u32, value: u32) -> Result<(), OtpWriteError> {
        flash()
            .program_otp_word(block, word, value)
            .map_err(|_| OtpWriteError)
    }

    fn lock(&mut self, block: u32) -> Result<(), OtpWriteError> {
        flash().lock_otp_block(block).map_err(|_| OtpWriteError)
    }
}

/// The flash controller for an OTP write.
#[cfg(not(feature = "qemu"))]
fn flash() -> super::flash::InternalFlash {
    // SAFETY: the flash interface is otherwise used only by the calibration store's
    // `InternalFlash`, from this same context (the main loop), never while this runs.
    super::flash::InternalFlash::new(unsafe { super::pac::FLASH::steal() })
}

/// The serial number the QEMU build's OTP model holds (the production jig's word).
#[cfg(feature = "qemu")]
pub const QEMU_SERIAL: u32 = 1;

#[cfg(feature = "qemu")]
type Model = ([[u32; 8]; KEY_BLOCKS as usize], [bool; KEY_BLOCKS as usize]);

#[cfg(feature = "qemu")]
static MODEL: cortex_m::interrupt::Mutex<core::cell::Cell<Option<Model>>> =
    cortex_m::interrupt::Mutex::new(core::cell::Cell::new(None));

#[cfg(feature = "qemu")]
fn model() -> Model {
    cortex_m::interrupt::free(|cs| {
        MODEL.borrow(cs).get().unwrap_or_else(|| {
            let mut words = [[otp_record::BLANK; 8]; KEY_BLOCKS as usize];
            words[0][0] = QEMU_SERIAL;
            (words, [false; KEY_BLOCKS as usize])
        })
    })
}

#[cfg(feature = "qemu")]
fn with_model<R>(f: impl FnOnce(&mut Model) -> R) -> R {
    let mut m = model();
    let r = f(&mut m);
    cortex_m::interrupt::free(|cs| MODEL.borrow(cs).set(Some(m)));
    r
}

#[cfg(feature = "qemu")]
impl OtpCells for Cells {
    fn read(&self, block: u32, word: u32) -> u32 {
        let (words, _) = model();
        words
            .get(block as usize)
            .and_then(|b| b.get(word as usize))
            .copied()
            .unwrap_or(otp_record::BLANK)
    }

    fn locked(&self, block: u32) -> bool {
        model().1.get(block as usize).copied().unwrap_or(true)
    }

    fn program(&mut self, block: u32, word: u32, value: u32) -> Result<(), OtpWriteError> {
        with_model(|(words, locks)| {
            if locks.get(block as usize) != Some(&false) {
                return Err(OtpWriteError);
            }
            let cell = words
                .get_mut(block as usize)
                .and_then(|b| b.get_mut(word as usize))
                .ok_or(OtpWriteError)?;
            *cell &= value;
            Ok(())
        })
    }

    fn lock(&mut self, block: u32) -> Result<(), OtpWriteError> {
        with_model(|(_, locks)| {
            let lock = locks.get_mut(block as usize).ok_or(OtpWriteError)?;
            *lock = true;
            Ok(())
        })
    }
}

/// The serial number (0 when not programmed) and the key (`None`: unprovisioned, or only
/// spent blocks).
pub fn read() -> (u32, Option<Key>) {
    crate::service::power_up::otp_identity(&Cells)
}

/// Provisions `key` ([`crate::otp_record::provision`]): `NotBlank` when it is not possible
/// (no serial number, a key already there, no block left), `Failed` when a word did not
/// program or read back (that block is spent; the next attempt uses the next one).
pub fn program_key(key: &Key) -> Result<(), KeyWriteError> {
    otp_record::provision(&mut Cells, key).map_err(|e| match e {
        ProvisionError::NotPossible => KeyWriteError::NotBlank,
        ProvisionError::Failed => KeyWriteError::Failed,
    })
}
