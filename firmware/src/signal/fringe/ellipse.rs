//! The per-window half of the Heydemann fit (Heydemann 1981): the ellipse of the Lissajous
//! figure from a window's moment sums, and the normalisation coefficients derived from it.
//!
//! The fringes sweep psi_H over hundreds of turns per dither cycle, so (A, B) code pairs taken
//! at arbitrary instants cover the whole Lissajous figure. With offsets, unequal gains and a
//! quadrature (phase) error alpha the figure is an ellipse:
//!
//! ```text
//! A = offset_a + r_a cos(psi_H)
//! B = offset_b + r_b sin(psi_H + alpha)        (channel phase difference 90 deg - alpha)
//! ```
//!
//! # Fit, bit-exact
//!
//! At the window's end ([`fit_window`], once per window, low priority): the least-squares conic
//! `P U^2 + Q V^2 + R UV + S U + T V = 1` (U, V = u, v / 2048) from its 5x5 normal equations
//! (`moments.rs`; Gaussian elimination with partial pivoting in `f64`, `math::solve5`), then the
//! ellipse's centre, radii and alpha in closed form. Only `+ - * /` on `f64` (software floats on
//! the M4, SSE2 on x86: both IEEE correctly rounded, no fused operations) and a Newton square
//! root made of those ops (`math::sqrt_f64`), so both targets produce the same bits (checked: a
//! digest of 40 fits and their coefficients is identical in QEMU's Cortex-M4 and on x86-64).
//! About 51 000 instructions per solve at `opt-level = "s"` (QEMU `-icount`, software `f64`),
//! once per window.
//!
//! The algebraic fit is not weighted by the noise, so it is biased by about `sigma^2 / r` in the
//! radius; for 2 codes of noise on a 1500-code radius that is 3e-3 code, 2e-6 relative: negligible.
//!
//! # Rejected windows
//!
//! A window is rejected ([`FitRejection`]) for too few samples, a lost signal (channel span or
//! fitted radius below the configured minimum), a singular or non-elliptic fit, an
//! excessive quadrature error, incomplete coverage of the figure, or coefficients out of
//! range. The tracker (`tracker.rs`) then keeps the previous coefficients and reports the reason.

use super::levels::{LissajousCoefficients, ORIGIN_CODE};
use super::moments::{LissajousAccumulator, SCALE};
use crate::math::{atan2_q32, positive, round_to_i64, saturate_i32, solve5, sqrt_f64};
use crate::sample::AdcCode;
use crate::units::Q32_PER_FRINGE;

/// Smallest accepted radius (codes): keeps the Q34 matrix within `i32`.
pub const MIN_RADIUS_CODES: u16 = 16;
/// Largest accepted quadrature error: 45 deg = 1/8 turn in Q32 turns.
pub const MAX_QUADRATURE_ERROR_Q32: u32 = 1 << 29;
/// Each channel's code span must reach this fraction (in 1/256) of the fitted diameter.
pub const MIN_SPAN_OF_DIAMETER_Q8: u32 = 224; // 7/8

/// Settings of the fit (immutable, `Copy`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousConfig {
    /// Samples per window; the fit runs when the window is full (clipped to
    /// [`MAX_WINDOW_SAMPLES`](super::MAX_WINDOW_SAMPLES), at least 1).
    pub window_samples: u32,
    /// Fewest samples a window may be solved with ([`fit_window`] on a window
    /// closed early); at least 5 are always needed.
    pub min_samples: u32,
    /// Smallest radius of either channel, in codes, below which the signal counts as lost
    /// (raised to [`MIN_RADIUS_CODES`]).
    pub min_radius_codes: u16,
    /// Largest accepted |quadrature error| alpha in Q32 turns (clipped to 45 deg).
    pub max_quadrature_error_q32: u32,
}

impl LissajousConfig {
    /// 4096-sample windows, 200-code minimum radius, 20 deg maximum quadrature error.
    pub const DEFAULT: Self = Self {
        window_samples: 4096,
        min_samples: 256,
        min_radius_codes: 200,
        max_quadrature_error_q32: (1u64 << 32).div_ceil(18) as u32, // 20 deg
    };
}

impl Default for LissajousConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Why a window did not produce new coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FitRejection {
    /// Fewer than `min_samples` (or 5) samples in the window.
    TooFewSamples,
    /// A channel's amplitude (code span or fitted radius) below `min_radius_codes`: the
    /// fringe contrast is gone.
    SignalLost,
    /// The normal equations are singular (e.g. a straight line: channels in phase).
    Singular,
    /// The fitted conic is not an ellipse (hyperbola, parabola, imaginary).
    NotAnEllipse,
    /// |alpha| above the configured maximum.
    QuadratureErrorTooLarge,
    /// The samples do not span the whole figure (a partial arc).
    IncompleteCoverage,
    /// Centre outside the ADC range or a coefficient outside its fixed-point range.
    OutOfRange,
}

/// The fitted ellipse, for telemetry (physical units, `f32`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Ellipse {
    /// Centre of channel A, codes.
    pub offset_a_code: f32,
    /// Centre of channel B, codes.
    pub offset_b_code: f32,
    /// Amplitude of channel A, codes.
    pub radius_a_code: f32,
    /// Amplitude of channel B, codes.
    pub radius_b_code: f32,
    /// alpha: the channel phase difference is 90 deg - alpha.
    pub quadrature_error_rad: f32,
    /// alpha in Q32 turns (signed).
    pub quadrature_error_q32: i32,
    /// Samples in the window.
    pub samples: u32,
}

/// Fits the ellipse of a closed window and derives the normalisation coefficients.
pub fn fit_window(
    window: &LissajousAccumulator,
    config: &LissajousConfig,
) -> Result<(LissajousCoefficients, Ellipse), FitRejection> {
    if window.len() < config.min_samples.max(5) {
        return Err(FitRejection::TooFewSamples);
    }
    let min_radius = config.min_radius_codes.max(MIN_RADIUS_CODES) as u32;
    let (span_a, span_b) = window.spans();
    if span_a < 2 * min_radius || span_b < 2 * min_radius {
        return Err(FitRejection::SignalLost);
    }
    let conic = solve5(&mut window.normal_equations()).ok_or(FitRejection::Singular)?;
    let shape = EllipseShape::from_conic(conic)?;
    if shape.radius_a < min_radius as f64 || shape.radius_b < min_radius as f64 {
        return Err(FitRejection::SignalLost);
    }
    // alpha in Q32 turns through the bit-exact CORDIC (cos alpha > 0: |alpha| < 90 deg).
    let alpha_q32 = atan2_q32(
        saturate_i32(round_to_i64(shape.sin_alpha * (1u64 << 30) as f64)),
        saturate_i32(round_to_i64(shape.cos_alpha * (1u64 << 30) as f64)),
    )
    .to_signed();
    let max_alpha = config
        .max_quadrature_error_q32
        .min(MAX_QUADRATURE_ERROR_Q32);
    if alpha_q32.unsigned_abs() > max_alpha {
        return Err(FitRejection::QuadratureErrorTooLarge);
    }
    let need = |diameter: f64| diameter * (MIN_SPAN_OF_DIAMETER_Q8 as f64 / 256.0);
    if (span_a as f64) < need(2.0 * shape.radius_a) || (span_b as f64) < need(2.0 * shape.radius_b)
    {
        return Err(FitRejection::IncompleteCoverage);
    }
    let coefficients = shape.coefficients()?;
    let ellipse = Ellipse {
        offset_a_code: shape.offset_a as f32,
        offset_b_code: shape.offset_b as f32,
        radius_a_code: shape.radius_a as f32,
        radius_b_code: shape.radius_b as f32,
        quadrature_error_rad: (alpha_q32 as f64 * (core::f64::consts::TAU / Q32_PER_FRINGE)) as f32,
        quadrature_error_q32: alpha_q32,
        samples: window.len(),
    };
    Ok((coefficients, ellipse))
}

/// Ellipse parameters in codes, from the conic.
struct EllipseShape {
    offset_a: f64,
    offset_b: f64,
    radius_a: f64,
    radius_b: f64,
    sin_alpha: f64,
    cos_alpha: f64,
    tan_alpha: f64,
}

impl EllipseShape {
    /// Closed form (U, V coordinates, then back to codes). For the conic `G = 0` with
    /// `G = P U^2 + Q V^2 + R UV + S U + T V - 1` and `det = 4PQ - R^2 > 0`:
    /// centre `(RT - 2QS, RS - 2PT) / det`, `G_c = (S U_c + T V_c) / 2 - 1`,
    /// `r_a^2 = -4 Q G_c / det`, `r_b^2 = -4 P G_c / det`,
    /// `sin alpha = -sign(P) R / (2 sqrt(PQ))`, `tan alpha = -sign(P) R / sqrt(det)`.
    fn from_conic([p, q, r, s, t]: [f64; 5]) -> Result<Self, FitRejection> {
        let det = 4.0 * p * q - r * r;
        if !positive(det) {
            return Err(FitRejection::NotAnEllipse);
        }
        let uc = (r * t - 2.0 * q * s) / det;
        let vc = (r * s - 2.0 * p * t) / det;
        let gc = (s * uc + t * vc) / 2.0 - 1.0;
        let ra2 = -4.0 * q * gc / det;
        let rb2 = -4.0 * p * gc / det;
        if !(ra2 > 0.0 && rb2 > 0.0) {
            return Err(FitRejection::NotAnEllipse);
        }
        let sign = if p > 0.0 { 1.0 } else { -1.0 };
        let root_pq = sqrt_f64(p * q); // p q > 0 since det > 0
        let sin_alpha = -sign * r / (2.0 * root_pq);
        let cos_alpha = sqrt_f64(det) / (2.0 * root_pq);
        let tan_alpha = -sign * r / sqrt_f64(det);
        let shape = Self {
            offset_a: ORIGIN_CODE as f64 + SCALE * uc,
            offset_b: ORIGIN_CODE as f64 + SCALE * vc,
            radius_a: SCALE * sqrt_f64(ra2),
            radius_b: SCALE * sqrt_f64(rb2),
            sin_alpha,
            cos_alpha,
            tan_alpha,
        };
        let finite = [
            shape.offset_a,
            shape.offset_b,
            shape.radius_a,
            shape.radius_b,
            shape.sin_alpha,
            shape.cos_alpha,
            shape.tan_alpha,
        ]
        .iter()
        .all(|x| x.is_finite());
        if finite {
            Ok(shape)
        } else {
            Err(FitRejection::NotAnEllipse)
        }
    }

    /// The fixed-point coefficients; `OutOfRange` if the centre is outside the ADC range or a
    /// matrix entry does not fit an `i32`.
    fn coefficients(&self) -> Result<LissajousCoefficients, FitRejection> {
        let full = AdcCode::FULL_SCALE.to_f64();
        let in_range = |x: f64| (0.0..=full).contains(&x); // false for NaN
        if !in_range(self.offset_a) || !in_range(self.offset_b) {
            return Err(FitRejection::OutOfRange);
        }
        let q16 = 65_536.0;
        let q34 = 17_179_869_184.0;
        let to_i32 = |x: f64| {
            let r = round_to_i64(x);
            i32::try_from(r).map_err(|_| FitRejection::OutOfRange)
        };
        LissajousCoefficients::new(
            to_i32(self.offset_a * q16)?,
            to_i32(self.offset_b * q16)?,
            to_i32(q34 / self.radius_a)?,
            to_i32(-self.tan_alpha * q34 / self.radius_a)?,
            to_i32(q34 / (self.radius_b * self.cos_alpha))?,
        )
        .ok_or(FitRejection::OutOfRange)
    }
}

#[cfg(test)]
mod tests {
    use super::super::synthetic::{dither_psi, Truth};
    use super::*;
    use crate::test_rng::XorShift;
    use std::f64::consts::{PI, TAU};

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

    /// Worst radius error |r - 1| and phase error |atan2 - psi| (rad) of the normalised
    /// noise-free ellipse (unquantised codes, evaluated through the same fixed-point math by
    /// interpolating the Q16 offset arithmetic in f64).
    fn circle_errors(c: &LissajousCoefficients, truth: &Truth) -> (f64, f64) {
        let (m_aa, m_ba, m_bb) = c.matrix_q34();
        let mut worst_r: f64 = 0.0;
        let mut worst_phase: f64 = 0.0;
        for k in 0..3600 {
            let psi = k as f64 / 3600.0 * TAU;
            let (a, b) = truth.ideal(psi);
            let x = a * 65536.0 - c.offset_a_q16() as f64;
            let y = b * 65536.0 - c.offset_b_q16() as f64;
            let cs = x * m_aa as f64 / (1u64 << 50) as f64;
            let sn = (x * m_ba as f64 + y * m_bb as f64) / (1u64 << 50) as f64;
            worst_r = worst_r.max(((cs * cs + sn * sn).sqrt() - 1.0).abs());
            let mut dphi = sn.atan2(cs) - psi;
            dphi = (dphi + PI).rem_euclid(TAU) - PI;
            worst_phase = worst_phase.max(dphi.abs());
        }
        (worst_r, worst_phase)
    }

    /// Offsets, unequal gains, quadrature errors across 80..100 deg, 12-bit quantisation and
    /// 2 codes rms noise, 16384 samples. Tolerances: offsets 0.1 code, radii 0.05 %, alpha
    /// 2e-4 rad, normalised circle radius 5e-4 and phase 5e-4 rad (3e-5 turn). Reason: the
    /// statistical error of the fit is about sigma / (r sqrt(N)) ~ 1e-5 rad here, the fit's
    /// noise bias about sigma^2 / r^2 ~ 2e-6; the tolerances leave a factor >= 10, while
    /// a wrong sign or formula gives errors of order alpha (0.17 rad) or 1.
    #[test]
    fn recovers_synthetic_ellipses() {
        let mut worst = (0.0f64, 0.0f64);
        for (i, &alpha_deg) in [-10.0f64, -5.0, 0.0, 3.0, 10.0].iter().enumerate() {
            let truth = Truth {
                offset_a: 2100.3,
                offset_b: 1987.8,
                radius_a: 1500.0,
                radius_b: 1230.0,
                alpha: alpha_deg.to_radians(),
                noise: 2.0,
            };
            let (c, e) = fit(&truth, 16384, 1234 + i as u64).expect("fit");
            assert!(
                (e.offset_a_code as f64 - truth.offset_a).abs() < 0.1,
                "{e:?}"
            );
            assert!(
                (e.offset_b_code as f64 - truth.offset_b).abs() < 0.1,
                "{e:?}"
            );
            assert!(
                (e.radius_a_code as f64 / truth.radius_a - 1.0).abs() < 5e-4,
                "{e:?}"
            );
            assert!(
                (e.radius_b_code as f64 / truth.radius_b - 1.0).abs() < 5e-4,
                "{e:?}"
            );
            assert!(
                (e.quadrature_error_rad as f64 - truth.alpha).abs() < 2e-4,
                "{e:?}"
            );
            let (r_err, phase_err) = circle_errors(&c, &truth);
            assert!(r_err < 5e-4, "alpha {alpha_deg}: radius error {r_err}");
            assert!(
                phase_err < 5e-4,
                "alpha {alpha_deg}: phase error {phase_err}"
            );
            worst = (worst.0.max(r_err), worst.1.max(phase_err));
        }
        println!(
            "lissajous: worst normalised radius error {:.2e}, phase error {:.2e} rad",
            worst.0, worst.1
        );
    }

    /// Noise-free (only 12-bit quantisation) fit: the fit errors are those of the rounding
    /// of the codes, tolerance 1e-4 in radius and phase.
    #[test]
    fn quantisation_only() {
        let truth = Truth {
            offset_a: 2048.0,
            offset_b: 2048.0,
            radius_a: 1800.0,
            radius_b: 1900.0,
            alpha: 0.1,
            noise: 0.0,
        };
        let (c, _) = fit(&truth, 65536, 9).expect("fit");
        let (r_err, phase_err) = circle_errors(&c, &truth);
        println!("lissajous quantisation only: radius {r_err:.2e}, phase {phase_err:.2e} rad");
        assert!(r_err < 1e-4 && phase_err < 1e-4, "{r_err} {phase_err}");
    }

    #[test]
    fn degenerate_windows_are_rejected() {
        let cfg = LissajousConfig::DEFAULT;
        let base = Truth {
            offset_a: 2048.0,
            offset_b: 2048.0,
            radius_a: 1500.0,
            radius_b: 1500.0,
            alpha: 0.0,
            noise: 1.0,
        };
        // Too few samples.
        assert_eq!(
            fit(&base, 100, 1).map(|_| ()),
            Err(FitRejection::TooFewSamples)
        );
        // Signal lost: tiny amplitude.
        let small = Truth {
            radius_a: 50.0,
            radius_b: 50.0,
            ..base
        };
        assert_eq!(
            fit(&small, 4096, 2).map(|_| ()),
            Err(FitRejection::SignalLost)
        );
        // Constant codes: no contrast at all.
        let mut acc = LissajousAccumulator::new();
        for _ in 0..1000 {
            acc.add(AdcCode::MID, AdcCode::MID);
        }
        assert_eq!(
            fit_window(&acc, &cfg).map(|_| ()),
            Err(FitRejection::SignalLost)
        );
        // Channels in phase: a straight line, not an ellipse.
        let mut acc = LissajousAccumulator::new();
        for k in 0..4096 {
            let x = AdcCode::new(2048 + (1500.0 * (k as f64 * 0.01).cos()) as u16).unwrap();
            acc.add(x, x);
        }
        assert!(matches!(
            fit_window(&acc, &cfg),
            Err(FitRejection::Singular | FitRejection::NotAnEllipse)
        ));
        // Quadrature error beyond 20 deg.
        let skew = Truth {
            alpha: 30f64.to_radians(),
            ..base
        };
        assert_eq!(
            fit(&skew, 4096, 3).map(|_| ()),
            Err(FitRejection::QuadratureErrorTooLarge)
        );
        // A partial arc (psi within +-60 deg).
        let mut rng = XorShift(5);
        let mut acc = LissajousAccumulator::new();
        for _ in 0..4096 {
            let psi = (rng.uniform() - 0.5) * 2.0 * PI / 3.0;
            let (a, b) = base.codes(psi, &mut rng);
            acc.add(a, b);
        }
        assert_eq!(
            fit_window(&acc, &cfg).map(|_| ()),
            Err(FitRejection::IncompleteCoverage)
        );
    }

    /// Random codes and window lengths: never panics; accepted fits always give coefficients
    /// within their documented ranges.
    #[test]
    fn property_random_windows_never_panic() {
        let mut rng = XorShift(0xABCDEF);
        for trial in 0..300 {
            let mut acc = LissajousAccumulator::new();
            let n = (rng.next() % 3000) as u32;
            let mode = trial % 3;
            for _ in 0..n {
                let (a, b) = match mode {
                    0 => (rng.next() as u16, rng.next() as u16),
                    1 => ((rng.next() % 4096) as u16, (rng.next() % 4096) as u16),
                    _ => {
                        let psi = rng.uniform() * TAU;
                        (
                            (2048.0 + 2047.0 * psi.cos()) as u16,
                            (2048.0 + 2047.0 * (psi + 0.3 * rng.uniform()).sin()) as u16,
                        )
                    }
                };
                acc.add(AdcCode::saturating(a), AdcCode::saturating(b));
            }
            let cfg = LissajousConfig {
                min_samples: 5,
                min_radius_codes: 16,
                ..LissajousConfig::DEFAULT
            };
            if let Ok((c, _)) = fit_window(&acc, &cfg) {
                assert!(c.offset_a_q16() >= 0 && c.offset_a_q16() <= 4095 << 16);
                let (m_aa, _, m_bb) = c.matrix_q34();
                assert!(m_aa > 0 && m_bb > 0);
            }
        }
    }
}
