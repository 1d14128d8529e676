//! The dither drive's peripherals: TIM4 ticks at 40 kHz; each update loads the DAC's next
//! drive sample and starts the pick-off's conversion, in hardware; a compare 2 us later
//! raises the drive interrupt, whose handler copies the pick-off code, calls
//! `crate::dither::DitherController::on_tick` and writes the DAC's holding register.
//!
//! # The chain
//! ```text
//! TIM4 (84 MHz, PSC 0, ARR 2099): update every 25 us = 40 kHz
//!   TRGO (MMS = 010, update) +-> DAC1 trigger (TSEL1 = 101): DHR12R1 -> DOR1 -> PA4 (buffered)
//!                            +-> ADC3 injected (JEXTSEL = 1001, JEXTEN = rising): PC2 (IN12)
//!   CC1 match at CCR1 = 168 (2 us): CC1IF -> TIM4 interrupt (priority 0x10)
//!       JDR1 (pick-off code) -> on_tick -> DHR12R1 (the code for the next update)
//! ```
//! Sampling and drive update are hardware-timed to the same edge: the handler's latency (and
//! any preemption by the turnaround latch) moves nothing but its own start, and its deadline is
//! the next update (23 us after the compare).
//!
//! # Why TIM4, not TIM6
//! TIM6 and TIM7 (the basic timers the DAC is usually paired with) can trigger the DAC but no
//! ADC conversion (RM0090 tables 69-70: ADC triggers come from TIM1-5 and TIM8 only), and
//! their update is not routed to an ADC. TIM4's TRGO is both a DAC trigger (TSEL 101) and an
//! injected-ADC trigger (JEXTSEL 1001), so one timer edge samples the pick-off and updates the
//! drive; TIM4 is otherwise unused (TIM2 turnaround timing, TIM3 Lissajous trigger, TIM5
//! encoder) and, on APB1, runs at the same 84 MHz the profile's tick is derived from.
//!
//! # ADC3
//! Independent of the ADC1/ADC2 dual mode (`ADC_CCR.MULTI` concerns ADC1 and ADC2 only); the
//! common prescaler gives it the same 21 MHz clock, 15-cycle sampling (0.71 us, source
//! impedance below ~1.5 kOhm: the pick-off amplifier's output), conversion 1.29 us, done well
//! before the compare. The sampling instant, 0.83 us after the update, is
//! `BoardProfile::aperture_delay_ticks` (the same ADC set-up as the photodiodes') and enters
//! the controller's phase detector (`DitherConfig::sample_delay_ticks`).
//!
//! # DAC
//! Channel 1, 12-bit right-aligned, output buffer on (it drives the drive amplifier's input:
//! the buffer's 5 kOhm minimum load), triggered by TIM4's TRGO: the code written in tick k's
//! handler appears at tick k + 1's update (3 APB1 clocks later), which is the controller's
//! convention (`on_tick` returns the code of the next tick). Before the first tick and
//! whenever the controller is off the output is mid-scale (zero drive).
//!
//! Mid-scale from the start: with a trigger selected (`TEN1`) the output register `DOR1` is
//! loaded only by a trigger and resets to 0, so enabling the channel triggered would drive 0 V,
//! a full negative drive step, until TIM4's first update. So the channel is enabled first
//! without a trigger, which loads `DHR12R1` (mid-scale) into `DOR1` one APB1 clock later
//! (RM0090 14.3.4), and the trigger is selected after that. The codes stay inside the buffered
//! output's linear range (`crate::dither::drive_limit_codes`).

use core::sync::atomic::{AtomicU32, Ordering};

use super::pac;
use super::ram::FLASH_BUSY;
use super::resources::DitherTask;
use super::turnaround::DRIVE_LOCKED;
use super::{Owned, Shared};
use crate::dither::{Coast, DitherState};
use crate::profile::BoardProfile;
use crate::sample::AdcCode;
use crate::signal::output::dither_model::PickoffSample;

/// TIM4 reload: 84 MHz / 2100 = 40 kHz, the profile's drive tick.
pub const TIM4_ARR: u32 = BoardProfile::F405.drive_tick_period_timer_ticks() - 1;
/// The compare that raises the handler, ticks after the update: 2 us, after the pick-off's
/// conversion has ended (1.43 us).
pub const TIM4_CCR1: u32 = 168;
/// Update to end of conversion: (3 latency + 15 sampling + 12 conversion) ADC clocks at 21 MHz
/// = 1.43 us = 120 timer ticks, below [`TIM4_CCR1`].
const CONVERSION_DONE_TICKS: u32 = 120;
const _: () = assert!(CONVERSION_DONE_TICKS < TIM4_CCR1);
/// The pick-off's ADC channel (PC2 = ADC123_IN12).
const PICKOFF_CHANNEL: u32 = 12;

/// Ticks whose pick-off conversion had not finished when the handler ran (the previous code
/// was used).
pub static SAMPLES_MISSED: AtomicU32 = AtomicU32::new(0);
/// Drive ticks handled, wrapping: the rate monitor's count.
pub static TICKS: AtomicU32 = AtomicU32::new(0);
/// The drive in force and the ticks coasted (owner: the drive tick; set by
/// `resources::start_dither` before its interrupt is unmasked).
pub static COAST: Owned<Coast> = Owned::new();

// TIMx_CR2: MMS[6:4] = 010 (update -> TRGO)
const TIM_CR2_MMS_UPDATE: u32 = 0b010 << 4;
// TIMx_DIER: CC1IE 1; SR: CC1IF 1
const TIM_CC1: u32 = 1 << 1;
// DAC_CR: EN1 0, BOFF1 1 (0: buffer on), TEN1 2, TSEL1[5:3] = 101 (TIM4 TRGO)
const DAC_CR_EN1: u32 = 1;
const DAC_CR: u32 = DAC_CR_EN1 | (1 << 2) | (0b101 << 3);
// ADC_CR2: ADON 0, JEXTSEL[19:16] = 1001 (TIM4 TRGO), JEXTEN[21:20] = 01 (rising); the regular
// group is the output latch's pick-off: EXTSEL[27:24] = 0110 (TIM2 TRGO, the latch's compare
// pulse, as ADC1/ADC2's injected pair), EXTEN[29:28] = 01 (rising). EOCS and DMA stay 0: no
// overrun detection, which would stop the regular group until cleared; the latch reads DR at
// every latch anyway.
const ADC_CR2: u32 = 1 | (0b1001 << 16) | (0b01 << 20) | (0b0110 << 24) | (0b01 << 28);
// ADC_SMPR1: SMP12[8:6] = 001 (15 cycles)
const ADC_SMPR1: u32 = 0b001 << 6;
// ADC_SR: JEOC 2
const ADC_SR_JEOC: u32 = 1 << 2;

/// Configures DAC1, ADC3 and TIM4 and starts the tick (clocks for TIM4, DAC, ADC3, GPIOA and
/// GPIOC must be on; the ADC common clock is set by `adc::init`). The controller must be in
/// place (`super::resources::DITHER`) before the TIM4 interrupt is unmasked.
pub fn init(tim: &pac::TIM4, dac: &pac::DAC, adc3: &pac::ADC3, mid_code: u16) {
    super::Port::A.analog(4); // DAC_OUT1
    super::Port::C.analog(2); // ADC3 IN12: the pick-off
    dac.dhr12r1().write(|w| unsafe { w.bits(mid_code as u32) });
    // Enabled untriggered first: DOR1 = mid-scale one APB1 clock later (module docs), then
    // the trigger.
    dac.cr().write(|w| unsafe { w.bits(DAC_CR_EN1) });
    cortex_m::asm::delay(16);
    dac.cr().write(|w| unsafe { w.bits(DAC_CR) });
    adc3.smpr1().write(|w| unsafe { w.bits(ADC_SMPR1) });
    adc3.jsqr()
        .write(|w| unsafe { w.bits(PICKOFF_CHANNEL << 15) }); // JL = 0: JSQ4
    adc3.sqr1().write(|w| unsafe { w.bits(0) }); // L = 0: one regular conversion
    adc3.sqr3().write(|w| unsafe { w.bits(PICKOFF_CHANNEL) }); // SQ1: the pick-off
    adc3.cr1().write(|w| unsafe { w.bits(0) });
    adc3.cr2().write(|w| unsafe { w.bits(ADC_CR2) });
    // t_STAB (3 us) before the first trigger.
    cortex_m::asm::delay(super::SYSCLK_HZ / 1_000_000 * 3);
    tim.cr1().write(|w| unsafe { w.bits(0) });
    tim.psc().write(|w| unsafe { w.bits(0) });
    tim.arr().write(|w| unsafe { w.bits(TIM4_ARR) });
    tim.ccr1().write(|w| unsafe { w.bits(TIM4_CCR1) });
    tim.ccmr1_output().write(|w| unsafe { w.bits(0) }); // frozen: CC1IF only
    tim.cr2().write(|w| unsafe { w.bits(TIM_CR2_MMS_UPDATE) });
    tim.sr().write(|w| unsafe { w.bits(0) });
    tim.dier().write(|w| unsafe { w.bits(TIM_CC1) });
    tim.cr1().write(|w| unsafe { w.bits(1) }); // CEN
}

/// The handler's register part: clears the compare flag and returns the pick-off code
/// (counting a conversion that had not finished).
#[inline(always)]
pub fn take_pickoff(tim: &pac::tim3::RegisterBlock, adc3: &pac::adc1::RegisterBlock) -> AdcCode {
    tim.sr().write(|w| unsafe { w.bits(!TIM_CC1) });
    if adc3.sr().read().bits() & ADC_SR_JEOC == 0 {
        SAMPLES_MISSED.fetch_add(1, Ordering::Relaxed);
    }
    adc3.sr().write(|w| unsafe { w.bits(!ADC_SR_JEOC) });
    AdcCode::from_register(adc3.jdr1().read().bits())
}

/// Drive off by software, without TIM4: the trigger deselected, so the DAC takes mid-scale at
/// once (the drive tick stopped, or the clock was lost: nothing else would move the DAC off
/// its last code, a DC force on the dither). The main loop's, once; the tick is inhibited too.
pub fn force_mid(dac: &pac::dac::RegisterBlock, mid_code: u16) {
    dac.cr().write(|w| unsafe { w.bits(DAC_CR_EN1) });
    dac.dhr12r1().write(|w| unsafe { w.bits(mid_code as u32) });
}

/// The drive tick: the pick-off code to the controller (`dither`), its DAC code to the holding
/// register (or, while a flash operation is under way, the drive in force continued: `coast`);
/// returns the code stamped with TIM2's time of this tick's update edge (the pick-off stream's
/// sample, on the output latches' time base: their stamps are their compare edges, and both
/// conversions follow their edge by the same aperture). Runs from RAM (`super::ram::tim4`):
/// everything here is inlined there, except [`controller_tick`], called only while the flash
/// is idle.
#[inline(always)]
pub fn on_tick(
    tim: &pac::tim3::RegisterBlock,
    adc3: &pac::adc1::RegisterBlock,
    dac: &pac::dac::RegisterBlock,
    tim2: &pac::tim2::RegisterBlock,
    coast: Option<&mut Coast>,
    dither: &mut impl Shared<Value = DitherTask>,
) -> PickoffSample {
    // The update edge in TIM2's time: both timers count the same 84 MHz clock, TIM4 from 0 at
    // its update. The two reads are taken together (a latch between them would move one by
    // its handler's time); their own spacing is a constant offset of a few ticks, the same for
    // every sample (a fixed phase the stripping's quadrature tap takes up).
    let (tim2_now, tim4_now) =
        cortex_m::interrupt::free(|_| (tim2.cnt().read().bits(), tim.cnt().read().bits()));
    let code = take_pickoff(tim, adc3);
    TICKS.fetch_add(1, Ordering::Relaxed);
    if let Some(coast) = coast {
        if FLASH_BUSY.load(Ordering::Relaxed) {
            let next = coast.code();
            dac.dhr12r1().write(|w| unsafe { w.bits(next as u32) });
        } else {
            controller_tick(code, dac, coast, dither);
        }
    }
    PickoffSample {
        timestamp_ticks: tim2_now.wrapping_sub(tim4_now),
        code,
    }
}

/// The controller's tick (in flash, reached only while the flash is idle): first the ticks it
/// missed, then this one; its DAC code to the holding register, its drive to the coast state.
#[inline(never)]
pub fn controller_tick(
    code: AdcCode,
    dac: &pac::dac::RegisterBlock,
    coast: &mut Coast,
    dither: &mut impl Shared<Value = DitherTask>,
) {
    dither.lock(|task| {
        coast.hand_over(&mut task.controller, &task.config);
        let tick = task.controller.on_tick(&task.config, code);
        dac.dhr12r1()
            .write(|w| unsafe { w.bits(tick.dac_code as u32) });
        coast.follow(&task.controller);
        let locked = task.controller.state() == DitherState::Locked;
        DRIVE_LOCKED.store(locked, Ordering::Relaxed);
    });
}
