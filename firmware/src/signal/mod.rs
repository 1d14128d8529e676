//! The signal chain: fringe counting -> turnaround sampling -> P1/P2 -> compensation -> output.

pub mod fringe_count;
pub mod quadrature;
pub mod lissajous;
pub mod fractional_fringe;
pub mod fringe_phase;
pub mod lockin_terms;
pub mod compensation;
pub mod output;
pub mod cycle;
