//! The driven dither's parameters: the resonator (f0, Q, piezo gain), its drive amplifier and
//! DAC, the temperature drift of f0 and Q, and the start state; with the transfer functions a
//! firmware designer (or a test) needs to set a drive.
//!
//! # Units and the default set
//!
//! The angle is the body's dither angle in arcsec (the integrator converts it to beat phase
//! with the scale factor, as the prescribed dither does); the piezo gain `G` is the static
//! deflection per volt on the piezo. The defaults are chosen so that the docs/physics.md
//! dither (389 Hz, 450 arcsec, Q = 1000) needs a quarter of the drive range at resonance:
//! `450 / (Q G |H_lp(f0)|) = 7.56 V` of the amplifier's +-30 V (25 %), i.e. 0.378 V of the
//! DAC's +-1.65 V (470 codes of 2047, 23 %).
//! The headroom (4x, 12 dB) is for the firmware's start-up (full drive reaches 450 arcsec in
//! `tau ln(4/3) = 0.24 s` instead of approaching it over several `tau = Q/(pi f0) = 0.82 s`) and
//! for low Q (Q = 250 needs the full range). At Q = 5000 the same amplitude needs 5 % of the
//! range (94 codes: one code is 1.1 % of the amplitude, 4.8 arcsec), a resolution the
//! firmware's amplitude loop has to live with; the ring-down time is then 4.1 s.
//!
//! # Temperature drift
//!
//! `f0(T) = f0 + f0_hz_per_c (T - T_ref)`, `Q(T) = Q (1 + q_relative_per_c (T - T_ref))`,
//! with `T(t)` a scripted piecewise-linear profile ([`TemperatureProfile`]). Both are held
//! constant over each drive segment (evaluated at its start), and a segment is split every
//! [`TemperatureDrift::hold_s`] while the temperature changes (a split is a breakpoint for the
//! phase integrator: one more piece per hold, 10 ms by default, only during a ramp). The step this leaves is tiny: a 1 K/min
//! ramp with -0.04 Hz/K (-100 ppm/K, a steel spring) moves f0 by 8.6e-7 Hz per half cycle and
//! 6.7e-6 Hz per 10 ms hold. The state (piezo voltage, angle, rate) is continuous across a
//! parameter step; the angle's second derivative steps with w0^2.

use super::amplifier::AmplifierParams;
use super::drive::{DacParams, DriveSegment};
use super::linear::{Complex, Forcing, LinearSystem, ResonatorState, SegmentResponse};
use crate::param_error::ParamError;
use core::f64::consts::{PI, TAU};

/// A scripted temperature of the gyro block: piecewise linear through up to
/// [`TemperatureProfile::MAX_KNOTS`] knots `(t_s, temp_c)` (constant before the first and after
/// the last: the chamber's constants, steps and ramps), plus an optional warm-up transient
/// `d0 exp(-t / tau)` ([`TemperatureProfile::warm_up`]: the block starting `d0` away from the
/// profile and settling with its thermal time constant).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemperatureProfile {
    knots: [(f64, f64); TemperatureProfile::MAX_KNOTS],
    len: usize,
    /// The warm-up transient: its amplitude at t = 0, °C, and time constant, s.
    transient: Option<(f64, f64)>,
}

impl TemperatureProfile {
    /// Most knots a profile holds.
    pub const MAX_KNOTS: usize = 16;

    /// A constant temperature, deg C.
    pub const fn constant(temp_c: f64) -> Self {
        let mut knots = [(0.0, 0.0); Self::MAX_KNOTS];
        knots[0] = (0.0, temp_c);
        Self {
            knots,
            len: 1,
            transient: None,
        }
    }

    /// Through `knots` `(t_s, temp_c)`: 1..=16 knots, finite, times strictly increasing.
    pub fn knots(knots: &[(f64, f64)]) -> Result<Self, ParamError> {
        let ok = (1..=Self::MAX_KNOTS).contains(&knots.len())
            && knots.iter().all(|(t, c)| t.is_finite() && c.is_finite())
            && knots.windows(2).all(|w| w[1].0 > w[0].0);
        if !ok {
            return Err(ParamError::OutOfRange(
                "temperature profile: 1..=16 finite knots, times strictly increasing",
            ));
        }
        let mut p = Self::constant(0.0);
        p.knots[..knots.len()].copy_from_slice(knots);
        p.len = knots.len();
        Ok(p)
    }

    /// A linear ramp from `temp0_c` at `t0_s` to `temp1_c` at `t1_s` (`t1_s > t0_s`).
    pub fn ramp(t0_s: f64, temp0_c: f64, t1_s: f64, temp1_c: f64) -> Result<Self, ParamError> {
        Self::knots(&[(t0_s, temp0_c), (t1_s, temp1_c)])
    }

    /// A warm-up: the block starts at `from_c` and settles to `to_c` as
    /// `to_c + (from_c - to_c) exp(-t / tau_s)` (`tau_s` in (0, 1e6]).
    pub fn warm_up(from_c: f64, to_c: f64, tau_s: f64) -> Result<Self, ParamError> {
        if !(from_c.is_finite() && to_c.is_finite() && tau_s > 0.0 && tau_s <= 1e6) {
            return Err(ParamError::OutOfRange(
                "warm-up: finite temperatures, time constant in (0, 1e6] s",
            ));
        }
        Ok(Self {
            transient: Some((from_c - to_c, tau_s)),
            ..Self::constant(to_c)
        })
    }

    fn linear_at(&self, t_s: f64) -> (f64, f64) {
        let k = &self.knots[..self.len];
        let i = k.partition_point(|&(t, _)| t <= t_s);
        if i == 0 || i == k.len() {
            return (k[i.saturating_sub(1)].1, 0.0);
        }
        let ((ta, ca), (tb, cb)) = (k[i - 1], k[i]);
        let slope = (cb - ca) / (tb - ta);
        (ca + slope * (t_s - ta), slope)
    }

    /// The temperature at `t_s`, deg C.
    pub fn at(&self, t_s: f64) -> f64 {
        let (linear, _) = self.linear_at(t_s);
        match self.transient {
            Some((d0, tau)) => linear + d0 * (-t_s.max(0.0) / tau).exp(),
            None => linear,
        }
    }

    /// The temperature's rate at `t_s` (the right-hand rate at a knot), deg C/s.
    pub fn rate_c_per_s(&self, t_s: f64) -> f64 {
        let (_, slope) = self.linear_at(t_s);
        match self.transient {
            Some((d0, tau)) => slope - d0 / tau * (-t_s.max(0.0) / tau).exp(),
            None => slope,
        }
    }

    /// The times at which the profile is linear in between: its knots, and with a warm-up a
    /// grid of tau/16 up to 12 tau (the transient is then 6e-6 of its start; a linear piece of
    /// tau/16 is within 5e-4 of the transient's amplitude of the exponential). Sorted, from 0.
    pub fn linear_pieces(&self) -> Vec<f64> {
        let mut times: Vec<f64> = self.knots[..self.len]
            .iter()
            .map(|k| k.0)
            .filter(|&t| t > 0.0)
            .collect();
        times.push(0.0);
        if let Some((_, tau)) = self.transient {
            let step = tau / 16.0;
            times.extend((1..=16 * 12).map(|i| i as f64 * step));
        }
        times.sort_by(f64::total_cmp);
        times.dedup();
        times
    }

    /// Lowest and highest temperature, deg C.
    pub fn range_c(&self) -> (f64, f64) {
        let (lo, hi) = self.knots[..self.len]
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &(_, c)| {
                (lo.min(c), hi.max(c))
            });
        let start = self.at(0.0);
        (lo.min(start), hi.max(start))
    }

    /// True if the temperature never changes.
    pub fn is_flat(&self) -> bool {
        let (lo, hi) = self.range_c();
        lo == hi
    }
}

/// How f0 and Q follow the temperature.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TemperatureDrift {
    /// The temperature over the run.
    pub profile: TemperatureProfile,
    /// Temperature at which `f0_hz` and `q` hold, deg C (finite).
    pub reference_c: f64,
    /// df0/dT, Hz/K. Range [-1, 1] (a steel spring: ~-100 ppm/K, -0.04 Hz/K at 389 Hz).
    pub f0_hz_per_c: f64,
    /// (dQ/dT)/Q, 1/K. Range [-0.1, 0.1].
    pub q_relative_per_c: f64,
    /// Longest stretch with constant f0 and Q while the temperature changes, s: longer drive
    /// segments are split. Range [1e-4, 10].
    pub hold_s: f64,
}

impl TemperatureDrift {
    /// No drift: 25 deg C throughout, zero coefficients.
    pub const NONE: Self = Self {
        profile: TemperatureProfile::constant(25.0),
        reference_c: 25.0,
        f0_hz_per_c: 0.0,
        q_relative_per_c: 0.0,
        hold_s: 0.01,
    };

    /// True if f0 or Q changes over the run.
    pub fn is_on(&self) -> bool {
        (self.f0_hz_per_c != 0.0 || self.q_relative_per_c != 0.0) && !self.profile.is_flat()
    }
}

/// The driven dither: resonator, amplifier, DAC, drift and start state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResonatorParams {
    /// Resonance frequency f0 at the reference temperature, Hz. Range [10, 1e4] (the board's
    /// scheduler accepts 200..1500 Hz).
    pub f0_hz: f64,
    /// Quality factor at the reference temperature. Range [10, 1e6].
    pub q: f64,
    /// Piezo gain G: static body deflection per volt on the piezo, arcsec/V. Range (0, 100].
    pub piezo_gain_arcsec_per_v: f64,
    /// The drive amplifier.
    pub amplifier: AmplifierParams,
    /// The DAC and the drive timer's rate.
    pub dac: DacParams,
    /// Temperature drift of f0 and Q.
    pub temperature: TemperatureDrift,
    /// The state at t = 0 (finite). [`ResonatorParams::steady_state`] gives a drive's steady
    /// state; [`ResonatorState::REST`] starts from rest.
    pub initial: ResonatorState,
}

impl Default for ResonatorParams {
    /// The board profile's nominal dither frequency, Q = 1000, 0.06 arcsec/V, the default
    /// amplifier and DAC, no drift, at rest.
    fn default() -> Self {
        Self {
            f0_hz: firmware::profile::BoardProfile::F405.nominal_dither_hz,
            q: 1000.0,
            piezo_gain_arcsec_per_v: 0.06,
            amplifier: AmplifierParams::default(),
            dac: DacParams::default(),
            temperature: TemperatureDrift::NONE,
            initial: ResonatorState::REST,
        }
    }
}

fn check(ok: bool, what: &'static str) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError::OutOfRange(what))
    }
}

fn in_range(x: f64, lo: f64, hi: f64) -> bool {
    x.is_finite() && x >= lo && x <= hi
}

impl ResonatorParams {
    /// Checks every field against its range, along the whole temperature profile.
    pub fn validate(&self) -> Result<(), ParamError> {
        let amp = &self.amplifier;
        let dac = &self.dac;
        let temp = &self.temperature;
        check(
            in_range(self.piezo_gain_arcsec_per_v, 1e-12, 100.0),
            "resonator: piezo_gain_arcsec_per_v must be in (0, 100]",
        )?;
        check(
            in_range(amp.gain_v_per_v, 1e-12, 1000.0),
            "amplifier: gain_v_per_v must be in (0, 1000]",
        )?;
        check(
            in_range(amp.output_limit_v, 1e-12, 1000.0),
            "amplifier: output_limit_v must be in (0, 1000]",
        )?;
        check(
            in_range(dac.reference_v, 1e-12, 10.0),
            "dac: reference_v must be in (0, 10]",
        )?;
        check(
            in_range(amp.input_ref_v, 0.0, dac.reference_v),
            "amplifier: input_ref_v must be in [0, dac.reference_v]",
        )?;
        check(
            temp.reference_c.is_finite()
                && in_range(temp.f0_hz_per_c, -1.0, 1.0)
                && in_range(temp.q_relative_per_c, -0.1, 0.1)
                && in_range(temp.hold_s, 1e-4, 10.0),
            "temperature: finite reference, f0_hz_per_c in [-1, 1], q_relative_per_c in \
             [-0.1, 0.1], hold_s in [1e-4, 10]",
        )?;
        check(
            self.initial.is_finite(),
            "resonator: initial state must be finite",
        )?;
        let (lo, hi) = temp.profile.range_c();
        for t_c in [lo, hi, temp.reference_c] {
            let (f0, q) = self.f0_q_at_temp(t_c);
            check(
                in_range(f0, 10.0, 1e4),
                "resonator: f0_hz must be in [10, 1e4] (over the temperature profile)",
            )?;
            check(
                in_range(q, 10.0, 1e6),
                "resonator: q must be in [10, 1e6] (over the temperature profile)",
            )?;
            check(
                in_range(dac.tick_hz, 8.0 * f0, 1e7),
                "dac: tick_hz must be in [8 f0, 1e7]",
            )?;
            check(
                in_range(amp.cutoff_hz, f0, 1e5),
                "amplifier: cutoff_hz must be in [f0, 1e5]",
            )?;
        }
        Ok(())
    }

    fn f0_q_at_temp(&self, temp_c: f64) -> (f64, f64) {
        let d = &self.temperature;
        let dt = temp_c - d.reference_c;
        (
            self.f0_hz + d.f0_hz_per_c * dt,
            self.q * (1.0 + d.q_relative_per_c * dt),
        )
    }

    /// `(f0, Q)` at `t_s` (the temperature profile's value then), Hz and 1.
    pub fn f0_q_at(&self, t_s: f64) -> (f64, f64) {
        if self.temperature.is_on() {
            self.f0_q_at_temp(self.temperature.profile.at(t_s))
        } else {
            (self.f0_hz, self.q)
        }
    }

    /// The linear system's coefficients at `t_s`.
    pub fn system_at(&self, t_s: f64) -> LinearSystem {
        let (f0, q) = self.f0_q_at(t_s);
        LinearSystem {
            w0_rad_per_s: TAU * f0,
            q,
            lowpass_rad_per_s: self.amplifier.lowpass_rad_per_s(),
            gain_arcsec_per_v: self.piezo_gain_arcsec_per_v,
        }
    }

    /// What the resonator sees of `segment` (see [`super::amplifier`]).
    pub fn forcing(&self, segment: &DriveSegment) -> Forcing {
        self.amplifier.forcing(&self.dac, segment)
    }

    /// The complex gain from a DAC sinusoid `a sin(2 pi f t + phi)` (V) to the angle's steady
    /// response `|h| a sin(2 pi f t + phi + arg h)` (arcsec) at `t_s`'s f0 and Q: amplifier gain,
    /// zero-order hold (gain and half-tick delay), output low-pass and resonator; the limit
    /// not reached. At resonance `arg h` = -90 deg - the low-pass's lag - half a tick.
    pub fn dac_to_angle(&self, freq_hz: f64, t_s: f64) -> Complex {
        let half_step = PI * freq_hz / self.dac.tick_hz;
        let sinc = if half_step == 0.0 {
            1.0
        } else {
            half_step.sin() / half_step
        };
        Complex::polar(self.amplifier.gain_v_per_v * sinc, -half_step)
            * self.system_at(t_s).response(freq_hz)
    }

    /// The steady state of `segment`'s drive at its start (no transient).
    pub fn steady_state(&self, segment: &DriveSegment) -> ResonatorState {
        let t0 = segment.start_s;
        SegmentResponse::new(
            &self.system_at(t0),
            &self.forcing(segment),
            t0,
            &ResonatorState::REST,
        )
        .steady_state_at(t0)
    }

    /// Ring-down time constant of the amplitude `Q / (pi f0)` at `t_s`, s.
    pub fn ring_down_s(&self, t_s: f64) -> f64 {
        let (f0, q) = self.f0_q_at(t_s);
        q / (PI * f0)
    }

    /// The images of a DDS at `freq_hz` with amplitude `dac_amplitude_v`: the sums over the
    /// images at `k f_s +- f` (k = 1..64) of their amplitudes after the zero-order hold
    /// (`a |sin(pi f/f_s)| / (pi |k +- f/f_s|)`) and the amplifier's gain, in the piezo
    /// voltage (V), the angle (arcsec) and the rate (arcsec/s): bounds on the steady state the
    /// model leaves out. (The neglected tail beyond k = 64 is ~1e-6 of the sums.)
    fn image_sums(&self, freq_hz: f64, dac_amplitude_v: f64) -> [f64; 3] {
        let fs = self.dac.tick_hz;
        let sys = self.system_at(0.0);
        let s = (PI * freq_hz / fs).sin().abs();
        let mut sums = [0.0; 3];
        for k in 1..=64 {
            for sign in [-1.0, 1.0] {
                let fk = k as f64 * fs + sign * freq_hz;
                let img = dac_amplitude_v * s / (PI * fk / fs) * self.amplifier.gain_v_per_v;
                let iw = Complex::new(0.0, TAU * fk);
                let v = img * sys.lowpass(iw).abs();
                let angle = img * sys.response(fk).abs();
                sums[0] += v;
                sums[1] += angle;
                sums[2] += angle * TAU * fk;
            }
        }
        sums
    }

    /// Bound on the angle the DAC's images add to the modelled (fundamental) response of a
    /// steady DDS at `freq_hz` with amplitude `dac_amplitude_v`, arcsec: the sum of the
    /// images' steady responses. About `(f/f_s) (f_c/f_s) (f0/f_s)^2 / Q` of the resonant
    /// response (1.1e-9 at 389 Hz, f_s = 20 kHz, f_c = 3 kHz, Q = 1000).
    pub fn image_bound_arcsec(&self, freq_hz: f64, dac_amplitude_v: f64) -> f64 {
        self.image_sums(freq_hz, dac_amplitude_v)[1]
    }

    /// Bound on the ringing a change of the DDS leaves that the model does not have, arcsec:
    /// the images change with the drive, and the change of their steady state (in the piezo
    /// voltage, the angle and the rate) is a kick the resonator rings down from (time constant
    /// `Q/(pi f0)`). `dac_change_v` is the magnitude of the change of the DAC's complex
    /// amplitude (`|a1 e^{i phi1} - a0 e^{i phi0}|`; `a` to switch a drive on or off). The
    /// images align at the ticks, so the bound is reached: about `(pi^2/3) (|da|/a) (f/f_s)
    /// (f0/f_s) / Q` of the resonant response (1.25e-6 at the set above for `|da| = a`).
    pub fn image_ring_bound_arcsec(&self, freq_hz: f64, dac_change_v: f64) -> f64 {
        let [v, angle, rate] = self.image_sums(freq_hz, dac_change_v);
        let sys = self.system_at(0.0);
        let p = sys.lowpass_rad_per_s;
        let (alpha, wd) = (sys.decay_per_s(), sys.damped_rad_per_s());
        // A piezo voltage offset `dv` decays through the low-pass: `E e^{-p t}` in the angle,
        // `E = H_res(-p) dv`, and the free mode takes `-E` and `p E` as its start.
        let e = v * sys.resonator(Complex::new(-p, 0.0)).abs();
        e * (1.0 + ((p - alpha) / wd).powi(2)).sqrt() + angle + rate / wd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_needs_a_quarter_of_the_range_at_450_arcsec() {
        let p = ResonatorParams::default();
        p.validate().unwrap();
        let h = p.dac_to_angle(389.0, 0.0);
        let dac_v = 450.0 / h.abs();
        let out_v = dac_v * p.amplifier.gain_v_per_v;
        assert!(
            (out_v / p.amplifier.output_limit_v - 0.25).abs() < 0.01,
            "{out_v}"
        );
        assert!((dac_v / 1.65 - 0.23).abs() < 0.01, "{dac_v}");
        // -90 deg, the low-pass's atan(389/3000) = 7.39 deg, half a 40 kHz tick 1.75 deg.
        let lag_deg = -h.arg().to_degrees();
        assert!((lag_deg - (90.0 + 7.39 + 1.75)).abs() < 0.01, "{lag_deg}");
    }

    #[test]
    fn temperature_profile_interpolates_and_validates() {
        let p = TemperatureProfile::knots(&[(1.0, 20.0), (3.0, 30.0), (4.0, 30.0)]).unwrap();
        assert_eq!(p.at(0.0), 20.0);
        assert_eq!(p.at(2.0), 25.0);
        assert_eq!(p.at(10.0), 30.0);
        assert!(TemperatureProfile::knots(&[(1.0, 20.0), (1.0, 30.0)]).is_err());
        assert!(TemperatureProfile::knots(&[]).is_err());
        let r = ResonatorParams {
            temperature: TemperatureDrift {
                profile: TemperatureProfile::ramp(0.0, 25.0, 10.0, 35.0).unwrap(),
                f0_hz_per_c: -0.04,
                q_relative_per_c: -0.005,
                ..TemperatureDrift::NONE
            },
            ..Default::default()
        };
        r.validate().unwrap();
        let (f0, q) = r.f0_q_at(5.0);
        assert!((f0 - 388.8).abs() < 1e-12 && (q - 975.0).abs() < 1e-9);
        // A drift that takes Q below its range somewhere on the profile is refused.
        let bad = ResonatorParams {
            temperature: TemperatureDrift {
                q_relative_per_c: -0.05,
                ..r.temperature
            },
            ..r
        };
        assert!(bad.validate().is_ok());
        // Q = 15 at 25 deg C is in range, but 7.5 at 35 deg C is not.
        let bad = ResonatorParams { q: 15.0, ..bad };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn every_range_is_checked() {
        let ok = ResonatorParams::default();
        let cases: [ResonatorParams; 9] = [
            ResonatorParams { f0_hz: 5.0, ..ok },
            ResonatorParams { q: 5.0, ..ok },
            ResonatorParams {
                piezo_gain_arcsec_per_v: 0.0,
                ..ok
            },
            ResonatorParams {
                amplifier: AmplifierParams {
                    cutoff_hz: 100.0,
                    ..ok.amplifier
                },
                ..ok
            },
            ResonatorParams {
                amplifier: AmplifierParams {
                    gain_v_per_v: f64::NAN,
                    ..ok.amplifier
                },
                ..ok
            },
            ResonatorParams {
                amplifier: AmplifierParams {
                    input_ref_v: 4.0,
                    ..ok.amplifier
                },
                ..ok
            },
            ResonatorParams {
                dac: DacParams {
                    tick_hz: 2000.0,
                    ..ok.dac
                },
                ..ok
            },
            ResonatorParams {
                initial: ResonatorState {
                    angle_arcsec: f64::INFINITY,
                    ..ResonatorState::REST
                },
                ..ok
            },
            ResonatorParams {
                temperature: TemperatureDrift {
                    hold_s: 0.0,
                    ..TemperatureDrift::NONE
                },
                ..ok
            },
        ];
        for (i, c) in cases.iter().enumerate() {
            assert!(c.validate().is_err(), "case {i} accepted");
        }
    }
}
