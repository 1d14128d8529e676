//! Stage 6a, dither stripping: the output angle is the counted (and compensated) beat phase
//! minus `K` times the dither angle the pick-off reports at the same instant, so an output
//! period may begin and end anywhere in the dither cycle (docs/physics.md section 12). The
//! pick-off's dither at the latch comes from the model of its 40 kHz stream
//! ([`super::dither_model`]), in phase and in quadrature, far below one conversion's noise.
//!
//! # K, and how it is learned
//!
//! `K` is fringes per pick-off ADC code: the pick-off's sensitivity (nominally
//! `BoardProfile::pickoff_arcsec_per_code`) over the gyro's scale factor. Neither is known to
//! better than a few per cent on a real board (the gauge's gain, the amplifier, ageing), and a
//! 1 % error leaves 1 % of the ~480-fringe dither in the output. So `K` is fitted online, from
//! what the board measures: between two output latches the phase moves by
//!
//! ```text
//! d_psi = Omega dt + K d_p + K_q d_q + (lock-in, photodiode and model noise)
//! ```
//!
//! with p and q the modelled dither in phase and in quadrature, and the exponentially weighted
//! least-squares fit of `d_psi` on `[1, d_p, d_q]` (an intercept for the input rate) gives the
//! `K` that leaves the output uncorrelated with the pick-off.
//! Increments at output latches (100 Hz - 2 kHz, incommensurate with the dither) sample every
//! phase of the dither, so `d_p` and `d_q` span +-2 amplitudes and the fit is well conditioned.
//!
//! The sums are `f32` (IEEE on both the M4F's FPU and the host: the same bits) and decay by
//! `1 - 1/memory` per update; the estimate replaces the starting `K` after
//! [`StripConfig::min_updates`] increments, and counts as converged when its standard error
//! (from the weighted residual) falls below [`StripConfig::converged_rel`] of `K`. An increment
//! with a fault (counter glitch, signal lost, pick-off at a rail, drive not locked, no valid
//! model) is not learned from, and breaks the chain of increments.
//!
//! # A pick-off out of phase
//!
//! A pick-off that lags the dither (the gauge, the preamplifier) by `tau` reads
//! `p(t) = G theta(t - tau)`: `K` alone would leave the quadrature part, `K A w tau`
//! (0.1 % of the dither per 0.4 us at 389 Hz: -60 dB needs the lag below 0.4 us). The dither
//! in the count is `(cos(w tau) p - sin(w tau) q) / G`, so the quadrature tap
//! `K_q = -K tan(w tau)` takes it out whatever the sync, and measures the lag:
//! [`StripStatus::pickoff_lag_s`], which the turnaround schedule subtracts (the comparator
//! edges lag by the same `tau`: docs/physics.md pitfall 2).
//!
//! # The innovation gate
//!
//! A stripped increment is compared with the recent ones ([`StripConfig::innovation_limit_fringes`]):
//! a pick-off that stops reporting the dither (a broken wire reads its offset) leaves the dither
//! itself in the increment, hundreds of fringes, and the latch is flagged before the dither
//! supervisor has even noticed; the record is then invalid (`record.rs`).

use super::dither_model::DitherEstimate;
use crate::sample::AdcCode;
use crate::units::{PhaseDelta, TotalPhase, Q32_PER_FRINGE};

/// Settings of the stripper (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StripConfig {
    /// The `K` to start from, fringes per pick-off code (the profile's nominal pick-off
    /// sensitivity over the nominal scale factor, or the value stored with the calibration).
    pub initial_k: f32,
    /// Memory of the fit, increments: the sums decay by `1 - 1/memory` per increment.
    pub memory_updates: u32,
    /// Increments before the fitted `K` replaces the starting one.
    pub min_updates: u32,
    /// Relative standard error of `K` below which it counts as converged.
    pub converged_rel: f32,
    /// Innovation gate, fringes: a latch whose stripped increment departs from the recent
    /// increments by more than this is implausible (a pick-off that stopped reporting the
    /// dither leaves the dither itself, hundreds of fringes, in the increment). It tolerates an
    /// angular acceleration of `limit / (2 dt^2)`: 26000 deg/s^2 at a 1 kHz sync, 260 deg/s^2
    /// at 100 Hz, for the default 100 fringes (187 arcsec).
    pub innovation_limit_fringes: f32,
    /// Codes at (or beyond) which the pick-off counts as clipped: `0..rail_margin` and
    /// `4095 - rail_margin..=4095` (a saturated pick-off does not report the dither angle).
    pub rail_margin_codes: u16,
}

impl StripConfig {
    /// For a pick-off of `arcsec_per_code` read by a gyro of `scale_factor_arcsec` per fringe:
    /// memory 4096 increments (4 s at a 1 kHz sync), the fit in use after 64, converged at
    /// 1e-4.
    pub fn for_pickoff(arcsec_per_code: f64, scale_factor_arcsec: f64) -> Self {
        Self {
            initial_k: (arcsec_per_code / scale_factor_arcsec) as f32,
            memory_updates: 4096,
            min_updates: 64,
            converged_rel: 1e-4,
            innovation_limit_fringes: 100.0,
            rail_margin_codes: 2,
        }
    }

    /// True when `code` is at a rail of the 12-bit converter.
    pub fn at_rail(&self, code: AdcCode) -> bool {
        let code = code.to_bits();
        code < self.rail_margin_codes
            || code > AdcCode::FULL_SCALE.to_bits() - self.rail_margin_codes
    }
}

/// The state of `K`'s fit, as `status` reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StripStatus {
    /// `K` in use, fringes per pick-off code (the tap on the modelled dither in phase).
    pub k: f32,
    /// The tap on the modelled dither in quadrature, fringes per code: `-K tan(w tau)` for a
    /// pick-off lagging the dither by `tau` (0 for a pick-off in phase with it).
    pub k_quadrature: f32,
    /// Relative standard error of the fitted `K` (infinite before the fit is in use).
    pub k_std_rel: f32,
    /// Increments learned from since start (saturating).
    pub updates: u32,
    /// The fit is in use and its standard error is below [`StripConfig::converged_rel`].
    pub converged: bool,
}

impl StripStatus {
    /// How far the pick-off lags the dither, s, for a dither at `w_rad_per_s`:
    /// `atan(-K_q / K) / w` (negative: it leads). `None` before the fit converged.
    pub fn pickoff_lag_s(&self, w_rad_per_s: f32) -> Option<f32> {
        let lag = libm::atanf(-self.k_quadrature / self.k) / w_rad_per_s;
        (self.converged && lag.is_finite()).then_some(lag)
    }
}

/// The stripper's running state.
#[derive(Clone, Copy, Debug)]
pub struct DitherStripper {
    k: f32,
    k_quadrature: f32,
    /// Weighted sums of the regression of `d_psi` on `[1, d_p, d_q]`: 1, x1, x2,
    /// x1 x1, x1 x2, x2 x2, y, x1 y, x2 y (fringes and codes); and of the squared a-priori
    /// residual (the prediction error before each update: no cancellation between large sums).
    s: [f32; 9],
    srr: f32,
    sr0: f32,
    updates: u32,
    std_rel: f32,
    /// The previous latch: its phase and the modelled dither there (in phase, in quadrature),
    /// while the chain of latches holds.
    previous: Option<(TotalPhase, f32, f32)>,
    /// The recent stripped increment, fringes (the innovation gate's prediction: an average
    /// with gain 1/2, so it follows a changing rate within two latches).
    recent_increment: Option<f32>,
    /// Consecutive increments the gate rejected.
    rejections: u32,
}

/// Consecutive rejections after which the gate's prediction is learned anew.
const MAX_REJECTIONS: u32 = 16;
/// Below this normalised determinant of the two taps' regressors (the latches sample the dither
/// at its frequency or twice it, where the increments of p and q carry the same information)
/// the fit keeps one tap.
const MIN_TWO_TAP_DETERMINANT: f32 = 0.02;

/// One stripped latch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stripped {
    /// The phase without the dither (wrapping like the phase).
    pub phase: TotalPhase,
    /// The increment since the previous latch broke the innovation gate: the pick-off and the
    /// count disagree about the dither.
    pub implausible: bool,
}

impl DitherStripper {
    /// A stripper starting from `config.initial_k`.
    pub fn new(config: &StripConfig) -> Self {
        Self {
            k: config.initial_k,
            k_quadrature: 0.0,
            s: [0.0; 9],
            srr: 0.0,
            sr0: 0.0,
            updates: 0,
            std_rel: f32::INFINITY,
            previous: None,
            recent_increment: None,
            rejections: 0,
        }
    }

    /// Starts from stored taps `k` and `k_quadrature` and forgets the fit.
    pub fn restart_from(&mut self, config: &StripConfig, k: f32, k_quadrature: f32) {
        *self = Self::new(&StripConfig {
            initial_k: k,
            ..*config
        });
        self.k_quadrature = k_quadrature;
    }

    /// The dither in the count at a latch, fringes.
    fn dither_fringes(&self, dither: &DitherEstimate) -> f32 {
        self.k * dither.in_phase_codes + self.k_quadrature * dither.quadrature_codes
    }

    /// The stripped phase at one latch: `phase - K p - K_q q` with the modelled dither
    /// there, and whether the increment since the previous latch passes the innovation gate.
    /// No model, or `usable` false (a fault in the period), leaves the fit alone and breaks the
    /// chain of increments (the phase is then returned unstripped: the record is invalid); an
    /// implausible increment is not learned from either.
    pub fn strip(
        &mut self,
        config: &StripConfig,
        phase: TotalPhase,
        dither: Option<&DitherEstimate>,
        usable: bool,
    ) -> Stripped {
        let Some(dither) = dither.filter(|_| usable) else {
            self.previous = None;
            self.recent_increment = None;
            return Stripped {
                phase,
                implausible: false,
            };
        };
        let mut implausible = false;
        let dither_fringes = self.dither_fringes(dither);
        if let Some((phase0, p0, q0)) = self.previous {
            let d_psi = (phase - phase0).fringes_f64() as f32;
            let (x1, x2) = (dither.in_phase_codes - p0, dither.quadrature_codes - q0);
            let increment = d_psi - (self.k * x1 + self.k_quadrature * x2);
            if let Some(recent) = self.recent_increment {
                implausible = (increment - recent).abs() > config.innovation_limit_fringes;
            }
            if implausible {
                // The prediction stays; after a run of rejections (a real change of rate
                // beyond the gate) it is learned anew.
                self.rejections = self.rejections.saturating_add(1);
                if self.rejections >= MAX_REJECTIONS {
                    self.recent_increment = None;
                    self.rejections = 0;
                }
            } else {
                self.rejections = 0;
                self.learn(config, d_psi, x1, x2);
                self.recent_increment = Some(match self.recent_increment {
                    Some(recent) => recent + 0.5 * (increment - recent),
                    None => increment,
                });
            }
        }
        self.previous = Some((phase, dither.in_phase_codes, dither.quadrature_codes));
        let dither_q32 = (dither_fringes as f64 * Q32_PER_FRINGE) as i64;
        Stripped {
            phase: phase - PhaseDelta::from_q32(dither_q32),
            implausible,
        }
    }

    fn learn(&mut self, config: &StripConfig, y: f32, x1: f32, x2: f32) {
        let decay = 1.0 - 1.0 / config.memory_updates.max(2) as f32;
        let in_use = self.updates >= config.min_updates.max(4);
        let s = &mut self.s;
        if in_use {
            let intercept = (s[6] - self.k * s[1] - self.k_quadrature * s[2]) / s[0];
            let r = y - self.k * x1 - self.k_quadrature * x2 - intercept;
            self.srr = self.srr * decay + r * r;
            self.sr0 = self.sr0 * decay + 1.0;
        }
        for (sum, term) in
            s.iter_mut()
                .zip([1.0, x1, x2, x1 * x1, x1 * x2, x2 * x2, y, x1 * y, x2 * y])
        {
            *sum = *sum * decay + term;
        }
        self.updates = self.updates.saturating_add(1);
        if self.updates < config.min_updates.max(4) {
            return;
        }
        // Centred sums: the intercept (input rate) taken out.
        let n = s[0];
        let c11 = s[3] - s[1] * s[1] / n;
        let c12 = s[4] - s[1] * s[2] / n;
        let c22 = s[5] - s[2] * s[2] / n;
        let c1y = s[7] - s[1] * s[6] / n;
        let c2y = s[8] - s[2] * s[6] / n;
        if c11.is_nan() || c11 <= 0.0 || c22.is_nan() || c22 <= 0.0 {
            return;
        }
        let det = c11 * c22 - c12 * c12;
        let (k, k_quadrature, var_factor) = if det > MIN_TWO_TAP_DETERMINANT * c11 * c22 {
            (
                (c1y * c22 - c2y * c12) / det,
                (c2y * c11 - c1y * c12) / det,
                c22 / det,
            )
        } else {
            (c1y / c11, 0.0, 1.0 / c11)
        };
        if !(k.is_finite() && k_quadrature.is_finite()) || k == 0.0 {
            return;
        }
        self.k = k;
        self.k_quadrature = k_quadrature;
        if in_use {
            let residual_var = self.srr / self.sr0.max(1.0);
            self.std_rel = libm::sqrtf(residual_var * var_factor) / k.abs();
        }
    }

    /// `K` and the state of its fit.
    pub fn status(&self, config: &StripConfig) -> StripStatus {
        let in_use = self.updates >= config.min_updates.max(4);
        StripStatus {
            k: self.k,
            k_quadrature: self.k_quadrature,
            k_std_rel: if in_use { self.std_rel } else { f32::INFINITY },
            updates: self.updates,
            converged: in_use && self.std_rel < config.converged_rel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::TAU;

    fn config(k: f32) -> StripConfig {
        StripConfig {
            initial_k: k,
            ..StripConfig::for_pickoff(0.4, 1.8655)
        }
    }

    /// The modelled dither of a pick-off reading `amp` codes of a 389 Hz dither lagging by
    /// `lag_s`, at `t` s (what `dither_model` gives, noise-free).
    fn model(amp: f64, lag_s: f64, t: f64) -> DitherEstimate {
        let x = TAU * 389.0 * (t - lag_s);
        DitherEstimate {
            in_phase_codes: (amp * x.cos()) as f32,
            quadrature_codes: (amp * x.sin()) as f32,
            offset_codes: 0.0,
        }
    }

    /// A synthetic dither seen by the count (K_true fringes per code) and the model: the fit
    /// finds K_true from a 5 % error, and the stripped phase is the input angle alone.
    #[test]
    fn learns_k_and_strips_the_dither() {
        let k_true = 0.4 / 1.8655 * 1.05;
        let cfg = config(0.4 / 1.8655);
        let mut s = DitherStripper::new(&cfg);
        let rate_fringes_per_s = 3.0;
        let (mut worst, mut n) = (0.0f64, 0);
        for i in 0..20_000 {
            let t = i as f64 * 1e-3;
            let m = model(1125.0, 0.0, t);
            let psi = rate_fringes_per_s * t + k_true * m.in_phase_codes as f64;
            let out = s
                .strip(
                    &cfg,
                    TotalPhase::from_q32((psi * Q32_PER_FRINGE) as i64),
                    Some(&m),
                    true,
                )
                .phase;
            let err = out.to_q32() as f64 / Q32_PER_FRINGE - rate_fringes_per_s * t;
            if i > 2000 {
                worst = worst.max(err.abs());
                n += 1;
            }
        }
        let st = s.status(&cfg);
        // The fit is exact on noise-free data up to f32 rounding of the sums (1e-6 relative).
        assert!(((st.k as f64) / k_true - 1.0).abs() < 1e-5, "{st:?}");
        assert!(st.converged, "{st:?}");
        assert!(st.k_quadrature.abs() < 1e-5 * st.k, "{st:?}");
        // Residual: the fit's f32 precision (~1e-5 of K) times the 240-fringe dither;
        // 0.004 arcsec, against the model's 0.04 arcsec on a board.
        assert!(worst < 5e-3, "worst {worst} fringes over {n} latches");
    }

    /// A fault breaks the chain: the increment across it is not learned from; no model is the
    /// same.
    #[test]
    fn a_fault_or_no_model_is_not_learned_from() {
        let cfg = config(0.2);
        let mut s = DitherStripper::new(&cfg);
        s.strip(
            &cfg,
            TotalPhase::from_q32(0),
            Some(&model(1000.0, 0.0, 0.0)),
            true,
        );
        s.strip(
            &cfg,
            TotalPhase::from_q32(1 << 40),
            Some(&model(1000.0, 0.0, 1e-3)),
            false,
        );
        s.strip(
            &cfg,
            TotalPhase::from_q32(1 << 41),
            Some(&model(1000.0, 0.0, 2e-3)),
            true,
        );
        s.strip(&cfg, TotalPhase::from_q32(1 << 42), None, true);
        s.strip(
            &cfg,
            TotalPhase::from_q32(1 << 43),
            Some(&model(1000.0, 0.0, 4e-3)),
            true,
        );
        assert_eq!(s.status(&cfg).updates, 0);
        assert_eq!(s.status(&cfg).k, 0.2);
        assert!(!s.status(&cfg).converged);
    }

    /// A pick-off that stops reporting the dither (the model of a flat pick-off) breaks the
    /// gate at once: the increment then carries the dither itself.
    #[test]
    fn a_silent_pickoff_breaks_the_innovation_gate() {
        let cfg = config(0.2144);
        let mut s = DitherStripper::new(&cfg);
        let mut flagged = 0;
        for i in 0..2000 {
            let t = i as f64 * 1e-3;
            let lost = i >= 1000;
            let m = model(1125.0, 0.0, t);
            let psi = 0.2144 * m.in_phase_codes as f64;
            let seen = if lost { model(0.0, 0.0, t) } else { m };
            let out = s.strip(
                &cfg,
                TotalPhase::from_q32((psi * Q32_PER_FRINGE) as i64),
                Some(&seen),
                true,
            );
            assert!(lost || !out.implausible, "latch {i}");
            flagged += usize::from(out.implausible);
        }
        // 389 Hz seen at 1 kHz: the dither increment exceeds the 100-fringe gate at most
        // latches (the rest pass with an error inside the gate).
        assert!(flagged > 600, "{flagged} of 1000 flagged");
    }

    /// A pick-off lagging the dither by 5 us with a 3 % gain error: the quadrature tap strips
    /// the dither to the f32 rounding (K alone would leave 12 mrad of quadrature, 2.9 fringes),
    /// and gives back the lag (5 us to 1 ns).
    #[test]
    fn the_quadrature_tap_strips_a_lagging_pickoff_and_measures_its_lag() {
        let k_nominal = 0.4 / 1.8655;
        let cfg = config(k_nominal as f32);
        let mut s = DitherStripper::new(&cfg);
        let (lag_s, gain) = (5e-6, 1.03);
        let mut worst = 0.0f64;
        for i in 0..20_000 {
            let t = i as f64 * 1e-3;
            let dither_codes = 1125.0 * (TAU * 389.0 * t).cos();
            let psi = 2.5 * t + k_nominal * dither_codes;
            let m = model(gain * 1125.0, lag_s, t);
            let out = s
                .strip(
                    &cfg,
                    TotalPhase::from_q32((psi * Q32_PER_FRINGE) as i64),
                    Some(&m),
                    true,
                )
                .phase;
            if i > 2000 {
                let err = out.to_q32() as f64 / Q32_PER_FRINGE - 2.5 * t;
                worst = worst.max(err.abs());
            }
        }
        let st = s.status(&cfg);
        assert!(worst < 5e-3, "worst {worst} fringes; {st:?}");
        let lag = st.pickoff_lag_s((TAU * 389.0) as f32).unwrap();
        assert!((lag as f64 - lag_s).abs() < 1e-9, "{lag} s; {st:?}");
    }

    #[test]
    fn rails_are_detected() {
        let cfg = config(0.2);
        let at_rail = |c| cfg.at_rail(AdcCode::new(c).unwrap());
        assert!(at_rail(0) && at_rail(1) && at_rail(4095) && at_rail(4094));
        assert!(!at_rail(2) && !at_rail(4093) && !at_rail(2048));
    }
}
