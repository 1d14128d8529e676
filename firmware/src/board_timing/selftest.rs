//! The power-up self-test's verdicts: plain functions from what the board measured (register
//! flags, counter advances, trigger flags) to a pass or a named failure, so the board and the
//! simulated board judge alike and the judgement is tested here.
//!
//! | check | what is measured (`board::selftest`) | fails with |
//! |---|---|---|
//! | `clock` | RCC: HSE ready, PLL locked, SYSCLK switched to the PLL | `hse` (the crystal did not start: HSI, 1 %), `pll`, `sysclk` |
//! | `timers` | TIM2, TIM3, TIM4 counters advance over 20 us | the first that stands still: `tim2`, `tim3`, `tim4` |
//! | `timer_clock` | their advance against the core's cycles (SysTick): 84 MHz against 168 MHz, 1/2 within 3 % | the first off: `tim2`, `tim3`, `tim4` (an APB1 prescaler wrong) |
//! | `triggers` | one TIM2 compare, TIM4 updates, TIM3 updates: the flags they must set | the first missing: `adc1_injected`, `adc2_injected`, `encoder_latch`, `adc3_regular`, `adc3_injected`, `dac`, `lissajous_dma` |
//! | `pickoff` | the half-drive sweep (`crate::dither`'s self-test) | `rail`, `flat`, `no_response` |
//!
//! The first four run before any interrupt is unmasked; if one fails the drive is inhibited
//! and the pick-off check is not run. QEMU models none of the clock tree, the triggers or the
//! DAC, and runs its timers at 1 GHz: there `clock`, `timer_clock` and `triggers` fail and
//! `pickoff` is not run ([`QEMU_UNMODELLED`]); `timers` passes.

use crate::dither::PickoffCheck;

/// The self-test's checks, in the order they run and are reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Check {
    /// The clock tree.
    Clock,
    /// Every timer counts.
    Timers,
    /// The timers count at 84 MHz.
    TimerClock,
    /// Every ADC and DAC trigger fires.
    Triggers,
    /// The pick-off answers the drive.
    Pickoff,
}

impl Check {
    /// Every check, in order.
    pub const ALL: [Self; 5] = [
        Self::Clock,
        Self::Timers,
        Self::TimerClock,
        Self::Triggers,
        Self::Pickoff,
    ];

    /// The check's name.
    pub const fn word(self) -> &'static str {
        match self {
            Self::Clock => "clock",
            Self::Timers => "timers",
            Self::TimerClock => "timer_clock",
            Self::Triggers => "triggers",
            Self::Pickoff => "pickoff",
        }
    }
}

/// The checks QEMU's `netduinoplus2` cannot pass (it models no RCC, no trigger routing, no
/// DAC, and counts its timers at 1 GHz); the pick-off check is then not run either.
pub const QEMU_UNMODELLED: [Check; 4] = [
    Check::Clock,
    Check::TimerClock,
    Check::Triggers,
    Check::Pickoff,
];

/// One check's outcome.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Outcome {
    /// Not run (an earlier check failed, or no board).
    NotRun,
    /// Under way.
    Running,
    /// Passed.
    Pass,
    /// Failed: what was wrong, one word.
    Fail(&'static str),
}

/// The self-test's outcomes, in [`Check::ALL`]'s order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SelfTestReport(pub [Outcome; 5]);

impl Default for SelfTestReport {
    fn default() -> Self {
        Self::NOT_RUN
    }
}

impl SelfTestReport {
    /// Nothing run (a build without the board: the QEMU serial example, the fuzzer).
    pub const NOT_RUN: Self = Self([Outcome::NotRun; 5]);

    /// The outcome of `check`.
    pub fn outcome(&self, check: Check) -> Outcome {
        self.0
            .get(check as usize)
            .copied()
            .unwrap_or(Outcome::NotRun)
    }

    /// Sets the outcome of `check`.
    pub fn set(&mut self, check: Check, outcome: Outcome) {
        if let Some(o) = self.0.get_mut(check as usize) {
            *o = outcome;
        }
    }

    /// The clock, timer and trigger checks all passed: the drive may start its pick-off check.
    pub fn hardware_passed(&self) -> bool {
        Check::ALL
            .into_iter()
            .filter(|&c| c != Check::Pickoff)
            .all(|c| self.outcome(c) == Outcome::Pass)
    }

    /// The first failed check and its reason.
    pub fn first_failure(&self) -> Option<(Check, &'static str)> {
        Check::ALL.into_iter().find_map(|c| match self.outcome(c) {
            Outcome::Fail(why) => Some((c, why)),
            _ => None,
        })
    }

    /// With the pick-off check's outcome (the dither controller's).
    pub fn with_pickoff(mut self, check: PickoffCheck) -> Self {
        let outcome = match check {
            PickoffCheck::NotRun => Outcome::NotRun,
            PickoffCheck::Running => Outcome::Running,
            PickoffCheck::Pass => Outcome::Pass,
            PickoffCheck::Fail(why) => Outcome::Fail(why.word()),
        };
        self.set(Check::Pickoff, outcome);
        self
    }
}

/// The clock tree's state after the start-up (RCC_CR, RCC_CFGR).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockFlags {
    /// HSERDY: the 8 MHz crystal oscillates.
    pub hse_ready: bool,
    /// PLLRDY: the PLL is locked.
    pub pll_locked: bool,
    /// SWS = PLL: SYSCLK comes from the PLL (168 MHz).
    pub sysclk_from_pll: bool,
}

/// `clock`: crystal, PLL, SYSCLK source, in that order.
pub fn check_clock(flags: ClockFlags) -> Outcome {
    if !flags.hse_ready {
        Outcome::Fail("hse")
    } else if !flags.pll_locked {
        Outcome::Fail("pll")
    } else if !flags.sysclk_from_pll {
        Outcome::Fail("sysclk")
    } else {
        Outcome::Pass
    }
}

/// The three timers' advances over one interval of `core_cycles` core clock cycles, ticks
/// (each below its own period: the counters of TIM3 and TIM4 reload).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimerAdvance {
    /// Core clock cycles of the interval (SysTick).
    pub core_cycles: u32,
    /// TIM2, TIM3, TIM4 ticks over it.
    pub ticks: [u32; 3],
}

const TIMER_NAMES: [&str; 3] = ["tim2", "tim3", "tim4"];

/// Relative tolerance of a timer's ticks against half the core cycles: the counters are read
/// a few bus cycles apart from SysTick (tens of ticks in the 1680 of 20 us).
pub const TIMER_CLOCK_TOLERANCE: f32 = 0.03;

/// `timers`: every counter moved.
pub fn check_timers(advance: TimerAdvance) -> Outcome {
    match advance.ticks.iter().position(|&t| t == 0) {
        Some(i) => Outcome::Fail(TIMER_NAMES.get(i).copied().unwrap_or("timer")),
        None => Outcome::Pass,
    }
}

/// `timer_clock`: every counter at `timer_hz` against a core at `core_hz` (84 and 168 MHz),
/// within [`TIMER_CLOCK_TOLERANCE`].
pub fn check_timer_clock(advance: TimerAdvance, timer_hz: u32, core_hz: u32) -> Outcome {
    let expected = advance.core_cycles as f32 * timer_hz as f32 / core_hz as f32;
    let off = |t: u32| (t as f32 - expected).abs() > TIMER_CLOCK_TOLERANCE * expected;
    match advance.ticks.iter().position(|&t| off(t)) {
        Some(i) => Outcome::Fail(TIMER_NAMES.get(i).copied().unwrap_or("timer")),
        None => Outcome::Pass,
    }
}

/// The flags the triggers must have set (each true if it fired).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TriggerFlags {
    /// TIM2's compare pulse (TRGO) started ADC1's injected conversion (JEOC).
    pub adc1_injected: bool,
    /// ... and ADC2's, its dual-mode slave.
    pub adc2_injected: bool,
    /// ... and TIM5 captured the count on it (CC3IF: capture on TRC in encoder mode).
    pub encoder_latch: bool,
    /// ... and ADC3's regular conversion of the pick-off (EOC).
    pub adc3_regular: bool,
    /// TIM4's update (TRGO) started ADC3's injected conversion (JEOC).
    pub adc3_injected: bool,
    /// ... and loaded the DAC's holding register into its output register (DOR).
    pub dac: bool,
    /// TIM3's update started the photodiode pairs, and the DMA moved them (NDTR fell).
    pub lissajous_dma: bool,
}

/// `triggers`: the first that did not fire.
pub fn check_triggers(t: TriggerFlags) -> Outcome {
    let named = [
        (t.adc1_injected, "adc1_injected"),
        (t.adc2_injected, "adc2_injected"),
        (t.encoder_latch, "encoder_latch"),
        (t.adc3_regular, "adc3_regular"),
        (t.adc3_injected, "adc3_injected"),
        (t.dac, "dac"),
        (t.lissajous_dma, "lissajous_dma"),
    ];
    match named.into_iter().find(|&(fired, _)| !fired) {
        Some((_, name)) => Outcome::Fail(name),
        None => Outcome::Pass,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dither::PickoffFailure;

    const GOOD_CLOCK: ClockFlags = ClockFlags {
        hse_ready: true,
        pll_locked: true,
        sysclk_from_pll: true,
    };
    const ALL_FIRED: TriggerFlags = TriggerFlags {
        adc1_injected: true,
        adc2_injected: true,
        encoder_latch: true,
        adc3_regular: true,
        adc3_injected: true,
        dac: true,
        lissajous_dma: true,
    };

    #[test]
    fn the_clock_check_names_the_first_fault() {
        assert_eq!(check_clock(GOOD_CLOCK), Outcome::Pass);
        let no_hse = ClockFlags {
            hse_ready: false,
            ..GOOD_CLOCK
        };
        assert_eq!(check_clock(no_hse), Outcome::Fail("hse"));
        // A PLL that never locked leaves SYSCLK on HSI: both wrong, the PLL named.
        let no_pll = ClockFlags {
            pll_locked: false,
            sysclk_from_pll: false,
            ..GOOD_CLOCK
        };
        assert_eq!(check_clock(no_pll), Outcome::Fail("pll"));
        let not_switched = ClockFlags {
            sysclk_from_pll: false,
            ..GOOD_CLOCK
        };
        assert_eq!(check_clock(not_switched), Outcome::Fail("sysclk"));
        // QEMU: RCC reads 0.
        let qemu = ClockFlags {
            hse_ready: false,
            pll_locked: false,
            sysclk_from_pll: false,
        };
        assert_eq!(check_clock(qemu), Outcome::Fail("hse"));
    }

    /// 20 us at 168 MHz: 3360 core cycles, 1680 timer ticks. A stopped timer, a timer at
    /// twice or half the clock (a wrong APB1 prescaler), QEMU's 1 GHz: each named.
    #[test]
    fn the_timer_checks_name_the_stopped_or_wrong_timer() {
        let good = TimerAdvance {
            core_cycles: 3360,
            ticks: [1680, 1690, 1672],
        };
        assert_eq!(check_timers(good), Outcome::Pass);
        assert_eq!(
            check_timer_clock(good, 84_000_000, 168_000_000),
            Outcome::Pass
        );
        let stopped = TimerAdvance {
            ticks: [1680, 0, 1680],
            ..good
        };
        assert_eq!(check_timers(stopped), Outcome::Fail("tim3"));
        for wrong in [840, 3360, 1680 * 1000 / 168 * 1000 / 1000] {
            let a = TimerAdvance {
                ticks: [1680, 1680, wrong],
                ..good
            };
            assert_eq!(check_timers(a), Outcome::Pass);
            assert_eq!(
                check_timer_clock(a, 84_000_000, 168_000_000),
                Outcome::Fail("tim4"),
                "{wrong}"
            );
        }
        // The tolerance: 2.9 % passes, 3.1 % fails.
        let at = |t: u32| TimerAdvance {
            ticks: [t, 1680, 1680],
            ..good
        };
        assert_eq!(
            check_timer_clock(at(1729), 84_000_000, 168_000_000),
            Outcome::Pass
        );
        assert_eq!(
            check_timer_clock(at(1733), 84_000_000, 168_000_000),
            Outcome::Fail("tim2")
        );
    }

    #[test]
    fn the_trigger_check_names_the_first_missing_trigger() {
        assert_eq!(check_triggers(ALL_FIRED), Outcome::Pass);
        let no_latch = TriggerFlags {
            encoder_latch: false,
            dac: false,
            ..ALL_FIRED
        };
        assert_eq!(check_triggers(no_latch), Outcome::Fail("encoder_latch"));
        let no_dma = TriggerFlags {
            lissajous_dma: false,
            ..ALL_FIRED
        };
        assert_eq!(check_triggers(no_dma), Outcome::Fail("lissajous_dma"));
    }

    #[test]
    fn the_report_gates_the_drive_and_names_the_first_failure() {
        let mut r = SelfTestReport::NOT_RUN;
        assert!(!r.hardware_passed());
        for c in [
            Check::Clock,
            Check::Timers,
            Check::TimerClock,
            Check::Triggers,
        ] {
            r.set(c, Outcome::Pass);
        }
        assert!(r.hardware_passed());
        assert_eq!(r.first_failure(), None);
        let r = r.with_pickoff(PickoffCheck::Fail(PickoffFailure::NoResponse));
        assert_eq!(r.first_failure(), Some((Check::Pickoff, "no_response")));
        assert!(r.hardware_passed());
        let mut r = r;
        r.set(Check::Triggers, Outcome::Fail("dac"));
        assert!(!r.hardware_passed());
        assert_eq!(r.first_failure(), Some((Check::Triggers, "dac")));
    }
}
