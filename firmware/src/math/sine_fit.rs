//! Least-squares fit of `offset + a cos(theta) + b sin(theta)` to samples whose regressor phase
//! theta is known (a drive's DDS, a tracker's oscillator): synchronous demodulation made exact
//! for a window that is not a whole number of periods.
//!
//! # Why a fit and not a plain lock-in sum
//! A window's ends fall between samples and rarely span whole periods. A plain demodulation
//! `sum x cos` then leaks the 2f term by up to one sample's worth (1/N of the amplitude), and an
//! offset d enters the amplitude with a sign that depends on where the window starts. Solving
//! the 3x3 normal equations of [1, cos, sin] instead is exact for an offset plus a sine at the
//! regressor's frequency whatever the window, for five more 64-bit multiply-accumulates per
//! sample (the regressors' own sums) and one small solve per window.
//!
//! # Formats
//! Samples are centred codes (`x = code - mid`, |x| <= 2^12); the regressors are
//! `idsp::cossin`'s Q31 shifted to Q15; sums are exact integers (`i32` for the plain sums, `i64`
//! for the products), so windows add without rounding ([`SineSums::merge`]). A fit is capped at
//! [`MAX_SAMPLES`] = 2^10 samples, so every term of the centred normal equations,
//! n * sum - sum * sum, stays below 2^51. The 2x2 solve after centring is `f32` (condition
//! number below 10 for a window of half a period or more: 1e-6 relative error, against 1e-4
//! from a 12-bit converter's quantisation), with basic IEEE operations only: the host and the
//! Cortex-M4F compute the same bits.

use crate::units::Phase;

/// The most samples one set of sums may hold.
pub const MAX_SAMPLES: u32 = 1 << 10;

/// `(cos, sin)` of `phase` in Q31 (`idsp::cossin`: ~40 Cortex-M4 instructions, spurs at
/// -120 dBc).
#[inline]
pub fn cos_sin_q31(phase: Phase) -> (i32, i32) {
    idsp::cossin(phase.to_signed())
}

/// The running sums of the normal equations of one window (or of several, merged).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SineSums {
    n: u32,
    sx: i32,
    sc: i32,
    ss: i32,
    scc: i64,
    scs: i64,
    sss: i64,
    sxc: i64,
    sxs: i64,
}

/// A fitted sine: `x = offset + amplitude cos(theta + phase)` in codes, with theta the regressor
/// phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SineFit {
    /// Amplitude, codes: `hypot(a, b)`.
    pub amplitude_codes: f32,
    /// Phase of the signal relative to the regressor phase: `x = offset + amplitude *
    /// cos(theta + phase)`, Q32 turns (`idsp::atan2`).
    pub phase: Phase,
    /// The offset, codes relative to the mid-code the samples were centred on.
    pub offset_codes: f32,
}

impl SineFit {
    /// The fitted signal at regressor phase `theta`, codes relative to the mid-code.
    pub fn value_at(&self, theta: Phase) -> f32 {
        let (cos_q31, _) = cos_sin_q31(theta + self.phase);
        self.offset_codes + self.amplitude_codes * (cos_q31 as f32 / 2_147_483_648.0)
    }
}

impl SineSums {
    /// No sample.
    pub const fn new() -> Self {
        Self {
            n: 0,
            sx: 0,
            sc: 0,
            ss: 0,
            scc: 0,
            scs: 0,
            sss: 0,
            sxc: 0,
            sxs: 0,
        }
    }

    /// Samples so far.
    #[inline]
    pub fn len(&self) -> u32 {
        self.n
    }

    /// No sample yet.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Adds one sample: the centred code `x` and the regressors in Q15. The caller keeps the
    /// count at or below [`MAX_SAMPLES`].
    #[inline]
    pub fn push(&mut self, x: i32, cos_q15: i32, sin_q15: i32) {
        self.n += 1;
        self.sx += x;
        self.sc += cos_q15;
        self.ss += sin_q15;
        // Widened before the product: one multiply-accumulate (SMLAL) each on the M4, the same
        // exact integer as the product widened after.
        let (x, c, s) = (i64::from(x), i64::from(cos_q15), i64::from(sin_q15));
        self.scc += c * c;
        self.scs += c * s;
        self.sss += s * s;
        self.sxc += x * c;
        self.sxs += x * s;
    }

    /// Adds another window's sums (exact: integer sums). The caller keeps the total at or
    /// below [`MAX_SAMPLES`].
    pub fn merge(&mut self, other: &Self) {
        self.n += other.n;
        self.sx += other.sx;
        self.sc += other.sc;
        self.ss += other.ss;
        self.scc += other.scc;
        self.scs += other.scs;
        self.sss += other.sss;
        self.sxc += other.sxc;
        self.sxs += other.sxs;
    }

    /// The least-squares fit of `[1, cos, sin]`: centred normal equations (exact integers), then
    /// the 2x2 solve in `f32`. `None` for fewer than 4 samples or regressors that do not span a
    /// sine (a window far shorter than a period, or no sample).
    pub fn fit(&self) -> Option<SineFit> {
        if self.n < 4 {
            return None;
        }
        let n = self.n as i64;
        let (sx, sc, ss) = (self.sx as i64, self.sc as i64, self.ss as i64);
        let dcc = (n * self.scc - sc * sc) as f32;
        let dcs = (n * self.scs - sc * ss) as f32;
        let dss = (n * self.sss - ss * ss) as f32;
        let dxc = (n * self.sxc - sx * sc) as f32;
        let dxs = (n * self.sxs - sx * ss) as f32;
        let det = dcc * dss - dcs * dcs;
        if det.is_nan() || det <= 0.0 {
            return None;
        }
        // Coefficients per Q15 unit of the regressors; * 2^15 gives codes.
        let a = (dss * dxc - dcs * dxs) / det;
        let b = (dcc * dxs - dcs * dxc) / det;
        let offset = (self.sx as f32 - a * self.sc as f32 - b * self.ss as f32) / self.n as f32;
        let (a, b) = (a * 32_768.0, b * 32_768.0);
        // x = a cos + b sin = A cos(theta + phase) with A cos(phase) = a, A sin(phase) = -b.
        let amplitude = libm::sqrtf(a * a + b * b);
        let to_i32 = |v: f32| crate::math::round_f32_to_i32(v * 65_536.0);
        let phase = Phase::from_bits(idsp::atan2(to_i32(-b), to_i32(a)) as u32);
        Some(SineFit {
            amplitude_codes: amplitude,
            phase,
            offset_codes: offset,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// Two windows merged fit as the one window of all their samples, bit for bit, and the
    /// fitted sine gives back its samples (noise-free, 1e-3 code: the ADC-free f32 model).
    #[test]
    fn merged_windows_fit_as_one_and_the_fit_gives_back_the_signal() {
        let step = Phase::from_bits(41_757_000);
        let signal = |theta: Phase| {
            12.5 + 800.0 * (TAU * (theta.to_bits() as f64 / 4_294_967_296.0 + 0.3)).cos()
        };
        let (mut first, mut second, mut whole) =
            (SineSums::new(), SineSums::new(), SineSums::new());
        let mut theta = Phase::from_bits(123_456_789);
        let start = theta;
        for i in 0..300 {
            let (c, s) = cos_sin_q31(theta);
            let x = signal(theta).round() as i32;
            if i < 120 {
                first.push(x, c >> 16, s >> 16);
            } else {
                second.push(x, c >> 16, s >> 16);
            }
            whole.push(x, c >> 16, s >> 16);
            theta = theta + step;
        }
        first.merge(&second);
        assert_eq!(first, whole);
        let fit = whole.fit().unwrap();
        let mut worst: f64 = 0.0;
        let mut theta = start;
        for _ in 0..300 {
            worst = worst.max((fit.value_at(theta) as f64 - signal(theta)).abs());
            theta = theta + step;
        }
        // The samples were rounded to whole codes: the fit is within a fraction of a code.
        assert!(worst < 0.6, "{worst}");
        assert!((fit.amplitude_codes - 800.0).abs() < 0.05, "{fit:?}");
        assert!((fit.offset_codes - 12.5).abs() < 0.05, "{fit:?}");
    }
}
