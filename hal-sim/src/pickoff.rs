//! The dither pick-off: a piezo strain gauge on the dither spring whose voltage follows the
//! body's dither angle, read by an ADC channel of the board (the firmware's drive loop samples
//! it at every drive tick) and squared by the comparator whose edges TIM2 captures (the
//! turnaround schedule).
//!
//! # Model
//!
//! ```text
//! v(t) = offset + k (1 + gain_error) (theta(t - lag) + cubic theta(t - lag)^3) + n(t)
//! code = clamp(round(v / lsb), 0, 4095)
//! ```
//!
//! with `theta` the dither angle in arcsec ([`crate::gyro::Gyro::dither_pickoff_arcsec`]: the
//! prescribed sine or the driven resonator), `k` the nominal sensitivity, `n` white Gaussian
//! noise (seeded, one draw per conversion). The ADC is the board's 12-bit converter
//! ([`crate::photodiode::AdcConfig`]); the codes clip at 0 and 4095, so a pick-off driven past
//! the rails (an amplitude beyond `full_scale_arcsec`, 550 arcsec with the defaults) reads as
//! saturated, as on the board.
//!
//! - **The lag is a pure delay** (the piezo's and the preamplifier's phase lag at the dither
//!   frequency, as a time): closed form at any instant, no state. A first-order filter would
//!   also scale the amplitude by `1/sqrt(1 + (w tau)^2)` (2e-5 for 10 us at 389 Hz): below the
//!   gain error one would specify, so the delay carries the part that matters, the timing.
//! - **The comparator** squares the noise-free voltage against a threshold voltage
//!   ([`PickoffConfig::threshold_v`]: the voltage of a given angle at the nominal sensitivity,
//!   so a gain error moves the angle at which it switches). Noise on the comparator would need
//!   its hysteresis to be modelled (it would chatter at a crossing), so the edges are clean.
//! - **Lost** ([`Pickoff::set_lost`]): the signal disappears (a broken wire, a dead gauge):
//!   the ADC reads the offset plus noise, and the comparator sees a constant (no edges).

use crate::gyro::Gyro;
use crate::param_error::ParamError;
use crate::photodiode::AdcConfig;
use firmware::sample::AdcCode;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The pick-off and its ADC channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PickoffConfig {
    /// Nominal sensitivity `k`, V per arcsec of dither angle. Range (0, 1].
    pub sensitivity_v_per_arcsec: f64,
    /// Output at zero angle, V. Range [0, ADC reference].
    pub offset_v: f64,
    /// Relative gain error (the true sensitivity is `k (1 + gain_error)`). Range (-0.5, 0.5).
    pub gain_error: f64,
    /// Delay of the pick-off's output behind the angle, s. Range [0, 1e-3].
    pub lag_s: f64,
    /// Cubic non-linearity: the relative deviation at angle `theta` is `cubic theta^2`,
    /// 1/arcsec^2. Range [-1e-5, 1e-5], and monotonic over the ADC's range.
    pub cubic_per_arcsec2: f64,
    /// RMS of the white noise at the ADC input, V. Range [0, 1].
    pub noise_rms_v: f64,
    /// The converter (the board's 12-bit ADC, 3.3 V).
    pub adc: AdcConfig,
}

impl Default for PickoffConfig {
    /// The board's nominal pick-off (`BoardProfile::F405.pickoff_arcsec_per_code`, 0.4 arcsec
    /// per code: 2.01 mV/arcsec, so 450 arcsec is +-0.91 V, 55 % of the ADC's half range, and
    /// it saturates beyond 819 arcsec), centred at mid-scale, no errors, 1 mV RMS noise
    /// (1.2 LSB), no lag. The firmware converts codes with the same nominal figure: a real
    /// board's deviation from it is `gain_error`.
    fn default() -> Self {
        let adc = AdcConfig::default();
        let arcsec_per_code = firmware::profile::BoardProfile::F405.pickoff_arcsec_per_code;
        Self {
            sensitivity_v_per_arcsec: adc.lsb_v() / arcsec_per_code,
            offset_v: adc.mid_scale_v(),
            gain_error: 0.0,
            lag_s: 0.0,
            cubic_per_arcsec2: 0.0,
            noise_rms_v: 1e-3,
            adc,
        }
    }
}

fn check(ok: bool, what: &'static str) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError::OutOfRange(what))
    }
}

impl PickoffConfig {
    /// The default pick-off without noise.
    pub fn ideal() -> Self {
        Self {
            noise_rms_v: 0.0,
            ..Self::default()
        }
    }

    /// Checks every field against its range.
    pub fn validate(&self) -> Result<(), ParamError> {
        let in_range = |x: f64, lo: f64, hi: f64| x.is_finite() && x >= lo && x <= hi;
        check(
            self.adc.reference_v > 0.0 && self.adc.reference_v.is_finite(),
            "pickoff: ADC reference must be positive",
        )?;
        check(
            in_range(self.sensitivity_v_per_arcsec, 1e-12, 1.0),
            "pickoff: sensitivity_v_per_arcsec must be in (0, 1]",
        )?;
        check(
            in_range(self.offset_v, 0.0, self.adc.reference_v),
            "pickoff: offset_v must be within the ADC's range",
        )?;
        check(
            in_range(self.gain_error, -0.499_999, 0.499_999),
            "pickoff: gain_error must be in (-0.5, 0.5)",
        )?;
        check(
            in_range(self.lag_s, 0.0, 1e-3),
            "pickoff: lag_s must be in [0, 1e-3]",
        )?;
        check(
            in_range(self.noise_rms_v, 0.0, 1.0),
            "pickoff: noise_rms_v must be in [0, 1]",
        )?;
        let c = self.cubic_per_arcsec2;
        let full = self.full_scale_arcsec();
        check(
            in_range(c, -1e-5, 1e-5) && 1.0 + 3.0 * c.min(0.0) * full * full > 0.0,
            "pickoff: cubic_per_arcsec2 must be in [-1e-5, 1e-5] and keep the pick-off \
             monotonic over the ADC's range",
        )
    }

    /// The largest angle the ADC resolves at the nominal sensitivity (the farther rail),
    /// arcsec.
    pub fn full_scale_arcsec(&self) -> f64 {
        self.offset_v.max(self.adc.reference_v - self.offset_v) / self.sensitivity_v_per_arcsec
    }

    /// The noise-free voltage for a dither angle (no lag: the angle at the delayed instant), V.
    pub fn voltage_v(&self, angle_arcsec: f64) -> f64 {
        let a = angle_arcsec;
        self.offset_v
            + self.sensitivity_v_per_arcsec
                * (1.0 + self.gain_error)
                * (a + self.cubic_per_arcsec2 * a * a * a)
    }

    /// The comparator threshold that stands for `angle_arcsec`: the voltage of that angle at
    /// the nominal sensitivity, V (thresholds are set in volts, so the errors move the angle
    /// at which the comparator switches).
    pub fn threshold_v(&self, angle_arcsec: f64) -> f64 {
        self.offset_v + self.sensitivity_v_per_arcsec * angle_arcsec
    }
}

/// The pick-off of one board: its configuration, its noise and its fault switch.
#[derive(Clone, Debug)]
pub struct Pickoff {
    config: PickoffConfig,
    rng: ChaCha8Rng,
    /// Noise of the conversions at output latches: a stream of its own, so that switching
    /// the sync on leaves the drive loop's pick-off noise as it was.
    latch_rng: ChaCha8Rng,
    lost: bool,
}

impl Pickoff {
    /// The pick-off with `config` (validated by the board) and its noise seeded by `seed`.
    pub fn new(config: PickoffConfig, seed: u64) -> Self {
        Self {
            config,
            rng: ChaCha8Rng::seed_from_u64(seed),
            latch_rng: ChaCha8Rng::seed_from_u64(seed ^ 0x4C41_5443_4845_5321),
            lost: false,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &PickoffConfig {
        &self.config
    }

    /// Loses the signal (`true`: the output sits at the offset) or restores it.
    pub fn set_lost(&mut self, lost: bool) {
        self.lost = lost;
    }

    /// True if the signal is lost.
    pub fn is_lost(&self) -> bool {
        self.lost
    }

    /// The noise-free output at `t_s` (the dither angle `lag_s` earlier), V.
    pub fn clean_v(&self, gyro: &Gyro, t_s: f64) -> f64 {
        if self.lost {
            return self.config.offset_v;
        }
        let v = self
            .config
            .voltage_v(gyro.dither_pickoff_arcsec(t_s - self.config.lag_s));
        // The gain moves with the block's temperature (`crate::thermal`; 1 at T_ref).
        let factor = gyro.params().thermal.pickoff_gain_factor(t_s);
        if factor == 1.0 {
            return v;
        }
        self.config.offset_v + (v - self.config.offset_v) * factor
    }

    /// The output at `t_s` with one noise draw, V.
    pub fn sample_v(&mut self, gyro: &Gyro, t_s: f64) -> f64 {
        let v = self.clean_v(gyro, t_s);
        if self.config.noise_rms_v == 0.0 {
            return v;
        }
        let z: f64 = StandardNormal.sample(&mut self.rng);
        v + self.config.noise_rms_v * z
    }

    /// One ADC conversion at `t_s` (one noise draw): the 12-bit code, clipped at 0..=4095.
    pub fn sample_code(&mut self, gyro: &Gyro, t_s: f64) -> AdcCode {
        let v = self.sample_v(gyro, t_s);
        self.config.adc.code(v)
    }

    /// One conversion at an output latch at `t_s` (its own noise stream), the 12-bit code.
    pub fn sample_latch_code(&mut self, gyro: &Gyro, t_s: f64) -> AdcCode {
        let mut v = self.clean_v(gyro, t_s);
        if self.config.noise_rms_v > 0.0 {
            let z: f64 = StandardNormal.sample(&mut self.latch_rng);
            v += self.config.noise_rms_v * z;
        }
        self.config.adc.code(v)
    }

    /// The comparator's output at `t_s`: the noise-free pick-off at or above `threshold_v`.
    pub fn comparator_high(&self, gyro: &Gyro, t_s: f64, threshold_v: f64) -> bool {
        self.clean_v(gyro, t_s) >= threshold_v
    }
}
