//! Synthetic Lissajous figures for the fringe stage's tests: a true ellipse, its noisy 12-bit
//! codes along a dithered phase, and a fitted window.

use super::ellipse::{fit_window, Ellipse, FitRejection, LissajousConfig};
use super::levels::LissajousCoefficients;
use super::moments::LissajousAccumulator;
use crate::test_rng::XorShift;
use std::f64::consts::TAU;

#[derive(Clone, Copy)]
pub struct Truth {
    pub offset_a: f64,
    pub offset_b: f64,
    pub radius_a: f64,
    pub radius_b: f64,
    pub alpha: f64,
    pub noise: f64,
}

impl Truth {
    pub fn ideal(&self, psi: f64) -> (f64, f64) {
        (
            self.offset_a + self.radius_a * psi.cos(),
            self.offset_b + self.radius_b * (psi + self.alpha).sin(),
        )
    }
    /// 12-bit quantised, noisy codes.
    pub fn codes(&self, psi: f64, rng: &mut XorShift) -> (u16, u16) {
        let (a, b) = self.ideal(psi);
        let q = |x: f64| x.round().clamp(0.0, 4095.0) as u16;
        (
            q(a + self.noise * rng.gauss()),
            q(b + self.noise * rng.gauss()),
        )
    }
}

/// Sample phases like a dithered gyro sampled at arbitrary instants: psi = A sin(phase)
/// with A = 241 fringes (450 arcsec / 1.8655) and a random instant.
pub fn dither_psi(rng: &mut XorShift) -> f64 {
    241.0 * TAU * (TAU * rng.uniform()).sin() + 0.37
}

/// Fits `n` samples of `truth` (seeded) in one window.
pub fn fit(
    truth: &Truth,
    n: u32,
    seed: u64,
) -> Result<(LissajousCoefficients, Ellipse), FitRejection> {
    let mut rng = XorShift(seed);
    let mut acc = LissajousAccumulator::new();
    for _ in 0..n {
        let psi = dither_psi(&mut rng);
        let (a, b) = truth.codes(psi, &mut rng);
        acc.add(a, b);
    }
    let cfg = LissajousConfig {
        window_samples: n,
        ..LissajousConfig::DEFAULT
    };
    fit_window(&acc, &cfg)
}
