//! Temperature on the simulated gyro with the firmware in the loop: the gyro's bias (with its
//! dT/dt term), scale factor, Omega_L, eps and pick-off gain follow a -20..+60 °C profile with
//! the default coefficients (`hal_sim::thermal`), the board reads its TMP117 through the
//! firmware's driver (`firmware::thermal`), the thermal calibration fits the model on one
//! profile, and the board applies it on another: IEEE Std 647's bias and scale factor over
//! temperature, model off and on (`rlg_sim::thermal::procedure`, the one `rlg-sim characterize
//! --thermal` reports). docs/physics.md section 13 gives the figures and the command that prints
//! them (`cargo test --release --test thermal -- --nocapture`).
//!
//! The board here: the latch scheduled from the pick-off, the 1 kHz output, the prescribed
//! sine dither, the lock-in compensation from the gyro's a and b at 25 °C (the calibration is
//! `precision.rs`'s subject), the Earth-rate input of the paper's table (+13.888 deg/h) for the
//! bias.

use firmware::signal::compensation::{Coefficients, CompensationSettings};
use firmware::signal::output::record::OutputStatus;
use firmware::thermal::model::ThermalModel;
use hal_sim::board::LatchTiming;
use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::harness::{Harness, HarnessOptions};
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::random_gyro::RandomGyro;
use hal_sim::tmp117::SensorFault;
use rayon::prelude::*;
use rlg_sim::experiment::{BoardSetup, DitherDrive, Latch};
use rlg_sim::thermal::procedure::{run, ThermalPlan};
use std::f64::consts::{FRAC_PI_4, TAU};

fn compensation(params: &GyroParams) -> CompensationSettings {
    let omega_l = TAU * params.lock_in_deg_per_h / params.scale_factor_arcsec;
    let (a, b) = (
        omega_l * (params.eps_rad + FRAC_PI_4).cos(),
        omega_l * (params.eps_rad + FRAC_PI_4).sin(),
    );
    CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(a as f32, b as f32).unwrap(),
        enabled: true,
    }
}

fn setup(gyro: &RandomGyro) -> BoardSetup {
    BoardSetup {
        drive: DitherDrive::Ideal,
        latch: Latch::Scheduled,
        sync_hz: Some(1000.0),
        pickoff_gain_error: gyro.pickoff_gain_error,
        pickoff_lag_s: gyro.pickoff_lag_us * 1e-6,
    }
}

fn harness(gyro: &RandomGyro, profile: TemperatureProfile, input: InputProfile) -> Harness {
    let params = gyro.params.with_temperature(profile);
    let mut options = HarnessOptions::new(params, input)
        .latch(LatchTiming::scheduled(0.0))
        .sync_hz(Some(1000.0))
        .compensation(compensation(&params));
    options.board.pickoff.gain_error = gyro.pickoff_gain_error;
    options.board.pickoff.lag_s = gyro.pickoff_lag_us * 1e-6;
    options.build().unwrap()
}

/// The acceptance on the docs/physics.md gyro and on two random gyros, calibrated on ramps at
/// +-2 °C/s and checked elsewhere: over a -20 to +60 °C ramp at 0.5 °C/s the bias residual with
/// the model (rms of every 5 s window) at least 10x smaller than without it, and the scale
/// factor within 10 ppm at eight soaks away from the calibration's temperatures, where without
/// the model it is off by more than 10 ppm. Measured (the printed lines; docs/physics.md
/// section 13): ramp 0.0723 -> 0.0030-0.0032 deg/h (23-24x; 267-345x clear of the ramp's
/// start, where the board's rate estimate lags), soaks' bias 0.077 -> 0.0005 deg/h, scale
/// factor 19.5 -> 0.04 ppm. Regression bounds near them: 18x (150x clear), 0.002 deg/h,
/// 0.2 ppm.
#[test]
fn the_thermal_model_takes_out_bias_and_scale_factor_over_temperature() {
    let gyros: Vec<(u64, RandomGyro)> = std::iter::once((
        0,
        RandomGyro {
            params: GyroParams::default(),
            pickoff_gain_error: 0.0,
            pickoff_lag_us: 0.0,
        },
    ))
    .chain((1..=2).map(|s| (s, RandomGyro::draw(s))))
    .collect();
    let plan = ThermalPlan::default_plan();
    let outcomes: Vec<_> = gyros
        .par_iter()
        .map(|(seed, g)| {
            let o = run(&g.params, setup(g), compensation(&g.params), &plan).unwrap();
            (*seed, o)
        })
        .collect();
    for (seed, o) in outcomes {
        let r = &o.ramp;
        let worst = |f: fn(&rlg_sim::thermal::procedure::SoakCheck) -> f64| {
            o.soaks.iter().map(f).map(f64::abs).fold(0.0, f64::max)
        };
        let (sf_raw, sf_comp) = (
            worst(|s| s.scale_factor_raw_ppm),
            worst(|s| s.scale_factor_compensated_ppm),
        );
        let (bias_raw, bias_comp) = (
            worst(|s| s.bias_raw_deg_h),
            worst(|s| s.bias_compensated_deg_h),
        );
        eprintln!(
            "gyro {seed}: ramp bias rms clear of its start raw {:.5} / with model {:.5} deg/h \
             (ratio {:.1}; every window: {:.5} / {:.5}, ratio {:.1}); soaks: bias worst raw {bias_raw:.4} / with \
             model {bias_comp:.4} deg/h, SF worst raw {sf_raw:.2} / with model {sf_comp:.2} ppm; \
             model {:?}",
            r.raw_rms_deg_h,
            r.corrected_rms_deg_h,
            r.raw_rms_deg_h / r.corrected_rms_deg_h,
            r.raw_rms_all_deg_h,
            r.corrected_rms_all_deg_h,
            r.raw_rms_all_deg_h / r.corrected_rms_all_deg_h,
            o.calibration.model
        );
        assert!(
            r.corrected_throughout,
            "gyro {seed}: the model was applied throughout"
        );
        let all = r.raw_rms_all_deg_h / r.corrected_rms_all_deg_h;
        assert!(all >= 10.0, "gyro {seed}: {o:?}");
        assert!(all >= 18.0, "gyro {seed}: regression {all}");
        assert!(
            r.raw_rms_deg_h >= 150.0 * r.corrected_rms_deg_h,
            "gyro {seed}: regression"
        );
        assert!(sf_comp <= 10.0, "gyro {seed}: {o:?}");
        assert!(sf_comp <= 0.2, "gyro {seed}: regression {sf_comp}");
        assert!(
            sf_raw > 10.0,
            "gyro {seed}: the test has something to correct"
        );
        assert!(bias_comp < 0.002 && bias_raw > 0.05, "gyro {seed}: {o:?}");
    }
}

/// A sensor fault (NACK, stuck bus, frozen conversion, stuck code) shows in every output
/// record within its stated time (`firmware::thermal::sensor`: 100 ms, 100 ms, 425 ms, 8.1 s
/// plus one 50 ms poll), and the model is not applied meanwhile; the records stay valid.
#[test]
fn a_sensor_fault_shows_in_the_records_and_stops_the_correction() {
    let model = ThermalModel {
        reference_c: 25.0,
        min_c: -40.0,
        max_c: 80.0,
        bias_deg_h: [0.01, 0.0, 0.0, 0.0],
        bias_deg_h_per_c_per_min: 0.0,
        scale_ppm: [0.0; 3],
    };
    let faults = [
        (SensorFault::Nack, 0.15),
        (SensorFault::StuckBus, 0.15),
        (SensorFault::Frozen, 0.475),
        (SensorFault::StuckCode, 8.15),
    ];
    let results: Vec<_> = faults
        .par_iter()
        .map(|&(fault, within_s)| {
            let gyro = RandomGyro {
                params: GyroParams::default(),
                pickoff_gain_error: 0.0,
                pickoff_lag_us: 0.0,
            };
            let profile = TemperatureProfile::constant(30.0);
            let mut h = harness(&gyro, profile, InputProfile::constant(13.888));
            h.set_thermal_model(Some(model));
            h.run_until(3.0, |_, _| {});
            let before = h.outputs().last().unwrap().1;
            let fault_s = h.time_s();
            h.sensor_mut().set_fault(Some(fault));
            let mut first_fault = None;
            let mut after = Vec::new();
            h.run_until(fault_s + 10.0, |h, _| {
                for (latch, r) in h.outputs() {
                    if r.status.contains(OutputStatus::THERMAL_SENSOR_FAULT) {
                        first_fault.get_or_insert(latch.t_s);
                        after.push(*r);
                    }
                }
            });
            (
                fault,
                within_s,
                before,
                first_fault.map(|t| t - fault_s),
                after,
            )
        })
        .collect();
    for (fault, within_s, before, latency, after) in results {
        eprintln!("{fault:?}: in the records after {latency:?} s");
        assert!(before.status.contains(OutputStatus::THERMAL_CORRECTED));
        let latency = latency.expect("the fault shows");
        assert!(latency <= within_s, "{fault:?}: {latency} s");
        assert!(after
            .iter()
            .all(|r| !r.status.contains(OutputStatus::THERMAL_CORRECTED)
                && r.temperature_c().is_none()
                && r.is_valid()));
    }
}
