//! The drive amplifier between the DAC and the piezo: gain, output limit, output low-pass; and
//! what the resonator sees of one drive segment (the DAC's zero-order-hold fundamental through
//! the gain and the limit), as a [`Forcing`].
//!
//! # From DAC samples to the forcing
//!
//! Within a segment the DAC writes `u_n = offset + a sin(phase + n step)` at the ticks
//! `t_n = start + n / f_s` and holds each value for one tick. The held staircase is exactly
//! its *fundamental*
//!
//! ```text
//! a sinc(step/2) sin(phase + w (t - start) - step/2),     w = step f_s,  sinc x = sin x / x
//! ```
//!
//! (the zero-order hold's gain and its delay of half a tick) plus *images* at `k f_s +- f`
//! (k >= 1) of amplitude `~a f / (k f_s)`. The fundamental is modelled exactly; the images are
//! not (bound below).
//!
//! The amplifier multiplies `u - input_ref` by its gain and clips at its rails. The clip acts
//! on every sample; it is modelled by its *describing function*: the constant and the
//! fundamental of `clip(c + a' sin x)` (exact, [`clipped_fourier`]), with the DAC's own rails
//! (0 and its reference) folded into the same clip. The output low-pass (the amplifier's
//! output resistance into the piezo's capacitance, cutoff a few kHz) comes after the clip and
//! is part of the linear system ([`super::linear`]).
//!
//! # What is left out, and its size
//!
//! - **Images** at `f_s - f` and `f_s + f` (the largest): amplitude `~a f/f_s` at the
//!   amplifier, attenuated by the low-pass (`~f_c/f_s`) and by the resonator (`~(f0/f_s)^2`
//!   against its DC gain, i.e. `(f0/f_s)^2 / Q` against the resonant response). Relative to
//!   the resonant amplitude: `(f/f_s) (f_c/f_s) (f0/f_s)^2 / Q` = 1.1e-9 at 389 Hz, 20 kHz,
//!   3 kHz, Q = 1000 (5e-7 arcsec of 450; computed exactly by
//!   [`super::resonator::ResonatorParams::image_bound_arcsec`]).
//! - **The images' ringing.** A change of the DDS changes its images; the change of their
//!   ripple on the piezo voltage (the images summed through the low-pass, `~K a (f/f_s)
//!   (f_c/f_s) pi^2/3`, all in phase at the ticks) kicks the resonator by `G (w0/p)` times it,
//!   and that rings down with `Q/(pi f0)`: `(pi^2/3) (|da|/a) (f/f_s) (f0/f_s) / Q` of the
//!   resonant amplitude, 1.25e-6 for `|da| = a` (a drive switched on or off, 5.6e-4 arcsec at
//!   450 arcsec), proportionally less for the small corrections of an amplitude loop
//!   ([`super::resonator::ResonatorParams::image_ring_bound_arcsec`]).
//!   `tests/dither_resonator.rs` holds both bounds against a brute-force integration of the
//!   true staircase.
//! - **Harmonics of the clip** (odd; for a hard clip, a square wave, the n-th is 1/n of the
//!   fundamental) fall on the resonator's skirt: `|H(n w0)| / |H(w0)| = 1/((n^2 - 1) Q)`, so
//!   together at most `sum 1/(n (n^2 - 1)) / Q = 1/(17.6 Q)` of the response at resonance
//!   (the third alone `1/(24 Q)`; 5.7e-5 at Q = 1000), and only while the limit is hit
//!   (start-up).
//! - **DAC quantisation** (the codes are rounded: +-1/2 LSB = +-0.4 mV at the DAC) and the
//!   images of the clipped waveform: not modelled.

use super::drive::{DacParams, DriveSegment};
use super::linear::Forcing;
use core::f64::consts::{FRAC_PI_2, PI, TAU};

/// The drive amplifier (a piezo driver).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmplifierParams {
    /// Voltage gain from the DAC output to the amplifier output, V/V. Range (0, 1000].
    pub gain_v_per_v: f64,
    /// DAC voltage that gives zero output (the amplifier's reference: the DAC's mid-scale),
    /// V. Range [0, DAC reference].
    pub input_ref_v: f64,
    /// The output clips at +- this, V. Range (0, 1000].
    pub output_limit_v: f64,
    /// Cutoff of the first-order output low-pass, Hz. Range [f0, 1e5] (its phase lag at the
    /// dither frequency is part of the drive loop: 7.4 deg at 389 Hz for 3 kHz).
    pub cutoff_hz: f64,
}

impl Default for AmplifierParams {
    /// Gain 20 (the DAC's +-1.65 V become +-33 V), reference 1.65 V, limit +-30 V, and the
    /// board's output low-pass (`BoardProfile::F405.drive_lowpass_hz`, 3 kHz).
    fn default() -> Self {
        Self {
            gain_v_per_v: 20.0,
            input_ref_v: 1.65,
            output_limit_v: 30.0,
            cutoff_hz: firmware::profile::BoardProfile::F405.drive_lowpass_hz,
        }
    }
}

impl AmplifierParams {
    /// What the resonator sees of `segment`: the zero-order-hold fundamental of the DAC
    /// samples through the gain, the limit (describing function) and the half-tick delay.
    pub fn forcing(&self, dac: &DacParams, segment: &DriveSegment) -> Forcing {
        let k = self.gain_v_per_v;
        // DAC rails, gain, amplifier rails: one clip of `k (u - ref)` to [lo, hi].
        let lo = (-self.output_limit_v).max(-k * self.input_ref_v);
        let hi = self
            .output_limit_v
            .min(k * (dac.reference_v - self.input_ref_v));
        let (dc, fundamental) = clipped_fourier(
            k * (segment.offset_v - self.input_ref_v),
            k * segment.amplitude_v,
            lo,
            hi,
        );
        let half_step = 0.5 * segment.step_rad;
        let sinc = if half_step == 0.0 {
            1.0
        } else {
            half_step.sin() / half_step
        };
        Forcing {
            dc_v: dc,
            amplitude_v: fundamental * sinc,
            freq_hz: segment.freq_hz(dac),
            phase_rad: segment.phase_rad - half_step,
        }
    }

    /// The first-order low-pass's pole, rad/s.
    pub fn lowpass_rad_per_s(&self) -> f64 {
        TAU * self.cutoff_hz
    }
}

/// The constant and the fundamental's amplitude of `clip(c + a sin x, lo, hi)` over one
/// period (`a >= 0`, `lo < hi`): the describing function of a clip, offset included. The
/// fundamental is in phase with `sin x` (the clipped wave is symmetric about `x = pi/2`).
///
/// With `s = sin x` the wave is `lo` below `s_l = (lo - c)/a`, `hi` above `s_u = (hi - c)/a`,
/// linear between; integrating over `x in [-pi/2, pi/2]` (the other half mirrors it) with
/// `b_l = asin s_l`, `b_u = asin s_u` (clamped to +-pi/2) gives the closed forms below.
pub fn clipped_fourier(c: f64, a: f64, lo: f64, hi: f64) -> (f64, f64) {
    if a <= 0.0 {
        return (c.clamp(lo, hi), 0.0);
    }
    let beta = |s: f64| s.clamp(-1.0, 1.0).asin();
    let (bl, bu) = (beta((lo - c) / a), beta((hi - c) / a));
    let (cl, cu) = (bl.cos(), bu.cos());
    let i0 = lo * (bl + FRAC_PI_2) + c * (bu - bl) + a * (cl - cu) + hi * (FRAC_PI_2 - bu);
    let i1 = -lo * cl
        + c * (cl - cu)
        + a * (0.5 * (bu - bl) - 0.25 * ((2.0 * bu).sin() - (2.0 * bl).sin()))
        + hi * cu;
    (i0 / PI, 2.0 * i1 / PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Midpoint quadrature of the clipped wave's constant and fundamental.
    fn numeric(c: f64, a: f64, lo: f64, hi: f64) -> (f64, f64) {
        let n = 200_000;
        let (mut dc, mut b1) = (0.0, 0.0);
        for i in 0..n {
            let x = TAU * (i as f64 + 0.5) / n as f64;
            let y = (c + a * x.sin()).clamp(lo, hi);
            dc += y;
            b1 += y * x.sin();
        }
        (dc / n as f64, 2.0 * b1 / n as f64)
    }

    #[test]
    fn clipped_fourier_matches_quadrature() {
        for &(c, a, lo, hi) in &[
            (0.0, 7.5, -30.0, 30.0),
            (0.0, 60.0, -30.0, 30.0),
            (5.0, 40.0, -30.0, 30.0),
            (-3.0, 35.0, -33.0, 30.0),
            (40.0, 5.0, -30.0, 30.0),
            (0.0, 1e6, -30.0, 30.0),
            (2.0, 0.0, -1.0, 1.0),
        ] {
            let (dc, b1) = clipped_fourier(c, a, lo, hi);
            let (ndc, nb1) = numeric(c, a, lo, hi);
            // Midpoint rule on a periodic integrand with kinks: error ~ (2 pi / n)^2 ~ 1e-9.
            assert!(
                (dc - ndc).abs() < 1e-6 * (1.0 + a),
                "{c} {a}: dc {dc} vs {ndc}"
            );
            assert!(
                (b1 - nb1).abs() < 1e-6 * (1.0 + a),
                "{c} {a}: b1 {b1} vs {nb1}"
            );
        }
        // A hard clip is a square wave: fundamental 4 L / pi.
        let (_, b1) = clipped_fourier(0.0, 1e12, -30.0, 30.0);
        assert!((b1 - 120.0 / PI).abs() < 1e-6);
    }

    #[test]
    fn the_forcing_is_the_zoh_fundamental() {
        let dac = DacParams::default();
        let amp = AmplifierParams::default();
        let step = TAU * 389.0 / dac.tick_hz;
        let seg = DriveSegment {
            start_s: 0.0,
            phase_rad: 0.3,
            step_rad: step,
            amplitude_v: 0.4,
            offset_v: 1.65,
        };
        let f = amp.forcing(&dac, &seg);
        let sinc = (step / 2.0).sin() / (step / 2.0);
        assert!((f.amplitude_v - 8.0 * sinc).abs() < 1e-12);
        assert!((f.phase_rad - (0.3 - step / 2.0)).abs() < 1e-15);
        assert!((f.freq_hz - 389.0).abs() < 1e-9);
        assert!(f.dc_v.abs() < 1e-12);
    }
}
