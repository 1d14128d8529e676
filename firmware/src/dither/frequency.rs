//! The frequency loop: keeps the drive at resonance, where the pick-off is 90 degrees behind
//! the drive. The phase detector is the half-cycle fit's phase ([`super::measure`]), corrected
//! for the known delays (the DAC's zero-order hold, the ADC's aperture; [`reference_shift`]);
//! its error drives a PI controller (`idsp::iir::BiquadClamp`, fixed point) whose output is the
//! DDS step, clamped to the search range (its anti-windup). The DDS is the loop's oscillator.
//!
//! # Why not `idsp::PLL`
//! idsp's PLL tracks the phase of an input signal sampled at a uniform rate and locks to that
//! signal's frequency. Here the signal (the pick-off) follows the drive: a PLL on it locks to
//! the drive's own frequency, wherever the resonance is. The resonance condition is a phase
//! *difference* (pick-off behind drive by 90 degrees), and the resonator itself turns a
//! frequency error into that phase difference: near resonance `d(dphi)/dt = -dphi / tau - dw`
//! (tau = 2Q / w0), an integrator above 1/tau. So the loop is a PI on the phase difference with
//! the resonator as its integrator, sampled once per half cycle: idsp's clamped biquad, with
//! the DDS accumulator as the VCO.
//!
//! # Gains
//! With the error in Q32 turns and the output in Q32 turns per tick, a proportional gain kp
//! gives a crossover `w_c = kp f_s`: kp = w_c / f_s (2 pi 2 Hz / 40 kHz = 3.1e-4, Q30). The
//! integral corner at w_c / 4 (62 degrees of phase margin against the plant's integrator).
//! A drift of f0 by 0.5 Hz in 60 s then leaves a phase error of 1.3e-3 rad, i.e. a frequency
//! error of 2.6e-4 Hz at Q = 1000 (the phase-to-frequency slope near resonance is 2Q / f0).

use dsp_fixedpoint::Q32;
use dsp_process::SplitProcess;
use idsp::iir::{Biquad, BiquadClamp, DirectForm1Wide};

use crate::units::Phase;

/// The frequency loop's settings (immutable).
#[derive(Clone, Debug)]
pub struct FrequencyLoopConfig {
    /// The PI: `[kp (1 + w_i T), -kp, 0, 1, 0]` in Q30, input the phase error (Q32 turns),
    /// output the DDS step (Q32 turns per tick) clamped to the search range.
    pub pi: BiquadClamp<Q32<30>, i32>,
    /// Largest phase error fed to the PI, Q32 turns (an eighth of a turn: acquisition with a
    /// larger error is slewed, not kicked).
    pub max_error: Phase,
}

impl FrequencyLoopConfig {
    /// A loop of crossover `crossover_hz` and integral corner `crossover_hz / integral_ratio`,
    /// updated every half cycle of `dither_hz`, at tick rate `tick_hz`, its DDS step clamped to
    /// `step_range`.
    pub fn new(
        crossover_hz: f32,
        integral_ratio: f32,
        dither_hz: f32,
        tick_hz: f32,
        step_range: (Phase, Phase),
    ) -> Self {
        let w_c = core::f32::consts::TAU * crossover_hz;
        let kp = w_c / tick_hz;
        let half_cycle_s = 0.5 / dither_hz;
        let b0 = kp * (1.0 + w_c / integral_ratio * half_cycle_s);
        let coefficients = [b0, -kp, 0.0, 1.0, 0.0].map(Q32::<30>::from_f32);
        Self {
            pi: BiquadClamp {
                coeff: Biquad { ba: coefficients },
                u: 0,
                min: step_range.0.to_bits() as i32,
                max: step_range.1.to_bits() as i32,
            },
            max_error: Phase::EIGHTH_TURN,
        }
    }
}

/// The frequency loop's state.
#[derive(Clone, Debug, Default)]
pub struct FrequencyLoop {
    pi: DirectForm1Wide,
    fresh: bool,
}

impl FrequencyLoop {
    /// Starts at DDS step `step` (bumpless).
    pub fn start(&mut self, step: Phase) {
        self.pi = DirectForm1Wide {
            x: [0, 0],
            y: [(step.to_bits() as i64) << 32; 2],
        };
        self.fresh = true;
    }

    /// One half cycle: the DDS step for the next half cycle from the phase error (Q32 turns,
    /// positive when the pick-off lags the drive by less than 90 degrees: drive below
    /// resonance).
    pub fn update(&mut self, config: &FrequencyLoopConfig, error: Phase) -> Phase {
        let limit = config.max_error.to_bits() as i32;
        let x = error.to_signed().clamp(-limit, limit);
        if self.fresh {
            self.pi.x = [x, x];
            self.fresh = false;
        }
        Phase::from_bits(config.pi.process(&mut self.pi, x) as u32)
    }
}

/// The phase from a sample's regressor to the drive's phase at that sample's instant, Q32
/// turns. Sample k is regressed on the phase of the DAC sample that tick k outputs,
/// phi(k + 1); the drive in force then, seen through the DAC's zero-order hold, has the phase
/// phi(k) - step / 2 at tick k, and the ADC samples `sample_delay_q16` (ticks, Q16) after
/// tick k: `shift = step * (3/2 - sample_delay)` (integer arithmetic: once per half cycle).
pub fn reference_shift(step: Phase, sample_delay_q16: u32) -> Phase {
    let ticks_q16 = (3u64 << 15).saturating_sub(sample_delay_q16 as u64);
    Phase::from_bits(((step.to_bits() as u64 * ticks_q16 + (1 << 15)) >> 16) as u32)
}

/// The phase the drive advances in `delay_q16` ticks (Q16): `step * delay`, rounded.
pub fn phase_in(step: Phase, delay_q16: u32) -> Phase {
    Phase::from_bits(((step.to_bits() as u64 * delay_q16 as u64 + (1 << 15)) >> 16) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dither::dds::{hz_to_step, step_to_hz};

    fn config() -> FrequencyLoopConfig {
        FrequencyLoopConfig::new(
            2.0,
            4.0,
            389.0,
            40_000.0,
            (hz_to_step(280.0, 40e3), hz_to_step(620.0, 40e3)),
        )
    }

    /// The resonator's phase difference as the loop sees it near resonance (the integrator with
    /// leak 1/tau of the module docs), stepped once per half cycle.
    struct PhasePlant {
        f0: f64,
        tau: f64,
        dphi: f64,
    }

    impl PhasePlant {
        fn step(&mut self, drive_hz: f64, dt: f64) -> Phase {
            let dw = std::f64::consts::TAU * (drive_hz - self.f0);
            self.dphi += (-self.dphi / self.tau - dw) * dt;
            Phase::from_bits(
                ((self.dphi / std::f64::consts::TAU) * crate::units::Q32_PER_TURN) as i64 as u32,
            )
        }
    }

    /// Lock on a phase step and on a frequency ramp (the acceptance's drift, 10x faster).
    #[test]
    fn locks_after_a_frequency_step_and_tracks_a_ramp() {
        let c = config();
        let mut l = FrequencyLoop::default();
        l.start(hz_to_step(389.4, 40e3)); // 0.4 Hz off, as a rough ring measurement
        let mut p = PhasePlant {
            f0: 389.0,
            tau: 2.0 * 1000.0 / (std::f64::consts::TAU * 389.0),
            dphi: 0.0,
        };
        let mut hz = 389.4;
        let dt = 0.5 / 389.0;
        for _ in 0..(2 * 778) {
            hz = step_to_hz(l.update(&c, p.step(hz, dt)), 40e3);
        }
        assert!((hz - 389.0).abs() < 1e-3, "{hz}");
        // A phase step of 0.3 rad (a disturbance): back within 1e-3 rad in 2 s.
        p.dphi += 0.3;
        for _ in 0..(2 * 778) {
            hz = step_to_hz(l.update(&c, p.step(hz, dt)), 40e3);
        }
        assert!(
            p.dphi.abs() < 1e-3 && (hz - 389.0).abs() < 1e-3,
            "{} {hz}",
            p.dphi
        );
        // f0 ramps by 0.5 Hz in 6 s (10x the acceptance's drift): the drive lags by 2.6e-3 Hz
        // (so 2.6e-4 Hz at the acceptance's 0.5 Hz in 60 s, against 0.015 Hz allowed).
        let mut worst: f64 = 0.0;
        for k in 0..(6 * 778) {
            p.f0 = 389.0 + 0.5 * k as f64 / (6.0 * 778.0);
            hz = step_to_hz(l.update(&c, p.step(hz, dt)), 40e3);
            if k > 778 {
                worst = worst.max((hz - p.f0).abs());
            }
        }
        assert!(worst < 3e-3, "{worst}");
    }

    #[test]
    fn output_is_clamped_to_the_search_range() {
        let c = config();
        let mut l = FrequencyLoop::default();
        l.start(hz_to_step(600.0, 40e3));
        for _ in 0..100_000 {
            l.update(&c, Phase::QUARTER_TURN);
        }
        let top = step_to_hz(l.update(&c, Phase::QUARTER_TURN), 40e3);
        assert!((top - 620.0).abs() < 1e-3, "{top}");
        // Leaves the clamp at once when the error reverses (anti-windup).
        let back = step_to_hz(l.update(&c, -Phase::EIGHTH_TURN), 40e3);
        assert!(back < top);
    }

    #[test]
    fn reference_shift_is_one_and_a_half_steps_less_the_sample_delay() {
        let step = Phase::from_bits(1000);
        assert_eq!(reference_shift(step, 0).to_bits(), 1500);
        assert_eq!(reference_shift(step, 1 << 15).to_bits(), 1000);
        assert_eq!(phase_in(step, 3 << 15).to_bits(), 1500);
    }
}
