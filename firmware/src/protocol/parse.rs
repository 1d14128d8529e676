//! Command parsing: a line of text -> a [`Command`], or the [`ErrorCode`] that says why not.
//!
//! Grammar: `<command> [<argument>...] [*<crc>]`, words separated by spaces or tabs,
//! case-insensitive command words. The optional suffix `*XXXX` is the CRC-16/CCITT-FALSE
//! (poly 0x1021, init 0xFFFF) of every byte before the `*`, in 4 hex digits; the host tool
//! always sends it, a person typing may leave it out. A wrong CRC rejects the line before it is
//! parsed. Numbers are decimal (`f32` via `core`'s parser, which also accepts exponents); NaN
//! and infinities are refused, and so is anything outside the documented range.

use super::key::Key;
use super::ErrorCode;

/// Which coefficient.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Coefficient {
    /// a, the coefficient of P1.
    A,
    /// b, the coefficient of P2.
    B,
}

/// A `dither` command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DitherCommand {
    /// `dither on` | `dither off`: start the drive (its start-up finds the resonance) or stop it.
    Enable(bool),
    /// `dither amp <arcsec>`: the amplitude setpoint, arcsec peak of body angle (the drive's
    /// range, `DitherConfig::setpoint_range_arcsec`).
    Amplitude(f32),
    /// `dither noise <percent>`: the random-noise dither's depth, percent (0 = off).
    Noise(f32),
    /// `dither status`: state, amplitude, frequency, drive level, phase error, faults.
    Status,
}

/// A `thermal` command.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ThermalCommand {
    /// `thermal`: the temperature, its rate, the sensor, the model's state.
    Read,
    /// `thermal model`: the model in force, its coefficients and its switch.
    Model,
    /// `thermal set <name> <value>`: one coefficient of the edited model, by its index in
    /// `ThermalModel::NAMES` (`t_ref t_min t_max` in °C, each within the sensor's -55..150;
    /// `b0..b3` deg/h per °C^k, `b_rate` deg/h per °C/min, `s0..s2` ppm per °C^k).
    Set(u8, f32),
    /// `thermal apply`: the edited model, checked whole, in force and switched on.
    Apply,
    /// `thermal on` | `thermal off`: the model in force switched on or off.
    Enable(bool),
}

impl ThermalCommand {
    /// Whether it only reads.
    pub fn is_read(&self) -> bool {
        matches!(self, Self::Read | Self::Model)
    }
}

/// Every command of the protocol (see docs/protocol.md "Commands" for examples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Command {
    /// `help` | `?`: the command list.
    Help,
    /// `id` | `identify`: firmware, board, serial number, scale factor, timer clock.
    Identify,
    /// `status`: signal, dither, rate, counters, compensation, tracking, source, lock, board.
    Status,
    /// `output status`: the fixed-rate output's dither stripping and its record count.
    OutputStatus,
    /// `selftest`: the power-up self-test's checks, the timing faults raised now.
    SelfTest,
    /// `thermal [model|set <name> <value>|apply|on|off]`: the block's temperature and
    /// the thermal model.
    Thermal(ThermalCommand),
    /// `get a` | `get b` | `get coeffs`: one coefficient, or both with Omega_L and eps.
    Get(Option<Coefficient>),
    /// `set a <rad/s>` | `set b <rad/s>`.
    Set(Coefficient, f32),
    /// `comp on` | `comp off`.
    Compensation(bool),
    /// `track on` | `track off`: online tracking of a and b outside the dead band.
    Tracking(bool),
    /// `cal start <cycles> [<warmup cycles>]`: one calibration run (pooled with a completed one).
    CalStart {
        /// Dither cycles to feed into the fit, 1..=[`MAX_CAL_CYCLES`].
        cycles: u32,
        /// Cycles discarded first, 0..=[`MAX_CAL_CYCLES`] (default 0).
        warmup_cycles: u32,
    },
    /// `cal status`: the session's state and cycles collected.
    CalStatus,
    /// `cal abort`: drop the runs and any fit; back to idle.
    CalAbort,
    /// `cal result`: solve the pooled runs (once complete) and report the fit.
    CalResult,
    /// `cal accept`: apply the passing fit (unsaved until `store`).
    CalAccept,
    /// `store`: write the active coefficients to flash (pauses the readout).
    Store,
    /// `reload`: load the newest valid record from flash.
    Reload,
    /// `defaults`: back to the default coefficients (unsaved until `store`).
    Defaults,
    /// `stream on <divider>` (every n-th cycle) | `stream off`.
    Stream(Option<u16>),
    /// `stream output`: the fixed-rate output records, one frame per output period.
    StreamOutput,
    /// `unlock <key>`: allow commands that change coefficients or flash (32 hex digits).
    Unlock(Key),
    /// `key provision <key>`: write the board's key to OTP, once (production; see [`super::key`]).
    KeyProvision(Key),
    /// `lock`: lock at once.
    Lock,
    /// `dither on|off|amp <arcsec>|noise <percent>|status`: the dither drive.
    Dither(DitherCommand),
    /// `yes`: executes the state-changing command typed without a CRC just before, after the
    /// board echoed it as parsed ([`super::confirm`]).
    Confirm,
}

/// Largest run length `cal start` accepts: one hour at 1 kHz dither.
pub const MAX_CAL_CYCLES: u32 = 3_600_000;
/// Largest magnitude `set` accepts, rad/s (the Q15.16 range).
pub const MAX_COEFFICIENT_RAD_PER_S: f32 = 32_767.0;

/// CRC-16/CCITT-FALSE of `bytes`.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut crc: u16 = 0xFFFF;
    for &b in bytes {
        crc ^= (b as u16) << 8;
        for _ in 0..8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// Splits off and checks the CRC suffix. Returns the command text and whether a CRC was given.
pub fn strip_checksum(line: &str) -> Result<(&str, bool), ErrorCode> {
    let Some(star) = line.rfind('*') else {
        return Ok((line, false));
    };
    let (body, suffix) = line.split_at(star);
    let suffix = suffix.get(1..).unwrap_or("").trim_end(); // after the '*' (one byte)
    if suffix.len() != 4 || !suffix.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(ErrorCode::BadChecksum);
    }
    let given = u16::from_str_radix(suffix, 16).map_err(|_| ErrorCode::BadChecksum)?;
    if given != crc16(body.as_bytes()) {
        return Err(ErrorCode::BadChecksum);
    }
    Ok((body, true))
}

/// A key argument: 32 hex digits ([`Key::parse_hex`]).
fn key(word: Option<&str>) -> Result<Key, ErrorCode> {
    Key::parse_hex(word.ok_or(ErrorCode::Syntax)?).ok_or(ErrorCode::BadNumber)
}

fn number(word: Option<&str>) -> Result<f32, ErrorCode> {
    let word = word.ok_or(ErrorCode::Syntax)?;
    let v = super::decimal::parse_f32(word).ok_or(ErrorCode::BadNumber)?;
    if !v.is_finite() {
        return Err(ErrorCode::NotFinite);
    }
    Ok(v)
}

fn integer(word: Option<&str>, max: u32) -> Result<u32, ErrorCode> {
    let word = word.ok_or(ErrorCode::Syntax)?;
    let v: u32 = word.parse().map_err(|_| ErrorCode::BadNumber)?;
    if v > max {
        return Err(ErrorCode::OutOfRange);
    }
    Ok(v)
}

fn coefficient(word: Option<&str>) -> Result<Coefficient, ErrorCode> {
    match word {
        Some(w) if w.eq_ignore_ascii_case("a") => Ok(Coefficient::A),
        Some(w) if w.eq_ignore_ascii_case("b") => Ok(Coefficient::B),
        _ => Err(ErrorCode::Syntax),
    }
}

fn on_off(word: Option<&str>) -> Result<bool, ErrorCode> {
    match word {
        Some(w) if w.eq_ignore_ascii_case("on") => Ok(true),
        Some(w) if w.eq_ignore_ascii_case("off") => Ok(false),
        _ => Err(ErrorCode::Syntax),
    }
}

/// The words after `thermal`.
fn thermal<'a>(words: &mut impl Iterator<Item = &'a str>) -> Result<ThermalCommand, ErrorCode> {
    use crate::thermal::model::{ThermalModel, SENSOR_MAX_C, SENSOR_MIN_C, TEMPERATURES};
    let Some(sub) = words.next() else {
        return Ok(ThermalCommand::Read);
    };
    let sub_is = |w: &str| sub.eq_ignore_ascii_case(w);
    Ok(if sub_is("model") {
        ThermalCommand::Model
    } else if sub_is("set") {
        let name = words.next().ok_or(ErrorCode::Syntax)?;
        let index = ThermalModel::NAMES
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name))
            .ok_or(ErrorCode::Syntax)?;
        let value = number(words.next())?;
        if index < TEMPERATURES && !(SENSOR_MIN_C..=SENSOR_MAX_C).contains(&value) {
            return Err(ErrorCode::OutOfRange);
        }
        ThermalCommand::Set(u8::try_from(index).map_err(|_| ErrorCode::Syntax)?, value)
    } else if sub_is("apply") {
        ThermalCommand::Apply
    } else {
        ThermalCommand::Enable(on_off(Some(sub))?)
    })
}

/// Parses a command text (CRC already stripped).
pub fn parse(text: &str) -> Result<Command, ErrorCode> {
    let mut words = text.split([' ', '\t']).filter(|w| !w.is_empty());
    let head = words.next().ok_or(ErrorCode::Syntax)?;
    let is = |w: &str| head.eq_ignore_ascii_case(w);
    let command = if is("help") || is("?") {
        Command::Help
    } else if is("id") || is("identify") {
        Command::Identify
    } else if is("status") {
        Command::Status
    } else if is("selftest") {
        Command::SelfTest
    } else if is("output") {
        match words.next() {
            Some(w) if w.eq_ignore_ascii_case("status") => Command::OutputStatus,
            _ => return Err(ErrorCode::Syntax),
        }
    } else if is("thermal") {
        Command::Thermal(thermal(&mut words)?)
    } else if is("get") {
        match words.next() {
            Some(w) if w.eq_ignore_ascii_case("coeffs") => Command::Get(None),
            w => Command::Get(Some(coefficient(w)?)),
        }
    } else if is("set") {
        let which = coefficient(words.next())?;
        let value = number(words.next())?;
        if value.abs() > MAX_COEFFICIENT_RAD_PER_S {
            return Err(ErrorCode::OutOfRange);
        }
        Command::Set(which, value)
    } else if is("comp") {
        Command::Compensation(on_off(words.next())?)
    } else if is("track") {
        Command::Tracking(on_off(words.next())?)
    } else if is("cal") {
        let sub = words.next().ok_or(ErrorCode::Syntax)?;
        let sub_is = |w: &str| sub.eq_ignore_ascii_case(w);
        if sub_is("start") {
            let cycles = integer(words.next(), MAX_CAL_CYCLES)?;
            if cycles == 0 {
                return Err(ErrorCode::OutOfRange);
            }
            let warmup_cycles = match words.next() {
                None => 0,
                w => integer(w, MAX_CAL_CYCLES)?,
            };
            Command::CalStart {
                cycles,
                warmup_cycles,
            }
        } else if sub_is("status") {
            Command::CalStatus
        } else if sub_is("abort") {
            Command::CalAbort
        } else if sub_is("result") {
            Command::CalResult
        } else if sub_is("accept") {
            Command::CalAccept
        } else {
            return Err(ErrorCode::Syntax);
        }
    } else if is("dither") {
        let sub = words.next().ok_or(ErrorCode::Syntax)?;
        let sub_is = |w: &str| sub.eq_ignore_ascii_case(w);
        Command::Dither(if sub_is("on") {
            DitherCommand::Enable(true)
        } else if sub_is("off") {
            DitherCommand::Enable(false)
        } else if sub_is("amp") {
            DitherCommand::Amplitude(number(words.next())?)
        } else if sub_is("noise") {
            DitherCommand::Noise(number(words.next())?)
        } else if sub_is("status") {
            DitherCommand::Status
        } else {
            return Err(ErrorCode::Syntax);
        })
    } else if is("store") {
        Command::Store
    } else if is("reload") {
        Command::Reload
    } else if is("defaults") {
        Command::Defaults
    } else if is("stream") {
        match words.next() {
            Some(w) if w.eq_ignore_ascii_case("off") => Command::Stream(None),
            Some(w) if w.eq_ignore_ascii_case("output") => Command::StreamOutput,
            Some(w) if w.eq_ignore_ascii_case("on") => {
                let divider = match words.next() {
                    None => 1,
                    w => integer(w, u16::MAX as u32)?,
                };
                if divider == 0 {
                    return Err(ErrorCode::OutOfRange);
                }
                Command::Stream(Some(divider as u16))
            }
            _ => return Err(ErrorCode::Syntax),
        }
    } else if is("unlock") {
        Command::Unlock(key(words.next())?)
    } else if is("key") {
        match words.next() {
            Some(w) if w.eq_ignore_ascii_case("provision") => {
                Command::KeyProvision(key(words.next())?)
            }
            _ => return Err(ErrorCode::Syntax),
        }
    } else if is("lock") {
        Command::Lock
    } else if is("yes") {
        Command::Confirm
    } else {
        return Err(ErrorCode::UnknownCommand);
    };
    if words.next().is_some() {
        return Err(ErrorCode::Syntax);
    }
    Ok(command)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The check value of CRC-16/CCITT-FALSE ("123456789" -> 0x29B1).
    #[test]
    fn crc_check_value() {
        assert_eq!(crc16(b"123456789"), 0x29B1);
    }

    #[test]
    fn checksum_suffix() {
        let crc = crc16(b"get a");
        let line = std::format!("get a*{crc:04X}");
        assert_eq!(strip_checksum(&line), Ok(("get a", true)));
        assert_eq!(strip_checksum("get a"), Ok(("get a", false)));
        let wrong = std::format!("get a*{:04X}", crc ^ 1);
        assert_eq!(strip_checksum(&wrong), Err(ErrorCode::BadChecksum));
        assert_eq!(strip_checksum("get a*12"), Err(ErrorCode::BadChecksum));
        assert_eq!(strip_checksum("get a*zzzz"), Err(ErrorCode::BadChecksum));
    }

    #[test]
    fn commands() {
        assert_eq!(parse("help"), Ok(Command::Help));
        assert_eq!(parse("ID"), Ok(Command::Identify));
        assert_eq!(parse("get coeffs"), Ok(Command::Get(None)));
        assert_eq!(parse("get B"), Ok(Command::Get(Some(Coefficient::B))));
        assert_eq!(
            parse("set a 344.25"),
            Ok(Command::Set(Coefficient::A, 344.25))
        );
        assert_eq!(
            parse("set b -5.5e2"),
            Ok(Command::Set(Coefficient::B, -550.0))
        );
        assert_eq!(parse("comp off"), Ok(Command::Compensation(false)));
        assert_eq!(parse("track on"), Ok(Command::Tracking(true)));
        assert_eq!(
            parse("cal start 4000 400"),
            Ok(Command::CalStart {
                cycles: 4000,
                warmup_cycles: 400
            })
        );
        assert_eq!(
            parse("cal start 4000"),
            Ok(Command::CalStart {
                cycles: 4000,
                warmup_cycles: 0
            })
        );
        assert_eq!(parse("stream on 10"), Ok(Command::Stream(Some(10))));
        assert_eq!(parse("stream on"), Ok(Command::Stream(Some(1))));
        assert_eq!(parse("stream off"), Ok(Command::Stream(None)));
        assert_eq!(parse("stream output"), Ok(Command::StreamOutput));
        assert_eq!(parse("stream output 3"), Err(ErrorCode::Syntax));
        let key = Key::parse_hex("000102030405060708090a0b0c0d0e0f").unwrap();
        assert_eq!(
            parse("unlock 000102030405060708090a0b0c0d0e0f"),
            Ok(Command::Unlock(key))
        );
        assert_eq!(
            parse("key provision 0x000102030405060708090A0B0C0D0E0F"),
            Ok(Command::KeyProvision(key))
        );
        // A 32-bit key (the old development key) is no key.
        assert_eq!(parse("unlock c0ffee42"), Err(ErrorCode::BadNumber));
        assert_eq!(parse("key provision"), Err(ErrorCode::Syntax));
        assert_eq!(parse("key"), Err(ErrorCode::Syntax));
        assert_eq!(parse("  status\t"), Ok(Command::Status));
        assert_eq!(parse("SelfTest"), Ok(Command::SelfTest));
        assert_eq!(parse("output status"), Ok(Command::OutputStatus));
        assert_eq!(parse("output"), Err(ErrorCode::Syntax));
        assert_eq!(
            parse("dither amp 420.5"),
            Ok(Command::Dither(DitherCommand::Amplitude(420.5)))
        );
        assert_eq!(
            parse("DITHER noise 12"),
            Ok(Command::Dither(DitherCommand::Noise(12.0)))
        );
        assert_eq!(
            parse("dither off"),
            Ok(Command::Dither(DitherCommand::Enable(false)))
        );
        assert_eq!(
            parse("dither status"),
            Ok(Command::Dither(DitherCommand::Status))
        );
        assert_eq!(parse("dither"), Err(ErrorCode::Syntax));
        assert_eq!(parse("dither spin"), Err(ErrorCode::Syntax));
        assert_eq!(parse("dither amp"), Err(ErrorCode::Syntax));
        assert_eq!(parse("dither amp nan"), Err(ErrorCode::NotFinite));
        assert_eq!(parse("dither noise x"), Err(ErrorCode::BadNumber));
    }

    /// Every kind of bad input has its own error code.
    #[test]
    fn bad_input() {
        assert_eq!(parse("frobnicate"), Err(ErrorCode::UnknownCommand));
        assert_eq!(parse("get"), Err(ErrorCode::Syntax));
        assert_eq!(parse("get c"), Err(ErrorCode::Syntax));
        assert_eq!(parse("status now"), Err(ErrorCode::Syntax));
        assert_eq!(parse("set a"), Err(ErrorCode::Syntax));
        assert_eq!(parse("set a 12x"), Err(ErrorCode::BadNumber));
        assert_eq!(parse("set a NaN"), Err(ErrorCode::NotFinite));
        assert_eq!(parse("set a inf"), Err(ErrorCode::NotFinite));
        assert_eq!(parse("set a -infinity"), Err(ErrorCode::NotFinite));
        assert_eq!(parse("set a 1e6"), Err(ErrorCode::OutOfRange));
        assert_eq!(parse("set a 1e39"), Err(ErrorCode::NotFinite));
        assert_eq!(parse("cal start 0"), Err(ErrorCode::OutOfRange));
        assert_eq!(parse("cal start -5"), Err(ErrorCode::BadNumber));
        assert_eq!(parse("cal start 99999999999"), Err(ErrorCode::BadNumber));
        assert_eq!(parse("cal start 3600001"), Err(ErrorCode::OutOfRange));
        assert_eq!(parse("stream on 0"), Err(ErrorCode::OutOfRange));
        assert_eq!(parse("stream sideways"), Err(ErrorCode::Syntax));
        assert_eq!(parse("unlock"), Err(ErrorCode::Syntax));
        assert_eq!(parse("unlock xyz"), Err(ErrorCode::BadNumber));
        assert_eq!(parse(""), Err(ErrorCode::Syntax));
    }
}
