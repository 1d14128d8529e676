//! Fault injection into the simulated board's timing chain, and what the board's power-up
//! self-test measures on it.
//!
//! Each fault is one the board watches for (`firmware::board_timing`): a trigger that stops
//! (the timer runs, its event no longer reaches the converter, the DMA or the interrupt), a
//! wrong clock (the PLL that never locks at power-up; the crystal that stops later, which the
//! clock security system reports), a dead pick-off. [`SimBoard::inject`](super::SimBoard::inject)
//! sets one; the board, the harness and the simulated device act on it as the hardware would:
//!
//! | fault | what stops | the board sees |
//! |---|---|---|
//! | `StoppedTrigger(Lissajous)` | TIM3's photodiode pairs (no DMA halves) | self-test `triggers=fail:lissajous_dma`; at run time `lissajous` |
//! | `StoppedTrigger(LatchCompare)` | TIM2's compare pulse: no turnaround or output latch | `triggers=fail:adc1_injected`; `turnaround`, `output_latch` |
//! | `StoppedTrigger(DriveTick)` | TIM4: no drive tick, the DAC holds its last code | `triggers=fail:adc3_injected`; `drive_tick` (the drive is taken off) |
//! | `StoppedTrigger(Sync)` | TIM2 CC2: no sync edge, no output latch | `sync`, `output_latch` |
//! | `PllUnlocked` | SYSCLK stays on the 16 MHz HSI | `clock=fail:pll` |
//! | `ClockLost` | the crystal, at run time: the clock security system's NMI | `clock_lost` (the drive is taken off) |
//! | `DeadPickoff` | the pick-off's signal ([`crate::pickoff::Pickoff::set_lost`]) | `pickoff=fail:no_response` |

use firmware::board_timing::selftest::{
    check_clock, check_timer_clock, check_timers, check_triggers, Check, ClockFlags,
    SelfTestReport, TimerAdvance, TriggerFlags,
};
use firmware::profile::BoardProfile;

/// A periodic trigger of the board's timing chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trigger {
    /// TIM3's update: the photodiode pairs for the Lissajous fit (ADC regular group + DMA).
    Lissajous,
    /// TIM2's compare pulse: the turnaround and output latches (ADC injected, TIM5 capture).
    LatchCompare,
    /// TIM4's update: the drive tick (DAC load, ADC3 injected, the tick's interrupt).
    DriveTick,
    /// TIM2 CC2: the sync edges (or the internal output rate).
    Sync,
}

/// A fault of the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardFault {
    /// A trigger stops.
    StoppedTrigger(Trigger),
    /// The PLL never locks: SYSCLK on the HSI (at power-up).
    PllUnlocked,
    /// The crystal stops (at run time): the clock security system switches to the HSI.
    ClockLost,
    /// The pick-off's signal is gone.
    DeadPickoff,
}

/// The faults injected so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BoardFaults {
    stopped: [bool; 4],
    pll_unlocked: bool,
    clock_lost: bool,
}

impl BoardFaults {
    /// Adds `fault` (the pick-off's is the pick-off's own state: [`super::SimBoard::inject`]).
    pub fn inject(&mut self, fault: BoardFault) {
        match fault {
            BoardFault::StoppedTrigger(t) => self.stopped[t as usize] = true,
            BoardFault::PllUnlocked => self.pll_unlocked = true,
            BoardFault::ClockLost => self.clock_lost = true,
            BoardFault::DeadPickoff => {}
        }
    }

    /// Whether `trigger` has stopped.
    pub fn stopped(&self, trigger: Trigger) -> bool {
        self.stopped[trigger as usize]
    }

    /// Whether the clock security system has reported the crystal lost.
    pub fn clock_lost(&self) -> bool {
        self.clock_lost
    }

    /// The power-up self-test's clock, timer and trigger checks as the board's would measure
    /// them on this board (`board::selftest`), judged by the firmware's own verdicts. The
    /// timers advance at half the core clock whatever SYSCLK is (the APB1 prescaler and the
    /// timers' x2 are fixed), so a wrong SYSCLK shows in the clock check, not there.
    pub fn selftest(&self) -> SelfTestReport {
        let mut report = SelfTestReport::NOT_RUN;
        let clock = ClockFlags {
            hse_ready: true,
            pll_locked: !self.pll_unlocked,
            sysclk_from_pll: !self.pll_unlocked,
        };
        report.set(Check::Clock, check_clock(clock));
        let advance = TimerAdvance {
            core_cycles: 2400,
            ticks: [1200; 3],
        };
        report.set(Check::Timers, check_timers(advance));
        report.set(
            Check::TimerClock,
            check_timer_clock(
                advance,
                BoardProfile::F405.timer_hz,
                BoardProfile::F405.core_clock_hz,
            ),
        );
        let latch = !self.stopped(Trigger::LatchCompare);
        let tick = !self.stopped(Trigger::DriveTick);
        report.set(
            Check::Triggers,
            check_triggers(TriggerFlags {
                adc1_injected: latch,
                adc2_injected: latch,
                encoder_latch: latch,
                adc3_regular: latch,
                adc3_injected: tick,
                dac: tick,
                lissajous_dma: !self.stopped(Trigger::Lissajous),
            }),
        );
        report
    }
}
