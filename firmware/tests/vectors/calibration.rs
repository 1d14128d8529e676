//! Cases for `firmware::calibration`.
use super::{Outputs, Rng};
use firmware::calibration::fit::{FitAccumulator, FitResult, SolveError};
use firmware::calibration::tracking::{Tracker, TrackingConfig};

fn result(out: &mut Outputs, fit: Result<FitResult, SolveError>) {
    match fit {
        Ok(r) => {
            for v in [
                r.a_rad_per_s,
                r.b_rad_per_s,
                r.a_std_rad_per_s,
                r.b_std_rad_per_s,
                r.lock_in_rad_per_s,
                r.eps_rad,
                r.variance_reduction,
                r.condition_number,
                r.residual_std_rad,
                r.mean_rate_rad_per_s,
            ] {
                out.f64(v);
            }
            out.u64(r.cycles);
            out.u32(r.runs);
        }
        Err(e) => out.u32(0xdead_0000 | e as u32),
    }
}

/// The Welford fit over pooled runs at three input rates (y = c + a P1 + b P2 + noise), plus
/// the refusals (too few cycles, collinear P1/P2, non-finite input).
pub fn calibration_fit(out: &mut Outputs) {
    let (a, b, k) = (387.0, 383.0, 26.3e-6);
    let mut rng = Rng::new(0x5eed_0020);
    let mut pooled = FitAccumulator::new();
    for c_rad in [0.05, 0.2, -0.1] {
        let mut run = FitAccumulator::new();
        for _ in 0..300 {
            let (p1, p2) = (k * rng.f64_in(-2.0, 2.0), k * rng.f64_in(-2.0, 2.0));
            let y = c_rad + a * p1 + b * p2 + 1e-4 * rng.f64_in(-1.0, 1.0);
            out.bool(run.push(y, p1, p2, 1.0 / 389.0));
        }
        run.end_run();
        pooled.pool(&run);
        result(out, run.solve());
    }
    out.bool(pooled.push(f64::NAN, 0.0, 0.0, 1.0));
    result(out, pooled.solve());
    let mut collinear = FitAccumulator::new();
    for i in 0..50 {
        collinear.push(i as f64, i as f64 * k, 2.0 * i as f64 * k, 1.0 / 389.0);
    }
    result(out, collinear.solve());
    result(out, FitAccumulator::new().solve());
}

/// The Kalman tracker of (c, a, b): noisy cycles, a rate step, frozen (unusable) cycles.
pub fn calibration_tracking(out: &mut Outputs) {
    let (a, b, k) = (387.0, 383.0, 26.3e-6);
    let config = TrackingConfig::with_memory(500.0, k);
    let mut tracker = Tracker::new(&config, 300.0, 450.0);
    let mut rng = Rng::new(0x5eed_0021);
    for i in 0..3000 {
        let c_rad = if i < 1500 { 0.05 } else { 0.3 }; // a rate step half-way
        let (p1, p2) = (k * rng.f64_in(-2.0, 2.0), k * rng.f64_in(-2.0, 2.0));
        let y = c_rad + a * p1 + b * p2 + 1e-4 * rng.f64_in(-1.0, 1.0);
        tracker.update(&config, y, p1, p2, !rng.one_in(20));
        if i % 10 == 0 {
            let (a_est, b_est) = tracker.coefficients_rad_per_s(&config);
            out.f64(a_est);
            out.f64(b_est);
        }
    }
    tracker.update(&config, f64::NAN, 0.0, 0.0, true);
    let (updates, frozen) = tracker.counts();
    out.u64(updates);
    out.u64(frozen);
    out.u64(tracker.rate_steps());
}
