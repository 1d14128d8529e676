//! The dither drive (issue 12): a sans-IO controller that drives the gyro's dither resonator
//! through the DAC, holds its amplitude at a setpoint in arcsec, keeps the drive at resonance
//! as f0 drifts, finds the resonance from a cold start, supervises the oscillation, and tells
//! the readout what the dither is doing. The board calls it once per drive tick from the TIM4
//! interrupt (`board::dither`); a simulator calls the same [`DitherController::on_tick`] with
//! its own pick-off codes and turns [`DitherController::drive`] into its drive.
//!
//! # The interface
//! - [`DitherConfig`] (immutable, [`DitherConfig::for_profile`]) apart from the state,
//!   [`DitherController`] (`new(&config)`);
//! - `on_tick(&mut self, &DitherConfig, pickoff_code: AdcCode) -> Tick`: the pick-off ADC code
//!   sampled at drive tick k in ([`DitherController::tick`] is k), the DAC code of tick k + 1
//!   out, with `drive_changed` (the code is the first sample of a new [`Drive`]) and
//!   `half_cycle` (a new [`DitherEstimate`]);
//! - `drive(&self) -> Drive`: `dac(n) = mid + round(amplitude * sin(phase + n * step))` from
//!   tick `start_tick`, computed bit-exactly by [`Drive::dac_code`]; it changes only at a loop
//!   update, once per half cycle, at the drive's peaks (at resonance the pick-off's zero
//!   crossings, the dither's rate peaks), or when the drive goes off (disable, a fault);
//! - commands `enable`, `disable`, `restart`, `set_setpoint_arcsec` and
//!   `set_noise_depth_percent` (range-checked: an error changes nothing), `set_noise_seed`;
//!   they take effect at the next tick (or half cycle), never between ticks;
//! - `status(&self, &DitherConfig) -> DitherStatus`: state (`Off`, `Starting`, `Locked`,
//!   `Fault(kind)`), amplitude, frequency, drive level, phase error, plant gain, fault counters,
//!   back-off;
//! - `estimate(&self) -> DitherEstimate`: the dither as the loop knows it, per half cycle
//!   (amplitude, frequency, the angle's phase at a tick; psi_ddot and the turnaround instants
//!   from them), `valid` only while locked (item 9: never the simulator's truth).
//!
//! # The tick rate: 40 kHz = 84 MHz / 2100
//! Derived exactly from the 84 MHz timer clock (`BoardProfile::drive_tick_hz`). It gives 64-143
//! samples per dither period over the 280-620 Hz search range (every half-cycle fit has at
//! least 32), puts the DAC's first image at f_s - f >= 39.4 kHz (attenuated by the resonator's
//! (f / f0)^2, over 80 dB, and the drive's own filtering), makes the zero-order hold's delay
//! half a tick (1.75 degrees at 389 Hz, compensated in the phase detector), and costs 10.8 %
//! of the CPU (below). 20 kHz would halve the cost and still work (fits of 16 samples at
//! 620 Hz); 50 kHz would add cost and nothing the loops need.
//!
//! # How it works (one file per part, in the order a sample meets them)
//! | file | part |
//! |---|---|
//! | `dds` | phase accumulator ([`crate::units::Phase`], Q32 turns) and `cossin` (`crate::math::cossin`: idsp's, its table in RAM) -> [`Drive`], the DAC code |
//! | `measure` | the half-cycle window: least-squares fit of offset + cos + sin of the drive's phase (exact for any window length), extremes, rail count |
//! | `frequency` | PI (`idsp` clamped biquad) from the pick-off's phase lag (90 degrees at resonance) to the DDS step, clamped to the search range |
//! | `amplitude` | PI (`idsp` clamped biquad) from the amplitude to the drive, gain normalised by the measured plant gain, clamped at the drive limit (guard and anti-windup) |
//! | `startup` | listen (time a ring by its zero crossings), sweep (300 Hz/s, which rings any Q up at f0), ring-up, lock criteria |
//! | `supervisor` | states, faults, limits, counters, back-off |
//! | `self_test` | the power-up check that the pick-off answers the drive: a sweep at a low drive |
//! | `noise` | random-noise dither: the drive's amplitude times 1 + depth r every half cycle (seeded xorshift32) |
//! | `estimate` | the per-half-cycle [`DitherEstimate`] for the readout |
//! | `controller` | [`DitherController`]: the tick, the half-cycle update, the commands, the status |
//! | `coast` | [`Coast`]: the drive tick without the controller (a flash stall): the drive in force continued, the gap handed over |
//! | `config` | [`DitherConfig`] assembled from the parts' settings |
//!
//! Trade-offs: the fit costs five more 64-bit accumulations per tick than a plain lock-in sum
//! but removes its 1-3 % leakage and the alternating offset error (`measure`); the amplitude
//! loop measures its plant gain at every start instead of trusting a constant, because the
//! drive's efficiency is the gyro's, not the board's, and a PI tuned for the wrong gain either
//! crawls or overshoots (`amplitude`); the start-up sweeps fast and listens instead of
//! sweeping slowly, which would take minutes at Q = 5000 (`startup`).
//!
//! # idsp: what is used, what not (measured)
//! - **`cossin`** for the DDS and the demodulation's regressors (one call per tick serves
//!   both; the firmware's bit-identical copy, `crate::math::cossin`, whose table is in RAM so
//!   the drive tick can run while the flash stalls): 47 Cortex-M4 instructions; the drive's harmonics (2..10) are at -114 dBc, set by
//!   the DAC's 12-bit rounding, not by cossin's -120 dBc spurs (`dds` tests).
//! - **`iir::BiquadClamp`** (`Q32<30>` coefficients, `DirectForm1Wide` state) for both PI
//!   loops: its clamp is the anti-windup and the drive guard; 82 (frequency) and 99
//!   (amplitude) instructions per half cycle. A hand-written PI would save a few dozen
//!   instructions per half cycle (under 0.02 % of the CPU): not worth a second PI.
//! - **`atan2`** for the phase detector: 122 instructions and 1.3e-6 rad, against 347 and
//!   7.6e-9 rad for the readout's CORDIC (`crate::math`); the loop needs far less than the
//!   0.08 rad that is 0.015 Hz at Q = 1000, so idsp's is the right one here.
//! - not **`Accu`**: the project's [`crate::units::Phase`] is the phase type, and its wrapping
//!   `+` is the same single add.
//! - not **`PLL`/`RPLL`**: they lock to an input signal's own phase; the pick-off follows the
//!   drive, so a PLL on it locks to the drive wherever the resonance is. The resonance
//!   condition is a phase difference that the resonator itself integrates (`frequency`).
//!
//! # Measured (host tests on a test model of the resonator, `tests`; QEMU `-icount`)
//! - demodulator (`measure` tests, 2000 random half cycles, 280-620 Hz, 1125-code amplitude,
//!   offsets to +-40 codes): amplitude 0.12 code rms (1e-4), phase 1e-4 rad rms; with 1 code
//!   rms of noise 0.40 code and 3.6e-4 rad;
//! - from rest at 389 Hz: within 1 % in 0.84 s (Q = 1000) and 0.76 s (Q = 5000), 0.05 %
//!   overshoot (the drive limited to the DAC's linear range: [`drive_limit_codes`]);
//!   cold starts at 300 and 600 Hz lock in 1.54 and 1.60 s (locking waits for the amplitude
//!   to hold within 0.2 % for 256 half cycles: the hand-over to the slow locked loop);
//! - f0 drifting 0.5 Hz in 60 s: amplitude 0.0072 % rms off the setpoint, drive within
//!   0.0012 Hz of the resonance (the locked amplitude loop's 0.25 Hz crossover trades tracking
//!   for quiet: `config::LOCKED_AMPLITUDE_CROSSOVER_HZ`);
//! - faults, from the injection (slowest of four injection instants a quarter period apart):
//!   pick-off lost 0.81, saturated 0.55, no oscillation 0.81, amplitude out of range 1.06
//!   periods; drive saturated 2.50 periods after the loop reached its limit; the drive off at
//!   the next tick each time;
//! - the drive's changes while locked fall within two ticks of the angle's zero crossings;
//! - estimate while locked: amplitude within 4.3e-4, the angle's phase within 1.8e-4 rad;
//! - noise dither at 30 %: the mean amplitude within 0.003 % of the setpoint, 0.09 arcsec of
//!   change per half cycle (0.3 rad of turnaround phase at 1.8655 arcsec per fringe);
//! - cost (`examples/dither_cost.rs`): 232 instructions per tick, 1221 at a half cycle (1243
//!   with the noise dither; the amplifier-lag compensation's `atanf` included), plus 18 for the handler's registers: 10.8 % of the CPU at
//!   168 MHz (docs/board.md has the total with the readout).

mod amplitude;
mod coast;
mod config;
mod controller;
mod dds;
mod estimate;
mod frequency;
mod measure;
mod noise;
mod self_test;
mod startup;
mod supervisor;

#[cfg(test)]
mod tests;

/// The dither amplitude the fringe count measured over `record`'s cycle, arcsec of body angle
/// (beat-phase rad x scale factor / 2 pi): what [`DitherController::check_count_amplitude`]
/// takes, on the board (`board::app`) and the simulated board alike.
pub fn count_amplitude_arcsec(
    record: &crate::signal::lockin::CycleRecord,
    scale_factor_arcsec: f32,
) -> f32 {
    record.dither_amplitude_rad * scale_factor_arcsec / core::f32::consts::TAU
}

pub use amplitude::{AmplitudeLoop, AmplitudeLoopConfig, PlantGainProbe};
pub use coast::Coast;
pub use config::{drive_limit_codes, DitherConfig};
pub use controller::{CommandError, DitherController, DitherStatus, StartPhase, Tick};
pub use dds::{cos_sin_q31, hz_to_step, step_to_hz, Drive};
pub use estimate::DitherEstimate;
pub use frequency::{phase_in, reference_shift, FrequencyLoop, FrequencyLoopConfig};
pub use measure::{HalfCycle, SineFit, Window, MAX_WINDOW};
pub use noise::{NoiseDither, MAX_DEPTH_PERCENT};
pub use self_test::{PickoffCheck, PickoffFailure, SELF_TEST_DRIVE_FRACTION};
pub use startup::{Ring, RingListener, StartupConfig};
pub use supervisor::{Backoff, DitherState, FaultCounters, FaultKind, FaultLimits, Run};
