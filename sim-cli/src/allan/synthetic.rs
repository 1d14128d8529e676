//! Synthetic rate records with known IEEE 952 noise terms: the estimator's and the fit's
//! tests, and the acceptance figures of docs/results.md.
//!
//! Per sample of period `tau0` (rates in deg/h, angles in arcsec):
//! - quantisation `Q` (arcsec): white angle noise `e` of rms `Q` read into the rate as
//!   `(e[k] - e[k-1]) / tau0`, so `AVAR = 3 Q^2 / tau^2` exactly;
//! - angle random walk `N` (deg/sqrt(h)): white rate of rms `60 N / sqrt(tau0)`,
//!   `AVAR = (60 N)^2 / tau`;
//! - bias instability `B` (deg/h): flicker rate noise from a sum of first-order Gauss-Markov
//!   processes, correlation times `tau0 * r^k` (`r = sqrt(10)`, two per decade) up to ten
//!   times the record, each of variance `B^2 ln r / pi`: their one-sided spectrum is
//!   `h / f` with `h = B^2 / pi` between the poles, so the floor is
//!   `AVAR = 2 ln 2 h = B^2 (2 ln 2 / pi)` (`ADEV = 0.664 B`), within about 1 % ripple;
//! - rate random walk `K` (deg/h/sqrt(h)): the rate steps by `K / 60 * sqrt(tau0)` rms,
//!   `AVAR = (K / 60)^2 tau / 3`.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The IEEE 952 terms of a rate record.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NoiseTerms {
    /// Quantisation noise, arcsec.
    pub quantisation_arcsec: f64,
    /// Angle random walk, deg/sqrt(h).
    pub arw_deg_rt_h: f64,
    /// Bias instability, deg/h.
    pub bias_instability_deg_h: f64,
    /// Rate random walk, deg/h/sqrt(h).
    pub rrw_deg_h_rt_h: f64,
}

/// A generator of rate samples with given terms.
pub struct Synthetic {
    terms: NoiseTerms,
    period_s: f64,
    rng: ChaCha8Rng,
}

impl Synthetic {
    /// Terms, sample period (s), seed (same seed, same record).
    pub fn new(terms: NoiseTerms, period_s: f64, seed: u64) -> Self {
        Self {
            terms,
            period_s,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    fn gauss(&mut self) -> f64 {
        StandardNormal.sample(&mut self.rng)
    }

    /// `n` rate samples, deg/h.
    pub fn rates(&mut self, n: usize) -> Vec<f64> {
        let t = self.terms;
        let tau0 = self.period_s;
        let white = 60.0 * t.arw_deg_rt_h / tau0.sqrt();
        let walk_step = t.rrw_deg_h_rt_h / 60.0 * tau0.sqrt();
        let ratio = 10f64.sqrt();
        let flicker_sigma = t.bias_instability_deg_h * (ratio.ln() / std::f64::consts::PI).sqrt();
        // (decay per sample, innovation rms) of each Gauss-Markov process.
        let mut poles = Vec::new();
        if flicker_sigma > 0.0 {
            let mut corr_s = tau0;
            while corr_s < 10.0 * tau0 * n as f64 {
                let a = (-tau0 / corr_s).exp();
                poles.push((a, flicker_sigma * (1.0 - a * a).sqrt()));
                corr_s *= ratio;
            }
        }
        let mut state: Vec<f64> = poles.iter().map(|_| flicker_sigma).collect();
        for s in &mut state {
            *s *= self.gauss();
        }
        let (mut walk, mut last_e) = (0.0, t.quantisation_arcsec * self.gauss());
        (0..n)
            .map(|_| {
                let mut y = white * self.gauss();
                walk += walk_step * self.gauss();
                y += walk;
                for ((a, b), s) in poles.iter().zip(state.iter_mut()) {
                    *s = a * *s + b * self.gauss();
                    y += *s;
                }
                let e = t.quantisation_arcsec * self.gauss();
                y += (e - last_e) / tau0;
                last_e = e;
                y
            })
            .collect()
    }
}
