//! Stage 6a, dither stripping: the output angle is the counted (and compensated) beat phase
//! minus `K` times the dither angle the pick-off reports at the same instant, so an output
//! period may begin and end anywhere in the dither cycle (docs/physics.md section 12).
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
//! d_psi = Omega dt + K d_p + (lock-in, photodiode and pick-off noise)
//! ```
//!
//! and the exponentially weighted least-squares fit of `d_psi` on `[1, d_p]` (an intercept for
//! the input rate; with the second tap below, on `[1, d_p, d_p_previous]`) gives the `K` that
//! leaves the output uncorrelated with the pick-off.
//! Increments at output latches (100 Hz - 2 kHz, incommensurate with the dither) sample every
//! phase of the dither, so `d_p` spans +-2 amplitudes and the fit is well conditioned; the
//! pick-off's noise in the regressor biases `K` by its variance over the dither's, about 1e-6.
//!
//! The sums are `f32` (IEEE on both the M4F's FPU and the host: the same bits) and decay by
//! `1 - 1/memory` per update; the estimate replaces the starting `K` after
//! [`StripConfig::min_updates`] increments, and counts as converged when its standard error
//! (from the weighted residual) falls below [`StripConfig::converged_rel`] of `K`. An increment
//! with a fault (counter glitch, signal lost, pick-off at a rail, drive not locked) is not
//! learned from; the stripping itself goes on with the last `K`.
//!
//! # A pick-off out of phase
//!
//! A pick-off that lags the dither (the gauge, the preamplifier) by `tau` reads
//! `p(t) = G theta(t - tau)`: one coefficient would leave the quadrature part, `K A w tau`
//! (0.1 % of the dither per 0.4 us at 389 Hz: -60 dB needs the lag below 0.4 us). So the fit
//! has two taps, on the latch's own code and on the previous latch's:
//! `dither = K (p_k - mid) + K' (p_{k-1} - mid)`. Two samples of one sinusoid a sync period
//! apart span every phase of it (unless the sync is at the dither frequency or twice it, where
//! the fit falls back to one tap), so the pair reproduces the dither in the count whatever the
//! pick-off's phase at the dither frequency; `K'` is about `K w tau / sin(w dt)`, small, and
//! adds little of the pick-off's noise. The two taps assume a steady sync period: a missed
//! sync leaves one record off by `K'` times the dither's step.
//!
//! # The innovation gate
//!
//! A stripped increment is compared with the recent ones ([`StripConfig::innovation_limit_fringes`]):
//! a pick-off that stops reporting the dither (a broken wire reads its offset) leaves the dither
//! itself in the increment, hundreds of fringes, and the latch is flagged before the dither
//! supervisor has even noticed; the record is then invalid (`record.rs`).

use crate::units::Q32_PER_FRINGE;

/// Settings of the stripper (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StripConfig {
    /// The `K` to start from, fringes per pick-off code (the profile's nominal pick-off
    /// sensitivity over the nominal scale factor, or the value stored with the calibration).
    pub initial_k: f32,
    /// The pick-off code of a zero dither angle.
    pub mid_code: u16,
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
    /// For a pick-off of `arcsec_per_code` read by a gyro of `scale_factor_arcsec` per fringe,
    /// centred at `mid_code`: memory 4096 increments (4 s at a 1 kHz sync), the fit in use
    /// after 64, converged at 1e-4.
    pub fn for_pickoff(arcsec_per_code: f64, scale_factor_arcsec: f64, mid_code: u16) -> Self {
        Self {
            initial_k: (arcsec_per_code / scale_factor_arcsec) as f32,
            mid_code,
            memory_updates: 4096,
            min_updates: 64,
            converged_rel: 1e-4,
            innovation_limit_fringes: 100.0,
            rail_margin_codes: 2,
        }
    }

    /// True when `code` is at a rail of the 12-bit converter.
    pub fn at_rail(&self, code: u16) -> bool {
        code < self.rail_margin_codes || code > 4095 - self.rail_margin_codes
    }
}

/// The state of `K`'s fit, as `status` reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StripStatus {
    /// `K` in use, fringes per pick-off code (the tap on the latch's own pick-off code).
    pub k: f32,
    /// The tap on the previous latch's code, fringes per code: the pick-off's phase error
    /// (0 for a pick-off in phase with the dither).
    pub k_previous: f32,
    /// Relative standard error of the fitted `K` (infinite before the fit is in use).
    pub k_std_rel: f32,
    /// Increments learned from since start (saturating).
    pub updates: u32,
    /// The fit is in use and its standard error is below [`StripConfig::converged_rel`].
    pub converged: bool,
}

/// The stripper's running state.
#[derive(Clone, Copy, Debug)]
pub struct DitherStripper {
    k: f32,
    k_previous: f32,
    /// Weighted sums of the regression of `d_psi` on `[1, d_p, d_p_previous]`: 1, x1, x2,
    /// x1 x1, x1 x2, x2 x2, y, x1 y, x2 y (fringes and codes); and of the squared a-priori
    /// residual (the prediction error before each update: no cancellation between large sums).
    s: [f32; 9],
    srr: f32,
    sr0: f32,
    updates: u32,
    std_rel: f32,
    /// The previous latch: phase (Q32 fringes, wrapping), its pick-off code and the code before
    /// it, while the chain of latches holds.
    previous: Option<(i64, u16, Option<u16>)>,
    /// The recent stripped increment, fringes (the innovation gate's prediction: an average
    /// with gain 1/2, so it follows a changing rate within two latches).
    recent_increment: Option<f32>,
    /// Consecutive increments the gate rejected.
    rejections: u32,
}

/// Consecutive rejections after which the gate's prediction is learned anew.
const MAX_REJECTIONS: u32 = 16;
/// Below this normalised determinant of the two taps' regressors (the latches sample the dither
/// near twice its frequency or at it, where the two codes carry the same information) the
/// fit keeps one tap.
const MIN_TWO_TAP_DETERMINANT: f32 = 0.02;

/// One stripped latch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stripped {
    /// The phase without the dither, Q32 fringes (wrapping like the phase).
    pub phase_q32: i64,
    /// The increment since the previous latch broke the innovation gate: the pick-off and the
    /// count disagree about the dither.
    pub implausible: bool,
}

impl DitherStripper {
    /// A stripper starting from `config.initial_k`.
    pub fn new(config: &StripConfig) -> Self {
        Self {
            k: config.initial_k,
            k_previous: 0.0,
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

    /// Starts from stored taps `k` and `k_previous` and forgets the fit.
    pub fn restart_from(&mut self, config: &StripConfig, k: f32, k_previous: f32) {
        *self = Self::new(&StripConfig {
            initial_k: k,
            ..*config
        });
        self.k_previous = k_previous;
    }

    /// The dither in the count at a latch, fringes: the two taps on this latch's code and the
    /// previous one's (this one's twice when there is none).
    fn dither_fringes(&self, config: &StripConfig, code: u16, previous: Option<u16>) -> f32 {
        let mid = f32::from(config.mid_code);
        let p = f32::from(code) - mid;
        let p1 = previous.map_or(p, |c| f32::from(c) - mid);
        self.k * p + self.k_previous * p1
    }

    /// The stripped phase at one latch: `phase_q32 - K (p - mid) - K' (p_previous - mid)`, and
    /// whether the increment since the previous latch passes the innovation gate. `usable`
    /// false (a fault in the period) leaves the fit alone and breaks the chain of increments;
    /// an implausible increment is not learned from either.
    pub fn strip(
        &mut self,
        config: &StripConfig,
        phase_q32: i64,
        pickoff_code: u16,
        usable: bool,
    ) -> Stripped {
        let mut implausible = false;
        let before = self.previous;
        let previous_code = before.map(|(_, code, _)| code);
        if usable {
            if let Some((phase0, code0, code00)) = before {
                let d_psi = (phase_q32.wrapping_sub(phase0) as f64 / Q32_PER_FRINGE) as f32;
                let increment = d_psi
                    - (self.dither_fringes(config, pickoff_code, Some(code0))
                        - self.dither_fringes(config, code0, code00));
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
                    if let Some(code00) = code00 {
                        let x1 = f32::from(pickoff_code) - f32::from(code0);
                        let x2 = f32::from(code0) - f32::from(code00);
                        self.learn(config, d_psi, x1, x2);
                    }
                    self.recent_increment = Some(match self.recent_increment {
                        Some(recent) => recent + 0.5 * (increment - recent),
                        None => increment,
                    });
                }
            }
            self.previous = Some((phase_q32, pickoff_code, previous_code));
        } else {
            self.previous = None;
            self.recent_increment = None;
        }
        let dither = self.dither_fringes(
            config,
            pickoff_code,
            if usable { previous_code } else { None },
        );
        Stripped {
            phase_q32: phase_q32.wrapping_sub((dither as f64 * Q32_PER_FRINGE) as i64),
            implausible,
        }
    }

    fn learn(&mut self, config: &StripConfig, y: f32, x1: f32, x2: f32) {
        let decay = 1.0 - 1.0 / config.memory_updates.max(2) as f32;
        let in_use = self.updates >= config.min_updates.max(4);
        let s = &mut self.s;
        if in_use {
            let intercept = (s[6] - self.k * s[1] - self.k_previous * s[2]) / s[0];
            let r = y - self.k * x1 - self.k_previous * x2 - intercept;
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
        let (k, k_previous, var_factor) = if det > MIN_TWO_TAP_DETERMINANT * c11 * c22 {
            (
                (c1y * c22 - c2y * c12) / det,
                (c2y * c11 - c1y * c12) / det,
                c22 / det,
            )
        } else {
            (c1y / c11, 0.0, 1.0 / c11)
        };
        if !(k.is_finite() && k_previous.is_finite()) || k == 0.0 {
            return;
        }
        self.k = k;
        self.k_previous = k_previous;
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
            k_previous: self.k_previous,
            k_std_rel: if in_use { self.std_rel } else { f32::INFINITY },
            updates: self.updates,
            converged: in_use && self.std_rel < config.converged_rel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(k: f32) -> StripConfig {
        StripConfig {
            initial_k: k,
            ..StripConfig::for_pickoff(0.4, 1.8655, 2048)
        }
    }

    /// A synthetic dither seen by the count (K_true fringes per code) and the pick-off: the
    /// fit finds K_true from a 5 % error, and the stripped phase is the input angle alone.
    #[test]
    fn learns_k_and_strips_the_dither() {
        let k_true = 0.4 / 1.8655 * 1.05;
        let cfg = config(0.4 / 1.8655);
        let mut s = DitherStripper::new(&cfg);
        let rate_fringes_per_s = 3.0;
        let (mut worst, mut n) = (0.0f64, 0);
        for i in 0..20_000 {
            let t = i as f64 * 1e-3;
            let dither_codes = 1125.0 * (core::f64::consts::TAU * 389.0 * t).sin();
            let code = (2048.0 + dither_codes).round();
            let psi = rate_fringes_per_s * t + k_true * (code - 2048.0);
            let out = s
                .strip(&cfg, (psi * Q32_PER_FRINGE) as i64, code as u16, true)
                .phase_q32;
            let err = out as f64 / Q32_PER_FRINGE - rate_fringes_per_s * t;
            if i > 2000 {
                worst = worst.max(err.abs());
                n += 1;
            }
        }
        let st = s.status(&cfg);
        // The fit is exact on noise-free data up to f32 rounding of the sums (1e-6 relative).
        assert!(((st.k as f64) / k_true - 1.0).abs() < 1e-5, "{st:?}");
        assert!(st.converged, "{st:?}");
        // Residual: the fit's f32 precision (~1e-5 of K) times the 240-fringe dither, 2.2e-3
        // fringes measured; 0.004 arcsec, against 0.5 arcsec of pick-off noise on a board.
        assert!(worst < 5e-3, "worst {worst} fringes over {n} latches");
    }

    /// A fault breaks the chain: the increment across it is not learned from.
    #[test]
    fn a_fault_is_not_learned_from() {
        let cfg = config(0.2);
        let mut s = DitherStripper::new(&cfg);
        s.strip(&cfg, 0, 2048, true);
        s.strip(&cfg, 1 << 40, 3000, false);
        s.strip(&cfg, 1 << 41, 100, true);
        assert_eq!(s.status(&cfg).updates, 0);
        assert_eq!(s.status(&cfg).k, 0.2);
        assert!(!s.status(&cfg).converged);
    }

    /// A pick-off that stops reporting the dither (it reads its offset) breaks the gate at
    /// once: the increment then carries the dither itself.
    #[test]
    fn a_silent_pickoff_breaks_the_innovation_gate() {
        let cfg = config(0.2144);
        let mut s = DitherStripper::new(&cfg);
        let mut flagged = 0;
        for i in 0..2000 {
            let t = i as f64 * 1e-3;
            let lost = i >= 1000;
            let dither_codes = 1125.0 * (core::f64::consts::TAU * 389.0 * t).sin();
            let psi = 0.2144 * dither_codes;
            let code = if lost {
                2048.0
            } else {
                2048.0 + dither_codes.round()
            };
            let out = s.strip(&cfg, (psi * Q32_PER_FRINGE) as i64, code as u16, true);
            assert!(lost || !out.implausible, "latch {i}");
            flagged += usize::from(out.implausible);
        }
        // 389 Hz seen at 1 kHz: the dither increment exceeds the 100-fringe gate at most
        // latches (the rest pass with an error inside the gate).
        assert!(flagged > 600, "{flagged} of 1000 flagged");
    }

    /// A pick-off lagging the dither by 5 us with a 3 % gain error: the two taps strip the
    /// dither to the noise-free residual of f32 rounding (a single K would leave 12 mrad of
    /// quadrature, 2.9 fringes).
    #[test]
    fn two_taps_strip_a_lagging_pickoff() {
        let k_nominal = 0.4 / 1.8655;
        let cfg = config(k_nominal as f32);
        let mut s = DitherStripper::new(&cfg);
        let (lag_s, gain) = (5e-6, 1.03);
        let mut worst = 0.0f64;
        for i in 0..20_000 {
            let t = i as f64 * 1e-3;
            let w = core::f64::consts::TAU * 389.0;
            let dither_codes = 1125.0 * (w * t).sin();
            let code = (2048.0 + gain * 1125.0 * (w * (t - lag_s)).sin()).round();
            let psi = 2.5 * t + k_nominal * dither_codes;
            let out = s
                .strip(&cfg, (psi * Q32_PER_FRINGE) as i64, code as u16, true)
                .phase_q32;
            if i > 2000 {
                let err = out as f64 / Q32_PER_FRINGE - 2.5 * t;
                worst = worst.max(err.abs());
            }
        }
        let st = s.status(&cfg);
        // The codes' rounding (0.29 codes rms) is the noise here: 0.06 fringes rms, 0.25 worst.
        assert!(worst < 0.35, "worst {worst} fringes; {st:?}");
        assert!(st.k_previous.abs() > 1e-4, "{st:?}");
    }

    #[test]
    fn rails_are_detected() {
        let cfg = config(0.2);
        assert!(cfg.at_rail(0) && cfg.at_rail(1) && cfg.at_rail(4095) && cfg.at_rail(4094));
        assert!(!cfg.at_rail(2) && !cfg.at_rail(4093) && !cfg.at_rail(2048));
    }
}
