//! The power-up self-test's measurements: what the registers say after start-up, before any
//! interrupt is unmasked. The verdicts are plain functions (`crate::board_timing::selftest`,
//! host-tested, the same the simulated board's self-test uses); the pick-off check is the
//! dither controller's half-drive sweep, which runs after these have passed
//! (`super::resources::start_dither`).
//!
//! - **clock**: RCC_CR / RCC_CFGR as they are ([`super::clocks::flags`]).
//! - **timers**: SysTick's current value and the counters of TIM2, TIM3 and TIM4, read in one
//!   critical section, again about 1200 core cycles later (the interval below TIM4's period of
//!   2100 ticks, so the reloading counters' advances are unambiguous); SysTick counts the core
//!   clock down, the timers the APB1 timer clock up. The reads are in the same order both times,
//!   so their skew cancels.
//! - **triggers**: one compare of TIM2 10 us ahead, then after 40 us the flags its TRGO must
//!   have set (ADC1 and ADC2 JEOC, TIM5 CC3IF: the count latched on TRC in encoder mode,
//!   ADC3 EOC); TIM4's updates: ADC3 JEOC within 60 us, and the DAC's output register taking
//!   a holding-register value one code above mid-scale and back (a one-code step of the drive);
//!   TIM3's updates: DMA2 stream 0's NDTR moving within 250 us. PA15 toggles once (the
//!   compare). Every flag is cleared afterwards and the NVIC's pending bits dropped, so the
//!   handlers start clean.

use cortex_m::peripheral::{NVIC, SYST};

use super::pac;
use crate::board_timing::selftest::{
    check_clock, check_timer_clock, check_timers, check_triggers, Check, SelfTestReport,
    TimerAdvance, TriggerFlags,
};

/// The peripherals the checks read, all set up and running.
pub struct Under<'a> {
    /// The clock tree.
    pub rcc: &'a pac::RCC,
    /// The latch timer (its compare is fired once).
    pub tim2: &'a pac::tim2::RegisterBlock,
    /// The photodiode stream's trigger.
    pub tim3: &'a pac::tim3::RegisterBlock,
    /// The drive tick.
    pub tim4: &'a pac::tim3::RegisterBlock,
    /// The photodiodes' converters.
    pub adc1: &'a pac::adc1::RegisterBlock,
    /// ADC1's dual-mode slave.
    pub adc2: &'a pac::adc1::RegisterBlock,
    /// The pick-off's converter.
    pub adc3: &'a pac::adc1::RegisterBlock,
    /// The drive DAC.
    pub dac: &'a pac::dac::RegisterBlock,
    /// The photodiode stream's DMA.
    pub dma: &'a pac::dma2::RegisterBlock,
}

// ADC_SR: EOC 1, JEOC 2; TIMx_SR: CC3IF 3; DMA_SxCR / NDTR
const ADC_SR_EOC: u32 = 1 << 1;
const ADC_SR_JEOC: u32 = 1 << 2;
const TIM_SR_CC1IF: u32 = 1 << 1;
const TIM_SR_CC3IF: u32 = 1 << 3;
/// The periods of the reloading counters, ticks (`adc::TIM3_ARR` + 1, the drive tick's).
const TIM3_PERIOD: u32 = super::adc::TIM3_ARR + 1;
const TIM4_PERIOD: u32 = super::dither::TIM4_ARR + 1;

/// Runs the clock, timer and trigger checks (the pick-off check is left not run: the drive's).
pub fn run(p: &Under<'_>, dac_mid_code: u16) -> SelfTestReport {
    let mut report = SelfTestReport::NOT_RUN;
    report.set(Check::Clock, check_clock(super::clocks::flags(p.rcc)));
    let advance = timer_advance(p);
    report.set(Check::Timers, check_timers(advance));
    report.set(
        Check::TimerClock,
        check_timer_clock(advance, super::TIMER_HZ, super::SYSCLK_HZ),
    );
    report.set(Check::Triggers, check_triggers(triggers(p, dac_mid_code)));
    clean_up(p);
    report
}

fn delay_us(us: u32) {
    cortex_m::asm::delay(super::SYSCLK_HZ / 1_000_000 * us);
}

/// The advance of `now` from `before` on a counter that reloads after `period`.
fn advance_in_period(before: u32, now: u32, period: u32) -> u32 {
    if now >= before {
        now - before
    } else {
        now + period - before
    }
}

fn timer_advance(p: &Under<'_>) -> TimerAdvance {
    let read = || {
        cortex_m::interrupt::free(|_| {
            (
                SYST::get_current(),
                p.tim2.cnt().read().bits(),
                p.tim3.cnt().read().bits(),
                p.tim4.cnt().read().bits(),
            )
        })
    };
    let a = read();
    cortex_m::asm::delay(1200);
    let b = read();
    let reload = SYST::get_reload() + 1;
    TimerAdvance {
        // SysTick counts down.
        core_cycles: advance_in_period(b.0, a.0, reload),
        ticks: [
            b.1.wrapping_sub(a.1),
            advance_in_period(a.2, b.2, TIM3_PERIOD),
            advance_in_period(a.3, b.3, TIM4_PERIOD),
        ],
    }
}

fn triggers(p: &Under<'_>, dac_mid_code: u16) -> TriggerFlags {
    // SAFETY: read and flag-clear of TIM5's SR and CCR3; the encoder's configuration is
    // untouched and no handler runs yet.
    let tim5 = unsafe { &*pac::TIM5::ptr() };
    for adc in [p.adc1, p.adc2, p.adc3] {
        adc.sr().write(|w| unsafe { w.bits(0) });
    }
    let _ = p.adc3.dr().read().bits();
    tim5.sr().write(|w| unsafe { w.bits(0) });
    // One compare of TIM2, 10 us ahead: its TRGO pulse.
    let now = p.tim2.cnt().read().bits();
    p.tim2
        .ccr1()
        .write(|w| unsafe { w.bits(now.wrapping_add(840)) });
    delay_us(40);
    let adc1_injected = p.adc1.sr().read().bits() & ADC_SR_JEOC != 0;
    let adc2_injected = p.adc2.sr().read().bits() & ADC_SR_JEOC != 0;
    let encoder_latch = tim5.sr().read().bits() & TIM_SR_CC3IF != 0;
    let adc3_regular = p.adc3.sr().read().bits() & ADC_SR_EOC != 0;
    // TIM4's updates: ADC3's injected conversion, the DAC's load.
    p.adc3.sr().write(|w| unsafe { w.bits(0) });
    p.dac
        .dhr12r1()
        .write(|w| unsafe { w.bits(u32::from(dac_mid_code) + 1) });
    delay_us(60);
    let adc3_injected = p.adc3.sr().read().bits() & ADC_SR_JEOC != 0;
    let dac_up = p.dac.dor1().read().bits() == u32::from(dac_mid_code) + 1;
    p.dac
        .dhr12r1()
        .write(|w| unsafe { w.bits(u32::from(dac_mid_code)) });
    delay_us(60);
    let dac_back = p.dac.dor1().read().bits() == u32::from(dac_mid_code);
    // TIM3's updates: the photodiode pairs, moved by the DMA.
    let ndtr = p.dma.st(0).ndtr().read().bits();
    delay_us(250);
    let lissajous_dma = p.dma.st(0).ndtr().read().bits() != ndtr;
    TriggerFlags {
        adc1_injected,
        adc2_injected,
        encoder_latch,
        adc3_regular,
        adc3_injected,
        dac: dac_up && dac_back,
        lissajous_dma,
    }
}

/// Leaves no flag for the handlers: the compare parked, the converters' and TIM5's flags and
/// data taken, the NVIC's pending bits of the still masked vectors dropped.
fn clean_up(p: &Under<'_>) {
    // SAFETY: as in `triggers`.
    let tim5 = unsafe { &*pac::TIM5::ptr() };
    let now = p.tim2.cnt().read().bits();
    p.tim2
        .ccr1()
        .write(|w| unsafe { w.bits(now.wrapping_add(1 << 31)) });
    let _ = p.adc3.dr().read().bits();
    let _ = tim5.ccr3().read().bits();
    for adc in [p.adc1, p.adc2, p.adc3] {
        adc.sr().write(|w| unsafe { w.bits(0) });
    }
    tim5.sr().write(|w| unsafe { w.bits(0) });
    // Only CC1IF (the fired compare): a pending CC2IF is the sync's next edge, whose handler
    // must still see it (the internal rate's next compare is set there).
    p.tim2.sr().write(|w| unsafe { w.bits(!TIM_SR_CC1IF) });
    p.tim4.sr().write(|w| unsafe { w.bits(0) });
    for irq in [
        pac::Interrupt::ADC,
        pac::Interrupt::TIM2,
        pac::Interrupt::TIM4,
        pac::Interrupt::DMA2_STREAM0,
    ] {
        NVIC::unpend(irq);
    }
}
