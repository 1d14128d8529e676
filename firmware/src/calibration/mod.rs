//! Calibration: the least-squares fit of the compensation coefficients a and b, the checks a
//! fit must pass, and the on-device procedure that runs them.

pub mod fit;
pub mod session;
pub mod tracking;
pub mod validation;
