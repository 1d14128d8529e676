//! The signal chain: fringe counting -> turnaround sampling -> P1/P2 -> compensation -> output.

pub mod compensation;
pub mod cycle;
pub mod fractional_fringe;
pub mod fringe_count;
pub mod fringe_phase;
pub mod lissajous;
pub mod lockin_terms;
pub mod output;
pub mod quadrature;
pub mod turnaround_schedule;
