//! The dither drive: a sans-IO controller that drives the gyro's dither resonator through the
//! DAC, holds its amplitude at a setpoint in arcsec, keeps it at resonance, finds the
//! resonance from a cold start, supervises it, and tells the readout what the dither is doing.
//!
//! DRAFT: the design summary and measured figures follow.

mod amplitude;
mod config;
mod controller;
mod dds;
mod estimate;
mod frequency;
mod measure;
mod noise;
mod startup;
mod supervisor;

#[cfg(test)]
mod tests;

pub use amplitude::{AmplitudeLoop, AmplitudeLoopConfig, PlantGainProbe};
pub use config::DitherConfig;
pub use controller::{CommandError, DitherController, DitherStatus, StartPhase, Tick};
pub use dds::{cos_sin_q31, hz_to_step, step_to_hz, Drive};
pub use estimate::DitherEstimate;
pub use frequency::{reference_shift, FrequencyLoop, FrequencyLoopConfig};
pub use measure::{HalfCycle, SineFit, Window, MAX_WINDOW};
pub use noise::{NoiseDither, MAX_DEPTH_PERCENT};
pub use startup::{Ring, RingListener, StartupConfig};
pub use supervisor::{Backoff, DitherState, FaultCounters, FaultKind, FaultLimits, Run};
