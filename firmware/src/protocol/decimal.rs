//! The protocol's decimal numbers to `f32`, in a few hundred bytes of code.
//!
//! `core`'s `f32::from_str` is exact in every case (Eisel-Lemire with a fallback), but brings a
//! 10 KiB table of 128-bit powers of five and 3 KiB of code into the board image (measured with
//! `llvm-nm --size-sort` on the `hw` image: `POWER_OF_FIVE_128` 10 416 bytes, `from_str` 2 672,
//! `compute_float` 606). The protocol's numbers are typed coefficients and setpoints of a few
//! significant digits, all of them checked against a range and most rounded to Q15.16 right
//! after, so this parser trades the last-ulp guarantee for size: up to 19 significant digits
//! are kept in a `u64`, scaled by one exact power of ten in `f64` (a single correctly rounded
//! operation for |exponent| <= 22), and rounded to `f32`. The result is within one `f32` ulp of
//! the exact value, and exact for every number of up to 7 significant digits with |exponent|
//! <= 22 except halfway double-rounding cases (tests against `core`'s parser).
//!
//! Grammar (as `core` accepts it): optional sign, digits with an optional `.`, optional
//! exponent `e`/`E` with optional sign; `nan`, `inf`, `infinity` (any case) give those values
//! so the caller refuses them as not finite.

/// Exact powers of ten in `f64` (10^22 is the largest exactly representable one).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// `text` as an `f32`, or `None` if it is not a decimal number.
pub fn parse_f32(text: &str) -> Option<f32> {
    let (negative, body) = match text.as_bytes().first()? {
        b'-' => (true, text.get(1..)?),
        b'+' => (false, text.get(1..)?),
        _ => (false, text),
    };
    let special = if body.eq_ignore_ascii_case("nan") {
        Some(f32::NAN)
    } else if body.eq_ignore_ascii_case("inf") || body.eq_ignore_ascii_case("infinity") {
        Some(f32::INFINITY)
    } else {
        None
    };
    let magnitude = match special {
        Some(v) => v,
        None => magnitude(body.as_bytes())?,
    };
    Some(if negative { -magnitude } else { magnitude })
}

/// The exact power of ten `10^e` for `0 <= e <= 22` (`POW10`), else 1 (callers keep `e` in
/// that range).
fn pow10(e: i32) -> f64 {
    usize::try_from(e)
        .ok()
        .and_then(|i| POW10.get(i))
        .copied()
        .unwrap_or(1.0)
}

/// The largest exact power of ten, 10^22.
const POW10_MAX: f64 = 1e22;

fn magnitude(bytes: &[u8]) -> Option<f32> {
    let mut mantissa: u64 = 0;
    let mut significant = 0u32;
    let mut exp10: i32 = 0;
    let mut digits = 0u32;
    let mut seen_point = false;
    let mut rest = bytes;
    // Counts stay far from their types' limits: `digits` and `exp10` grow by one per byte of
    // a line of at most 96 bytes, `mantissa` holds at most 19 digits (< 10^19 < 2^64).
    while let Some((&byte, after)) = rest.split_first() {
        match byte {
            b'0'..=b'9' => {
                digits = digits.saturating_add(1);
                let d = u64::from(byte.wrapping_sub(b'0'));
                if significant < 19 {
                    if mantissa != 0 || d != 0 {
                        significant = significant.saturating_add(1);
                    }
                    mantissa = mantissa.saturating_mul(10).saturating_add(d);
                    if seen_point {
                        exp10 = exp10.saturating_sub(1);
                    }
                } else if !seen_point {
                    exp10 = exp10.saturating_add(1); // a dropped integer digit still counts
                }
            }
            b'.' if !seen_point => seen_point = true,
            b'e' | b'E' => break,
            _ => return None,
        }
        rest = after;
    }
    if digits == 0 {
        return None;
    }
    if let Some((_, exponent_text)) = rest.split_first() {
        exp10 = exp10.saturating_add(exponent(exponent_text)?);
    }
    let mut value = mantissa as f64;
    if value == 0.0 {
        return Some(0.0);
    }
    // At most a few steps: the exponent saturates at +-99 999 and the value leaves f64's range
    // (or reaches 0) long before; then no further scaling can bring it back.
    while exp10 > 22 {
        if !value.is_finite() {
            return Some(f32::INFINITY);
        }
        value *= POW10_MAX;
        exp10 = exp10.saturating_sub(22);
    }
    while exp10 < -22 {
        if value == 0.0 {
            return Some(0.0);
        }
        value /= POW10_MAX;
        exp10 = exp10.saturating_add(22);
    }
    value = if exp10 >= 0 {
        value * pow10(exp10)
    } else {
        value / pow10(exp10.saturating_neg())
    };
    Some(value as f32)
}

/// The exponent after `e`: optional sign and at least one digit (saturating at +-99 999).
fn exponent(bytes: &[u8]) -> Option<i32> {
    let (negative, digits) = match bytes.split_first()? {
        (b'-', rest) => (true, rest),
        (b'+', rest) => (false, rest),
        _ => (false, bytes),
    };
    if digits.is_empty() {
        return None;
    }
    let mut e: i32 = 0;
    for &b in digits {
        if !b.is_ascii_digit() {
            return None;
        }
        e = e
            .saturating_mul(10)
            .saturating_add(i32::from(b.wrapping_sub(b'0')))
            .min(99_999);
    }
    Some(if negative { e.saturating_neg() } else { e })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::XorShift;

    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    /// The protocol's typical numbers parse exactly as `core` parses them.
    #[test]
    fn typical_numbers_are_exact() {
        for text in [
            "0",
            "-0",
            "1",
            "12.5",
            "344.25",
            "344.123456",
            "-5.5e2",
            "1e9",
            "420.5",
            "0.001",
            "3600000",
            "-13.888",
            "1E-3",
            ".5",
            "5.",
            "+7",
            "32767",
            "-32767.99",
            "1e-7",
        ] {
            let want: f32 = text.parse().unwrap();
            assert_eq!(parse_f32(text), Some(want), "{text}");
        }
    }

    /// What `core` refuses is refused; NaN and infinities come through for the range check.
    #[test]
    fn non_numbers_are_refused_and_specials_kept() {
        for text in [
            "", "-", ".", "e5", "1e", "1e+", "1.2.3", "12a", "0x10", "1 2", "--1", "+-1",
        ] {
            assert_eq!(parse_f32(text), None, "{text:?}");
            assert!(text.parse::<f32>().is_err(), "core accepts {text:?}");
        }
        assert!(parse_f32("NaN").unwrap().is_nan());
        assert_eq!(parse_f32("-inf"), Some(f32::NEG_INFINITY));
        assert_eq!(parse_f32("Infinity"), Some(f32::INFINITY));
        assert_eq!(parse_f32("1e39"), Some(f32::INFINITY));
        assert_eq!(parse_f32("1e-50"), Some(0.0));
        // Found by the protocol fuzzer: exponents far beyond f64 must not index past the table.
        for text in [
            "1e399",
            "1e99999999",
            "9999999999999999999999e400",
            "1e-400",
            "1e-99999",
        ] {
            let want: f32 = text.parse().unwrap();
            assert_eq!(parse_f32(text), Some(want), "{text}");
        }
    }

    /// Random decimals (1-12 significant digits, exponents -30..30): within 1 ulp of `core`.
    #[test]
    fn random_decimals_are_within_one_ulp() {
        let mut rng = XorShift(0x9E37_79B9_7F4A_7C15);
        let mut exact = 0;
        for _ in 0..20_000 {
            let digits = 1 + rng.next() % 12;
            let mantissa = rng.next() % 10u64.pow(digits as u32);
            let exp = (rng.next() % 61) as i32 - 30;
            let text = format!("{mantissa}e{exp}");
            let want: f32 = text.parse().unwrap();
            let got = parse_f32(&text).unwrap();
            assert!(ulps(got, want) <= 1, "{text}: {got} vs {want}");
            exact += usize::from(got == want);
        }
        assert!(exact > 19_900, "{exact} of 20000 exact");
    }
}
