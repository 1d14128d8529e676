//! The units of the signal chain, defined once.
//!
//! Phase is counted in fringes: one fringe is one period of the beat signal, 2 pi rad of beat
//! phase psi_H, four x4 counts of the encoder, SF arcsec of rotation. Inside the chain phases
//! are fixed point in **Q32 fringes** (2^32 per fringe): a `u32` for a phase within one fringe
//! (so wrapping arithmetic is fringe arithmetic), an `i64` for totals and increments (2^31
//! fringes of range). Radians appear only where the physics needs them (P1/P2, the
//! compensation); deg/h only at the rate output.

/// One fringe (2 pi rad of beat phase) in Q32 fringes: 2^32, as `f64` for conversions.
pub const Q32_PER_FRINGE: f64 = 4_294_967_296.0;
