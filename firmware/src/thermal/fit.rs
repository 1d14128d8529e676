//! The thermal calibration's fits: the bias model from a log of the output against temperature,
//! the scale-factor model from scale factors measured at several temperatures, and their
//! validity checks. Host code (`rlg-cal thermal`, `rlg-sim characterize --thermal`, the system
//! tests) runs them; the board only applies their result ([`super::model`]).
//!
//! # The bias fit: on the integrated angle
//!
//! The fixed-rate output's noise is white in *angle* (the pick-off read once per latch,
//! docs/physics.md section 12): a record's increment carries the difference of two such errors.
//! Fitting biases window by window averages that noise only over each window; the least-squares
//! fit of the *integrated* angle error on the integrated regressors is the best linear one for
//! white angle noise (the same reason the sweep's rate is the slope of the integrated angle):
//!
//! ```text
//! e(t_k) = sum_j c_j integral_0^t_k phi_j dt + e0,    phi = [1, x, x^2, x^3, Tdot]
//! ```
//!
//! with `e` the output's angle minus the true angle (arcsec; 1 deg/h = 1 arcsec/s),
//! `x = T - T_ref` from the board's own sensor, `Tdot` in °C/min, and one offset `e0` per
//! unbroken stretch of records (a lost record starts a new one). Regressors are scaled
//! (x by 50 °C, Tdot by 10 °C/min) before the normal equations are formed.
//!
//! # Checks
//!
//! A fit is refused ([`FitError`]) with too few records, a temperature span under
//! [`MIN_SPAN_C`], or singular normal equations. The rate term is fitted only when the log's
//! rates spread by [`MIN_RATE_SPREAD_C_PER_MIN`] or more (a single ramp has one rate, which the
//! T terms cannot be told from); otherwise it is 0 and the fit says so. The result must pass
//! the model's own plausibility checks (`ThermalModel::check`).

use super::model::{ModelError, ThermalModel};

/// The smallest temperature span a fit accepts, °C.
pub const MIN_SPAN_C: f64 = 10.0;
/// The smallest spread (standard deviation) of the rate that makes its term fitted, °C/min.
pub const MIN_RATE_SPREAD_C_PER_MIN: f64 = 0.2;
/// The fewest records a bias fit accepts.
pub const MIN_RECORDS: u64 = 1000;
/// Most unbroken stretches of records (each has its own offset): a log of ramps and soaks
/// from which the transients and the table's runs are left out has a few dozen.
pub const MAX_STRETCHES: usize = 32;

const X_SCALE_C: f64 = 50.0;
const RATE_SCALE: f64 = 10.0;
const TERMS: usize = 5;
const UNKNOWNS: usize = TERMS + MAX_STRETCHES;

/// Why a fit is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FitError {
    /// Fewer records or points than the fit needs.
    TooFew,
    /// The temperatures span less than [`MIN_SPAN_C`].
    NarrowSpan,
    /// More unbroken stretches than [`MAX_STRETCHES`].
    TooManyStretches,
    /// The normal equations are singular.
    Singular,
    /// The fitted model fails its plausibility checks.
    Model(ModelError),
}

impl FitError {
    /// Words for a person.
    pub fn text(&self) -> &'static str {
        match self {
            Self::TooFew => "too few records or points",
            Self::NarrowSpan => "temperature span under 10 C",
            Self::TooManyStretches => "more than 32 unbroken stretches of records",
            Self::Singular => "singular normal equations",
            Self::Model(_) => "the fitted model is implausible",
        }
    }
}

/// Solves the symmetric system `a x = b` of size `n` (Gauss-Jordan with partial pivoting).
#[allow(clippy::indexing_slicing)] // row and column indices count below n, clamped to N
fn solve<const N: usize>(mut a: [[f64; N]; N], mut b: [f64; N], n: usize) -> Option<[f64; N]> {
    let n = n.min(N);
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() <= 1e-12 || a[pivot][col].is_nan() {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (pivot_row, pivot_b) = (a[col], b[col]);
        for (row, (values, rhs)) in a.iter_mut().zip(b.iter_mut()).enumerate().take(n) {
            if row != col {
                let f = values[col] / pivot_row[col];
                for (v, p) in values.iter_mut().zip(pivot_row.iter()).take(n).skip(col) {
                    *v -= f * p;
                }
                *rhs -= f * pivot_b;
            }
        }
    }
    let mut x = [0.0; N];
    for i in 0..n {
        x[i] = b[i] / a[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The bias fit's accumulator (see the module docs).
#[derive(Clone, Debug)]
pub struct BiasFit {
    reference_c: f64,
    /// The integrated regressors (scaled), s.
    integral: [f64; TERMS],
    /// The integrated angle error, arcsec.
    error_arcsec: f64,
    stretch: usize,
    broken: bool,
    /// Normal equations over [terms, one offset per stretch], and the right-hand side.
    ata: [[f64; UNKNOWNS]; UNKNOWNS],
    aty: [f64; UNKNOWNS],
    records: u64,
    min_c: f64,
    max_c: f64,
    rate_sum: f64,
    rate_sq: f64,
}

/// A fitted bias model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BiasResult {
    /// b0..b3 (deg/h per °C^k) and b_rate (deg/h per °C/min).
    pub bias_deg_h: [f64; 4],
    /// The rate coefficient (0 when not fitted).
    pub bias_deg_h_per_c_per_min: f64,
    /// Whether the rate term was fitted.
    pub rate_fitted: bool,
    /// The temperatures the log spans, °C.
    pub min_c: f64,
    /// Highest temperature of the log, °C.
    pub max_c: f64,
    /// Records used.
    pub records: u64,
}

impl BiasFit {
    /// An empty fit around `reference_c`.
    pub fn new(reference_c: f64) -> Self {
        Self {
            reference_c,
            integral: [0.0; TERMS],
            error_arcsec: 0.0,
            stretch: 0,
            broken: false,
            ata: [[0.0; UNKNOWNS]; UNKNOWNS],
            aty: [0.0; UNKNOWNS],
            records: 0,
            min_c: f64::INFINITY,
            max_c: f64::NEG_INFINITY,
            rate_sum: 0.0,
            rate_sq: 0.0,
        }
    }

    /// One record: its period `dt_s`, the board's temperature and rate over it, and its angle
    /// error (the record's increment minus the true one), arcsec.
    pub fn push(&mut self, dt_s: f64, temp_c: f64, rate_c_per_min: f64, error_arcsec: f64) {
        if self.broken {
            self.broken = false;
            if self.records > 0 {
                self.stretch += 1;
            }
        }
        let x = (temp_c - self.reference_c) / X_SCALE_C;
        let phi = [1.0, x, x * x, x * x * x, rate_c_per_min / RATE_SCALE];
        for (i, p) in self.integral.iter_mut().zip(phi) {
            *i += p * dt_s;
        }
        self.error_arcsec += error_arcsec;
        self.records += 1;
        self.min_c = self.min_c.min(temp_c);
        self.max_c = self.max_c.max(temp_c);
        self.rate_sum += rate_c_per_min;
        self.rate_sq += rate_c_per_min * rate_c_per_min;
        if self.stretch >= MAX_STRETCHES {
            return;
        }
        let mut row = [0.0; UNKNOWNS];
        for (r, i) in row.iter_mut().zip(self.integral) {
            *r = i;
        }
        if let Some(offset) = row.get_mut(TERMS + self.stretch) {
            *offset = 1.0;
        }
        let rows = self.ata.iter_mut().zip(self.aty.iter_mut()).zip(row);
        for ((ata_row, aty), ri) in rows.filter(|(_, ri)| *ri != 0.0) {
            *aty += ri * self.error_arcsec;
            for (a, rj) in ata_row.iter_mut().zip(row) {
                *a += ri * rj;
            }
        }
    }

    /// A record was lost: the next one starts a new stretch (its own offset).
    pub fn break_stretch(&mut self) {
        self.broken = true;
    }

    /// Solves (see the module docs for the checks).
    pub fn solve(&self) -> Result<BiasResult, FitError> {
        if self.records < MIN_RECORDS {
            return Err(FitError::TooFew);
        }
        if self.stretch >= MAX_STRETCHES {
            return Err(FitError::TooManyStretches);
        }
        if self.max_c - self.min_c < MIN_SPAN_C {
            return Err(FitError::NarrowSpan);
        }
        let n = self.records as f64;
        let mean = self.rate_sum / n;
        let spread = libm::sqrt((self.rate_sq / n - mean * mean).max(0.0));
        let rate_fitted = spread >= MIN_RATE_SPREAD_C_PER_MIN;
        // Without the rate term: drop unknown 4 (move the offsets down by one).
        let keep: [usize; UNKNOWNS] = core::array::from_fn(|i| {
            if rate_fitted || i < 4 {
                i
            } else {
                (i + 1).min(UNKNOWNS - 1)
            }
        });
        let unknowns = TERMS + self.stretch + 1 - usize::from(!rate_fitted);
        let mut a = [[0.0; UNKNOWNS]; UNKNOWNS];
        let mut b = [0.0; UNKNOWNS];
        let rows = a.iter_mut().zip(b.iter_mut()).zip(keep).take(unknowns);
        for ((a_row, b_i), ki) in rows {
            *b_i = self.aty.get(ki).copied().unwrap_or(0.0);
            let source = self.ata.get(ki);
            for (a_ij, kj) in a_row.iter_mut().zip(keep).take(unknowns) {
                *a_ij = source.and_then(|r| r.get(kj)).copied().unwrap_or(0.0);
            }
        }
        let x = solve(a, b, unknowns).ok_or(FitError::Singular)?;
        let [c0, c1, c2, c3, c_rate, ..] = x;
        let bias = [
            c0,
            c1 / X_SCALE_C,
            c2 / (X_SCALE_C * X_SCALE_C),
            c3 / (X_SCALE_C * X_SCALE_C * X_SCALE_C),
        ];
        Ok(BiasResult {
            bias_deg_h: bias,
            bias_deg_h_per_c_per_min: if rate_fitted {
                c_rate / RATE_SCALE
            } else {
                0.0
            },
            rate_fitted,
            min_c: self.min_c,
            max_c: self.max_c,
            records: self.records,
        })
    }
}

/// A fitted scale-factor model: s0..s2, ppm per °C^k.
pub fn fit_scale(reference_c: f64, points: &[(f64, f64)]) -> Result<[f64; 3], FitError> {
    if points.len() < 4 {
        return Err(FitError::TooFew);
    }
    let (lo, hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
            (l.min(p.0), h.max(p.0))
        });
    if hi - lo < MIN_SPAN_C {
        return Err(FitError::NarrowSpan);
    }
    let mut a = [[0.0; 3]; 3];
    let mut b = [0.0; 3];
    for &(t, ppm) in points {
        let x = (t - reference_c) / X_SCALE_C;
        let phi = [1.0, x, x * x];
        for ((a_row, b_i), pi) in a.iter_mut().zip(b.iter_mut()).zip(phi) {
            *b_i += pi * ppm;
            for (a_ij, pj) in a_row.iter_mut().zip(phi) {
                *a_ij += pi * pj;
            }
        }
    }
    let [s0, s1, s2] = solve(a, b, 3).ok_or(FitError::Singular)?;
    Ok([s0, s1 / X_SCALE_C, s2 / (X_SCALE_C * X_SCALE_C)])
}

/// The model of a bias fit and a scale-factor fit (`scale`: ppm per °C^k), valid over the
/// bias log's temperatures, checked.
pub fn model_of(
    reference_c: f64,
    bias: &BiasResult,
    scale: [f64; 3],
) -> Result<ThermalModel, FitError> {
    let model = ThermalModel {
        reference_c: reference_c as f32,
        min_c: bias.min_c as f32,
        max_c: bias.max_c as f32,
        bias_deg_h: bias.bias_deg_h.map(|c| c as f32),
        bias_deg_h_per_c_per_min: bias.bias_deg_h_per_c_per_min as f32,
        scale_ppm: scale.map(|c| c as f32),
    };
    model.check().map_err(FitError::Model)?;
    Ok(model)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    /// A log generated from a known model (up and down ramps, white angle noise of 0.5 arcsec
    /// per record at 1 kHz): the fit returns the model's coefficients to within what the noise
    /// allows; one rate only: the rate term is not fitted.
    #[test]
    fn recovers_a_known_bias_model() {
        let truth = [0.001, 0.002, 2e-5, 1e-7];
        let b_rate = 0.002;
        let mut rng = XorShift(7);
        let mut fit = BiasFit::new(25.0);
        let (dt, n) = (1e-3, 160_000);
        let mut last_noise = 0.0;
        for k in 0..n {
            let t = k as f64 * dt;
            // -20 -> 60 °C over 80 s, and back: +-60 °C/min.
            let (temp, rate) = if t < 80.0 {
                (-20.0 + t, 60.0)
            } else {
                (60.0 - (t - 80.0), -60.0)
            };
            let x = temp - 25.0;
            let bias = truth[0] + x * (truth[1] + x * (truth[2] + x * truth[3])) + b_rate * rate;
            let noise = 0.5 * rng.gauss();
            fit.push(dt, temp, rate, bias * dt + noise - last_noise);
            last_noise = noise;
        }
        let r = fit.solve().unwrap();
        assert!(r.rate_fitted);
        // The coefficients are correlated (the cubic's terms with each other and with the
        // rate's): what the model must get right is the bias over the range. Without noise the fit
        // is exact; 0.5 arcsec per record over 160 s leaves 1.3e-3 deg/h at the range's ends
        // (the cubic's x^3 = 9e4 there), bounded at 3e-3.
        let worst = (0..=80)
            .flat_map(|i| [(-20.0 + i as f64, 60.0), (-20.0 + i as f64, -60.0)])
            .map(|(temp, rate)| {
                let x = temp - 25.0;
                let c = r.bias_deg_h;
                let fitted =
                    c[0] + x * (c[1] + x * (c[2] + x * c[3])) + r.bias_deg_h_per_c_per_min * rate;
                let true_bias =
                    truth[0] + x * (truth[1] + x * (truth[2] + x * truth[3])) + b_rate * rate;
                (fitted - true_bias).abs()
            })
            .fold(0.0, f64::max);
        assert!(worst < 3e-3 && worst > 1e-5, "{worst} {r:?}");
        assert!((r.bias_deg_h_per_c_per_min - b_rate).abs() < 2e-6, "{r:?}");
        let mut one_rate = BiasFit::new(25.0);
        for k in 0..2000 {
            one_rate.push(0.01, -20.0 + 0.04 * k as f64, 2.4, 0.0);
        }
        let r = one_rate.solve().unwrap();
        assert!(!r.rate_fitted && r.bias_deg_h_per_c_per_min == 0.0);
    }

    #[test]
    fn refuses_what_it_cannot_fit() {
        let mut fit = BiasFit::new(25.0);
        for k in 0..2000 {
            fit.push(0.001, 25.0 + 0.001 * k as f64, 0.0, 0.0);
        }
        assert_eq!(fit.solve(), Err(FitError::NarrowSpan));
        assert_eq!(BiasFit::new(25.0).solve(), Err(FitError::TooFew));
        let pts = [(-20.0, -12.0), (0.0, -5.0), (25.0, 0.0), (60.0, 24.0)];
        let s = fit_scale(25.0, &pts).unwrap();
        assert!(s.iter().all(|c| c.is_finite()));
        assert_eq!(fit_scale(25.0, &pts[..3]), Err(FitError::TooFew));
    }
}
