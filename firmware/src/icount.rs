//! Instruction counting on the emulated Cortex-M4 (MCU only): under QEMU's `-icount shift=0`
//! a 32-bit timer at prescaler 0 advances exactly one per executed instruction (TOOLCHAIN.md
//! section 7; run with `cargo fw-icount --example NAME`). On a board, or in QEMU without
//! `-icount`, it counts timer clocks instead and the figures mean nothing.
//!
//! Used by the measurement examples (`cost`, `icount`, `fit_hours`, `board_cost`). TIM2 serves
//! unless the program needs it (the board's turnaround timing does: `board_cost` uses TIM5).

use crate::rt::pac;

/// Which 32-bit general-purpose timer counts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Timer {
    /// TIM2, the default.
    Tim2,
    /// TIM5, for programs that use TIM2 themselves (`board_cost`).
    Tim5,
}

/// A running instruction counter, with the measured cost of an empty section.
#[derive(Clone, Copy, Debug)]
pub struct InstructionCounter {
    timer: Timer,
    overhead: u32,
}

impl InstructionCounter {
    /// Enables the timer's clock, starts it free-running at prescaler 0 and measures the cost
    /// of an empty [`count`](Self::count).
    pub fn start(timer: Timer) -> Self {
        // SAFETY: the measurement programs own these timers; the RCC write only sets an
        // enable bit (QEMU ignores RCC, a board needs it).
        let rcc = unsafe { &*pac::RCC::ptr() };
        match timer {
            Timer::Tim2 => rcc.apb1enr().modify(|_, w| w.tim2en().set_bit()),
            Timer::Tim5 => rcc.apb1enr().modify(|_, w| w.tim5en().set_bit()),
        };
        macro_rules! run {
            ($t:expr) => {{
                $t.psc().write(|w| unsafe { w.bits(0) });
                $t.arr().write(|w| unsafe { w.bits(u32::MAX) });
                $t.cr1().write(|w| w.cen().set_bit());
            }};
        }
        match timer {
            Timer::Tim2 => run!(unsafe { &*pac::TIM2::ptr() }),
            Timer::Tim5 => run!(unsafe { &*pac::TIM5::ptr() }),
        }
        let mut counter = Self { timer, overhead: 0 };
        counter.overhead = counter.count(|| {});
        counter
    }

    /// The counter now (instructions, wrapping).
    #[inline(always)]
    pub fn now(&self) -> u32 {
        // SAFETY: a read of the free-running counter register.
        match self.timer {
            Timer::Tim2 => unsafe { (*pac::TIM2::ptr()).cnt().read().bits() },
            Timer::Tim5 => unsafe { (*pac::TIM5::ptr()).cnt().read().bits() },
        }
    }

    /// Instructions executed by `f`, less the cost of an empty section.
    #[inline(always)]
    pub fn count(&self, f: impl FnOnce()) -> u32 {
        let a = self.now();
        f();
        self.now().wrapping_sub(a).saturating_sub(self.overhead)
    }
}
