//! The IEEE 952 noise model fitted to the Allan variance, and the terms' confidence intervals.
//!
//! Model: `AVAR(tau) = 3 Q^2 / tau^2 + (60 N)^2 / tau + (2 ln 2 / pi) B^2 + (K / 60)^2 tau / 3`
//! (tau in s, AVAR in (deg/h)^2): quantisation `Q` (arcsec, slope -1), angle random walk `N`
//! (deg/sqrt(h), slope -1/2), bias instability `B` (deg/h, the floor `0.664 B`, slope 0),
//! rate random walk `K` (deg/h/sqrt(h), slope +1/2). Each term is read from its own straight
//! line of the log-log plot as IEEE 952 does (`N` is the -1/2 line at tau = 1 s divided by
//! 60, `B` the floor over 0.664, `K` the +1/2 line at tau = 3 s times 60, `Q` the -1 line at
//! tau = sqrt(3) s), but the lines are fitted jointly rather than by eye, so a term is not
//! biased by its neighbours where two cross.
//!
//! The fit is linear in the coefficients (`Q^2`, `(60 N)^2`, `B^2`, `(K/60)^2`), weighted by
//! each point's inverse variance `edf / (2 AVAR^2)` with the model's AVAR (iterated three times
//! from the measured one), constrained non-negative by trying every subset of terms and keeping
//! the best fit whose coefficients are all positive: a term absent from the data is reported
//! as not resolved, never as a negative variance. The EDF of each point depends on the noise
//! type: under the previous iteration's model, each term's share of the variance with its own
//! type's EDF ([`NoiseFit::edf`]).
//!
//! Confidence intervals: the coefficient's variance from the weighted normal equations (times
//! the Birge ratio when the scatter exceeds the weights) gives its equivalent degrees of
//! freedom `2 c^2 / var(c)`, and the chi-squared interval of a variance with that many. The
//! normal equations take the octave points as independent; they are not (neighbouring octaves
//! of an overlapping ADEV share their data), so the variance is multiplied by
//! `CORRELATION_INFLATION`, a factor measured on synthetic records (see there): the trade-off
//! is an empirical constant instead of Greenhall's full covariance of the octave estimates,
//! which would be a project of its own.
//!
//! A term whose coefficient is below twice its standard deviation is flagged not significant
//! (compatible with zero: the interval of a variance never reaches zero, so its lower end is
//! then no evidence of the term).
//!
//! The fit may start at a tau (`min_tau_s`): a dithered gyro's output holds what is left of
//! the dither (a model's error at the dither frequency, modulated), whose Allan deviation at
//! taus of a few dither periods rises and falls with the tau and is none of the model's
//! noises; fitted there, it takes the weight of the best-determined points and hides the
//! terms the longer taus show. `rlg-sim characterize` starts at ten dither periods.

use super::chi2::variance_interval;
use super::estimator::{AllanVariance, NoiseType};

const NOISE: [NoiseType; 4] = [
    NoiseType::Quantisation,
    NoiseType::AngleRandomWalk,
    NoiseType::BiasInstability,
    NoiseType::RateRandomWalk,
];

/// The variance of a coefficient from the normal equations, which take the octave points as
/// independent, times this: neighbouring octaves of an overlapping ADEV share their data.
/// Set from synthetic records with the acceptance test's four terms, 40 seeds each, 95 %
/// intervals (Q, N, B, K holding the truth): with 1 (independent points) 34, 34, 31, 32 of 40;
/// with the mixed-noise EDF of [`NoiseFit::edf`], 4 gave 40, 40, 38, 35 (seeds 3000-3039),
/// 6 gave 40, 40, 40, 37 (seeds 1000-1039, where it was chosen) and 40, 40, 39, 40 (seeds
/// 5000-5039, fresh): the intervals are about 2.4 times as wide as independent points would
/// make them. Re-measured by `cargo test -p rlg-sim --lib --release -- --ignored
/// interval_coverage --nocapture` (seeds 5000-5039).
const CORRELATION_INFLATION: f64 = 6.0;

/// `sqrt(2 ln 2 / pi)`: the flicker floor in units of the bias instability.
pub const FLOOR_FACTOR: f64 = 0.664_282_7;

/// The basis function of each coefficient at `tau_s`.
fn basis(tau_s: f64) -> [f64; 4] {
    [
        3.0 / (tau_s * tau_s),
        1.0 / tau_s,
        FLOOR_FACTOR * FLOOR_FACTOR,
        tau_s / 3.0,
    ]
}

/// A fitted term with its interval, in the term's unit; `None` when the data do not resolve it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Term {
    /// Estimate.
    pub value: f64,
    /// Lower end of the confidence interval.
    pub low: f64,
    /// Upper end of the confidence interval.
    pub high: f64,
    /// The coefficient exceeds twice its standard deviation. When not, the term is
    /// compatible with zero: the data bound it from above but do not show it (the chi-squared
    /// interval of a variance never reaches zero, so its lower end says nothing then).
    pub significant: bool,
}

/// The four terms, and the model they make.
#[derive(Clone, Debug, PartialEq)]
pub struct NoiseFit {
    /// Quantisation noise, arcsec.
    pub quantisation_arcsec: Option<Term>,
    /// Angle random walk, deg/sqrt(h).
    pub arw_deg_rt_h: Option<Term>,
    /// Bias instability, deg/h.
    pub bias_instability_deg_h: Option<Term>,
    /// Rate random walk, deg/h/sqrt(h).
    pub rrw_deg_h_rt_h: Option<Term>,
    /// The model's coefficients (`Q^2`, `(60 N)^2`, `B^2`, `(K/60)^2`).
    pub coefficients: [f64; 4],
    /// The confidence of the intervals.
    pub confidence: f64,
    /// The shortest tau fitted, s.
    pub min_tau_s: f64,
}

impl NoiseFit {
    /// The model's Allan variance at `tau_s`, (deg/h)^2.
    pub fn avar(&self, tau_s: f64) -> f64 {
        basis(tau_s)
            .iter()
            .zip(self.coefficients)
            .map(|(f, c)| f * c)
            .sum()
    }

    /// The model's term `k` alone at `tau_s` (0 Q, 1 N, 2 B, 3 K), (deg/h)^2.
    pub fn term_avar(&self, k: usize, tau_s: f64) -> f64 {
        basis(tau_s)[k] * self.coefficients[k]
    }

    /// Equivalent degrees of freedom of the point at factor `m` (tau `tau_s`) of `av` under
    /// this model: each term's variance estimate has the EDF of its own noise type, and the
    /// sum of independent estimates has `(sum a_k)^2 / sum (a_k^2 / edf_k)`. A point where
    /// quantisation dominates but ARW is a third of the variance has the ARW's few hundred
    /// EDF for that third, not the quantisation's millions.
    pub fn edf(&self, av: &AllanVariance, m: usize, tau_s: f64) -> f64 {
        let parts: Vec<(f64, f64)> = (0..4)
            .map(|k| self.term_avar(k, tau_s))
            .zip(NOISE)
            .filter(|(a, _)| *a > 0.0)
            .map(|(a, kind)| (a, av.edf(m, kind)))
            .collect();
        let total: f64 = parts.iter().map(|(a, _)| a).sum();
        let spread: f64 = parts.iter().map(|(a, edf)| a * a / edf).sum();
        if spread > 0.0 {
            total * total / spread
        } else {
            av.edf(m, NoiseType::AngleRandomWalk)
        }
    }

    /// The noise type of the largest term at `tau_s`.
    pub fn dominant(&self, tau_s: f64) -> NoiseType {
        let f = basis(tau_s);
        let k = (0..4)
            .max_by(|&a, &b| {
                (f[a] * self.coefficients[a]).total_cmp(&(f[b] * self.coefficients[b]))
            })
            .unwrap_or(1);
        NOISE[k]
    }
}

/// Solves the `n x n` system `m x = b` (Gaussian elimination, partial pivoting); `None` if
/// singular.
fn solve<const N: usize>(mut m: [[f64; N]; N], mut b: [f64; N], n: usize) -> Option<[f64; N]> {
    for col in 0..n {
        let pivot = (col..n).max_by(|&i, &j| m[i][col].abs().total_cmp(&m[j][col].abs()))?;
        if m[pivot][col].abs() < 1e-12 {
            return None;
        }
        m.swap(col, pivot);
        b.swap(col, pivot);
        let pivot_row = m[col];
        for row in col + 1..n {
            let f = m[row][col] / pivot_row[col];
            for (v, p) in m[row][col..n].iter_mut().zip(&pivot_row[col..n]) {
                *v -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; N];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| m[row][k] * x[k]).sum();
        x[row] = (b[row] - s) / m[row][row];
    }
    Some(x)
}

/// Weighted least squares on the terms in `subset`: coefficients (0 outside it), their
/// variances, and the weighted residual sum of squares.
fn least_squares(
    taus: &[f64],
    avar: &[f64],
    weights: &[f64],
    subset: &[usize],
) -> Option<([f64; 4], [f64; 4], f64)> {
    let n = subset.len();
    // Columns scaled to unit weighted norm: the basis spans 20 decades over the taus.
    let mut scale = [0.0; 4];
    for (j, &k) in subset.iter().enumerate() {
        let s: f64 = taus
            .iter()
            .zip(weights)
            .map(|(&t, w)| w * basis(t)[k].powi(2))
            .sum();
        scale[j] = s.sqrt();
    }
    let mut m = [[0.0; 4]; 4];
    let mut b = [0.0; 4];
    for ((&t, &y), &w) in taus.iter().zip(avar).zip(weights) {
        let f = basis(t);
        for (i, &ki) in subset.iter().enumerate() {
            let fi = f[ki] / scale[i];
            b[i] += w * fi * y;
            for (j, &kj) in subset.iter().enumerate() {
                m[i][j] += w * fi * f[kj] / scale[j];
            }
        }
    }
    let x = solve(m, b, n)?;
    let mut coefficients = [0.0; 4];
    let mut variances = [0.0; 4];
    for (j, &k) in subset.iter().enumerate() {
        coefficients[k] = x[j] / scale[j];
        let mut unit = [0.0; 4];
        unit[j] = 1.0;
        variances[k] = solve(m, unit, n)?[j] / (scale[j] * scale[j]);
    }
    let cost = taus
        .iter()
        .zip(avar)
        .zip(weights)
        .map(|((&t, &y), &w)| {
            let model: f64 = basis(t).iter().zip(coefficients).map(|(f, c)| f * c).sum();
            w * (y - model).powi(2)
        })
        .sum();
    Some((coefficients, variances, cost))
}

/// The best non-negative fit over all subsets of terms.
fn best_subset(taus: &[f64], avar: &[f64], weights: &[f64]) -> Option<([f64; 4], [f64; 4])> {
    let mut best: Option<([f64; 4], [f64; 4], f64, usize)> = None;
    for mask in 1u32..16 {
        let subset: Vec<usize> = (0..4).filter(|k| mask & (1 << k) != 0).collect();
        if subset.len() > taus.len() {
            continue;
        }
        let Some(fit) = least_squares(taus, avar, weights, &subset) else {
            continue;
        };
        let positive = subset.iter().all(|&k| fit.0[k] > 0.0);
        if positive && best.as_ref().is_none_or(|b| fit.2 < b.2) {
            best = Some((fit.0, fit.1, fit.2, subset.len()));
        }
    }
    best.map(|(c, v, cost, terms)| (c, inflate(v, cost, taus.len(), terms)))
}

/// The coefficient variances times [`CORRELATION_INFLATION`] and the Birge ratio: a scatter
/// larger than the weights say (correlated octaves) widens the intervals; never narrows them.
fn inflate(mut v: [f64; 4], cost: f64, points: usize, terms: usize) -> [f64; 4] {
    let free = points.saturating_sub(terms).max(1) as f64;
    let inflation = CORRELATION_INFLATION * (cost / free).max(1.0);
    v.iter_mut().for_each(|v| *v *= inflation);
    v
}

/// An upper bound of the angle random walk, deg/sqrt(h), where `fit` may not resolve one
/// (e.g. under a quantisation floor): the terms `fit` kept plus the ARW term, fitted with
/// `fit`'s weights and no sign constraint, give the ARW coefficient `c` with its (inflated)
/// standard deviation `s`; the bound is `sqrt(max(c, 0) + 2 s) / 60` (one-sided, about
/// 97.7 %). Unlike reading the -1/2 line off the longest tau, this uses every octave: the
/// short taus pin the floor, so the bound is as tight as the record allows.
pub fn arw_upper_bound(av: &AllanVariance, fit: &NoiseFit) -> Option<f64> {
    let points: Vec<_> = av
        .points
        .iter()
        .filter(|p| p.avar > 0.0 && p.tau_s >= fit.min_tau_s)
        .collect();
    let taus: Vec<f64> = points.iter().map(|p| p.tau_s).collect();
    let avar: Vec<f64> = points.iter().map(|p| p.avar).collect();
    let weights: Vec<f64> = points
        .iter()
        .map(|p| fit.edf(av, p.m, p.tau_s) / (2.0 * fit.avar(p.tau_s).powi(2)))
        .collect();
    let subset: Vec<usize> = (0..4)
        .filter(|&k| k == 1 || fit.coefficients[k] > 0.0)
        .collect();
    if subset.len() >= taus.len() {
        return None;
    }
    let (c, v, cost) = least_squares(&taus, &avar, &weights, &subset)?;
    let v = inflate(v, cost, taus.len(), subset.len());
    let bound = c[1].max(0.0) + 2.0 * v[1].sqrt();
    (bound.is_finite() && bound > 0.0).then(|| bound.sqrt() / 60.0)
}

/// The term of coefficient `c` with variance `var`: `value(c)` maps a coefficient to the unit.
fn term(c: f64, var: f64, confidence: f64, value: impl Fn(f64) -> f64) -> Option<Term> {
    (c > 0.0).then(|| {
        let dof = (2.0 * c * c / var).max(0.1);
        let (low, high) = variance_interval(c, dof, confidence);
        Term {
            value: value(c),
            low: value(low),
            high: value(high),
            significant: c > 2.0 * var.sqrt(),
        }
    })
}

/// Fits the noise model to the points of `av` at `min_tau_s` and above; `None` if none of them
/// has a positive variance.
pub fn fit(av: &AllanVariance, confidence: f64, min_tau_s: f64) -> Option<NoiseFit> {
    let points: Vec<_> = av
        .points
        .iter()
        .filter(|p| p.avar > 0.0 && p.tau_s >= min_tau_s)
        .collect();
    let taus: Vec<f64> = points.iter().map(|p| p.tau_s).collect();
    let avar: Vec<f64> = points.iter().map(|p| p.avar).collect();
    let mut result: Option<NoiseFit> = None;
    for _ in 0..3 {
        // Inverse variance of each point: of the previous model, else of white rate noise at
        // the measured value.
        let weights: Vec<f64> = points
            .iter()
            .map(|p| match &result {
                Some(fit) => fit.edf(av, p.m, p.tau_s) / (2.0 * fit.avar(p.tau_s).powi(2)),
                None => av.edf(p.m, NoiseType::AngleRandomWalk) / (2.0 * p.avar * p.avar),
            })
            .collect();
        let (coefficients, variances) = best_subset(&taus, &avar, &weights)?;
        let fit = NoiseFit {
            quantisation_arcsec: term(coefficients[0], variances[0], confidence, f64::sqrt),
            arw_deg_rt_h: term(coefficients[1], variances[1], confidence, |c| {
                c.sqrt() / 60.0
            }),
            bias_instability_deg_h: term(coefficients[2], variances[2], confidence, f64::sqrt),
            rrw_deg_h_rt_h: term(coefficients[3], variances[3], confidence, |c| {
                60.0 * c.sqrt()
            }),
            coefficients,
            confidence,
            min_tau_s,
        };
        result = Some(fit);
    }
    result
}

#[cfg(test)]
mod tests {

    use super::super::estimator::allan_variance;
    use super::super::input::RateRecord;
    use super::super::synthetic::{NoiseTerms, Synthetic};
    use super::*;

    fn analyse(terms: NoiseTerms, period_s: f64, n: usize, seed: u64) -> NoiseFit {
        let rates = Synthetic::new(terms, period_s, seed).rates(n);
        let record = RateRecord {
            period_s,
            rates_deg_h: rates,
            rows: n as u64,
            invalid_rows: 0,
            missing_samples: 0,
        };
        fit(&allan_variance(&record).unwrap(), 0.95, 0.0).unwrap()
    }

    fn within(name: &str, term: Option<Term>, truth: f64) {
        let t = term.unwrap_or_else(|| panic!("{name} not resolved"));
        assert!(
            t.low <= truth && truth <= t.high,
            "{name}: truth {truth} outside [{}, {}] (estimate {})",
            t.low,
            t.high,
            t.value
        );
    }

    /// Issue 14's acceptance: white rate noise of 0.003 deg/sqrt(h) (2^20 samples at 100 Hz,
    /// 2.9 h): ARW within 5 %, and inside its interval.
    #[test]
    fn white_rate_noise_gives_the_arw_within_5_percent() {
        let truth = 0.003;
        let terms = NoiseTerms {
            arw_deg_rt_h: truth,
            ..NoiseTerms::default()
        };
        let fit = analyse(terms, 0.01, 1 << 20, 11);
        let arw = fit.arw_deg_rt_h.unwrap();
        println!("white rate noise, N = {truth}: {arw:?}");
        assert!((arw.value / truth - 1.0).abs() < 0.05, "{arw:?}");
        within("ARW", fit.arw_deg_rt_h, truth);
        // No term the record does not have: absent, or not significant.
        for (name, t) in [
            ("Q", fit.quantisation_arcsec),
            ("B", fit.bias_instability_deg_h),
            ("K", fit.rrw_deg_h_rt_h),
        ] {
            assert!(t.is_none_or(|t| !t.significant), "{name}: {t:?}");
        }
    }

    /// Issue 14's acceptance: white rate noise, a flicker floor and a rate random walk (and
    /// quantisation): each term inside its 95 % interval.
    #[test]
    fn every_term_is_recovered_within_its_interval() {
        let terms = NoiseTerms {
            quantisation_arcsec: 0.2,
            arw_deg_rt_h: 0.003,
            bias_instability_deg_h: 0.01,
            rrw_deg_h_rt_h: 0.01,
        };
        // 2^22 samples at 10 Hz (116 h): Q dominates below 4 s, N to 700 s, the floor to
        // 5000 s, K above.
        let fit = analyse(terms, 0.1, 1 << 22, 5);
        println!("{terms:?}:\n{fit:#?}");
        within("Q", fit.quantisation_arcsec, terms.quantisation_arcsec);
        within("ARW", fit.arw_deg_rt_h, terms.arw_deg_rt_h);
        within(
            "B",
            fit.bias_instability_deg_h,
            terms.bias_instability_deg_h,
        );
        within("K", fit.rrw_deg_h_rt_h, terms.rrw_deg_h_rt_h);
        let all = [
            fit.quantisation_arcsec,
            fit.arw_deg_rt_h,
            fit.bias_instability_deg_h,
            fit.rrw_deg_h_rt_h,
        ];
        assert!(
            all.iter().all(|t| t.is_some_and(|t| t.significant)),
            "{all:?}"
        );
    }

    /// The coverage of the 95 % intervals over 40 seeds (prints the count per term; asserts
    /// at least 34 of 40, i.e. 85 %): the measurement behind `CORRELATION_INFLATION`. 20 s,
    /// so not in the default run.
    #[test]
    #[ignore]
    fn interval_coverage() {
        let terms = NoiseTerms {
            quantisation_arcsec: 0.2,
            arw_deg_rt_h: 0.003,
            bias_instability_deg_h: 0.01,
            rrw_deg_h_rt_h: 0.01,
        };
        let truth = [0.2, 0.003, 0.01, 0.01];
        let runs = 40;
        let mut hits = [0; 4];
        for seed in 0..runs {
            let f = analyse(terms, 0.1, 1 << 22, 5000 + seed);
            let fitted = [
                f.quantisation_arcsec,
                f.arw_deg_rt_h,
                f.bias_instability_deg_h,
                f.rrw_deg_h_rt_h,
            ];
            for k in 0..4 {
                if let Some(t) = fitted[k] {
                    hits[k] += u32::from(t.low <= truth[k] && truth[k] <= t.high);
                }
            }
        }
        println!("95 % intervals holding the truth (Q, N, B, K): {hits:?} of {runs}");
        assert!(hits.iter().all(|&h| h >= 34), "{hits:?}");
    }

    /// Under a quantisation floor like the simulated board's (0.5 arcsec at 1 kHz, 300 s):
    /// without ARW the bound is far below an ARW of 3e-3 deg/sqrt(h) (which the floor hides
    /// below tau of ~20 s) and far below the 1 s reading ADEV(1 s) / 60; with that ARW added,
    /// the bound holds it. Seeds 21-23.
    #[test]
    fn the_arw_bound_sees_under_a_quantisation_floor() {
        let (q, n_true, period, samples) = (0.5, 3e-3, 1e-3, 300_000);
        for seed in 21..24 {
            for arw in [0.0, n_true] {
                let rates = Synthetic::new(
                    NoiseTerms {
                        quantisation_arcsec: q,
                        arw_deg_rt_h: arw,
                        ..NoiseTerms::default()
                    },
                    period,
                    seed,
                )
                .rates(samples);
                let record = RateRecord {
                    period_s: period,
                    rates_deg_h: rates,
                    rows: samples as u64,
                    invalid_rows: 0,
                    missing_samples: 0,
                };
                let av = allan_variance(&record).unwrap();
                let f = fit(&av, 0.95, 0.0).unwrap();
                let bound = arw_upper_bound(&av, &f).unwrap();
                let adev_1s = av.points.iter().find(|p| p.m == 1024).unwrap().adev_deg_h();
                if arw == 0.0 {
                    assert!(bound < 0.25 * n_true, "seed {seed}: bound {bound}");
                    assert!(
                        bound < 0.1 * adev_1s / 60.0,
                        "seed {seed}: {bound} {adev_1s}"
                    );
                } else {
                    assert!(bound > n_true, "seed {seed}: bound {bound}");
                    assert!(bound < 2.0 * n_true, "seed {seed}: bound {bound}");
                }
            }
        }
    }
}
