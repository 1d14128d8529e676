//! The two photodiode channels, their 12-bit ADC, and the comparators (squaring circuits) that
//! feed the fringe counter.
//!
//! # Model
//!
//! The channels see the beat phase `psi_H` (rad, unwrapped; `psi_H = psi - eps`, docs/physics.md):
//!
//! ```text
//! v_A = mid_A + amp_A cos(psi_H)          + n_A
//! v_B = mid_B + amp_B sin(psi_H + delta)  + n_B
//! ```
//!
//! with DC levels `mid`, amplitudes `amp` (gain x optical contrast), a quadrature error `delta`
//! (the deviation of the two detectors from 90 degrees) and white Gaussian noise `n` of the same
//! RMS on both channels, drawn from a seeded ChaCha8 stream: one independent draw per channel per
//! sample, so the noise bandwidth is the sample rate of whoever samples.
//!
//! The ADC is an ideal 12-bit converter: `code = round(v / lsb)` (or `floor`, see
//! [`AdcRounding`]) with `lsb = reference_v / 4096`, clamped to `0..=4095`
//! ([`firmware::sample::AdcCode::FULL_SCALE`]). The default board centres both signals at
//! mid-scale (1.65 V of 3.3 V) with 80 % swing (amplitude 1.32 V, codes 410..3686).
//!
//! Each comparator squares its channel against a threshold at the channel's mid-level plus an
//! optional trim error, with optional hysteresis (a Schmitt trigger): it switches high above
//! `threshold + hysteresis/2`, low below `threshold - hysteresis/2`, and otherwise keeps its
//! state. The comparators are not sampled: [`EdgeGeometry`] turns the thresholds into edge
//! positions in phase (a Schmitt trigger on `cos(x)` is exactly an ideal comparator behind a
//! backlash (play) of half-width `w` on the phase), which is what [`crate::counter`] uses to
//! count. The tests hold it against a voltage-domain Schmitt trigger.
//!
//! # Limits (what a real board does that this model does not)
//!
//! - The ADC samples instantaneously: no sample-and-hold aperture (3 to 480 ADC cycles on the
//!   F405), no differential or integral non-linearity, no offset/gain error of the converter
//!   itself (fold those into `mid` and `amp`), no missing codes.
//! - Noise is white and Gaussian; no 1/f noise, no laser intensity noise proportional to the
//!   signal, no drift of offsets, gains or contrast with temperature.
//! - Detectors respond instantly (no photodiode or amplifier bandwidth, so no phase lag that
//!   grows with beat frequency, which at ~590 kHz peak beat would be real).
//! - Comparators have no propagation delay and see the same analog signal as the ADC.
//! - Same seed, same output bit for bit on one platform and toolchain; `cos`, `sin` and the
//!   normal sampler's `exp`/`ln` come from the platform's libm, so another platform may differ
//!   in the last bit.

use core::f64::consts::TAU;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use firmware::sample::AdcCode;

/// How the ADC maps a voltage to a code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AdcRounding {
    /// `round(v / lsb)`: code transitions at half-LSB points (the ideal transfer curve).
    Nearest,
    /// `floor(v / lsb)`: code transitions at whole-LSB points.
    Floor,
}

/// The ADC converter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcConfig {
    /// Reference voltage (V); one LSB is `reference_v / 4096`.
    pub reference_v: f64,
    /// Code transitions.
    pub rounding: AdcRounding,
}

impl Default for AdcConfig {
    fn default() -> Self {
        Self {
            reference_v: 3.3,
            rounding: AdcRounding::Nearest,
        }
    }
}

impl AdcConfig {
    /// One LSB (V).
    pub fn lsb_v(&self) -> f64 {
        self.reference_v / (AdcCode::FULL_SCALE.to_f64() + 1.0)
    }

    /// The code for voltage `v`, clipped to `0..=`[`AdcCode::FULL_SCALE`].
    pub fn code(&self, v: f64) -> AdcCode {
        let x = v / self.lsb_v();
        let x = match self.rounding {
            AdcRounding::Nearest => x.round(),
            AdcRounding::Floor => x.floor(),
        };
        // `as` saturates (NaN -> 0); the 12-bit range clips the rest.
        AdcCode::saturating(x.max(0.0) as u16)
    }

    /// The mid-scale voltage `reference_v / 2` (V).
    pub fn mid_scale_v(&self) -> f64 {
        self.reference_v / 2.0
    }
}

/// The squaring circuit of one channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComparatorConfig {
    /// Threshold minus the channel's mid-level (V): a trim error; 0 = ideal.
    pub threshold_offset_v: f64,
    /// Full width of the hysteresis band (V); 0 = none.
    pub hysteresis_v: f64,
}

impl ComparatorConfig {
    /// Threshold exactly at mid-level, no hysteresis.
    pub const IDEAL: Self = Self {
        threshold_offset_v: 0.0,
        hysteresis_v: 0.0,
    };
}

/// One photodiode channel: its analog signal and its comparator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChannelConfig {
    /// DC level of the signal (V).
    pub mid_level_v: f64,
    /// Peak amplitude of the fringe signal (V), > 0.
    pub amplitude_v: f64,
    /// The channel's comparator.
    pub comparator: ComparatorConfig,
}

/// Both channels, the quadrature error, the noise and the ADC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhotodiodeConfig {
    /// Channel A, ~cos psi_H.
    pub a: ChannelConfig,
    /// Channel B, ~sin(psi_H + delta).
    pub b: ChannelConfig,
    /// Deviation of channel B from exact quadrature, `delta` (rad).
    pub quadrature_error_rad: f64,
    /// RMS of the additive white noise on each channel (V).
    pub noise_rms_v: f64,
    /// The converter for both channels.
    pub adc: AdcConfig,
}

impl Default for PhotodiodeConfig {
    /// A nominal board: centred at mid-scale with 80 % swing, 1 mV RMS noise (~1.2 LSB), exact
    /// quadrature, 20 mV comparator hysteresis.
    fn default() -> Self {
        let adc = AdcConfig::default();
        let channel = ChannelConfig {
            mid_level_v: adc.mid_scale_v(),
            amplitude_v: 0.8 * adc.mid_scale_v(),
            comparator: ComparatorConfig {
                threshold_offset_v: 0.0,
                hysteresis_v: 0.020,
            },
        };
        Self {
            a: channel,
            b: channel,
            quadrature_error_rad: 0.0,
            noise_rms_v: 1.0e-3,
            adc,
        }
    }
}

/// Why a configuration cannot work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhotodiodeConfigError {
    /// An amplitude is not positive.
    NonPositiveAmplitude,
    /// Noise RMS, hysteresis or reference is negative or not finite.
    InvalidValue,
    /// A comparator's switching levels lie outside the signal swing: it would never toggle.
    ComparatorNeverSwitches,
}

impl PhotodiodeConfig {
    /// Ideal detectors: the default levels with no noise, exact quadrature and ideal comparators.
    pub fn ideal() -> Self {
        let mut config = Self::default();
        config.a.comparator = ComparatorConfig::IDEAL;
        config.b.comparator = ComparatorConfig::IDEAL;
        config.noise_rms_v = 0.0;
        config
    }

    /// Check that every value is usable and both comparators toggle over a fringe.
    pub fn validate(&self) -> Result<(), PhotodiodeConfigError> {
        let finite_non_negative = |x: f64| x.is_finite() && x >= 0.0;
        if !(finite_non_negative(self.noise_rms_v)
            && self.adc.reference_v > 0.0
            && self.quadrature_error_rad.is_finite())
        {
            return Err(PhotodiodeConfigError::InvalidValue);
        }
        for channel in [&self.a, &self.b] {
            if !(channel.amplitude_v > 0.0 && channel.amplitude_v.is_finite()) {
                return Err(PhotodiodeConfigError::NonPositiveAmplitude);
            }
            let c = &channel.comparator;
            if !(finite_non_negative(c.hysteresis_v) && c.threshold_offset_v.is_finite()) {
                return Err(PhotodiodeConfigError::InvalidValue);
            }
            if c.threshold_offset_v.abs() + c.hysteresis_v / 2.0 >= channel.amplitude_v {
                return Err(PhotodiodeConfigError::ComparatorNeverSwitches);
            }
        }
        Ok(())
    }

    /// Noise-free analog levels `(v_A, v_B)` at beat phase `psi_h_rad`.
    pub fn levels_v(&self, psi_h_rad: f64) -> [f64; 2] {
        [
            self.a.mid_level_v + self.a.amplitude_v * psi_h_rad.cos(),
            self.b.mid_level_v + self.b.amplitude_v * (psi_h_rad + self.quadrature_error_rad).sin(),
        ]
    }

    /// Edge positions of both comparators in phase (A, B).
    pub fn edge_geometry(&self) -> [EdgeGeometry; 2] {
        [
            EdgeGeometry::new(&self.a, 0.0),
            EdgeGeometry::new(
                &self.b,
                core::f64::consts::FRAC_PI_2 - self.quadrature_error_rad,
            ),
        ]
    }
}

/// Two 12-bit ADC codes latched together.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdcCodes {
    /// Channel A (~cos psi_H).
    pub a_code: AdcCode,
    /// Channel B (~sin psi_H).
    pub b_code: AdcCode,
}

/// A fault of the analog front end, injected by tests ([`Photodiodes::set_fault`]).
///
/// Only the ADC conversions (the Lissajous stream and the turnaround latch) see it: the
/// comparators that feed the counter ([`crate::counter`]) follow the configuration and keep
/// counting, so the count stays right and the fault shows in the fractional fringe alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhotodiodeFault {
    /// Both amplifiers driven past the ADC's input range (overload, a lost reference): every
    /// conversion reads full scale.
    AdcSaturated,
    /// No light on either photodiode (the beam lost): both channels sit at their DC level.
    Dark,
    /// Channel B's photodiode lost (open, dark): B sits at its DC level, A still sees fringes.
    ChannelBLost,
}

/// The photodiode pair with its noise source: produces analog levels and ADC codes.
#[derive(Clone, Debug)]
pub struct Photodiodes {
    config: PhotodiodeConfig,
    rng: ChaCha8Rng,
    fault: Option<PhotodiodeFault>,
}

impl Photodiodes {
    /// Panics if `config` is invalid (see [`PhotodiodeConfig::validate`]).
    pub fn new(config: PhotodiodeConfig, seed: u64) -> Self {
        if let Err(e) = config.validate() {
            panic!("invalid photodiode config: {e:?}");
        }
        Self {
            config,
            rng: ChaCha8Rng::seed_from_u64(seed),
            fault: None,
        }
    }

    /// Injects a front-end fault from now on (`None` clears it).
    pub fn set_fault(&mut self, fault: Option<PhotodiodeFault>) {
        self.fault = fault;
    }

    /// The configuration.
    pub fn config(&self) -> &PhotodiodeConfig {
        &self.config
    }

    /// Noisy analog levels `(v_A, v_B)` at `psi_h_rad`; draws one noise sample per channel.
    pub fn sample_v(&mut self, psi_h_rad: f64) -> [f64; 2] {
        let [a, b] = self.config.levels_v(psi_h_rad);
        let [a, b] = match self.fault {
            None => [a, b],
            Some(PhotodiodeFault::AdcSaturated) => [self.config.adc.reference_v; 2],
            Some(PhotodiodeFault::Dark) => [self.config.a.mid_level_v, self.config.b.mid_level_v],
            Some(PhotodiodeFault::ChannelBLost) => [a, self.config.b.mid_level_v],
        };
        [a + self.noise_v(), b + self.noise_v()]
    }

    /// Both ADC codes at `psi_h_rad` (one noisy conversion per channel, simultaneous).
    pub fn sample_codes(&mut self, psi_h_rad: f64) -> AdcCodes {
        let [a, b] = self.sample_v(psi_h_rad);
        AdcCodes {
            a_code: self.config.adc.code(a),
            b_code: self.config.adc.code(b),
        }
    }

    fn noise_v(&mut self) -> f64 {
        gaussian_v(&mut self.rng, self.config.noise_rms_v)
    }
}

/// A zero-mean Gaussian sample of RMS `rms_v`; draws nothing when `rms_v == 0` so that a noise-free
/// configuration does not advance the stream.
fn gaussian_v(rng: &mut ChaCha8Rng, rms_v: f64) -> f64 {
    if rms_v == 0.0 {
        return 0.0;
    }
    let z: f64 = StandardNormal.sample(rng);
    rms_v * z
}

/// A noise-free comparator's edges in phase, for a channel `mid + amp cos(psi_H - phase)`.
///
/// With `z = threshold_offset / amp` and `h = hysteresis / (2 amp)`, the output is high where
/// `cos x > z + h` and low where `cos x < z - h` (`x = psi_H - phase`). Both hysteresis bands have
/// the same half-width `w = (acos(z - h) - acos(z + h)) / 2` around `x = +-c` with
/// `c = (acos(z + h) + acos(z - h)) / 2`. So the output equals an ideal comparator
/// (high iff `y` in `(-c, c)` mod 2 pi) applied to `y`, a copy of `x` behind a backlash of
/// half-width `w`: `y` follows `x` only when `|x - y|` would exceed `w`. Exact for any path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeGeometry {
    /// Phase of the channel's cosine (rad): 0 for A, pi/2 - delta for B.
    pub phase_rad: f64,
    /// Half-angle of the high interval (rad): pi/2 for an ideal comparator.
    pub half_high_rad: f64,
    /// Backlash half-width (rad): 0 without hysteresis.
    pub backlash_rad: f64,
}

impl EdgeGeometry {
    fn new(channel: &ChannelConfig, phase_rad: f64) -> Self {
        let c = &channel.comparator;
        let z = c.threshold_offset_v / channel.amplitude_v;
        let h = c.hysteresis_v / (2.0 * channel.amplitude_v);
        let (upper, lower) = ((z + h).acos(), (z - h).acos());
        Self {
            phase_rad,
            half_high_rad: (upper + lower) / 2.0,
            backlash_rad: (lower - upper) / 2.0,
        }
    }

    /// Number of edges at or below the backlashed phase `y_rad` (edge positions
    /// `+-half_high_rad + 2 pi m`, up to a constant). Odd means the output is high.
    pub fn edge_index(&self, y_rad: f64) -> i64 {
        let c = self.half_high_rad;
        ((y_rad - c) / TAU).floor() as i64 + ((y_rad + c) / TAU).floor() as i64
    }
}
