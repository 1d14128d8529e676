//! The phase equation (PHYSICS.md Eq. 6) integrated fast and verifiably.
pub mod far;
pub mod free_phase;
pub mod near;
pub mod reference;
pub mod plan;
pub mod integrator;
