//! Generic maths of the firmware, bit-exact on every target: the integer CORDIC `atan2`, the
//! small `f64` solver of the Lissajous fit and the scalar helpers it is built from.
//!
//! Nothing here knows about gyros. The rule every function follows: the Cortex-M4F and x86-64
//! must compute the same bits (the golden vectors check it), so there are only integer
//! operations, or `f64`/`f32` basic operations that IEEE 754 rounds correctly (no fused
//! multiply-add, no library transcendental functions).

mod atan2;
mod linear;
mod scalar;

pub use atan2::{atan2_q32, radius_sq_q30, CORDIC_ITERATIONS, MAX_ERROR_Q32};
pub use linear::solve5;
pub use scalar::{
    abs_f64, max_f64, positive, powi_f64, round_f32_to_i32, round_to_i64, saturate_i32, sqrt_f64,
};
