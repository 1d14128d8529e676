//! Online tracking of a and b (beyond the paper): a Kalman filter on the calibration model.
//!
//! The paper warms the gyro up for hours until Omega_L and eps are steady, then fits once.
//! Tracking instead follows their drift while the gyro runs outside the dead band: per cycle,
//! the output y = c + a P1 + b P2 + noise updates the estimate of (c, a, b). Each is modelled as
//! a random walk, with its own memory:
//!
//! - a and b drift slowly (temperature, ageing): memory `memory_cycles` (thousands of cycles);
//! - the intercept c is the input rate times the cycle time, which jumps whenever the vehicle or
//!   the table moves: short memory `intercept_memory_cycles`, so a rate step is absorbed by c
//!   within tens of cycles instead of leaking into a and b (which a single forgetting factor,
//!   plain RLS, would do: a rate step of 0.24 rad per cycle is 13 times the lock-in signal).
//!
//! A rate step still arrives as one huge innovation (thousands of sigma), which the filter
//! would partly trust. An innovation gate catches it: beyond `gate_sigma` it counts as a rate
//! change, goes wholly into the intercept (whose variance is re-opened) and leaves a and b alone.
//!
//! With measurement variance r and regressors of order one, a random walk of variance
//! r / N^2 per cycle gives a steady-state memory of about N cycles; r itself then only sets the
//! scale of the initial covariance. Inside the dead band the output carries no rate information
//! (the paper's point), so updates are frozen there: the caller says whether the cycle is
//! usable, typically |rate| > margin x Omega_L0 from the current estimate, and not flagged.
//!
//! [`TrackingLoop`] runs it in the cycle task: it estimates the rate from the uncompensated
//! output, uses a cycle only while that rate is outside the dead band (Chow's Omega_L0 from the
//! current estimate and the measured dither amplitude) and hands out new coefficients to stage
//! every so many used cycles.
//!
//! # Numerics
//! P1 and P2 are scaled by k_ref (~26 us) to order one, so the 3x3 covariance is well
//! conditioned in f64; it is re-symmetrised after every update. f64 is software floating point
//! on the M4F: about 80 operations per cycle, tens of microseconds at 389 Hz, run in the
//! low-priority cycle task, never in the turnaround interrupt.

use super::validation::chow_dead_band_rad_per_s;
use crate::signal::compensation::Coefficients;
use crate::signal::lockin::CycleRecord;

/// Tracker settings (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingConfig {
    /// Memory of a and b, cycles.
    pub memory_cycles: f64,
    /// Memory of the intercept (the input rate), cycles.
    pub intercept_memory_cycles: f64,
    /// Initial guess of the per-cycle output noise, rad (ARW, ADC noise on the two fractional
    /// fringes, residual model error); the tracker then estimates it from the innovations.
    pub noise_rad: f64,
    /// Memory of that noise estimate, cycles.
    pub noise_memory_cycles: f64,
    /// Scale of P1, P2 (s): the traversal time constant k of the gyro, ~26 us.
    pub k_ref_s: f64,
    /// Initial standard deviation of a and b, rad/s.
    pub initial_std_rad_per_s: f64,
    /// Innovations beyond this many standard deviations are rate changes (intercept only).
    pub gate_sigma: f64,
}

impl TrackingConfig {
    /// Memory of `cycles` cycles for a and b, 20 cycles for the intercept, 2e-3 rad initial
    /// noise (memory 500 cycles), 100 rad/s initial spread of a and b, gate at 8 sigma.
    pub fn with_memory(cycles: f64, k_ref_s: f64) -> Self {
        Self {
            memory_cycles: cycles.max(1.0),
            intercept_memory_cycles: 20.0,
            noise_rad: 2e-3,
            noise_memory_cycles: 500.0,
            k_ref_s,
            initial_std_rad_per_s: 100.0,
            gate_sigma: 8.0,
        }
    }

    /// Per-cycle random-walk variances of [c, a k_ref, b k_ref] for measurement variance r.
    fn process_variance(&self, r: f64) -> [f64; 3] {
        let q_ab = r / (self.memory_cycles * self.memory_cycles);
        let q_c = r / (self.intercept_memory_cycles * self.intercept_memory_cycles).max(1.0);
        [q_c, q_ab, q_ab]
    }
}

/// The tracker's state: estimate [c, a k_ref, b k_ref] (rad) and its covariance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tracker {
    theta: [f64; 3],
    p: [[f64; 3]; 3],
    updates: u64,
    frozen: u64,
    rate_steps: u64,
    /// Estimated measurement variance r, rad^2.
    noise_var: f64,
}

/// Initial (and re-opened) variance of the intercept, rad^2.
const INTERCEPT_VARIANCE_RAD2: f64 = 1.0;

impl Tracker {
    /// Starts from coefficients a, b (rad/s), e.g. the stored calibration; the intercept is
    /// unknown (large initial variance).
    pub fn new(config: &TrackingConfig, a_rad_per_s: f64, b_rad_per_s: f64) -> Self {
        let s = config.initial_std_rad_per_s * config.k_ref_s;
        Self {
            theta: [
                0.0,
                a_rad_per_s * config.k_ref_s,
                b_rad_per_s * config.k_ref_s,
            ],
            p: [
                [INTERCEPT_VARIANCE_RAD2, 0.0, 0.0],
                [0.0, s * s, 0.0],
                [0.0, 0.0, s * s],
            ],
            updates: 0,
            frozen: 0,
            rate_steps: 0,
            noise_var: config.noise_rad * config.noise_rad,
        }
    }

    /// Current a, b in rad/s.
    pub fn coefficients_rad_per_s(&self, config: &TrackingConfig) -> (f64, f64) {
        (
            self.theta[1] / config.k_ref_s,
            self.theta[2] / config.k_ref_s,
        )
    }

    /// Cycles used and cycles frozen (inside the dead band, flagged or not finite).
    pub fn counts(&self) -> (u64, u64) {
        (self.updates, self.frozen)
    }

    /// Innovations the gate took for rate changes.
    pub fn rate_steps(&self) -> u64 {
        self.rate_steps
    }

    /// One cycle: output y (rad), P1, P2 (s). `usable` false (inside the dead band, a flagged
    /// cycle) freezes the estimate and its covariance. Non-finite input is ignored.
    #[allow(clippy::indexing_slicing)] // indices count over the 3-vectors and the 3 x 3 covariance
    pub fn update(
        &mut self,
        config: &TrackingConfig,
        y_rad: f64,
        p1_s: f64,
        p2_s: f64,
        usable: bool,
    ) {
        if !(usable && y_rad.is_finite() && p1_s.is_finite() && p2_s.is_finite()) {
            self.frozen += 1;
            return;
        }
        // Predict: the random walk widens the covariance.
        for (i, q) in config
            .process_variance(self.noise_var)
            .into_iter()
            .enumerate()
        {
            self.p[i][i] += q;
        }
        // Update with y = x' theta + v.
        let x = [1.0, p1_s / config.k_ref_s, p2_s / config.k_ref_s];
        let mut px = [0.0; 3];
        for (i, row) in self.p.iter().enumerate() {
            px[i] = row[0] * x[0] + row[1] * x[1] + row[2] * x[2];
        }
        let innovation_var = self.noise_var + x[0] * px[0] + x[1] * px[1] + x[2] * px[2];
        if !(innovation_var.is_finite() && innovation_var > 0.0) {
            self.frozen += 1;
            return;
        }
        let err = y_rad - (self.theta[0] * x[0] + self.theta[1] * x[1] + self.theta[2] * x[2]);
        if err * err > config.gate_sigma * config.gate_sigma * innovation_var {
            // A rate change: the intercept takes it all and starts afresh; a, b untouched.
            self.theta[0] += err;
            self.p[0] = [INTERCEPT_VARIANCE_RAD2, 0.0, 0.0];
            self.p[1][0] = 0.0;
            self.p[2][0] = 0.0;
            self.rate_steps += 1;
            return;
        }
        let gain = [
            px[0] / innovation_var,
            px[1] / innovation_var,
            px[2] / innovation_var,
        ];
        for (t, g) in self.theta.iter_mut().zip(gain) {
            *t += g * err;
        }
        // P = P - gain px', kept symmetric.
        for (i, g) in gain.into_iter().enumerate() {
            for (j, pxj) in px.iter().enumerate().skip(i) {
                let v = self.p[i][j] - g * pxj;
                self.p[i][j] = v;
                self.p[j][i] = v;
            }
        }
        // The noise estimate follows the accepted innovations (slightly high by x' P x, which
        // is small once converged); gated innovations do not enter it.
        let memory = config.noise_memory_cycles.max(1.0);
        self.noise_var =
            (self.noise_var + (err * err - self.noise_var) / memory).max(MIN_NOISE_VAR_RAD2);
        self.updates += 1;
    }

    /// The estimated per-cycle output noise, rad.
    pub fn noise_rad(&self) -> f64 {
        libm::sqrt(self.noise_var)
    }
}

/// Floor of the noise estimate, rad^2 (1e-6 rad: below any real fractional-fringe noise).
const MIN_NOISE_VAR_RAD2: f64 = 1e-12;

/// Settings of the tracking loop (immutable).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingLoopConfig {
    /// Settings of the Kalman tracker itself (memories, gate, k_ref).
    pub tracking: TrackingConfig,
    /// Cycles are used only while |rate| > margin x Omega_L0 (Chow, from the current a, b and
    /// the measured dither amplitude).
    pub dead_band_margin: f64,
    /// Memory of the rate estimate that decides it, cycles.
    pub rate_memory_cycles: f64,
    /// New coefficients are staged every this many used cycles.
    pub stage_every_cycles: u32,
}

impl TrackingLoopConfig {
    /// Memory `cycles`, k_ref 26 us, 1.5 x the dead band, rate over 100 cycles, staging every
    /// 389 used cycles (once a second at the paper's dither).
    pub fn with_memory(cycles: f64) -> Self {
        Self {
            tracking: TrackingConfig::with_memory(cycles, 26e-6),
            dead_band_margin: 1.5,
            rate_memory_cycles: 100.0,
            stage_every_cycles: 389,
        }
    }
}

/// The tracking loop of the cycle task: decides whether a cycle may be used, feeds the
/// tracker, and hands out new coefficients to stage now and then.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingLoop {
    tracker: Tracker,
    rate_rad_per_s: f64,
    countdown: u32,
}

impl TrackingLoop {
    /// Starts from the coefficients in force.
    pub fn new(config: &TrackingLoopConfig, start: Coefficients) -> Self {
        Self {
            tracker: Tracker::new(
                &config.tracking,
                start.a_rad_per_s() as f64,
                start.b_rad_per_s() as f64,
            ),
            rate_rad_per_s: 0.0,
            countdown: config.stage_every_cycles,
        }
    }

    /// The tracker: its current a and b, cycle counts and noise estimate.
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// One dither cycle; returns coefficients to stage when due. Cycles inside the dead band
    /// (judged from the uncompensated rate, which is ~0 there) or flagged ones freeze it.
    pub fn on_cycle(
        &mut self,
        config: &TrackingLoopConfig,
        record: &CycleRecord,
        cycle_s: f64,
    ) -> Option<Coefficients> {
        let y = record.raw_increment_rad();
        if cycle_s > 0.0 && y.is_finite() {
            let alpha = 1.0 / config.rate_memory_cycles.max(1.0);
            self.rate_rad_per_s += alpha * (y / cycle_s - self.rate_rad_per_s);
        }
        let (a, b) = self.tracker.coefficients_rad_per_s(&config.tracking);
        let band = chow_dead_band_rad_per_s(libm::hypot(a, b), record.dither_amplitude_rad as f64);
        let usable = record.output.flags.is_empty()
            && record.dither_amplitude_rad > 0.0
            && libm::fabs(self.rate_rad_per_s) > config.dead_band_margin * band;
        self.tracker.update(
            &config.tracking,
            y,
            record.terms.p1_s as f64,
            record.terms.p2_s as f64,
            usable,
        );
        if !usable {
            return None;
        }
        self.countdown = self.countdown.saturating_sub(1);
        if self.countdown > 0 {
            return None;
        }
        self.countdown = config.stage_every_cycles;
        let (a, b) = self.tracker.coefficients_rad_per_s(&config.tracking);
        Coefficients::from_rad_per_s(a as f32, b as f32).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TAU: f64 = core::f64::consts::TAU;
    const K: f64 = 26.3e-6;

    /// Synthetic cycle i: random-ish turnaround phases, output = rate T + a P1 + b P2 + noise.
    fn cycle(i: u64, a: f64, b: f64, rate: f64, noise: f64) -> (f64, f64, f64) {
        let h = |s: f64| ((i as f64 * s).sin() * 43758.5453).fract();
        let (u, v) = (h(12.9898) * TAU, h(78.233) * TAU);
        let p1 = K * (u.cos() + v.sin());
        let p2 = K * (v.cos() - u.sin());
        (
            rate / 389.0 + a * p1 + b * p2 + noise * (h(37.719) - 0.5),
            p1,
            p2,
        )
    }

    /// Omega_L drifts by 5 % and eps by 0.05 rad over 200 000 cycles (8.6 min at 389 Hz), a
    /// drift of 2.4e-4 rad/s per cycle in (a, b). A tracker with a 2000-cycle memory lags such a
    /// drift by about memory x drift = 0.5 rad/s (0.07 % of Omega_L) plus noise: it follows a and
    /// b to within 0.3 % of Omega_L, while the starting (static) coefficients end up 7 % off.
    #[test]
    fn tracking_follows_a_drifting_lock_in() {
        let config = TrackingConfig::with_memory(2_000.0, K);
        let (l0, e0) = (673.6_f64, 0.3_f64);
        let ab = |t: f64| {
            let l = l0 * (1.0 + 0.05 * t);
            let e = e0 + 0.05 * t;
            (l * (e + TAU / 8.0).cos(), l * (e + TAU / 8.0).sin())
        };
        let (a0, b0) = ab(0.0);
        let mut tracker = Tracker::new(&config, a0, b0);
        let n = 200_000u64;
        for i in 0..n {
            let (a, b) = ab(i as f64 / n as f64);
            let (y, p1, p2) = cycle(i, a, b, 46.8, 1e-5);
            tracker.update(&config, y, p1, p2, true);
        }
        let (a_true, b_true) = ab(1.0);
        let (a_est, b_est) = tracker.coefficients_rad_per_s(&config);
        let err_tracked = (a_est - a_true).hypot(b_est - b_true);
        let err_static = (a0 - a_true).hypot(b0 - b_true);
        assert!(err_tracked < 0.003 * l0, "tracked {err_tracked}");
        assert!(err_static > 0.04 * l0, "static {err_static}");
        assert_eq!(tracker.counts(), (n, 0));
    }

    /// Frozen cycles change nothing, whatever their content.
    #[test]
    fn frozen_cycles_change_nothing() {
        let config = TrackingConfig::with_memory(1000.0, K);
        let mut tracker = Tracker::new(&config, 300.0, 500.0);
        let before = tracker;
        tracker.update(&config, 123.0, 1e-5, -1e-5, false);
        tracker.update(&config, f64::NAN, 1e-5, -1e-5, true);
        assert_eq!(
            tracker.coefficients_rad_per_s(&config),
            before.coefficients_rad_per_s(&config)
        );
        assert_eq!(tracker.counts(), (0, 2));
    }

    /// A step of the input rate (+13.888 to -13.888 deg/h: 0.24 rad per cycle) is absorbed by
    /// the intercept: a and b never move by more than 0.2 % of Omega_L.
    #[test]
    fn a_rate_step_does_not_disturb_the_coefficients() {
        let config = TrackingConfig::with_memory(5000.0, K);
        let (a, b) = (344.0, 579.0);
        let mut tracker = Tracker::new(&config, a, b);
        for i in 0..50_000u64 {
            let rate = if i < 25_000 { 46.8 } else { -46.8 };
            let (y, p1, p2) = cycle(i, a, b, rate, 1e-5);
            let before = tracker.rate_steps();
            tracker.update(&config, y, p1, p2, true);
            // The gate fires on the step cycle and nowhere else.
            let gated = tracker.rate_steps() != before;
            assert_eq!(gated, i == 25_000, "cycle {i}");
            let (ae, be) = tracker.coefficients_rad_per_s(&config);
            assert!(
                (ae - a).hypot(be - b) < 0.002 * 673.6,
                "cycle {i}: {ae} {be}"
            );
        }
    }
}
