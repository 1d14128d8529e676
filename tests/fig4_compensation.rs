//! Fig. 4 of the paper through the firmware's own signal chain: after the calibration fit
//! outside the dead band, the compensated output is a straight line through the dead band.
//!
//! Acceptance (issue 4), all seeded:
//! - the fit's Omega_L = hypot(a, b) and eps = atan2(b, a) - pi/4 within 1 % of the simulator's
//!   truth;
//! - without noise: max |output - ideal| <= 0.01 deg/h over +-13.888 deg/h, 10 s per point;
//! - with ARW 3e-4 deg/sqrt(h): the rms deviation over the points within 1.5 x the white-noise
//!   limit ARW x 60 / sqrt(T) deg/h (T = 10 s: 5.7e-3 deg/h). Rms, not max: with 15 points of
//!   Gaussian scatter, the largest is expected near 2 sigma.
//!
//! Regression bounds (issue 11). The noise-free tolerances above are physics tolerances, 30 to
//! 80 times what the chain achieves; the noise-free test also asserts bounds about 3 times above
//! the worst of eight noise seeds (base seeds 11..=18; the seed changes only the photodiode
//! noise of these runs), so that a tenfold regression fails:
//!
//! | quantity | measured (8 seeds) | physics bound | regression bound |
//! | --- | --- | --- | --- |
//! | Omega_L vs truth | 0.02e-4 .. 1.3e-4 relative | 1e-2 | 4e-4 |
//! | eps vs truth | 0.3e-4 .. 3.7e-4 relative | 1e-2 | 1.2e-3 |
//! | max compensated deviation | 1.2e-4 .. 4.0e-4 deg/h | 1e-2 deg/h | 1.2e-3 deg/h |
//!
//! The noisy test needs none: its rms measured 0.83 to 1.36 times the white-noise limit over
//! the same eight seeds, against the physics bound 1.5.

mod common;

use common::{paper_gyro, TAU};
use firmware::signal::compensation::CompensationSettings;
use hal_sim::params::GyroParams;
use rayon::prelude::*;
use rlg_sim::experiment::{calibrate, measure_rate, settings_from_fit, DitherDrive, RunLength};

const RECORD: RunLength = RunLength {
    warmup_s: 0.5,
    record_s: 10.0,
};
const CALIBRATION: RunLength = RunLength {
    warmup_s: 0.5,
    record_s: 20.0,
};
const RANGE_DEG_H: f64 = 13.888;

fn calibrated(
    params: &GyroParams,
) -> (CompensationSettings, firmware::calibration::fit::FitResult) {
    let fit = calibrate(
        params,
        DitherDrive::Ideal,
        &[-RANGE_DEG_H, RANGE_DEG_H],
        CALIBRATION,
    )
    .expect("calibration");
    (settings_from_fit(&fit).expect("representable"), fit)
}

/// Compensated deviation from ideal (deg/h) at evenly spaced rates across the range.
fn deviations(
    params: &GyroParams,
    settings: CompensationSettings,
    points: usize,
) -> Vec<(f64, f64)> {
    (0..points)
        .into_par_iter()
        .map(|i| {
            let input = -RANGE_DEG_H + 2.0 * RANGE_DEG_H * i as f64 / (points - 1) as f64;
            let m = measure_rate(params, DitherDrive::Ideal, input, RECORD, settings).expect("run");
            (input, m.compensated_hz * params.scale_factor_arcsec - input)
        })
        .collect()
}

#[test]
fn compensation_removes_the_dead_band_without_noise() {
    let params = paper_gyro(11);
    let (settings, fit) = calibrated(&params);

    // The fit against the simulator's truth: 200 deg/h and 0.3 rad.
    let sf = params.scale_factor_arcsec;
    let lock_in_deg_h = fit.lock_in_rad_per_s * sf / TAU;
    assert!(
        (lock_in_deg_h / 200.0 - 1.0).abs() < 0.01,
        "Omega_L {lock_in_deg_h} deg/h"
    );
    assert!(
        (fit.eps_rad / 0.3 - 1.0).abs() < 0.01,
        "eps {} rad",
        fit.eps_rad
    );
    // Regression bounds (module docs).
    assert!(
        (lock_in_deg_h / 200.0 - 1.0).abs() < 4e-4,
        "regression: Omega_L {lock_in_deg_h} deg/h"
    );
    assert!(
        (fit.eps_rad / 0.3 - 1.0).abs() < 1.2e-3,
        "regression: eps {} rad",
        fit.eps_rad
    );

    // 29 points, 1 deg/h apart: inside and across the +-3.36 deg/h band.
    let devs = deviations(&params, settings, 29);
    let worst = devs.iter().map(|d| d.1.abs()).fold(0.0, f64::max);
    eprintln!("fit: Omega_L {lock_in_deg_h:.4} deg/h, eps {:.5} rad; worst compensated deviation {worst:.2e} deg/h", fit.eps_rad);
    assert!(
        worst <= 0.01,
        "worst compensated deviation {worst} deg/h: {devs:?}"
    );
    assert!(
        worst <= 1.2e-3,
        "regression: worst compensated deviation {worst} deg/h: {devs:?}"
    );
}

#[test]
fn compensation_adds_no_noise_of_its_own() {
    let arw = 3e-4;
    let params = GyroParams {
        arw_deg_per_rt_h: arw,
        ..paper_gyro(12)
    };
    let (settings, _) = calibrated(&params);
    let devs = deviations(&params, settings, 15);
    let rms = (devs.iter().map(|d| d.1 * d.1).sum::<f64>() / devs.len() as f64).sqrt();
    let limit = arw * 60.0 / RECORD.record_s.sqrt();
    eprintln!(
        "rms compensated deviation {rms:.2e} deg/h = {:.2} x the white-noise limit {limit:.2e}",
        rms / limit
    );
    assert!(
        rms <= 1.5 * limit,
        "rms deviation {rms} deg/h vs white-noise limit {limit}: {devs:?}"
    );
}
