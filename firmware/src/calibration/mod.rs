//! Calibration: the least-squares fit of the compensation coefficients a and b.

pub mod fit;
