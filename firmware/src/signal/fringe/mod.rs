//! Stage 3, the fringe: photodiode normalisation from the signal itself (a Heydemann ellipse
//! fit of the Lissajous figure), the fractional fringe, and the total beat phase (count plus
//! fraction).
//!
//! Two inputs arrive at different rates:
//!
//! - the free-running photodiode ADC stream (pairs at arbitrary instants, DMA blocks on the
//!   board) feeds the fit, which learns the channels' offsets, gains and quadrature error;
//! - each turnaround latch (`crate::sample::TurnaroundSample`: both ADC codes, and the x4 count
//!   extended by stage 1, `super::count`) is normalised with the coefficients in use to
//!   (cos psi_H, sin psi_H), whose CORDIC angle (`crate::math::atan2_q32`) is the fractional
//!   fringe; the count decides the whole fringes.
//!
//! | file | what | rate |
//! |---|---|---|
//! | `moments.rs` | [`LissajousAccumulator`]: exact integer moment sums of a window | per ADC pair |
//! | `ellipse.rs` | [`fit_window`]: conic -> ellipse -> [`LissajousCoefficients`]; [`LissajousConfig`], [`FitRejection`] | per window (4096 pairs) |
//! | `tracker.rs` | [`LissajousTracker`]: windows one after another, the last good fit kept | per ADC pair |
//! | `levels.rs` | [`LissajousCoefficients::normalise`]: codes -> [`NormalisedLevels`] (Q30) | per turnaround |
//! | `convention.rs` | [`FringeConvention`]: the board's channel and count wiring undone | per turnaround |
//! | `resolver.rs` | [`FringeResolver`]: count + fractional fringe -> [`FringePhase`], glitches flagged | per turnaround |
//!
//! Imports run one way inside the stage too: `levels` <- `moments` <- `ellipse` <- `tracker`;
//! `levels` <- `convention` <- `resolver`.

mod convention;
mod ellipse;
mod levels;
mod moments;
mod resolver;
#[cfg(test)]
mod synthetic;
mod tracker;

pub use convention::FringeConvention;
pub use ellipse::{
    fit_window, Ellipse, FitRejection, LissajousConfig, MAX_QUADRATURE_ERROR_Q32, MIN_RADIUS_CODES,
    MIN_SPAN_OF_DIAMETER_Q8,
};
pub use levels::{LissajousCoefficients, NormalisedLevels, ORIGIN_CODE};
pub use moments::{LissajousAccumulator, MAX_WINDOW_SAMPLES};
pub use resolver::{
    FringePhase, FringePhaseConfig, FringeReading, FringeResolver, GLITCH_DISAGREEMENT_Q32,
};
pub use tracker::LissajousTracker;
