//! P1 and P2 as the firmware forms them, against the simulator's true lock-in error of each
//! dither cycle (issue 4 acceptance), with dither amplitude jitter on.
//!
//! A steady sine dither hides a wrong sign pattern of P1/P2 (docs/physics.md pitfall 4: a reflected
//! psi_H, the misprinted Eq. 19): the turnaround phases then repeat in a way that a wrong model
//! can still fit. With the amplitude jittering, the turnaround phases decorrelate, and only the
//! correct Eq. 18 explains the truth.
//!
//! Truth: the lock-in phase phi = psi - theta at each turnaround (hal-sim). The firmware's cycle
//! increment runs between 1-2-1 averages of the latched phases centred on two "-" turnarounds
//! a period apart; the same averages of phi give exactly the lock-in error it holds, latch
//! split included. Model: a P1 + b P2 with the true a = Omega_L cos(eps + pi/4), b = Omega_L
//! sin(eps + pi/4). Acceptance: correlation >= 0.999, and the rms residual (model - truth)
//! bounded twice:
//! - physics: below 1 % of the rms truth. The parabolic approximation of a traversal neglects
//!   terms of relative order (w_d k)^2 = 4e-3 for the parameter set of docs/physics.md, and k is
//!   measured from the dither; 1 % leaves room for both. Measured: 0.09 %.
//! - regression: below 1.5 times the floor set by the photodiode noise. The levels at a latch
//!   carry sigma = noise / amplitude (1 mV / 1.32 V) plus the ADC's quantisation
//!   (LSB / sqrt(12)); each latch enters a P term as k sigma, weighted 1/8, 1/2, 3/4, 1/2, 1/8
//!   over the cycle's five turnarounds, so the model scatters by Omega_L k sigma 1.046 =
//!   1.44e-5 rad per cycle. Measured over eight seeds (21..=28): 1.52e-5 to 1.62e-5 rad (1.05
//!   to 1.12 times the floor). The bound, 1.5 x floor = 2.2e-5 rad, fails if the model's own
//!   error (0.6e-5 rad) grows threefold.

mod common;

use common::{paper_gyro, TAU};
use hal_sim::board::BoardConfig;
use hal_sim::harness::HarnessOptions;
use hal_sim::input::InputProfile;
use hal_sim::params::{AmplitudeModulation, GyroParams};

fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    sxy / (sxx * syy).sqrt()
}

/// The weights of a cycle's five latches in its increment (`firmware::signal::lockin`: the
/// 1-2-1 averages centred on two "-" turnarounds a period apart).
const WEIGHTS: [f64; 5] = [0.125, 0.5, 0.75, 0.5, 0.125];

/// (model, truth) per cycle, for `seconds` of gyro time at `rate_deg_h`.
fn model_and_truth(params: &GyroParams, rate_deg_h: f64, seconds: f64) -> (Vec<f64>, Vec<f64>) {
    let mut harness = HarnessOptions::new(*params, InputProfile::constant(rate_deg_h))
        .build()
        .unwrap();
    let omega_l = harness.gyro().derived().omega_l_rad_per_s;
    let (a, b) = (
        omega_l * (params.eps_rad + TAU / 8.0).cos(),
        omega_l * (params.eps_rad + TAU / 8.0).sin(),
    );
    // Firmware cycles: (closing latch, model); truth: phi at every turnaround, in time order.
    let mut cycles = Vec::new();
    let mut phi = std::collections::BTreeMap::new();
    harness.run_until(seconds, |h, half| {
        let t = half.latch_s();
        if let Some(record) = &half.record {
            if record.output.flags.is_empty() && t > 0.5 {
                let model = a * record.terms.p1_s as f64 + b * record.terms.p2_s as f64;
                cycles.push((t, model));
            }
        }
        for tr in h.take_traversals() {
            phi.insert(tr.turnaround.time_s.to_bits(), tr.turnaround.phi_rad);
        }
    });
    // The exact latch is the true turnaround: times match bit for bit.
    let times: Vec<u64> = phi.keys().copied().collect();
    let phis: Vec<f64> = phi.values().copied().collect();
    let smoothed =
        |centre: usize| 0.25 * (phis[centre - 1] + 2.0 * phis[centre] + phis[centre + 1]);
    let (mut model, mut truth) = (Vec::new(), Vec::new());
    for (end, m) in cycles {
        // The cycle closing at "+" turnaround e runs from the smoothed phi centred on e - 3 to
        // the one centred on e - 1.
        if let Ok(e) = times.binary_search(&end.to_bits()) {
            if e >= 4 {
                model.push(m);
                truth.push(smoothed(e - 1) - smoothed(e - 3));
            }
        }
    }
    (model, truth)
}

#[test]
fn p1_p2_explain_the_true_lockin_error_with_amplitude_jitter() {
    let params = GyroParams {
        amplitude_jitter: AmplitudeModulation::jitter(0.01),
        ..paper_gyro(21)
    };
    let (model, truth) = model_and_truth(&params, 10.0, 5.0);
    assert!(model.len() > 1500, "matched cycles: {}", model.len());
    let r = correlation(&model, &truth);
    let rms_truth = (truth.iter().map(|t| t * t).sum::<f64>() / truth.len() as f64).sqrt();
    let rms_resid = (model
        .iter()
        .zip(&truth)
        .map(|(m, t)| (m - t) * (m - t))
        .sum::<f64>()
        / truth.len() as f64)
        .sqrt();
    eprintln!(
        "{} cycles: correlation {r:.6}, rms truth {rms_truth:.3e} rad, rms residual {rms_resid:.3e} rad",
        model.len()
    );
    assert!(r >= 0.999, "correlation {r}");
    assert!(
        rms_resid < 0.01 * rms_truth,
        "rms residual {rms_resid:.3e} rad vs rms truth {rms_truth:.3e} rad"
    );
    let floor = noise_floor_rad(&params);
    eprintln!(
        "photodiode-noise floor {floor:.3e} rad: residual {:.2} x the floor",
        rms_resid / floor
    );
    assert!(
        rms_resid < 1.5 * floor,
        "regression: rms residual {rms_resid:.3e} rad vs noise floor {floor:.3e} rad"
    );
}

/// Per-cycle rms of a P1 + b P2 caused by the photodiode noise and the ADC quantisation at the
/// latches (module docs), rad.
fn noise_floor_rad(params: &GyroParams) -> f64 {
    let photodiodes = BoardConfig::for_gyro(params).photodiodes;
    let lsb_v = photodiodes.adc.lsb_v();
    let sigma_v = (photodiodes.noise_rms_v.powi(2) + lsb_v * lsb_v / 12.0).sqrt();
    let sigma = sigma_v / photodiodes.a.amplitude_v;
    let amplitude_rad = TAU * params.dither_amplitude_arcsec / params.scale_factor_arcsec;
    let w_d = TAU * params.dither_hz;
    let k_s = (TAU / (amplitude_rad * w_d * w_d)).sqrt();
    let omega_l = TAU * params.lock_in_deg_per_h / params.scale_factor_arcsec;
    let weights_rms = WEIGHTS.iter().map(|w| w * w).sum::<f64>().sqrt();
    omega_l * k_s * sigma * weights_rms
}
