//! The output latch on the board: the end of each output period, from the sync input or the
//! board's own output rate, latched by the turnaround latch's hardware.
//!
//! ```text
//! sync input --PB3 (TIM2_CH2, AF1)--> IC2 (rising, 95 ns filter): CCR2 = t_edge   (external)
//! or TIM2 CC2 as an output compare, CCR2 += period, no pin                        (internal)
//!     TIM2 IRQ (the pick-off handler's, priority 0x20): LatchPlan::on_sync -> CCR1
//! CNT == CCR1 -> the turnaround latch's compare pulse (TRGO):
//!     ADC1 + ADC2 injected (photodiodes), TIM5 IC3 (count), and ADC3 regular (pick-off,
//!     EXTSEL = TIM2_TRGO: `dither::init`)
//! ADC JEOC IRQ (priority 0x00): LatchPlan::on_fired says "output" -> OutputSample
//! ```
//!
//! The compare is shared with the turnarounds: [`crate::signal::output::latch_plan`] decides
//! which is armed (a turnaround is never moved; an output latch waits until just after a
//! turnaround it would crowd). The record's time is the latch's (2 us after the sync edge, at
//! most about 13 us), so the angle and the time it was taken belong together.
//!
//! # The pick-off's conversion
//!
//! ADC3 also converts the pick-off for the dither drive (injected, on TIM4's 40 kHz update).
//! An injected conversion delays a regular one that it meets (1.3 us of sampling and
//! conversion, 5 % of a 25 us tick): the plan is told the drive tick's phase in TIM2 ticks
//! ([`DRIVE_TICK_PHASE_TICKS`], fixed at start-up: both timers count the same 84 MHz clock from
//! a common start) and keeps output latches out of that window.

use super::pac;

/// Where the output periods come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SyncSource {
    /// The navigation computer's sync pulse on PB3 (rising edge).
    External,
    /// The board's own output rate: a latch every `period_ticks` of the 84 MHz timer.
    Internal {
        /// Timer ticks per output period (84 000 = 1 kHz).
        period_ticks: u32,
    },
}

/// This board's output: its own 1 kHz until a sync is wired (change to `External` then).
pub const SYNC_SOURCE: SyncSource = SyncSource::Internal {
    period_ticks: 84_000,
};

/// TIM2 ticks from a drive tick's TIM4 update to TIM2's count of the same instant, modulo the
/// drive period: 0, since `app::run` starts TIM4 and TIM2 back to back from zero (the few
/// instructions between the two enables, < 40 ticks, lie inside the keep-out margin).
pub const DRIVE_TICK_PHASE_TICKS: u32 = 0;

// CCMR1 (TIM2): CC2S[9:8] = 01 (IC2 on TI2), IC2F[15:12] = 0011 (95 ns), for the external
// sync; CC2S = 00 with OC2M = 000 (frozen: CC2IF only) for the internal rate. The low byte
// (channel 1, the compare pulse) is the turnaround module's.
const CCMR1_IC2: u32 = (0b01 << 8) | (0b0011 << 12);
// CCER: CC2E 4 (capture enabled; rising: CC2P 5 = 0)
const CCER_CC2E: u32 = 1 << 4;
// DIER / SR: CC2IE / CC2IF 2
pub(super) const SR_CC2IF: u32 = 1 << 2;

/// Adds the output latch's channel to TIM2 (after `turnaround::init`; clock for GPIOB on).
pub fn init(tim: &pac::TIM2) {
    match SYNC_SOURCE {
        SyncSource::External => {
            super::Port::B.alternate(3, 1); // TIM2_CH2: the sync input
            tim.ccmr1_input()
                .modify(|r, w| unsafe { w.bits(r.bits() | CCMR1_IC2) });
            tim.ccer()
                .modify(|r, w| unsafe { w.bits(r.bits() | CCER_CC2E) });
        }
        SyncSource::Internal { period_ticks } => {
            let now = tim.cnt().read().bits();
            tim.ccr2()
                .write(|w| unsafe { w.bits(now.wrapping_add(period_ticks)) });
        }
    }
    tim.dier()
        .modify(|r, w| unsafe { w.bits(r.bits() | SR_CC2IF) });
}

/// The sync edge's time, if CC2 fired (TIM2 handler): the capture (reading CCR2 clears the
/// flag), or the internal compare's instant (the flag cleared and the next period set).
pub fn take_edge(tim: &pac::tim2::RegisterBlock, sr: u32) -> Option<u32> {
    if sr & SR_CC2IF == 0 {
        return None;
    }
    let edge = tim.ccr2().read().bits();
    if let SyncSource::Internal { period_ticks } = SYNC_SOURCE {
        tim.sr().write(|w| unsafe { w.bits(!SR_CC2IF) });
        tim.ccr2()
            .write(|w| unsafe { w.bits(edge.wrapping_add(period_ticks)) });
    }
    Some(edge)
}
