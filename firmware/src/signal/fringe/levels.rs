//! Normalisation (per turnaround, integer): the latched photodiode codes -> (cos psi_H,
//! sin psi_H).
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
//! instructions. The matrix entries fit an `i32` for radii >= `MIN_RADIUS_CODES` (16) and
//! |alpha| <= 45 deg; resolution 1 part in 2^23 at a full-scale radius of 2048 codes. The
//! coefficients come from the window fit (`ellipse.rs`), or [`LissajousCoefficients::NOMINAL`]
//! until the first one.

use crate::math::{atan2_q32, radius_sq_q30, saturate_i32};
use crate::sample::AdcCode;
use crate::units::Phase;

/// Mid-scale of the 12-bit ADC: the origin of the fit's integer moment coordinates and the
/// nominal offsets.
pub const ORIGIN_CODE: i32 = AdcCode::MID.to_bits() as i32;

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
    /// cos psi_H, Q30 (saturated).
    pub cos_q30: i32,
    /// sin psi_H, Q30 (saturated).
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

    /// The fractional fringe: psi_H modulo one fringe, the angle of (cos psi_H, sin psi_H) by
    /// the bit-exact CORDIC (`math::atan2_q32`, error <= 32 LSB = 4.7e-8 rad).
    #[inline]
    pub fn fractional_fringe(self) -> Phase {
        atan2_q32(self.sin_q30, self.cos_q30)
    }

    /// cos^2 + sin^2 in Q30 (1.0 = 2^30, saturating): about 2^30 for a healthy signal, much
    /// less when the fringe contrast is gone.
    #[inline]
    pub fn radius_sq_q30(self) -> u32 {
        radius_sq_q30(self.cos_q30, self.sin_q30)
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
        const MAX_OFFSET_Q16: i32 = (AdcCode::FULL_SCALE.to_bits() as i32) << 16;
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

    /// Normalises one pair of ADC codes.
    #[inline]
    pub fn normalise(&self, a_code: AdcCode, b_code: AdcCode) -> NormalisedLevels {
        let a = a_code.to_bits() as i64;
        let b = b_code.to_bits() as i64;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    /// The integer normalisation agrees with the f64 formula to a few Q30 LSB, and a point
    /// on the fitted ellipse maps onto the unit circle.
    #[test]
    fn normalise_fixed_point() {
        let c = LissajousCoefficients::NOMINAL;
        let code = |c| AdcCode::new(c).unwrap();
        let n = c.normalise(AdcCode::FULL_SCALE, AdcCode::MID);
        assert!((n.cos_q30 - (1 << 30)).abs() <= 2);
        assert_eq!(n.sin_q30, 0);
        assert!((n.cos_f32() - 1.0).abs() < 1e-6);
        let n = c.normalise(AdcCode::MID, code(1));
        assert!((n.sin_q30 + (1 << 30)).abs() <= 1 << 20, "{n:?}");
        // Offsets outside the ADC range are refused; extreme matrices and codes saturate.
        assert!(LissajousCoefficients::new(-1, 0, 1, 1, 1).is_none());
        assert!(LissajousCoefficients::new(0, (4095 << 16) + 1, 1, 1, 1).is_none());
        let wild = LissajousCoefficients::new(0, 4095 << 16, i32::MAX, i32::MIN, i32::MAX).unwrap();
        let n = wild.normalise(AdcCode::FULL_SCALE, AdcCode::ZERO);
        assert_eq!(n.cos_q30, i32::MAX);
        assert_eq!(n.sin_q30, i32::MIN);
        let n = wild.normalise(AdcCode::ZERO, AdcCode::FULL_SCALE);
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
            let mut code = || AdcCode::new((rng.next() % 4096) as u16).unwrap();
            let (a, b) = (code(), code());
            let x = a.to_f64() * 65536.0 - c.offset_a_q16 as f64;
            let y = b.to_f64() * 65536.0 - c.offset_b_q16 as f64;
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
}
