//! The mechanical dither, in one of two models ([`DitherModel`]):
//!
//! - **ideal** ([`sine`]): a prescribed sine, `theta_d = -A(t) cos(w_d t)` with an optional
//!   smooth amplitude modulation. The paper's idealised experiment and the theory tests.
//! - **driven** ([`driven`]): the body on its dither spring as a driven resonator,
//!   `theta'' + (w0/Q) theta' + w0^2 theta = w0^2 G v`, with `v` the drive amplifier's output
//!   after its output low-pass, driven by the firmware's DDS through the DAC ([`drive`],
//!   [`amplifier`]); f0 and Q drift with a scripted temperature ([`resonator`]).
//!
//! Both give the dither angle in beat phase with all the derivatives the phase integrator
//! needs (up to [`MAX_JET`]) in closed form at any instant, so the integrator never integrates
//! the dither rate (~3.7e6 rad/s of beat phase) and stays exact.
//!
//! # Why the driven model is exact, and fast
//!
//! Between two DDS updates the DAC output is a sampled sinusoid held for a tick: its
//! fundamental (the sinusoid times `sinc(pi f/f_s)`, half a tick late) plus images at
//! `k f_s +- f`. The amplifier's limit acts on the samples and is taken by its describing
//! function (the clipped wave's constant and fundamental, exact). So within a segment the
//! linear 3-state system (low-pass + resonator) sees a constant plus a sinusoid, and its
//! response from any start state is closed form ([`linear`]): forced sinusoid, the low-pass
//! transient, the damped free mode. Each segment's end state starts the next. Per evaluation
//! this costs two `(cos, sin)` and two `exp`, about as much as the ideal sine with its
//! modulation, and a segment start is just one more breakpoint for the integrator (the drive
//! steps there, so the angle's third derivative jumps: the integrator treats it like a noise
//! segment boundary).
//!
//! What is left out, with bounds ([`amplifier`]): the images (1.1e-9 of the resonant
//! response at 389 Hz, f_s = 20 kHz, Q = 1000), the ringing a change of the DDS leaves through
//! them (1.25e-6 of the response for a drive switched on, proportionally less for small
//! changes), the clip's harmonics (at most 1/(17.6 Q), only while the limit is hit) and the
//! DAC's rounding. The alternative, an exact
//! zero-order-hold discretisation of the staircase itself (a state transition per tick),
//! would make every tick a breakpoint: ~50 smooth pieces per half cycle instead of one, and
//! the far-field expansion of the phase integrator would lose its long steps.
//!
//! # The drive is known only so far
//!
//! A driven gyro knows its dither only up to the last drive data supplied
//! ([`driven::DrivenDither::known_until_s`]). The phase integrator plans piece by piece; it
//! never plans a piece beyond that time, and refuses (`Gyro::try_advance_to`) to go past it.
//! Its pieces end at segment starts, and at the latest one nominal dither period after they
//! begin; the next turnaround is at most half a period ahead. So a caller that keeps the drive
//! known **two nominal dither periods** ahead of any time it advances the gyro to
//! (`Gyro::drive_lead_s`) never has a piece cut short by the horizon, and its results do not
//! depend on how it interleaves pushing drive and advancing. With a shorter lead the gyro still
//! integrates exactly up to the horizon (it cuts the piece there: one more far-field boundary,
//! ~1e-8 rad), but a turnaround whose piece is not complete is not reported until more drive
//! arrives.
//!
//! With the angle random walk on, the noise steps snap to the drive's segment starts
//! ([`crate::noise`]), and a noise segment is known once the drive decides its end: the gyro
//! goes no further than the *noise horizon* (`Gyro::known_until_s`), less than 3/4 of a
//! nominal period before the drive's. The lead argument above still holds: the next
//! turnaround is at most half a period ahead, the noise segment containing it ends less than
//! 3/4 of a period after it, and a drive known that far (1.25 periods) decides that end; so a
//! caller keeping the two-period lead never meets the noise horizon. With a shorter lead the
//! gyro refuses to pass it, but never cuts a piece: every piece ends at or before its noise
//! segment's decided end, so with the noise on the results are the same bit for bit whatever
//! the lead.
//!
//! # The pick-off
//!
//! The strain pick-off reports the body's dither angle (arcsec), in either model
//! ([`Dither::pickoff_angle_arcsec`]); its voltage, errors and ADC are the board's
//! (`crate::pickoff`).

pub mod amplifier;
pub mod drive;
pub mod driven;
pub mod linear;
mod modulation;
pub mod open_loop;
pub mod resonator;
pub mod sine;

use core::f64::consts::TAU;
use driven::DrivenDither;
use firmware::sample::TurnaroundKind;
pub use modulation::AmplitudeModulation;
use resonator::ResonatorParams;
use sine::SineDither;

/// Which dither the gyro has (see [`crate::dither`]).
// Part of the `Copy` parameter set: a box would not be `Copy`; ~300 bytes copied is nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum DitherModel {
    /// The prescribed sine of `dither_hz` and `dither_amplitude_arcsec` (with the amplitude
    /// modulations): the paper's idealised experiment and the theory tests.
    #[default]
    Ideal,
    /// The driven resonator: the dither is what the pushed drive segments make of it
    /// (`Gyro::push_drive`). `dither_hz` is then the *nominal* dither frequency (the
    /// readout's configuration, the noise segments, the planner's grid; the resonance f0 must
    /// lie within a factor 4 of it), `dither_amplitude_arcsec` the nominal amplitude (what
    /// `GyroParams::open_loop_drive` aims at); the amplitude modulations are ignored.
    Driven(ResonatorParams),
}

/// What a dither is made from: the gyro's parameters in the dither's own terms
/// (`crate::params::GyroParams::dither_spec`), so this layer imports nothing of the parameter
/// set above it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DitherSpec {
    /// Prescribed or driven.
    pub model: DitherModel,
    /// There is a dither at all (a prescribed one needs an amplitude and a frequency).
    pub on: bool,
    /// The dither frequency, Hz (the driven resonator's nominal one).
    pub hz: f64,
    /// w_d, rad/s.
    pub w_rad_per_s: f64,
    /// The prescribed amplitude, rad of beat phase.
    pub amp_rad: f64,
    /// Scale factor, arcsec of angle per fringe (the pick-off's angle from the beat phase).
    pub scale_factor_arcsec: f64,
    /// The prescribed amplitude's slow jitter.
    pub jitter: AmplitudeModulation,
    /// The prescribed amplitude's random-noise dither.
    pub noise: AmplitudeModulation,
    /// The seed of both modulations.
    pub seed: u64,
}

/// Longest derivative jet the dither evaluates (angle and 15 derivatives).
pub const MAX_JET: usize = 16;

/// The dither of one gyro: prescribed or driven.
// One per gyro, in the integrator's hot path: unboxed (the sine's modulation cache is large).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Dither {
    /// The prescribed sine (`ideal`).
    Ideal(SineDither),
    /// The driven resonator.
    Driven(DrivenDither),
}

impl Dither {
    /// The dither of `spec`.
    pub fn new(spec: &DitherSpec) -> Self {
        match &spec.model {
            DitherModel::Ideal => Self::Ideal(SineDither::new(spec)),
            DitherModel::Driven(r) => Self::Driven(DrivenDither::new(
                r,
                spec.hz,
                TAU / spec.scale_factor_arcsec,
            )),
        }
    }

    /// True if there is a dither (the driven resonator always counts, even at rest).
    pub fn is_on(&self) -> bool {
        match self {
            Self::Ideal(d) => d.is_on(),
            Self::Driven(_) => true,
        }
    }

    /// The dither frequency (ideal) or the nominal one (driven), Hz; 0 without dither.
    pub fn freq_hz(&self) -> f64 {
        match self {
            Self::Ideal(d) => d.freq_hz(),
            Self::Driven(d) => d.nominal_hz(),
        }
    }

    /// The prescribed sine, if that is the model.
    pub fn sine(&self) -> Option<&SineDither> {
        match self {
            Self::Ideal(d) => Some(d),
            Self::Driven(_) => None,
        }
    }

    /// The driven resonator, if that is the model.
    pub fn driven(&self) -> Option<&DrivenDither> {
        match self {
            Self::Ideal(_) => None,
            Self::Driven(d) => Some(d),
        }
    }

    /// The driven resonator, to push drive into.
    pub fn driven_mut(&mut self) -> Option<&mut DrivenDither> {
        match self {
            Self::Ideal(_) => None,
            Self::Driven(d) => Some(d),
        }
    }

    /// The time up to which the dither is known, s (infinite for the prescribed sine).
    pub fn known_until_s(&self) -> f64 {
        match self {
            Self::Ideal(_) => f64::INFINITY,
            Self::Driven(d) => d.known_until_s(),
        }
    }

    /// Which drive segment contains `t_s` (0 for the prescribed sine).
    pub fn drive_index_at(&self, t_s: f64) -> u64 {
        match self {
            Self::Ideal(_) => 0,
            Self::Driven(d) => d.index_at(t_s),
        }
    }

    /// Dither angle `theta_d` and its derivatives at `t_s` in beat phase (`out[1]` = dither
    /// rate, rad/s), with the formula of drive segment `drive_index` (ignored by the sine).
    /// `out.len() <= MAX_JET`.
    #[inline]
    pub fn angle_jet(&self, t_s: f64, drive_index: u64, out: &mut [f64]) {
        match self {
            Self::Ideal(d) => d.angle_jet(t_s, out),
            Self::Driven(d) => d.angle_jet(t_s, drive_index, out),
        }
    }

    /// Dither angle, rad of beat phase.
    pub fn angle_rad(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, self.drive_index_at(t_s), &mut d);
        d[0]
    }

    /// Dither rate, rad/s of beat phase.
    pub fn rate_rad_per_s(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 2];
        self.angle_jet(t_s, self.drive_index_at(t_s), &mut d);
        d[1]
    }

    /// What the strain pick-off reports: the dither deflection, arcsec of body angle. The
    /// driven model panics beyond its known drive.
    pub fn pickoff_angle_arcsec(&self, t_s: f64) -> f64 {
        match self {
            Self::Ideal(d) => d.pickoff_angle_arcsec(t_s),
            Self::Driven(d) => d.angle_arcsec(t_s),
        }
    }

    /// The first zero of the dither-only rate strictly after `t_s` (a pick-off turnaround),
    /// with its kind. `None` without dither, or (driven) none within the known drive.
    pub fn pickoff_turnaround_after(&self, t_s: f64) -> Option<(f64, TurnaroundKind)> {
        match self {
            Self::Ideal(d) => d.pickoff_turnaround_after(t_s),
            Self::Driven(d) => d.pickoff_turnaround_after(t_s),
        }
    }
}
