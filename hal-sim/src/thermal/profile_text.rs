//! The gyro block's temperature profile as a user types it on a command line (`rlg-sim
//! --temperature-profile`, `rlg-cal serve-sim --temperature-profile`, `rlg-cal
//! --sim-temperature-profile`): one parser, one syntax and one set of ranges for every CLI.
//!
//! ```text
//! constant:<C>                        the block held at C
//! ramp:<from C>:<to C>:<C per min>    from `from` at t = 0 to `to` at that rate, then held
//! steps:<C>,<C>,...:<hold s>          each level held `hold` s, 1 s linear transitions (1..=8 levels)
//! warmup:<from C>:<to C>:<tau s>      from `from` settling to `to` with time constant tau
//! knots:<t s>/<C>,<t s>/<C>,...       piecewise linear through 1..=16 knots, held outside
//! ```
//!
//! Temperatures within [`TEMPERATURE_RANGE_C`] (the TMP117's range), ramps within
//! [`RAMP_RATE_RANGE_C_PER_MIN`], holds and time constants within [`DURATION_RANGE_S`]. Times
//! are the simulation's, from its start (so a profile includes the run's warm-up).
//!
//! Plain Rust, no CLI library: each CLI hands [`parse_flag`] to its own argument parser, with
//! the flag's name for the message, and [`help`] as the flag's help.

use crate::dither::resonator::TemperatureProfile;
use std::ops::RangeInclusive;

/// Temperatures a profile may reach, °C (the TMP117's operating range).
pub const TEMPERATURE_RANGE_C: RangeInclusive<f64> = -55.0..=150.0;
/// Ramp rates, °C/min (magnitude; a thermal chamber ramps at 1-10 °C/min, the tests at 120).
pub const RAMP_RATE_RANGE_C_PER_MIN: RangeInclusive<f64> = 0.01..=600.0;
/// Holds and time constants, s.
pub const DURATION_RANGE_S: RangeInclusive<f64> = 1.0..=360_000.0;
/// Most levels of `steps` (two knots each within the profile's 16).
pub const MAX_STEPS: usize = 8;
/// The transition between two levels of `steps`, s.
pub const STEP_TRANSITION_S: f64 = 1.0;

/// The syntax, for error messages and `--help`.
pub const SYNTAX: &str = "constant:<C> | ramp:<from C>:<to C>:<C per min> | \
steps:<C>,<C>,...:<hold s> | warmup:<from C>:<to C>:<tau s> | knots:<t s>/<C>,...";

fn number(text: &str, what: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{what}: not a number: {text:?}"))
}

fn temperature(text: &str) -> Result<f64, String> {
    let c = number(text, "temperature")?;
    if TEMPERATURE_RANGE_C.contains(&c) {
        Ok(c)
    } else {
        Err(format!(
            "temperature {c} outside {}..={} C",
            TEMPERATURE_RANGE_C.start(),
            TEMPERATURE_RANGE_C.end()
        ))
    }
}

fn duration(text: &str, what: &str) -> Result<f64, String> {
    let s = number(text, what)?;
    if DURATION_RANGE_S.contains(&s) {
        Ok(s)
    } else {
        Err(format!(
            "{what} {s} outside {}..={} s",
            DURATION_RANGE_S.start(),
            DURATION_RANGE_S.end()
        ))
    }
}

/// What the flag's help says: the syntax and the ranges.
pub fn help(what: &str) -> String {
    format!(
        "{what}: {SYNTAX} (temperatures {}..={} C, ramps {}..={} C/min, holds and tau {}..={} s; \
         times from the start of the simulation)",
        TEMPERATURE_RANGE_C.start(),
        TEMPERATURE_RANGE_C.end(),
        RAMP_RATE_RANGE_C_PER_MIN.start(),
        RAMP_RATE_RANGE_C_PER_MIN.end(),
        DURATION_RANGE_S.start(),
        DURATION_RANGE_S.end()
    )
}

/// Parses the value of `flag` (see the module docs); the message names the flag and the value,
/// says what is wrong and gives the syntax.
pub fn parse_flag(flag: &str, text: &str) -> Result<TemperatureProfile, String> {
    parse(text).map_err(|e| format!("{flag} {text:?}: {e} ({SYNTAX})"))
}

/// Parses a profile (see the module docs); the message says what is wrong.
pub fn parse(text: &str) -> Result<TemperatureProfile, String> {
    let (kind, rest) = text.split_once(':').ok_or("no kind")?;
    let fields: Vec<&str> = rest.split(':').collect();
    let profile = |r: Result<TemperatureProfile, crate::param_error::ParamError>| {
        r.map_err(|e| format!("{e:?}"))
    };
    match (kind, fields.as_slice()) {
        ("constant", [c]) => Ok(TemperatureProfile::constant(temperature(c)?)),
        ("ramp", [from, to, rate]) => {
            let (from, to) = (temperature(from)?, temperature(to)?);
            let rate = number(rate, "ramp rate")?.abs();
            if !RAMP_RATE_RANGE_C_PER_MIN.contains(&rate) {
                return Err(format!(
                    "ramp rate {rate} outside {}..={} C/min",
                    RAMP_RATE_RANGE_C_PER_MIN.start(),
                    RAMP_RATE_RANGE_C_PER_MIN.end()
                ));
            }
            if from == to {
                return Ok(TemperatureProfile::constant(from));
            }
            profile(TemperatureProfile::ramp(
                0.0,
                from,
                (to - from).abs() / rate * 60.0,
                to,
            ))
        }
        ("steps", [levels, hold]) => {
            let hold = duration(hold, "hold")?;
            let levels = levels
                .split(',')
                .map(temperature)
                .collect::<Result<Vec<f64>, String>>()?;
            if levels.is_empty() || levels.len() > MAX_STEPS {
                return Err(format!("1..={MAX_STEPS} levels"));
            }
            let mut knots = vec![(0.0, levels[0])];
            for (i, pair) in levels.windows(2).enumerate() {
                let end = hold * (i + 1) as f64;
                knots.push((end, pair[0]));
                knots.push((end + STEP_TRANSITION_S, pair[1]));
            }
            profile(TemperatureProfile::knots(&knots))
        }
        ("warmup", [from, to, tau]) => profile(TemperatureProfile::warm_up(
            temperature(from)?,
            temperature(to)?,
            duration(tau, "time constant")?,
        )),
        ("knots", [list]) => {
            let knots = list
                .split(',')
                .map(|k| {
                    let (t, c) = k.split_once('/').ok_or("a knot is <t s>/<C>")?;
                    Ok((number(t, "knot time")?, temperature(c)?))
                })
                .collect::<Result<Vec<(f64, f64)>, String>>()?;
            profile(TemperatureProfile::knots(&knots))
        }
        _ => Err("unknown kind or wrong number of fields".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_parses_to_its_profile() {
        assert_eq!(parse("constant:40").unwrap().at(100.0), 40.0);
        let ramp = parse("ramp:-20:60:2").unwrap();
        // 80 °C at 2 °C/min: 2400 s.
        assert_eq!(
            (ramp.at(0.0), ramp.at(1200.0), ramp.at(9999.0)),
            (-20.0, 20.0, 60.0)
        );
        let steps = parse("steps:0,20,10:30").unwrap();
        assert_eq!(
            (
                steps.at(29.0),
                steps.at(30.5),
                steps.at(40.0),
                steps.at(75.0)
            ),
            (0.0, 10.0, 20.0, 10.0)
        );
        let warm = parse("warmup:20:45:600").unwrap();
        assert!((warm.at(600.0) - (45.0 - 25.0 / std::f64::consts::E)).abs() < 1e-9);
        let knots = parse("knots:0/25,10/35,20/35").unwrap();
        assert_eq!((knots.at(5.0), knots.at(30.0)), (30.0, 35.0));
    }

    /// Every malformed or out-of-range profile is refused with a message naming the flag and
    /// the value.
    #[test]
    fn bad_profiles_are_refused() {
        for bad in [
            "",
            "constant",
            "constant:200",
            "constant:x",
            "ramp:0:10",
            "ramp:0:10:0",
            "ramp:0:10:1000",
            "steps::10",
            "steps:1,2,3,4,5,6,7,8,9:10",
            "steps:0,10:0.5",
            "warmup:20:45:0",
            "knots:5/20,5/30",
            "knots:5-20",
            "sine:1:2",
        ] {
            let e = parse_flag("--temperature-profile", bad).unwrap_err();
            let named = format!("--temperature-profile {bad:?}: ");
            assert!(e.starts_with(&named), "{bad}: {e}");
            assert!(e.ends_with(&format!("({SYNTAX})")), "{bad}: {e}");
        }
    }
}
