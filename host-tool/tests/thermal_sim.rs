//! `rlg-cal thermal` against the simulated board in this process: the block goes through a
//! chamber's run (ramps -20..+60 °C at 2 °C/s with holds, then five soaks with the rate table
//! at +-10 deg/s) with the default thermal coefficients; the tool records the board's output and
//! temperatures through the protocol, fits the model, puts it in force and stores it; after a
//! power cycle the board has it again.

use hal_sim::dither::resonator::TemperatureProfile;
use hal_sim::flash::CalibrationFlash;
use hal_sim::input::InputProfile;
use hal_sim::params::GyroParams;
use hal_sim::thermal::ThermalCoefficients;
use rlg_cal::client::Client;
use rlg_cal::link::SimLink;
use rlg_cal::ops;
use rlg_cal::sim::{self, key_hex, test_key};
use rlg_cal::thermal::{apply_model, fit_log, record_log, ThermalOptions};
use std::f64::consts::{FRAC_PI_4, TAU};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

const EARTH_DEG_H: f64 = 13.888;
const TABLE_DEG_H: f64 = 36_000.0;
/// The chamber's run starts this long after power-up (the drive locks first), s.
const LEAD_S: f64 = 8.0;
const SOAKS_C: [f64; 5] = [-20.0, 0.0, 20.0, 40.0, 60.0];
/// One soak: 2 s transition, 5 s at rest, +R 2.5 s, -R 2.5 s, s.
const SOAK_S: f64 = 12.0;

/// The run: ramps, then the soaks; the input at rest is Earth rate, the table's steps on top.
fn chamber() -> (TemperatureProfile, InputProfile, f64) {
    let mut knots: Vec<(f64, f64)> = [
        (2.0, -20.0),
        (4.0, -20.0),
        (44.0, 60.0),
        (46.0, 60.0),
        (86.0, -20.0),
    ]
    .iter()
    .map(|&(t, c)| (LEAD_S + t, c))
    .collect();
    let soaks_from = LEAD_S + 90.0;
    let mut steps = Vec::new();
    for (i, &level) in SOAKS_C.iter().enumerate() {
        let start = soaks_from + SOAK_S * i as f64;
        if i > 0 {
            knots.push((start, SOAKS_C[i - 1]));
            knots.push((start + 2.0, level));
        }
        steps.push((start + 7.0, EARTH_DEG_H + TABLE_DEG_H));
        steps.push((start + 9.5, EARTH_DEG_H - TABLE_DEG_H));
        steps.push((start + 12.0, EARTH_DEG_H));
    }
    let end = soaks_from + SOAK_S * SOAKS_C.len() as f64;
    (
        TemperatureProfile::knots(&knots).unwrap(),
        InputProfile::steps(EARTH_DEG_H, &steps),
        end,
    )
}

/// The tool's calibration on the simulated board (compensation at the gyro's true a and b, as
/// after `rlg-cal calibrate`): the fitted bias within 0.003 deg/h of the simulated gyro's over
/// -20..+60 °C at rest, the rate term within 3 %, the scale factor within 0.2 ppm (measured:
/// printed); put in force exactly, stored, and back after a power cycle.
#[test]
fn thermal_calibrates_applies_and_stores_on_the_simulated_board() {
    let (profile, input, end_s) = chamber();
    let params = GyroParams::default().with_temperature(profile);
    let device = sim::boot_gyro(
        params,
        input,
        CalibrationFlash::default(),
        0,
        Some(test_key()),
    )
    .unwrap();
    let mut client = Client::new(SimLink::new(device));
    let key = key_hex(&test_key());
    ops::unlock(&mut client, &key).unwrap();
    let omega_l = TAU * params.lock_in_deg_per_h / params.scale_factor_arcsec;
    let (a, b) = (
        omega_l * (params.eps_rad + FRAC_PI_4).cos(),
        omega_l * (params.eps_rad + FRAC_PI_4).sin(),
    );
    for line in [format!("set a {a}"), format!("set b {b}"), "comp on".into()] {
        client.command(&line).unwrap();
    }
    client
        .pause(Duration::from_secs_f64(
            LEAD_S - client.elapsed().as_secs_f64(),
        ))
        .unwrap();
    let stop = AtomicBool::new(false);
    let duration = Duration::from_secs_f64(end_s - LEAD_S);
    let (log, bad) = record_log(&mut client, duration, &mut |_| {}, &stop).unwrap();
    assert_eq!((log.lost, bad), (0, 0));
    let options = ThermalOptions {
        input_rate_deg_h: EARTH_DEG_H,
        table_rate_deg_h: Some(TABLE_DEG_H),
        reference_c: 25.0,
    };
    let fit = fit_log(log.records(), &options).unwrap();
    let m = fit.model;
    let truth = ThermalCoefficients::DEFAULT;
    let worst_bias = (-20..=60)
        .map(|t| (f64::from(m.bias_deg_h(t as f32, 0.0)) - truth.bias_deg_h(t as f64, 0.0)).abs())
        .fold(0.0, f64::max);
    let worst_sf = (-20..=60)
        .map(|t| (f64::from(m.scale_ppm(t as f32)) - truth.scale_factor_ppm(t as f64)).abs())
        .fold(0.0, f64::max);
    let rate_term = f64::from(m.bias_deg_h_per_c_per_min) / truth.bias_deg_h_per_c_per_min;
    eprintln!(
        "records {} (bias {}), scale points {}, worst bias {worst_bias:.5} deg/h, worst SF \
         {worst_sf:.3} ppm, rate term {rate_term:.4} of the truth; model {m:?}",
        fit.records,
        fit.bias_records,
        fit.scale_points.len()
    );
    assert_eq!(fit.scale_points.len(), 5, "{:?}", fit.scale_points);
    assert!(worst_bias < 0.003, "{worst_bias}");
    assert!(worst_sf < 0.2, "{worst_sf}");
    assert!((rate_term - 1.0).abs() < 0.03, "{rate_term}");

    let answer = apply_model(&mut client, &m).unwrap();
    assert!(answer.text.starts_with("thermal=on "), "{}", answer.text);
    client.pause(Duration::from_millis(500)).unwrap();
    let thermal = client.command("thermal").unwrap();
    assert_eq!(thermal.field("model"), Some("applied"), "{}", thermal.text);
    assert!(client
        .command("store")
        .unwrap()
        .text
        .starts_with("stored seq=1"));

    // A power cycle: the stored model is in force again, switched on.
    let flash = client.into_link().into_device().power_off();
    let device =
        sim::boot_gyro(params, InputProfile::constant(EARTH_DEG_H), flash, 1, None).unwrap();
    let mut client = Client::new(SimLink::new(device));
    let after = client.command("thermal model").unwrap();
    assert_eq!(
        after.text.split(" model=").next(),
        answer.text.split(" model=").next(),
        "the same model, on"
    );
}
