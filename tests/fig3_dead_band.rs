//! Fig. 3 of the paper through the firmware's own signal chain: the uncompensated output is
//! flat (locked) inside Chow's dynamic dead band and follows Eq. 10,
//! out = sqrt(in^2 - Omega_L0^2), outside it.
//!
//! Method: the band edge is estimated from points outside the band, Omega_L0^2 = in^2 - out^2,
//! each averaged over whole output periods (10 s per point: 20 or more slips); a point inside
//! the band must read zero. Acceptance (issue 4): the edge within 3 % of Chow's value, for the
//! PHYSICS.md set and one other. Chow's law itself is first order in Omega_L; the simulator
//! matches it to 0.5 % (hal-sim's theory tests), the rest of the 3 % is the chain's margin.

mod common;

use common::{chow_dead_band_deg_h, paper_gyro};
use firmware::signal::compensation::CompensationSettings;
use hal_sim::params::GyroParams;
use rlg_sim::experiment::{measure_rate, RunLength};

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
            let out = measure_rate(params, input, LENGTH, CompensationSettings::default())
                .expect("run")
                .uncompensated_hz
                * sf;
            (input * input - out * out).sqrt()
        })
        .collect();
    estimates.iter().sum::<f64>() / estimates.len() as f64
}

fn check_band(params: &GyroParams) {
    let chow = chow_dead_band_deg_h(params);
    let edge = edge_from_outside(params, chow, &[1.5, 2.0, 3.0]);
    eprintln!(
        "band edge {edge:.4} deg/h, Chow {chow:.4} deg/h ({:+.2} %)",
        100.0 * (edge / chow - 1.0)
    );
    assert!(
        (edge / chow - 1.0).abs() < 0.03,
        "edge {edge:.4} deg/h vs Chow {chow:.4}"
    );
    // Inside the band (70 % of it) the output is flat: below 1 % of the band.
    let inside = measure_rate(params, 0.7 * chow, LENGTH, CompensationSettings::default())
        .expect("run")
        .uncompensated_hz
        * params.scale_factor_arcsec;
    assert!(
        inside.abs() < 0.01 * chow,
        "inside the band: {inside} deg/h"
    );
}

#[test]
fn dead_band_of_the_paper_gyro_matches_chow() {
    let params = paper_gyro(3);
    assert!((chow_dead_band_deg_h(&params) - 3.358).abs() < 1e-3);
    check_band(&params);
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
    check_band(&params);
}
