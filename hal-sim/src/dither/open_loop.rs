//! An open-loop drive: a DDS of constant frequency, amplitude and centre, re-stated as a drive
//! segment every half cycle (as a firmware updating twice per cycle hands them over). The
//! simulator's tests, benches and the harness's open-loop mode use it; the firmware's own drive
//! is `crate::drive_loop::FirmwareDrive`.

use super::drive::{DacParams, DriveError, DriveSegment, DriveSink};
use super::linear::ResonatorState;
use super::resonator::ResonatorParams;
use core::f64::consts::TAU;

/// An open-loop DDS: constant frequency, amplitude and centre, with its phase accumulator in
/// Q32 turns as the firmware's would be (exact over any run), re-stated as a new segment every
/// half cycle (where the drive phase passes a chosen boundary phase + k pi), as a firmware
/// that updates twice per cycle would hand them over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenLoopDrive {
    tick_hz: f64,
    phase0_q32: u32,
    step_q32: u32,
    amplitude_v: f64,
    offset_v: f64,
    /// Segment boundaries where the unwrapped DDS phase passes this + k/2, turns in [0, 1/2).
    boundary_turns: f64,
    next: u64,
}

const Q32: f64 = firmware::units::Q32_PER_TURN;

impl OpenLoopDrive {
    /// A DDS at `freq_hz` (rounded to the accumulator's resolution `f_s / 2^32`), amplitude
    /// `amplitude_v` and centre `offset_v` at the DAC output, phase 0 at t = 0, boundaries
    /// where the drive phase is 0 or pi.
    pub fn new(dac: &DacParams, freq_hz: f64, amplitude_v: f64, offset_v: f64) -> Self {
        let step = (freq_hz / dac.tick_hz * Q32).round();
        Self {
            tick_hz: dac.tick_hz,
            phase0_q32: 0,
            step_q32: step.clamp(0.0, Q32 / 2.0 - 1.0) as u32,
            amplitude_v,
            offset_v,
            boundary_turns: 0.0,
            next: 0,
        }
    }

    /// The DDS that holds the steady amplitude `amplitude_arcsec` at `freq_hz` through
    /// `params` (linear: the limit not reached), centred at the amplifier's reference, with
    /// segment boundaries where the dither angle crosses zero (the rate peaks, where a
    /// firmware updating at the pick-off comparator's edges would start its segments).
    pub fn tuned(params: &ResonatorParams, freq_hz: f64, amplitude_arcsec: f64) -> Self {
        let mut d = Self::new(&params.dac, freq_hz, 0.0, params.amplifier.input_ref_v);
        let h = params.dac_to_angle(d.freq_hz(), 0.0);
        d.amplitude_v = amplitude_arcsec / h.abs();
        // theta ~ sin(drive phase + arg h): zero where the drive phase is -arg h (mod pi).
        d.with_boundaries_at_drive_phase(-h.arg())
    }

    /// With the DDS phase at t = 0 set to `phase_rad`.
    pub fn with_phase(mut self, phase_rad: f64) -> Self {
        self.phase0_q32 = (phase_rad.rem_euclid(TAU) / TAU * Q32).round() as u64 as u32;
        self
    }

    /// With segment boundaries where the drive phase passes `phase_rad` (mod pi).
    pub fn with_boundaries_at_drive_phase(mut self, phase_rad: f64) -> Self {
        self.boundary_turns = (phase_rad / TAU).rem_euclid(0.5);
        self
    }

    /// The DDS frequency (after rounding the step), Hz.
    pub fn freq_hz(&self) -> f64 {
        f64::from(self.step_q32) / Q32 * self.tick_hz
    }

    /// The amplitude at the DAC output, V.
    pub fn amplitude_v(&self) -> f64 {
        self.amplitude_v
    }

    /// The DDS phase of tick `n`, rad (exact: Q32 accumulator).
    fn phase_at_tick(&self, n: u64) -> f64 {
        let acc = (u128::from(self.phase0_q32) + u128::from(n) * u128::from(self.step_q32))
            % (1u128 << 32);
        acc as f64 / Q32 * TAU
    }

    /// First tick at which the unwrapped phase reaches boundary `j` (may be <= 0).
    fn boundary_tick(&self, j: u64) -> f64 {
        let target = (self.boundary_turns + 0.5 * j as f64) * Q32 - f64::from(self.phase0_q32);
        (target / f64::from(self.step_q32)).ceil()
    }

    /// Start tick of segment `k`: 0 for the first, then the boundaries after tick 0.
    fn start_tick(&self, k: u64) -> u64 {
        if k == 0 {
            return 0;
        }
        if self.step_q32 == 0 {
            // A constant drive has no half cycles: one segment per second.
            return k * self.tick_hz.round() as u64;
        }
        let skip = (0..3).find(|&j| self.boundary_tick(j) >= 1.0).unwrap_or(3);
        self.boundary_tick(skip + k - 1) as u64
    }

    /// Segment `k` (the first starts at t = 0).
    pub fn segment(&self, k: u64) -> DriveSegment {
        let n = self.start_tick(k);
        DriveSegment {
            start_s: n as f64 / self.tick_hz,
            phase_rad: self.phase_at_tick(n),
            step_rad: f64::from(self.step_q32) / Q32 * TAU,
            amplitude_v: self.amplitude_v,
            offset_v: self.offset_v,
        }
    }

    /// The next segment not yet handed out.
    pub fn next_segment(&mut self) -> DriveSegment {
        let s = self.segment(self.next);
        self.next += 1;
        s
    }

    /// Pushes segments into `sink` until its drive is known at least until `until_s`.
    pub fn keep_ahead(
        &mut self,
        sink: &mut impl DriveSink,
        until_s: f64,
    ) -> Result<(), DriveError> {
        while sink.drive_known_until_s() < until_s {
            sink.push_drive(self.next_segment())?;
        }
        Ok(())
    }

    /// The steady state of this drive through `params` at t = 0: start a resonator there and
    /// it has no transient.
    pub fn steady_state(&self, params: &ResonatorParams) -> ResonatorState {
        params.steady_state(&self.segment(0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    #[test]
    fn open_loop_segments_are_half_cycles_with_a_continuous_phase() {
        let dac = DacParams::default();
        let d = OpenLoopDrive::new(&dac, 389.0, 0.4, 1.65).with_boundaries_at_drive_phase(1.0);
        assert!((d.freq_hz() - 389.0).abs() < 1e-5);
        let s0 = d.segment(0);
        assert_eq!(s0.start_s, 0.0);
        for k in 1..2000 {
            let (a, b) = (d.segment(k), d.segment(k + 1));
            let ticks = (b.start_s - a.start_s) * dac.tick_hz;
            // Half a cycle is 0.5 f_s / 389 Hz ticks (51.4 at 40 kHz): the whole ticks around it.
            let half = 0.5 * dac.tick_hz / 389.0;
            assert!(
                (ticks - half.floor()).abs() < 1e-6 || (ticks - half.ceil()).abs() < 1e-6,
                "{ticks}"
            );
            // The phase continues the accumulator across the boundary.
            let expect = (a.phase_rad + ticks.round() * a.step_rad).rem_euclid(TAU);
            let diff = (b.phase_rad - expect).rem_euclid(TAU);
            assert!(diff.min(TAU - diff) < 1e-9, "{k}");
            // The boundary is the first tick past the boundary phase (1 rad + k pi).
            let past = (b.phase_rad - 1.0).rem_euclid(PI);
            assert!(past < b.step_rad + 1e-12, "{past}");
        }
    }
}
