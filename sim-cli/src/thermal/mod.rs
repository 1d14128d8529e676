//! Temperature on the simulated gyro: the thermal calibration and its check, IEEE Std 647's
//! bias and scale factor over temperature ([`procedure`]), which `rlg-sim characterize
//! --thermal` reports and the system tests (`tests/thermal.rs`) judge. The block's profile as
//! the user types it is hal-sim's ([`hal_sim::thermal::profile_text`]), shared with `rlg-cal`.

pub mod procedure;
