//! Fast `(cos, sin)` for the integrator's inner loops and the dither phase, and the dither
//! phase itself reduced exactly ([`reduced_phase`]).

use core::f64::consts::TAU;

/// `(cos x, sin x)` for |x| < 1e5, to ~2 ulp of 1: Cody-Waite reduction by pi/2 and Taylor
/// polynomials on [-pi/4, pi/4] (libm is ~3x slower and this is the integrator's inner loop).
#[inline(always)]
pub fn fast_cos_sin(x: f64) -> (f64, f64) {
    const TWO_OVER_PI: f64 = core::f64::consts::FRAC_2_PI;
    const P1: f64 = 1.570_796_326_734_125_6; // pi/2 high part (33 bits)
    const P2: f64 = 6.077_100_506_506_192e-11; // pi/2 - P1
                                               // Round to nearest by the 1.5 * 2^52 trick (`f64::round` is a libm call on x86-64 v1).
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let k = (x * TWO_OVER_PI + MAGIC) - MAGIC;
    let r = (x - k * P1) - k * P2;
    let r2 = r * r;
    // cos and sin Taylor series to r^16 / r^17 (|r| <= pi/4: error < 1e-17).
    let c = 1.0
        + r2 * (-0.5
            + r2 * (1.0 / 24.0
                + r2 * (-1.0 / 720.0
                    + r2 * (1.0 / 40320.0
                        + r2 * (-1.0 / 3628800.0
                            + r2 * (1.0 / 479001600.0
                                + r2 * (-1.0 / 87178291200.0 + r2 * (1.0 / 20922789888000.0))))))));
    let sn = r
        * (1.0
            + r2 * (-1.0 / 6.0
                + r2 * (1.0 / 120.0
                    + r2 * (-1.0 / 5040.0
                        + r2 * (1.0 / 362880.0
                            + r2 * (-1.0 / 39916800.0
                                + r2 * (1.0 / 6227020800.0 + r2 * (-1.0 / 1307674368000.0))))))));
    // Quadrant without branches (the quadrant of a fringe phase is random: a `match`
    // would mispredict most of the time).
    const SIGN: [f64; 2] = [1.0, -1.0];
    let q = (k as i64 & 3) as usize;
    let v = [c, sn];
    let swap = q & 1;
    (
        v[swap] * SIGN[((q + 1) >> 1) & 1],
        v[1 - swap] * SIGN[q >> 1],
    )
}

#[inline]
fn split(a: f64) -> (f64, f64) {
    let c = 134_217_729.0 * a;
    let hi = c - (c - a);
    (hi, a - hi)
}

/// `2 pi frac(f t)`: the dither phase in [0, 2 pi), with `f t` formed as an error-free
/// product (Dekker; `f64::mul_add` would be a slow libm call without target FMA) and the
/// floor by the 1.5 * 2^52 rounding trick (valid for |f t| < 2^51, negative times included).
pub fn reduced_phase(freq_hz: f64, t_s: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let p = freq_hz * t_s;
    let (fh, fl) = split(freq_hz);
    let (th, tl) = split(t_s);
    let e = ((fh * th - p) + fh * tl + fl * th) + fl * tl;
    let mut n = (p + MAGIC) - MAGIC;
    if n > p {
        n -= 1.0;
    }
    TAU * ((p - n) + e)
}
