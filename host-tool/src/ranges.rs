//! The valid range of every numeric command-line argument of `rlg-cal`, as clap value parsers.
//!
//! Every number is parsed here, so a value outside its range (or a leading minus where the
//! value cannot be negative) is refused by clap before anything runs: exit status 2, a message
//! naming the flag, the value and the range, e.g.
//! `error: invalid value '-5' for '--seconds <S>': -5 is outside 0 < S <= 86400 (s)`.
//! The flags also accept a leading minus as a value (`allow_negative_numbers`), so `-5` reaches
//! the parser instead of being taken for an unknown flag. Ranges are physical or practical
//! limits stated once, next to the parser that enforces them.

use std::fmt::Display;
use std::str::FromStr;

/// A closed (or, at the bottom, open) range with its unit, for the message.
struct Range<T> {
    lo: T,
    lo_open: bool,
    hi: T,
    unit: &'static str,
}

impl<T: PartialOrd + Display + Copy> Range<T> {
    fn check(&self, text: &str, value: T) -> Result<T, String> {
        let above_lo = if self.lo_open {
            value > self.lo
        } else {
            value >= self.lo
        };
        if above_lo && value <= self.hi {
            return Ok(value);
        }
        let op = if self.lo_open { "<" } else { "<=" };
        Err(format!(
            "{text} is outside {} {op} x <= {} ({})",
            self.lo, self.hi, self.unit
        ))
    }
}

fn number<T: FromStr>(text: &str, what: &str) -> Result<T, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("{text} is not {what}"))
}

fn float(text: &str, range: Range<f64>) -> Result<f64, String> {
    let value: f64 = number(text, "a number")?;
    if !value.is_finite() {
        return Err(format!("{text} is not a finite number"));
    }
    range.check(text, value)
}

fn integer<T: FromStr + PartialOrd + Display + Copy>(
    text: &str,
    range: Range<T>,
) -> Result<T, String> {
    // Parsed as i128 first, so `-5` for an unsigned flag gets the range message.
    let wide: i128 = number(text, "a whole number")?;
    match T::from_str(&wide.to_string()) {
        Ok(value) => range.check(text, value),
        Err(_) => Err(format!(
            "{text} is outside {} <= x <= {} ({})",
            range.lo, range.hi, range.unit
        )),
    }
}

const fn closed<T>(lo: T, hi: T, unit: &'static str) -> Range<T> {
    Range {
        lo,
        lo_open: false,
        hi,
        unit,
    }
}

const fn above<T>(lo: T, hi: T, unit: &'static str) -> Range<T> {
    Range {
        lo,
        lo_open: true,
        hi,
        unit,
    }
}

/// `--baud`: 1200 ..= 4 000 000 Bd (the F405's USART at 84 MHz goes up to 5.25 MBd).
pub fn baud(text: &str) -> Result<u32, String> {
    integer(text, closed(1_200, 4_000_000, "Bd"))
}

/// `--timeout-ms`: 1 ms ..= 10 minutes.
pub fn timeout_ms(text: &str) -> Result<u64, String> {
    integer(text, closed(1, 600_000, "ms"))
}

/// An input rate of the simulated gyro (`--sim-rate`, `serve-sim --rate`): |rate| <= 100 000
/// deg/h (the model's lock-in and dither hold far beyond any RLG's measuring range).
pub fn rate_deg_h(text: &str) -> Result<f64, String> {
    float(text, closed(-100_000.0, 100_000.0, "deg/h"))
}

/// Calibration cycles (`--cycles`, `--cal-cycles`): 1 ..= 3 600 000, the board's limit.
pub fn cal_cycles(text: &str) -> Result<u32, String> {
    integer(
        text,
        closed(
            1,
            firmware::protocol::parse::MAX_CAL_CYCLES,
            "dither cycles",
        ),
    )
}

/// Warm-up cycles (`--warmup`, `--cal-warmup`): 0 ..= 3 600 000.
pub fn warmup_cycles(text: &str) -> Result<u32, String> {
    integer(
        text,
        closed(
            0,
            firmware::protocol::parse::MAX_CAL_CYCLES,
            "dither cycles",
        ),
    )
}

/// A stream divider (`--divider`): every n-th cycle, 1 ..= 65535.
pub fn divider(text: &str) -> Result<u16, String> {
    integer(text, closed(1, u16::MAX, "cycles"))
}

/// `calibrate --poll-ms`: 10 ms ..= 1 minute.
pub fn poll_ms(text: &str) -> Result<u64, String> {
    integer(text, closed(10, 60_000, "ms"))
}

/// A duration in seconds (`stream --seconds`, `sweep --seconds`, `serve-sim --seconds`):
/// 0 < s <= one day.
pub fn seconds(text: &str) -> Result<f64, String> {
    float(text, above(0.0, 86_400.0, "s"))
}

/// `sweep --settle`: 0 ..= 600 s.
pub fn settle_s(text: &str) -> Result<f64, String> {
    float(text, closed(0.0, 600.0, "s"))
}

/// `stream --timer-hz`: 1 kHz ..= 1 GHz.
pub fn timer_hz(text: &str) -> Result<f64, String> {
    float(text, closed(1e3, 1e9, "Hz"))
}

/// A latitude: -90 ..= 90 deg.
pub fn latitude_deg(text: &str) -> Result<f64, String> {
    float(text, closed(-90.0, 90.0, "deg"))
}

/// An azimuth: -360 ..= 360 deg.
pub fn azimuth_deg(text: &str) -> Result<f64, String> {
    float(text, closed(-360.0, 360.0, "deg"))
}

/// `serve-sim --speed`: 0 < x <= 1000 simulated seconds per second.
pub fn speed(text: &str) -> Result<f64, String> {
    float(text, above(0.0, 1000.0, "simulated s per s"))
}

/// `thermal --seconds`: up to 100 h (a chamber's run of ramps and soaks takes hours).
pub fn thermal_seconds(text: &str) -> Result<f64, String> {
    float(text, above(0.0, 360_000.0, "s"))
}

/// `thermal --table-rate-deg-h`: R of the rate table, 3 600 ..= 1 000 000 deg/h (1 deg/s
/// upwards: the scale factor's +-R must stand far out of the bias and the noise).
pub fn table_rate_deg_h(text: &str) -> Result<f64, String> {
    float(text, closed(3_600.0, 1_000_000.0, "deg/h"))
}

/// `thermal --reference-c`: T_ref within the TMP117's -55 ..= 150 °C.
pub fn reference_c(text: &str) -> Result<f64, String> {
    float(text, closed(-55.0, 150.0, "C"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_refuse_with_the_range_and_accept_negative_values_where_legal() {
        assert_eq!(rate_deg_h("-13.888"), Ok(-13.888));
        assert_eq!(latitude_deg("-45"), Ok(-45.0));
        assert_eq!(
            seconds("-5").unwrap_err(),
            "-5 is outside 0 < x <= 86400 (s)"
        );
        assert_eq!(seconds("0").unwrap_err(), "0 is outside 0 < x <= 86400 (s)");
        assert_eq!(
            cal_cycles("-1").unwrap_err(),
            "-1 is outside 1 <= x <= 3600000 (dither cycles)"
        );
        assert_eq!(
            baud("99999999999999999999").unwrap_err(),
            "99999999999999999999 is outside 1200 <= x <= 4000000 (Bd)"
        );
        assert_eq!(speed("inf").unwrap_err(), "inf is not a finite number");
        assert_eq!(speed("NaN").unwrap_err(), "NaN is not a finite number");
        assert_eq!(timeout_ms("2s").unwrap_err(), "2s is not a whole number");
        assert_eq!(
            rate_deg_h("1e300").unwrap_err(),
            "1e300 is outside -100000 <= x <= 100000 (deg/h)"
        );
    }
}
