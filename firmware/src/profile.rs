//! The board profile: the facts of one readout board that the firmware, the simulated board and
//! the host tools share, defined once.
//!
//! A profile is what would change if the same firmware ran on another board or read another
//! gyro: the capture-timer clock, the encoder register's width, the fixed delays of the
//! turnaround path, the dither frequencies the scheduler accepts, and the nominal gyro the board
//! is built for. `board/` (the MCU) reads [`BoardProfile::F405`]; hal-sim's simulated board
//! reads the same constant, so a timing or width change is made here and nowhere else.
//!
//! The delays are nominal values from the data sheets (see `board::turnaround`); they are to be
//! calibrated on a real board with the PA15 test point and then changed here.

use crate::readout::ReadoutConfig;
use crate::sample::{AdcCode, TurnaroundKind};
use crate::signal::count::CounterWidth;
use crate::signal::output::dither_model::DitherModelConfig;
use crate::signal::output::record::OutputConfig;
use crate::signal::output::strip::StripConfig;
use crate::signal::turnaround::SchedulerConfig;

/// The facts of one readout board (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardProfile {
    /// Board name, as `id` reports it.
    pub name: &'static str,
    /// Kernel clock of the capture timer (TIM2) and the encoder timer (TIM5), Hz: the unit of
    /// every turnaround timestamp.
    pub timer_hz: u32,
    /// Core clock (SYSCLK, HCLK), Hz: the self-test's reference for `timer_hz`, the delays
    /// counted in core cycles, the 1 ms tick.
    pub core_clock_hz: u32,
    /// Width of the encoder timer's count register.
    pub counter_width: CounterWidth,
    /// Pick-off comparator + input filter + resynchronisation: edge to capture, timer ticks.
    pub pickoff_delay_ticks: u32,
    /// Compare match to the end of the ADC sampling window, timer ticks (the sampling instant
    /// of a turnaround is its compare instant plus this).
    pub aperture_delay_ticks: u32,
    /// Which turnaround follows a rising pick-off edge (the pick-off's polarity).
    pub after_rising_edge: TurnaroundKind,
    /// Dither frequencies the turnaround scheduler accepts, Hz (inclusive).
    pub dither_hz_range: (u32, u32),
    /// The dither frequency of the gyro this board is built for, Hz (the cycle assembler accepts
    /// +-20 % around it; the rate output averages over one second of it).
    pub nominal_dither_hz: f64,
    /// Scale factor of that gyro, arcsec per fringe (only the rate output in deg/h uses it).
    pub scale_factor_arcsec: f64,
    /// Peak dither amplitude of that gyro, arcsec of body angle: the drive's default setpoint.
    pub nominal_dither_amplitude_arcsec: f64,
    /// Tick rate of the dither drive, Hz: the rate at which the DAC takes a new drive sample and
    /// the ADC samples the pick-off (one timer update, `board::dither`). Divides [`Self::timer_hz`]
    /// exactly ([`Self::drive_tick_period_timer_ticks`]); `crate::dither` justifies the value.
    pub drive_tick_hz: u32,
    /// Pick-off sensitivity: dither angle per pick-off ADC code, arcsec per code (the pick-off
    /// amplifier's gain into the 12-bit ADC; nominal, to be calibrated against the fringe count).
    pub pickoff_arcsec_per_code: f64,
    /// The pick-off ADC code of a zero dither angle (nominal; the half-cycle fit estimates the
    /// real offset).
    pub pickoff_mid_code: AdcCode,
    /// Full scale of the drive DAC, codes (12 bit: 4095); its mid-code is the zero drive.
    pub dac_full_scale: u16,
    /// The codes the drive DAC's output follows linearly (inclusive): its output buffer, on for
    /// the drive amplifier's input, swings from 0.2 V to VDDA - 0.2 V only (F405 datasheet,
    /// DAC characteristics, buffer on, R_L >= 5 kOhm); beyond, the drive clips.
    pub dac_linear_codes: (u16, u16),
    /// Frequencies the dither start-up searches for the resonance, Hz (inclusive).
    pub dither_search_hz: (f64, f64),
    /// Corner of the drive amplifier's output low-pass (its output resistance into the piezo's
    /// capacitance), Hz: its phase lag at the dither frequency, atan(f / f_c), is part of the
    /// drive-to-pick-off phase the frequency loop holds at resonance.
    pub drive_lowpass_hz: f64,
}

impl BoardProfile {
    /// The STM32F405 readout board (docs/board.md) for the docs/physics.md gyro: 84 MHz APB1
    /// timers, 32-bit TIM5 encoder, 18 ticks pick-off path, 70 ticks ADC aperture (2.5 + 15 ADC
    /// clocks at 21 MHz), 200-1500 Hz dither, 389 Hz and 450 arcsec nominal, 1.8655 arcsec per
    /// fringe; the dither drive ticks at 40 kHz (84 MHz / 2100), 0.4 arcsec per pick-off code
    /// (the nominal amplitude is 1125 codes, 700 arcsec before the rails), 12-bit DAC, resonance
    /// searched in 280-620 Hz, the drive amplifier's output low-pass at 3 kHz; the buffered DAC
    /// linear over codes 249-3846 (0.2 V to 3.1 V at VDDA = 3.3 V: 0.2 / 3.3 x 4095 = 248.2
    /// rounded up, 3.1 / 3.3 x 4095 = 3846.8 rounded down).
    pub const F405: Self = Self {
        name: "rlg-readout-f405",
        timer_hz: 84_000_000,
        core_clock_hz: 168_000_000,
        counter_width: CounterWidth::Bits32,
        pickoff_delay_ticks: 18,
        aperture_delay_ticks: 70,
        after_rising_edge: TurnaroundKind::Minus,
        dither_hz_range: (200, 1500),
        nominal_dither_hz: 389.0,
        scale_factor_arcsec: 1.8655,
        nominal_dither_amplitude_arcsec: 450.0,
        drive_tick_hz: 40_000,
        pickoff_arcsec_per_code: 0.4,
        pickoff_mid_code: AdcCode::MID,
        dac_full_scale: 4095,
        dac_linear_codes: (249, 3846),
        dither_search_hz: (280.0, 620.0),
        drive_lowpass_hz: 3000.0,
    };

    /// Timer ticks per drive tick: the drive timer's reload + 1 (2100 on the F405). Exact when
    /// [`Self::drive_tick_hz`] divides [`Self::timer_hz`] (a test checks the F405's).
    pub const fn drive_tick_period_timer_ticks(&self) -> u32 {
        self.timer_hz / self.drive_tick_hz
    }

    /// The turnaround scheduler's settings on this board.
    pub const fn scheduler_config(&self) -> SchedulerConfig {
        SchedulerConfig::for_dither_range(
            self.timer_hz,
            self.dither_hz_range.0,
            self.dither_hz_range.1,
            self.pickoff_delay_ticks,
            self.aperture_delay_ticks,
            self.after_rising_edge,
        )
    }

    /// The readout's settings on this board for a dither near `dither_hz`.
    pub fn readout_config(&self, dither_hz: f64) -> ReadoutConfig {
        let output = OutputConfig {
            model: DitherModelConfig::for_pickoff(
                self.drive_tick_hz as f32,
                self.timer_hz,
                self.pickoff_mid_code,
            ),
            strip: StripConfig::for_pickoff(self.pickoff_arcsec_per_code, self.scale_factor_arcsec),
            timer_hz: self.timer_hz,
            scale_factor_arcsec: self.scale_factor_arcsec as f32,
        };
        ReadoutConfig::for_board(self.timer_hz as f64, dither_hz, self.counter_width, output)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f405_scheduler_accepts_the_nominal_dither_and_refuses_outside_its_range() {
        let p = BoardProfile::F405;
        let s = p.scheduler_config();
        let half = |hz: f64| (p.timer_hz as f64 / (2.0 * hz)) as u32;
        assert!((s.min_half_ticks..=s.max_half_ticks).contains(&half(p.nominal_dither_hz)));
        assert!((s.min_half_ticks..=s.max_half_ticks).contains(&half(300.0)));
        assert!((s.min_half_ticks..=s.max_half_ticks).contains(&half(1000.0)));
        assert!(half(100.0) > s.max_half_ticks);
        assert!(half(5000.0) < s.min_half_ticks);
        assert_eq!(s.fixed_delay_ticks(), 88);
    }

    #[test]
    fn drive_tick_divides_the_timer_clock_exactly() {
        let p = BoardProfile::F405;
        assert_eq!(p.timer_hz % p.drive_tick_hz, 0);
        assert_eq!(p.drive_tick_period_timer_ticks(), 2100);
        // The start-up search covers at least 300-600 Hz, inside the scheduler's range.
        assert!(p.dither_search_hz.0 <= 300.0 && p.dither_search_hz.1 >= 600.0);
        assert!(p.dither_search_hz.0 >= p.dither_hz_range.0 as f64);
        assert!(p.dither_search_hz.1 <= p.dither_hz_range.1 as f64);
    }

    #[test]
    fn readout_config_uses_the_profile_counter_width() {
        let c = BoardProfile::F405.readout_config(389.0);
        assert_eq!(c.counter.width, CounterWidth::Bits32);
    }
}
