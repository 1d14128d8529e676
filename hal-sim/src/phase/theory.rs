//! Closed-form results the simulator is held against (docs/physics.md): Eq. 5, Chow's dead band,
//! the stationary-phase error of one traversal, and the Bessel function they need.

use core::f64::consts::{FRAC_PI_4, PI, TAU};

/// Bessel function `J0(x)`: power series for |x| <= 20 (accurate to ~1e-9 near x = 20,
/// 1e-15 for |x| < 8), Hankel's asymptotic expansion beyond (terms summed while they
/// shrink; error < 1e-17 for x > 20).
pub fn bessel_j0(x: f64) -> f64 {
    let x = x.abs();
    if x <= 20.0 {
        let q = -0.25 * x * x;
        let mut term = 1.0;
        let mut sum = 1.0;
        for k in 1..200 {
            term *= q / (k * k) as f64;
            sum += term;
            if term.abs() < 1e-18 * sum.abs().max(1e-300) && k > 5 {
                break;
            }
        }
        return sum;
    }
    // J0 = sqrt(2/(pi x)) (P cos(x - pi/4) - Q sin(x - pi/4)),
    // a_k = prod_{j=1..k} (-(2j-1)^2) / (k! 8^k); P = sum (-1)^m a_{2m} / x^{2m},
    // Q = sum (-1)^m a_{2m+1} / x^{2m+1}.
    let (mut p, mut q) = (1.0, 0.0);
    let mut a = 1.0; // a_k / x^k
    let mut prev = f64::INFINITY;
    for k in 1..60 {
        let j = (2 * k - 1) as f64;
        a *= -(j * j) / (k as f64 * 8.0 * x);
        if a.abs() >= prev {
            break;
        }
        prev = a.abs();
        // (-1)^m with k = 2m or 2m+1
        let m = k / 2;
        let s = if m % 2 == 0 { 1.0 } else { -1.0 };
        if k % 2 == 0 {
            p += s * a;
        } else {
            q += s * a;
        }
        if a.abs() < 1e-18 {
            break;
        }
    }
    let ph = x - FRAC_PI_4;
    (2.0 / (PI * x)).sqrt() * (p * ph.cos() - q * ph.sin())
}

/// Eq. 5: mean beat rate without dither, rad/s (0 when locked).
pub fn eq5_mean_rate(omega_i: f64, omega_l: f64) -> f64 {
    if omega_i.abs() <= omega_l {
        0.0
    } else {
        omega_i.signum() * (omega_i * omega_i - omega_l * omega_l).sqrt()
    }
}

/// Chow's dead band (Eq. 8): `Omega_L |J0(A)|`, `A = Omega_d / w_d` in rad of beat phase.
pub fn chow_dead_band(omega_l: f64, dither_amp_rad: f64) -> f64 {
    omega_l * bessel_j0(dither_amp_rad).abs()
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn j0_matches_tabulated_values() {
        // Abramowitz & Stegun / mpmath values.
        let cases = [
            (0.0, 1.0, 1e-16),
            (1.0, 0.765_197_686_557_966_6, 1e-15),
            (2.404_825_557_695_773, 0.0, 1e-15),
            (5.0, -0.177_596_771_314_338_3, 1e-15),
            (10.0, -0.245_935_764_451_348_3, 1e-13),
            (25.0, 0.096_266_783_275_958_17, 1e-15),
            (100.0, 0.019_985_850_304_223_12, 1e-15),
            (1000.0, 0.024_786_686_152_420_17, 1e-15),
        ];
        for (x, want, tol) in cases {
            let got = bessel_j0(x);
            assert!((got - want).abs() < tol, "J0({x}) = {got}, want {want}");
        }
        // Both branches agree where they meet.
        assert!((bessel_j0(20.0) - bessel_j0(20.000_000_001)).abs() < 1e-9);
    }

    #[test]
    fn chow_band_of_the_paper_set() {
        let sf = 1.8655;
        let a = TAU * 450.0 / sf;
        let l = TAU * 200.0 / sf;
        let band_deg_h = chow_dead_band(l, a) * sf / TAU;
        assert!((band_deg_h - 3.358).abs() < 0.002, "{band_deg_h}");
    }
}
