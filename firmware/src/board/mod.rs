//! Board support for the STM32F405RG readout board: the one place where registers are touched.
//!
//! Everything outside this module is plain logic that also builds and is tested on the host;
//! this module is compiled only for `target_os = "none"`. It is written against the `stm32f4`
//! PAC with raw register values whose bit positions are named next to each write (RM0090
//! numbering), because every field choice here is a design decision worth reading in one place.
//! The HAL's clock set-up is avoided on purpose: it polls RCC ready bits, which QEMU never sets.
//!
//! One file per peripheral, in signal-chain order:
//!
//! | file | peripheral | job |
//! |---|---|---|
//! | [`clocks`] | RCC, FLASH.ACR | 168 MHz SYSCLK from the 8 MHz HSE, APB1 42 / APB2 84 MHz |
//! | [`encoder`] | TIM5 | x4 up/down count of the squared photodiode signals; latch on TIM2's TRGO |
//! | [`turnaround`] | TIM2 | pick-off zero-crossing capture, output compare at the predicted turnaround |
//! | [`adc`] | ADC1+ADC2, DMA2 stream 0, TIM3 | injected pair at the turnaround; regular pairs for the Lissajous fit |
//! | [`dither`] | TIM4, DAC1, ADC3 | the dither drive's 40 kHz tick: pick-off sample and DAC update on one timer edge, `crate::dither` in the handler |
//! | [`usart`] | USART1 | the calibration protocol's serial link (RXNE/TXE interrupts, bounded queues) |
//! | [`flash`] | FLASH | sectors 10-11 as an `embedded_storage` `NorFlash`; OTP programming |
//! | [`i2c`] | I2C1 (PB6, PB7) | the gyro block's TMP117 at 400 kHz, behind `embedded_hal::i2c::I2c`; polled in the main loop; bus clear through GPIO at start-up and after a bus error |
//! | [`otp`] | OTP block 0 | serial number and the 128-bit key (`key provision`) |
//! | [`backup`] | PWR, backup SRAM | the wrong-key count across resets |
//! | [`watchdog`] | IWDG | reset if the main loop stops |
//!
//! and the board's watch over itself: [`selftest`] (the power-up checks' measurements) and
//! [`watch`] (the rate monitors' counts and reactions), whose judgements are the host-tested
//! `crate::board_timing`.
//!
//! and the contexts around them, in files that import one way (`app` -> `ports` ->
//! `resources` <- `isr` <- `ram`):
//!
//! | file | job |
//! |---|---|
//! | [`resources`] | NVIC priorities, the queues and the priority lock the contexts share, SysTick; the readout's start, pause and resume |
//! | [`isr`] | the thin interrupt handlers (registers -> plain structs -> queues or plain logic) and the macro binding them to the vectors |
//! | [`ram`] | what runs from RAM while a flash store stalls every fetch from flash: the vector table, the drive tick, the serial link, the millisecond tick, the flash operation's wait |
//! | [`ports`] | the board's implementation of the command service's ports (clock, serial, readout access, the pause) |
//! | [`app`] | start-up ([`app::run`]) and the main loop ([`app::serve`]) running `crate::service::Service` |
//!
//! **Timer roles.** The issue asks for the encoder on "TIM2 or TIM5" and the brief suggested TIM2
//! as encoder and TIM5 for the turnaround timing, with the encoder latched "through ITR". That
//! combination does not exist on the F405: TIM2's internal trigger inputs are TIM1, TIM8, TIM3 and
//! TIM4 (RM0090 table 100), so TIM5 can never trigger TIM2. TIM5's ITR0, however, *is* TIM2's
//! TRGO, and TIM2's TRGO is also an injected-ADC trigger (JEXTSEL = 3). So the roles are swapped:
//! TIM2 (32-bit) times the turnarounds, TIM5 (32-bit) counts fringes. One TRGO pulse of TIM2 then
//! starts the ADC pair and captures the fringe count, entirely in hardware (see [`turnaround`]).

pub mod adc;
pub mod app;
pub mod backup;
pub mod clocks;
pub mod dither;
pub mod encoder;
pub mod flash;
pub mod i2c;
pub mod isr;
pub mod otp;
pub mod ports;
pub mod ram;
pub mod resources;
pub mod selftest;
pub mod sync;
pub mod turnaround;
pub mod usart;
pub mod watch;
pub mod watchdog;

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicBool, Ordering};

pub use crate::rt::pac;

/// Timer kernel clock of APB1 timers (TIM2-TIM5): APB1 = 42 MHz with prescaler 4, so the timers
/// run at twice that (RM0090 6.2, "timer clock = 2 x PCLK1 when the APB1 prescaler is not 1").
/// The board profile states it for everyone else (`crate::profile::BoardProfile::F405`).
pub const TIMER_HZ: u32 = crate::profile::BoardProfile::F405.timer_hz;
/// APB2 clock (USART1, ADC interface).
pub const PCLK2_HZ: u32 = 84_000_000;
/// Core clock (the PLL's 168 MHz, `clocks.rs`), as the board profile states it.
pub const SYSCLK_HZ: u32 = crate::profile::BoardProfile::F405.core_clock_hz;

/// One value owned by exactly one execution context (an interrupt handler or the main loop)
/// after it has been set once during start-up, before that context's interrupt is enabled.
///
/// The cheapest sound way to hand a queue end or a peripheral to a handler without a critical
/// section on every access: the ownership rule replaces the lock. Every `get` site names its
/// owner in a `SAFETY` comment.
pub struct Owned<T> {
    value: UnsafeCell<MaybeUninit<T>>,
    set: AtomicBool,
}

// SAFETY: access is restricted by the ownership rule above (one context uses the value).
unsafe impl<T: Send> Sync for Owned<T> {}

impl<T> Owned<T> {
    /// An empty slot, set once by [`init`](Self::init).
    pub const fn new() -> Self {
        Self {
            value: UnsafeCell::new(MaybeUninit::uninit()),
            set: AtomicBool::new(false),
        }
    }

    /// Stores the value; call once, before the owner can run. A second call panics.
    pub fn init(&self, value: T) {
        assert!(!self.set.swap(true, Ordering::AcqRel), "Owned::init twice");
        // SAFETY: the flag was clear, so nobody holds a reference yet.
        unsafe { (*self.value.get()).write(value) };
    }

    /// The value, or `None` before `init`.
    ///
    /// # Safety
    /// Only the one owning context may call this, and never re-entrantly.
    #[allow(clippy::mut_from_ref)]
    #[inline(always)]
    pub unsafe fn get(&self) -> Option<&mut T> {
        if self.set.load(Ordering::Acquire) {
            Some(unsafe { (*self.value.get()).assume_init_mut() })
        } else {
            None
        }
    }
}

impl<T> Default for Owned<T> {
    fn default() -> Self {
        Self::new()
    }
}

/// A value that several contexts share, reached through its lock for the span of a closure.
///
/// The handler bodies and drivers that touch a shared value take it as `impl Shared` instead of
/// naming a static, so the binding decides how it is locked: the board binds the statics of
/// [`resources`] (a [`resources::PriorityLock`], or [`turnaround::PlanLock`]'s critical
/// section), `examples/rtic_board.rs` binds RTIC's resource proxies (the same stack resource
/// policy, with the ceilings computed by RTIC). docs/firmware.md#concurrency compares the two.
pub trait Shared {
    /// The value.
    type Value;
    /// Runs `f` with the value, no other user of it running meanwhile; `None` while the value
    /// is not set (start-up sets each before the interrupts of its users are unmasked).
    fn lock<R>(&mut self, f: impl FnOnce(&mut Self::Value) -> R) -> Option<R>;
}

/// A GPIO port by base address. The ports' register blocks are different PAC types with one
/// layout, so pin set-up goes through the addresses (RM0090 8.4: MODER 0x00, OTYPER 0x04,
/// OSPEEDR 0x08, PUPDR 0x0C, IDR 0x10, BSRR 0x18, AFRL 0x20, AFRH 0x24). Used during start-up,
/// and by I2C1's bus clear in the main loop (`i2c`: PB6/PB7 only); no handler touches a port.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Port(usize);

impl Port {
    pub const A: Self = Self(0x4002_0000);
    pub const B: Self = Self(0x4002_0400);
    pub const C: Self = Self(0x4002_0800);

    fn read(self, offset: usize) -> u32 {
        // SAFETY: a GPIO register of this port; reading has no side effect.
        unsafe { ((self.0 + offset) as *const u32).read_volatile() }
    }

    fn write(self, offset: usize, value: u32) {
        // SAFETY: a GPIO register of this port (BSRR: a write sets or resets only its pins).
        unsafe { ((self.0 + offset) as *mut u32).write_volatile(value) };
    }

    fn modify(self, offset: usize, clear: u32, set: u32) {
        let reg = (self.0 + offset) as *mut u32;
        // SAFETY: a GPIO register of this port; start-up code, no other context touches it.
        unsafe { reg.write_volatile((reg.read_volatile() & !clear) | set) };
    }

    /// Alternate function `af` (push-pull, very high speed, no pull).
    pub fn alternate(self, pin: u32, af: u32) {
        self.modify(0x00, 0b11 << (2 * pin), 0b10 << (2 * pin));
        self.modify(0x08, 0, 0b11 << (2 * pin));
        let (offset, shift) = if pin < 8 {
            (0x20, 4 * pin)
        } else {
            (0x24, 4 * (pin - 8))
        };
        self.modify(offset, 0xF << shift, af << shift);
    }

    /// Alternate function with the pull-up on (inputs that may float, e.g. USART RX).
    pub fn alternate_pull_up(self, pin: u32, af: u32) {
        self.alternate(pin, af);
        self.modify(0x0C, 0b11 << (2 * pin), 0b01 << (2 * pin));
    }

    /// Analog mode (ADC inputs: digital buffer off).
    pub fn analog(self, pin: u32) {
        self.modify(0x00, 0, 0b11 << (2 * pin));
    }
}
