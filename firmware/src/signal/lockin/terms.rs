//! P1 and P2: the per-cycle regressors of the dynamic lock-in error (docs/physics.md, Eq. 18),
//! one traversal's share at a time.
//!
//! Each crossing of the lock-in zone at a dither turnaround loses a phase that the parabolic
//! approximation gives as (k = sqrt(2 pi / |psi_ddot|), eps the photodiode phase offset):
//!
//! ```text
//! "+" turnaround:  dE+ = Omega_L k cos(psi0+ + pi/4) = a k cos psiH+ - b k sin psiH+
//! "-" turnaround:  dE- = Omega_L k sin(psi0- + pi/4) = a k sin psiH- + b k cos psiH-
//! ```
//!
//! with a = Omega_L cos(eps + pi/4), b = Omega_L sin(eps + pi/4) and psi_H = psi - eps, the phase
//! the photodiodes see. So one traversal contributes `(k cos psiH, -k sin psiH)` ("+") or
//! `(k sin psiH, k cos psiH)` ("-") to (P1, P2), and the error of a dither cycle is
//! dE = a P1 + b P2. This is the corrected form: the paper's Eq. 12 prints cos for the "-"
//! turnaround, and its Eq. 19 gives a P2 that is collinear with P1 under a steady dither.
//!
//! The levels enter as the normalised photodiode pair (cos psi_H, sin psi_H): no trigonometry
//! runs here. Everything is f32 with basic IEEE operations and `libm::sqrtf` (correctly rounded),
//! so the host and the Cortex-M4F compute identical bits.
//!
//! Units: k, P1 and P2 in seconds; a and b in rad/s of beat phase; a P1 + b P2 in radians.

use crate::sample::TurnaroundKind;

/// 2 pi in f32 (correctly rounded).
const TWO_PI: f32 = core::f32::consts::TAU;

/// The normalised photodiode levels latched at a turnaround: a point on the unit circle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LevelPair {
    /// Channel A after offset and gain correction, ~cos psi_H.
    pub cos_psi_h: f32,
    /// Channel B after offset, gain and quadrature correction, ~sin psi_H.
    pub sin_psi_h: f32,
}

/// The two regressors of one dither cycle (or one traversal's share of them), in seconds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LockinTerms {
    /// P1, seconds (the regressor of a).
    pub p1_s: f32,
    /// P2, seconds (the regressor of b).
    pub p2_s: f32,
}

impl core::ops::Add for LockinTerms {
    type Output = Self;
    /// Sum of two shares.
    fn add(self, other: Self) -> Self {
        Self {
            p1_s: self.p1_s + other.p1_s,
            p2_s: self.p2_s + other.p2_s,
        }
    }
}

impl LockinTerms {
    /// A share scaled by `weight` (a traversal's weight in a cycle: `cycle.rs`, the latch split).
    pub fn scaled(self, weight: f32) -> Self {
        Self {
            p1_s: self.p1_s * weight,
            p2_s: self.p2_s * weight,
        }
    }
}

/// The traversal time constant k = sqrt(2 pi / |psi_ddot|) in seconds, from the beat-phase
/// acceleration at the turnaround in rad/s^2. Returns `None` for a zero, negative-zero or
/// non-finite acceleration (no dither: there is no traversal to correct).
pub fn traversal_time_s(psi_ddot_rad_per_s2: f32) -> Option<f32> {
    let accel = if psi_ddot_rad_per_s2 < 0.0 {
        -psi_ddot_rad_per_s2
    } else {
        psi_ddot_rad_per_s2
    };
    if !(accel.is_finite() && accel > 0.0) {
        return None;
    }
    Some(libm::sqrtf(TWO_PI / accel))
}

/// The beat-phase acceleration at a turnaround of a sine dither, in rad/s^2, from what the
/// firmware measures itself: the peak-to-peak beat-phase excursion between two consecutive
/// turnarounds (rad, = 2 x amplitude) and the time between them (s, = half a dither period).
///
/// For psi_d = -A cos(w t): |psi_ddot| = A w^2 at the turnaround, with A = excursion / 2 and
/// w = pi / half_period. (The input rate shifts the turnaround off the dither extreme by
/// Omega_i / (A w), which changes |psi_ddot| by a relative (Omega_i / (A w))^2 / 2: below 1e-10
/// in the paper's input range.)
pub fn sine_dither_accel_rad_per_s2(excursion_pp_rad: f32, half_period_s: f32) -> Option<f32> {
    let amplitude_rad = 0.5 * excursion_pp_rad.abs();
    if !(half_period_s.is_finite() && half_period_s > 0.0 && amplitude_rad.is_finite()) {
        return None;
    }
    let w_rad_per_s = core::f32::consts::PI / half_period_s;
    let accel = amplitude_rad * w_rad_per_s * w_rad_per_s;
    (accel.is_finite() && accel > 0.0).then_some(accel)
}

/// One traversal's contribution to (P1, P2), given its kind, the normalised levels at its
/// turnaround and its time constant k.
pub fn traversal_terms(kind: TurnaroundKind, levels: LevelPair, k_s: f32) -> LockinTerms {
    match kind {
        TurnaroundKind::Plus => LockinTerms {
            p1_s: k_s * levels.cos_psi_h,
            p2_s: -(k_s * levels.sin_psi_h),
        },
        TurnaroundKind::Minus => LockinTerms {
            p1_s: k_s * levels.sin_psi_h,
            p2_s: k_s * levels.cos_psi_h,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn levels(psi_h: f64) -> LevelPair {
        LevelPair {
            cos_psi_h: psi_h.cos() as f32,
            sin_psi_h: psi_h.sin() as f32,
        }
    }

    /// a P1 + b P2 must reproduce the parabolic traversal errors Omega_L k cos(psi0+ + pi/4)
    /// and Omega_L k sin(psi0- + pi/4) for every phase: this pins the sign pattern of Eq. 18.
    /// Tolerance 1e-5 relative to Omega_L k: f32 rounding of the levels and products.
    #[test]
    fn terms_reproduce_the_parabolic_traversal_errors() {
        let omega_l = 673.6_f64;
        let eps = 0.3_f64;
        let k = 26.3e-6_f64;
        let a = omega_l * (eps + core::f64::consts::FRAC_PI_4).cos();
        let b = omega_l * (eps + core::f64::consts::FRAC_PI_4).sin();
        for i in 0..720 {
            let psi0 = i as f64 * core::f64::consts::TAU / 720.0 - 3.0;
            let plus = traversal_terms(TurnaroundKind::Plus, levels(psi0 - eps), k as f32);
            let minus = traversal_terms(TurnaroundKind::Minus, levels(psi0 - eps), k as f32);
            let de_plus = a * plus.p1_s as f64 + b * plus.p2_s as f64;
            let de_minus = a * minus.p1_s as f64 + b * minus.p2_s as f64;
            let want_plus = omega_l * k * (psi0 + core::f64::consts::FRAC_PI_4).cos();
            let want_minus = omega_l * k * (psi0 + core::f64::consts::FRAC_PI_4).sin();
            assert!(
                (de_plus - want_plus).abs() < 1e-5 * omega_l * k,
                "psi0={psi0}"
            );
            assert!(
                (de_minus - want_minus).abs() < 1e-5 * omega_l * k,
                "psi0={psi0}"
            );
        }
    }

    /// docs/physics.md parameter set: 450 arcsec at 389 Hz with SF 1.8655 arcsec/pulse gives
    /// |psi_ddot| = 9.05e9 rad/s^2 and k = 26.3 us. Tolerance: the table's 3 digits.
    #[test]
    fn time_constant_of_the_paper_parameter_set() {
        let amplitude_rad = core::f64::consts::TAU * 450.0 / 1.8655;
        let half_period_s = 0.5 / 389.0;
        let accel = sine_dither_accel_rad_per_s2((2.0 * amplitude_rad) as f32, half_period_s)
            .expect("valid dither");
        assert!((accel / 9.05e9 - 1.0).abs() < 1e-3, "accel={accel}");
        let k = traversal_time_s(accel).unwrap();
        assert!((k / 26.3e-6 - 1.0).abs() < 2e-3, "k={k}");
        assert_eq!(traversal_time_s(-accel), Some(k));
    }

    #[test]
    fn degenerate_dither_gives_no_time_constant() {
        assert_eq!(traversal_time_s(0.0), None);
        assert_eq!(traversal_time_s(f32::NAN), None);
        assert_eq!(traversal_time_s(f32::INFINITY), None);
        assert_eq!(sine_dither_accel_rad_per_s2(3000.0, 0.0), None);
        assert_eq!(sine_dither_accel_rad_per_s2(f32::NAN, 1e-3), None);
        assert_eq!(sine_dither_accel_rad_per_s2(0.0, 1e-3), None);
    }
}
