//! The simulated board behind the in-process link, the server and the sweep: hal-sim's
//! [`SimDevice`] (the firmware's protocol, readout and store against the simulated gyro) with
//! the docs/physics.md gyro (noise off), its block at a temperature profile if one is given
//! ([`gyro`]), and the simulated board's identity.
//!
//! The simulated board has no fixed key: it boots with the key given in a file
//! (`serve-sim --board-key-file`) or the environment variable [`BOARD_KEY_ENV`], or unprovisioned
//! like a new board (then `key provision <key>` sets one). Runs that talk only to a board inside
//! this process (the sweep) give it a fresh random key ([`fresh_key`]).

use firmware::protocol::key::Key;
use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::flash::CalibrationFlash;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use std::io;

/// The environment variable with the simulated board's key (32 hex digits).
pub const BOARD_KEY_ENV: &str = "RLG_SIM_BOARD_KEY";

/// The simulated board's key: `given` (read from `--board-key-file`), else [`BOARD_KEY_ENV`],
/// else none (unprovisioned). A value that is no 128-bit key is an error naming where it came
/// from (not the value).
pub fn board_key(given: Option<&str>) -> Result<Option<Key>, String> {
    let (text, from) = match given {
        Some(text) => (text.to_owned(), "--board-key-file"),
        None => match std::env::var(BOARD_KEY_ENV) {
            Ok(text) => (text, BOARD_KEY_ENV),
            Err(_) => return Ok(None),
        },
    };
    Key::parse_hex(text.trim())
        .map(Some)
        .ok_or_else(|| format!("{from}: a key is 32 hex digits (128 bits), not all f"))
}

/// A random 128-bit key (from the operating system's hash seed and the clock), for a board
/// that lives only inside this process.
pub fn fresh_key() -> Key {
    use std::hash::{BuildHasher, Hasher};
    let half = |salt: u64| {
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u64(salt);
        h.write_u128(
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        h.finish()
    };
    let mut bytes = [0u8; 16];
    bytes[..8].copy_from_slice(&half(1).to_be_bytes());
    bytes[8..].copy_from_slice(&half(2).to_be_bytes());
    Key::parse_hex(&key_hex(&Key::from_bytes(bytes))).unwrap_or_else(fresh_key)
}

/// The key of the simulated boards in this crate's tests (a test fixture, no board's key).
pub fn test_key() -> Key {
    Key::parse_hex("3a7c5e91b2d4f60819e3c5a7b9d1f2e4").expect("32 hex digits")
}

/// A key as typed: 32 lower-case hex digits.
pub fn key_hex(key: &Key) -> String {
    key.hex().to_string()
}

/// What the simulated gyro measures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SimInput {
    /// A constant rate, deg/h.
    Constant {
        /// The input rate, deg/h.
        rate_deg_per_h: f64,
    },
    /// Earth rate on a horizontal axis on a rotary table at this latitude and azimuth.
    RotaryTable {
        /// Geographic latitude of the table, deg.
        latitude_deg: f64,
        /// Azimuth of the sensitive axis, deg from north.
        azimuth_deg: f64,
    },
}

impl SimInput {
    /// hal-sim's input profile for this input.
    pub fn profile(&self) -> InputProfile {
        match *self {
            Self::Constant { rate_deg_per_h } => InputProfile::constant(rate_deg_per_h),
            Self::RotaryTable {
                latitude_deg,
                azimuth_deg,
            } => InputProfile::rotary_table(latitude_deg, azimuth_deg),
        }
    }
}

/// The simulated gyro with `seed`, its block at `temperature` from power-up (hal-sim's default
/// thermal coefficients; `None`: at their T_ref, where none acts).
pub fn gyro(seed: u64, temperature: Option<TemperatureProfile>) -> GyroParams {
    let params = GyroParams {
        seed,
        ..GyroParams::default()
    };
    match temperature {
        Some(profile) => params.with_temperature(profile),
        None => params,
    }
}

/// Powers up a simulated board on `flash` (its calibration survives power cycles) with `key`
/// in its OTP (`None`: unprovisioned), its block at T_ref.
pub fn boot(
    input: SimInput,
    seed: u64,
    flash: CalibrationFlash,
    boot_count: u32,
    key: Option<Key>,
) -> io::Result<SimDevice> {
    boot_gyro(gyro(seed, None), input.profile(), flash, boot_count, key)
}

/// [`boot`] with any gyro (e.g. its block on a temperature profile) and input.
pub fn boot_gyro(
    params: GyroParams,
    input: InputProfile,
    flash: CalibrationFlash,
    boot_count: u32,
    key: Option<Key>,
) -> io::Result<SimDevice> {
    let identity = firmware::protocol::execute::Identity {
        key,
        ..SIM_IDENTITY
    };
    SimDevice::boot(params, input, identity, flash, boot_count)
        .map_err(|e| io::Error::other(format!("simulated board: {e:?}")))
}
