//! The independent watchdog (IWDG): resets the MCU if the main loop stops refreshing it.
//!
//! # Timeout
//! The IWDG counts the LSI oscillator, which the F405 datasheet gives as 17 to 47 kHz (32 kHz
//! typical): a timeout must be chosen against the *fast* end. Prescaler /64 (`PR = 100`) and
//! reload 3000 (`RLR`, 12 bits):
//!
//! | LSI | 47 kHz | 32 kHz | 17 kHz |
//! |---|---|---|---|
//! | timeout | 4.1 s | 6.0 s | 11.3 s |
//!
//! The longest legitimate pause of the main loop is a calibration store: up to 2 s of sector
//! erase (the CPU stalls, nothing can refresh) plus ~2 ms of programming and ~50 ms of scanning
//! (`storage::STORE_STALL_MAX_MS`). The store path refreshes right before and right after, so
//! the full 4.1 s minimum is available to it: a margin of 2x. Everything else in the main loop
//! is bounded to milliseconds. A longer timeout would only delay recovery from a real hang.
//!
//! Once started, the IWDG cannot be stopped (until reset). With a debugger attached and the
//! core halted, `DBGMCU_APB1_FZ.DBG_IWDG_STOP` freezes it, so breakpoints do not reset the board
//! (set on the board build only: QEMU does not map the DBGMCU).
//!
//! QEMU: the IWDG is an unimplemented device there (writes ignored, reads 0): harmless.

use super::pac;

const KEY_ACCESS: u16 = 0x5555;
const KEY_REFRESH: u16 = 0xAAAA;
const KEY_START: u16 = 0xCCCC;
/// PR = 100: LSI / 64.
const PRESCALER_64: u32 = 0b100;
/// Reload: 4.1 s at the fastest LSI (47 kHz), see the module docs.
const RELOAD: u16 = 3000;
/// DBGMCU_APB1_FZ (0xE004_2008), DBG_IWDG_STOP bit 12.
#[cfg(not(feature = "qemu"))]
const DBGMCU_APB1_FZ: *mut u32 = 0xE004_2008 as *mut u32;

/// The running watchdog.
pub struct Watchdog {
    iwdg: pac::IWDG,
}

impl Watchdog {
    /// Starts the watchdog (the LSI starts with it).
    pub fn start(iwdg: pac::IWDG) -> Self {
        #[cfg(not(feature = "qemu"))]
        // SAFETY: a debug register, written once at start-up.
        unsafe {
            DBGMCU_APB1_FZ.write_volatile(DBGMCU_APB1_FZ.read_volatile() | (1 << 12))
        };
        iwdg.kr().write(|w| unsafe { w.bits(KEY_START) });
        iwdg.kr().write(|w| unsafe { w.bits(KEY_ACCESS) });
        iwdg.pr().write(|w| unsafe { w.bits(PRESCALER_64 as _) });
        iwdg.rlr().write(|w| unsafe { w.bits(RELOAD) });
        // PVU/RVU: the values cross to the LSI domain within ~5 LSI cycles; bounded wait.
        for _ in 0..100_000 {
            if iwdg.sr().read().bits() & 0b11 == 0 {
                break;
            }
        }
        let mut dog = Self { iwdg };
        dog.refresh();
        dog
    }

    /// Reloads the counter: the next reset is one full timeout away.
    #[inline]
    pub fn refresh(&mut self) {
        self.iwdg.kr().write(|w| unsafe { w.bits(KEY_REFRESH) });
    }
}
