//! Temperature on the simulated gyro: the block's profile as the user types it
//! ([`profile_arg`]), and the thermal calibration and its check, IEEE Std 647's bias and scale
//! factor over temperature ([`procedure`]), which `rlg-sim characterize --thermal` reports and
//! the system tests (`tests/thermal.rs`) judge.

pub mod procedure;
pub mod profile_arg;
