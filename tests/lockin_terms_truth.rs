//! P1 and P2 as the firmware forms them, against the simulator's true lock-in error of each
//! dither cycle (issue 4 acceptance), with dither amplitude jitter on.
//!
//! A steady sine dither hides a wrong sign pattern of P1/P2 (PHYSICS.md pitfall 4: a reflected
//! psi_H, the misprinted Eq. 19): the turnaround phases then repeat in a way that a wrong model
//! can still fit. With the amplitude jittering, the turnaround phases decorrelate, and only the
//! correct Eq. 18 explains the truth.
//!
//! Truth: the lock-in phase phi = psi - theta at each turnaround (hal-sim); its change from one
//! "+" turnaround to the next is exactly the lock-in error of the firmware's cycle, latch split
//! included. Model: a P1 + b P2 with the true a = Omega_L cos(eps + pi/4), b = Omega_L
//! sin(eps + pi/4). Acceptance: correlation >= 0.999.

mod common;

use common::{paper_gyro, TAU};
use firmware::readout::{Readout, ReadoutConfig};
use firmware::sample::TurnaroundKind;
use firmware::signal::compensation::CompensationSettings;
use hal_sim::board::{BoardConfig, SimBoard};
use hal_sim::gyro::Gyro;
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

/// (model, truth) per cycle, for `seconds` of gyro time at `rate_deg_h`.
fn model_and_truth(params: &GyroParams, rate_deg_h: f64, seconds: f64) -> (Vec<f64>, Vec<f64>) {
    let gyro = Gyro::new(*params, InputProfile::constant(rate_deg_h)).unwrap();
    let board_config = BoardConfig::for_gyro(params);
    let mut board = SimBoard::new(gyro, board_config.clone()).unwrap();
    let config = ReadoutConfig::for_board(
        board_config.timer_hz,
        params.dither_hz,
        params.scale_factor_arcsec,
    );
    let mut readout = Readout::new(&config, CompensationSettings::default());
    let omega_l = board.gyro().derived().omega_l_rad_per_s;
    let (a, b) = (
        omega_l * (params.eps_rad + TAU / 8.0).cos(),
        omega_l * (params.eps_rad + TAU / 8.0).sin(),
    );
    // Firmware cycles: (start time, end time, model); truth: phi at each "+" turnaround.
    let mut cycles = Vec::new();
    let mut plus_phi = std::collections::BTreeMap::new();
    let mut lissajous = Vec::new();
    let mut last_plus_s = None;
    while board.time_s() < seconds {
        let sample = board.next_half_cycle(&mut lissajous);
        for &(a_code, b_code) in &lissajous {
            readout.on_lissajous_sample(&config, a_code, b_code);
        }
        let t = board.time_s();
        if let Some(record) = readout.on_turnaround(&config, sample) {
            if record.output.flags.is_empty() && t > 0.5 {
                let model = a * record.terms.p1_s as f64 + b * record.terms.p2_s as f64;
                cycles.push((last_plus_s.unwrap(), t, model));
            }
        }
        if sample.kind == TurnaroundKind::Plus {
            last_plus_s = Some(t);
        }
        for tr in board.take_traversals() {
            if tr.turnaround.kind == TurnaroundKind::Plus {
                plus_phi.insert(tr.turnaround.time_s.to_bits(), tr.turnaround.phi_rad);
            }
        }
    }
    let (mut model, mut truth) = (Vec::new(), Vec::new());
    for (start, end, m) in cycles {
        if let (Some(p0), Some(p1)) = (plus_phi.get(&start.to_bits()), plus_phi.get(&end.to_bits()))
        {
            model.push(m);
            truth.push(p1 - p0);
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
}
