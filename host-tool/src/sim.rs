//! The simulated board behind the in-process link, the server and the sweep: hal-sim's
//! [`SimDevice`] (the firmware's protocol, readout and store against the simulated gyro) with
//! the docs/physics.md gyro (noise off) and the simulated board's identity (key `c0ffee42`).

use hal_sim::device::{SimDevice, SIM_IDENTITY};
use hal_sim::flash::CalibrationFlash;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use std::io;

/// The unlock key of the simulated board, as typed.
pub fn sim_key() -> String {
    format!("{:08x}", SIM_IDENTITY.key)
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

/// Powers up a simulated board on `flash` (its calibration survives power cycles).
pub fn boot(
    input: SimInput,
    seed: u64,
    flash: CalibrationFlash,
    boot_count: u32,
) -> io::Result<SimDevice> {
    let params = GyroParams {
        seed,
        ..GyroParams::default()
    };
    SimDevice::boot(params, input.profile(), SIM_IDENTITY, flash, boot_count)
        .map_err(|e| io::Error::other(format!("simulated board: {e:?}")))
}
