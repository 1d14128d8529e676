//! The calibration fit (Ref. 18's curve fit): per-cycle output regressed on [1, P1, P2].
//!
//! Outside the dead band the per-cycle output is y = c + a P1 + b P2 + noise, with c the
//! input rate times the cycle time. Least squares gives a and b, and with them
//! Omega_L = hypot(a, b) and eps = atan2(b, a) - pi/4.
//!
//! # Numerics
//! The accumulator keeps means and centred co-moments updated per cycle (Welford's algorithm),
//! never raw sums of squares: raw sums of y ~ 0.1 rad with a 1e-3 rad signal on top would lose
//! the signal to cancellation after hours of cycles. The state is f64: on the Cortex-M4F that is
//! software floating point, about 20 operations per cycle (a few microseconds, once per dither
//! cycle, outside the turnaround interrupt), and IEEE-exact, so the host and the MCU accumulate
//! identical bits.
//!
//! # Pooling
//! Runs at several input rates are pooled with one intercept per run (fixed effects): the
//! within-run co-moments add, and the between-run differences in mean output, which are the
//! input rates, never leak into a and b.

use crate::signal::lockin::CycleRecord;

/// Means and centred co-moments of (y, P1, P2) for one or more pooled runs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitAccumulator {
    /// Cycles accumulated in all runs.
    pub cycles: u64,
    /// Runs pooled (each brings its own intercept).
    pub runs: u32,
    /// Sum over runs of y and of the cycle time, for the mean input rate.
    sum_y_rad: f64,
    sum_cycle_s: f64,
    /// Welford state of the run being accumulated.
    run_cycles: u64,
    mean: [f64; 3],
    /// Centred co-moments, pooled over closed runs plus the open one: [yy, y1, y2, 11, 12, 22].
    comoment: [f64; 6],
}

/// Why a fit cannot be solved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SolveError {
    /// Fewer cycles than unknowns plus one.
    TooFewCycles,
    /// P1 and P2 are (nearly) collinear or constant: a and b cannot be separated.
    Singular,
}

/// The solved fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitResult {
    /// a = Omega_L cos(eps + pi/4), the coefficient of P1, rad/s of beat phase.
    pub a_rad_per_s: f64,
    /// b = Omega_L sin(eps + pi/4), the coefficient of P2, rad/s of beat phase.
    pub b_rad_per_s: f64,
    /// Standard error of a, rad/s.
    pub a_std_rad_per_s: f64,
    /// Standard error of b, rad/s.
    pub b_std_rad_per_s: f64,
    /// Omega_L = hypot(a, b), rad/s.
    pub lock_in_rad_per_s: f64,
    /// eps = atan2(b, a) - pi/4, rad.
    pub eps_rad: f64,
    /// 1 - residual variance / output variance (within runs).
    pub variance_reduction: f64,
    /// Condition number of the normalised P1/P2 covariance: (1 + |r|) / (1 - |r|).
    pub condition_number: f64,
    /// Residual standard deviation of the per-cycle output, rad.
    pub residual_std_rad: f64,
    /// Mean output rate over all runs, rad/s of beat phase.
    pub mean_rate_rad_per_s: f64,
    /// Dither cycles in the fit, all runs.
    pub cycles: u64,
    /// Runs pooled, each with its own intercept.
    pub runs: u32,
}

impl FitAccumulator {
    /// Empty: no cycles, no runs.
    pub const fn new() -> Self {
        Self {
            cycles: 0,
            runs: 0,
            sum_y_rad: 0.0,
            sum_cycle_s: 0.0,
            run_cycles: 0,
            mean: [0.0; 3],
            comoment: [0.0; 6],
        }
    }

    /// Adds one dither cycle: output y (rad of beat phase, including the fractional fringe),
    /// its P1 and P2 (s), and its duration (s). Non-finite input is ignored (returns false).
    pub fn push(&mut self, y_rad: f64, p1_s: f64, p2_s: f64, cycle_s: f64) -> bool {
        if !(y_rad.is_finite() && p1_s.is_finite() && p2_s.is_finite() && cycle_s.is_finite()) {
            return false;
        }
        if self.run_cycles == 0 {
            self.runs = self.runs.saturating_add(1);
        }
        self.run_cycles += 1;
        self.cycles += 1;
        self.sum_y_rad += y_rad;
        self.sum_cycle_s += cycle_s;
        let x = [y_rad, p1_s, p2_s];
        let n = self.run_cycles as f64;
        let before = [
            x[0] - self.mean[0],
            x[1] - self.mean[1],
            x[2] - self.mean[2],
        ];
        for (m, d) in self.mean.iter_mut().zip(before) {
            *m += d / n;
        }
        let after = [
            x[0] - self.mean[0],
            x[1] - self.mean[1],
            x[2] - self.mean[2],
        ];
        const PAIRS: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        for (c, (i, j)) in self.comoment.iter_mut().zip(PAIRS) {
            #[allow(clippy::indexing_slicing)] // PAIRS holds indices of the 3-arrays
            let term = before[i] * after[j];
            *c += term;
        }
        true
    }

    /// Adds one dither cycle of the readout: its raw (uncompensated) increment with the
    /// fractional fringe, its P1 and P2, and its duration `cycle_s`. The caller decides which
    /// cycles are usable (flagged ones are left out everywhere in this firmware).
    pub fn push_cycle(&mut self, record: &CycleRecord, cycle_s: f64) -> bool {
        self.push(
            record.raw_increment_rad(),
            record.terms.p1_s as f64,
            record.terms.p2_s as f64,
            cycle_s,
        )
    }

    /// Closes the current run: the next cycle starts a new run with its own intercept.
    pub fn end_run(&mut self) {
        self.run_cycles = 0;
        self.mean = [0.0; 3];
    }

    /// Pools another accumulator's runs into this one (both must have ended their runs).
    pub fn pool(&mut self, other: &FitAccumulator) {
        self.end_run();
        self.cycles += other.cycles;
        self.runs = self.runs.saturating_add(other.runs);
        self.sum_y_rad += other.sum_y_rad;
        self.sum_cycle_s += other.sum_cycle_s;
        for (c, o) in self.comoment.iter_mut().zip(other.comoment) {
            *c += o;
        }
    }

    /// Solves the normal equations of the centred problem.
    pub fn solve(&self) -> Result<FitResult, SolveError> {
        let [syy, sy1, sy2, s11, s12, s22] = self.comoment;
        let dof = self.cycles as f64 - 2.0 - self.runs as f64;
        if dof < 1.0 {
            return Err(SolveError::TooFewCycles);
        }
        let det = s11 * s22 - s12 * s12;
        if !(det > 0.0 && s11 > 0.0 && s22 > 0.0) || det <= 1e-12 * s11 * s22 {
            return Err(SolveError::Singular);
        }
        let a = (s22 * sy1 - s12 * sy2) / det;
        let b = (s11 * sy2 - s12 * sy1) / det;
        let rss = (syy - a * sy1 - b * sy2).max(0.0);
        let sigma2 = rss / dof;
        let r = s12 / libm::sqrt(s11 * s22);
        let r_abs = r.abs();
        Ok(FitResult {
            a_rad_per_s: a,
            b_rad_per_s: b,
            a_std_rad_per_s: libm::sqrt(sigma2 * s22 / det),
            b_std_rad_per_s: libm::sqrt(sigma2 * s11 / det),
            lock_in_rad_per_s: libm::hypot(a, b),
            eps_rad: libm::atan2(b, a) - core::f64::consts::FRAC_PI_4,
            variance_reduction: if syy > 0.0 { 1.0 - rss / syy } else { 0.0 },
            condition_number: if r_abs < 1.0 {
                (1.0 + r_abs) / (1.0 - r_abs)
            } else {
                f64::INFINITY
            },
            residual_std_rad: libm::sqrt(sigma2),
            mean_rate_rad_per_s: if self.sum_cycle_s > 0.0 {
                self.sum_y_rad / self.sum_cycle_s
            } else {
                0.0
            },
            cycles: self.cycles,
            runs: self.runs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::test_rng::XorShift as Rng;

    const K: f64 = 26.3e-6;
    const A: f64 = 673.6 * 0.8253356149096783 * 0.6967067093471654; // ~ Omega_L cos(eps+pi/4)
    const B: f64 = 420.0;

    /// Synthetic cycles: the turnaround phases are random, so P1 and P2 are well separated.
    fn run(acc: &mut FitAccumulator, rng: &mut Rng, rate: f64, cycles: usize, noise: f64) {
        let t = 1.0 / 389.0;
        for _ in 0..cycles {
            let (u, v, w) = (rng.uniform(), rng.uniform(), rng.uniform());
            let tau = core::f64::consts::TAU;
            let (pp, pm) = (u * tau, v * tau);
            let p1 = 0.5 * K * (pp.cos() + (w * tau).cos()) + K * pm.sin();
            let p2 = K * pm.cos() - 0.5 * K * (pp.sin() + (w * tau).sin());
            let y = rate * t + A * p1 + B * p2 + noise * rng.gauss();
            assert!(acc.push(y, p1, p2, t));
        }
        acc.end_run();
    }

    /// Noise-free data: a and b exact to rounding (1e-9 relative).
    #[test]
    fn exact_data_is_fitted_exactly() {
        let mut acc = FitAccumulator::new();
        let mut rng = Rng(7);
        run(&mut acc, &mut rng, 46.8, 2000, 0.0);
        let fit = acc.solve().unwrap();
        assert!((fit.a_rad_per_s / A - 1.0).abs() < 1e-9, "{fit:?}");
        assert!((fit.b_rad_per_s / B - 1.0).abs() < 1e-9);
        assert!(fit.variance_reduction > 1.0 - 1e-12);
        assert!((fit.mean_rate_rad_per_s / 46.8 - 1.0).abs() < 0.01);
    }

    /// With noise the estimate lands within 4 standard errors, and the standard error matches
    /// the theory sigma / sqrt(n var(P)) within 20 % (a statement about the reported errors).
    #[test]
    fn noisy_fit_and_its_standard_errors() {
        let mut acc = FitAccumulator::new();
        let mut rng = Rng(11);
        let noise = 1e-3;
        run(&mut acc, &mut rng, 46.8, 20_000, noise);
        let fit = acc.solve().unwrap();
        assert!(
            (fit.a_rad_per_s - A).abs() < 4.0 * fit.a_std_rad_per_s,
            "{fit:?}"
        );
        assert!((fit.b_rad_per_s - B).abs() < 4.0 * fit.b_std_rad_per_s);
        assert!((fit.residual_std_rad / noise - 1.0).abs() < 0.05);
        // var(P1) = K^2 (1/4 + 1/2) = 0.75 K^2 for independent uniform phases.
        let expected = noise / (20_000f64 * 0.75 * K * K).sqrt();
        assert!(
            (fit.a_std_rad_per_s / expected - 1.0).abs() < 0.2,
            "{fit:?} vs {expected}"
        );
    }

    /// Pooling runs at +-13.888 deg/h (+-46.8 rad/s): per-run intercepts keep the rate difference
    /// out of a and b, so the pooled fit is as exact as a single run.
    #[test]
    fn pooled_runs_at_both_signs_keep_their_own_intercepts() {
        let mut rng = Rng(3);
        let mut pos = FitAccumulator::new();
        run(&mut pos, &mut rng, 46.8, 1000, 0.0);
        let mut neg = FitAccumulator::new();
        run(&mut neg, &mut rng, -46.8, 1000, 0.0);
        pos.pool(&neg);
        let fit = pos.solve().unwrap();
        assert_eq!(fit.runs, 2);
        assert!((fit.a_rad_per_s / A - 1.0).abs() < 1e-9, "{fit:?}");
        assert!((fit.b_rad_per_s / B - 1.0).abs() < 1e-9);
    }

    /// Hours of cycles: 389 Hz x 4 h = 5.6 M cycles with a large mean output. Welford's centring
    /// keeps a and b to 1e-6 relative where raw sums would lose them.
    #[test]
    fn precision_holds_over_hours_of_cycles() {
        let mut acc = FitAccumulator::new();
        let mut rng = Rng(5);
        run(&mut acc, &mut rng, 4680.0, 389 * 3600 * 4, 0.0);
        let fit = acc.solve().unwrap();
        assert!((fit.a_rad_per_s / A - 1.0).abs() < 1e-6, "{fit:?}");
        assert!((fit.b_rad_per_s / B - 1.0).abs() < 1e-6);
    }

    #[test]
    fn degenerate_problems_are_refused() {
        let mut acc = FitAccumulator::new();
        assert_eq!(acc.solve(), Err(SolveError::TooFewCycles));
        for i in 0..100 {
            // P2 = 2 P1: collinear.
            acc.push(i as f64, i as f64 * 1e-6, i as f64 * 2e-6, 1e-3);
        }
        assert_eq!(acc.solve(), Err(SolveError::Singular));
        assert!(!acc.push(f64::NAN, 0.0, 0.0, 1e-3));
        assert!(!acc.push(0.0, f64::INFINITY, 0.0, 1e-3));
    }
}
