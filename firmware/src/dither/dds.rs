//! The drive synthesis: a phase accumulator (DDS) whose sine is `idsp::cossin` (the firmware's
//! bit-identical copy with its table in RAM, `crate::math::cossin`), scaled to DAC codes.
//! [`Drive`] is the exact description of every DAC sample between two loop updates; the
//! controller computes its output with the same function the simulator calls
//! ([`Drive::code_at`]), so "exact" is by construction, not by a tolerance.
//!
//! # Formats
//! - phase: [`Phase`], Q32 turns (wrapping); step: Q32 turns per tick (a [`Phase`] too), so
//!   f = step / 2^32 * f_s (9.3 uHz per LSB at 40 kHz);
//! - amplitude: DAC codes in Q16 (`u32`, codes * 2^16; 1900 codes = 124 518 400);
//! - sine: `idsp::cossin`'s Q31 (`i32`, full scale 2^31 - 0.85 * 2^15: its gain is
//!   1 - 1.3e-5, max error 9e-6 of full scale, spurs near -120 dBc).
//!
//! `code = mid + round(amplitude * sin / 2^47)` (round half up), clamped to the DAC's range.
//! Against the ideal `mid + round(A sin(phase + n step))` with an exact sine and A =
//! amplitude / 2^16 the codes agree except within 0.03 code of a rounding boundary (cossin's
//! 9e-6 and its 1.3e-5 gain on at most 2047 codes), where they may differ by one code; the DAC's
//! own quantisation (12 bit) dominates the drive's spectrum either way (`tests` below: the
//! harmonics of a 1900-code drive at 389 Hz are below -90 dBc).
//!
//! `idsp::Accu` (the crate's phase accumulator) is not used: the project's wrapping
//! [`Phase`] is the phase type everywhere (`units`), and its `+` is the same single add.

use crate::units::Phase;

/// The DDS parameters in force: every DAC sample from tick [`Drive::start_tick`] until the next
/// change is `dac(n) = mid + round(amplitude * sin(phase + n * step))`, n = tick - start_tick,
/// computed by [`Drive::dac_code`]. Changes only at a loop update (at most once per half
/// dither cycle, at the drive's peaks) or when the drive is switched off; `Tick::drive_changed`
/// reports each change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Drive {
    /// The drive tick (the controller's tick index, wrapping) of the first sample described.
    pub start_tick: u32,
    /// Phase of that sample, Q32 turns.
    pub phase: Phase,
    /// Phase step per tick, Q32 turns (the drive frequency: step / 2^32 * f_s).
    pub step: Phase,
    /// Amplitude, DAC codes in Q16 (codes * 2^16); 0 = drive off (every sample is `mid_code`).
    pub amplitude_q16: u32,
    /// The DAC code of zero drive (mid-scale).
    pub mid_code: u16,
    /// The DAC's full scale (codes are clamped to 0..=full_scale).
    pub full_scale: u16,
}

impl Drive {
    /// Drive off from `start_tick`: every sample is `mid_code`.
    pub const fn off(start_tick: u32, mid_code: u16, full_scale: u16) -> Self {
        Self {
            start_tick,
            phase: Phase::ZERO,
            step: Phase::ZERO,
            amplitude_q16: 0,
            mid_code,
            full_scale,
        }
    }

    /// The DAC code of sample `n` of this segment (tick `start_tick + n`).
    #[inline]
    pub fn dac_code(&self, n: u32) -> u16 {
        self.code_at(self.phase_of(n))
    }

    /// The DAC code at drive tick `tick` (wrapping; meaningful from `start_tick` until the next
    /// change).
    #[inline]
    pub fn dac_code_at_tick(&self, tick: u32) -> u16 {
        self.dac_code(tick.wrapping_sub(self.start_tick))
    }

    /// Phase of sample `n`: `phase + n * step` (wrapping).
    #[inline]
    pub fn phase_of(&self, n: u32) -> Phase {
        self.phase + Phase::from_bits(n.wrapping_mul(self.step.to_bits()))
    }

    /// The DAC code of a sample at `phase`.
    #[inline]
    pub fn code_at(&self, phase: Phase) -> u16 {
        self.code_from_sin(cos_sin_q31(phase).1)
    }

    /// The DAC code for a sine value already computed (`cos_sin_q31(phase).1`).
    #[inline]
    pub fn code_from_sin(&self, sin_q31: i32) -> u16 {
        let scaled = (self.amplitude_q16 as i64 * sin_q31 as i64 + (1 << 46)) >> 47;
        (self.mid_code as i64 + scaled).clamp(0, self.full_scale as i64) as u16
    }

    /// The drive frequency, Hz, at tick rate `tick_hz`.
    pub fn frequency_hz(&self, tick_hz: f64) -> f64 {
        step_to_hz(self.step, tick_hz)
    }

    /// The amplitude in DAC codes.
    pub fn amplitude_codes(&self) -> f64 {
        self.amplitude_q16 as f64 / 65_536.0
    }
}

pub use crate::math::sine_fit::cos_sin_q31;

/// The DDS step (Q32 turns per tick) of `hz` at tick rate `tick_hz`, rounded; saturates at half
/// a turn (Nyquist).
pub fn hz_to_step(hz: f64, tick_hz: f64) -> Phase {
    let turns = hz / tick_hz;
    let bits = crate::math::round_to_i64(turns * crate::units::Q32_PER_FRINGE);
    Phase::from_bits(bits.clamp(0, 1 << 31) as u32)
}

/// The frequency (Hz) of DDS step `step` at tick rate `tick_hz`.
pub fn step_to_hz(step: Phase, tick_hz: f64) -> f64 {
    step.to_bits() as f64 / crate::units::Q32_PER_FRINGE * tick_hz
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn drive(hz: f64, amplitude_codes: f64) -> Drive {
        Drive {
            start_tick: 1000,
            phase: Phase::from_bits(0x1234_5678),
            step: hz_to_step(hz, 40_000.0),
            amplitude_q16: (amplitude_codes * 65_536.0) as u32,
            mid_code: 2048,
            full_scale: 4095,
        }
    }

    /// Magnitude of the DFT of `x` at `cycles` cycles per record (a single bin, exact for a
    /// whole number of cycles).
    fn bin(x: &[f64], cycles: f64) -> f64 {
        let n = x.len() as f64;
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in x.iter().enumerate() {
            let a = TAU * cycles * i as f64 / n;
            re += v * a.cos();
            im -= v * a.sin();
        }
        2.0 * (re * re + im * im).sqrt() / n
    }

    #[test]
    fn codes_follow_the_ideal_sine_within_one_code_and_mostly_exactly() {
        let d = drive(389.0, 1900.0);
        let mut differ = 0;
        for n in 0..200_000u32 {
            let turns = d.phase_of(n).to_bits() as f64 / crate::units::Q32_PER_TURN;
            let ideal = 2048.0 + (d.amplitude_codes() * (TAU * turns).sin() + 0.5).floor();
            let got = d.dac_code(n) as f64;
            assert!((got - ideal).abs() <= 1.0, "n {n}: {got} vs {ideal}");
            if got != ideal {
                differ += 1;
            }
        }
        // Differences only where the exact value lies within ~0.03 code of a rounding boundary.
        assert!(differ < 200_000 / 20, "{differ}");
        assert_eq!(d.dac_code_at_tick(1000), d.dac_code(0));
        assert_eq!(d.dac_code_at_tick(1007), d.dac_code(7));
    }

    #[test]
    fn off_and_clamped() {
        let off = Drive::off(5, 2048, 4095);
        assert_eq!(off.dac_code(123), 2048);
        let big = drive(389.0, 3000.0);
        let codes: Vec<u16> = (0..400).map(|n| big.dac_code(n)).collect();
        assert_eq!(*codes.iter().max().unwrap(), 4095);
        assert_eq!(*codes.iter().min().unwrap(), 0);
    }

    #[test]
    fn step_and_frequency_round_trip() {
        let s = hz_to_step(389.0, 40_000.0);
        assert!((step_to_hz(s, 40_000.0) - 389.0).abs() < 1e-5);
        assert_eq!(hz_to_step(1e9, 40_000.0).to_bits(), 1 << 31);
    }

    /// The drive's harmonics: a 1900-code drive at 388.8 Hz (637 cycles in 2^16 samples, so the
    /// record is exactly periodic and the DFT has no leakage), DFT at the fundamental and at
    /// 2..10 times it. Measured: the largest harmonic is printed (the DAC's 12-bit rounding,
    /// whose error is spread over many bins; cossin's own spurs are at -120 dBc); asserted below
    /// -90 dBc.
    #[test]
    fn harmonics_of_the_drive_are_below_minus_90_dbc() {
        const N: u32 = 1 << 16;
        let d = Drive {
            phase: Phase::ZERO,
            step: Phase::from_bits(637 << 16),
            ..drive(389.0, 1900.0)
        };
        let hz = 637.0;
        let x: Vec<f64> = (0..N).map(|n| d.dac_code(n) as f64 - 2048.0).collect();
        let fundamental = bin(&x, hz);
        assert!((fundamental - 1900.0).abs() < 0.1, "{fundamental}");
        let worst = (2..=10)
            .map(|h| 20.0 * (bin(&x, hz * h as f64) / fundamental).log10())
            .fold(f64::MIN, f64::max);
        println!("drive harmonics 2..10: worst {worst:.1} dBc");
        assert!(worst < -90.0, "{worst}");
    }
}
