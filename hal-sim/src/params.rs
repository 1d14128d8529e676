//! The gyro's parameter set: physical constants in the units an engineer quotes, plus the
//! solver settings, with the docs/physics.md set as [`GyroParams::DEFAULT`] (its scale factor
//! and nominal dither read from the board profile, the one place those facts are written).
//!
//! Design: [`GyroParams`] is plain, `Copy` and immutable once a gyro is built (what would live
//! in a data sheet); [`GyroParams::derive`] validates it and converts everything once into the
//! beat-phase units the integrator uses ([`Derived`], rad and rad/s of beat phase). Mutable
//! state lives elsewhere ([`crate::gyro::Gyro`]).

use crate::dither::open_loop::OpenLoopDrive;
use crate::dither::resonator::ResonatorParams;
use crate::dither::DitherSpec;
pub use crate::dither::{AmplitudeModulation, DitherModel};
use crate::param_error::ParamError;
use crate::thermal::GyroThermal;
use crate::units::{
    arcsec_to_beat_rad, arw_deg_per_rt_h_to_beat_rad_per_rt_s, deg_per_h_to_beat_rad_per_s,
    hz_to_rad_per_s,
};
use firmware::profile::BoardProfile;

/// Settings of the integrator (see [`crate::phase`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverParams {
    /// Largest beat-phase advance per step in near regions, rad (Gauss-Legendre, order 10;
    /// 2 gives 1.3e-8 rad per traversal at the docs/physics.md set, 4 gives 2e-4). The step
    /// is `h = dtheta / (sqrt(omega^2 + |omega'| 1 rad) + Omega_L)`.
    pub step_phase_rad: f64,
    /// Lock-in-free rate above which the far-field expansion replaces stepping, rad/s. A floor:
    /// the gyro uses at least 500 Omega_L (the far series runs in Omega_L / omega), see
    /// [`SolverParams::effective`].
    pub far_threshold_rad_per_s: f64,
    /// Largest adiabatic parameter |omega'|/omega^2 accepted in the far region.
    pub far_max_adiabatic: f64,
    /// Length of a smooth piece (and of a noise segment) when there is no dither, s.
    pub max_piece_s: f64,
}

impl SolverParams {
    /// The settings the integrator runs with for a lock-in of `omega_l_rad_per_s`: the far
    /// threshold raised to 500 Omega_L where the configured one is lower (a strong lock-in
    /// gets a wider near region instead of a far series that would not converge).
    pub fn effective(&self, omega_l_rad_per_s: f64) -> Self {
        Self {
            far_threshold_rad_per_s: self.far_threshold_rad_per_s.max(500.0 * omega_l_rad_per_s),
            ..*self
        }
    }
}

impl SolverParams {
    /// Order-10 steps of 2 rad, far series from 5e5 rad/s, 1 ms pieces.
    pub const DEFAULT: Self = Self {
        step_phase_rad: 2.0,
        far_threshold_rad_per_s: 5.0e5,
        far_max_adiabatic: 0.04,
        max_piece_s: 1.0e-3,
    };
}

impl Default for SolverParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The gyro's parameters in engineering units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroParams {
    /// Scale factor, arcsec of body angle per fringe (counter pulse).
    pub scale_factor_arcsec: f64,
    /// Dither frequency, Hz (the driven dither: its nominal frequency, see [`DitherModel`]).
    pub dither_hz: f64,
    /// Peak dither amplitude, arcsec of body angle (0 = no dither; the driven dither: its
    /// nominal amplitude, what [`GyroParams::open_loop_drive`] aims at).
    pub dither_amplitude_arcsec: f64,
    /// Lock-in threshold Omega_L, deg/h.
    pub lock_in_deg_per_h: f64,
    /// Photodiode phase offset eps (psi_H = psi - eps), rad.
    pub eps_rad: f64,
    /// Angle random walk, deg/sqrt(h) (0 = no noise).
    pub arw_deg_per_rt_h: f64,
    /// Slow amplitude jitter: of the prescribed sine's amplitude, or for the driven resonator
    /// of its drive's gain (the amplifier's and the piezo's drift, which the firmware's
    /// amplitude loop must hold the amplitude against: what remains is what a real loop
    /// leaves).
    pub amplitude_jitter: AmplitudeModulation,
    /// Random-noise dither (a large deliberate amplitude modulation); adds to the jitter (the
    /// prescribed sine only).
    pub random_noise_dither: AmplitudeModulation,
    /// Seed of every random process (noise, jitter tones).
    pub seed: u64,
    /// Beat phase at t = 0, rad.
    pub initial_psi_rad: f64,
    /// Linear drift of the lock-in threshold (backscatter changing with temperature), relative
    /// per second, from t = 0 until `lock_in_drift_until_s`: Omega_L(t) = Omega_L (1 + r t).
    /// Applied per integration segment (at most ~1.3 ms long), so a drift must be slow: well
    /// below 1e-3 relative per segment.
    pub lock_in_drift_per_s: f64,
    /// End of the lock-in drift, s: Omega_L keeps the value reached then.
    pub lock_in_drift_until_s: f64,
    /// Integrator settings.
    pub solver: SolverParams,
    /// The dither model: the prescribed sine (default) or the driven resonator.
    pub dither_model: DitherModel,
    /// The block's temperature and what it does to the gyro ([`crate::thermal`]; by default
    /// 25 °C throughout, the coefficients' reference: no effect).
    pub thermal: GyroThermal,
}

impl GyroParams {
    /// The docs/physics.md parameter set, noise and jitter off: the gyro the board is built
    /// for, so its scale factor and nominal dither are the board profile's
    /// ([`BoardProfile::F405`]); the lock-in and eps are this model's alone. `rlg-sim`'s flags
    /// default to these values.
    pub const DEFAULT: Self = Self {
        scale_factor_arcsec: BoardProfile::F405.scale_factor_arcsec,
        dither_hz: BoardProfile::F405.nominal_dither_hz,
        dither_amplitude_arcsec: BoardProfile::F405.nominal_dither_amplitude_arcsec,
        lock_in_deg_per_h: 200.0,
        eps_rad: 0.3,
        arw_deg_per_rt_h: 0.0,
        amplitude_jitter: AmplitudeModulation::OFF,
        random_noise_dither: AmplitudeModulation::OFF,
        seed: 1,
        initial_psi_rad: 0.0,
        lock_in_drift_per_s: 0.0,
        lock_in_drift_until_s: 0.0,
        solver: SolverParams::DEFAULT,
        dither_model: DitherModel::Ideal,
        thermal: GyroThermal::DEFAULT,
    };
}

impl Default for GyroParams {
    /// [`GyroParams::DEFAULT`].
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Parameters converted to beat-phase units (rad, rad/s), validated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Derived {
    /// Scale factor, arcsec/pulse (kept for conversions of the input).
    pub scale_factor_arcsec: f64,
    /// Lock-in threshold Omega_L, rad/s of beat phase.
    pub omega_l_rad_per_s: f64,
    /// Dither angular frequency w_d, rad/s (0 without dither).
    pub dither_w_rad_per_s: f64,
    /// Dither amplitude Omega_d / w_d, rad of beat phase.
    pub dither_amp_rad: f64,
    /// Peak dither rate Omega_d, rad/s of beat phase.
    pub dither_peak_rad_per_s: f64,
    /// Angle random walk, rad of beat phase per sqrt(s).
    pub arw_rad_per_rt_s: f64,
}

fn check(ok: bool, what: &'static str) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError::OutOfRange(what))
    }
}

fn check_modulation(m: &AmplitudeModulation, what: &'static str) -> Result<(), ParamError> {
    if !m.is_on() {
        return check(m.relative_rms == 0.0, what);
    }
    check(m.relative_rms.is_finite() && m.relative_rms < 0.3, what)?;
    check(m.tones >= 1 && m.tones <= 64, what)?;
    check(
        m.min_hz > 0.0 && m.max_hz >= m.min_hz && m.max_hz.is_finite(),
        what,
    )
}

impl GyroParams {
    /// True if the dither is on: the prescribed sine with nonzero amplitude and frequency, or
    /// the driven resonator (even at rest: it is there to be driven).
    pub fn has_dither(&self) -> bool {
        match self.dither_model {
            DitherModel::Ideal => self.dither_amplitude_arcsec > 0.0 && self.dither_hz > 0.0,
            DitherModel::Driven(_) => self.dither_hz > 0.0,
        }
    }

    /// What the gyro's dither is made from, in the dither's own terms (`crate::dither`).
    pub fn dither_spec(&self, derived: &Derived) -> DitherSpec {
        DitherSpec {
            model: self.dither_model,
            on: self.has_dither(),
            hz: self.dither_hz,
            w_rad_per_s: derived.dither_w_rad_per_s,
            amp_rad: derived.dither_amp_rad,
            scale_factor_arcsec: derived.scale_factor_arcsec,
            jitter: self.amplitude_jitter,
            noise: self.random_noise_dither,
            seed: self.seed,
        }
    }

    /// The driven resonator's parameters, if that is the model.
    pub fn resonator(&self) -> Option<&ResonatorParams> {
        match &self.dither_model {
            DitherModel::Ideal => None,
            DitherModel::Driven(r) => Some(r),
        }
    }

    /// The open-loop drive that holds `dither_amplitude_arcsec` at `dither_hz` in steady state
    /// (segments every half cycle, starting at the rate peaks); `None` for the prescribed sine.
    pub fn open_loop_drive(&self) -> Option<OpenLoopDrive> {
        self.resonator()
            .map(|r| OpenLoopDrive::tuned(r, self.dither_hz, self.dither_amplitude_arcsec))
    }

    /// This gyro with the driven resonator `resonator`, started in the steady state of
    /// [`Self::open_loop_drive`] (push that drive and the dither is a steady sine of
    /// `dither_amplitude_arcsec` at `dither_hz` from t = 0).
    pub fn with_steady_driven_dither(self, resonator: ResonatorParams) -> Self {
        let driven = Self {
            dither_model: DitherModel::Driven(resonator),
            ..self
        };
        let initial = driven
            .open_loop_drive()
            .expect("driven")
            .steady_state(&resonator);
        Self {
            dither_model: DitherModel::Driven(ResonatorParams {
                initial,
                ..resonator
            }),
            ..self
        }
    }

    /// This gyro with its block at `profile`; a driven resonator's f0 and Q follow the same
    /// profile (its own coefficients).
    pub fn with_temperature(
        mut self,
        profile: crate::dither::resonator::TemperatureProfile,
    ) -> Self {
        self.thermal.profile = profile;
        if let DitherModel::Driven(r) = &mut self.dither_model {
            r.temperature.profile = profile;
        }
        self
    }

    /// Validates and converts to beat-phase units.
    pub fn derive(&self) -> Result<Derived, ParamError> {
        let sf = self.scale_factor_arcsec;
        check(
            sf.is_finite() && sf > 0.0,
            "scale_factor_arcsec must be > 0",
        )?;
        check(
            self.dither_hz.is_finite() && self.dither_hz >= 0.0 && self.dither_hz < 1.0e5,
            "dither_hz must be in [0, 1e5)",
        )?;
        check(
            self.dither_amplitude_arcsec.is_finite() && self.dither_amplitude_arcsec >= 0.0,
            "dither_amplitude_arcsec must be >= 0",
        )?;
        check(
            self.lock_in_deg_per_h.is_finite() && self.lock_in_deg_per_h >= 0.0,
            "lock_in_deg_per_h must be >= 0",
        )?;
        check(self.eps_rad.is_finite(), "eps_rad must be finite")?;
        check(
            self.initial_psi_rad.is_finite(),
            "initial_psi_rad must be finite",
        )?;
        check(
            self.arw_deg_per_rt_h.is_finite() && self.arw_deg_per_rt_h >= 0.0,
            "arw_deg_per_rt_h must be >= 0",
        )?;
        check_modulation(
            &self.amplitude_jitter,
            "amplitude_jitter: rms in [0, 0.3), 1..64 tones, 0 < min_hz <= max_hz",
        )?;
        check_modulation(
            &self.random_noise_dither,
            "random_noise_dither: rms in [0, 0.3), 1..64 tones, 0 < min_hz <= max_hz",
        )?;
        self.thermal.coefficients.validate()?;
        if let DitherModel::Driven(r) = &self.dither_model {
            r.validate()?;
            check(
                self.dither_hz > 0.0
                    && r.f0_hz >= self.dither_hz / 4.0
                    && r.f0_hz <= 4.0 * self.dither_hz,
                "driven dither: dither_hz (nominal) must be > 0 and within a factor 4 of f0",
            )?;
        }
        let s = &self.solver;
        check(
            s.step_phase_rad > 0.0 && s.step_phase_rad <= 4.0,
            "solver.step_phase_rad must be in (0, 4]",
        )?;
        check(
            s.far_max_adiabatic > 0.0 && s.far_max_adiabatic <= 0.05,
            "solver.far_max_adiabatic must be in (0, 0.05]",
        )?;
        check(
            s.max_piece_s > 0.0 && s.max_piece_s <= 1.0,
            "solver.max_piece_s must be in (0, 1]",
        )?;
        check(
            s.far_threshold_rad_per_s.is_finite() && s.far_threshold_rad_per_s > 0.0,
            "solver.far_threshold_rad_per_s must be positive",
        )?;
        let omega_l = deg_per_h_to_beat_rad_per_s(self.lock_in_deg_per_h, sf);
        let (w, amp) = if self.has_dither() {
            (
                hz_to_rad_per_s(self.dither_hz),
                arcsec_to_beat_rad(self.dither_amplitude_arcsec, sf),
            )
        } else {
            (0.0, 0.0)
        };
        Ok(Derived {
            scale_factor_arcsec: sf,
            omega_l_rad_per_s: omega_l,
            dither_w_rad_per_s: w,
            dither_amp_rad: amp,
            dither_peak_rad_per_s: w * amp,
            arw_rad_per_rt_s: arw_deg_per_rt_h_to_beat_rad_per_rt_s(self.arw_deg_per_rt_h, sf),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The set docs/physics.md and docs/rlg-sim.md document (and `rlg-sim`'s flags default to):
    /// SF 1.8655 arcsec/pulse, 389 Hz / 450 arcsec dither, Omega_L 200 deg/h, eps 0.3 rad,
    /// no noise. Written out on purpose: a change of the board profile shows here.
    #[test]
    fn default_is_the_documented_set() {
        let p = GyroParams::DEFAULT;
        assert_eq!(p.scale_factor_arcsec, 1.8655);
        assert_eq!(p.dither_hz, 389.0);
        assert_eq!(p.dither_amplitude_arcsec, 450.0);
        assert_eq!((p.lock_in_deg_per_h, p.eps_rad), (200.0, 0.3));
        assert_eq!((p.arw_deg_per_rt_h, p.seed), (0.0, 1));
        assert_eq!(p, GyroParams::default());
    }

    #[test]
    fn default_derives_paper_numbers() {
        let d = GyroParams::default().derive().unwrap();
        assert!((d.omega_l_rad_per_s - 673.6).abs() < 0.05);
        assert!((d.dither_peak_rad_per_s / 3.70e6 - 1.0).abs() < 0.01);
    }

    #[test]
    fn rejects_nonsense() {
        let p = GyroParams {
            scale_factor_arcsec: -1.0,
            ..Default::default()
        };
        assert!(p.derive().is_err());
        let p = GyroParams {
            lock_in_deg_per_h: f64::NAN,
            ..Default::default()
        };
        assert!(p.derive().is_err());
        let p = GyroParams {
            amplitude_jitter: AmplitudeModulation::jitter(0.5),
            ..Default::default()
        };
        assert!(p.derive().is_err());
    }
}
