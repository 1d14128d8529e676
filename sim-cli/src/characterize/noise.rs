//! The static record's figures: bias, bias stability, and the noise terms of the Allan
//! deviation ([`crate::allan::analyse`], the estimator and fit of `rlg-sim allan`).
//!
//! The record is the board's fixed-rate output at zero input, one increment per sync period.
//! A record of hours at 1000 Hz is tens of millions of increments; [`Decimator`] sums
//! `factor` consecutive increments into one sample (exact for the angle: the increments add),
//! chosen so that no record holds more than [`MAX_STATIC_SAMPLES`] samples (memory 8 MB per
//! configuration, whatever the length); a block holding an invalid increment is invalid (a
//! gap: no angle spliced across it). The Allan deviation then starts at `factor` sync periods
//! (10 h at 1000 Hz: 36 ms, well below the 1 s where ARW is read).
//!
//! - **Bias**: the mean rate of the valid samples, deg/h.
//! - **Bias stability**: the standard deviation of consecutive [`BIAS_STABILITY_BLOCK_S`]
//!   means (a tenth of the record when that is shorter than 100 s).
//! - **ARW** and **bias instability**: the IEEE 952 fit's `N` and `B`, fitted from
//!   [`FIT_FROM_DITHER_PERIODS`] dither periods on. Where the fit finds no white rate noise
//!   (the board's readout floor, white angle noise of about 0.04 arcsec per sync period,
//!   dominates the deviation at short taus), the ARW is
//!   bounded from above instead ([`StaticFigures::arw_bound_deg_rt_h`],
//!   [`crate::allan::fit::arw_upper_bound`]: the ARW term forced into the fit beside the
//!   terms it found, its coefficient plus two standard deviations). The ADEV at 1 s over 60,
//!   the textbook reading, would be a far weaker bound under that floor.

use crate::allan::fit::{arw_upper_bound, Term};
use crate::allan::input::RateRecord;
use crate::allan::{analyse, Analysis};

/// The most samples a static record is kept at.
pub const MAX_STATIC_SAMPLES: u64 = 1_000_000;
/// The averaging time of the bias stability, s.
pub const BIAS_STABILITY_BLOCK_S: f64 = 10.0;
/// The noise terms are fitted from this many dither periods on (`crate::allan::fit`: what is
/// left of the dither at shorter taus is none of the IEEE 952 noises).
pub const FIT_FROM_DITHER_PERIODS: f64 = 10.0;

/// One (decimated) sample of the static record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StaticSample {
    /// The end of the sample, s.
    pub t_s: f64,
    /// The angle increment over the sample, arcsec (0 when invalid).
    pub delta_angle_arcsec: f64,
    /// Every increment of the sample was valid.
    pub valid: bool,
}

/// Sums `factor` consecutive increments into one sample.
#[derive(Clone, Copy, Debug)]
pub struct Decimator {
    factor: u64,
    count: u64,
    sum_arcsec: f64,
    valid: bool,
}

impl Decimator {
    /// The decimation of a record of `periods` sync periods: at most [`MAX_STATIC_SAMPLES`].
    pub fn for_periods(periods: u64) -> Self {
        Self {
            factor: periods.div_ceil(MAX_STATIC_SAMPLES).max(1),
            count: 0,
            sum_arcsec: 0.0,
            valid: true,
        }
    }

    /// Increments per sample.
    pub fn factor(&self) -> u64 {
        self.factor
    }

    /// Adds one increment; returns the sample it completes.
    pub fn push(&mut self, t_s: f64, delta_angle_arcsec: f64, valid: bool) -> Option<StaticSample> {
        self.count += 1;
        self.valid &= valid;
        if valid {
            self.sum_arcsec += delta_angle_arcsec;
        }
        (self.count == self.factor).then(|| {
            let sample = StaticSample {
                t_s,
                delta_angle_arcsec: if self.valid { self.sum_arcsec } else { 0.0 },
                valid: self.valid,
            };
            *self = Self {
                factor: self.factor,
                ..Self::for_periods(0)
            };
            sample
        })
    }
}

/// The samples as the Allan estimator's rate series (NaN for invalid samples).
pub fn rate_record(samples: &[StaticSample], period_s: f64) -> RateRecord {
    let invalid = samples.iter().filter(|s| !s.valid).count() as u64;
    RateRecord {
        period_s,
        rates_deg_h: samples
            .iter()
            .map(|s| {
                if s.valid {
                    s.delta_angle_arcsec / period_s
                } else {
                    f64::NAN
                }
            })
            .collect(),
        rows: samples.len() as u64,
        invalid_rows: invalid,
        missing_samples: 0,
    }
}

/// What the static record gives.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticFigures {
    /// Sample period of the record, s.
    pub period_s: f64,
    /// Samples, and how many were invalid.
    pub samples: u64,
    /// Invalid samples.
    pub invalid_samples: u64,
    /// Mean rate of the valid samples, deg/h (NaN if none).
    pub bias_deg_h: f64,
    /// Standard deviation of the block means, deg/h.
    pub bias_stability_deg_h: Option<f64>,
    /// The block of the bias stability, s.
    pub bias_stability_block_s: f64,
    /// The Allan deviation and its fit, or why there is none (e.g. a constant output).
    pub allan: Result<Analysis, String>,
    /// The Allan deviation at tau = 1 s (log-log interpolation between octaves), deg/h.
    pub adev_1s_deg_h: Option<f64>,
    /// The ARW's upper bound from the deviation's intervals, deg/sqrt(h).
    pub arw_bound_deg_rt_h: Option<f64>,
}

impl StaticFigures {
    /// The fitted angle random walk, deg/sqrt(h).
    pub fn arw(&self) -> Option<Term> {
        self.allan.as_ref().ok()?.fit.arw_deg_rt_h
    }

    /// The fitted bias instability, deg/h.
    pub fn bias_instability(&self) -> Option<Term> {
        self.allan.as_ref().ok()?.fit.bias_instability_deg_h
    }

    /// The ARW to compare configurations by: the fitted one where the fit resolves it, else
    /// its upper bound; and whether it is the bound.
    pub fn arw_for_comparison(&self) -> Option<(f64, bool)> {
        match self.arw() {
            Some(t) if t.significant => Some((t.value, false)),
            _ => self.arw_bound_deg_rt_h.map(|b| (b, true)),
        }
    }
}

/// The figures of a static record at `confidence`, its noise terms fitted from
/// `min_fit_tau_s` on.
pub fn static_figures(record: &RateRecord, confidence: f64, min_fit_tau_s: f64) -> StaticFigures {
    let valid: Vec<f64> = record
        .rates_deg_h
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .collect();
    let bias_deg_h = valid.iter().sum::<f64>() / valid.len() as f64;
    let length_s = record.rates_deg_h.len() as f64 * record.period_s;
    let block_s = BIAS_STABILITY_BLOCK_S.min(length_s / 10.0);
    let block = (block_s / record.period_s).round().max(1.0) as usize;
    let allan = analyse(record, confidence, min_fit_tau_s);
    let adev_1s_deg_h = allan.as_ref().ok().and_then(|a| adev_at(a, 1.0));
    let arw_bound_deg_rt_h = allan
        .as_ref()
        .ok()
        .and_then(|a| arw_upper_bound(&a.variance, &a.fit));
    StaticFigures {
        period_s: record.period_s,
        samples: record.rows,
        invalid_samples: record.invalid_rows,
        bias_deg_h,
        bias_stability_deg_h: super::figures::block_std(&record.rates_deg_h, block),
        bias_stability_block_s: block as f64 * record.period_s,
        allan,
        adev_1s_deg_h,
        arw_bound_deg_rt_h,
    }
}

/// The deviation at `tau_s`, interpolated log-log between the octaves around it.
fn adev_at(analysis: &Analysis, tau_s: f64) -> Option<f64> {
    let rows = &analysis.rows;
    let i = rows
        .windows(2)
        .position(|w| w[0].tau_s <= tau_s && tau_s <= w[1].tau_s)?;
    let (a, b) = (rows[i], rows[i + 1]);
    let f = (tau_s / a.tau_s).ln() / (b.tau_s / a.tau_s).ln();
    Some((a.adev_deg_h.ln() + f * (b.adev_deg_h / a.adev_deg_h).ln()).exp())
}

/// Valid samples of a record whose rate (deg/h = arcsec/s) is `rates`, one per `period_s`.
#[cfg(test)]
pub(crate) fn samples_from_rates(rates: &[f64], period_s: f64) -> Vec<StaticSample> {
    rates
        .iter()
        .enumerate()
        .map(|(i, r)| StaticSample {
            t_s: (i + 1) as f64 * period_s,
            delta_angle_arcsec: r * period_s,
            valid: true,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::allan::synthetic::{NoiseTerms, Synthetic};

    /// Sums of 3 increments; an invalid one voids its block.
    #[test]
    fn the_decimator_sums_whole_blocks() {
        let mut d = Decimator::for_periods(3 * MAX_STATIC_SAMPLES - 1);
        assert_eq!(d.factor(), 3);
        let out: Vec<StaticSample> = (0..9)
            .filter_map(|i| d.push(i as f64, 1.0 + i as f64, i != 4))
            .collect();
        assert_eq!(out.len(), 3);
        assert_eq!(out[0].delta_angle_arcsec, 6.0);
        assert!(!out[1].valid && out[1].delta_angle_arcsec == 0.0);
        assert_eq!(out[2].delta_angle_arcsec, 7.0 + 8.0 + 9.0);
        assert_eq!(out[2].t_s, 8.0);
        assert_eq!(Decimator::for_periods(10).factor(), 1);
    }

    /// White rate noise of ARW 0.003 deg/sqrt(h) plus a bias of 0.7 deg/h, 200 000 samples at
    /// 10 ms: the bias within 4 sigma of its standard error, the ARW within 5 %, the ADEV at 1 s
    /// within 5 % of 60 N (what white noise gives), and the bias stability over 10 s blocks
    /// within 20 % of 60 N / sqrt(10) (the std of 200 block means: 10 % standard error).
    #[test]
    fn static_figures_of_white_noise() {
        let arw = 0.003;
        let period = 0.01;
        let rates: Vec<f64> = Synthetic::new(
            NoiseTerms {
                arw_deg_rt_h: arw,
                ..NoiseTerms::default()
            },
            period,
            11,
        )
        .rates(200_000)
        .into_iter()
        .map(|r| r + 0.7)
        .collect();
        let samples = samples_from_rates(&rates, period);
        let f = static_figures(&rate_record(&samples, period), 0.95, 0.0);
        let sigma_mean = 60.0 * arw / (2000.0f64).sqrt();
        assert!(
            (f.bias_deg_h - 0.7).abs() < 4.0 * sigma_mean,
            "{}",
            f.bias_deg_h
        );
        let n = f.arw().unwrap().value;
        assert!((n / arw - 1.0).abs() < 0.05, "ARW {n}");
        assert!((f.adev_1s_deg_h.unwrap() / (60.0 * arw) - 1.0).abs() < 0.05);
        assert_eq!(f.bias_stability_block_s, 10.0);
        let want = 60.0 * arw / 10.0f64.sqrt();
        let got = f.bias_stability_deg_h.unwrap();
        assert!((got / want - 1.0).abs() < 0.2, "{got} vs {want}");
        // The bound is above the truth, and not far above it for white rate noise.
        let b = f.arw_bound_deg_rt_h.unwrap();
        assert!(b > arw && b < 1.3 * arw, "bound {b}");
        let (cmp, bound) = f.arw_for_comparison().unwrap();
        assert!(!bound && cmp == n);
    }

    /// A constant output has no Allan variance: the figures say why, and keep the bias.
    #[test]
    fn a_constant_record_has_no_noise_terms() {
        let samples: Vec<StaticSample> = (0..1000)
            .map(|i| StaticSample {
                t_s: i as f64 * 0.001,
                delta_angle_arcsec: 0.0,
                valid: true,
            })
            .collect();
        let f = static_figures(&rate_record(&samples, 0.001), 0.95, 0.0);
        assert_eq!(f.bias_deg_h, 0.0);
        assert!(f.allan.is_err() && f.arw().is_none() && f.arw_for_comparison().is_none());
    }
}
