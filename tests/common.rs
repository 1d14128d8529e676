//! Shared helpers of the system tests: the docs/physics.md gyro and unit conversions.
#![allow(dead_code)]

use hal_sim::params::GyroParams;

pub const TAU: f64 = std::f64::consts::TAU;

/// The docs/physics.md parameter set (the paper's gyro), noise-free, seeded.
pub fn paper_gyro(seed: u64) -> GyroParams {
    GyroParams {
        seed,
        ..GyroParams::default()
    }
}

/// deg/h of input -> Hz of beat (fringes/s).
pub fn deg_h_to_hz(rate_deg_h: f64, params: &GyroParams) -> f64 {
    rate_deg_h / params.scale_factor_arcsec
}

/// Chow's dynamic dead band Omega_L |J0(A)| in deg/h, A = dither amplitude in beat-phase rad.
pub fn chow_dead_band_deg_h(params: &GyroParams) -> f64 {
    let amplitude_rad = TAU * params.dither_amplitude_arcsec / params.scale_factor_arcsec;
    params.lock_in_deg_per_h * libm::j0(amplitude_rad).abs()
}
