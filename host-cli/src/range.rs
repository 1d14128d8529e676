//! The valid range of a numeric command-line flag, defined once as a [`Range`] constant and read
//! by everything that needs it: clap's value parser ([`Range::parser`]: a value outside is a
//! usage error, exit 2, with the range in the message), the flag's help ([`Range::help`]: the
//! range is printed from the same numbers) and the library's own checks of the same setting
//! ([`Range::check`], for callers that build the options in code).
//!
//! Every refusal names the range, e.g. `error: invalid value '-5' for '--seconds <SECONDS>': -5
//! is outside 0 < x <= 86400 s`. A whole number the flag's type cannot hold (`-1` for an
//! unsigned count, twenty digits) is outside the range like any other, not a parse error; `inf`
//! and `NaN` are refused as not finite. A ranged flag also takes `allow_negative_numbers =
//! true`, so that `-5` reaches the parser instead of being taken for an unknown flag.
//!
//! Trade-off: clap's derive takes help text from doc comments, which cannot hold a computed
//! number, so a ranged flag's help is an expression (`help = RANGE.help("...")`) instead of a
//! doc comment. Ranges that depend on another flag (a run's end, a maximum above a minimum) stay
//! checks after parsing.

use std::fmt::Display;
use std::str::FromStr;

/// An inclusive range (optionally open at the bottom) of one flag, with its unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range<T> {
    /// The flag, as the user types it (`--dither-hz`): named in [`Range::check`]'s message.
    pub flag: &'static str,
    /// Lowest valid value (excluded when `min_open`).
    pub min: T,
    /// Highest valid value.
    pub max: T,
    /// True when `min` itself is refused (a duration that must be positive).
    pub min_open: bool,
    /// Unit of the value, for the help and the messages ("" for a plain count or ratio).
    pub unit: &'static str,
    /// How the bounds are printed when their decimal form would not be read at a glance
    /// (`-pi..=pi`); `None`: the numbers.
    pub shown_as: Option<&'static str>,
}

impl<T: Copy> Range<T> {
    /// `min..=max` in `unit`.
    pub const fn closed(flag: &'static str, min: T, max: T, unit: &'static str) -> Self {
        Self {
            flag,
            min,
            max,
            min_open: false,
            unit,
            shown_as: None,
        }
    }

    /// `(min, max]` in `unit`: `min` refused.
    pub const fn above(flag: &'static str, min: T, max: T, unit: &'static str) -> Self {
        Self {
            min_open: true,
            ..Self::closed(flag, min, max, unit)
        }
    }

    /// The same range for another flag.
    pub const fn for_flag(self, flag: &'static str) -> Self {
        Self { flag, ..self }
    }

    /// The same range, its bounds printed as `text`.
    pub const fn shown_as(self, text: &'static str) -> Self {
        Self {
            shown_as: Some(text),
            ..self
        }
    }
}

impl Range<f64> {
    /// `-limit..=limit` in `unit`.
    pub const fn symmetric(flag: &'static str, limit: f64, unit: &'static str) -> Self {
        Self::closed(flag, -limit, limit, unit)
    }
}

impl<T: Copy + PartialOrd + Display> Range<T> {
    /// True if `value` is inside (a NaN never is).
    pub fn contains(&self, value: T) -> bool {
        let above_min = if self.min_open {
            value > self.min
        } else {
            value >= self.min
        };
        above_min && value <= self.max
    }

    /// The range as the help and the messages print it: `200..=1500 Hz`, `0 < x <= 3600 s`,
    /// `-1e6..=1e6 deg/h`.
    pub fn describe(&self) -> String {
        let (min, max) = (short(self.min), short(self.max));
        let bounds = match (self.shown_as, self.min_open) {
            (Some(text), _) => text.to_owned(),
            (None, false) => format!("{min}..={max}"),
            (None, true) => format!("{min} < x <= {max}"),
        };
        if self.unit.is_empty() {
            bounds
        } else {
            format!("{bounds} {}", self.unit)
        }
    }

    /// A flag's help: `what`, then the range in parentheses.
    pub fn help(&self, what: &str) -> String {
        format!("{what} ({})", self.describe())
    }

    /// A flag's help with a remark after the range: `what (range; why)`.
    pub fn help_why(&self, what: &str, why: &str) -> String {
        format!("{what} ({}; {why})", self.describe())
    }

    /// `value` if inside, else an error naming the flag, the range and the value.
    pub fn check(&self, value: T) -> Result<T, String> {
        if self.contains(value) {
            Ok(value)
        } else {
            Err(format!(
                "{} must be in {}, got {value}",
                self.flag,
                self.describe()
            ))
        }
    }
}

/// True for `inf`, `infinity` and `NaN` in any case and with a sign: words, not a number too
/// large for `f64` (`1e400` is a number outside every range).
fn names_a_non_finite(text: &str) -> bool {
    text.parse::<f64>().is_ok_and(|x| !x.is_finite())
        && text
            .bytes()
            .any(|b| b.is_ascii_alphabetic() && !b.eq_ignore_ascii_case(&b'e'))
}

/// True for an optional sign and decimal digits only: a whole number, whatever its size.
fn is_whole(text: &str) -> bool {
    let digits = text.strip_prefix(['-', '+']).unwrap_or(text);
    !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())
}

/// `value` as Display writes it, except a power of ten from 1e6 on, written as such (`1e6`).
fn short<T: Display>(value: T) -> String {
    let text = value.to_string();
    let (sign, digits) = match text.strip_prefix('-') {
        Some(rest) => ("-", rest),
        None => ("", text.as_str()),
    };
    let zeros = digits.len() - 1;
    if digits.starts_with('1') && zeros >= 6 && digits[1..].bytes().all(|b| b == b'0') {
        format!("{sign}1e{zeros}")
    } else {
        text
    }
}

impl<T: Copy + PartialOrd + Display + FromStr> Range<T> {
    /// Parses `text` and checks it; the message (clap puts the flag before it) gives the range.
    /// What is refused, and how:
    /// - a number outside, also one the type cannot hold (`-1` for an unsigned flag, twenty
    ///   digits): `is outside`;
    /// - `inf`, `NaN` (any case), for any flag: `is not a finite number`;
    /// - a fraction for a whole-number flag (`2.5`, `1e3`): `is not a whole number`;
    /// - anything else: `is not a number`.
    pub fn parse(&self, text: &str) -> Result<T, String> {
        let trimmed = text.trim();
        let refusal = match trimmed.parse::<T>() {
            Ok(value) if self.contains(value) => return Ok(value),
            _ if names_a_non_finite(trimmed) => "is not a finite number in",
            Ok(_) => "is outside",
            Err(_) if is_whole(trimmed) => "is outside",
            Err(_) if trimmed.parse::<f64>().is_ok() => "is not a whole number in",
            Err(_) => "is not a number in",
        };
        Err(format!("{text} {refusal} {}", self.describe()))
    }

    /// The clap value parser of the flag: [`Range::parse`].
    pub fn parser(self) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
    where
        T: Send + Sync + 'static,
    {
        move |text| self.parse(text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HZ: Range<f64> = Range::closed("--dither-hz", 200.0, 1500.0, "Hz");
    const SECONDS: Range<f64> = Range::above("--seconds", 0.0, 3600.0, "s");
    const POINTS: Range<usize> = Range::closed("--points", 1, 10_000, "");

    #[test]
    fn bounds_are_inside_and_the_open_bottom_is_not() {
        assert_eq!(HZ.parse("200"), Ok(200.0));
        assert_eq!(HZ.parse("1500"), Ok(1500.0));
        assert_eq!(SECONDS.parse("3600"), Ok(3600.0));
        assert_eq!(
            SECONDS.parse("0").unwrap_err(),
            "0 is outside 0 < x <= 3600 s"
        );
        assert_eq!(POINTS.parse("1"), Ok(1));
    }

    #[test]
    fn refusals_give_the_range_and_negative_values_are_numbers() {
        assert_eq!(HZ.parse("-5").unwrap_err(), "-5 is outside 200..=1500 Hz");
        assert_eq!(
            HZ.parse("nan").unwrap_err(),
            "nan is not a finite number in 200..=1500 Hz"
        );
        assert_eq!(
            HZ.parse("inf").unwrap_err(),
            "inf is not a finite number in 200..=1500 Hz"
        );
        assert_eq!(
            HZ.parse("fast").unwrap_err(),
            "fast is not a number in 200..=1500 Hz"
        );
        assert_eq!(POINTS.parse("-1").unwrap_err(), "-1 is outside 1..=10000");
        assert_eq!(
            POINTS.parse("2.5").unwrap_err(),
            "2.5 is not a whole number in 1..=10000"
        );
        assert_eq!(
            HZ.check(100.0).unwrap_err(),
            "--dither-hz must be in 200..=1500 Hz, got 100"
        );
        let rate = Range::symmetric("--rate-deg-h", 1e6, "deg/h");
        assert_eq!(rate.help("Rate"), "Rate (-1e6..=1e6 deg/h)");
        assert_eq!(
            Range::closed("--n", 100_000, 1_000_000_000, "").describe(),
            "100000..=1e9"
        );
        let eps = Range::closed("--eps-rad", -1.0, 1.0, "rad").shown_as("-1..=1");
        assert_eq!(eps.parse("-1"), Ok(-1.0));
        assert_eq!(eps.help("Phase"), "Phase (-1..=1 rad)");
        assert_eq!(
            HZ.help_why("Dither frequency", "the board's scheduler range"),
            "Dither frequency (200..=1500 Hz; the board's scheduler range)"
        );
    }

    const BAUD: Range<u32> = Range::closed("--baud", 1_200, 4_000_000, "Bd");
    const TIMEOUT_MS: Range<u64> = Range::closed("--timeout-ms", 1, 600_000, "ms");
    const RATE_DEG_H: Range<f64> = Range::symmetric("--rate", 100_000.0, "deg/h");

    /// Whole numbers the type cannot hold are outside the range (not a parse error); a
    /// non-finite value is refused as such for any flag, a number too large for `f64` as
    /// outside; a leading minus is a number wherever the range allows it.
    #[test]
    fn integers_beyond_the_type_and_non_finite_values() {
        assert_eq!(BAUD.parse("460800"), Ok(460_800));
        assert_eq!(BAUD.parse(" 1200 "), Ok(1_200));
        assert_eq!(
            BAUD.parse("99999999999999999999").unwrap_err(),
            "99999999999999999999 is outside 1200..=4000000 Bd"
        );
        assert_eq!(
            BAUD.parse("-99999999999999999999999999999999999999999")
                .unwrap_err(),
            "-99999999999999999999999999999999999999999 is outside 1200..=4000000 Bd"
        );
        assert_eq!(
            BAUD.parse("+0").unwrap_err(),
            "+0 is outside 1200..=4000000 Bd"
        );
        assert_eq!(
            TIMEOUT_MS.parse("-1").unwrap_err(),
            "-1 is outside 1..=600000 ms"
        );
        assert_eq!(
            TIMEOUT_MS.parse("2s").unwrap_err(),
            "2s is not a number in 1..=600000 ms"
        );
        assert_eq!(
            TIMEOUT_MS.parse("1e3").unwrap_err(),
            "1e3 is not a whole number in 1..=600000 ms"
        );
        assert_eq!(
            TIMEOUT_MS.parse("inf").unwrap_err(),
            "inf is not a finite number in 1..=600000 ms"
        );
        for word in ["NaN", "-inf", "+Infinity", "INF"] {
            assert_eq!(
                SECONDS.parse(word).unwrap_err(),
                format!("{word} is not a finite number in 0 < x <= 3600 s")
            );
        }
        assert_eq!(
            SECONDS.parse("-5").unwrap_err(),
            "-5 is outside 0 < x <= 3600 s"
        );
        assert_eq!(RATE_DEG_H.parse("-13.888"), Ok(-13.888));
        assert_eq!(
            RATE_DEG_H.parse("1e300").unwrap_err(),
            "1e300 is outside -100000..=100000 deg/h"
        );
        assert_eq!(
            RATE_DEG_H.parse("1e400").unwrap_err(),
            "1e400 is outside -100000..=100000 deg/h"
        );
    }
}
