//! The simulated gyro: the public face of the physics core.
//!
//! [`Gyro`] owns the parameters (immutable), the input profile and the integrator state,
//! and answers, for forward-moving time:
//! - the beat phase `psi(t)` (rad, unwrapped) and what the photodiodes see, `psi_H = psi - eps`;
//! - the turnarounds: exact zeros of the lock-in-free rate (dither + input + noise), with the
//!   beat phase at the instant and `psi_ddot` there;
//! - the truth about lock-in: per traversal the change of the slow lock-in phase `chi`
//!   across the near region ([`Traversal::lockin_error_rad`]), and at every turnaround the
//!   lock-in phase `phi = psi - theta` itself, whose difference between two turnarounds of
//!   the same kind is the exact lock-in error of that dither cycle;
//! - the free phase `theta(t)`, the true input rate, the dither pick-off and its turnarounds.
//!
//! With the driven dither ([`crate::params::DitherModel::Driven`]) the gyro also takes the
//! drive: [`Gyro::push_drive`] appends the firmware's DDS segments, [`Gyro::extend_drive_until`]
//! says how long the last one holds, and [`Gyro::drive_known_until_s`] is how far the dither is
//! known. The gyro never plans beyond that time, nor, with the noise on, beyond the noise
//! horizon (the noise steps snap to the drive's segment starts, so a noise segment is known
//! once the drive decides its end: [`Gyro::known_until_s`], less than 3/4 of a nominal period
//! before the drive horizon, [`crate::noise`]); [`Gyro::try_advance_to`] refuses to pass it
//! (and [`Gyro::advance_to`] panics). Keep the drive known [`Gyro::drive_lead_s`] (two nominal
//! dither periods) ahead of every time you advance to: then every planned piece is complete,
//! the next turnaround is always found, and the results do not depend on how pushing and
//! advancing interleave (see [`crate::dither`]).
//!
//! Time only moves forward (`advance_to` panics on a step back); clone the gyro to explore
//! ahead. `psi` is an unwrapped `f64`, so its resolution is one ulp of |psi| (2e-10 rad at
//! 1e6 rad, i.e. after ~1 s at 100 deg/s of input); time is an `f64` of seconds, whose ulp
//! (4.5e-13 s at 1 h) is worth ~2e-6 rad at the peak dither rate: inherent in the interface,
//! not in the integration, which works relative to each segment. Same parameters (and seed) and same input give the same results bit for bit,
//! independent of how often or where the caller looks.

use crate::dither::drive::{DriveError, DriveExhausted, DriveSegment, DriveSink};
use crate::dither::driven::HISTORY_S;
use crate::dither::linear::ResonatorState;
use crate::dither::sine::{draw_tones, modulation_at, Tone};
use crate::input::InputProfile;
use crate::param_error::ParamError;
use crate::params::{Derived, GyroParams};
use crate::phase::free_phase::FreePhase;
use crate::phase::integrator::{Event, Integrator, LockInDrift};
pub use crate::phase::plan::TurnaroundTime;
use firmware::sample::TurnaroundKind;
use std::collections::VecDeque;

/// A turnaround as the gyro passed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Turnaround {
    /// Exact zero of the lock-in-free rate, s.
    pub time_s: f64,
    /// Which way the rate crosses zero (`Plus`: beat phase at a minimum).
    pub kind: TurnaroundKind,
    /// Beat phase at the instant, rad (unwrapped).
    pub psi_rad: f64,
    /// Lock-in phase `psi - theta` at the instant, rad.
    pub phi_rad: f64,
    /// `d omega / dt` at the zero, rad/s^2 (psi_ddot without the small lock-in term).
    pub psi_ddot_rad_per_s2: f64,
}

/// One traversal of the lock-in zone (a near region containing exactly one turnaround).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Traversal {
    /// The turnaround inside the near region.
    pub turnaround: Turnaround,
    /// Change of the slow lock-in phase `chi` across the near region, rad: the lock-in phase
    /// error of this traversal with the far-field oscillation removed at both ends.
    pub lockin_error_rad: f64,
    /// Start of the near region, s.
    pub near_start_s: f64,
    /// End of the near region, s: when the traversal is logged.
    pub near_end_s: f64,
}

impl Turnaround {
    /// The exact lock-in phase error accumulated from `self` to a later turnaround `later`
    /// (of the same kind: one dither cycle), rad: the change of `phi = psi - theta`, i.e. the
    /// measured phase minus the true angle. The compensated output is the measured phase
    /// minus this.
    pub fn lockin_error_until_rad(&self, later: &Turnaround) -> f64 {
        later.phi_rad - self.phi_rad
    }
}

/// Traversals kept if the caller never drains them (oldest dropped first).
pub const TRAVERSAL_LOG_CAP: usize = 1 << 20;

/// A simulated ring laser gyro.
#[derive(Clone, Debug)]
pub struct Gyro {
    params: GyroParams,
    derived: Derived,
    integ: Integrator,
    run_turns: Vec<Turnaround>,
    last_turn: Option<Turnaround>,
    traversals: VecDeque<Traversal>,
    /// The true input (the gyro measures it with its thermal errors: [`crate::thermal`]).
    true_input: InputProfile,
    /// A driven dither's drive-gain wander (`GyroParams::amplitude_jitter` applied to the
    /// drive: the amplifier's and the piezo's gain drift that the amplitude loop must hold the
    /// amplitude against); empty without it.
    drive_gain_wander: Vec<Tone>,
}

impl Gyro {
    /// A gyro with `params`, driven by `input`, at t = 0.
    pub fn new(params: GyroParams, input: InputProfile) -> Result<Self, ParamError> {
        let derived = params.derive()?;
        let measured =
            crate::thermal::measured_input(&input, &params.thermal, params.scale_factor_arcsec)?;
        let fp = FreePhase::new(&params, &derived, measured);
        let mut integ = Integrator::new(
            fp,
            derived.omega_l_rad_per_s,
            &params.solver.effective(derived.omega_l_rad_per_s),
            params.initial_psi_rad,
        );
        integ.set_lock_in_drift(Self::lock_in_drift(&params, &derived));
        let mut drive_gain_wander = Vec::new();
        if params.resonator().is_some() {
            draw_tones(
                &params.amplitude_jitter,
                params.seed ^ 0x3c6e_f372_fe94_f82b,
                &mut drive_gain_wander,
            );
        }
        Ok(Self {
            true_input: input,
            params,
            derived,
            integ,
            run_turns: Vec::new(),
            last_turn: None,
            traversals: VecDeque::new(),
            drive_gain_wander,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &GyroParams {
        &self.params
    }

    fn lock_in_drift(params: &GyroParams, derived: &Derived) -> LockInDrift {
        LockInDrift {
            omega_l0: derived.omega_l_rad_per_s,
            rate_per_s: params.lock_in_drift_per_s,
            until_s: params.lock_in_drift_until_s,
            thermal: params.thermal.is_on().then_some(params.thermal),
        }
    }

    /// The lock-in threshold at `t_s`, rad/s of beat phase (drifting and following the
    /// temperature if the parameters say so).
    pub fn lock_in_rad_per_s(&self, t_s: f64) -> f64 {
        Self::lock_in_drift(&self.params, &self.derived).at(t_s)
    }

    /// The parameters in beat-phase units.
    pub fn derived(&self) -> &Derived {
        &self.derived
    }

    /// The latest time advanced to, s.
    pub fn t_s(&self) -> f64 {
        self.integ.t_now()
    }

    fn absorb_events(&mut self) {
        let events: Vec<Event> = self.integ.drain_events().collect();
        for ev in events {
            match ev {
                Event::Turnaround(ts) => {
                    let t = Turnaround {
                        time_s: ts.at.time_s,
                        kind: ts.at.kind,
                        psi_rad: ts.psi_rad,
                        phi_rad: ts.phi_rad,
                        psi_ddot_rad_per_s2: ts.at.psi_ddot_rad_per_s2,
                    };
                    self.run_turns.push(t);
                    self.last_turn = Some(t);
                }
                Event::NearRunEnd(run) => {
                    if let (Some(chi_in), [turn]) = (run.chi_in, self.run_turns.as_slice()) {
                        if self.traversals.len() == TRAVERSAL_LOG_CAP {
                            self.traversals.pop_front();
                        }
                        self.traversals.push_back(Traversal {
                            turnaround: *turn,
                            lockin_error_rad: run.chi_out - chi_in,
                            near_start_s: run.t_in,
                            near_end_s: run.t_out,
                        });
                    }
                    self.run_turns.clear();
                }
            }
        }
    }

    /// Advances to `t_s` (>= the current time) and returns the beat phase `psi(t)`, rad.
    /// Panics beyond the known drive of a driven dither ([`Self::try_advance_to`] refuses).
    pub fn advance_to(&mut self, t_s: f64) -> f64 {
        let psi = self.integ.advance_to(t_s);
        self.absorb_events();
        psi
    }

    /// As [`Self::advance_to`], but refuses (and stays where it is) if `t_s` lies beyond
    /// [`Self::known_until_s`].
    pub fn try_advance_to(&mut self, t_s: f64) -> Result<f64, DriveExhausted> {
        let known_until_s = self.known_until_s();
        if t_s > known_until_s {
            return Err(DriveExhausted {
                asked_s: t_s,
                known_until_s,
            });
        }
        Ok(self.advance_to(t_s))
    }

    /// Appends a drive segment to the driven dither: it starts at or after
    /// [`Self::drive_known_until_s`] (the previous segment holds until its start, which
    /// becomes the new horizon). [`DriveError::NotDriven`] for the prescribed sine.
    pub fn push_drive(&mut self, mut segment: DriveSegment) -> Result<(), DriveError> {
        // The drive's gain wanders (amplitude jitter on a driven dither): a segment's amplitude
        // is the gain at its start (0.1-2 Hz against segments of a half cycle or less).
        segment.amplitude_v *= 1.0 + modulation_at(&self.drive_gain_wander, segment.start_s);
        let keep_from_s = self.integ.t_now() - HISTORY_S;
        let fp = self.integ.free_phase_mut();
        let driven = fp.dither_mut().driven_mut().ok_or(DriveError::NotDriven)?;
        driven.push(segment)?;
        fp.forget_before(keep_from_s);
        Ok(())
    }

    /// States that the last drive segment holds at least until `t_s` (a DDS between two
    /// updates: the caller has ticked that far without changing it).
    pub fn extend_drive_until(&mut self, t_s: f64) -> Result<(), DriveError> {
        let dither = self.integ.free_phase_mut().dither_mut();
        dither
            .driven_mut()
            .ok_or(DriveError::NotDriven)?
            .extend_until(t_s)
    }

    /// The time up to which the dither is known, s: the driven dither's drive horizon (infinite
    /// for the prescribed sine).
    pub fn drive_known_until_s(&self) -> f64 {
        self.integ.free_phase().dither().known_until_s()
    }

    /// The time up to which the gyro can advance (and answer `theta`, the rate), s: the drive
    /// horizon [`Self::drive_known_until_s`], or with the noise on under a driven dither the
    /// noise horizon if that is earlier: the start of the first noise segment whose end the
    /// drive does not decide yet, less than 3/4 of a nominal period before the drive horizon
    /// (see [`crate::noise`]). Infinite for the prescribed sine.
    pub fn known_until_s(&self) -> f64 {
        self.integ.free_phase().known_until_s()
    }

    /// The lead a caller keeps between the drive horizon and the times it advances to: two
    /// nominal dither periods, s (see the module docs).
    pub fn drive_lead_s(&self) -> f64 {
        2.0 / self.params.dither_hz
    }

    /// The driven dither's state (piezo voltage, angle, rate) at `t_s`, within the known drive;
    /// `None` for the prescribed sine.
    pub fn dither_state(&self, t_s: f64) -> Option<ResonatorState> {
        let d = self.integ.free_phase().dither().driven()?;
        Some(d.state_at(t_s))
    }

    /// What the photodiodes see at `t_s`: `psi_H = psi - eps(T)`, rad (advances to `t_s`).
    pub fn psi_h(&mut self, t_s: f64) -> f64 {
        self.advance_to(t_s) - self.eps_rad(t_s)
    }

    /// The photodiode phase offset eps at `t_s` (the parameters' eps, moved by the
    /// temperature: [`crate::thermal`]), rad.
    pub fn eps_rad(&self, t_s: f64) -> f64 {
        self.params.eps_rad + self.params.thermal.eps_offset_rad(t_s)
    }

    /// The next turnaround after the current time, without advancing (plans ahead). Panics
    /// if a driven dither's drive does not reach it ([`Self::try_upcoming_turnaround`]).
    pub fn upcoming_turnaround(&mut self) -> TurnaroundTime {
        self.integ.upcoming_turnaround()
    }

    /// The next turnaround, or `None` if the known drive does not reach it (yet).
    pub fn try_upcoming_turnaround(&mut self) -> Option<TurnaroundTime> {
        self.integ.try_upcoming_turnaround()
    }

    /// Advances to the next turnaround and returns it with the beat phase at the instant.
    pub fn next_turnaround(&mut self) -> Turnaround {
        let next = self.integ.upcoming_turnaround();
        self.advance_to(next.time_s);
        let t = self.last_turn.expect("the turnaround was just passed");
        debug_assert_eq!(t.time_s, next.time_s);
        t
    }

    /// As [`Self::next_turnaround`], or `None` (without advancing) if the known drive does not
    /// reach it.
    pub fn try_next_turnaround(&mut self) -> Option<Turnaround> {
        let next = self.integ.try_upcoming_turnaround()?;
        self.advance_to(next.time_s);
        self.last_turn
    }

    /// Drains the traversals completed so far (a traversal completes when its near region
    /// ends, ~55 us after its turnaround with the default solver settings).
    pub fn take_traversals(&mut self) -> Vec<Traversal> {
        self.traversals.drain(..).collect()
    }

    fn check_known(&self, t_s: f64) {
        let known = self.known_until_s();
        assert!(
            t_s <= known,
            "t = {t_s} s lies beyond the drive (and noise) known until {known} s"
        );
    }

    /// The lock-in-free phase `theta(t)` (input + dither + noise angle), rad of beat phase.
    /// A driven dither answers only up to [`Self::known_until_s`] (panics beyond).
    pub fn theta_rad(&self, t_s: f64) -> f64 {
        self.check_known(t_s);
        self.integ.free_phase().theta_rad(t_s)
    }

    /// The lock-in-free rate at `t_s`, rad/s of beat phase, up to [`Self::known_until_s`] (with
    /// the noise on, strictly before the noise horizon: the rate after it is not known yet).
    pub fn lockin_free_rate_rad_per_s(&self, t_s: f64) -> f64 {
        self.check_known(t_s);
        let fp = self.integ.free_phase();
        let noise_until = fp.noise().known_until_s(fp.dither());
        assert!(
            t_s < noise_until,
            "t = {t_s} s: the noise rate from {noise_until} s on is not known yet"
        );
        fp.omega_and_slope(t_s, fp.piece_at(t_s)).0
    }

    /// The true input rate at `t_s`, deg/h.
    pub fn input_rate_deg_per_h(&self, t_s: f64) -> f64 {
        self.true_input.rate_deg_per_h(t_s)
    }

    /// The true input angle since t = 0, arcsec of body angle.
    pub fn input_angle_arcsec(&self, t_s: f64) -> f64 {
        self.true_input.angle_arcsec(t_s)
    }

    /// The dither pick-off (spring deflection) at `t_s`, arcsec of body angle: the true dither
    /// angle (the board's pick-off, `crate::pickoff`, adds its errors). A driven dither answers
    /// only within its known drive (panics beyond).
    pub fn dither_pickoff_arcsec(&self, t_s: f64) -> f64 {
        self.integ.free_phase().dither().pickoff_angle_arcsec(t_s)
    }

    /// The first zero of the dither-only rate after `t_s` (the pick-off's turnaround), which
    /// differs from the true turnaround by about `Omega_i / psi_ddot` (docs/physics.md pitfall 3).
    pub fn pickoff_turnaround_after(&self, t_s: f64) -> Option<(f64, TurnaroundKind)> {
        self.integ
            .free_phase()
            .dither()
            .pickoff_turnaround_after(t_s)
    }

    /// The free phase model (input, dither, noise).
    pub fn free_phase(&self) -> &FreePhase {
        self.integ.free_phase()
    }
}

impl DriveSink for Gyro {
    fn push_drive(&mut self, segment: DriveSegment) -> Result<(), DriveError> {
        Gyro::push_drive(self, segment)
    }

    fn extend_drive_until(&mut self, t_s: f64) -> Result<(), DriveError> {
        Gyro::extend_drive_until(self, t_s)
    }

    fn drive_known_until_s(&self) -> f64 {
        Gyro::drive_known_until_s(self)
    }
}

/// Speed of the simulation (see [`measure_speed`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Speed {
    /// Simulated gyro-seconds per wall-clock second.
    pub gyro_s_per_wall_s: f64,
    /// Simulated gyro-seconds per second of this thread's CPU time (Linux
    /// `/proc/thread-self/schedstat`; `None` elsewhere). On a loaded machine this is the
    /// figure that says what one free core would do.
    pub gyro_s_per_cpu_s: Option<f64>,
}

impl Speed {
    /// Times `run`, which simulates `gyro_seconds`, on this thread (wall clock and the
    /// thread's CPU time).
    pub fn of(gyro_seconds: f64, run: impl FnOnce()) -> Self {
        let cpu0 = thread_cpu_s();
        let start = std::time::Instant::now();
        run();
        let wall = start.elapsed().as_secs_f64();
        let cpu = match (cpu0, thread_cpu_s()) {
            (Some(a), Some(b)) if b > a => Some(gyro_seconds / (b - a)),
            _ => None,
        };
        Self {
            gyro_s_per_wall_s: gyro_seconds / wall,
            gyro_s_per_cpu_s: cpu,
        }
    }
}

/// This thread's CPU time in seconds, if the OS tells.
fn thread_cpu_s() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = s.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Measures [`Speed`] by simulating `gyro_seconds` of a gyro with `params` driven by `input`
/// on the calling thread (the benchmark uses the docs/physics.md set on the paper's rotary table at
/// 22.2 deg latitude, azimuth 0: +13.888 deg/h).
///
/// A driven dither gets [`GyroParams::open_loop_drive`] (a new segment every half cycle),
/// pushed [`Gyro::drive_lead_s`] ahead while the gyro advances half a nominal cycle at a time;
/// start it in the drive's steady state with [`GyroParams::with_steady_driven_dither`].
pub fn measure_speed(
    params: GyroParams,
    input: InputProfile,
    gyro_seconds: f64,
) -> Result<Speed, ParamError> {
    let mut g = Gyro::new(params, input)?;
    let mut drive = params.open_loop_drive();
    Ok(Speed::of(gyro_seconds, || match &mut drive {
        None => {
            g.advance_to(gyro_seconds);
        }
        Some(drive) => {
            let (step_s, lead_s) = (0.5 / params.dither_hz, g.drive_lead_s());
            let mut t = 0.0;
            while t < gyro_seconds {
                t = (t + step_s).min(gyro_seconds);
                drive
                    .keep_ahead(&mut g, t + lead_s)
                    .expect("the open-loop drive is valid");
                g.advance_to(t);
            }
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turnarounds_alternate_and_traversals_are_logged() {
        let mut g = Gyro::new(GyroParams::default(), InputProfile::constant(5.0)).unwrap();
        let mut last: Option<Turnaround> = None;
        for _ in 0..20 {
            let t = g.next_turnaround();
            assert!(g.lockin_free_rate_rad_per_s(t.time_s).abs() < 1e-4);
            if let Some(l) = last {
                assert_ne!(l.kind, t.kind);
                assert!(t.time_s > l.time_s);
            }
            last = Some(t);
        }
        g.advance_to(g.t_s() + 1e-3);
        let tr = g.take_traversals();
        assert!(tr.len() >= 19, "{}", tr.len());
        for x in &tr {
            // Per traversal ~ Omega_L k ~ 0.018 rad at most.
            assert!(x.lockin_error_rad.abs() < 0.03, "{x:?}");
        }
    }

    #[test]
    fn no_dither_ramp_has_one_turnaround_and_locks_then_slips() {
        let p = GyroParams {
            dither_amplitude_arcsec: 0.0,
            ..Default::default()
        };
        let mut g = Gyro::new(p, InputProfile::ramp(0.0, -400.0, 1.0, 400.0)).unwrap();
        let t = g.next_turnaround();
        assert_eq!(t.kind, TurnaroundKind::Plus);
        assert!((t.time_s - 0.5).abs() < 1e-12, "{}", t.time_s);
        let psi_locked = g.advance_to(0.55);
        // 0.55 s: 40 deg/h < Omega_L: locked, psi barely moves after settling.
        assert!((g.advance_to(0.6) - psi_locked).abs() < 0.5);
        // At the end the rate is 400 deg/h > Omega_L: slipping forward.
        let a = g.advance_to(0.95);
        assert!(g.advance_to(1.0) - a > 10.0);
        assert!(g.take_traversals().is_empty());
    }
}
