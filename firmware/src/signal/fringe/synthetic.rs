//! Synthetic Lissajous figures for the fringe stage's tests: a true ellipse and its noisy 12-bit
//! codes along a dithered phase. It imports nothing of the stage, so every file may use it.

use crate::sample::AdcCode;
use crate::test_rng::XorShift;
use std::f64::consts::TAU;

/// A true ellipse: offsets, radii, quadrature error (codes, rad) and the noise (codes rms).
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
    pub fn codes(&self, psi: f64, rng: &mut XorShift) -> (AdcCode, AdcCode) {
        let (a, b) = self.ideal(psi);
        let q = |x: f64| AdcCode::saturating(x.round().max(0.0) as u16);
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
