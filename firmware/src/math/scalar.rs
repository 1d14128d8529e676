//! Scalar helpers that give the same bits on every IEEE target.
//!
//! The firmware's `f64` work (the Lissajous window solve, conversions to Q32 fringes) must
//! produce identical bits on the Cortex-M4F (software `f64`) and on x86-64 (SSE2), so that the
//! simulator, the golden vectors and the board agree. Basic operations (`+ - * /`, comparisons,
//! `as` conversions) are correctly rounded on both, without fused multiply-adds; `core` offers
//! no `f64::sqrt`, `abs` or `round` without `std`, and `libm`'s versions are not all correctly
//! rounded. So these helpers are built from basic operations only.

/// `x > 0`, false for NaN.
#[inline]
pub fn positive(x: f64) -> bool {
    x > 0.0
}

/// `|x|` (NaN stays NaN).
#[inline]
pub fn abs_f64(x: f64) -> f64 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// The larger of `a` and `b`; `a` when they compare unordered (NaN).
#[inline]
pub fn max_f64(a: f64, b: f64) -> f64 {
    if b > a {
        b
    } else {
        a
    }
}

/// `base^exp` by repeated multiplication (exact for powers of two); 1 for `exp <= 0`.
pub fn powi_f64(base: f64, exp: i32) -> f64 {
    let mut r = 1.0;
    for _ in 0..exp {
        r *= base;
    }
    r
}

/// Round half away from zero, saturating (`as` saturates, NaN -> 0). `x + 0.5` is rounded
/// before the truncation, so the largest value below one half (and its negative) rounds away
/// from zero: a half-LSB quirk the callers' tolerances absorb, kept for bit-identical outputs.
#[inline]
pub fn round_to_i64(x: f64) -> i64 {
    if x >= 0.0 {
        (x + 0.5) as i64
    } else {
        (x - 0.5) as i64
    }
}

/// Round half away from zero in `f32`, saturating (`f32::round` is absent from `core`); the
/// same half-LSB quirk as [`round_to_i64`].
#[inline]
pub fn round_f32_to_i32(x: f32) -> i32 {
    if x >= 0.0 {
        (x + 0.5) as i32
    } else {
        (x - 0.5) as i32
    }
}

/// Saturating `i64 -> i32`.
#[inline]
pub fn saturate_i32(x: i64) -> i32 {
    x.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

/// Square root from basic operations only (bit-identical on every IEEE target): exponent-halving
/// first guess (within a factor 1.5 of the root), then Newton steps to convergence (within
/// 1 ulp of the correctly rounded root). Tiny inputs are scaled by an exact power of two first
/// so that the guess is good for subnormals too. 0 for x <= 0 or NaN.
pub fn sqrt_f64(x: f64) -> f64 {
    if !positive(x) {
        return 0.0;
    }
    if !x.is_finite() {
        return x;
    }
    let two_pow = |e: i64| f64::from_bits(((1023 + e) as u64) << 52);
    let (x, undo) = if x < two_pow(-500) {
        (x * two_pow(600), two_pow(-300))
    } else {
        (x, 1.0)
    };
    let mut y = f64::from_bits((x.to_bits() >> 1) + (1023u64 << 51));
    for _ in 0..8 {
        y = 0.5 * (y + x / y);
    }
    y * undo
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    #[test]
    fn sqrt_matches_std() {
        let mut rng = XorShift(3);
        for _ in 0..100_000 {
            let x = f64::from_bits(rng.next() >> 2); // positive, wide exponent range
            if !x.is_finite() || x == 0.0 {
                continue;
            }
            let got = sqrt_f64(x);
            let exact = x.sqrt();
            assert!(
                ((got - exact) / exact).abs() <= 2.3e-16,
                "{x}: {got} vs {exact}"
            );
        }
        assert_eq!(sqrt_f64(-1.0), 0.0);
        assert_eq!(sqrt_f64(f64::NAN), 0.0);
        assert_eq!(sqrt_f64(4.0), 2.0);
    }

    #[test]
    fn rounding_and_saturation() {
        assert_eq!(round_to_i64(2.5), 3);
        assert_eq!(round_to_i64(-2.5), -3);
        assert_eq!(round_to_i64(f64::NAN), 0);
        assert_eq!(round_to_i64(1e300), i64::MAX);
        assert_eq!(round_f32_to_i32(-0.5), -1);
        // The sum rounds first: the largest f32 below 1/2 rounds up (documented).
        assert_eq!(round_f32_to_i32(0.49999997), 1);
        assert_eq!(saturate_i32(i64::MIN), i32::MIN);
        assert_eq!(saturate_i32(-5), -5);
        assert_eq!(powi_f64(2048.0, 4), 2048.0 * 2048.0 * 2048.0 * 2048.0);
        assert_eq!(abs_f64(-0.25), 0.25);
        assert!(max_f64(f64::NAN, 1.0).is_nan());
        assert_eq!(max_f64(1.0, f64::NAN), 1.0);
    }
}
