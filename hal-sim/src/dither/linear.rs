//! The driven dither's linear core in closed form: the drive amplifier's output low-pass and
//! the dither resonator, excited by a constant plus a sinusoid over one drive segment.
//!
//! # The system
//!
//! ```text
//! v'      = p (y(t) - v)                                   amplifier output low-pass, p = 2 pi f_c
//! theta'' = -(w0/Q) theta' - w0^2 theta + w0^2 G v         dither resonator (body angle, arcsec)
//! y(t)    = c + b sin(w (t - t0) + phi)                    limited amplifier output (V), one segment
//! ```
//!
//! Three states (`v` in V, `theta` in arcsec, `theta'` in arcsec/s), linear with constant
//! coefficients inside a segment, so the response from any start state is a sum of exponentials:
//!
//! ```text
//! theta(tau) = G c + Re(P e^{i w tau}) + E e^{-p tau} + Re(R e^{lambda tau}),
//!              lambda = -w0/(2Q) + i w0 sqrt(1 - 1/(4 Q^2)),   tau = t - t0,
//! ```
//!
//! the forced (particular) response to the constant and the sinusoid, the low-pass's own
//! transient `V e^{-p tau}` passed through the resonator (`E = H_res(-p) V`), and the free,
//! damped resonator mode `R`, fitted to the start state. Every derivative is the same sum
//! with each term multiplied by its exponent (`i w`, `-p`, `lambda`) once per order, so the
//! angle and all the integrator's derivatives (up to [`super::MAX_JET`]) are exact at any
//! instant, and so is the state at the segment's end, which starts the next segment.
//!
//! # Precision
//!
//! The phases `w tau` and `Im(lambda) tau` are reduced by an error-free product (as the
//! prescribed dither does), so a segment may last hours without losing the phase; the decays
//! `e^{-w0 tau/(2Q)}` and `e^{-p tau}` are plain `exp` (relative error 1 ulp). A start state
//! that is already the forced steady state leaves `R` and `E` at rounding level, so a chain of
//! segments with the same drive (a new segment every half cycle) reproduces one long segment
//! to ~1e-13 relative.

use crate::trig::fast_cos_sin;
use crate::trig::reduced_phase;
use core::f64::consts::TAU;

/// A complex number (the few operations the closed form needs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Complex {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

impl Complex {
    /// `re + i im`.
    pub const fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }

    /// `r e^{i phi}`.
    pub fn polar(r: f64, phi_rad: f64) -> Self {
        let (s, c) = phi_rad.sin_cos();
        Self::new(r * c, r * s)
    }

    /// The product with a real number.
    #[inline(always)]
    pub fn scale(self, k: f64) -> Self {
        Self::new(self.re * k, self.im * k)
    }

    /// `|z|`.
    pub fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }

    /// `arg z`, rad.
    pub fn arg(self) -> f64 {
        self.im.atan2(self.re)
    }
}

impl core::ops::Add for Complex {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.re + o.re, self.im + o.im)
    }
}

impl core::ops::Mul for Complex {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

impl core::ops::Div for Complex {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let d = o.re * o.re + o.im * o.im;
        Self::new(
            (self.re * o.re + self.im * o.im) / d,
            (self.im * o.re - self.re * o.im) / d,
        )
    }
}

/// The state of the driven dither: amplifier output, angle and rate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ResonatorState {
    /// Output of the amplifier's low-pass (the voltage on the piezo), V.
    pub amp_output_v: f64,
    /// Dither angle of the body, arcsec.
    pub angle_arcsec: f64,
    /// Dither rate of the body, arcsec/s.
    pub rate_arcsec_per_s: f64,
}

impl ResonatorState {
    /// At rest: no voltage, no deflection, no motion.
    pub const REST: Self = Self {
        amp_output_v: 0.0,
        angle_arcsec: 0.0,
        rate_arcsec_per_s: 0.0,
    };

    /// True if every field is finite.
    pub fn is_finite(&self) -> bool {
        self.amp_output_v.is_finite()
            && self.angle_arcsec.is_finite()
            && self.rate_arcsec_per_s.is_finite()
    }
}

/// The constant coefficients of the linear system over one segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearSystem {
    /// Resonance `w0 = 2 pi f0`, rad/s.
    pub w0_rad_per_s: f64,
    /// Quality factor `Q` (> 1/2: underdamped).
    pub q: f64,
    /// Pole of the amplifier's output low-pass `p = 2 pi f_c`, rad/s.
    pub lowpass_rad_per_s: f64,
    /// Piezo gain `G`: static deflection per volt on the piezo, arcsec/V.
    pub gain_arcsec_per_v: f64,
}

impl LinearSystem {
    /// `H_res(s) = w0^2 G / (s^2 + s w0/Q + w0^2)`: piezo voltage to angle, arcsec/V.
    pub fn resonator(&self, s: Complex) -> Complex {
        let w0 = self.w0_rad_per_s;
        let den = s * s + s.scale(w0 / self.q) + Complex::new(w0 * w0, 0.0);
        Complex::new(w0 * w0 * self.gain_arcsec_per_v, 0.0) / den
    }

    /// `H_lp(s) = p / (s + p)`: amplifier output to piezo voltage.
    pub fn lowpass(&self, s: Complex) -> Complex {
        let p = self.lowpass_rad_per_s;
        Complex::new(p, 0.0) / (s + Complex::new(p, 0.0))
    }

    /// `H_lp H_res` at `i 2 pi f`: the limited amplifier output to the angle, arcsec/V.
    pub fn response(&self, freq_hz: f64) -> Complex {
        let s = Complex::new(0.0, TAU * freq_hz);
        self.lowpass(s) * self.resonator(s)
    }

    /// Decay rate of the free mode `w0 / (2 Q)`, 1/s (the ring-down time is its inverse).
    pub fn decay_per_s(&self) -> f64 {
        self.w0_rad_per_s / (2.0 * self.q)
    }

    /// Frequency of the free (damped) mode `w0 sqrt(1 - 1/(4 Q^2))`, rad/s.
    pub fn damped_rad_per_s(&self) -> f64 {
        self.w0_rad_per_s * (1.0 - 0.25 / (self.q * self.q)).sqrt()
    }
}

/// The limited amplifier output over one segment: `y = dc + amplitude sin(2 pi f (t - t0) +
/// phase)` (the DAC's zero-order-hold fundamental through the amplifier's gain and limit,
/// see [`super::amplifier`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Forcing {
    /// Constant part, V.
    pub dc_v: f64,
    /// Amplitude of the sinusoid, V (>= 0).
    pub amplitude_v: f64,
    /// Its frequency, Hz (>= 0).
    pub freq_hz: f64,
    /// Its phase at the segment's start, rad.
    pub phase_rad: f64,
}

impl Forcing {
    /// No drive: the amplifier's output is zero.
    pub const ZERO: Self = Self {
        dc_v: 0.0,
        amplitude_v: 0.0,
        freq_hz: 0.0,
        phase_rad: 0.0,
    };

    /// The same sinusoid seen from a start `dt_s` later (its phase advanced, exactly reduced).
    pub fn later_by(&self, dt_s: f64) -> Self {
        Self {
            phase_rad: self.phase_rad + reduced_phase(self.freq_hz, dt_s),
            ..*self
        }
    }
}

/// The exact response of the linear system over one segment (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentResponse {
    t0_s: f64,
    /// Forced constant: `v = c`, `theta = G c`.
    dc_v: f64,
    dc_arcsec: f64,
    /// Forced sinusoid of `v` and of `theta` (`Re(P e^{i w tau})`).
    forced_v: Complex,
    forced: Complex,
    freq_hz: f64,
    w_rad_per_s: f64,
    /// Low-pass transient `V e^{-p tau}` and its image in `theta`, `E e^{-p tau}`.
    lp_v: f64,
    lp: f64,
    p: f64,
    /// Free mode `Re(R e^{lambda tau})`.
    free: Complex,
    decay_per_s: f64,
    damped_hz: f64,
    lambda: Complex,
}

/// `e^{-x}` for `x >= 0`: the free mode's decay over a segment is tiny (`w0 tau / (2 Q)`,
/// ~1e-3 over half a cycle at Q 1000), where a series to `x^7` is exact to 3e-21 and three
/// times cheaper than libm's `exp` (this runs at every jet of the driven dither: tens per
/// half cycle); libm elsewhere.
#[inline(always)]
fn exp_neg(x: f64) -> f64 {
    if (0.0..0.01).contains(&x) {
        1.0 - x
            * (1.0
                - x * (0.5
                    - x * (1.0 / 6.0
                        - x * (1.0 / 24.0
                            - x * (1.0 / 120.0 - x * (1.0 / 720.0 - x * (1.0 / 5040.0)))))))
    } else {
        (-x).exp()
    }
}

impl SegmentResponse {
    /// The response to `forcing` from `state` at `t0_s`, with the coefficients `sys`.
    pub fn new(sys: &LinearSystem, forcing: &Forcing, t0_s: f64, state: &ResonatorState) -> Self {
        let w = TAU * forcing.freq_hz;
        let p = sys.lowpass_rad_per_s;
        let g = sys.gain_arcsec_per_v;
        let iw = Complex::new(0.0, w);
        // y = Im(B e^{i w tau}) = Re(-i B e^{i w tau}).
        let b = Complex::polar(forcing.amplitude_v, forcing.phase_rad) * Complex::new(0.0, -1.0);
        let forced_v = b * sys.lowpass(iw);
        let forced = forced_v * sys.resonator(iw);
        let dc_v = forcing.dc_v;
        let dc_arcsec = g * dc_v;
        let lp_v = state.amp_output_v - (dc_v + forced_v.re);
        let lp = lp_v * sys.resonator(Complex::new(-p, 0.0)).re;
        let alpha = sys.decay_per_s();
        let wd = sys.damped_rad_per_s();
        // Fit the free mode to the angle and rate left over by the other terms.
        let r0 = state.angle_arcsec - (dc_arcsec + forced.re + lp);
        let r1 = state.rate_arcsec_per_s - ((forced * iw).re - p * lp);
        let free = Complex::new(r0, -(r1 + alpha * r0) / wd);
        Self {
            t0_s,
            dc_v,
            dc_arcsec,
            forced_v,
            forced,
            freq_hz: forcing.freq_hz,
            w_rad_per_s: w,
            lp_v,
            lp,
            p,
            free,
            decay_per_s: alpha,
            damped_hz: wd / TAU,
            lambda: Complex::new(-alpha, wd),
        }
    }

    /// Start of the segment, s.
    pub fn t0_s(&self) -> f64 {
        self.t0_s
    }

    /// The parts at `t_s`: `(e^{i w tau}, R e^{lambda tau}, e^{-p tau})`.
    #[inline(always)]
    fn parts(&self, t_s: f64) -> (Complex, Complex, f64) {
        let tau = t_s - self.t0_s;
        let (c1, s1) = fast_cos_sin(reduced_phase(self.freq_hz, tau));
        let (c2, s2) = fast_cos_sin(reduced_phase(self.damped_hz, tau));
        let decay = exp_neg(self.decay_per_s * tau);
        (
            Complex::new(c1, s1),
            self.free * Complex::new(c2 * decay, s2 * decay),
            (-self.p * tau).exp(),
        )
    }

    /// The angle and its derivatives from [`Self::parts`], times `scale`.
    #[inline(always)]
    fn jet_from_parts(&self, parts: (Complex, Complex, f64), scale: f64, out: &mut [f64]) {
        let (rotation, mut free, decay) = parts;
        let mut forced = self.forced * rotation;
        let mut lp = self.lp * decay;
        let iw = Complex::new(0.0, self.w_rad_per_s);
        for (k, o) in out.iter_mut().enumerate() {
            if k > 0 {
                forced = forced * iw;
                free = free * self.lambda;
                lp *= -self.p;
            }
            let dc = if k == 0 { self.dc_arcsec } else { 0.0 };
            *o = scale * (dc + forced.re + free.re + lp);
        }
    }

    /// The angle and its derivatives at `t_s`, times `scale`: `out[0] = scale theta`,
    /// `out[k] = scale d^k theta / dt^k` (`scale` = 1 gives arcsec and arcsec/s^k).
    #[inline]
    pub fn angle_jet(&self, t_s: f64, scale: f64, out: &mut [f64]) {
        self.jet_from_parts(self.parts(t_s), scale, out);
    }

    /// The state at `t_s` (amplifier output, angle, rate): one evaluation of the parts for
    /// the angle, the rate and the voltage.
    pub fn state_at(&self, t_s: f64) -> ResonatorState {
        let parts = self.parts(t_s);
        let mut jet = [0.0; 2];
        self.jet_from_parts(parts, 1.0, &mut jet);
        let (rotation, _, decay) = parts;
        let v = self.dc_v + (self.forced_v * rotation).re + self.lp_v * decay;
        ResonatorState {
            amp_output_v: v,
            angle_arcsec: jet[0],
            rate_arcsec_per_s: jet[1],
        }
    }

    /// The forced steady state at `t_s` (what the state would be had this drive always run).
    pub fn steady_state_at(&self, t_s: f64) -> ResonatorState {
        let tau = t_s - self.t0_s;
        let (c, s) = fast_cos_sin(reduced_phase(self.freq_hz, tau));
        let e = Complex::new(c, s);
        ResonatorState {
            amp_output_v: self.dc_v + (self.forced_v * e).re,
            angle_arcsec: self.dc_arcsec + (self.forced * e).re,
            rate_arcsec_per_s: (self.forced * e * Complex::new(0.0, self.w_rad_per_s)).re,
        }
    }

    /// Amplitude of the forced sinusoid of the angle, arcsec.
    pub fn forced_amplitude_arcsec(&self) -> f64 {
        self.forced.abs()
    }

    /// Amplitude of the free (ringing) mode at `t_s`, arcsec: the distance from the steady
    /// state, decaying as `e^{-w0 t/(2Q)}`.
    pub fn free_amplitude_arcsec(&self, t_s: f64) -> f64 {
        self.free.abs() * (-self.decay_per_s * (t_s - self.t0_s)).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_series_matches_libm() {
        for i in 0..=2000 {
            let x = i as f64 * 1e-5;
            let (a, b) = (exp_neg(x), (-x).exp());
            assert!((a - b).abs() <= 2.0 * f64::EPSILON, "{x}: {a} vs {b}");
        }
        assert_eq!(exp_neg(3.0), (-3.0f64).exp());
    }

    fn sys() -> LinearSystem {
        LinearSystem {
            w0_rad_per_s: TAU * 389.0,
            q: 1000.0,
            lowpass_rad_per_s: TAU * 3000.0,
            gain_arcsec_per_v: 0.06,
        }
    }

    #[test]
    fn the_start_state_is_reproduced() {
        let state = ResonatorState {
            amp_output_v: 1.5,
            angle_arcsec: -120.0,
            rate_arcsec_per_s: 3.0e5,
        };
        let f = Forcing {
            dc_v: 0.3,
            amplitude_v: 7.0,
            freq_hz: 391.0,
            phase_rad: 0.4,
        };
        let r = SegmentResponse::new(&sys(), &f, 2.5, &state);
        let s = r.state_at(2.5);
        // Rounding of sums of ~500 arcsec and ~1e6 arcsec/s terms.
        assert!((s.amp_output_v - 1.5).abs() < 1e-14);
        assert!((s.angle_arcsec + 120.0).abs() < 1e-12);
        assert!((s.rate_arcsec_per_s - 3.0e5).abs() < 1e-9);
    }

    #[test]
    fn a_steady_start_leaves_no_transient() {
        let f = Forcing {
            dc_v: 0.0,
            amplitude_v: 7.5,
            freq_hz: 389.0,
            phase_rad: 1.0,
        };
        let probe = SegmentResponse::new(&sys(), &f, 0.0, &ResonatorState::REST);
        let steady = probe.steady_state_at(0.0);
        let r = SegmentResponse::new(&sys(), &f, 0.0, &steady);
        assert!(r.free_amplitude_arcsec(0.0) < 1e-12 * r.forced_amplitude_arcsec());
        assert!(r.lp.abs() < 1e-12);
    }
}
