//! The wrong-key count across resets, in the backup SRAM (4 KiB at 0x4002_4000).
//!
//! The protocol's wrong-key back-off (`crate::protocol::access`) would be worthless if a reset
//! cleared it, so the service saves the count whenever it changes
//! (`crate::service::ports::Secrets::save_wrong_keys`) and restores it at boot
//! ([`super::app::boot`]). Backup SRAM rather than flash: it has no wear and no erase stall,
//! keeps its contents across every reset (watchdog, software, pin) and, with the backup
//! regulator on and a VBAT supply, across power loss. Without VBAT a power cycle clears it, as it
//! clears the count: an attacker who can power-cycle the board gains at most the 3 free
//! attempts per cycle, a few seconds each (the board takes about 1.1 s to start).
//!
//! Record: three words, `MAGIC`, the count, and its complement; anything else (a cold start,
//! garbage) reads as 0.
//!
//! Registers (RM0090 5.1.2, 5.4): `RCC_APB1ENR.PWREN` and `RCC_AHB1ENR.BKPSRAMEN`
//! (`super::clocks`), `PWR_CR.DBP` (backup-domain write access), `PWR_CSR.BRE` (backup
//! regulator, for VBAT retention). QEMU (feature `qemu`) models neither PWR nor the backup SRAM:
//! that build keeps the record in a RAM section that start-up does not initialise (`.uninit`),
//! which likewise survives a reset.

use super::pac;

const MAGIC: u32 = 0x5752_4B31; // "WRK1"
/// Where the record lives.
#[cfg(not(feature = "qemu"))]
fn record() -> *mut [u32; 3] {
    0x4002_4000 as *mut [u32; 3]
}

#[cfg(feature = "qemu")]
#[link_section = ".uninit.WRONG_KEYS"]
static mut RECORD: core::mem::MaybeUninit<[u32; 3]> = core::mem::MaybeUninit::uninit();

#[cfg(feature = "qemu")]
fn record() -> *mut [u32; 3] {
    // Only the address is taken; accesses are volatile, from the main loop only.
    core::ptr::addr_of_mut!(RECORD).cast()
}

/// Polls of `PWR_CSR.BRR` after `BRE`: the backup regulator needs a few microseconds (the
/// datasheet's t_BRR is not characterised; this is about 10 ms at 168 MHz).
const BRR_POLLS: u32 = 200_000;

/// Opens the backup domain for writes and keeps the backup SRAM on VBAT (the clocks
/// `AHB1_BKPSRAM` and `APB1_PWR` must be on). Waits (bounded) until the backup regulator
/// reports ready (`BRR`, RM0090 5.4.2: the SRAM keeps its contents on VBAT only from then on);
/// returns whether it did (false: the wrong-key count survives resets, not a power loss;
/// logged). QEMU models no PWR: true at once.
pub fn init(pwr: &pac::PWR) -> bool {
    const CR_DBP: u32 = 1 << 8;
    const CSR_BRE: u32 = 1 << 9;
    const CSR_BRR: u32 = 1 << 3;
    pwr.cr().modify(|r, w| unsafe { w.bits(r.bits() | CR_DBP) });
    pwr.csr()
        .modify(|r, w| unsafe { w.bits(r.bits() | CSR_BRE) });
    cfg!(feature = "qemu") || (0..BRR_POLLS).any(|_| pwr.csr().read().bits() & CSR_BRR != 0)
}

/// The count kept before the reset (0 after a cold start).
pub fn load_wrong_keys() -> u32 {
    // SAFETY: the record's three words are always readable (backup SRAM or `.uninit` RAM).
    let [magic, count, check] = unsafe { record().read_volatile() };
    if magic == MAGIC && check == !count {
        count
    } else {
        0
    }
}

/// Keeps `count` (from the main loop only).
pub fn save_wrong_keys(count: u32) {
    // SAFETY: as in `load_wrong_keys`; writes are enabled by `init` (board) or plain RAM (QEMU).
    unsafe { record().write_volatile([MAGIC, count, !count]) };
}
