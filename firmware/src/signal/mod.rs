//! The signal chain: fringe counting -> turnaround sampling -> P1/P2 -> compensation -> output.
//!
//! # No software x4 decoder
//!
//! The fringes are counted in hardware: the board's TIM5 runs in encoder mode (x4, 95 ns input
//! filter, `board::encoder`) and keeps up with the 2.4 M edges/s peak of the docs/physics.md
//! parameter set; the chain only extends the latched register ([`count`]). A software
//! decoder of sampled comparator states (`signal/quadrature.rs`) existed until issue 11 and
//! was removed: nothing on the readout path called it (only its tests, a resolver test, the
//! `cost` example and a golden-vector case), and sampling the comparators at twice the peak
//! edge rate would have cost about a quarter of the CPU (8.0 instructions per sample measured
//! in QEMU, ~38 M instructions/s). git history keeps it for a board without an encoder timer.

pub mod compensation;
pub mod count;
pub mod fringe;
pub mod lockin;
pub mod output;
pub mod turnaround;
