//! Turnaround timing: TIM2 (32-bit, 84 MHz) captures the dither pick-off's zero crossings and
//! fires one compare event at each predicted turnaround; that event samples both photodiodes and
//! latches the fringe count in hardware. Software only schedules (hundreds of microseconds ahead)
//! and copies results (microseconds after): no instruction lies on the ~1 us timing path.
//!
//! # The chain
//! ```text
//! pick-off comparator --PB11 (TIM2_CH4)--> IC3 (rising) / IC4 (falling): CCR3/CCR4 = t_edge
//!     TIM2 IRQ (priority 1): t_compare = t_edge + half the previous same-polarity interval
//!                            -/+ input-rate shift - fixed delays; CCR1 = t_compare
//! CNT == CCR1 -> CC1 match -> TRGO pulse (CR2.MMS = 011, "compare pulse")
//!     +-> ADC1 JEXTSEL = 3 (TIM2_TRGO), JEXTEN = rising: injected pair, ADC1 + ADC2 simultaneous
//!     +-> TIM5 ITR0 -> TRC -> IC3: TIM5.CCR3 = fringe count          (see `encoder`)
//!     +-> OC1 toggles PA15 (test point for a scope: trigger vs pick-off vs photodiodes)
//! ADC JEOC IRQ (priority 0): ADC1.JDR1, ADC2.JDR1, TIM5.CCR3, TIM2.CCR1 -> TurnaroundSample
//! ```
//!
//! # Prediction
//! The prediction itself is plain logic in [`crate::signal::turnaround`] (host-tested,
//! and the same code drives the simulated board's latch in `hal-sim`): half the previous
//! same-polarity interval after each edge (which cancels a comparator threshold offset), the
//! input-rate shift with opposite signs at "+" and "-" (docs/physics.md pitfall 3), minus the fixed
//! delays; its module docs carry the derivation and the expected timing error. This module binds
//! it to the board: the fixed delays ([`PICKOFF_DELAY_TICKS`], [`APERTURE_DELAY_TICKS`]) and the
//! pick-off polarity ([`AFTER_RISING_EDGE`]) as constants, the rate shift published by the cycle
//! task through [`RATE_SHIFT_TICKS`] (an atomic word, [`publish_rate_shift`]), and the counters
//! ([`IMPLAUSIBLE`], [`LATE`], ...).
//!
//! The delays, to be calibrated on a board with the PA15 test point: the pick-off path
//! (comparator, 95 ns input filter, resynchronisation) and the ADC aperture (injected trigger
//! latency 2-3 ADC clocks plus the 15-clock sampling time; the hold happens at the end of
//! sampling, so the compare fires that much early and the *sampling* instant lands on the
//! turnaround). About +-0.1 us random error once they are calibrated, against the ~1 us
//! docs/physics.md asks for.

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, Ordering};

use cortex_m::interrupt::Mutex;

use super::{pac, Shared};
use crate::board_timing::phase::keep_out_now;
use crate::profile::BoardProfile;
use crate::sample::{AdcCode, OutputSample, TurnaroundKind, TurnaroundSample};
use crate::signal::lockin::CycleRecord;
use crate::signal::output::latch_plan::{Arm, LatchKind, LatchPlan, OUTPUT_LEAD_TICKS};
use crate::signal::turnaround::{self as schedule, SchedulerConfig};
pub use crate::signal::turnaround::{Edge, Schedule};

/// Pick-off comparator delay + input filter + resynchronisation, ticks (84 MHz). Nominal: 100 ns
/// comparator, 95 ns filter, 2 clocks = 18 ticks. Calibrate on the board; the value lives in
/// the board profile, which the simulated board reads too.
pub const PICKOFF_DELAY_TICKS: u32 = BoardProfile::F405.pickoff_delay_ticks;
/// Compare match to the end of the ADC sampling window, ticks: (2.5 + 15) ADC clocks at 21 MHz
/// = 0.83 us = 70 ticks. The sample's timestamp is `CCR1 + APERTURE_DELAY_TICKS`.
pub const APERTURE_DELAY_TICKS: u32 = BoardProfile::F405.aperture_delay_ticks;
/// The compare must be armed at least this far ahead (2 us), else the turnaround is skipped
/// (counted in [`LATE`]) rather than fired 51 s later, after the counter wraps.
const MIN_LEAD_TICKS: u32 = 168;
/// Which turnaround follows a rising pick-off edge (angle increasing through zero: the next
/// extremum is a maximum, the rate goes from + to -). A pick-off wired with the other polarity
/// flips it: docs/physics.md pitfall 4, check against the simulator's sign pattern on the board.
pub const AFTER_RISING_EDGE: TurnaroundKind = BoardProfile::F405.after_rising_edge;

/// Input-rate shift `Omega_i / |psi_ddot|` in timer ticks (signed), written by the cycle task,
/// read by the pick-off handler. One aligned word: no lock needed.
pub static RATE_SHIFT_TICKS: AtomicI32 = AtomicI32::new(0);
/// The pick-off's lag behind the dither in timer ticks (signed), written by the readout task
/// ([`publish_pickoff_lag`]), read by the pick-off handler. 0 until measured.
pub static PICKOFF_LAG_TICKS: AtomicI32 = AtomicI32::new(0);
/// What the compare is armed for: the next turnaround, an output latch (`super::sync`), or
/// both in turn ([`LatchPlan`]). Shared by the pick-off handler (priority 0x20), the latch
/// (0x00) and the main loop (a pause): every use is a short critical section that also writes
/// CCR1, so the plan and the register never disagree. A compare match nobody armed (the parked
/// compare coming round after 25 s without dither) is discarded. The functions here take it as
/// a [`Shared`] value: [`PlanLock`] on the board, an RTIC resource in `examples/rtic_board.rs`.
static PLAN: Mutex<RefCell<LatchPlan>> = Mutex::new(RefCell::new(LatchPlan::new()));

/// The board's latch plan ([`PLAN`]): its users include the highest-priority context, so its
/// lock is a critical section (PRIMASK; BASEPRI cannot mask priority 0x00).
pub struct PlanLock;

impl Shared for PlanLock {
    type Value = LatchPlan;

    #[inline(always)]
    fn lock<R>(&mut self, f: impl FnOnce(&mut LatchPlan) -> R) -> Option<R> {
        Some(cortex_m::interrupt::free(|cs| {
            f(&mut PLAN.borrow(cs).borrow_mut())
        }))
    }
}
/// Output latches whose pick-off conversion (ADC3 regular) had not ended when the latch was
/// read: the code is replaced by a rail code, so the record is flagged (`PICKOFF_FAULT`) and
/// invalid rather than carrying the previous latch's pick-off.
pub static PICKOFF_NOT_CONVERTED: AtomicU32 = AtomicU32::new(0);
/// Pick-off edges captured over an unread capture (TIM2 CC3OF/CC4OF: the handler was held off
/// for a whole half period): an edge was lost.
pub static PICKOFF_OVERCAPTURES: AtomicU32 = AtomicU32::new(0);
/// Latches taken (a turnaround's, an output's), wrapping: the rate monitors' counts.
pub static TURNAROUNDS_LATCHED: AtomicU32 = AtomicU32::new(0);
/// Output latches taken, wrapping.
pub static OUTPUTS_LATCHED: AtomicU32 = AtomicU32::new(0);
/// Latches nobody armed (discarded).
pub static UNARMED: AtomicU32 = AtomicU32::new(0);
/// Count latches overwritten before the handler read them (it ran a half cycle late).
pub static LATCH_OVERWRITTEN: AtomicU32 = AtomicU32::new(0);
/// Turnarounds not scheduled because the pick-off handler ran too late to arm the compare.
pub static LATE: AtomicU32 = AtomicU32::new(0);
/// Pick-off edges whose interval lay outside the plausible half-period range (a glitch or a
/// gap): the edge history was dropped.
pub static IMPLAUSIBLE: AtomicU32 = AtomicU32::new(0);
/// The dither drive is locked: written by the drive tick after every tick, copied into each
/// [`TurnaroundSample`] by the latch (a cycle latched while it is not is flagged invalid).
pub static DRIVE_LOCKED: AtomicBool = AtomicBool::new(false);
/// Set by [`pause`]: the pick-off handler forgets its edge history at its next run.
static RESTART: AtomicBool = AtomicBool::new(false);

// TIMx_CR2: MMS[6:4] = 011 compare pulse on CC1IF
const CR2_MMS_COMPARE_PULSE: u32 = 0b011 << 4;
// CCMR1 (output): CC1S = 00, OC1M[6:4] = 011 toggle (the test point), no preload
const CCMR1_OC1_TOGGLE: u32 = 0b011 << 4;
// CCMR2 (input): CC3S = 10 (IC3 on TI4), IC3F = 0011; CC4S = 01 (IC4 on TI4), IC4F = 0011
// (TI4's filter is IC4F; 95 ns as for the encoder, see there)
const CCMR2_PICKOFF: u32 = 0b10 | (0b0011 << 4) | (0b01 << 8) | (0b0011 << 12);
// CCER: CC1E 0 (PA15 output), CC3E 8 (rising), CC4E 12 + CC4P 13 (falling)
const CCER: u32 = (1 << 0) | (1 << 8) | (1 << 12) | (1 << 13);
// DIER: CC3IE 3, CC4IE 4; SR flags
const DIER_PICKOFF: u32 = (1 << 3) | (1 << 4);
const SR_CC3IF: u32 = 1 << 3;
const SR_CC4IF: u32 = 1 << 4;
// SR overcapture flags (rc_w0): CC3OF 11, CC4OF 12
const SR_CC3OF: u32 = 1 << 11;
const SR_CC4OF: u32 = 1 << 12;
// ADC_SR: EOC 1 (the regular conversion, ADC3's pick-off at an output latch)
const ADC_SR_EOC: u32 = 1 << 1;
/// Polls of ADC3's EOC before a latch's pick-off counts as not converted: each is an APB2 read
/// and a branch, at least 4 core cycles, so 64 polls last at least 1.5 us at 168 MHz, more
/// than the 1.3 us one injected conversion adds to the regular one it meets (the handler runs
/// after ADC1's JEOC, when an undelayed ADC3 conversion has ended too: one poll).
const EOC_POLLS: u32 = 64;

/// Configures TIM2 (clocks for TIM2, GPIOA, GPIOB must be on) and starts it, compare parked.
/// The pick-off interrupt is enabled in the peripheral; the NVIC line is the caller's.
pub fn init(tim: &pac::TIM2) {
    super::Port::B.alternate(11, 1); // TIM2_CH4: pick-off comparator
    super::Port::A.alternate(15, 1); // TIM2_CH1: trigger test point (JTDI; SWD does not need it)
    tim.cr1().write(|w| unsafe { w.bits(0) });
    tim.psc().write(|w| unsafe { w.bits(0) });
    tim.arr().write(|w| unsafe { w.bits(u32::MAX) });
    tim.ccmr1_output()
        .write(|w| unsafe { w.bits(CCMR1_OC1_TOGGLE) });
    tim.ccmr2_input()
        .write(|w| unsafe { w.bits(CCMR2_PICKOFF) });
    tim.ccer().write(|w| unsafe { w.bits(CCER) });
    tim.cr2()
        .write(|w| unsafe { w.bits(CR2_MMS_COMPARE_PULSE) });
    tim.cnt().write(|w| unsafe { w.bits(0) });
    park(tim, 0);
    tim.sr().write(|w| unsafe { w.bits(0) });
    tim.dier().write(|w| unsafe { w.bits(DIER_PICKOFF) });
    tim.cr1().write(|w| unsafe { w.bits(1) }); // CEN
}

/// Moves the compare half a counter period away from `now`: nothing fires for 25 s.
fn park(tim: &pac::tim2::RegisterBlock, now: u32) {
    tim.ccr1()
        .write(|w| unsafe { w.bits(now.wrapping_add(1 << 31)) });
}

/// Reads TIM2's and TIM4's counters together (inside the caller's critical section, a few
/// timer clocks apart: inside the window's margin) and re-anchors the plan's keep-out window
/// at them: TIM4 updates (and triggers ADC3's injected pick-off conversion) when its counter
/// wraps, and the window opens one conversion (27 ADC clocks = 108 ticks, plus margin) before
/// and closes one after. Never a stored phase: TIM2's wrap would move it
/// ([`crate::board_timing::phase`]). Returns TIM2's count.
fn anchor_keep_out(tim2: &pac::tim2::RegisterBlock, plan: &mut LatchPlan) -> u32 {
    // SAFETY: a read of TIM4's counter, which nobody writes after start-up.
    let tim4 = unsafe { &*pac::TIM4::ptr() };
    let t4 = tim4.cnt().read().bits();
    let t2 = tim2.cnt().read().bits();
    plan.set_keep_out(keep_out_now(
        t2,
        t4,
        BoardProfile::F405.drive_tick_period_timer_ticks(),
        DRIVE_KEEP_OUT_HALF_TICKS,
        2 * DRIVE_KEEP_OUT_HALF_TICKS,
    ));
    t2
}

/// Fewest ticks ahead a turnaround's compare may be re-armed at (after an output latch fired
/// before it): the write must land before the counter gets there (0.2 us).
const TURNAROUND_REARM_MIN_TICKS: i32 = 16;

/// Half the keep-out window around a drive tick's conversion, ticks: one conversion (27 ADC
/// clocks at 21 MHz, 108 ticks) plus the trigger latency and margin.
const DRIVE_KEEP_OUT_HALF_TICKS: u32 = 125;

/// Writes the plan's armed compare to CCR1 (inside the caller's critical section): an output
/// latch too close to `now` to be armed safely moves [`MIN_LEAD_TICKS`] on; nothing armed
/// parks the compare.
fn write_armed(tim: &pac::tim2::RegisterBlock, plan: &mut LatchPlan, arm: Arm, now: u32) {
    let mut arm = arm;
    if let Some((LatchKind::Turnaround(_), at)) = arm {
        // Armed in time when scheduled, but an output latch fired just before it and its
        // handler ran late: a compare already passed would fire 51 s later. Skipped, counted.
        if (at.wrapping_sub(now) as i32) < TURNAROUND_REARM_MIN_TICKS {
            LATE.fetch_add(1, Ordering::Relaxed);
            arm = plan.cancel_turnaround();
        }
    }
    if let Some((LatchKind::Output, at)) = arm {
        if (at.wrapping_sub(now) as i32) < MIN_LEAD_TICKS as i32 {
            arm = plan.defer_output(now.wrapping_add(MIN_LEAD_TICKS.max(OUTPUT_LEAD_TICKS)));
        }
    }
    match arm {
        Some((_, at)) => {
            tim.ccr1().write(|w| unsafe { w.bits(at) });
        }
        None => park(tim, now),
    }
}

/// The pick-off handler's prediction: the plain-logic scheduler and this board's settings;
/// implausible edges are counted in [`IMPLAUSIBLE`].
#[derive(Clone, Copy, Debug)]
pub struct Scheduler {
    config: SchedulerConfig,
    state: schedule::Scheduler,
}

impl Default for Scheduler {
    fn default() -> Self {
        Self::new()
    }
}

impl Scheduler {
    /// With this board's profile: its delays, polarity and dither range.
    pub const fn new() -> Self {
        Self {
            config: BoardProfile::F405.scheduler_config(),
            state: schedule::Scheduler::new(),
        }
    }

    /// Forgets the edge history (after a pause: the next full cycle rebuilds it).
    pub fn reset(&mut self) {
        self.state.reset();
    }

    /// One edge at `t` (ticks); `rate_shift` = Omega_i/|psi_ddot| in ticks, `pickoff_lag` the
    /// pick-off's measured lag in ticks. Returns the compare.
    #[inline(always)]
    pub fn on_edge(
        &mut self,
        edge: Edge,
        t: u32,
        rate_shift: i32,
        pickoff_lag: i32,
    ) -> Option<Schedule> {
        let outcome = self
            .state
            .on_edge(&self.config, edge, t, rate_shift, pickoff_lag);
        if outcome.implausible {
            IMPLAUSIBLE.fetch_add(1, Ordering::Relaxed);
        }
        outcome.schedule
    }
}

/// The TIM2 handler's work: the output latch's sync edge (CC2, `super::sync`) into the plan;
/// captured pick-off edges in time order -> the turnaround's compare.
/// About 55 instructions for one edge (`examples/board_cost.rs`); no floating point, no
/// division.
#[inline(always)]
pub fn on_pickoff_interrupt(
    tim: &pac::tim2::RegisterBlock,
    scheduler: &mut Scheduler,
    plan: &mut impl Shared<Value = LatchPlan>,
) {
    let sr = tim.sr().read().bits();
    if sr & (SR_CC3OF | SR_CC4OF) != 0 {
        // An edge captured over an unread one: lost (the scheduler sees the gap).
        tim.sr()
            .write(|w| unsafe { w.bits(!(sr & (SR_CC3OF | SR_CC4OF))) });
        PICKOFF_OVERCAPTURES.fetch_add(1, Ordering::Relaxed);
    }
    // The output latch's sync edge (or internal period), if CC2 fired.
    if let Some(edge) = super::sync::take_edge(tim, sr) {
        plan.lock(|plan| {
            let now = anchor_keep_out(tim, plan);
            let arm = plan.on_sync(edge, now);
            write_armed(tim, plan, arm, now);
        });
    }
    // Reading CCR3/CCR4 clears CC3IF/CC4IF.
    let rise = (sr & SR_CC3IF != 0).then(|| (Edge::Rising, tim.ccr3().read().bits()));
    let fall = (sr & SR_CC4IF != 0).then(|| (Edge::Falling, tim.ccr4().read().bits()));
    let now = tim.cnt().read().bits();
    // Both pending only if this handler was held off for half a dither period: oldest first.
    let mut edges = [rise, fall];
    if let [Some((_, a)), Some((_, b))] = edges {
        if now.wrapping_sub(a) < now.wrapping_sub(b) {
            edges.swap(0, 1);
        }
    }
    if RESTART.swap(false, Ordering::Relaxed) {
        scheduler.reset();
    }
    let shift = RATE_SHIFT_TICKS.load(Ordering::Relaxed);
    let lag = PICKOFF_LAG_TICKS.load(Ordering::Relaxed);
    for (edge, t) in edges.into_iter().flatten() {
        let Some(s) = scheduler.on_edge(edge, t, shift, lag) else {
            continue;
        };
        if !arm(tim, s, now, plan) {
            LATE.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Arms the compare for `schedule` if it lies at least [`MIN_LEAD_TICKS`] after `now`; else
/// parks it and returns false (that turnaround is skipped: the readout sees a gap).
pub fn arm(
    tim: &pac::tim2::RegisterBlock,
    schedule: Schedule,
    now: u32,
    plan: &mut impl Shared<Value = LatchPlan>,
) -> bool {
    let in_time = schedule.compare_ticks.wrapping_sub(now) as i32 >= MIN_LEAD_TICKS as i32;
    plan.lock(|plan| {
        let now = anchor_keep_out(tim, plan);
        let arm = if in_time {
            plan.on_turnaround(schedule.kind, schedule.compare_ticks)
        } else {
            plan.cancel_turnaround()
        };
        write_armed(tim, plan, arm, now);
    });
    in_time
}

/// What the latch took.
pub enum Latched {
    /// A turnaround (to the cycle assembly).
    Turnaround(TurnaroundSample),
    /// An output latch (the end of an output period).
    Output(OutputSample),
}

/// The JEOC handler's work (ADC IRQ, highest priority): copy the latched registers, then arm
/// the next compare the plan holds (an output latch waiting behind this turnaround, or the
/// turnaround behind this output latch). Nothing here is time-critical (the data registers
/// hold until the next trigger). `None` for a compare match nobody armed.
#[inline(always)]
pub fn latch(
    adc1: &pac::adc1::RegisterBlock,
    adc2: &pac::adc1::RegisterBlock,
    adc3: &pac::adc1::RegisterBlock,
    tim2: &pac::tim2::RegisterBlock,
    tim5: &pac::tim5::RegisterBlock,
    plan: &mut impl Shared<Value = LatchPlan>,
) -> Option<Latched> {
    super::adc::clear_jeoc(adc1);
    let (encoder_count, overwritten) = super::encoder::take_latched(tim5);
    if overwritten {
        LATCH_OVERWRITTEN.fetch_add(1, Ordering::Relaxed);
    }
    // Read before the compare is re-armed.
    let fired_at = tim2.ccr1().read().bits();
    // ADC3's regular group converts the pick-off at every latch: taken at every latch (so an
    // EOC left over can never pass for the next latch's), used by output latches.
    let pickoff = take_pickoff_conversion(adc3);
    let fired = plan
        .lock(|plan| {
            let now = anchor_keep_out(tim2, plan);
            let (fired, next) = plan.on_fired();
            write_armed(tim2, plan, next, now);
            fired
        })
        .flatten();
    let adc_a_code = AdcCode::from_register(adc1.jdr1().read().bits());
    let adc_b_code = AdcCode::from_register(adc2.jdr1().read().bits());
    let timestamp_ticks = fired_at.wrapping_add(APERTURE_DELAY_TICKS);
    let drive_locked = DRIVE_LOCKED.load(Ordering::Relaxed);
    match fired {
        Some(LatchKind::Turnaround(kind)) => {
            TURNAROUNDS_LATCHED.fetch_add(1, Ordering::Relaxed);
            Some(Latched::Turnaround(TurnaroundSample {
                kind,
                encoder_count,
                adc_a_code,
                adc_b_code,
                timestamp_ticks,
                drive_locked,
            }))
        }
        Some(LatchKind::Output) => {
            OUTPUTS_LATCHED.fetch_add(1, Ordering::Relaxed);
            // Not converted in time: a rail code (0), which the readout flags as a pick-off
            // fault (the record invalid), never the previous latch's code.
            let pickoff_code = pickoff.unwrap_or_else(|| {
                PICKOFF_NOT_CONVERTED.fetch_add(1, Ordering::Relaxed);
                AdcCode::ZERO
            });
            Some(Latched::Output(OutputSample {
                encoder_count,
                adc_a_code,
                adc_b_code,
                pickoff_code,
                timestamp_ticks,
                drive_locked,
            }))
        }
        None => {
            UNARMED.fetch_add(1, Ordering::Relaxed);
            None
        }
    }
}

/// ADC3's regular result, the pick-off at this latch, once its EOC says it is this latch's:
/// an injected drive-tick conversion that met it delays it by up to one conversion (RM0090
/// 13.3.9: the injected group interrupts the regular one, which restarts), so EOC is polled
/// for that long; `None` if it has not ended by then. Reading DR clears EOC.
#[inline(always)]
fn take_pickoff_conversion(adc3: &pac::adc1::RegisterBlock) -> Option<AdcCode> {
    (0..EOC_POLLS)
        .any(|_| adc3.sr().read().bits() & ADC_SR_EOC != 0)
        .then(|| AdcCode::from_register(adc3.dr().read().bits()))
}

/// Sync edges dropped because an output latch was still pending (the plan's overruns).
pub fn sync_overruns(plan: &mut impl Shared<Value = LatchPlan>) -> u32 {
    plan.lock(|plan| plan.overruns).unwrap_or(0)
}

/// Publishes the input-rate shift of the next turnarounds from one cycle (the cycle task, after
/// each record; docs/physics.md pitfall 3).
pub fn publish_rate_shift(record: &CycleRecord) {
    let shift = crate::signal::output::rate_shift_ticks(record, super::TIMER_HZ);
    RATE_SHIFT_TICKS.store(shift, Ordering::Relaxed);
}

/// Publishes the pick-off's lag behind the dither as the output stage measures it (the
/// readout task, after an output latch with a converged stripping:
/// `Readout::pickoff_lag_ticks`). The last value stays while the stripping learns anew.
pub fn publish_pickoff_lag(lag_ticks: i32) {
    PICKOFF_LAG_TICKS.store(lag_ticks, Ordering::Relaxed);
}

/// Input-rate shift in ticks of this board's timer for a rate (rad/s of beat phase) and a
/// measured dither ([`schedule::shift_ticks_for_rate`]).
pub fn rate_shift_ticks(rate_rad_per_s: f32, amplitude_rad: f32, dither_hz: f32) -> i32 {
    schedule::shift_ticks_for_rate(rate_rad_per_s, amplitude_rad, dither_hz, super::TIMER_HZ)
}

/// The readout pauses (TIM2's interrupt is masked by the caller): park the compare, drop
/// pending captures, and make the handler forget its edge history when it runs again.
pub fn pause(tim: &pac::tim2::RegisterBlock, plan: &mut impl Shared<Value = LatchPlan>) {
    plan.lock(|plan| {
        let overruns = plan.overruns;
        *plan = LatchPlan::new();
        plan.overruns = overruns;
    });
    park(tim, tim.cnt().read().bits());
    tim.sr().write(|w| unsafe { w.bits(0) });
    RESTART.store(true, Ordering::Relaxed);
}
