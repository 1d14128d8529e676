//! Stage 6, the output: what leaves the board.
//!
//! | part | module | in | out |
//! |---|---|---|---|
//! | 6a | [`dither_model`] | the pick-off stream (every drive tick) | the dither at any instant, far below one conversion's noise |
//! | 6a | [`strip`] | the compensated phase and the pick-off at an output latch | the phase without the dither (`K` fitted online) |
//! | 6b | [`record`] | the stripped phase at each output latch | one [`record::OutputRecord`] per output period (sync or internal rate) |
//! | 6c | [`rate`] | per-cycle compensated increments | the rate averaged over a window; the rate shift fed back to stage 2 |
//!
//! 6a and 6b run in the output-latch interrupt (the sync input's capture), through
//! [`crate::readout::Readout::on_output_latch`]; 6c in the cycle task.

pub mod dither_model;
pub mod latch_plan;
pub mod rate;
pub mod record;
pub mod strip;

pub use rate::*;
