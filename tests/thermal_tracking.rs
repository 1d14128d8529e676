//! Online tracking of a and b (`track on`) across temperature, with the default thermal
//! coefficients (`hal_sim::thermal`: Omega_L +1e-4 /°C, eps +5e-4 rad/°C, and the bias and
//! scale factor, which the thermal model takes care of and which are taken out of the errors
//! below so that what is left is the lock-in compensation's).
//!
//! 1. **Across a ramp**: the compensation exact at 25 °C, then the block ramps to 60 °C at
//!    0.5 °C/s (outside the dead band, Earth rate), then the input steps into the band (2
//!    deg/h) at 60 °C, where the compensation is what makes the output follow the input and
//!    where tracking is frozen. As `tracking_drift.rs`: the static readout is replayed the
//!    same half cycles as the tracked one.
//! 2. **The sweep at a temperature away from the calibration's**: coefficients exact at 25 °C,
//!    the paper's sweep (-6..+6 deg/h, 13 rates, the idealised board of `rlg-sim sweep
//!    --dither-drive ideal --latch exact`) at 55 °C, with the 25 °C coefficients (tracking
//!    off) and with the coefficients the tracker reached after 30 s at Earth rate at 55 °C
//!    (tracking on).
//!
//! Measured: see the printed lines (docs/physics.md section 13 gives them with this command:
//! `cargo test --release --test thermal_tracking -- --nocapture`).

mod common;

use common::{paper_gyro, static_and_tracked, TAU};
use firmware::calibration::tracking::{TrackingLoop, TrackingLoopConfig};
use firmware::signal::compensation::{Coefficients, CompensationSettings};
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::harness::HarnessOptions;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::thermal::ThermalCoefficients;
use rayon::prelude::*;
use rlg_sim::experiment::{measure_rate, BoardSetup, RunLength};

const EARTH_DEG_H: f64 = 13.888;
const INSIDE_DEG_H: f64 = 2.0;
/// A memory of 500 cycles (1.3 s), as `tracking_drift.rs`: the ramp is compressed in time.
const MEMORY_CYCLES: f64 = 500.0;

/// a and b of `params` at `temp_c` (Omega_L and eps moved by the thermal coefficients).
fn truth_at(params: &GyroParams, temp_c: f64) -> (f64, f64) {
    let c = ThermalCoefficients::DEFAULT;
    let x = temp_c - c.reference_c;
    let omega_l = params.derive().unwrap().omega_l_rad_per_s * (1.0 + c.lock_in_per_c * x);
    let eps = params.eps_rad + c.eps_rad_per_c * x;
    (
        omega_l * (eps + TAU / 8.0).cos(),
        omega_l * (eps + TAU / 8.0).sin(),
    )
}

fn settings(a: f64, b: f64) -> CompensationSettings {
    CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(a as f32, b as f32).unwrap(),
        enabled: true,
    }
}

/// The gyro's own thermal error at `temp_c` for `input_deg_h` (bias and scale factor, which
/// the thermal model corrects), deg/h.
fn thermal_error_deg_h(temp_c: f64, input_deg_h: f64) -> f64 {
    let c = ThermalCoefficients::DEFAULT;
    c.bias_deg_h(temp_c, 0.0) + input_deg_h * c.scale_factor_ppm(temp_c) * 1e-6
}

/// Scenario 1 (module docs): the tracked coefficients follow Omega_L and eps across the ramp
/// to within 1 % of Omega_L, and inside the band at 60 °C the tracked compensation's error is
/// below a third of the static one's. Measured: printed; regression bounds near it.
#[test]
fn tracking_holds_across_a_temperature_ramp() {
    let profile = TemperatureProfile::knots(&[(5.0, 25.0), (75.0, 60.0)]).unwrap();
    let params = paper_gyro(43).with_temperature(profile);
    let input = InputProfile::steps(EARTH_DEG_H, &[(80.0, INSIDE_DEG_H)]);
    let (a0, b0) = truth_at(&params, 25.0);
    let start = settings(a0, b0);
    let mut harness = HarnessOptions::new(params, input)
        .compensation(start)
        .build()
        .unwrap();
    let loop_config = TrackingLoopConfig::with_memory(MEMORY_CYCLES);
    let mut worst_during_ramp: f64 = 0.0;
    let run = static_and_tracked(
        &mut harness,
        start,
        &loop_config,
        params.scale_factor_arcsec,
        100.0,
        85.0,
        78.0,
        |t, tracking| {
            // Along the ramp (after the tracker's memory): the tracked coefficients against
            // the truth of the moment.
            if (10.0..75.0).contains(&t) {
                let (a, b) = tracking
                    .tracker()
                    .coefficients_rad_per_s(&loop_config.tracking);
                let (at, bt) = truth_at(&params, profile.at(t));
                let omega_l = at.hypot(bt);
                worst_during_ramp = worst_during_ramp.max((a - at).hypot(b - bt) / omega_l);
            }
        },
    );
    let (a_end, b_end) = truth_at(&params, 60.0);
    let omega_l = a_end.hypot(b_end);
    let (a_t, b_t) = run.tracked_at_snapshot;
    let tracked_coefficients = (a_t - a_end).hypot(b_t - b_end) / omega_l;
    let static_coefficients = (a0 - a_end).hypot(b0 - b_end) / omega_l;
    let thermal = thermal_error_deg_h(60.0, INSIDE_DEG_H);
    let static_err = (run.static_deg_h - INSIDE_DEG_H - thermal).abs();
    let tracked_err = (run.tracked_deg_h - INSIDE_DEG_H - thermal).abs();
    eprintln!(
        "ramp 25 -> 60 °C: coefficients off by {:.3} % of Omega_L tracked (worst along the ramp \
         {:.3} %), {:.3} % static; inside the band at 60 °C: error {tracked_err:.4} deg/h \
         tracked, {static_err:.4} static",
        100.0 * tracked_coefficients,
        100.0 * worst_during_ramp,
        100.0 * static_coefficients
    );
    assert!(tracked_coefficients < 0.01, "{tracked_coefficients}");
    assert!(worst_during_ramp < 0.01, "{worst_during_ramp}");
    assert!(static_coefficients > 0.015, "the ramp moves the truth");
    assert!(
        tracked_err < static_err / 3.0,
        "{tracked_err} vs {static_err}"
    );
    // Regression, near the measured 0.023 %, 0.081 % and 0.0003 deg/h.
    assert!(tracked_coefficients < 0.001 && worst_during_ramp < 0.003);
    assert!(tracked_err < 0.003, "{tracked_err}");
}

/// Scenario 2 (module docs): the sweep's worst compensated error at 55 °C, with the 25 °C
/// coefficients and with the tracked ones; the tracked sweep within a third of the static
/// one's worst error. Measured: printed; docs/physics.md section 13.
#[test]
fn the_sweep_away_from_the_calibration_temperature_with_tracking_on_and_off() {
    let hot = 55.0;
    let params = paper_gyro(44).with_temperature(TemperatureProfile::constant(hot));
    let (a0, b0) = truth_at(&params, 25.0);
    // Tracking on: 30 s at Earth rate at 55 °C from the 25 °C coefficients.
    let start = settings(a0, b0);
    let mut harness = HarnessOptions::new(params, InputProfile::constant(EARTH_DEG_H))
        .compensation(start)
        .build()
        .unwrap();
    let config = *harness.config();
    let loop_config = TrackingLoopConfig::with_memory(MEMORY_CYCLES);
    let mut tracking = TrackingLoop::new(&loop_config, start.coefficients);
    harness.run_until(30.0, |h, half| {
        if let Some(c) = &half.record {
            if let Some(coefficients) =
                tracking.on_cycle(&loop_config, c, c.duration_s(&config.cycle))
            {
                h.readout_mut().stage_compensation(CompensationSettings {
                    coefficients,
                    enabled: true,
                });
            }
        }
    });
    let (at, bt) = tracking
        .tracker()
        .coefficients_rad_per_s(&loop_config.tracking);
    let tracked = settings(at, bt);
    let rates: Vec<f64> = (0..13).map(|i| -6.0 + i as f64).collect();
    let length = RunLength {
        warmup_s: 0.5,
        record_s: 8.0,
    };
    let cases: Vec<(bool, f64)> = [false, true]
        .iter()
        .flat_map(|&on| rates.iter().map(move |&r| (on, r)))
        .collect();
    let errors: Vec<(bool, f64, f64)> = cases
        .par_iter()
        .map(|&(on, rate)| {
            let s = if on { tracked } else { start };
            let m = measure_rate(&params, BoardSetup::IDEAL, rate, length, s).unwrap();
            let out = m.compensated_hz * params.scale_factor_arcsec;
            (on, rate, out - rate - thermal_error_deg_h(hot, rate))
        })
        .collect();
    let worst = |on: bool| {
        errors
            .iter()
            .filter(|e| e.0 == on)
            .map(|e| e.2.abs())
            .fold(0.0, f64::max)
    };
    let (off, on) = (worst(false), worst(true));
    let per_rate: Vec<String> = errors
        .iter()
        .map(|(on, rate, e)| format!("{}{rate}: {e:+.4}", if *on { "on " } else { "off " }))
        .collect();
    eprintln!(
        "sweep -6..6 deg/h at {hot} °C, coefficients exact at 25 °C: worst compensated error \
         {off:.4} deg/h with tracking off, {on:.4} deg/h with the tracked coefficients; per \
         rate: {}",
        per_rate.join(", ")
    );
    assert!(on < off / 3.0, "{on} vs {off}");
    // Regression, near the measured 0.0511 and 0.0007 deg/h.
    assert!(off > 0.03 && on < 0.003, "{off} {on}");
}
