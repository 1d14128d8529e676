//! The commands, one module per group, each owning the state its commands change.
//!
//! [`super::execute::Executor`] holds one state value per group and dispatches each parsed
//! command to its group's function; the rules that cut across groups (which commands need an
//! unlock, which are refused while a calibration run collects cycles, when an unlock is
//! extended) stay in the executor, so every function here may assume it is allowed to run.
//!
//! | group | commands | state |
//! |---|---|---|
//! | [`info`] | `help` `id` `status` `get` | none (reads the device) |
//! | [`settings`] | `set` `comp` `track` `defaults` | [`provenance::Provenance`], tracking in [`calibration::CalibrationState`] |
//! | [`calibration`] | `cal start/status/abort/result/accept` | [`calibration::CalibrationState`] (session + tracking loop) |
//! | [`storage`] | `store` `reload` | [`provenance::Provenance`] |
//! | [`stream`] | `stream on/off` | [`stream::StreamState`] |
//! | [`access`] | `unlock` `lock` | [`access::AccessState`] |
//! | [`dither`] | `dither on/off/amp/noise/status` | none (the drive holds its setpoints) |
//! | [`thermal`] | `thermal`, `thermal model/range/bias/sf/apply/on/off` | [`thermal::ThermalEdit`] (the model being edited), [`provenance::Provenance`] |
//!
//! A group function answers `Ok(response)` or `Err(code)`; a refusal changes nothing (the one
//! deliberate exception is `cal result`, see [`calibration`]). Modules import downwards only:
//! `settings` uses `calibration` and `provenance`, `storage` and `calibration` use
//! `provenance`, nothing here imports the executor.

pub mod access;
pub mod calibration;
pub mod dither;
pub mod info;
pub mod provenance;
pub mod settings;
pub mod storage;
pub mod stream;
pub mod thermal;

use super::respond::Response;
use super::ErrorCode;

/// A command's answer: `Ok` is sent as it is (it may itself be an `ERR` line with fields, such
/// as a refused fit or a rate-limited unlock); `Err` becomes a bare `ERR <code> <text>`.
pub type Answer = Result<Response, ErrorCode>;

/// A response with one field.
fn ok_with(args: core::fmt::Arguments<'_>) -> Response {
    let mut r = Response::ok();
    r.field(args);
    r
}

/// An in-memory device for the groups' unit tests.
#[cfg(test)]
pub(crate) mod testing {
    use crate::dither::{CommandError, DitherConfig, DitherController, DitherStatus};
    use crate::profile::BoardProfile;
    use crate::protocol::key::Key;
    use crate::protocol::link::{DeviceLink, DeviceStatus, Identity, KeyWriteError};
    use crate::protocol::respond::Response;
    use crate::signal::compensation::CompensationSettings;
    use crate::storage::{
        CalibrationRecord, DefaultsReason, DitherSetpoints, LoadOutcome, LoadReport, StoreError,
    };

    pub const ID: Identity = Identity {
        firmware_version: "1.2.3",
        build: "test",
        board: "sim",
        serial_number: 4242,
        key: Some(Key::from_bytes([
            0x0f, 0x1e, 0x2d, 0x3c, 0x4b, 0x5a, 0x69, 0x78, 0x87, 0x96, 0xa5, 0xb4, 0xc3, 0xd2,
            0xe1, 0xf0,
        ])),
        scale_factor_arcsec: 2.0,
        capture_timer_hz: 84_000_000,
    };

    /// The firmware's dither controller without ticks (the F405 profile's settings, enabled):
    /// the commands' range checks and setpoints are the real ones. Equal when the setpoints
    /// and the state are.
    #[derive(Clone, Debug)]
    pub struct MemDrive {
        pub config: DitherConfig,
        pub controller: DitherController,
    }

    impl Default for MemDrive {
        fn default() -> Self {
            let config = DitherConfig::for_profile(&BoardProfile::F405);
            let mut controller = DitherController::new(&config);
            controller.enable();
            Self { config, controller }
        }
    }

    impl PartialEq for MemDrive {
        fn eq(&self, other: &Self) -> bool {
            self.controller.setpoints() == other.controller.setpoints()
                && self.controller.state() == other.controller.state()
        }
    }

    /// Settings in force, staged settings, stored records; `fail_store` makes `store` fail.
    #[derive(Clone, Debug, Default, PartialEq)]
    pub struct MemDevice {
        pub now_ms: u64,
        pub status: DeviceStatus,
        pub settings: CompensationSettings,
        pub staged: u32,
        pub stored: Vec<CalibrationRecord>,
        pub fail_store: bool,
        /// `store` reports an erase (the readout paused and re-synchronised).
        pub store_erases: bool,
        pub drive: MemDrive,
        pub strip: Option<crate::storage::StripCoefficients>,
        /// The key `program_key` wrote (OTP); `fail_store` makes the write fail too.
        pub otp_key: Option<Key>,
        /// What `board_health` reports.
        pub health: crate::board_timing::health::BoardHealth,
        /// The thermal model in force and its switch.
        pub thermal_model: Option<(crate::thermal::model::ThermalModel, bool)>,
    }

    impl DeviceLink for MemDevice {
        type FlashError = ();
        fn now_ms(&self) -> u64 {
            self.now_ms
        }
        fn status(&self) -> DeviceStatus {
            self.status
        }
        fn active_settings(&mut self) -> CompensationSettings {
            self.settings
        }
        fn stage_settings(&mut self, settings: CompensationSettings) {
            self.settings = settings;
            self.staged += 1;
        }
        fn store(
            &mut self,
            record: &CalibrationRecord,
        ) -> Result<crate::storage::Stored, StoreError<()>> {
            if self.fail_store {
                return Err(StoreError::Flash(()));
            }
            self.stored.push(*record);
            Ok(crate::storage::Stored {
                sequence: self.stored.len() as u32,
                erased: self.store_erases,
            })
        }
        fn load(&mut self) -> (CalibrationRecord, LoadReport) {
            let outcome = match self.stored.last() {
                Some(_) => LoadOutcome::Loaded {
                    sequence: self.stored.len() as u32,
                },
                None => LoadOutcome::Defaults {
                    reason: DefaultsReason::Erased,
                },
            };
            let record = self
                .stored
                .last()
                .copied()
                .unwrap_or(CalibrationRecord::DEFAULTS);
            (record, report(outcome))
        }
        /// The drive is locked whenever it is enabled (no ticks here to lock it).
        fn dither_status(&mut self) -> DitherStatus {
            let mut status = self.drive.controller.status(&self.drive.config);
            if self.drive.controller.enabled() {
                status.state = crate::dither::DitherState::Locked;
            }
            status
        }
        fn dither_setpoints(&mut self) -> DitherSetpoints {
            self.drive.controller.setpoints()
        }
        fn apply_dither(&mut self, setpoints: DitherSetpoints) -> Result<(), CommandError> {
            let MemDrive { config, controller } = &mut self.drive;
            controller.apply_setpoints(config, setpoints)
        }
        fn strip_coefficients(&mut self) -> Option<crate::storage::StripCoefficients> {
            self.strip
        }
        fn apply_strip(&mut self, strip: crate::storage::StripCoefficients) {
            self.strip = Some(strip);
        }
        fn program_key(&mut self, key: &Key) -> Result<(), KeyWriteError> {
            match (self.fail_store, self.otp_key) {
                (true, _) => Err(KeyWriteError::Failed),
                (false, Some(_)) => Err(KeyWriteError::NotBlank),
                (false, None) => {
                    self.otp_key = Some(*key);
                    Ok(())
                }
            }
        }
        fn board_health(&mut self) -> crate::board_timing::health::BoardHealth {
            self.health
        }
        fn thermal(&mut self) -> crate::thermal::state::ThermalState {
            let mut state = crate::thermal::state::ThermalState::new();
            if let Some((model, on)) = self.thermal_model {
                state.set_model(Some(model), on, 1.0);
            }
            state
        }
        fn set_thermal_model(
            &mut self,
            model: Option<crate::thermal::model::ThermalModel>,
            enabled: bool,
        ) {
            self.thermal_model = model.map(|m| (m, enabled));
        }
    }

    pub fn report(outcome: LoadOutcome) -> LoadReport {
        LoadReport {
            outcome,
            newer_format: None,
            rejected_records: 0,
            damaged_bytes: 0,
        }
    }

    /// The answer line as sent (no checksum).
    pub fn text(r: Response) -> String {
        r.finish(false).as_str().to_owned()
    }
}
