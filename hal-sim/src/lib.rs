//! A simulated ring laser gyro and readout board, so the firmware's logic runs on x86.
//!
//! Two rooms:
//! - the gyro ([`params`], [`units`], [`input`], [`dither`], [`noise`], [`phase`], [`gyro`]):
//!   the phase equation (docs/physics.md Eq. 6) integrated with the dither phase known analytically;
//! - the board ([`photodiode`], [`counter`], [`clock`], [`flash`]): the peripherals
//!   the firmware reads, producing exactly the plain structs of `firmware::sample`;
//! - [`board`]: gyro and peripherals assembled into what the firmware's interrupts receive.

pub mod dither;
pub mod gyro;
pub mod input;
pub mod noise;
pub mod params;
pub mod phase;
pub mod units;

pub mod clock;
pub mod counter;
pub mod flash;
pub mod photodiode;

pub mod board;
pub mod device;
