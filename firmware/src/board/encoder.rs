//! Fringe counting: TIM5 (32-bit) as an x4 quadrature counter of the squared photodiode signals,
//! latched in hardware at the turnaround.
//!
//! # Registers
//! - Pins: comparator A on PA0 (TIM5_CH1), comparator B on PA1 (TIM5_CH2), AF2.
//! - `SMCR.SMS = 011`: encoder mode 3, the counter moves on every edge of TI1FP1 and TI2FP2
//!   (x4: one count per quarter fringe), direction from the other channel's level.
//! - `CCMR1.CC1S = CC2S = 01`, `IC1F = IC2F = 0011` (filter, below); `CCER.CC1P = CC2P = 0`.
//!   Swapping A and B, or one polarity bit, reverses the count direction (docs/physics.md pitfall 4:
//!   validate the sign pattern on the board against the simulator).
//! - `ARR = 0xFFFF_FFFF`: the full 32-bit range, wrapping; the readout extends it.
//! - Latch: `SMCR.TS = 000` selects ITR0, which on TIM5 is TIM2's TRGO (RM0090 table 100);
//!   `CCMR2.CC3S = 11` maps input capture 3 on TRC (the selected trigger), `CCER.CC3E = 1`.
//!   Every TRGO pulse of the turnaround timer copies `CNT` into `CCR3` two to three timer clocks
//!   later (24-36 ns). In encoder mode the slave controller counts TI1/TI2 and does not use TRGI,
//!   so TS is free for this. (The manual documents TRC capture; that it works together with
//!   encoder mode is the one assumption here that only a board can confirm: see docs/board.md.)
//!   Fallback if it does not: a DMA1 request from TIM2_CH1 (stream 5, channel 3) copying
//!   `TIM5.CNT` to RAM, ~100 ns later with bus-dependent jitter.
//!
//! # Input filter
//! At the docs/physics.md peak beat frequency (~590 kHz) each channel toggles at 1.2 M edges/s and the
//! x4 edge rate is ~2.4 M edges/s: nominally 417 ns between consecutive edges of A and B. With a
//! quadrature error of +-30 degrees and 40/60 comparator duty cycle the closest pair of edges is
//! still about 200 ns apart. `ICxF = 0011` samples at f_CK_INT = 84 MHz and needs 8 equal samples:
//! 95 ns. It removes comparator chatter shorter than 95 ns, delays every edge by the same 95 ns
//! (+2 clocks of resynchronisation: no count error, only a common delay against the latch), and
//! leaves more than half of the closest edge spacing. The next setting (`0100`, f_DTS/2, N = 6:
//! 143 ns) would leave too little margin at full rate; `0010` (48 ns) too little rejection.
//! The counter itself resolves edges down to a few timer clocks (~50 ns), well inside.

use super::pac;

// TIMx_SMCR: SMS[2:0], TS[6:4]
const SMS_ENCODER_X4: u32 = 0b011;
const TS_ITR0: u32 = 0b000 << 4;
// TIMx_CCMR1 (input): CC1S[1:0], IC1F[7:4], CC2S[9:8], IC2F[15:12]
const IC_FILTER_95NS: u32 = 0b0011;
const CCMR1_ENCODER: u32 = 0b01 | (IC_FILTER_95NS << 4) | (0b01 << 8) | (IC_FILTER_95NS << 12);
// TIMx_CCMR2 (input): CC3S[1:0] = 11: IC3 on TRC
const CCMR2_LATCH_ON_TRC: u32 = 0b11;
// TIMx_CCER: CC3E bit 8 (capture enabled, rising edge of TRC)
const CCER_LATCH: u32 = 1 << 8;
// TIMx_SR: CC3IF bit 3, CC3OF bit 11
const SR_CC3OF: u32 = 1 << 11;

/// The fringe counter (owns TIM5).
pub struct Encoder {
    tim: pac::TIM5,
}

impl Encoder {
    /// Configures TIM5 and its pins (clocks for TIM5 and GPIOA must be on) and starts counting.
    pub fn new(tim: pac::TIM5) -> Self {
        super::Port::A.alternate(0, 2);
        super::Port::A.alternate(1, 2);
        tim.cr1().write(|w| unsafe { w.bits(0) });
        tim.psc().write(|w| unsafe { w.bits(0) });
        tim.arr().write(|w| unsafe { w.bits(u32::MAX) });
        tim.ccmr1_input()
            .write(|w| unsafe { w.bits(CCMR1_ENCODER) });
        tim.ccmr2_input()
            .write(|w| unsafe { w.bits(CCMR2_LATCH_ON_TRC) });
        tim.ccer().write(|w| unsafe { w.bits(CCER_LATCH) });
        tim.smcr()
            .write(|w| unsafe { w.bits(SMS_ENCODER_X4 | TS_ITR0) });
        tim.cnt().write(|w| unsafe { w.bits(0) });
        tim.cr1().write(|w| unsafe { w.bits(1) }); // CEN
        Self { tim }
    }

    /// The count now (for start-up and diagnostics; the readout uses [`Encoder::latched`]).
    pub fn count(&self) -> u32 {
        self.tim.cnt().read().bits()
    }

    /// Register access for the turnaround handler, which must not need `&self` of an owner.
    pub fn registers() -> &'static pac::tim5::RegisterBlock {
        // SAFETY: read-only use of CCR3/SR by the turnaround handler; configuration stays here.
        unsafe { &*pac::TIM5::ptr() }
    }
}

/// The count latched by the last turnaround trigger, and whether a latch was overwritten before
/// it was read (`CC3OF`: a turnaround handler ran late by a whole half cycle). Clears the flag.
#[inline(always)]
pub fn take_latched(tim: &pac::tim5::RegisterBlock) -> (u32, bool) {
    let overwritten = tim.sr().read().bits() & SR_CC3OF != 0;
    if overwritten {
        tim.sr().write(|w| unsafe { w.bits(!SR_CC3OF) }); // rc_w0
    }
    // Reading CCR3 clears CC3IF.
    (tim.ccr3().read().bits(), overwritten)
}
