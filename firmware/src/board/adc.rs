//! Photodiode ADCs: ADC1 (channel A, ~cos psi_H) and ADC2 (channel B, ~sin psi_H) in dual
//! *combined regular simultaneous + injected simultaneous* mode (`ADC_CCR.MULTI = 00001`).
//!
//! # Two groups, one pair of converters
//! - **Injected** (the turnaround): one conversion per ADC (`JL = 0`, so the channel is in
//!   `JSQ4`, the result in `JDR1`), triggered by TIM2's TRGO (`JEXTSEL = 0011`, `JEXTEN = 01`) on
//!   ADC1; ADC2 follows as the slave (its own external triggers off). The injected trigger
//!   interrupts a regular conversion in progress (which is redone afterwards), so the turnaround
//!   pair never waits for a Lissajous sample. `JEOCIE` on ADC1 raises the turnaround handler.
//! - **Regular** (the Lissajous fit): one conversion per ADC at each TIM3 update
//!   (`EXTSEL = 1000` TIM3_TRGO): 84 MHz / 6803 = 12 347.5 pairs/s, not a divisor of any dither
//!   frequency, so the samples cover the whole Lissajous figure (the fit needs spread, not
//!   timing). DMA mode 2 (`ADC_CCR.DMA = 10`, `DDS = 1`) delivers one 32-bit word per pair,
//!   `ADC2 << 16 | ADC1`, from `ADC_CDR` through DMA2 stream 0 channel 0, circular, into a
//!   double buffer of 2 x [`BLOCK_PAIRS`]; the half-transfer and transfer-complete interrupts
//!   hand each half (20.7 ms of samples) to the readout task, which has the other half's
//!   duration to process it (~0.25 ms needed).
//!
//! # Clock, resolution, sampling time
//! ADC clock = PCLK2 / 4 = 21 MHz (`ADCPRE = 01`; /2 would be 42 MHz, above the 36 MHz maximum).
//! 12 bits. Sampling time 15 cycles (`SMPx = 001`) = 0.71 us, conversion 15 + 12 = 27 cycles =
//! 1.29 us. The hold happens at the end of sampling: the effective sampling instant is the
//! trigger plus 2-3 clocks of latency plus 15 clocks, 0.83 us +-24 ns, compensated in the
//! schedule ([`super::turnaround::APERTURE_DELAY_TICKS`]). Averaging over the 0.71 us window at
//! a stationary phase biases the level by psi_ddot T^2/24 ~ 2e-4 rad: negligible. 15 cycles
//! needs a source impedance below ~1.5 kOhm at 12 bits (datasheet R_AIN formula): the photodiode
//! transimpedance amplifiers' outputs, with a small RC, not the bare photodiodes. 3 cycles
//! (143 ns) would need < 0.2 kOhm and gives no timing benefit once the delay is compensated.
//!
//! # Pins
//! Channel A on PC0 (ADC123_IN10), channel B on PC1 (ADC123_IN11), analog mode. Simultaneous mode
//! must never convert one channel on both ADCs at once: here each ADC has its own channel.
//!
//! # Overrun and transfer errors: the stream restarts
//! A regular pair that the DMA did not take before the next one (the bus held too long) sets
//! `OVR`, and the ADCs then stop issuing DMA requests (RM0090 13.8.1): the photodiode stream
//! would be over for good. `OVRIE` raises the ADC interrupt (the latch's vector, which checks
//! `OVR` first); a DMA transfer error disables the stream in hardware and raises the DMA
//! interrupt. Both restart the stream the same way ([`restart_stream`]): the DMA's request
//! bits in `ADC_CCR` off, the stream re-armed from the start of the buffer, the `OVR` flags
//! cleared, the request bits on again; the half buffer under way is dropped (the readout's
//! Lissajous fit loses one block; the next starts clean), and every restart is counted
//! ([`OVERRUNS`], [`DMA_ERRORS`]). The rate monitor (`board_timing::monitor`, `lissajous`)
//! names a stream that stops for any other reason.

use core::cell::UnsafeCell;
use core::sync::atomic::{compiler_fence, AtomicU32, AtomicU8, Ordering};

use super::pac;
use crate::sample::AdcCode;

/// Conversion pairs per half buffer: 256 pairs = 20.7 ms at 12 347.5 pairs/s (48 blocks/s).
pub const BLOCK_PAIRS: usize = 256;
/// TIM3 auto-reload for the regular trigger: 84 MHz / (6802 + 1) = 12 347.5 Hz.
pub const TIM3_ARR: u32 = 6802;
/// ADC channels of the photodiodes.
const CHANNEL_A: u32 = 10;
const CHANNEL_B: u32 = 11;

// ADC_CCR: MULTI[4:0] = 00001, DMA[15:14] = 10, DDS 13, ADCPRE[17:16] = 01
const CCR: u32 = 0b00001 | (0b10 << 14) | (1 << 13) | (0b01 << 16);
// ADC_CR1: JEOCIE 7, OVRIE 26; RES[25:24] = 00 (12 bits)
const CR1_JEOCIE: u32 = 1 << 7;
const CR1_OVRIE: u32 = 1 << 26;
// ADC_CR2: ADON 0, JEXTSEL[19:16], JEXTEN[21:20], EXTSEL[27:24], EXTEN[29:28]
const ADON: u32 = 1;
const CR2_MASTER: u32 = ADON | (0b0011 << 16) | (0b01 << 20) | (0b1000 << 24) | (0b01 << 28);
// SMPR1: SMP10[2:0], SMP11[5:3] = 001 (15 cycles)
const SMPR1: u32 = 0b001 | (0b001 << 3);
// ADC_SR: JEOC bit 2, OVR bit 5 (rc_w0)
const SR_JEOC: u32 = 1 << 2;
const SR_OVR: u32 = 1 << 5;
// ADC_CCR: DMA[15:14], the multi-mode DMA request
const CCR_DMA_MASK: u32 = 0b11 << 14;
/// JSQR with JL = 0: the single injected channel goes in JSQ4[19:15].
const fn jsqr(channel: u32) -> u32 {
    channel << 15
}

// DMA_SxCR: EN 0, TEIE 2, HTIE 3, TCIE 4, DIR[7:6] = 00, CIRC 8, MINC 10, PSIZE[12:11] = 10,
// MSIZE[14:13] = 10, PL[17:16] = 01, CHSEL[27:25] = 000
const DMA_CR: u32 = (1 << 2)
    | (1 << 3)
    | (1 << 4)
    | (1 << 8)
    | (1 << 10)
    | (0b10 << 11)
    | (0b10 << 13)
    | (0b01 << 16);
// DMA LISR/LIFCR, stream 0: FEIF0 0, DMEIF0 2, TEIF0 3, HTIF0 4, TCIF0 5
const S0_ALL: u32 = 0b11_1101;
const S0_TE: u32 = 1 << 3;
const S0_HT: u32 = 1 << 4;
const S0_TC: u32 = 1 << 5;
const ADC_CDR: u32 = 0x4001_2308;

/// The DMA's double buffer: written by DMA2 only, read by the readout task one half at a time.
struct DmaBuffer(UnsafeCell<[u32; 2 * BLOCK_PAIRS]>);
// SAFETY: the halves are handed over by the HT/TC protocol (see `take_ready_block`).
unsafe impl Sync for DmaBuffer {}
static BUFFER: DmaBuffer = DmaBuffer(UnsafeCell::new([0; 2 * BLOCK_PAIRS]));

/// Halves completed by the DMA and not yet processed (bit 0: first, bit 1: second).
static READY: AtomicU8 = AtomicU8::new(0);
/// A half completed again before the readout task had processed it (samples lost).
pub static BLOCK_OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// DMA transfer errors (each restarted the stream).
pub static DMA_ERRORS: AtomicU32 = AtomicU32::new(0);
/// Regular-group overruns (each restarted the stream).
pub static OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Half buffers completed, wrapping: the rate monitor's count.
pub static HALVES: AtomicU32 = AtomicU32::new(0);

/// Configures both ADCs, TIM3 and DMA2 stream 0 and starts the regular stream. Clocks for ADC1,
/// ADC2, TIM3, DMA2 and GPIOC must be on. The injected group waits for TIM2's TRGO.
pub fn init(
    common: &pac::ADC_COMMON,
    adc1: &pac::ADC1,
    adc2: &pac::ADC2,
    tim3: &pac::TIM3,
    dma: &pac::DMA2,
) {
    super::Port::C.analog(0);
    super::Port::C.analog(1);
    common.ccr().write(|w| unsafe { w.bits(CCR) });
    for (adc, channel) in [(&**adc1, CHANNEL_A), (&**adc2, CHANNEL_B)] {
        adc.smpr1().write(|w| unsafe { w.bits(SMPR1) });
        adc.sqr1().write(|w| unsafe { w.bits(0) }); // L = 0: one regular conversion
        adc.sqr3().write(|w| unsafe { w.bits(channel) });
        adc.jsqr().write(|w| unsafe { w.bits(jsqr(channel)) });
    }
    adc1.cr1()
        .write(|w| unsafe { w.bits(CR1_JEOCIE | CR1_OVRIE) });
    adc2.cr1().write(|w| unsafe { w.bits(CR1_OVRIE) });
    adc2.cr2().write(|w| unsafe { w.bits(ADON) }); // slave: triggered by the master
    adc1.cr2().write(|w| unsafe { w.bits(CR2_MASTER) });
    // t_STAB (3 us) before the first trigger: TIM3 starts below, TIM2's first compare is
    // scheduled a dither cycle later.
    cortex_m::asm::delay(super::SYSCLK_HZ / 1_000_000 * 3);

    arm_stream(dma);

    tim3.psc().write(|w| unsafe { w.bits(0) });
    tim3.arr().write(|w| unsafe { w.bits(TIM3_ARR) });
    tim3.cr2().write(|w| unsafe { w.bits(0b010 << 4) }); // MMS = update -> TRGO
    tim3.cr1().write(|w| unsafe { w.bits(1) });
}

/// Sets DMA2 stream 0 up from the start of the buffer and enables it (the stream must be
/// disabled).
fn arm_stream(dma: &pac::dma2::RegisterBlock) {
    let stream = dma.st(0);
    stream.cr().write(|w| unsafe { w.bits(0) });
    dma.lifcr().write(|w| unsafe { w.bits(S0_ALL) });
    stream.par().write(|w| unsafe { w.bits(ADC_CDR) });
    stream
        .m0ar()
        .write(|w| unsafe { w.bits(BUFFER.0.get() as u32) });
    stream
        .ndtr()
        .write(|w| unsafe { w.bits(2 * BLOCK_PAIRS as u32) });
    stream.fcr().write(|w| unsafe { w.bits(0) }); // direct mode
    stream.cr().write(|w| unsafe { w.bits(DMA_CR | 1) });
}

/// Polls of a stream's EN bit after clearing it (the stream finishes its current transfer
/// first: a few bus cycles).
const STREAM_STOP_POLLS: u32 = 1000;

/// Restarts the photodiode stream after an overrun or a transfer error (module docs): the
/// multi-mode DMA requests off, the stream re-armed at the start of the buffer, `OVR` cleared
/// on both ADCs, the requests on again. The halves not yet handed over are dropped.
pub fn restart_stream(
    common: &pac::adc_common::RegisterBlock,
    adc1: &pac::adc1::RegisterBlock,
    adc2: &pac::adc1::RegisterBlock,
    dma: &pac::dma2::RegisterBlock,
) {
    let ccr = common.ccr().read().bits();
    common
        .ccr()
        .write(|w| unsafe { w.bits(ccr & !CCR_DMA_MASK) });
    let stream = dma.st(0);
    stream.cr().write(|w| unsafe { w.bits(0) });
    let _ = (0..STREAM_STOP_POLLS).any(|_| stream.cr().read().bits() & 1 == 0);
    READY.store(0, Ordering::Release);
    arm_stream(dma);
    for adc in [adc1, adc2] {
        adc.sr().write(|w| unsafe { w.bits(!SR_OVR) });
    }
    common.ccr().write(|w| unsafe { w.bits(ccr) });
}

/// The latch vector's first job: an overrun of the regular pair (either ADC) restarts the
/// stream (counted). Returns whether ADC1's injected pair has a result (the latch's own
/// event; false when only the overrun raised the interrupt).
#[inline(always)]
pub fn on_adc_interrupt(
    common: &pac::adc_common::RegisterBlock,
    adc1: &pac::adc1::RegisterBlock,
    adc2: &pac::adc1::RegisterBlock,
    dma: &pac::dma2::RegisterBlock,
) -> bool {
    let sr = adc1.sr().read().bits();
    if (sr | adc2.sr().read().bits()) & SR_OVR != 0 {
        OVERRUNS.fetch_add(1, Ordering::Relaxed);
        restart_stream(common, adc1, adc2, dma);
        return sr & SR_JEOC != 0;
    }
    true
}

/// Clears the injected end-of-conversion flag (the turnaround handler, first thing).
#[inline(always)]
pub fn clear_jeoc(adc1: &pac::adc1::RegisterBlock) {
    adc1.sr().write(|w| unsafe { w.bits(!SR_JEOC) });
}

/// Drops a stale injected result (after a pause, before the turnaround IRQ is unmasked).
pub fn discard_injected(adc1: &pac::adc1::RegisterBlock) {
    clear_jeoc(adc1);
}

/// The DMA handler's work (DMA2 stream 0 IRQ): which half completed. Returns true when the
/// readout task should run.
#[inline(always)]
pub fn on_dma_interrupt(dma: &pac::dma2::RegisterBlock) -> bool {
    let flags = dma.lisr().read().bits() & S0_ALL;
    dma.lifcr().write(|w| unsafe { w.bits(flags) });
    if flags & S0_TE != 0 {
        // The hardware disabled the stream: restarted (module docs).
        DMA_ERRORS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the ADCs' CCR and OVR flags are touched only by a restart, this handler's
        // or the latch's; the latch (0x00) may preempt this one half-way and restart too:
        // every step leaves a state the next restart starts from, so the later one wins.
        let (common, adc1, adc2) = unsafe {
            (
                &*pac::ADC_COMMON::ptr(),
                &*pac::ADC1::ptr(),
                &*pac::ADC2::ptr(),
            )
        };
        restart_stream(common, adc1, adc2, dma);
        return false;
    }
    let mut halves = 0;
    if flags & S0_HT != 0 {
        halves |= 0b01;
    }
    if flags & S0_TC != 0 {
        halves |= 0b10;
    }
    let before = READY.fetch_or(halves, Ordering::Release);
    if before & halves != 0 {
        BLOCK_OVERRUNS.fetch_add(1, Ordering::Relaxed);
    }
    HALVES.fetch_add(halves.count_ones(), Ordering::Relaxed);
    halves != 0
}

/// Feeds every completed half to `f` as (a, b) code pairs (readout task only).
pub fn take_ready_blocks(mut f: impl FnMut(AdcCode, AdcCode)) {
    let ready = READY.swap(0, Ordering::Acquire);
    compiler_fence(Ordering::Acquire);
    for half in 0..2 {
        if ready & (1 << half) == 0 {
            continue;
        }
        // SAFETY: this half is complete and the DMA is filling the other one; it comes back
        // here only after 20.7 ms, by which time the loop below (~0.25 ms) is long done.
        let words = unsafe {
            let base = (BUFFER.0.get() as *const u32).add(half * BLOCK_PAIRS);
            core::slice::from_raw_parts(base, BLOCK_PAIRS)
        };
        for &w in words {
            f(AdcCode::from_register(w), AdcCode::from_register(w >> 16));
        }
    }
}
