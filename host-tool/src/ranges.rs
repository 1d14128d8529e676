//! The valid range of every numeric command-line flag of `rlg-cal`: one [`Range`] constant per
//! flag, with the reason for its bounds.
//!
//! `cli.rs` reads each constant twice: `RANGE.parser()` is the flag's clap value parser and
//! `RANGE.help(...)` writes its help, so the numbers are written here only. A value outside (a
//! leading minus included where the value cannot be negative, `inf`, `NaN`) is refused by clap
//! before anything runs: exit status 2, a message naming the flag, the value and the range
//! (`host_cli::range`). Ranges are physical or practical limits; a flag that shares another's
//! range reads it ([`Range::for_flag`]), so a shared limit is stated once too.

use firmware::protocol::parse::MAX_CAL_CYCLES;
use host_cli::range::Range;

/// `--baud`: 1200 ..= 4 000 000 Bd (the F405's USART at 84 MHz goes up to 5.25 MBd).
pub const BAUD: Range<u32> = Range::closed("--baud", 1_200, 4_000_000, "Bd");

/// `--timeout-ms`: 1 ms ..= 10 minutes.
pub const TIMEOUT_MS: Range<u64> = Range::closed("--timeout-ms", 1, 600_000, "ms");

/// `--sim-rate`, the input rate of the simulated gyro: |rate| <= 100 000 deg/h (the model's
/// lock-in and dither hold far beyond any RLG's measuring range).
pub const SIM_RATE_DEG_H: Range<f64> = Range::symmetric("--sim-rate", 100_000.0, "deg/h");

/// `serve-sim --rate`: the served simulated gyro's input rate, as [`SIM_RATE_DEG_H`].
pub const SERVE_RATE_DEG_H: Range<f64> = SIM_RATE_DEG_H.for_flag("--rate");

/// `thermal --input-rate-deg-h`: the gyro's true input at rest, as [`SIM_RATE_DEG_H`].
pub const INPUT_RATE_DEG_H: Range<f64> = SIM_RATE_DEG_H.for_flag("--input-rate-deg-h");

/// `calibrate --cycles`: 1 ..= 3 600 000 dither cycles in the fit, the board's limit.
pub const CAL_CYCLES: Range<u32> = Range::closed("--cycles", 1, MAX_CAL_CYCLES, "dither cycles");

/// `sweep --cal-cycles`: as [`CAL_CYCLES`].
pub const SWEEP_CAL_CYCLES: Range<u32> = CAL_CYCLES.for_flag("--cal-cycles");

/// `calibrate --warmup`: 0 ..= 3 600 000 dither cycles discarded first, the board's limit.
pub const WARMUP_CYCLES: Range<u32> = Range::closed("--warmup", 0, MAX_CAL_CYCLES, "dither cycles");

/// `sweep --cal-warmup`: as [`WARMUP_CYCLES`].
pub const SWEEP_CAL_WARMUP_CYCLES: Range<u32> = WARMUP_CYCLES.for_flag("--cal-warmup");

/// `stream --divider`, `sweep --divider`: every n-th cycle, 1 ..= 65535 (the board's `u16`).
pub const DIVIDER: Range<u16> = Range::closed("--divider", 1, u16::MAX, "cycles");

/// `calibrate --poll-ms`: 10 ms ..= 1 minute.
pub const POLL_MS: Range<u64> = Range::closed("--poll-ms", 10, 60_000, "ms");

/// A duration (`stream --seconds`, `sweep --seconds`, `serve-sim --seconds`): 0 < s <= one
/// day.
pub const SECONDS: Range<f64> = Range::above("--seconds", 0.0, 86_400.0, "s");

/// `record --seconds`: 0 < s <= 100 h (a record for an Allan deviation's long taus).
pub const RECORD_SECONDS: Range<f64> = Range::above("--seconds", 0.0, 360_000.0, "s");

/// `thermal --seconds`: a record of the output as [`RECORD_SECONDS`], up to 100 h (a
/// chamber's run of ramps and soaks takes hours).
pub const THERMAL_SECONDS: Range<f64> = RECORD_SECONDS;

/// `sweep --settle`: 0 ..= 600 s.
pub const SETTLE_S: Range<f64> = Range::closed("--settle", 0.0, 600.0, "s");

/// `stream --timer-hz`, `record --timer-hz`: 1 kHz ..= 1 GHz.
pub const TIMER_HZ: Range<f64> = Range::closed("--timer-hz", 1e3, 1e9, "Hz");

/// `sweep --latitude`, `serve-sim --latitude`: -90 ..= 90 deg.
pub const LATITUDE_DEG: Range<f64> = Range::symmetric("--latitude", 90.0, "deg");

/// `sweep --azimuths`: each -360 ..= 360 deg.
pub const AZIMUTHS_DEG: Range<f64> = Range::symmetric("--azimuths", 360.0, "deg");

/// `sweep --cal-azimuth`: as [`AZIMUTHS_DEG`].
pub const CAL_AZIMUTH_DEG: Range<f64> = AZIMUTHS_DEG.for_flag("--cal-azimuth");

/// `serve-sim --azimuth`: as [`AZIMUTHS_DEG`].
pub const AZIMUTH_DEG: Range<f64> = AZIMUTHS_DEG.for_flag("--azimuth");

/// `serve-sim --speed`: 0 < x <= 1000 simulated seconds per second.
pub const SPEED: Range<f64> = Range::above("--speed", 0.0, 1000.0, "simulated s per s");

/// `thermal --table-rate-deg-h`: R of the rate table, 3 600 ..= 1 000 000 deg/h (1 deg/s
/// upwards: the scale factor's +-R must stand far out of the bias and the noise).
pub const TABLE_RATE_DEG_H: Range<f64> =
    Range::closed("--table-rate-deg-h", 3_600.0, 1_000_000.0, "deg/h");

/// `thermal --reference-c`: T_ref within the TMP117's -55 ..= 150 °C.
pub const REFERENCE_C: Range<f64> = Range::closed("--reference-c", -55.0, 150.0, "C");
