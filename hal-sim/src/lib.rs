//! A simulated ring laser gyro and readout board, so the firmware's logic runs on x86.
