//! Allan deviation of a recorded rate and its IEEE 952 noise terms (`rlg-sim allan`).
//!
//! The pipeline, one file per step, sans-IO except the reader's `BufRead`:
//! - [`input`]: the CSV of `rlg-sim record` / `rlg-cal record` into a uniform rate series,
//!   invalid and lost records as gaps;
//! - [`estimator`]: the overlapping Allan variance at octave taus, no difference across a gap,
//!   and the equivalent degrees of freedom per noise type;
//! - [`fit`]: the noise model (quantisation, ARW, bias instability, rate random walk) fitted
//!   to it, with intervals;
//! - [`chi2`]: the chi-squared quantiles of the intervals;
//! - [`output`]: the table, the CSV and the log-log figure;
//! - `synthetic`: records with known terms, for the tests (compiled for them only; the CLI's
//!   tests include the same file).
//!
//! [`analyse`] ties them: each tau's interval is the chi-squared interval of its EDF under the
//! fitted model (each term's share with its noise type's EDF).

pub mod chi2;
pub mod estimator;
pub mod fit;
pub mod input;
pub mod output;
#[cfg(test)]
pub mod synthetic;

use estimator::{AllanVariance, NoiseType};
use fit::NoiseFit;
use host_cli::range::Range;
use input::RateRecord;

/// Valid two-sided confidence levels of the intervals (`--confidence`).
pub const CONFIDENCE: Range<f64> = Range::closed("--confidence", 0.5, 0.999, "");

/// One tau of the result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AllanRow {
    /// Averaging time, s.
    pub tau_s: f64,
    /// Overlapping Allan deviation, deg/h.
    pub adev_deg_h: f64,
    /// Lower end of its confidence interval, deg/h.
    pub ci_low_deg_h: f64,
    /// Upper end of its confidence interval, deg/h.
    pub ci_high_deg_h: f64,
    /// Equivalent degrees of freedom.
    pub edf: f64,
    /// The fitted model's dominant term (the EDF mixes the terms by their shares).
    pub noise: NoiseType,
    /// Second differences averaged.
    pub terms: u64,
}

/// Everything `rlg-sim allan` reports.
#[derive(Clone, Debug, PartialEq)]
pub struct Analysis {
    /// One row per octave tau.
    pub rows: Vec<AllanRow>,
    /// The fitted terms.
    pub fit: NoiseFit,
    /// The variance the rows come from.
    pub variance: AllanVariance,
}

/// The Allan deviation of `record` with intervals at `confidence`, and the terms fitted from
/// `min_fit_tau_s` on (`fit`). Errs when the record is too short (no segment of 3 valid
/// samples) or has no variance there.
pub fn analyse(
    record: &RateRecord,
    confidence: f64,
    min_fit_tau_s: f64,
) -> Result<Analysis, String> {
    let variance = estimator::allan_variance(record).ok_or_else(|| {
        "no run of at least 2 consecutive valid samples: nothing to compute".to_string()
    })?;
    let fit = fit::fit(&variance, confidence, min_fit_tau_s)
        .ok_or("the Allan variance is zero at every tau (a constant rate): nothing to fit")?;
    let rows = variance
        .points
        .iter()
        .map(|p| {
            let noise = fit.dominant(p.tau_s);
            let edf = fit.edf(&variance, p.m, p.tau_s);
            let (lo, hi) = chi2::variance_interval(p.avar, edf, confidence);
            AllanRow {
                tau_s: p.tau_s,
                adev_deg_h: p.adev_deg_h(),
                ci_low_deg_h: lo.sqrt(),
                ci_high_deg_h: hi.sqrt(),
                edf,
                noise,
                terms: p.terms,
            }
        })
        .collect();
    Ok(Analysis {
        rows,
        fit,
        variance,
    })
}
