//! The record's parts besides the compensation settings, each with the plausibility check
//! the store applies before writing and after loading: the fit's summary, the dither drive's
//! setpoints, the dither stripping's coefficients, the thermal model. The byte layout is the module's
//! ([`super`]); these are the values.

use super::RecordError;
use crate::calibration::fit::FitResult;
use crate::thermal::model::ThermalModel;

/// Largest dither amplitude setpoint a record may hold, arcsec (far above any dither: a sanity
/// bound for the record; the drive applies its own, narrower range).
pub const MAX_DITHER_AMPLITUDE_ARCSEC: f32 = 10_000.0;

/// The dither drive's setpoints as stored: what the board starts the drive with at power-up.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DitherSetpoints {
    /// Drive on at power-up.
    pub enabled: bool,
    /// Peak dither amplitude the amplitude loop holds, arcsec of body angle (0 exclusive to
    /// [`MAX_DITHER_AMPLITUDE_ARCSEC`]).
    pub amplitude_arcsec: f32,
    /// Random-noise dither depth, percent of the setpoint (0 = off, at most 100).
    pub noise_percent: f32,
}

impl DitherSetpoints {
    /// Finite, amplitude in (0, [`MAX_DITHER_AMPLITUDE_ARCSEC`]], noise in [0, 100].
    pub fn check(&self) -> Result<(), RecordError> {
        let amplitude_ok =
            self.amplitude_arcsec > 0.0 && self.amplitude_arcsec <= MAX_DITHER_AMPLITUDE_ARCSEC;
        let noise_ok = (0.0..=100.0).contains(&self.noise_percent);
        if amplitude_ok && noise_ok {
            Ok(())
        } else {
            Err(RecordError::ImplausibleDither)
        }
    }
}

/// The fit behind the stored coefficients, condensed for the record (see the module table).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FitSummary {
    /// Dither cycles in the fit (saturates at `u32::MAX`).
    pub cycles: u32,
    /// Runs pooled (saturates at `u16::MAX`).
    pub runs: u16,
    /// Standard error of a, rad/s (>= 0).
    pub a_std_rad_per_s: f32,
    /// Standard error of b, rad/s (>= 0).
    pub b_std_rad_per_s: f32,
    /// Residual standard deviation of the per-cycle output, rad (>= 0).
    pub residual_std_rad: f32,
    /// 1 - residual variance / output variance (<= 1).
    pub variance_reduction: f32,
    /// Condition number of the normalised P1/P2 covariance (>= 1; infinite when collinear).
    pub condition_number: f32,
    /// Mean output rate over all runs (the input rate), rad/s of beat phase.
    pub mean_rate_rad_per_s: f32,
}

impl FitSummary {
    /// Condenses a fit: f64 -> f32 (rounded; beyond the f32 range it becomes infinite, which the
    /// checks accept), counts saturated.
    pub fn from_fit(fit: &FitResult) -> Self {
        Self {
            cycles: u32::try_from(fit.cycles).unwrap_or(u32::MAX),
            runs: u16::try_from(fit.runs).unwrap_or(u16::MAX),
            a_std_rad_per_s: fit.a_std_rad_per_s as f32,
            b_std_rad_per_s: fit.b_std_rad_per_s as f32,
            residual_std_rad: fit.residual_std_rad as f32,
            variance_reduction: fit.variance_reduction as f32,
            condition_number: fit.condition_number as f32,
            mean_rate_rad_per_s: fit.mean_rate_rad_per_s as f32,
        }
    }

    /// No NaN; standard deviations >= 0; condition number >= 1; variance reduction <= 1.
    pub fn check(&self) -> Result<(), RecordError> {
        let values = [
            self.a_std_rad_per_s,
            self.b_std_rad_per_s,
            self.residual_std_rad,
            self.variance_reduction,
            self.condition_number,
            self.mean_rate_rad_per_s,
        ];
        let plausible = values.iter().all(|value| !value.is_nan())
            && self.a_std_rad_per_s >= 0.0
            && self.b_std_rad_per_s >= 0.0
            && self.residual_std_rad >= 0.0
            && self.condition_number >= 1.0
            && self.variance_reduction <= 1.0;
        if plausible {
            Ok(())
        } else {
            Err(RecordError::ImplausibleFit)
        }
    }
}

/// The dither stripping's coefficients as stored (fixed point, Q8.24 fringes per pick-off
/// code): the taps on the modelled dither in phase and in quadrature
/// (`signal::output::strip`). What the board starts its stripping with at power-up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StripCoefficients {
    /// K, Q8.24 fringes per code.
    pub k_q24: i32,
    /// K_q, Q8.24 fringes per code.
    pub k_quadrature_q24: i32,
}

impl StripCoefficients {
    /// One Q8.24 unit.
    const ONE: f32 = (1u32 << 24) as f32;

    /// From the taps in fringes per code; `None` when one is not finite or beyond +-128.
    pub fn from_fringes_per_code(k: f32, k_quadrature: f32) -> Option<Self> {
        let q = |x: f32| {
            let v = x * Self::ONE;
            (x.is_finite() && v.abs() < i32::MAX as f32).then(|| crate::math::round_f32_to_i32(v))
        };
        Some(Self {
            k_q24: q(k)?,
            k_quadrature_q24: q(k_quadrature)?,
        })
    }

    /// K in fringes per code.
    pub fn k(&self) -> f32 {
        self.k_q24 as f32 / Self::ONE
    }

    /// K_q in fringes per code.
    pub fn k_quadrature(&self) -> f32 {
        self.k_quadrature_q24 as f32 / Self::ONE
    }

    /// A K of zero strips nothing: no board stores one (the fit refuses a zero K).
    pub fn check(&self) -> Result<(), RecordError> {
        if self.k_q24 == 0 {
            Err(RecordError::ImplausibleStrip)
        } else {
            Ok(())
        }
    }
}

/// The thermal model as stored (`crate::thermal::model`), with its switch: what the board
/// corrects its output with from power-up on.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermalCalibration {
    /// The coefficients and the temperatures they hold for.
    pub model: ThermalModel,
    /// Applied (`thermal on`) or kept but not applied (`thermal off`).
    pub enabled: bool,
}

impl ThermalCalibration {
    /// The model's own plausibility checks (`ThermalModel::check`).
    pub fn check(&self) -> Result<(), RecordError> {
        self.model
            .check()
            .map_err(|_| RecordError::ImplausibleThermal)
    }
}
