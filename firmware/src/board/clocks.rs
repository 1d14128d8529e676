//! Clock tree: SYSCLK 168 MHz from the 8 MHz HSE crystal through the main PLL.
//!
//! | node | value | register choice |
//! |---|---|---|
//! | PLL input | 8 MHz / M=4 = 2 MHz | RM0090 recommends 2 MHz at the PLL input to limit jitter |
//! | VCO | 2 MHz x N=168 = 336 MHz | inside 100-432 MHz |
//! | SYSCLK, HCLK | 336 / P=2 = 168 MHz | AHB prescaler 1 |
//! | PLL48CK | 336 / Q=7 = 48 MHz | USB OTG FS ready (unused) |
//! | APB1 | 168 / 4 = 42 MHz (max 42) | timers TIM2-TIM5 at 84 MHz (x2 rule) |
//! | APB2 | 168 / 2 = 84 MHz (max 84) | USART1, ADC interface; ADC clock 84 / 4 = 21 MHz |
//!
//! Flash: 5 wait states (RM0090 table 10: 150-168 MHz at 2.7-3.6 V), instruction and data
//! caches on, **prefetch off**: errata ES0182, "Internal noise impacting the ADC accuracy",
//! whose workaround is exactly this ART setting (prefetch off, both caches on); the photodiodes
//! and the pick-off are the measurement. Loops and the handlers' hot paths run from the 64-line
//! I-cache either way; straight-line code after a miss pays the wait states the prefetch would
//! have hidden. The wait states are set *before* the switch to the PLL, as the manual requires.
//!
//! The voltage regulator stays in its reset state, scale 1, which 168 MHz needs.
//!
//! A crystal that does not start must not hang the board before the watchdog runs: the HSE is
//! waited for a bounded time, and if it never reports ready the PLL runs from the 16 MHz HSI
//! (M=8 gives the same 2 MHz), with the poorer HSI accuracy (1 %). A PLL that does not lock
//! leaves SYSCLK on the HSI at 16 MHz: every timing constant of the board is then wrong by
//! 10.5x. Neither is hidden: [`flags`] reads the clock tree's real state back from the RCC, the
//! power-up self-test fails its `clock` check on either (`board_timing::selftest`), and the
//! drive stays off; the serial link still answers (at the wrong baud rate if SYSCLK is 16 MHz:
//! the bring-up's first check, docs/bringup.md).
//!
//! The clock security system (`CSSON`) watches the crystal from then on: if it stops, the
//! hardware switches SYSCLK to the HSI (the PLL too goes off) and raises the NMI, whose handler
//! ([`on_nmi`]) clears the flag and records the loss ([`CLOCK_LOST`]); the main loop then takes
//! the drive off and marks every output record invalid (RM0090 6.2.7).
//!
//! QEMU (feature `qemu`) does not model the RCC: ready bits read 0 forever, so the waits are
//! skipped there (the writes are harmless and ignored).

use core::sync::atomic::{AtomicBool, Ordering};

use super::pac;
use crate::board_timing::selftest::ClockFlags;

/// Set by the NMI when the clock security system saw the crystal stop (SYSCLK is then the
/// 16 MHz HSI); never cleared before a reset.
pub static CLOCK_LOST: AtomicBool = AtomicBool::new(false);

/// Where SYSCLK comes from after [`init`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum ClockSource {
    /// PLL from the 8 MHz crystal.
    Hse,
    /// The crystal did not start: PLL from the internal 16 MHz RC oscillator.
    HsiFallback,
}

// RCC_CR
const HSEON: u32 = 1 << 16;
const HSERDY: u32 = 1 << 17;
const CSSON: u32 = 1 << 19;
// RCC_CIR: CSSF 7 (clock security system interrupt flag), CSSC 23 (its clear bit)
const CIR_CSSF: u32 = 1 << 7;
const CIR_CSSC: u32 = 1 << 23;
const PLLON: u32 = 1 << 24;
const PLLRDY: u32 = 1 << 25;
// RCC_PLLCFGR: PLLM[5:0], PLLN[14:6], PLLP[17:16] (00 = /2), PLLSRC[22], PLLQ[27:24]
const PLLSRC_HSE: u32 = 1 << 22;
const fn pllcfgr(m: u32, n: u32, q: u32, hse: bool) -> u32 {
    m | (n << 6) | (if hse { PLLSRC_HSE } else { 0 }) | (q << 24)
}
// RCC_CFGR: SW[1:0] = 10 (PLL), SWS[3:2], HPRE[7:4] = 0 (/1), PPRE1[12:10] = 101 (/4),
// PPRE2[15:13] = 100 (/2)
const CFGR_PRESCALERS: u32 = (0b101 << 10) | (0b100 << 13);
const SW_PLL: u32 = 0b10;
const SWS_MASK: u32 = 0b11 << 2;
const SWS_PLL: u32 = 0b10 << 2;
// FLASH_ACR: LATENCY[2:0] = 5, ICEN 9, DCEN 10; PRFTEN 8 off (ES0182, module docs)
const ACR_168MHZ: u32 = 5 | (1 << 9) | (1 << 10);

/// Polls of a ready bit before giving up: about 60 ms at the 16 MHz reset clock (HSE start-up
/// is 2 ms typical).
const READY_POLLS: u32 = 200_000;

/// Waits until `ready()`; false after [`READY_POLLS`]. Under `qemu`: true at once.
fn wait(ready: impl Fn() -> bool) -> bool {
    if cfg!(feature = "qemu") {
        return true;
    }
    (0..READY_POLLS).any(|_| ready())
}

/// Brings SYSCLK to 168 MHz (see the module docs). Call once, first thing after reset.
pub fn init(rcc: &pac::RCC, flash: &pac::FLASH) -> ClockSource {
    rcc.cr().modify(|r, w| unsafe { w.bits(r.bits() | HSEON) });
    let hse = wait(|| rcc.cr().read().bits() & HSERDY != 0);
    let source = if hse {
        // From now on a stopped crystal switches SYSCLK to the HSI and raises the NMI.
        rcc.cr().modify(|r, w| unsafe { w.bits(r.bits() | CSSON) });
        ClockSource::Hse
    } else {
        rcc.cr().modify(|r, w| unsafe { w.bits(r.bits() & !HSEON) });
        ClockSource::HsiFallback
    };
    let m = if hse { 4 } else { 8 };
    rcc.pllcfgr()
        .write(|w| unsafe { w.bits(pllcfgr(m, 168, 7, hse)) });
    rcc.cr().modify(|r, w| unsafe { w.bits(r.bits() | PLLON) });
    // A PLL that does not lock leaves SYSCLK on HSI (16 MHz): slow but alive.
    let locked = wait(|| rcc.cr().read().bits() & PLLRDY != 0);
    flash.acr().write(|w| unsafe { w.bits(ACR_168MHZ) });
    rcc.cfgr().write(|w| unsafe { w.bits(CFGR_PRESCALERS) });
    if locked {
        rcc.cfgr()
            .write(|w| unsafe { w.bits(CFGR_PRESCALERS | SW_PLL) });
        wait(|| rcc.cfgr().read().bits() & SWS_MASK == SWS_PLL);
    }
    source
}

/// The clock tree's state as the RCC reports it now (never what was intended): the
/// self-test's `clock` check. QEMU models no RCC: all false there.
pub fn flags(rcc: &pac::RCC) -> ClockFlags {
    let cr = rcc.cr().read().bits();
    ClockFlags {
        hse_ready: cr & HSERDY != 0,
        pll_locked: cr & PLLRDY != 0,
        sysclk_from_pll: rcc.cfgr().read().bits() & SWS_MASK == SWS_PLL,
    }
}

/// SYSCLK now, Hz: 168 MHz from the PLL, else the 16 MHz HSI (the reset clock), for the log.
pub fn sysclk_hz(flags: ClockFlags) -> u32 {
    if flags.sysclk_from_pll {
        super::SYSCLK_HZ
    } else {
        16_000_000
    }
}

/// The NMI's work: the clock security system's flag (the crystal stopped; SYSCLK is on the
/// HSI now) cleared and recorded in [`CLOCK_LOST`]. Returns whether it was set.
pub fn on_nmi() -> bool {
    // SAFETY: CIR's CSSC is a write-1-to-clear bit the NMI alone uses; the other clear bits
    // written 0 change nothing, the enable bits are kept.
    let rcc = unsafe { &*pac::RCC::ptr() };
    let cir = rcc.cir().read().bits();
    if cir & CIR_CSSF == 0 {
        return false;
    }
    rcc.cir()
        .write(|w| unsafe { w.bits((cir & 0xFF00) | CIR_CSSC) });
    CLOCK_LOST.store(true, Ordering::Relaxed);
    true
}

// Peripheral clock enables (RCC_AHB1ENR, APB1ENR, APB2ENR bit numbers).
/// GPIOA clock enable (AHB1ENR).
pub const AHB1_GPIOA: u32 = 1 << 0;
/// GPIOB clock enable (AHB1ENR).
pub const AHB1_GPIOB: u32 = 1 << 1;
/// GPIOC clock enable (AHB1ENR).
pub const AHB1_GPIOC: u32 = 1 << 2;
/// Backup SRAM interface clock enable (AHB1ENR).
pub const AHB1_BKPSRAM: u32 = 1 << 18;
/// DMA2 clock enable (AHB1ENR).
pub const AHB1_DMA2: u32 = 1 << 22;
/// TIM2 clock enable (APB1ENR).
pub const APB1_TIM2: u32 = 1 << 0;
/// TIM3 clock enable (APB1ENR).
pub const APB1_TIM3: u32 = 1 << 1;
/// TIM4 clock enable (APB1ENR).
pub const APB1_TIM4: u32 = 1 << 2;
/// TIM5 clock enable (APB1ENR).
pub const APB1_TIM5: u32 = 1 << 3;
/// Power interface clock enable (APB1ENR): needed to open the backup domain.
pub const APB1_PWR: u32 = 1 << 28;
/// DAC clock enable (APB1ENR).
pub const APB1_DAC: u32 = 1 << 29;
/// USART1 clock enable (APB2ENR).
pub const APB2_USART1: u32 = 1 << 4;
/// ADC1 clock enable (APB2ENR).
pub const APB2_ADC1: u32 = 1 << 8;
/// ADC2 clock enable (APB2ENR).
pub const APB2_ADC2: u32 = 1 << 9;
/// ADC3 clock enable (APB2ENR).
pub const APB2_ADC3: u32 = 1 << 10;

/// Turns on peripheral clocks (read back once: RM0090 erratum-style delay of two AHB cycles
/// before the peripheral may be accessed).
pub fn enable(rcc: &pac::RCC, ahb1: u32, apb1: u32, apb2: u32) {
    rcc.ahb1enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | ahb1) });
    rcc.apb1enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | apb1) });
    rcc.apb2enr()
        .modify(|r, w| unsafe { w.bits(r.bits() | apb2) });
    let _ = rcc.apb2enr().read().bits();
}
