//! Closed-form results the simulator is held against (docs/physics.md): Eq. 5 and the
//! stationary-phase error of one traversal. Chow's dead band is the firmware's
//! (`firmware::calibration::validation::chow_dead_band_rad_per_s`, libm's J0): the board needs it
//! to validate a calibration, and the simulator is held against the same function.

use core::f64::consts::{FRAC_PI_4, TAU};

/// Eq. 5: mean beat rate without dither, rad/s (0 when locked).
pub fn eq5_mean_rate(omega_i: f64, omega_l: f64) -> f64 {
    if omega_i.abs() <= omega_l {
        0.0
    } else {
        omega_i.signum() * (omega_i * omega_i - omega_l * omega_l).sqrt()
    }
}

/// `k = sqrt(2 pi / |psi_ddot|)`, s.
pub fn k_s(psi_ddot: f64) -> f64 {
    (TAU / psi_ddot.abs()).sqrt()
}

/// Stationary-phase lock-in error of one traversal (docs/physics.md, corrected):
/// `Omega_L k cos(psi0 + pi/4)` at a "+" turnaround (`psi_ddot > 0`),
/// `Omega_L k sin(psi0 + pi/4)` at a "-" turnaround.
pub fn traversal_error(omega_l: f64, psi0: f64, psi_ddot: f64) -> f64 {
    let k = k_s(psi_ddot);
    if psi_ddot > 0.0 {
        omega_l * k * (psi0 + FRAC_PI_4).cos()
    } else {
        omega_l * k * (psi0 + FRAC_PI_4).sin()
    }
}
