//! Generic maths of the firmware, bit-exact on every target: the integer CORDIC `atan2`, the
//! small `f64` solver of the Lissajous fit and the scalar helpers it is built from.
//!
//! Nothing here knows about gyros. The rule every function follows: the Cortex-M4F and x86-64
//! must compute the same bits (the golden vectors check it), so there are only integer
//! operations, or `f64`/`f32` basic operations that IEEE 754 rounds correctly (no fused
//! multiply-add, no library transcendental functions).
//!
//! # `atan2`: ours against QUARTIQ's `idsp` (measured, issue 11)
//!
//! STYLE.md says to reach for the field's library first: `idsp` has a fixed-point `atan2`
//! (reciprocal LUT, one Newton step, odd polynomial), a generic CORDIC (`sqrt_atan2`) and
//! `cossin`; its angles are Q32 turns like those of [`atan2_q32`] (`i32`, a full turn = 2^32).
//! Measured with idsp 0.23.1 against `f64::atan2` of the same integer inputs (rad; 4 x 10^6
//! inputs per domain on the host), and in instructions per call on the emulated Cortex-M4F
//! (QEMU `-icount shift=0`, TIM2 counting by `firmware::icount` as `cargo fw-icount` does; mean
//! over 256 chain-domain inputs with the loop's own cost subtracted; the workspace's release
//! profile, `opt-level = "s"`, fat LTO):
//!
//! | | rms error | max error | instructions | idsp at opt 3 | all at opt 3 |
//! |---|---|---|---|---|---|
//! | [`atan2_q32`] (27-step CORDIC, normalised inputs) | 7.6e-9 | 4.3e-8 | 347 | 347 | 457 |
//! | `idsp::atan2` | 1.28e-6 | 2.29e-6 | 122 | 86 | 78 |
//! | `idsp::sqrt_atan2` (30-step CORDIC; inputs `>> 1`) | 4.4e-9 | 3.0e-8 | 360 | 360 | 317 |
//!
//! The error columns are the chain's domain: normalised levels in Q30 with a radius of 0.5 to
//! 1.5 (the resolver's bounds), any angle. Over any `i32` pair ours stays at 7.0e-9 rms /
//! 4.0e-8 max and `idsp::atan2` at 1.26e-6 / 2.29e-6, while `sqrt_atan2` (inputs `>> 2` there
//! against the CORDIC gain) reaches 4.3e-6 max, and 1.3e-3 rms for radii near 1000 (it does
//! not normalise small inputs). The method: a scratch crate outside the repository (not kept),
//! `cargo run --release` on the host for the errors and with the QEMU `-icount` runner of
//! `.cargo/config.toml` for the counts.
//!
//! Decision: **ours stays**. `idsp::atan2` is 3x faster (225 instructions saved per turnaround,
//! about 0.1 % of the CPU at 389 Hz) but 170x less accurate; `sqrt_atan2` is as accurate only
//! in the chain's domain and not faster. Neither is "as accurate and as fast", and either would
//! change every bit the chain computes (golden vectors, the sweep). For the record, idsp's
//! accuracy would be enough for the readout: its 2.3e-6 rad is 100x below what the 12-bit
//! photodiode levels resolve (0.5 code on a 2047-code radius = 2.4e-4 rad), 1e-4 of the
//! 0.018 rad lock-in correction per cycle, and the phase errors of the readings telescope in
//! the averaged rate (only the window's first and last reading count).
//!
//! # `sine_fit`: a sine of known phase
//!
//! The least-squares fit of offset + cos + sin of a known regressor phase, in exact integer
//! sums ([`sine_fit::SineSums`]), shared by the dither drive's half-cycle measurement and the
//! output stage's dither model; [`cossin`] (`idsp::cossin` bit for bit, its table in RAM)
//! makes the regressors.

mod atan2;
pub mod cossin;
mod linear;
mod scalar;
pub mod sine_fit;

pub use atan2::{atan2_q32, radius_sq_q30, CORDIC_ITERATIONS, MAX_ERROR_Q32};
pub use linear::solve5;
pub use scalar::{
    abs_f64, max_f64, positive, powi_f64, round_f32_to_i32, round_to_i64, saturate_i32, sqrt_f64,
};
