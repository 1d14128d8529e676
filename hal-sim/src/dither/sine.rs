//! The prescribed (`ideal`) dither: a sine oscillation of the gyro body whose *angle* is known
//! in closed form, so the integrator never has to integrate the ~3.7e6 rad/s dither rate. This
//! is the paper's idealised experiment and the model the theory tests hold the integrator
//! against; the driven resonator is [`super::driven`].
//!
//! Model (all in beat phase: rad, rad/s):
//!
//! ```text
//! theta_d(t) = -A(t) cos(w_d t),        A(t) = A0 (1 + m(t)),
//! rate_d(t)  = A(t) w_d sin(w_d t) - A'(t) cos(w_d t)
//! ```
//!
//! so the steady dither rate is `Omega_d sin(w_d t)` with `Omega_d = A0 w_d`, as in Eq. 6.
//! `m(t)` is a seeded sum of low-frequency sinusoids (see
//! [`super::AmplitudeModulation`]): smooth at every order, so the amplitude of a
//! high-Q resonator drifts slowly and never jumps from one half-cycle to the next. The
//! "random-noise dither" is the same process with a much larger depth and bandwidth; both
//! can be on at once (their modulations add).
//!
//! Precision: `w_d t` is reduced with an error-free product (`fma`), so the dither angle
//! stays exact to ~1e-13 rad after hours of simulated time (a plain `w_d * t` would lose
//! ~1e-6 rad at t = 1 h).
//!
//! The dither pick-off: a piezo strain pick-off reports the spring's deflection, i.e. the
//! dither angle; the instants where the dither rate is zero (the pick-off's extremes, the
//! zero crossings of its derivative or of a 90-degree-shifted copy) are the *dither-only*
//! turnarounds. They differ from the true turnarounds (zeros of dither + input + noise rate)
//! by about `Omega_i / psi_ddot` (docs/physics.md pitfall 3), which is why both are offered.

use super::MAX_JET;
use super::{AmplitudeModulation, DitherSpec};
use crate::trig::reduced_phase;
use crate::units::beat_rad_to_arcsec;
use core::f64::consts::TAU;
use firmware::sample::TurnaroundKind;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::cell::RefCell;

/// One modulation tone: `a sin(nu t + phase)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Tone {
    a: f64,
    nu_rad_per_s: f64,
    phase_rad: f64,
}

/// The prescribed sine dither of one gyro (immutable).
#[derive(Clone, Debug)]
pub struct SineDither {
    freq_hz: f64,
    w_rad_per_s: f64,
    amp0_rad: f64,
    tones: Vec<Tone>,
    scale_factor_arcsec: f64,
    /// Grid step of the modulation cache, s.
    window_s: f64,
    cache: RefCell<[Option<ModWindow>; CACHE_SLOTS]>,
}

/// Degree of the cached Taylor polynomial of the modulation.
const MOD_DEGREE: usize = 12;
const CACHE_SLOTS: usize = 4;

/// `m(t)` on one window of a fixed time grid as a Taylor polynomial about the window's
/// centre (exact to rounding: `nu tau <= 0.15`, so the remainder is < 1e-19).
#[derive(Clone, Copy, Debug)]
struct ModWindow {
    index: i64,
    t_c: f64,
    c: [f64; MOD_DEGREE + 1],
}

/// `sum a sin(nu t + phase)` of `tones` at `t_s`: the relative modulation `m(t)`.
pub(crate) fn modulation_at(tones: &[Tone], t_s: f64) -> f64 {
    tones
        .iter()
        .map(|t| t.a * (t.nu_rad_per_s * t_s + t.phase_rad).sin())
        .sum()
}

/// The tones of `m` (none when it is off), seeded.
pub(crate) fn draw_tones(m: &AmplitudeModulation, seed: u64, out: &mut Vec<Tone>) {
    if m.relative_rms <= 0.0 {
        return;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let a = m.relative_rms * (2.0 / m.tones as f64).sqrt();
    for _ in 0..m.tones {
        let f = m.min_hz + (m.max_hz - m.min_hz) * rng.random::<f64>();
        out.push(Tone {
            a,
            nu_rad_per_s: TAU * f,
            phase_rad: TAU * rng.random::<f64>(),
        });
    }
}

/// Veltkamp split of `a` into two 26-bit halves (`a = hi + lo` exactly).
fn binomial_row(n: usize) -> [f64; MAX_JET] {
    let mut row = [0.0; MAX_JET];
    row[0] = 1.0;
    for k in 1..=n {
        row[k] = row[k - 1] * (n + 1 - k) as f64 / k as f64;
    }
    row
}

impl SineDither {
    /// Builds the dither of `spec` (no dither: amplitude 0, every value 0).
    pub fn new(spec: &DitherSpec) -> Self {
        let mut tones = Vec::new();
        if spec.on {
            draw_tones(&spec.jitter, spec.seed ^ 0x6a09_e667_f3bc_c908, &mut tones);
            draw_tones(&spec.noise, spec.seed ^ 0xbb67_ae85_84ca_a73b, &mut tones);
        }
        Self {
            freq_hz: if spec.on { spec.hz } else { 0.0 },
            w_rad_per_s: spec.w_rad_per_s,
            amp0_rad: spec.amp_rad,
            window_s: {
                let f_max = tones.iter().map(|t| t.nu_rad_per_s).fold(0.0, f64::max);
                if f_max > 0.0 {
                    (0.3 / f_max).min(1e-3)
                } else {
                    1e-3
                }
            },
            tones,
            scale_factor_arcsec: spec.scale_factor_arcsec,
            cache: RefCell::new([None; CACHE_SLOTS]),
        }
    }

    /// True if there is a dither.
    pub fn is_on(&self) -> bool {
        self.amp0_rad > 0.0
    }

    /// Dither frequency, Hz (0 if off).
    pub fn freq_hz(&self) -> f64 {
        self.freq_hz
    }

    /// `m(t)` and its derivatives summed over the tones (exact, slow: one sincos per tone).
    fn modulation_jet_exact(&self, t_s: f64, out: &mut [f64]) {
        out.fill(0.0);
        for tone in &self.tones {
            // Reduce mod 2 pi by the rounding trick (fmod is a slow libm call); the error,
            // ~n ulp(2 pi) ~ 1e-10 rad of modulation phase after hours, is far below anything
            // a modulation depth of <= 0.3 could show.
            const MAGIC: f64 = 6_755_399_441_055_744.0;
            let x = tone.nu_rad_per_s * t_s + tone.phase_rad;
            let n = (x * (1.0 / TAU) + MAGIC) - MAGIC;
            let (c, s) = crate::trig::fast_cos_sin(x - n * TAU);
            crate::input::add_sinusoid_derivs_sc(tone.a, tone.nu_rad_per_s, s, c, out);
        }
    }

    /// Relative amplitude modulation `m(t)` and its derivatives, from a Taylor polynomial
    /// on a fixed time grid (a pure function of `t`, so results never depend on the order
    /// of queries), cached for a few windows: the integrator asks for `theta` hundreds of
    /// times per half cycle, and a dozen tones cost a dozen sincos per ask.
    fn modulation_jet(&self, t_s: f64, out: &mut [f64]) {
        let index = (t_s / self.window_s).floor() as i64;
        let slot = index.rem_euclid(CACHE_SLOTS as i64) as usize;
        let w = {
            let mut cache = self.cache.borrow_mut();
            match cache[slot] {
                Some(w) if w.index == index => w,
                _ => {
                    let t_c = (index as f64 + 0.5) * self.window_s;
                    let mut d = [0.0; MOD_DEGREE + 1];
                    self.modulation_jet_exact(t_c, &mut d);
                    let mut c = [0.0; MOD_DEGREE + 1];
                    let mut fact = 1.0;
                    for (k, ck) in c.iter_mut().enumerate() {
                        if k > 0 {
                            fact *= k as f64;
                        }
                        *ck = d[k] / fact;
                    }
                    let w = ModWindow { index, t_c, c };
                    cache[slot] = Some(w);
                    w
                }
            }
        };
        let tau = t_s - w.t_c;
        // j-th derivative: sum_k c_k k!/(k-j)! tau^(k-j), by Horner on the shifted series.
        let mut falling = [1.0; MOD_DEGREE + 1];
        for (j, o) in out.iter_mut().enumerate() {
            if j > MOD_DEGREE {
                *o = 0.0;
                continue;
            }
            let mut acc = 0.0;
            for k in (j..=MOD_DEGREE).rev() {
                acc = acc * tau + w.c[k] * falling[k];
            }
            *o = acc;
            // falling[k] becomes k!/(k-j-1)! for the next order.
            for (k, f) in falling.iter_mut().enumerate() {
                *f *= k as f64 - j as f64;
            }
        }
    }

    /// Dither amplitude `A(t)`, rad of beat phase.
    pub fn amplitude_rad(&self, t_s: f64) -> f64 {
        let mut m = [0.0; 1];
        self.modulation_jet(t_s, &mut m);
        self.amp0_rad * (1.0 + m[0])
    }

    /// Dither angle `theta_d` and its derivatives at `t_s` (`out[1]` = dither rate, rad/s).
    /// `out.len() <= MAX_JET`.
    // Always inlined into `FreePhase::angle_jet` (the integrator's hottest call): left to the
    // heuristics it was not once the noise's jet grew the snapped grid's branch (+1 % of
    // instructions for the prescribed sine).
    #[inline(always)]
    pub fn angle_jet(&self, t_s: f64, out: &mut [f64]) {
        let n = out.len();
        out.fill(0.0);
        if !self.is_on() {
            return;
        }
        // -cos(x) = -sin(x + pi/2): pass sin and cos of x + pi/2, i.e. cos x and -sin x.
        let (c, s) = crate::trig::fast_cos_sin(reduced_phase(self.freq_hz, t_s));
        if self.tones.is_empty() {
            // A0 times the derivatives of -cos(w t), straight into `out` (no scratch to zero).
            crate::input::add_sinusoid_derivs_sc(-self.amp0_rad, self.w_rad_per_s, c, -s, out);
            return;
        }
        // g = -cos(w t) and its derivatives; A = A0 (1 + m).
        let mut g = [0.0; MAX_JET];
        crate::input::add_sinusoid_derivs_sc(-1.0, self.w_rad_per_s, c, -s, &mut g[..n]);
        let mut a = [0.0; MAX_JET];
        self.modulation_jet(t_s, &mut a[..n]);
        a[0] += 1.0;
        for (j, o) in out.iter_mut().enumerate() {
            let c = binomial_row(j);
            let mut s = 0.0;
            for k in 0..=j {
                s += c[k] * a[k] * g[j - k];
            }
            *o = self.amp0_rad * s;
        }
    }

    /// Dither angle, rad of beat phase.
    pub fn angle_rad(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 1];
        self.angle_jet(t_s, &mut d);
        d[0]
    }

    /// Dither rate, rad/s of beat phase.
    pub fn rate_rad_per_s(&self, t_s: f64) -> f64 {
        let mut d = [0.0; 2];
        self.angle_jet(t_s, &mut d);
        d[1]
    }

    /// What the strain pick-off reports: the dither deflection, arcsec of body angle.
    pub fn pickoff_angle_arcsec(&self, t_s: f64) -> f64 {
        beat_rad_to_arcsec(self.angle_rad(t_s), self.scale_factor_arcsec)
    }

    /// Time of the `n`-th peak of the unmodulated dither rate, `(n + 1/2) / (2 f_d)`:
    /// the middle of a half cycle, as far from any turnaround as possible.
    pub fn rate_peak_time_s(&self, n: u64) -> f64 {
        (n as f64 + 0.5) / (2.0 * self.freq_hz)
    }

    /// The first zero of the dither-only rate strictly after `t_s` (a pick-off turnaround),
    /// with its kind. `None` without dither.
    pub fn pickoff_turnaround_after(&self, t_s: f64) -> Option<(f64, TurnaroundKind)> {
        if !self.is_on() {
            return None;
        }
        // Unmodulated zeros at n / (2 f); the modulation moves them by ~A'/(A w) (tiny).
        let mut n = (2.0 * self.freq_hz * t_s).floor() as i64;
        loop {
            let mut t = n as f64 / (2.0 * self.freq_hz);
            for _ in 0..50 {
                let mut d = [0.0; 3];
                self.angle_jet(t, &mut d);
                let dt = d[1] / d[2];
                t -= dt;
                if dt.abs() < 1e-16 * (1.0 + t.abs()) {
                    break;
                }
            }
            if t > t_s {
                let mut d = [0.0; 3];
                self.angle_jet(t, &mut d);
                let kind = if d[2] > 0.0 {
                    TurnaroundKind::Plus
                } else {
                    TurnaroundKind::Minus
                };
                return Some((t, kind));
            }
            n += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::GyroParams;

    fn dither(jitter: f64) -> SineDither {
        let p = GyroParams {
            amplitude_jitter: AmplitudeModulation::jitter(jitter),
            ..Default::default()
        };
        SineDither::new(&p.dither_spec(&p.derive().unwrap()))
    }

    #[test]
    fn jet_is_consistent_with_finite_differences() {
        for jitter in [0.0, 0.01] {
            let d = dither(jitter);
            let t = 0.123_456;
            let mut j = [0.0; 6];
            d.angle_jet(t, &mut j);
            let h = 1e-7;
            for k in 0..5 {
                let mut a = [0.0; 6];
                let mut b = [0.0; 6];
                d.angle_jet(t + h, &mut a);
                d.angle_jet(t - h, &mut b);
                let fd = (a[k] - b[k]) / (2.0 * h);
                // Central difference: relative error ~ (w h)^2 / 6 ~ 1e-11, plus rounding.
                assert!(
                    (fd - j[k + 1]).abs()
                        < 1e-6
                            * j[k + 1]
                                .abs()
                                .max(1e-3 * d.amp0_rad * d.w_rad_per_s.powi(k as i32 + 1)),
                    "k={k} {fd} {}",
                    j[k + 1]
                );
            }
        }
    }

    #[test]
    fn cached_modulation_equals_the_tone_sum() {
        let p = GyroParams {
            amplitude_jitter: AmplitudeModulation::jitter(0.01),
            random_noise_dither: AmplitudeModulation::random_noise_dither(0.2),
            ..Default::default()
        };
        let d = SineDither::new(&p.dither_spec(&p.derive().unwrap()));
        for i in 0..2000 {
            let t = 3.7 * ((i as f64 * 0.618_033_988_749_895) % 1.0);
            let mut a = [0.0; 8];
            let mut b = [0.0; 8];
            d.modulation_jet(t, &mut a);
            d.modulation_jet_exact(t, &mut b);
            for k in 0..8 {
                // The k-th derivative of a degree-12 Taylor polynomial misses the remainder
                // ~(nu tau)^(13-k) / (13-k)! with nu tau <= 0.15 (relative to the k-th
                // derivative's scale 0.3 nu_max^k): 1e-13 up to k = 4 (all the far series
                // needs), 1e-9 beyond (only enters the near polynomial, times tau^k/k!).
                let scale = 0.3 * (TAU * 30.0f64).powi(k as i32);
                let tol = if k <= 4 { 1e-13 } else { 1e-9 };
                assert!(
                    (a[k] - b[k]).abs() < tol * scale,
                    "t {t} k {k}: {} vs {}",
                    a[k],
                    b[k]
                );
            }
        }
    }

    #[test]
    fn reduced_phase_is_exact_at_late_times() {
        let d = dither(0.0);
        // At t = 3600 s + 1/(4 f) the phase is pi/2 (+ 2 pi n), the rate at its peak.
        let t = 3600.0 + 1.0 / (4.0 * 389.0);
        let r = d.rate_rad_per_s(t) / (d.amp0_rad * d.w_rad_per_s);
        assert!((r - 1.0).abs() < 1e-12);
    }

    #[test]
    fn pickoff_turnarounds_alternate() {
        let d = dither(0.01);
        let (t1, k1) = d.pickoff_turnaround_after(0.01).unwrap();
        let (t2, k2) = d.pickoff_turnaround_after(t1).unwrap();
        assert_ne!(k1, k2);
        assert!(((t2 - t1) * 2.0 * 389.0 - 1.0).abs() < 1e-3);
        assert!(d.rate_rad_per_s(t1).abs() < 1e-6);
    }
}
