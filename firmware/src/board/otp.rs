//! OTP block 0: the board's identity, written once at production.
//!
//! | word | content |
//! |---|---|
//! | 0 | the gyro's serial number (all ones: serial 0) |
//! | 1..=4 | the 128-bit calibration key, big-endian words (all ones: unprovisioned) |
//!
//! The serial number is programmed first (production jig, over SWD); the key last, by the
//! firmware itself on `key provision` ([`program_key`]), which also writes block 0's lock byte:
//! afterwards no bit of the block can change, not even through the flash controller. The key is
//! read once at boot ([`read`]); provisioning takes effect at once (the service keeps the key it
//! wrote).
//!
//! QEMU (feature `qemu`) does not map the OTP area (a read faults) and its flash controller
//! ignores writes, so that build models a blank OTP block in RAM: it boots unprovisioned, and a
//! `key provision` lasts until the emulator exits, like every other QEMU state.

use crate::protocol::key::Key;
use crate::protocol::link::KeyWriteError;

/// Words 0..=4 of block 0 as read now.
#[cfg(not(feature = "qemu"))]
fn words() -> [u32; 5] {
    // SAFETY: the OTP area is always readable on the F405.
    core::array::from_fn(|i| unsafe { (0x1FFF_7800 as *const u32).add(i).read_volatile() })
}

#[cfg(feature = "qemu")]
static MODEL: cortex_m::interrupt::Mutex<core::cell::Cell<[u32; 5]>> =
    cortex_m::interrupt::Mutex::new(core::cell::Cell::new([u32::MAX; 5]));

#[cfg(feature = "qemu")]
fn words() -> [u32; 5] {
    cortex_m::interrupt::free(|cs| MODEL.borrow(cs).get())
}

/// The serial number (0 when unprogrammed) and the key (`None`: unprovisioned), decoded by
/// the host-tested `service::power_up::otp_identity`.
pub fn read() -> (u32, Option<Key>) {
    crate::service::power_up::otp_identity(words())
}

/// Writes `key` to words 1..=4 and locks block 0; refused unless those words are blank. The
/// words are read back: a key that did not program exactly is reported as failed.
pub fn program_key(key: &Key) -> Result<(), KeyWriteError> {
    if words()[1..] != [u32::MAX; 4] {
        return Err(KeyWriteError::NotBlank);
    }
    let new = key.to_otp_words();
    write(&new)?;
    match read().1 {
        Some(k) if k.matches(key) => Ok(()),
        _ => Err(KeyWriteError::Failed),
    }
}

#[cfg(not(feature = "qemu"))]
fn write(key_words: &[u32; 4]) -> Result<(), KeyWriteError> {
    // SAFETY: the flash interface is otherwise used only by the calibration store's
    // `InternalFlash`, from this same context (the main loop), never while this runs.
    let regs = unsafe { super::pac::FLASH::steal() };
    super::flash::InternalFlash::new(regs)
        .program_otp_and_lock(0, 1, key_words)
        .map_err(|_| KeyWriteError::Failed)
}

#[cfg(feature = "qemu")]
fn write(key_words: &[u32; 4]) -> Result<(), KeyWriteError> {
    cortex_m::interrupt::free(|cs| {
        let cell = MODEL.borrow(cs);
        let mut w = cell.get();
        w[1..].copy_from_slice(key_words);
        cell.set(w);
    });
    Ok(())
}
