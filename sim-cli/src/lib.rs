//! The simulator's experiments with the firmware's signal chain in the loop, and their reports.
//!
//! Used by the `rlg-sim` CLI and by the workspace's system tests (`tests/`), so that the tests
//! check exactly what the CLI prints.

#![warn(missing_docs)]

pub mod allan;
pub mod characterize;
pub mod dither_run;
pub mod experiment;
pub mod record_run;
pub mod report;
pub mod thermal;
