//! Shared helpers of the system tests: the docs/physics.md gyro and unit conversions.
#![allow(dead_code)]

use firmware::calibration::validation::chow_dead_band_rad_per_s;
use hal_sim::params::GyroParams;
use hal_sim::units::{
    arcsec_to_beat_rad, beat_rad_per_s_to_deg_per_h, deg_per_h_to_beat_rad_per_s,
};

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

/// Chow's dynamic dead band Omega_L |J0(A)| in deg/h (the firmware's function, A = dither
/// amplitude in beat-phase rad).
pub fn chow_dead_band_deg_h(params: &GyroParams) -> f64 {
    let sf = params.scale_factor_arcsec;
    let band_rad_per_s = chow_dead_band_rad_per_s(
        deg_per_h_to_beat_rad_per_s(params.lock_in_deg_per_h, sf),
        arcsec_to_beat_rad(params.dither_amplitude_arcsec, sf),
    );
    beat_rad_per_s_to_deg_per_h(band_rad_per_s, sf)
}
