//! The per-sample half of the Heydemann fit: exact integer moment sums of a window of
//! photodiode code pairs.
//!
//! With `u = A - 2048`, `v = B - 2048` (integers, |u|, |v| <= 2048), the 14 moment sums
//! `sum u^i v^j`, `1 <= i+j <= 4`, accumulate exactly in `i64` (each term <= 2^44, so up to
//! [`MAX_WINDOW_SAMPLES`] = 2^18 samples cannot overflow), plus the min/max code of each
//! channel. Exact integer sums are independent of order and target. About 130 instructions per
//! sample at `opt-level = "s"` (QEMU `-icount`; the 28-word state does not fit the registers).
//!
//! At the window's end the sums become the normal equations of the conic fit
//! ([`LissajousAccumulator::normal_equations`]), which `ellipse.rs` solves.

use super::levels::ORIGIN_CODE;
use crate::math::powi_f64;
use crate::sample::AdcCode;

/// Largest window: the `i64` fourth-moment sums cannot overflow below 2^63 / 2048^4 = 2^19.
pub const MAX_WINDOW_SAMPLES: u32 = 1 << 18;

/// The fit's coordinates are U, V = u, v / SCALE: all moments O(1) for full-scale data.
pub(super) const SCALE: f64 = ORIGIN_CODE as f64;

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

    /// Adds one pair of codes. Returns `false` (sample ignored) when
    /// the window already holds [`MAX_WINDOW_SAMPLES`].
    #[inline]
    pub fn add(&mut self, a_code: AdcCode, b_code: AdcCode) -> bool {
        if self.n >= MAX_WINDOW_SAMPLES {
            return false;
        }
        let (a, b) = (a_code.to_bits(), b_code.to_bits());
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

    /// The code span (max - min) of channel A and of channel B over the window.
    pub(super) fn spans(&self) -> (u32, u32) {
        (
            self.max_a.saturating_sub(self.min_a) as u32,
            self.max_b.saturating_sub(self.min_b) as u32,
        )
    }

    /// The normal equations of the least-squares conic `P U^2 + Q V^2 + R UV + S U + T V = 1`
    /// in U, V = u, v / 2048, as the augmented 5x6 matrix of `math::solve5`: regressors
    /// (U^2, V^2, UV, U, V), the matrix of their mean products and the right-hand side of their
    /// means. Meaningful for a non-empty window.
    pub(super) fn normal_equations(&self) -> [[f64; 6]; 5] {
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
        [
            [uuuu, uuvv, uuuv, uuu, uuv, uu],
            [uuvv, vvvv, uvvv, uvv, vvv, vv],
            [uuuv, uvvv, uuvv, uuv, uvv, uv],
            [uuu, uvv, uuv, uu, uv, u],
            [uuv, vvv, uvv, uv, vv, v],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The accumulator at its maximum window with full-scale extremes: exact, no overflow.
    #[test]
    fn full_window_no_overflow() {
        let mut acc = LissajousAccumulator::new();
        for k in 0..MAX_WINDOW_SAMPLES {
            let a = if k % 2 == 0 {
                AdcCode::ZERO
            } else {
                AdcCode::FULL_SCALE
            };
            assert!(acc.add(a, AdcCode::ZERO));
        }
        assert!(!acc.add(AdcCode::ZERO, AdcCode::ZERO));
        assert_eq!(acc.len(), MAX_WINDOW_SAMPLES);
        assert_eq!(acc.s_vvvv, 2048i64.pow(4) * MAX_WINDOW_SAMPLES as i64);
        assert_eq!(acc.spans(), (4095, 0));
    }
}
