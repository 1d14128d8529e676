//! Firmware of the dither-control and readout board for mechanically dithered ring laser gyros.
//!
//! Architecture (sans-IO): interrupt handlers copy peripheral registers into the plain structs of
//! [`sample`] and call the pure functions of the signal chain. Everything outside `rt` (the MCU
//! glue) is ordinary `no_std` logic that also builds and is tested on x86, where `hal-sim`
//! drives it with a simulated gyro.
//!
//! Signal chain ([`signal`]), one module per stage, imports one way:
//! count -> turnaround sample -> Lissajous normalisation and fractional fringe -> P1/P2 (cycle
//! assembly) -> compensation -> output; [`readout`] wires it. Units in one place ([`units`]:
//! Q32 fringes, the wrapping [`units::Phase`]); generic bit-exact maths in [`math`].
#![cfg_attr(not(test), no_std)]
#![warn(missing_docs)]
// No panics on the product path, in every module (the board's register code included): no
// unwrap, expect, panic, unreachable or slice indexing. Where the input comes from outside the
// board (the protocol, the service, the storage), integer arithmetic is checked, wrapping or
// saturating too (`clippy::arithmetic_side_effects` in those modules); the signal chain's
// integers are bounded codes and sums, and its phases wrap by design (`wrapping_*`). Each
// exception is allowed where it stands, with its reason. Tests may panic.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo
    )
)]

mod flags;

pub mod board_timing;
pub mod calibration;
pub mod dither;
pub mod math;
pub mod millis;
pub mod otp_record;
pub mod profile;
pub mod protocol;
pub mod readout;
pub mod sample;
pub mod service;
pub mod signal;
pub mod units;

pub mod storage;
#[cfg(test)]
mod test_rng;
pub mod thermal;

#[cfg(target_os = "none")]
pub mod board;
#[cfg(target_os = "none")]
pub mod icount;
#[cfg(target_os = "none")]
pub mod rt;
#[cfg(target_os = "none")]
pub mod stack;
