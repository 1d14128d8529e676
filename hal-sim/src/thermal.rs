//! How the simulated gyro follows its temperature: bias (with a dT/dt term), scale factor,
//! lock-in threshold Omega_L, photodiode phase eps and the pick-off's gain, on one temperature
//! profile of the block ([`TemperatureProfile`]: constant, ramps, steps, a warm-up transient),
//! which also moves the driven resonator's f0 and Q ([`GyroParams::with_temperature`]) and is
//! what the simulated TMP117 reads ([`crate::tmp117`]); the profile as the CLIs' users type it
//! is [`profile_text`].
//!
//! With `x = T - T_ref` and `Tdot` in °C/min (docs/physics.md section 13 gives the defaults'
//! sources):
//!
//! ```text
//! bias      = b1 x + b2 x^2 + b_rate Tdot                      deg/h (0 at T_ref, at rest)
//! SF error  = s1 x + s2 x^2                                    ppm: the gyro counts (1 + SF) x the input
//! Omega_L   = Omega_L (1 + l1 x)
//! eps       = eps + e1 x                                       rad
//! pick-off  = k (1 + gain_error) (1 + p1 x)
//! ```
//!
//! # How the integrator sees them
//!
//! - Bias, scale factor and eps enter the lock-in-free phase as a rate: the gyro measures the
//!   input `(1 + SF) Omega_in + bias`, and the photodiodes' phase offset eps moving with the
//!   temperature adds `eps'` to the beat phase whose lock-in term is `cos(psi)`, so that the
//!   phase the photodiodes see, `psi - eps(t)`, follows `Omega + Omega_L cos(psi_H + eps(t))`
//!   (the back-scatter phase moves, the counted phase does not). [`measured_input`] folds them
//!   into a piecewise-cubic rate over the profile's linear pieces (the input must be piecewise
//!   linear: constant, steps, ramps, a fixed table); the gyro keeps the true input for its
//!   truth (`Gyro::input_angle_arcsec`).
//! - Omega_L follows the profile per integration segment (`LockInDrift`), the pick-off's gain
//!   per conversion (`Pickoff`), eps at the photodiodes per sample (`SimBoard::eps_at`).
//!
//! A flat profile at `T_ref` changes nothing: the results are bit for bit those of a gyro
//! without thermal effects (the default).

pub mod profile_text;

use crate::dither::resonator::TemperatureProfile;
use crate::input::{InputProfile, PiecewiseRate};
use crate::param_error::ParamError;
use core::f64::consts::TAU;

/// The gyro's temperature sensitivities (see the module docs for the model).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThermalCoefficients {
    /// T_ref, °C: every effect is 0 there.
    pub reference_c: f64,
    /// b1, deg/h per °C. Range [-1, 1].
    pub bias_deg_h_per_c: f64,
    /// b2, deg/h per °C^2. Range [-0.01, 0.01].
    pub bias_deg_h_per_c2: f64,
    /// b_rate, deg/h per °C/min. Range [-1, 1].
    pub bias_deg_h_per_c_per_min: f64,
    /// s1, ppm per °C. Range [-100, 100].
    pub scale_factor_ppm_per_c: f64,
    /// s2, ppm per °C^2. Range [-1, 1].
    pub scale_factor_ppm_per_c2: f64,
    /// l1, relative per °C. Range [-0.01, 0.01].
    pub lock_in_per_c: f64,
    /// e1, rad per °C. Range [-0.05, 0.05].
    pub eps_rad_per_c: f64,
    /// p1, relative per °C. Range [-0.01, 0.01].
    pub pickoff_gain_per_c: f64,
    /// df0/dT of a driven dither resonator, Hz per °C (`TemperatureDrift::f0_hz_per_c`).
    /// Range [-1, 1].
    pub dither_hz_per_c: f64,
    /// (dQ/dT)/Q of a driven dither resonator, per °C. Range [-0.1, 0.1].
    pub dither_q_per_c: f64,
}

/// The largest magnitude of each coefficient ([`ThermalCoefficients::validate`]; `rlg-sim`'s
/// flags check against the same): `reference_c` is the range's bound on T_ref instead.
pub const LIMITS: ThermalCoefficients = ThermalCoefficients {
    reference_c: 150.0,
    bias_deg_h_per_c: 1.0,
    bias_deg_h_per_c2: 0.01,
    bias_deg_h_per_c_per_min: 1.0,
    scale_factor_ppm_per_c: 100.0,
    scale_factor_ppm_per_c2: 1.0,
    lock_in_per_c: 0.01,
    eps_rad_per_c: 0.05,
    pickoff_gain_per_c: 0.01,
    dither_hz_per_c: 1.0,
    dither_q_per_c: 0.1,
};

impl ThermalCoefficients {
    /// No thermal effect.
    pub const NONE: Self = Self {
        reference_c: 25.0,
        bias_deg_h_per_c: 0.0,
        bias_deg_h_per_c2: 0.0,
        bias_deg_h_per_c_per_min: 0.0,
        scale_factor_ppm_per_c: 0.0,
        scale_factor_ppm_per_c2: 0.0,
        lock_in_per_c: 0.0,
        eps_rad_per_c: 0.0,
        pickoff_gain_per_c: 0.0,
        dither_hz_per_c: 0.0,
        dither_q_per_c: 0.0,
    };

    /// The defaults (docs/physics.md section 13): over -20..+60 °C about 0.17 deg/h of bias
    /// change, 36 ppm of scale factor, 0.8 % of Omega_L, 0.04 rad of eps, 0.8 % of pick-off
    /// gain, 0.002 deg/h per °C/min of rate term, and a driven resonator's f0 -0.04 Hz/°C
    /// (a steel spring's -100 ppm/°C at 389 Hz).
    pub const DEFAULT: Self = Self {
        reference_c: 25.0,
        bias_deg_h_per_c: 0.002,
        bias_deg_h_per_c2: 2e-5,
        bias_deg_h_per_c_per_min: 0.002,
        scale_factor_ppm_per_c: 0.5,
        scale_factor_ppm_per_c2: 0.005,
        lock_in_per_c: 1e-4,
        eps_rad_per_c: 5e-4,
        pickoff_gain_per_c: -1e-4,
        dither_hz_per_c: -0.04,
        dither_q_per_c: 0.0,
    };

    /// Each coefficient with its name (as `rlg-sim`'s flags spell it after `--thermal-`) and
    /// its largest magnitude ([`LIMITS`]).
    pub fn each(&self) -> [(&'static str, f64, f64); 10] {
        let l = LIMITS;
        [
            (
                "bias-deg-h-per-c",
                self.bias_deg_h_per_c,
                l.bias_deg_h_per_c,
            ),
            (
                "bias-deg-h-per-c2",
                self.bias_deg_h_per_c2,
                l.bias_deg_h_per_c2,
            ),
            (
                "bias-deg-h-per-c-per-min",
                self.bias_deg_h_per_c_per_min,
                l.bias_deg_h_per_c_per_min,
            ),
            (
                "sf-ppm-per-c",
                self.scale_factor_ppm_per_c,
                l.scale_factor_ppm_per_c,
            ),
            (
                "sf-ppm-per-c2",
                self.scale_factor_ppm_per_c2,
                l.scale_factor_ppm_per_c2,
            ),
            ("lock-in-per-c", self.lock_in_per_c, l.lock_in_per_c),
            ("eps-rad-per-c", self.eps_rad_per_c, l.eps_rad_per_c),
            (
                "pickoff-gain-per-c",
                self.pickoff_gain_per_c,
                l.pickoff_gain_per_c,
            ),
            ("dither-hz-per-c", self.dither_hz_per_c, l.dither_hz_per_c),
            ("dither-q-per-c", self.dither_q_per_c, l.dither_q_per_c),
        ]
    }

    /// Checks every coefficient against its range ([`LIMITS`]); the error names the first
    /// one out of it.
    pub fn validate(&self) -> Result<(), ParamError> {
        let reference_ok =
            self.reference_c.is_finite() && self.reference_c.abs() <= LIMITS.reference_c;
        if !reference_ok {
            return Err(ParamError::OutOfRange(
                "thermal T_ref: within -150..=150 °C",
            ));
        }
        match self
            .each()
            .into_iter()
            .find(|(_, v, lim)| !(v.is_finite() && v.abs() <= *lim))
        {
            Some((name, _, _)) => Err(ParamError::OutOfRange(name)),
            None => Ok(()),
        }
    }

    /// The bias at `temp_c` and `rate_c_per_min`, deg/h.
    pub fn bias_deg_h(&self, temp_c: f64, rate_c_per_min: f64) -> f64 {
        let x = temp_c - self.reference_c;
        x * (self.bias_deg_h_per_c + x * self.bias_deg_h_per_c2)
            + self.bias_deg_h_per_c_per_min * rate_c_per_min
    }

    /// The scale-factor error at `temp_c`, ppm.
    pub fn scale_factor_ppm(&self, temp_c: f64) -> f64 {
        let x = temp_c - self.reference_c;
        x * (self.scale_factor_ppm_per_c + x * self.scale_factor_ppm_per_c2)
    }
}

/// The gyro block's temperature and what it does to the gyro.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroThermal {
    /// The block's temperature over the run.
    pub profile: TemperatureProfile,
    /// The sensitivities.
    pub coefficients: ThermalCoefficients,
}

impl GyroThermal {
    /// 25 °C throughout with the default coefficients: no effect (T = T_ref).
    pub const DEFAULT: Self = Self {
        profile: TemperatureProfile::constant(25.0),
        coefficients: ThermalCoefficients::DEFAULT,
    };

    /// Whether anything changes: the profile leaves T_ref.
    pub fn is_on(&self) -> bool {
        let (lo, hi) = self.profile.range_c();
        !(lo == hi && lo == self.coefficients.reference_c)
    }

    /// `T - T_ref` at `t_s`, °C.
    pub fn offset_c(&self, t_s: f64) -> f64 {
        self.profile.at(t_s) - self.coefficients.reference_c
    }

    /// Omega_L's factor at `t_s`.
    pub fn lock_in_factor(&self, t_s: f64) -> f64 {
        if !self.is_on() {
            return 1.0;
        }
        1.0 + self.coefficients.lock_in_per_c * self.offset_c(t_s)
    }

    /// eps's change at `t_s`, rad.
    pub fn eps_offset_rad(&self, t_s: f64) -> f64 {
        if !self.is_on() {
            return 0.0;
        }
        self.coefficients.eps_rad_per_c * self.offset_c(t_s)
    }

    /// The pick-off gain's factor at `t_s`.
    pub fn pickoff_gain_factor(&self, t_s: f64) -> f64 {
        if !self.is_on() {
            return 1.0;
        }
        1.0 + self.coefficients.pickoff_gain_per_c * self.offset_c(t_s)
    }
}

fn poly_mul(a: &[f64], b: &[f64]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            if i + j < 4 {
                out[i + j] += x * y;
            }
        }
    }
    out
}

/// The rate the gyro measures, `(1 + SF) input + bias + eps'` (see the module docs), as a
/// piecewise-cubic input over the profile's linear pieces and the input's own. `input` itself
/// when the thermal effects are off. Needs a piecewise-linear input (or a constant one).
pub fn measured_input(
    input: &InputProfile,
    thermal: &GyroThermal,
    scale_factor_arcsec: f64,
) -> Result<InputProfile, ParamError> {
    if !thermal.is_on() {
        return Ok(input.clone());
    }
    let input_pieces: Vec<(f64, [f64; 4])> = match input {
        InputProfile::Piecewise(p) => p.pieces().collect(),
        _ => {
            // A constant in disguise (a fixed table, a sine of frequency 0).
            let (r0, r1) = (input.rate_deg_per_h(0.0), input.rate_deg_per_h(1.0));
            if r0 != r1
                || !matches!(input, InputProfile::RotaryTable { table_rate_rad_per_s, .. } if *table_rate_rad_per_s == 0.0)
                    && !matches!(input, InputProfile::Sinusoid { freq_hz, .. } if *freq_hz == 0.0)
            {
                return Err(ParamError::OutOfRange(
                    "thermal effects need a piecewise-linear input (constant, steps, ramps, a \\
                     fixed table)",
                ));
            }
            vec![(0.0, [r0, 0.0, 0.0, 0.0])]
        }
    };
    let c = &thermal.coefficients;
    let profile = &thermal.profile;
    let mut times: Vec<f64> = profile.linear_pieces();
    times.extend(input_pieces.iter().map(|p| p.0));
    times.sort_by(f64::total_cmp);
    times.dedup();
    let eps_arcsec_per_rad = scale_factor_arcsec / TAU;
    let mut pieces = Vec::with_capacity(times.len());
    for (k, &a) in times.iter().enumerate() {
        let i = input_pieces.partition_point(|p| p.0 <= a).saturating_sub(1);
        let (start, coef) = input_pieces[i];
        // The input's rate as a polynomial in the time since `a` (input pieces are linear).
        let d = a - start;
        let r = [coef[0] + coef[1] * d, coef[1]];
        let (x_a, g) = match times.get(k + 1) {
            Some(&b) => {
                let x_a = profile.at(a) - c.reference_c;
                (x_a, (profile.at(b) - profile.at(a)) / (b - a))
            }
            None => (profile.at(a) - c.reference_c, 0.0),
        };
        let x = [x_a, g];
        let x2 = poly_mul(&x, &x);
        let bias = [
            c.bias_deg_h_per_c * x_a
                + c.bias_deg_h_per_c2 * x2[0]
                + c.bias_deg_h_per_c_per_min * g * 60.0
                + c.eps_rad_per_c * g * eps_arcsec_per_rad,
            c.bias_deg_h_per_c * g + c.bias_deg_h_per_c2 * x2[1],
            c.bias_deg_h_per_c2 * x2[2],
        ];
        let sf = [
            1e-6 * (c.scale_factor_ppm_per_c * x_a + c.scale_factor_ppm_per_c2 * x2[0]),
            1e-6 * (c.scale_factor_ppm_per_c * g + c.scale_factor_ppm_per_c2 * x2[1]),
            1e-6 * c.scale_factor_ppm_per_c2 * x2[2],
        ];
        let scaled = poly_mul(&r, &sf);
        let mut rate = [r[0], r[1], 0.0, 0.0];
        for j in 0..4 {
            rate[j] += scaled[j] + bias.get(j).copied().unwrap_or(0.0);
        }
        pieces.push((a, rate));
    }
    Ok(InputProfile::Piecewise(PiecewiseRate::polynomial(&pieces)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The measured angle is the integral of `(1 + SF) input + bias + eps'` along the profile:
    /// against a fine trapezoid of the model's own functions (a ramp and a warm-up).
    #[test]
    fn the_measured_angle_integrates_the_model() {
        let sf = 1.8655;
        for profile in [
            TemperatureProfile::knots(&[(1.0, -20.0), (9.0, 60.0), (12.0, 40.0)]).unwrap(),
            TemperatureProfile::warm_up(10.0, 45.0, 3.0).unwrap(),
        ] {
            let thermal = GyroThermal {
                profile,
                coefficients: ThermalCoefficients::DEFAULT,
            };
            let input = InputProfile::steps(3600.0, &[(5.0, -7200.0)]);
            let measured = measured_input(&input, &thermal, sf).unwrap();
            let c = thermal.coefficients;
            // The midpoint rule on a grid that holds every step and knot: O(h^2) in between.
            let n = 140_000;
            let h = 14.0 / n as f64;
            let rate = |t: f64| {
                let temp = profile.at(t);
                input.rate_deg_per_h(t) * (1.0 + 1e-6 * c.scale_factor_ppm(temp))
                    + c.bias_deg_h(temp, 60.0 * profile.rate_c_per_s(t))
                    + c.eps_rad_per_c * profile.rate_c_per_s(t) * sf / TAU
            };
            let mut acc = 0.0;
            for i in 0..n {
                acc += h * rate((i as f64 + 0.5) * h);
            }
            let got = measured.angle_arcsec(14.0);
            // The warm-up's linear pieces (tau/16): 1e-3 arcsec.
            assert!((got - acc).abs() < 1e-3, "{got} vs {acc}");
            let thermal_part = got - input.angle_arcsec(14.0);
            assert!(thermal_part.abs() > 0.05, "{thermal_part}");
        }
    }

    #[test]
    fn off_at_the_reference() {
        let input = InputProfile::constant(5.0);
        let out = measured_input(&input, &GyroThermal::DEFAULT, 1.8655).unwrap();
        assert_eq!(out, input);
    }
}
