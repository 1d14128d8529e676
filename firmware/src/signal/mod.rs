//! The signal chain, one module per stage, in the order the data flows:
//!
//! | # | stage | module | in | out |
//! |---|---|---|---|---|
//! | 1 | count | [`count`] | the latched x4 encoder register (`u32`, wraps) | a 64-bit fringe count, glitches rejected |
//! | 2 | turnaround | [`turnaround`] | pick-off comparator edges | the instant to latch: what it latches is a [`crate::sample::TurnaroundSample`] |
//! | 3 | fringe | [`fringe`] | the ADC stream; the latched codes and count | normalised levels (cos, sin psi_H), the fractional fringe, the total phase |
//! | 4 | lock-in terms | [`lockin`] | a [`lockin::TurnaroundReading`] per turnaround | P1/P2; a [`lockin::CycleRecord`] per dither cycle, with its flags |
//! | 5 | compensation | [`compensation`] | the record, a and b | the record with a P1 + b P2 subtracted |
//! | 6 | output | [`output`] | the compensated phase and the pick-off at each output latch; compensated records | the stripped fixed-rate output records; the averaged rate; the rate shift fed back to stage 2 |
//!
//! Units come from [`crate::units`] (Q32 fringes, the [`crate::units::Phase`] of a fractional
//! fringe), generic maths (the CORDIC `atan2`, the fit's solver) from [`crate::math`].
//!
//! # One way
//!
//! A stage imports only earlier stages (and `units`, `math`, `sample`), never a later one, and
//! no two modules import each other, inside a stage either. The one backward flow, the input
//! rate that stage 6 measures and stage 2 needs for its prediction, crosses as a plain `i32`
//! argument ([`turnaround::Scheduler::on_edge`]'s `rate_shift_ticks`). [`crate::readout`] wires
//! stages 1, 3, 4 and 5 behind the two interrupts; the board (`board::turnaround`,
//! `board::isr`) and the simulated board (`hal-sim`) run stages 2 and 6.
//!
//! # No software x4 decoder
//!
//! The fringes are counted in hardware: the board's TIM5 runs in encoder mode (x4, 95 ns input
//! filter, `board::encoder`) and keeps up with the 2.4 M edges/s peak of the docs/physics.md
//! parameter set; the chain only extends the latched register ([`count`]). A software decoder
//! of sampled comparator states (`signal/quadrature.rs`) existed until issue 11 and was
//! removed: nothing on the readout path called it (only its tests, a resolver test, the `cost`
//! example and a golden-vector case), and sampling the comparators at twice the peak edge rate
//! would have cost about a quarter of the CPU (8.0 instructions per sample measured in QEMU,
//! ~38 M instructions/s). git history keeps it for a board without an encoder timer.

pub mod compensation;
pub mod count;
pub mod fringe;
pub mod lockin;
pub mod output;
pub mod turnaround;
