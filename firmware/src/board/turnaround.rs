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
//! # Prediction (PHYSICS.md pitfalls 2 and 3)
//! A turnaround lies a quarter period after a zero crossing of the dither angle. A comparator
//! threshold offset makes rising crossings late and falling ones early by the same amount (or
//! the reverse), so "crossing + T/4" would be off by that amount with alternating sign. Half the
//! previous interval of the same polarity cancels it exactly: after a rising edge at t_r,
//! `t_r + high/2` (high = previous rising-to-falling interval) is the midpoint of that pulse, i.e.
//! the angle maximum, whatever the threshold. Only a slowly varying dither is assumed (a high-Q
//! resonator: period and amplitude change little in one cycle).
//!
//! The input rate moves the turnaround (pitfall 3): the lock-in-free rate Omega_i + psi_ddot (t -
//! t_p) is zero at `t_p - Omega_i/psi_ddot` for a "+" turnaround and `t_p + Omega_i/|psi_ddot|`
//! for a "-" one. The readout task computes `Omega_i/|psi_ddot|` in timer ticks from each cycle's
//! rate and measured dither and publishes it through [`RATE_SHIFT_TICKS`] (an atomic word); at
//! 1 deg/s of input it is 1.3 us, at Earth rate 6 ns.
//!
//! Fixed delays subtracted (constants, to be calibrated on a board with the PA15 test point):
//! the pick-off path ([`PICKOFF_DELAY_TICKS`]: comparator, 95 ns input filter, resynchronisation)
//! and the ADC aperture ([`APERTURE_DELAY_TICKS`]: injected trigger latency 2-3 ADC clocks plus
//! the 15-clock sampling time; the hold happens at the end of sampling, so the compare fires that
//! much early and the *sampling* instant lands on the turnaround). The encoder latch then comes
//! ~0.85 us before the turnaround: at psi_ddot ~ 9e9 rad/s^2 the beat phase differs by
//! 9e9 x (0.85e-6)^2 / 2 = 3e-3 rad between the two instants, far inside the quarter fringe the
//! count-plus-fraction resolver tolerates.
//!
//! # Expected timing error (to be measured on the board)
//! | source | size |
//! |---|---|
//! | timer resolution (84 MHz) | +-6 ns |
//! | input filter + resynchronisation, pick-off edge | 95 ns fixed, +-12 ns jitter |
//! | injected trigger latency (2-3 ADC clocks at 21 MHz) | 119 ns mean, +-24 ns jitter |
//! | comparator noise at the zero crossing (sigma_v / slope) | ~10-50 ns (pick-off noise) |
//! | dither period change within one cycle (high-Q resonator) | < 10 ns |
//! | pick-off phase lag vs the true angle, comparator delay | fixed: calibrate once |
//! | rate shift taken from the previous cycle | (rate change per cycle) / psi_ddot: 0 for a steady rate |
//!
//! So about +-0.1 us random error once the fixed terms are calibrated, against the ~1 us
//! PHYSICS.md asks for; an uncalibrated fixed term of 0.5 us costs psi_ddot dt^2/2 ~ 1e-3 rad.

use core::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicU8, Ordering};

use super::pac;
use crate::sample::{TurnaroundKind, TurnaroundSample};

/// Pick-off comparator delay + input filter + resynchronisation, ticks (84 MHz). Nominal: 100 ns
/// comparator, 95 ns filter, 2 clocks. Calibrate on the board.
pub const PICKOFF_DELAY_TICKS: u32 = 18;
/// Compare match to the end of the ADC sampling window, ticks: (2.5 + 15) ADC clocks at 21 MHz
/// = 0.83 us = 70 ticks. The sample's timestamp is `CCR1 + APERTURE_DELAY_TICKS`.
pub const APERTURE_DELAY_TICKS: u32 = 70;
/// The compare must be armed at least this far ahead (2 us), else the turnaround is skipped
/// (counted in [`LATE`]) rather than fired 51 s later, after the counter wraps.
const MIN_LEAD_TICKS: u32 = 168;
/// Which turnaround follows a rising pick-off edge (angle increasing through zero: the next
/// extremum is a maximum, the rate goes from + to -). A pick-off wired with the other polarity
/// flips it: PHYSICS.md pitfall 4, check against the simulator's sign pattern on the board.
pub const AFTER_RISING_EDGE: TurnaroundKind = TurnaroundKind::Minus;

/// Input-rate shift `Omega_i / |psi_ddot|` in timer ticks (signed), written by the cycle task,
/// read by the pick-off handler. One aligned word: no lock needed.
pub static RATE_SHIFT_TICKS: AtomicI32 = AtomicI32::new(0);
/// Kind of the turnaround whose compare is armed (0 = Plus, 1 = Minus), written before CCR1;
/// `NOT_ARMED` once the latch has taken it, or while the compare is parked. A compare match
/// nobody armed (the parked compare coming round after 25 s without dither) is discarded.
static ARMED_KIND: AtomicU8 = AtomicU8::new(NOT_ARMED);
const NOT_ARMED: u8 = 0xFF;
/// Latches nobody armed (discarded).
pub static UNARMED: AtomicU32 = AtomicU32::new(0);
/// Count latches overwritten before the handler read them (it ran a half cycle late).
pub static LATCH_OVERWRITTEN: AtomicU32 = AtomicU32::new(0);
/// Turnarounds not scheduled: the pick-off handler ran too late, or the interval was implausible.
pub static LATE: AtomicU32 = AtomicU32::new(0);
pub static IMPLAUSIBLE: AtomicU32 = AtomicU32::new(0);
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
    ARMED_KIND.store(NOT_ARMED, Ordering::Relaxed);
    tim.ccr1()
        .write(|w| unsafe { w.bits(now.wrapping_add(1 << 31)) });
}

/// A pick-off edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    Rising,
    Falling,
}

/// Where and which turnaround to fire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Schedule {
    pub compare_ticks: u32,
    pub kind: TurnaroundKind,
}

/// The prediction (plain logic: edges and a rate shift in, a compare time out).
#[derive(Clone, Copy, Debug)]
pub struct Scheduler {
    last: Option<(Edge, u32)>,
    /// Previous rising-to-falling and falling-to-rising intervals, ticks.
    high_ticks: Option<u32>,
    low_ticks: Option<u32>,
    /// Plausible half period, ticks.
    min_half_ticks: u32,
    max_half_ticks: u32,
}

impl Scheduler {
    /// For a dither between `min_hz` and `max_hz`.
    pub const fn new(timer_hz: u32, min_hz: u32, max_hz: u32) -> Self {
        Self {
            last: None,
            high_ticks: None,
            low_ticks: None,
            // Half periods, with room for a pick-off duty cycle of 30/70.
            min_half_ticks: timer_hz / max_hz * 3 / 10,
            max_half_ticks: timer_hz / min_hz * 7 / 10,
        }
    }

    /// Forgets the edge history (after a pause: the next full cycle rebuilds it).
    pub fn reset(&mut self) {
        *self = Self::new_like(self);
    }

    const fn new_like(s: &Self) -> Self {
        Self {
            last: None,
            high_ticks: None,
            low_ticks: None,
            min_half_ticks: s.min_half_ticks,
            max_half_ticks: s.max_half_ticks,
        }
    }

    /// One edge at `t` (ticks); `rate_shift` = Omega_i/|psi_ddot| in ticks. Returns the compare.
    pub fn on_edge(&mut self, edge: Edge, t: u32, rate_shift: i32) -> Option<Schedule> {
        if let Some((previous, t0)) = self.last {
            let interval = t.wrapping_sub(t0);
            let plausible = (self.min_half_ticks..=self.max_half_ticks).contains(&interval);
            match (previous, edge) {
                _ if !plausible => {
                    // A glitch or a gap: neither this edge nor the history can be trusted.
                    IMPLAUSIBLE.fetch_add(1, Ordering::Relaxed);
                    (self.high_ticks, self.low_ticks) = (None, None);
                }
                (Edge::Rising, Edge::Falling) => self.high_ticks = Some(interval),
                (Edge::Falling, Edge::Rising) => self.low_ticks = Some(interval),
                // Two edges of one polarity: a lost edge; start over.
                _ => (self.high_ticks, self.low_ticks) = (None, None),
            }
        }
        self.last = Some((edge, t));
        let (half_same_polarity, kind) = match edge {
            Edge::Rising => (self.high_ticks?, AFTER_RISING_EDGE),
            Edge::Falling => (self.low_ticks?, opposite(AFTER_RISING_EDGE)),
        };
        let shift = match kind {
            TurnaroundKind::Plus => -rate_shift,
            TurnaroundKind::Minus => rate_shift,
        };
        let quarter = (half_same_polarity / 2) as i32;
        let lead = quarter + shift - (PICKOFF_DELAY_TICKS + APERTURE_DELAY_TICKS) as i32;
        Some(Schedule {
            compare_ticks: t.wrapping_add_signed(lead),
            kind,
        })
    }
}

fn opposite(kind: TurnaroundKind) -> TurnaroundKind {
    match kind {
        TurnaroundKind::Plus => TurnaroundKind::Minus,
        TurnaroundKind::Minus => TurnaroundKind::Plus,
    }
}

/// The pick-off handler's work (TIM2 IRQ): captured edges in time order -> compare armed.
/// About 55 instructions for one edge (`examples/board_cost.rs`); no floating point, no
/// division.
#[inline(always)]
pub fn on_pickoff_interrupt(tim: &pac::tim2::RegisterBlock, scheduler: &mut Scheduler) {
    let sr = tim.sr().read().bits();
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
    for (edge, t) in edges.into_iter().flatten() {
        let Some(s) = scheduler.on_edge(edge, t, shift) else {
            continue;
        };
        if !arm(tim, s, now) {
            LATE.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Arms the compare for `schedule` if it lies at least [`MIN_LEAD_TICKS`] after `now`; else
/// parks it and returns false (that turnaround is skipped: the readout sees a gap).
pub fn arm(tim: &pac::tim2::RegisterBlock, schedule: Schedule, now: u32) -> bool {
    if schedule.compare_ticks.wrapping_sub(now) as i32 >= MIN_LEAD_TICKS as i32 {
        ARMED_KIND.store(schedule.kind as u8, Ordering::Relaxed);
        tim.ccr1()
            .write(|w| unsafe { w.bits(schedule.compare_ticks) });
        true
    } else {
        park(tim, now);
        false
    }
}

/// The JEOC handler's work (ADC IRQ, highest priority): copy the four latched registers.
/// Nothing here is time-critical any more (the data registers hold until the next trigger,
/// ~1.3 ms later at 389 Hz). `None` for a compare match nobody armed.
#[inline(always)]
pub fn latch(
    adc1: &pac::adc1::RegisterBlock,
    adc2: &pac::adc1::RegisterBlock,
    tim2: &pac::tim2::RegisterBlock,
    tim5: &pac::tim5::RegisterBlock,
) -> Option<TurnaroundSample> {
    super::adc::clear_jeoc(adc1);
    let (encoder_count, overwritten) = super::encoder::take_latched(tim5);
    if overwritten {
        LATCH_OVERWRITTEN.fetch_add(1, Ordering::Relaxed);
    }
    let kind = match ARMED_KIND.swap(NOT_ARMED, Ordering::Relaxed) {
        k if k == TurnaroundKind::Plus as u8 => TurnaroundKind::Plus,
        k if k == TurnaroundKind::Minus as u8 => TurnaroundKind::Minus,
        _ => {
            UNARMED.fetch_add(1, Ordering::Relaxed);
            return None;
        }
    };
    Some(TurnaroundSample {
        kind,
        encoder_count,
        adc_a_code: adc1.jdr1().read().bits() as u16,
        adc_b_code: adc2.jdr1().read().bits() as u16,
        timestamp_ticks: tim2.ccr1().read().bits().wrapping_add(APERTURE_DELAY_TICKS),
    })
}

/// Input-rate shift in ticks from one cycle's measurements: `Omega_i / |psi_ddot|` with
/// `psi_ddot = amplitude * (2 pi f)^2` (PHYSICS.md). Clamped to +-T/16: beyond that the
/// parabolic turnaround model no longer holds anyway.
pub fn rate_shift_ticks(rate_rad_per_s: f32, amplitude_rad: f32, dither_hz: f32) -> i32 {
    let w = core::f32::consts::TAU * dither_hz;
    let psi_ddot = amplitude_rad * w * w;
    if !(psi_ddot.is_finite() && psi_ddot > 0.0 && rate_rad_per_s.is_finite() && dither_hz > 0.0) {
        return 0;
    }
    let limit = super::TIMER_HZ as f32 / dither_hz / 16.0;
    let ticks = rate_rad_per_s / psi_ddot * super::TIMER_HZ as f32;
    ticks.clamp(-limit, limit) as i32
}

/// The readout pauses (TIM2's interrupt is masked by the caller): park the compare, drop
/// pending captures, and make the handler forget its edge history when it runs again.
pub fn pause(tim: &pac::tim2::RegisterBlock) {
    park(tim, tim.cnt().read().bits());
    tim.sr().write(|w| unsafe { w.bits(0) });
    RESTART.store(true, Ordering::Relaxed);
}
