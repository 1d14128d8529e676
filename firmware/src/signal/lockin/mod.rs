//! Stage 4, the lock-in terms: P1/P2 per turnaround, and the dither cycles they are summed over.
//!
//! | file | what | rate |
//! |---|---|---|
//! | `terms.rs` | [`traversal_terms`]: one traversal's share of (P1, P2) from the normalised levels and k | per turnaround |
//! | `cycle.rs` | [`CycleAssembler`]: cycles closing at "+", their increment between 1-2-1 averages of the latched phases (a wandering dither cancels), the latch split, k from the measured dither; the [`CycleRecord`] it closes with its [`CycleFlags`] | per turnaround, a record per cycle |
//!
//! The record leaves the assembler uncompensated (increment = raw increment, correction 0);
//! stage 5 (`super::compensation`) subtracts a P1 + b P2.

mod cycle;
mod terms;

#[cfg(test)]
pub(crate) use cycle::synthetic;

pub use cycle::{
    CycleAssembler, CycleConfig, CycleFlags, CycleOutput, CycleRecord, TurnaroundReading,
};
pub use terms::{
    sine_dither_accel_rad_per_s2, traversal_terms, traversal_time_s, LevelPair, LockinTerms,
};
