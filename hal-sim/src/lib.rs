//! A simulated ring laser gyro and readout board, so the firmware's logic runs on x86.
//!
//! The rooms:
//! - the gyro ([`params`], [`units`], [`input`], [`dither`], [`noise`], [`phase`], [`gyro`];
//!   [`random_gyro`] draws gyros within what real ones have; [`trig`] is the fast cos/sin the
//!   dither and the integrator share, below both):
//!   the phase equation (docs/physics.md Eq. 6) integrated with the dither phase known analytically,
//!   the dither a prescribed sine (`ideal`) or a resonator driven by the firmware's DAC through
//!   its amplifier (the drive pushed in segments, [`dither`]);
//! - the board ([`photodiode`], [`pickoff`], [`counter`], [`clock`], [`flash`]): the peripherals
//!   the firmware reads, producing exactly the plain structs of `firmware::sample`;
//! - [`board`]: gyro and peripherals assembled into what the firmware's interrupts receive;
//! - [`harness`]: the board with the firmware's readout in the loop, one half dither cycle per
//!   step: every firmware-in-the-loop run (the sweep, the system tests) goes through it;
//!   [`drive_loop`] puts the firmware's dither drive in the loop beside it.
//!
//! The board's facts (timer clock, counter width, latch delays, dither range) are the
//! firmware's (`firmware::profile::BoardProfile::F405`), not repeated here.

#![warn(missing_docs)]

pub mod dither;
pub mod gyro;
pub mod input;
pub mod noise;
pub mod param_error;
pub mod params;
pub mod phase;
pub mod random_gyro;
pub mod thermal;
pub mod tmp117;
pub mod trig;
pub mod units;

pub mod clock;
pub mod counter;
pub mod flash;
pub mod photodiode;
pub mod pickoff;

pub mod board;
pub mod device;
pub mod drive_loop;
pub mod harness;
