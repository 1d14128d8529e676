//! The valid range of a numeric command-line flag, defined once as a [`Range`] constant and read
//! by everything that needs it: clap's value parser ([`Range::parser`]: a value outside is a
//! usage error, exit 2, with the range in the message), the flag's help ([`Range::help`]: the
//! range is printed from the same numbers) and the library's own checks of the same setting
//! ([`Range::check`], for callers that build the options in code).
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
    pub fn parse(&self, text: &str) -> Result<T, String> {
        match text.trim().parse::<T>() {
            Ok(value) if self.contains(value) => Ok(value),
            Ok(_) => Err(format!("{text} is outside {}", self.describe())),
            // Not a `T`, but a number: a whole one is outside an unsigned type's range (`-1`).
            Err(_) => match text.trim().parse::<f64>() {
                Ok(x) if x.fract() == 0.0 => Err(format!("{text} is outside {}", self.describe())),
                Ok(_) => Err(format!(
                    "{text} is not a whole number in {}",
                    self.describe()
                )),
                Err(_) => Err(format!("{text} is not a number in {}", self.describe())),
            },
        }
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
        assert_eq!(HZ.parse("nan").unwrap_err(), "nan is outside 200..=1500 Hz");
        assert_eq!(HZ.parse("inf").unwrap_err(), "inf is outside 200..=1500 Hz");
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
}
