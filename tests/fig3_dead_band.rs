//! Fig. 3 of the paper through the firmware's own signal chain: the uncompensated output is
//! flat (locked) inside Chow's dynamic dead band and follows Eq. 10,
//! out = sqrt(in^2 - Omega_L0^2), outside it.
//!
//! Method: the band edge is estimated from points outside the band, Omega_L0^2 = in^2 - out^2,
//! each averaged over whole output periods (10 s per point: 20 or more slips); a point inside
//! the band must read zero. Acceptance (issue 4): the edge within 3 % of Chow's value, for the
//! parameter set of docs/physics.md and one other. Chow's law itself is first order in Omega_L;
//! the simulator matches it to 0.5 % (hal-sim's theory tests), the rest of the 3 % is the
//! chain's margin.
//!
//! Regression bounds (issue 11): the 3 % above is the physics tolerance, about 1000 times what
//! the chain achieves, so each gyro also carries a [`Regression`] bound set about 3 to 5 times
//! above the worst of eight noise seeds (base seeds 3..=10 and 4..=11; the seed only changes the
//! photodiode noise, the runs are otherwise noise-free), so that a tenfold regression fails:
//!
//! | gyro | edge vs Chow, measured | bound | inside the band, measured | bound |
//! | --- | --- | --- | --- | --- |
//! | paper set | -0.0001 % .. -0.0030 % | 0.01 % | 3.4e-4 .. 4.1e-4 deg/h | 1.5e-3 deg/h |
//! | second | -0.017 % .. -0.020 % | 0.06 % | 3e-7 .. 8.7e-5 deg/h | 3e-4 deg/h |
//!
//! The second gyro's edge sits 0.02 % below Chow's value for every seed: a systematic of the
//! first-order law (or the 10 s average), not noise.

mod common;

use common::{chow_dead_band_deg_h, paper_gyro};
use firmware::signal::compensation::CompensationSettings;
use hal_sim::params::GyroParams;
use rlg_sim::experiment::{measure_rate, DitherDrive, RunLength};

const LENGTH: RunLength = RunLength {
    warmup_s: 0.5,
    record_s: 10.0,
};

/// Band edge estimated from the uncompensated output at `multiples` of Chow's band.
fn edge_from_outside(params: &GyroParams, chow_deg_h: f64, multiples: &[f64]) -> f64 {
    let sf = params.scale_factor_arcsec;
    let estimates: Vec<f64> = multiples
        .iter()
        .map(|m| {
            let input = m * chow_deg_h;
            let out = measure_rate(
                params,
                DitherDrive::Ideal,
                input,
                LENGTH,
                CompensationSettings::default(),
            )
            .expect("run")
            .uncompensated_hz
                * sf;
            (input * input - out * out).sqrt()
        })
        .collect();
    estimates.iter().sum::<f64>() / estimates.len() as f64
}

/// Regression bounds of one gyro, near the measured values (module docs).
struct Regression {
    /// |edge / Chow - 1|.
    edge_relative: f64,
    /// |uncompensated output| at 70 % of the band, deg/h.
    inside_deg_h: f64,
}

fn check_band(params: &GyroParams, regression: Regression) {
    let chow = chow_dead_band_deg_h(params);
    let edge = edge_from_outside(params, chow, &[1.5, 2.0, 3.0]);
    let edge_relative = edge / chow - 1.0;
    eprintln!(
        "band edge {edge:.5} deg/h, Chow {chow:.5} deg/h ({:+.4} %)",
        100.0 * edge_relative
    );
    assert!(
        edge_relative.abs() < 0.03,
        "edge {edge:.4} deg/h vs Chow {chow:.4}"
    );
    assert!(
        edge_relative.abs() < regression.edge_relative,
        "regression: edge {:+.4} % off Chow (bound {} %)",
        100.0 * edge_relative,
        100.0 * regression.edge_relative
    );
    // Inside the band (70 % of it) the output is flat: below 1 % of the band.
    let inside = measure_rate(
        params,
        DitherDrive::Ideal,
        0.7 * chow,
        LENGTH,
        CompensationSettings::default(),
    )
    .expect("run")
    .uncompensated_hz
        * params.scale_factor_arcsec;
    eprintln!("inside the band: {inside:.3e} deg/h");
    assert!(
        inside.abs() < 0.01 * chow,
        "inside the band: {inside} deg/h"
    );
    assert!(
        inside.abs() < regression.inside_deg_h,
        "regression: inside the band {inside:.3e} deg/h (bound {:.1e})",
        regression.inside_deg_h
    );
}

#[test]
fn dead_band_of_the_paper_gyro_matches_chow() {
    let params = paper_gyro(3);
    assert!((chow_dead_band_deg_h(&params) - 3.358).abs() < 1e-3);
    check_band(
        &params,
        Regression {
            edge_relative: 1e-4,
            inside_deg_h: 1.5e-3,
        },
    );
}

#[test]
fn dead_band_of_a_second_gyro_matches_chow() {
    // A stronger lock-in and a smaller dither: a band twice as wide (6.96 deg/h), at an
    // amplitude near a maximum of |J0| (away from its zeros, where Chow's first-order law
    // is least reliable).
    let params = GyroParams {
        lock_in_deg_per_h: 300.0,
        dither_amplitude_arcsec: 350.0,
        seed: 4,
        ..GyroParams::default()
    };
    let chow = chow_dead_band_deg_h(&params);
    assert!((chow - 6.963).abs() < 0.01, "{chow}");
    check_band(
        &params,
        Regression {
            edge_relative: 6e-4,
            inside_deg_h: 3e-4,
        },
    );
}
