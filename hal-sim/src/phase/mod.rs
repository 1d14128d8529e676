//! The phase equation (docs/physics.md Eq. 6) integrated fast and verifiably.
//!
//! ```text
//! dpsi/dt = omega(t) + Omega_L cos(psi),   omega = input + dither + noise rate
//! ```
//!
//! Brute force cannot be fast: the beat phase travels ~2.4e6 rad per gyro-second at the
//! docs/physics.md set, and a solver must advance well under 2 pi per step. The method here
//! splits `psi = theta(t) + phi`, with `theta` the lock-in-free phase known in closed form
//! ([`free_phase`]), so only the lock-in phase `phi` is integrated:
//! `dphi/dt = Omega_L cos(theta + phi)`. `phi` changes substantively only near the
//! turnarounds, where `omega` crosses zero.
//!
//! - [`plan`] splits time, from `omega(t)` alone, into *near* segments (|omega| small, around
//!   each turnaround; default |omega| < 5e5 rad/s, +-55 us) and *far* segments, and finds the
//!   turnarounds by Newton to the last bit.
//! - [`near`]: 5-stage Gauss-Legendre collocation (order 10) on `phi` with `theta` from a
//!   local Taylor polynomial; the step limits the beat-phase advance to `dtheta` = 2 rad.
//! - [`far`]: no stepping; a near-identity transformation `phi = chi + W(t, psi)` removes the
//!   fringe-rate oscillation to 8th order in `Omega_L/omega` and `omega'/omega^2`, and the
//!   slow `chi` drifts by `-Omega_L^2/(2 omega) + ...`, integrated by a 10-node Gauss rule
//!   in `ln|t - t_zero|` (dense output anywhere in the segment from the same nodes).
//! - [`integrator`] walks the timeline and reports turnarounds and per-traversal errors;
//!   [`reference`](mod@reference) is the brute-force RK4 the tests hold it against; [`theory`]
//!   has the closed forms (Eq. 5, the stationary-phase traversal error; Chow's J0 band is the
//!   firmware's).
//!
//! Measured (tests `theory_convergence`, bench `phase`): per-traversal error 1.3e-8 rad at
//! the defaults against the converged reference, order >= 10 under step halving; the speed
//! is in docs/results.md (`cargo bench -p hal-sim --bench phase`, `rlg-sim speed`).
//!
//! Where the time goes (callgrind, the docs/physics.md set at 13.888 deg/h: 54 M
//! instructions per gyro-second, 69 k per half cycle; 57 M before the far series' short
//! runs): the near steps 42 % (21 steps of
//! five stages per traversal, ~3.6 fixed-point sweeps each, the sweeps after the first by
//! angle addition), the far series at both ends of every far segment 19 % (all 8 orders at
//! a boundary), the planner's ~40 rate evaluations per half cycle 18 % (a 32-per-cycle probe
//! grid, Newton at the turnaround, the two boundaries), the drift's 20 evaluations 13 %, the
//! near polynomials 5 %. The far series is at its optimal truncation for the near/far
//! boundary (`delta_max` 0.04: a wider far region needs more orders than it saves steps), so
//! a further factor needs a different decomposition, not tuning.
//!
//! The simulated board (`rlg-sim speed --board`: closed-loop drive, scheduled latches,
//! firmware in the loop) costs 183 M instructions per gyro-second, 3.4 times the bare gyro:
//! self time in this module 101 M (the integrator with the driven dither's jets, and ~13 k
//! dense `psi` queries per second for the photodiode ADC stream at 12 345 Hz and the 1 kHz
//! sync, each a far-series evaluation; 209 M in all before the series' short runs, see
//! [`far::oscillation_with_means`]), the driven dither's closed form 20 M (pick-off samples at every drive tick and ~20 per
//! pick-off edge search), the firmware's own code 6.5 M, libm and the rest 55 M. Issue 14's
//! 250 gyro-s per wall-s would be ~30 M instructions per gyro-second on this machine: the
//! phase solver alone, at the accuracy the theory tests hold, is twice that for the bare
//! gyro and three times it in the board; no single part is more than a third of the total.
pub mod far;
pub mod free_phase;
pub mod gauss;
pub mod integrator;
pub mod near;
pub mod plan;
pub mod reference;
pub mod theory;
