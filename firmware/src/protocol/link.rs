//! The protocol's boundary to the rest of the firmware: what the device is ([`Identity`]), a
//! snapshot of the readout ([`DeviceStatus`]) and the few things a command may ask of the
//! device ([`DeviceLink`]).
//!
//! The board implements [`DeviceLink`] with critical sections around the readout's staging
//! slot, hal-sim's simulated board and the fuzzer with plain memory; the command groups in
//! [`super::commands`] see nothing else of the device. These types are re-exported from
//! [`super::execute`], where callers have always found them.

use super::key::Key;
use crate::board_timing::health::BoardHealth;
use crate::dither::{CommandError, DitherStatus};
use crate::signal::compensation::CompensationSettings;
use crate::signal::output::strip::StripStatus;
use crate::storage::{
    CalibrationRecord, DitherSetpoints, LoadReport, StoreError, Stored, StripCoefficients,
};

/// What the device is, for `id` (constants of the build and of the board's OTP block).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Identity {
    /// Firmware version (the crate version), `fw=`.
    pub firmware_version: &'static str,
    /// Build profile (`release`, `debug`; `hal-sim` in the simulator), `build=`.
    pub build: &'static str,
    /// Board name (the board profile's), `board=`.
    pub board: &'static str,
    /// The gyro's serial number (OTP flash on the board).
    pub serial_number: u32,
    /// The calibration unlock key as read at boot (OTP on the board, written once by `key
    /// provision`); `None`: unprovisioned, protected commands are refused until it is.
    pub key: Option<Key>,
    /// Scale factor, arcsec per fringe: only for reporting deg/h.
    pub scale_factor_arcsec: f32,
    /// Capture-timer frequency, Hz: the unit of the streamed cycle durations.
    pub capture_timer_hz: u32,
}

/// A snapshot of the readout, for `status`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceStatus {
    /// The last turnaround's photodiode levels were usable.
    pub signal_ok: bool,
    /// Measured dither frequency, Hz.
    pub dither_hz: f32,
    /// Dither amplitude, beat-phase rad.
    pub dither_amplitude_rad: f32,
    /// Turnarounds latched since boot (wrapping).
    pub turnarounds: u32,
    /// Dither cycles closed since boot (wrapping).
    pub cycles: u32,
    /// Turnarounds whose encoder count jumped (glitch or resync), since boot (saturating).
    pub counter_glitches: u32,
    /// Turnarounds whose photodiode phase lay over a quadrant off the count (saturating).
    pub phase_glitches: u32,
    /// Turnarounds whose photodiode levels were unusable (radius out of bounds; saturating).
    pub signal_lost: u32,
    /// Missed turnarounds: the larger of the cycles flagged missed and the hardware path's losses.
    pub missed_turnarounds: u32,
    /// Latest averaged output rate, deg/h.
    pub rate_deg_per_h: f32,
    /// The dither stripping's coefficients and the state of their fit.
    pub strip: StripStatus,
    /// Output records made since boot (the next record's sequence number).
    pub output_records: u64,
    /// Closed cycles lost before the service saw them (a full record queue; saturating).
    pub cycles_dropped: u32,
}

/// What the protocol needs from the rest of the firmware.
pub trait DeviceLink {
    /// The flash driver's error, carried in [`StoreError::Flash`].
    type FlashError: core::fmt::Debug;
    /// Milliseconds since boot, monotonic, 64 bits (never wraps).
    fn now_ms(&self) -> u64;
    /// A snapshot of the readout's counters and dither, for `status`.
    fn status(&self) -> DeviceStatus;
    /// The settings the readout applies now.
    fn active_settings(&mut self) -> CompensationSettings;
    /// Hands settings to the readout; they take effect whole at the next cycle boundary.
    fn stage_settings(&mut self, settings: CompensationSettings);
    /// Stores the record (read back), pausing and re-synchronising the readout only if a sector
    /// is erased for it; returns its sequence number and whether it erased.
    fn store(&mut self, record: &CalibrationRecord)
        -> Result<Stored, StoreError<Self::FlashError>>;
    /// Reads the newest valid record (or the defaults) with the store's report.
    fn load(&mut self) -> (CalibrationRecord, LoadReport);
    /// The dither drive's status, in physical units.
    fn dither_status(&mut self) -> DitherStatus;
    /// The dither drive's setpoints in force (what `store` saves).
    fn dither_setpoints(&mut self) -> DitherSetpoints;
    /// Applies setpoints to the dither drive whole: every field is range-checked first, and a
    /// refused one changes nothing.
    fn apply_dither(&mut self, setpoints: DitherSetpoints) -> Result<(), CommandError>;
    /// The dither stripping's coefficients, once their fit has converged (what `store` saves);
    /// `None` while it is still learning.
    fn strip_coefficients(&mut self) -> Option<StripCoefficients>;
    /// Starts the stripping from stored coefficients (`reload`), its fit learning on from them.
    fn apply_strip(&mut self, strip: StripCoefficients);
    /// Writes the key to the board's one-time-programmable memory and locks it (`key
    /// provision`; the executor calls it only while no key is provisioned). `Err`: the write
    /// failed or did not read back; the board stays unprovisioned.
    fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError>;
    /// The board's power-up self-test and the timing faults raised now (`status`'s `board=`,
    /// `selftest`); a device without a board: untested.
    fn board_health(&mut self) -> BoardHealth {
        BoardHealth::UNTESTED
    }
    /// The thermal state (`thermal`): the sensor, the model in force and its switch.
    fn thermal(&mut self) -> crate::thermal::state::ThermalState;
    /// Puts a thermal model in force (`None`: none), switched on (`enabled`) or off; the
    /// output's next records follow it (`thermal apply|on|off`, `reload`).
    fn set_thermal_model(
        &mut self,
        model: Option<crate::thermal::model::ThermalModel>,
        enabled: bool,
    );
    /// The scale factor the thermal corrections are in, arcsec per fringe.
    fn thermal_scale_factor_arcsec(&mut self) -> f32 {
        1.0
    }
}

/// Why the key could not be written to OTP.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyWriteError {
    /// The OTP words are not blank (another key, or a failed earlier attempt): the board can
    /// never be provisioned; it stays locked.
    NotBlank,
    /// The flash controller reported an error, or the words did not read back.
    Failed,
}
