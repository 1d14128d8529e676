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
//! conversion, 5 % of a 25 us tick): the plan keeps output latches out of that window, placed
//! from TIM4's count read beside TIM2's at every use (`super::turnaround`,
//! [`crate::board_timing::phase`]).
//!
//! # The internal rate after a pause
//!
//! A flash store masks TIM2's interrupt for up to 2.1 s; the compare fires meanwhile and its
//! handler runs only afterwards. The next compare is the first instant of the output grid
//! still ahead of the counter ([`crate::board_timing::compare::next_period_compare`]), never
//! "the fired compare plus one period", which would lie in the past and match only after the
//! counter's wrap, 51 s later. The grid instants passed over are counted in
//! [`PERIODS_MISSED`]; the record after the gap spans them (its `period_ticks`).
//!
//! # PB3
//!
//! With the external sync PB3 is its input (IC2, rising edge, 95 ns filter). With the internal
//! rate PB3 is CC2's output and toggles at every compare: a 500 Hz square wave from the 84 MHz
//! timer clock, the bring-up's check of the clock tree with a frequency counter
//! (docs/bringup.md).

use core::sync::atomic::{AtomicU32, Ordering};

use super::pac;
use crate::board_timing::compare::next_period_compare;

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

/// Ahead of the counter the next internal compare must lie at least, ticks (2 us: the
/// handler's write lands before the counter gets there).
const MIN_LEAD_TICKS: u32 = 168;

/// Output periods of the internal rate that passed without their compare (the handler ran late
/// by more than a period: a flash store). Saturating.
pub static PERIODS_MISSED: AtomicU32 = AtomicU32::new(0);
/// Sync edges (or internal compares) taken by the handler, wrapping: the rate monitor's count.
pub static EDGES: AtomicU32 = AtomicU32::new(0);

// CCMR1 (TIM2): CC2S[9:8] = 01 (IC2 on TI2), IC2F[15:12] = 0011 (95 ns), for the external
// sync; CC2S = 00 with OC2M[14:12] = 011 (toggle on match: PB3 shows the rate) for the
// internal rate. The low byte (channel 1, the compare pulse) is the turnaround module's.
const CCMR1_IC2: u32 = (0b01 << 8) | (0b0011 << 12);
const CCMR1_OC2_TOGGLE: u32 = 0b011 << 12;
// CCER: CC2E 4 (capture enabled, or output enabled; rising / active high: CC2P 5 = 0)
const CCER_CC2E: u32 = 1 << 4;
// DIER / SR: CC2IE / CC2IF 2
pub(super) const SR_CC2IF: u32 = 1 << 2;

/// Adds the output latch's channel to TIM2 (after `turnaround::init`; clock for GPIOB on).
pub fn init(tim: &pac::TIM2) {
    // TIM2_CH2: the sync input, or the internal rate's toggling output (PB3 is JTDO/SWO after
    // reset; SWD does not need it).
    super::Port::B.alternate(3, 1);
    match SYNC_SOURCE {
        SyncSource::External => {
            tim.ccmr1_input()
                .modify(|r, w| unsafe { w.bits(r.bits() | CCMR1_IC2) });
        }
        SyncSource::Internal { period_ticks } => {
            tim.ccmr1_output()
                .modify(|r, w| unsafe { w.bits(r.bits() | CCMR1_OC2_TOGGLE) });
            let now = tim.cnt().read().bits();
            tim.ccr2()
                .write(|w| unsafe { w.bits(now.wrapping_add(period_ticks)) });
        }
    }
    tim.ccer()
        .modify(|r, w| unsafe { w.bits(r.bits() | CCER_CC2E) });
    tim.dier()
        .modify(|r, w| unsafe { w.bits(r.bits() | SR_CC2IF) });
}

/// The sync edge's time, if CC2 fired (TIM2 handler): the capture (reading CCR2 clears the
/// flag), or the internal compare's instant (the flag cleared and the next compare set on the
/// grid ahead of the counter, however late this handler runs: see the module docs).
pub fn take_edge(tim: &pac::tim2::RegisterBlock, sr: u32) -> Option<u32> {
    if sr & SR_CC2IF == 0 {
        return None;
    }
    let edge = tim.ccr2().read().bits();
    if let SyncSource::Internal { period_ticks } = SYNC_SOURCE {
        tim.sr().write(|w| unsafe { w.bits(!SR_CC2IF) });
        let now = tim.cnt().read().bits();
        let next = next_period_compare(edge, period_ticks, now, MIN_LEAD_TICKS);
        tim.ccr2().write(|w| unsafe { w.bits(next.at_ticks) });
        if next.missed_periods > 0 {
            let missed = PERIODS_MISSED.load(Ordering::Relaxed);
            PERIODS_MISSED.store(
                missed.saturating_add(next.missed_periods),
                Ordering::Relaxed,
            );
        }
    }
    EDGES.fetch_add(1, Ordering::Relaxed);
    Some(edge)
}

/// The sync's nominal rate, Hz (the internal rate's, or the external sync's expected one).
pub fn nominal_hz() -> f32 {
    match SYNC_SOURCE {
        SyncSource::Internal { period_ticks } => super::TIMER_HZ as f32 / period_ticks as f32,
        SyncSource::External => EXTERNAL_SYNC_HZ,
    }
}

/// The rate the navigation computer's sync is expected at when it is wired, Hz (its rate
/// monitor's reference).
pub const EXTERNAL_SYNC_HZ: f32 = 1000.0;
