//! The board's power-up decisions as one plain function, so the host tests what the board's
//! boot does (`board::app::boot` is a call to [`power_up`] plus the queues and the log).
//!
//! What a reset decides, in order:
//! 1. the identity: serial number and key from OTP ([`otp_identity`], the layout
//!    `crate::otp_record`): a blank serial word is serial 0 and no complete key record is *no
//!    key*, so a board nobody provisioned refuses every unlock (`ERR 16`); there is no default
//!    key;
//! 2. the calibration: the newest valid record of this gyro from flash, or the defaults
//!    (`Service::boot`);
//! 3. the wrong-key count the backup domain kept across the reset, restored into the access
//!    control (`Service::restore_wrong_keys`): past the free attempts, unlock attempts are
//!    checked only in the windows, the first one window period after the boot;
//! 4. the readout, started with the loaded compensation and, when the record has them, the
//!    stored stripping coefficients; the dither drive's stored setpoints are handed on;
//! 5. the stored thermal model and its switch, in force in the service's thermal state
//!    (`Service::boot`) and staged into the readout: its records are corrected from the
//!    sensor's first result on (none before: the model needs the temperature).

use embedded_storage::nor_flash::NorFlash;

use super::{Service, ServiceConfig};
use crate::otp_record::{self, OtpCells};
use crate::protocol::key::Key;
use crate::readout::Readout;
use crate::storage::{DitherSetpoints, GeometryError, LoadReport};

/// A board just powered up: what its contexts start with.
pub struct PoweredUp<F: NorFlash> {
    /// The command service, locked, the wrong-key count restored, owning the flash.
    pub service: Service<F>,
    /// The readout with the loaded compensation (and stripping coefficients).
    pub readout: Readout,
    /// The dither drive's stored setpoints; `None`: the drive keeps its defaults.
    pub dither: Option<DitherSetpoints>,
    /// What the load found.
    pub report: LoadReport,
    /// Wrong keys kept across the reset (0 after a cold start), for the log.
    pub wrong_keys: u32,
}

/// The serial number (0 when not programmed) and the key (`None`: unprovisioned, or only
/// spent blocks) in the OTP `cells` (`crate::otp_record`).
pub fn otp_identity(cells: &impl OtpCells) -> (u32, Option<Key>) {
    (
        otp_record::serial(cells).unwrap_or(0),
        otp_record::key(cells),
    )
}

/// Powers up on `flash` (see the module docs); `kept_wrong_keys` is what the backup domain
/// held (0 when it was lost), `now_ms` the clock at boot.
pub fn power_up<F: NorFlash>(
    config: ServiceConfig,
    flash: F,
    kept_wrong_keys: u32,
    now_ms: u64,
) -> Result<PoweredUp<F>, GeometryError> {
    let mut booted = Service::boot(config, flash, None)?;
    booted.service.restore_wrong_keys(kept_wrong_keys, now_ms);
    let mut readout = Readout::new(&config.readout, booted.settings);
    if let Some(strip) = booted.strip {
        // The stripping starts from the stored K (its fit learns on from there).
        readout.restart_strip_from(&config.readout, strip.k(), strip.k_quadrature());
    }
    readout.set_thermal(booted.service.thermal().input());
    Ok(PoweredUp {
        service: booted.service,
        readout,
        dither: booted.dither,
        report: booted.report,
        wrong_keys: kept_wrong_keys,
    })
}
