//! The dither as the loop knows it, once per half cycle: the record the readout can use for
//! psi_ddot = A w^2 and the turnaround instants (docs/physics.md sections 5 and 10, pitfall 2),
//! from the drive's own phase and the pick-off fit, never from a simulator's truth.
//!
//! The dither angle is modelled over the half cycle as `A cos(w (t - t_k) + angle_phase)` with
//! t_k the instant of drive tick `tick`: `angle_phase` 0 is the angle's maximum (a "-"
//! turnaround when the beat phase grows with the angle), a half turn its minimum ("+").
//! `valid` is false unless the controller is locked: every record of a start-up or a fault is
//! marked invalid.

use crate::units::{Phase, Q32_PER_FRINGE};

/// One half cycle's estimate of the dither.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DitherEstimate {
    /// The drive tick the estimate refers to (the half cycle's last sample).
    pub tick: u32,
    /// Peak amplitude over the half cycle, arcsec.
    pub amplitude_arcsec: f32,
    /// The dither frequency (the drive's, locked to the resonance), Hz.
    pub frequency_hz: f32,
    /// The angle's phase at `tick`, Q32 turns (0: the maximum).
    pub angle_phase: Phase,
    /// The controller was locked: the estimate may be used.
    pub valid: bool,
}

impl DitherEstimate {
    /// w = 2 pi f, rad/s.
    pub fn angular_frequency_rad_s(&self) -> f64 {
        core::f64::consts::TAU * self.frequency_hz as f64
    }

    /// |psi_ddot| at a turnaround, rad/s^2 of beat phase: A w^2 with A = 2 pi amplitude / SF
    /// (docs/physics.md section 5), for a scale factor of `scale_factor_arcsec` per fringe.
    pub fn psi_ddot_rad_per_s2(&self, scale_factor_arcsec: f64) -> f64 {
        let a_rad = core::f64::consts::TAU * self.amplitude_arcsec as f64 / scale_factor_arcsec;
        let w = self.angular_frequency_rad_s();
        a_rad * w * w
    }

    /// Seconds from `tick` to the next instant where the angle's phase is `target` (0: the
    /// next maximum, a half turn: the next minimum), in (0, 1 period].
    pub fn seconds_to(&self, target: Phase) -> f64 {
        let ahead = (target - self.angle_phase).to_bits();
        let turns = if ahead == 0 {
            1.0
        } else {
            ahead as f64 / Q32_PER_FRINGE
        };
        turns / self.frequency_hz as f64
    }

    /// Seconds from `tick` to the next maximum of the angle.
    pub fn seconds_to_next_maximum(&self) -> f64 {
        self.seconds_to(Phase::ZERO)
    }

    /// Seconds from `tick` to the next minimum of the angle.
    pub fn seconds_to_next_minimum(&self) -> f64 {
        self.seconds_to(Phase::HALF_TURN)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psi_ddot_and_turnaround_times() {
        let e = DitherEstimate {
            tick: 0,
            amplitude_arcsec: 450.0,
            frequency_hz: 389.0,
            angle_phase: Phase::QUARTER_TURN,
            valid: true,
        };
        // docs/physics.md's set: 9.05e9 rad/s^2.
        assert!((e.psi_ddot_rad_per_s2(1.8655) / 9.054e9 - 1.0).abs() < 1e-3);
        let period = 1.0 / 389.0;
        assert!((e.seconds_to_next_minimum() - 0.25 * period).abs() < 1e-9);
        assert!((e.seconds_to_next_maximum() - 0.75 * period).abs() < 1e-9);
        let at_max = DitherEstimate {
            angle_phase: Phase::ZERO,
            ..e
        };
        assert!((at_max.seconds_to_next_maximum() - period).abs() < 1e-9);
    }
}
