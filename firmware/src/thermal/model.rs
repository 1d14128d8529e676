//! The thermal model of the gyro's bias and scale factor, as stored with the calibration and
//! applied to the output.
//!
//! With `x = T - T_ref` (°C) and `Tdot` the temperature's rate (°C/min):
//!
//! ```text
//! bias(T, Tdot)  = b0 + b1 x + b2 x^2 + b3 x^3 + b_rate Tdot        deg/h
//! scale(T)       = s0 + s1 x + s2 x^2                                ppm of the nominal SF
//! ```
//!
//! The gyro's output over a period `dt` is `(1 + scale 1e-6) true + bias dt`; the board
//! corrects each output increment to `(measured - bias dt) / (1 + scale 1e-6)`
//! (`signal::output::record`). A cubic in T is what published RLG thermal models use for the
//! block temperature; the rate term stands for the thermal gradients across the block that a
//! changing temperature sets up (docs/physics.md section 13). The model is valid over the
//! temperatures it was fitted on, `[min_c, max_c]`: outside them it is not applied (a cubic
//! extrapolates badly), and the records say so.

/// Bounds of a plausible model: a sensor range and corrections no gyro needs more of.
pub const SENSOR_MIN_C: f32 = -55.0;
/// Highest temperature the sensor reports (TMP117: +150 °C).
pub const SENSOR_MAX_C: f32 = 150.0;
/// Largest bias correction a plausible model makes anywhere in its range, deg/h.
pub const MAX_BIAS_DEG_H: f32 = 100.0;
/// Largest scale-factor correction a plausible model makes anywhere in its range, ppm.
pub const MAX_SCALE_PPM: f32 = 10_000.0;

/// The first [`TEMPERATURES`] of [`ThermalModel::NAMES`] are temperatures (°C).
pub const TEMPERATURES: usize = 3;

/// The model's coefficients (immutable once applied; the protocol edits a copy).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermalModel {
    /// T_ref, °C.
    pub reference_c: f32,
    /// Lowest temperature the model holds for, °C.
    pub min_c: f32,
    /// Highest temperature the model holds for, °C.
    pub max_c: f32,
    /// b0..b3: deg/h, deg/h/°C, deg/h/°C^2, deg/h/°C^3.
    pub bias_deg_h: [f32; 4],
    /// b_rate: deg/h per °C/min.
    pub bias_deg_h_per_c_per_min: f32,
    /// s0..s2: ppm, ppm/°C, ppm/°C^2.
    pub scale_ppm: [f32; 3],
}

/// Why a model is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ModelError {
    /// A coefficient is NaN or infinite.
    NotFinite,
    /// The range is empty, outside the sensor's, or does not hold T_ref.
    Range,
    /// The corrections exceed [`MAX_BIAS_DEG_H`] or [`MAX_SCALE_PPM`] somewhere in the range.
    Implausible,
}

impl ThermalModel {
    /// The coefficients in the protocol's order: `t_ref t_min t_max b0 b1 b2 b3 b_rate s0 s1 s2`.
    pub const NAMES: [&'static str; 11] = [
        "t_ref", "t_min", "t_max", "b0", "b1", "b2", "b3", "b_rate", "s0", "s1", "s2",
    ];

    /// Every coefficient in [`Self::NAMES`]' order.
    pub fn values(&self) -> [f32; 11] {
        let [b0, b1, b2, b3] = self.bias_deg_h;
        let [s0, s1, s2] = self.scale_ppm;
        [
            self.reference_c,
            self.min_c,
            self.max_c,
            b0,
            b1,
            b2,
            b3,
            self.bias_deg_h_per_c_per_min,
            s0,
            s1,
            s2,
        ]
    }

    /// A model from the coefficients in [`Self::NAMES`]' order.
    pub fn from_values(v: [f32; 11]) -> Self {
        let [reference_c, min_c, max_c, b0, b1, b2, b3, b_rate, s0, s1, s2] = v;
        Self {
            reference_c,
            min_c,
            max_c,
            bias_deg_h: [b0, b1, b2, b3],
            bias_deg_h_per_c_per_min: b_rate,
            scale_ppm: [s0, s1, s2],
        }
    }

    /// The plausibility checks (before applying or storing, and after loading).
    pub fn check(&self) -> Result<(), ModelError> {
        if !self.values().iter().all(|v| v.is_finite()) {
            return Err(ModelError::NotFinite);
        }
        let range_ok = SENSOR_MIN_C <= self.min_c
            && self.min_c < self.max_c
            && self.max_c <= SENSOR_MAX_C
            && (self.min_c..=self.max_c).contains(&self.reference_c);
        if !range_ok {
            return Err(ModelError::Range);
        }
        // The polynomials' extremes lie at the ends or at stationary points: 65 points over the
        // range bound them closely enough for a plausibility check.
        let plausible = (0..=64).all(|i| {
            let t = self.min_c + (self.max_c - self.min_c) * i as f32 / 64.0;
            self.bias_deg_h(t, 0.0).abs() <= MAX_BIAS_DEG_H
                && self.scale_ppm(t).abs() <= MAX_SCALE_PPM
        }) && self.bias_deg_h_per_c_per_min.abs() * 10.0 <= MAX_BIAS_DEG_H;
        if !plausible {
            return Err(ModelError::Implausible);
        }
        Ok(())
    }

    /// Whether `temp_c` lies in the model's range.
    pub fn holds_at(&self, temp_c: f32) -> bool {
        (self.min_c..=self.max_c).contains(&temp_c)
    }

    /// The bias at `temp_c` and a rate of `rate_c_per_min`, deg/h.
    pub fn bias_deg_h(&self, temp_c: f32, rate_c_per_min: f32) -> f32 {
        let x = temp_c - self.reference_c;
        let [b0, b1, b2, b3] = self.bias_deg_h;
        b0 + x * (b1 + x * (b2 + x * b3)) + self.bias_deg_h_per_c_per_min * rate_c_per_min
    }

    /// The scale-factor error at `temp_c`, ppm.
    pub fn scale_ppm(&self, temp_c: f32) -> f32 {
        let x = temp_c - self.reference_c;
        let [s0, s1, s2] = self.scale_ppm;
        s0 + x * (s1 + x * s2)
    }

    /// Whether the model needs the rate.
    pub fn uses_rate(&self) -> bool {
        self.bias_deg_h_per_c_per_min != 0.0
    }
}

/// What the output stage subtracts, in its own units (`signal::output::record`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermalCorrection {
    /// The bias, fringes per second (deg/h over the scale factor in arcsec per fringe).
    pub bias_fringes_per_s: f32,
    /// The scale-factor error, relative (ppm x 1e-6).
    pub scale_error: f32,
}

impl ThermalCorrection {
    /// The model's correction at `temp_c` and `rate_c_per_min` for a gyro of
    /// `scale_factor_arcsec` per fringe (1 deg/h = 1 arcsec/s).
    pub fn of(
        model: &ThermalModel,
        temp_c: f32,
        rate_c_per_min: f32,
        scale_factor_arcsec: f32,
    ) -> Self {
        Self {
            bias_fringes_per_s: model.bias_deg_h(temp_c, rate_c_per_min) / scale_factor_arcsec,
            scale_error: model.scale_ppm(temp_c) * 1e-6,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn model() -> ThermalModel {
        ThermalModel {
            reference_c: 25.0,
            min_c: -20.0,
            max_c: 60.0,
            bias_deg_h: [0.001, 0.002, 2e-5, 0.0],
            bias_deg_h_per_c_per_min: 0.002,
            scale_ppm: [0.0, 0.5, 0.005],
        }
    }

    #[test]
    fn evaluates_and_checks() {
        let m = model();
        assert!(m.check().is_ok());
        // x = 35: 0.001 + 0.07 + 0.0245, and 1 °C/min more.
        assert!((m.bias_deg_h(60.0, 1.0) - 0.0975).abs() < 1e-6);
        assert!((m.scale_ppm(-20.0) - (-22.5 + 10.125)).abs() < 1e-4);
        assert_eq!(ThermalModel::from_values(m.values()), m);
        let bad = ThermalModel { min_c: 30.0, ..m };
        assert_eq!(bad.check(), Err(ModelError::Range));
        let bad = ThermalModel {
            scale_ppm: [0.0, 1000.0, 0.0],
            ..m
        };
        assert_eq!(bad.check(), Err(ModelError::Implausible));
        let bad = ThermalModel {
            reference_c: f32::NAN,
            ..m
        };
        assert_eq!(bad.check(), Err(ModelError::NotFinite));
    }
}
