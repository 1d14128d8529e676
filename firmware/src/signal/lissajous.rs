//! Photodiode normalisation from the signal itself: a Heydemann ellipse fit of the Lissajous
//! figure of the two channels.
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
//! # Fit (Heydemann 1981), bit-exact
//!
//! Per sample ([`LissajousAccumulator::add`], the cheap part): with `u = A - 2048`,
//! `v = B - 2048` (integers, |u|, |v| <= 2048), the 14 moment sums `sum u^i v^j`, `1 <= i+j <= 4`,
//! accumulate exactly in `i64` (each term <= 2^44, so up to [`MAX_WINDOW_SAMPLES`] = 2^18
//! samples cannot overflow), plus the min/max code of each channel. Exact integer sums are
//! independent of order and target.
//!
//! At the window's end ([`LissajousAccumulator::solve`], once per window, low priority): the
//! least-squares conic `P U^2 + Q V^2 + R UV + S U + T V = 1` (U, V = u, v / 2048) from its 5x5
//! normal equations (Gaussian elimination with partial pivoting in `f64`), then the ellipse's
//! centre, radii and alpha in closed form. Only `+ - * /` on `f64` (software floats on the M4,
//! SSE2 on x86: both IEEE correctly rounded, no fused operations) and a Newton square root made
//! of those ops, so both targets produce the same bits (checked: a digest of 40 fits and their
//! coefficients is identical in QEMU's Cortex-M4 and on x86-64). Cost at `opt-level = "s"`
//! (QEMU `-icount` instruction counts, not cycles): about 130 instructions per sample added
//! (the 28-word state does not fit the registers), about 51 000 per solve (software `f64`),
//! once per window.
//!
//! The algebraic fit is not weighted by the noise, so it is biased by about `sigma^2 / r` in the
//! radius; for 2 codes of noise on a 1500-code radius that is 3e-3 code, 2e-6 relative: negligible.
//!
//! # Normalisation (per turnaround, integer)
//!
//! [`LissajousCoefficients`] hold the offsets in Q16 codes and a lower-triangular matrix in
//! Q34 per code:
//!
//! ```text
//! x = A*2^16 - offset_a_q16,   y = B*2^16 - offset_b_q16            (Q16 codes)
//! cos_q30 = (x * m_aa_q34 + 2^19) >> 20                  m_aa = 1 / r_a
//! sin_q30 = (x * m_ba_q34 + y * m_bb_q34 + 2^19) >> 20   m_ba = -tan(alpha) / r_a,
//!                                                         m_bb = 1 / (r_b cos(alpha))
//! ```
//!
//! giving (cos psi_H, sin psi_H) in Q30 (1.0 = 2^30, saturated to i32) in about 40
//! instructions. The matrix entries fit an `i32` for radii >= [`MIN_RADIUS_CODES`] and
//! |alpha| <= 45 deg; resolution 1 part in 2^23 at a full-scale radius of 2048 codes.
//!
//! # Rejected windows
//!
//! A window is rejected ([`FitRejection`]) for too few samples, a lost signal (channel span or
//! fitted radius below the configured minimum), a singular or non-elliptic fit, an
//! excessive quadrature error, incomplete coverage of the figure, or coefficients out of
//! range. [`LissajousTracker`] then keeps the previous coefficients and reports the reason.

use crate::math::{atan2_q32, positive, powi_f64, round_to_i64, saturate_i32, solve5, sqrt_f64};
use crate::sample::ADC_FULL_SCALE_CODE;
use crate::units::Q32_PER_FRINGE;

/// Origin of the integer moment coordinates (mid-scale of the 12-bit ADC).
pub const ORIGIN_CODE: i32 = 2048;
/// Largest window: the `i64` fourth-moment sums cannot overflow below 2^63 / 2048^4 = 2^19.
pub const MAX_WINDOW_SAMPLES: u32 = 1 << 18;
/// Smallest accepted radius (codes): keeps the Q34 matrix within `i32`.
pub const MIN_RADIUS_CODES: u16 = 16;
/// Largest accepted quadrature error: 45 deg = 1/8 turn in Q32 turns.
pub const MAX_QUADRATURE_ERROR_Q32: u32 = 1 << 29;
/// Each channel's code span must reach this fraction (in 1/256) of the fitted diameter.
pub const MIN_SPAN_OF_DIAMETER_Q8: u32 = 224; // 7/8

const SCALE: f64 = ORIGIN_CODE as f64; // U = u / 2048

/// Settings of the fit (immutable, `Copy`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousConfig {
    /// Samples per window; the fit runs when the window is full (clipped to
    /// [`MAX_WINDOW_SAMPLES`], at least 1).
    pub window_samples: u32,
    /// Fewest samples a window may be solved with ([`LissajousAccumulator::solve`] on a
    /// window closed early); at least 5 are always needed.
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
    pub offset_a_code: f32,
    pub offset_b_code: f32,
    pub radius_a_code: f32,
    pub radius_b_code: f32,
    /// alpha: the channel phase difference is 90 deg - alpha.
    pub quadrature_error_rad: f32,
    /// alpha in Q32 turns (signed).
    pub quadrature_error_q32: i32,
    /// Samples in the window.
    pub samples: u32,
}

/// Normalisation coefficients (immutable, `Copy`): see the module docs for the formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousCoefficients {
    /// Channel A offset, codes * 2^16, in [0, 4095 * 2^16].
    offset_a_q16: i32,
    /// Channel B offset, codes * 2^16, in [0, 4095 * 2^16].
    offset_b_q16: i32,
    /// 1 / r_a, per code, * 2^34.
    m_aa_q34: i32,
    /// -tan(alpha) / r_a, per code, * 2^34.
    m_ba_q34: i32,
    /// 1 / (r_b cos alpha), per code, * 2^34.
    m_bb_q34: i32,
}

/// The two photodiode levels after normalisation: (cos psi_H, sin psi_H), Q30 (1.0 = 2^30).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NormalisedLevels {
    pub cos_q30: i32,
    pub sin_q30: i32,
}

impl NormalisedLevels {
    /// cos psi_H as `f32` (exact power-of-two scaling of the rounded integer: bit-exact).
    #[inline]
    pub fn cos_f32(self) -> f32 {
        self.cos_q30 as f32 * (1.0 / (1u64 << 30) as f32)
    }

    /// sin psi_H as `f32`.
    #[inline]
    pub fn sin_f32(self) -> f32 {
        self.sin_q30 as f32 * (1.0 / (1u64 << 30) as f32)
    }
}

impl LissajousCoefficients {
    /// Ideal mid-scale channels: offsets 2048, radii 2047 codes, no quadrature error. A
    /// placeholder until the first fit.
    pub const NOMINAL: Self = Self {
        offset_a_q16: ORIGIN_CODE << 16,
        offset_b_q16: ORIGIN_CODE << 16,
        m_aa_q34: ((1u64 << 34) / 2047) as i32,
        m_ba_q34: 0,
        m_bb_q34: ((1u64 << 34) / 2047) as i32,
    };

    /// Coefficients from their fixed-point values (e.g. stored ones); `None` if an offset lies
    /// outside [0, 4095 * 2^16] (the range that keeps [`normalise`](Self::normalise) free of
    /// overflow). Matrix entries may be any `i32`.
    pub const fn new(
        offset_a_q16: i32,
        offset_b_q16: i32,
        m_aa_q34: i32,
        m_ba_q34: i32,
        m_bb_q34: i32,
    ) -> Option<Self> {
        const MAX_OFFSET_Q16: i32 = (ADC_FULL_SCALE_CODE as i32) << 16;
        if offset_a_q16 < 0
            || offset_a_q16 > MAX_OFFSET_Q16
            || offset_b_q16 < 0
            || offset_b_q16 > MAX_OFFSET_Q16
        {
            return None;
        }
        Some(Self {
            offset_a_q16,
            offset_b_q16,
            m_aa_q34,
            m_ba_q34,
            m_bb_q34,
        })
    }

    /// Channel A offset, codes * 2^16.
    pub const fn offset_a_q16(&self) -> i32 {
        self.offset_a_q16
    }

    /// Channel B offset, codes * 2^16.
    pub const fn offset_b_q16(&self) -> i32 {
        self.offset_b_q16
    }

    /// The normalisation matrix `(m_aa, m_ba, m_bb)`, per code, * 2^34.
    pub const fn matrix_q34(&self) -> (i32, i32, i32) {
        (self.m_aa_q34, self.m_ba_q34, self.m_bb_q34)
    }

    /// Normalises one pair of ADC codes (codes above full scale are clamped to it).
    #[inline]
    pub fn normalise(&self, a_code: u16, b_code: u16) -> NormalisedLevels {
        let a = a_code.min(ADC_FULL_SCALE_CODE) as i64;
        let b = b_code.min(ADC_FULL_SCALE_CODE) as i64;
        // Offsets and codes in [0, 4095 * 2^16] (checked by `new`): |x|, |y| < 2^28, each
        // product < 2^59, the sum < 2^60: no overflow in i64.
        let x = (a << 16) - self.offset_a_q16 as i64;
        let y = (b << 16) - self.offset_b_q16 as i64;
        let c = (x * self.m_aa_q34 as i64 + (1 << 19)) >> 20;
        let s = (x * self.m_ba_q34 as i64 + y * self.m_bb_q34 as i64 + (1 << 19)) >> 20;
        NormalisedLevels {
            cos_q30: saturate_i32(c),
            sin_q30: saturate_i32(s),
        }
    }
}

/// Integer moment sums of one window (the mutable per-sample state).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousAccumulator {
    n: u32,
    s_u: i64,
    s_v: i64,
    s_uu: i64,
    s_uv: i64,
    s_vv: i64,
    s_uuu: i64,
    s_uuv: i64,
    s_uvv: i64,
    s_vvv: i64,
    s_uuuu: i64,
    s_uuuv: i64,
    s_uuvv: i64,
    s_uvvv: i64,
    s_vvvv: i64,
    min_a: u16,
    max_a: u16,
    min_b: u16,
    max_b: u16,
}

impl LissajousAccumulator {
    /// An empty window.
    pub const fn new() -> Self {
        Self {
            n: 0,
            s_u: 0,
            s_v: 0,
            s_uu: 0,
            s_uv: 0,
            s_vv: 0,
            s_uuu: 0,
            s_uuv: 0,
            s_uvv: 0,
            s_vvv: 0,
            s_uuuu: 0,
            s_uuuv: 0,
            s_uuvv: 0,
            s_uvvv: 0,
            s_vvvv: 0,
            min_a: u16::MAX,
            max_a: 0,
            min_b: u16::MAX,
            max_b: 0,
        }
    }

    /// Samples in the window.
    #[inline]
    pub const fn len(&self) -> u32 {
        self.n
    }

    /// True when no sample was added.
    #[inline]
    pub const fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Adds one pair of codes (clamped to full scale). Returns `false` (sample ignored) when
    /// the window already holds [`MAX_WINDOW_SAMPLES`].
    #[inline]
    pub fn add(&mut self, a_code: u16, b_code: u16) -> bool {
        if self.n >= MAX_WINDOW_SAMPLES {
            return false;
        }
        let a = a_code.min(ADC_FULL_SCALE_CODE);
        let b = b_code.min(ADC_FULL_SCALE_CODE);
        self.min_a = self.min_a.min(a);
        self.max_a = self.max_a.max(a);
        self.min_b = self.min_b.min(b);
        self.max_b = self.max_b.max(b);
        // |u|, |v| <= 2048: second-order products fit i32, third and fourth order are
        // products of two i32 factors in i64 (<= 2^44), their sums over 2^18 samples < 2^63.
        let u = a as i32 - ORIGIN_CODE;
        let v = b as i32 - ORIGIN_CODE;
        let (uu, uv, vv) = ((u * u) as i64, (u * v) as i64, (v * v) as i64);
        let (u, v) = (u as i64, v as i64);
        self.n += 1;
        self.s_u = self.s_u.wrapping_add(u);
        self.s_v = self.s_v.wrapping_add(v);
        self.s_uu = self.s_uu.wrapping_add(uu);
        self.s_uv = self.s_uv.wrapping_add(uv);
        self.s_vv = self.s_vv.wrapping_add(vv);
        self.s_uuu = self.s_uuu.wrapping_add(uu * u);
        self.s_uuv = self.s_uuv.wrapping_add(uu * v);
        self.s_uvv = self.s_uvv.wrapping_add(vv * u);
        self.s_vvv = self.s_vvv.wrapping_add(vv * v);
        self.s_uuuu = self.s_uuuu.wrapping_add(uu * uu);
        self.s_uuuv = self.s_uuuv.wrapping_add(uu * uv);
        self.s_uuvv = self.s_uuvv.wrapping_add(uu * vv);
        self.s_uvvv = self.s_uvvv.wrapping_add(uv * vv);
        self.s_vvvv = self.s_vvvv.wrapping_add(vv * vv);
        true
    }

    /// Fits the ellipse of this window and derives the coefficients.
    pub fn solve(
        &self,
        config: &LissajousConfig,
    ) -> Result<(LissajousCoefficients, Ellipse), FitRejection> {
        if self.n < config.min_samples.max(5) {
            return Err(FitRejection::TooFewSamples);
        }
        let min_radius = config.min_radius_codes.max(MIN_RADIUS_CODES) as u32;
        let span_a = self.max_a.saturating_sub(self.min_a) as u32;
        let span_b = self.max_b.saturating_sub(self.min_b) as u32;
        if span_a < 2 * min_radius || span_b < 2 * min_radius {
            return Err(FitRejection::SignalLost);
        }
        let conic = self.fit_conic()?;
        let shape = EllipseShape::from_conic(conic)?;
        if shape.radius_a < min_radius as f64 || shape.radius_b < min_radius as f64 {
            return Err(FitRejection::SignalLost);
        }
        // alpha in Q32 turns through the bit-exact CORDIC (cos alpha > 0: |alpha| < 90 deg).
        let alpha_q32 = atan2_q32(
            saturate_i32(round_to_i64(shape.sin_alpha * (1u64 << 30) as f64)),
            saturate_i32(round_to_i64(shape.cos_alpha * (1u64 << 30) as f64)),
        ) as i32;
        let max_alpha = config
            .max_quadrature_error_q32
            .min(MAX_QUADRATURE_ERROR_Q32);
        if alpha_q32.unsigned_abs() > max_alpha {
            return Err(FitRejection::QuadratureErrorTooLarge);
        }
        let need = |diameter: f64| diameter * (MIN_SPAN_OF_DIAMETER_Q8 as f64 / 256.0);
        if (span_a as f64) < need(2.0 * shape.radius_a)
            || (span_b as f64) < need(2.0 * shape.radius_b)
        {
            return Err(FitRejection::IncompleteCoverage);
        }
        let coefficients = shape.coefficients()?;
        let ellipse = Ellipse {
            offset_a_code: shape.offset_a as f32,
            offset_b_code: shape.offset_b as f32,
            radius_a_code: shape.radius_a as f32,
            radius_b_code: shape.radius_b as f32,
            quadrature_error_rad: (alpha_q32 as f64 * (core::f64::consts::TAU / Q32_PER_FRINGE))
                as f32,
            quadrature_error_q32: alpha_q32,
            samples: self.n,
        };
        Ok((coefficients, ellipse))
    }

    /// Least-squares conic `P U^2 + Q V^2 + R UV + S U + T V = 1` in U, V = u, v / 2048.
    fn fit_conic(&self) -> Result<[f64; 5], FitRejection> {
        let n = self.n as f64;
        // Moment of total order k, scaled by 2048^-k and averaged: all O(1) for full-scale data.
        let m = |sum: i64, order: i32| sum as f64 / (powi_f64(SCALE, order) * n);
        let (u, v) = (m(self.s_u, 1), m(self.s_v, 1));
        let (uu, uv, vv) = (m(self.s_uu, 2), m(self.s_uv, 2), m(self.s_vv, 2));
        let (uuu, uuv, uvv, vvv) = (
            m(self.s_uuu, 3),
            m(self.s_uuv, 3),
            m(self.s_uvv, 3),
            m(self.s_vvv, 3),
        );
        let (uuuu, uuuv, uuvv, uvvv, vvvv) = (
            m(self.s_uuuu, 4),
            m(self.s_uuuv, 4),
            m(self.s_uuvv, 4),
            m(self.s_uvvv, 4),
            m(self.s_vvvv, 4),
        );
        // Regressors (U^2, V^2, UV, U, V); normal matrix and right-hand side (their means).
        let mut a = [
            [uuuu, uuvv, uuuv, uuu, uuv, uu],
            [uuvv, vvvv, uvvv, uvv, vvv, vv],
            [uuuv, uvvv, uuvv, uuv, uvv, uv],
            [uuu, uvv, uuv, uu, uv, u],
            [uuv, vvv, uvv, uv, vv, v],
        ];
        solve5(&mut a).ok_or(FitRejection::Singular)
    }
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
        let full = ADC_FULL_SCALE_CODE as f64;
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

/// Per-window fitting with the coefficients in use: the previous ones are kept when a window
/// is rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LissajousTracker {
    coefficients: LissajousCoefficients,
    ellipse: Option<Ellipse>,
    accumulator: LissajousAccumulator,
    last_rejection: Option<FitRejection>,
    rejections: u32,
}

impl LissajousTracker {
    /// Starts with `initial` coefficients (e.g. [`LissajousCoefficients::NOMINAL`] or stored
    /// ones) and no fit yet.
    pub const fn new(initial: LissajousCoefficients) -> Self {
        Self {
            coefficients: initial,
            ellipse: None,
            accumulator: LissajousAccumulator::new(),
            last_rejection: None,
            rejections: 0,
        }
    }

    /// Adds a sample; at the window's end fits, and returns the outcome (`Some`), starting a
    /// new window. On success the new coefficients take effect for the next [`normalise`].
    ///
    /// [`normalise`]: Self::normalise
    pub fn add(
        &mut self,
        config: &LissajousConfig,
        a_code: u16,
        b_code: u16,
    ) -> Option<Result<Ellipse, FitRejection>> {
        self.accumulator.add(a_code, b_code);
        let window = config.window_samples.clamp(1, MAX_WINDOW_SAMPLES);
        if self.accumulator.len() >= window {
            Some(self.finish_window(config))
        } else {
            None
        }
    }

    /// Closes the current window now (fits it if it has enough samples) and starts a new one.
    pub fn finish_window(&mut self, config: &LissajousConfig) -> Result<Ellipse, FitRejection> {
        let outcome = self.accumulator.solve(config);
        self.accumulator = LissajousAccumulator::new();
        match outcome {
            Ok((coefficients, ellipse)) => {
                self.coefficients = coefficients;
                self.ellipse = Some(ellipse);
                self.last_rejection = None;
                Ok(ellipse)
            }
            Err(reason) => {
                self.last_rejection = Some(reason);
                self.rejections = self.rejections.saturating_add(1);
                Err(reason)
            }
        }
    }

    /// Coefficients in use.
    #[inline]
    pub const fn coefficients(&self) -> LissajousCoefficients {
        self.coefficients
    }

    /// The last accepted fit (`None` before the first).
    #[inline]
    pub const fn ellipse(&self) -> Option<Ellipse> {
        self.ellipse
    }

    /// Why the last window was rejected (`None` if it was accepted or none closed yet).
    #[inline]
    pub const fn last_rejection(&self) -> Option<FitRejection> {
        self.last_rejection
    }

    /// Rejected windows since start (saturating).
    #[inline]
    pub const fn rejections(&self) -> u32 {
        self.rejections
    }

    /// Normalises with the coefficients in use.
    #[inline]
    pub fn normalise(&self, a_code: u16, b_code: u16) -> NormalisedLevels {
        self.coefficients.normalise(a_code, b_code)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{PI, TAU};

    use crate::test_rng::XorShift;

    #[derive(Clone, Copy)]
    struct Truth {
        offset_a: f64,
        offset_b: f64,
        radius_a: f64,
        radius_b: f64,
        alpha: f64,
        noise: f64,
    }

    impl Truth {
        fn ideal(&self, psi: f64) -> (f64, f64) {
            (
                self.offset_a + self.radius_a * psi.cos(),
                self.offset_b + self.radius_b * (psi + self.alpha).sin(),
            )
        }
        /// 12-bit quantised, noisy codes.
        fn codes(&self, psi: f64, rng: &mut XorShift) -> (u16, u16) {
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
    fn dither_psi(rng: &mut XorShift) -> f64 {
        241.0 * TAU * (TAU * rng.uniform()).sin() + 0.37
    }

    fn fit(
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
        acc.solve(&cfg)
    }

    /// Worst radius error |r - 1| and phase error |atan2 - psi| (rad) of the normalised
    /// noise-free ellipse (unquantised codes, evaluated through the same fixed-point math by
    /// interpolating the Q16 offset arithmetic in f64).
    fn circle_errors(c: &LissajousCoefficients, truth: &Truth) -> (f64, f64) {
        let mut worst_r: f64 = 0.0;
        let mut worst_phase: f64 = 0.0;
        for k in 0..3600 {
            let psi = k as f64 / 3600.0 * TAU;
            let (a, b) = truth.ideal(psi);
            let x = a * 65536.0 - c.offset_a_q16 as f64;
            let y = b * 65536.0 - c.offset_b_q16 as f64;
            let cs = x * c.m_aa_q34 as f64 / (1u64 << 50) as f64;
            let sn = (x * c.m_ba_q34 as f64 + y * c.m_bb_q34 as f64) / (1u64 << 50) as f64;
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

    /// The integer normalisation agrees with the f64 formula to a few Q30 LSB, and a point
    /// on the fitted ellipse maps onto the unit circle.
    #[test]
    fn normalise_fixed_point() {
        let c = LissajousCoefficients::NOMINAL;
        let n = c.normalise(2048 + 2047, 2048);
        assert!((n.cos_q30 - (1 << 30)).abs() <= 2);
        assert_eq!(n.sin_q30, 0);
        assert!((n.cos_f32() - 1.0).abs() < 1e-6);
        let n = c.normalise(2048, 1);
        assert!((n.sin_q30 + (1 << 30)).abs() <= 1 << 20, "{n:?}");
        // Offsets outside the ADC range are refused; extreme matrices and codes saturate.
        assert!(LissajousCoefficients::new(-1, 0, 1, 1, 1).is_none());
        assert!(LissajousCoefficients::new(0, (4095 << 16) + 1, 1, 1, 1).is_none());
        let wild = LissajousCoefficients::new(0, 4095 << 16, i32::MAX, i32::MIN, i32::MAX).unwrap();
        let n = wild.normalise(u16::MAX, 0);
        assert_eq!(n.cos_q30, i32::MAX);
        assert_eq!(n.sin_q30, i32::MIN);
        let n = wild.normalise(0, u16::MAX);
        assert_eq!((n.cos_q30, n.sin_q30), (0, 0));
    }

    /// The integer normalisation against the same formula in f64 for random valid
    /// coefficients and codes: within 1 LSB of Q30 (the final rounding; the i64 products are
    /// exact).
    #[test]
    fn normalise_matches_f64_formula() {
        let mut rng = XorShift(31);
        for _ in 0..200_000 {
            let c = LissajousCoefficients::new(
                (rng.next() % (4095 << 16)) as i32,
                (rng.next() % (4095 << 16)) as i32,
                (rng.next() >> 34) as i32,
                rng.next() as i32 >> 2,
                (rng.next() >> 34) as i32,
            )
            .unwrap();
            let (a, b) = ((rng.next() % 4096) as u16, (rng.next() % 4096) as u16);
            let x = a as f64 * 65536.0 - c.offset_a_q16 as f64;
            let y = b as f64 * 65536.0 - c.offset_b_q16 as f64;
            let want_c = x * c.m_aa_q34 as f64 / (1u64 << 20) as f64;
            let want_s = (x * c.m_ba_q34 as f64 + y * c.m_bb_q34 as f64) / (1u64 << 20) as f64;
            let n = c.normalise(a, b);
            let sat = |v: f64| v.clamp(i32::MIN as f64, i32::MAX as f64);
            assert!(
                (n.cos_q30 as f64 - sat(want_c)).abs() <= 1.0,
                "{n:?} {want_c}"
            );
            assert!(
                (n.sin_q30 as f64 - sat(want_s)).abs() <= 1.0,
                "{n:?} {want_s}"
            );
        }
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
            acc.add(2048, 2048);
        }
        assert_eq!(acc.solve(&cfg).map(|_| ()), Err(FitRejection::SignalLost));
        // Channels in phase: a straight line, not an ellipse.
        let mut acc = LissajousAccumulator::new();
        for k in 0..4096 {
            let x = 2048 + (1500.0 * (k as f64 * 0.01).cos()) as i32;
            acc.add(x as u16, x as u16);
        }
        assert!(matches!(
            acc.solve(&cfg),
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
            acc.solve(&cfg).map(|_| ()),
            Err(FitRejection::IncompleteCoverage)
        );
    }

    #[test]
    fn tracker_keeps_coefficients_on_rejection() {
        let cfg = LissajousConfig {
            window_samples: 2048,
            ..LissajousConfig::DEFAULT
        };
        let good = Truth {
            offset_a: 2000.0,
            offset_b: 2100.0,
            radius_a: 1400.0,
            radius_b: 1600.0,
            alpha: 0.05,
            noise: 1.5,
        };
        let mut rng = XorShift(77);
        let mut tracker = LissajousTracker::new(LissajousCoefficients::NOMINAL);
        let mut outcomes = Vec::new();
        for _ in 0..2048 {
            let (a, b) = good.codes(dither_psi(&mut rng), &mut rng);
            if let Some(o) = tracker.add(&cfg, a, b) {
                outcomes.push(o);
            }
        }
        assert_eq!(outcomes.len(), 1);
        assert!(outcomes[0].is_ok());
        let fitted = tracker.coefficients();
        assert_ne!(fitted, LissajousCoefficients::NOMINAL);
        // Signal lost for a window: rejected, coefficients kept.
        for _ in 0..2048 {
            tracker.add(&cfg, 2000, 2100);
        }
        assert_eq!(tracker.last_rejection(), Some(FitRejection::SignalLost));
        assert_eq!(tracker.coefficients(), fitted);
        assert_eq!(tracker.rejections(), 1);
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
                acc.add(a, b);
            }
            let cfg = LissajousConfig {
                min_samples: 5,
                min_radius_codes: 16,
                ..LissajousConfig::DEFAULT
            };
            if let Ok((c, _)) = acc.solve(&cfg) {
                assert!(c.offset_a_q16 >= 0 && c.offset_a_q16 <= 4095 << 16);
                assert!(c.m_aa_q34 > 0 && c.m_bb_q34 > 0);
            }
        }
    }

    /// The accumulator at its maximum window with full-scale extremes: exact, no overflow.
    #[test]
    fn full_window_no_overflow() {
        let mut acc = LissajousAccumulator::new();
        for k in 0..MAX_WINDOW_SAMPLES {
            let (a, b) = if k % 2 == 0 { (0, 0) } else { (4095, 0) };
            assert!(acc.add(a, b));
        }
        assert!(!acc.add(0, 0));
        assert_eq!(acc.len(), MAX_WINDOW_SAMPLES);
        assert_eq!(acc.s_vvvv, 2048i64.pow(4) * MAX_WINDOW_SAMPLES as i64);
    }
}
