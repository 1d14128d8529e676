//! Shared helpers of the system tests: the docs/physics.md gyro and unit conversions.
#![allow(dead_code)]

use firmware::calibration::validation::chow_dead_band_rad_per_s;
use hal_sim::params::GyroParams;
use hal_sim::units::{
    arcsec_to_beat_rad, beat_rad_per_s_to_deg_per_h, deg_per_h_to_beat_rad_per_s,
};

pub const TAU: f64 = std::f64::consts::TAU;

/// The docs/physics.md parameter set (the paper's gyro), noise-free, seeded.
pub fn paper_gyro(seed: u64) -> GyroParams {
    GyroParams {
        seed,
        ..GyroParams::default()
    }
}

/// deg/h of input -> Hz of beat (fringes/s).
pub fn deg_h_to_hz(rate_deg_h: f64, params: &GyroParams) -> f64 {
    rate_deg_h / params.scale_factor_arcsec
}

/// Chow's dynamic dead band Omega_L |J0(A)| in deg/h (the firmware's function, A = dither
/// amplitude in beat-phase rad).
pub fn chow_dead_band_deg_h(params: &GyroParams) -> f64 {
    let sf = params.scale_factor_arcsec;
    let band_rad_per_s = chow_dead_band_rad_per_s(
        deg_per_h_to_beat_rad_per_s(params.lock_in_deg_per_h, sf),
        arcsec_to_beat_rad(params.dither_amplitude_arcsec, sf),
    );
    beat_rad_per_s_to_deg_per_h(band_rad_per_s, sf)
}

/// `rlg-sim sweep` on `params` and `setup` over `rates_deg_h`: the calibration as the CLI's
/// (+-13.888 deg/h, 20 s each after 0.5 s of warm-up, the fit rounded to the flash format),
/// then every rate for `seconds` (in parallel). Returns the fit and the worst |board output -
/// input| in deg/h; every output record of the runs must be valid.
pub fn sweep_worst_deg_h(
    params: &GyroParams,
    setup: rlg_sim::experiment::BoardSetup,
    rates_deg_h: &[f64],
    seconds: f64,
) -> (firmware::calibration::fit::FitResult, f64) {
    use rayon::prelude::*;
    use rlg_sim::experiment::{calibrate, measure_rate, settings_from_fit, RunLength};
    let warmup_s = 0.5;
    let fit = calibrate(
        params,
        setup,
        &[-13.888, 13.888],
        RunLength {
            warmup_s,
            record_s: 20.0,
        },
    )
    .expect("calibration");
    let settings = settings_from_fit(&fit).expect("coefficients");
    let sf = params.scale_factor_arcsec;
    let worst = rates_deg_h
        .par_iter()
        .map(|&rate| {
            let length = RunLength {
                warmup_s,
                record_s: seconds,
            };
            let m = measure_rate(params, setup, rate, length, settings).expect("run");
            assert_eq!(m.invalid_records, 0, "{rate} deg/h");
            (m.board_output_hz() * sf - rate).abs()
        })
        .reduce(|| 0.0, f64::max);
    (fit, worst)
}

/// Amplitude of the best-fitting sine near `f_hz` (+-1 Hz, 0.01 Hz steps) in a series sampled
/// at `rate_hz`: the dither tone of an output.
pub fn tone_amplitude(series: &[f64], rate_hz: f64, f_hz: f64) -> f64 {
    let mean = series.iter().sum::<f64>() / series.len() as f64;
    (-100..=100)
        .map(|k| {
            let f = f_hz + 0.01 * k as f64;
            let (mut c, mut s) = (0.0, 0.0);
            for (i, x) in series.iter().enumerate() {
                let ph = std::f64::consts::TAU * f * i as f64 / rate_hz;
                c += (x - mean) * ph.cos();
                s += (x - mean) * ph.sin();
            }
            2.0 * (c * c + s * s).sqrt() / series.len() as f64
        })
        .fold(0.0, f64::max)
}

/// What [`static_and_tracked`] measures.
pub struct StaticAndTracked {
    /// The static compensation's rate over the measurement, deg/h.
    pub static_deg_h: f64,
    /// The tracked compensation's rate over the measurement, deg/h.
    pub tracked_deg_h: f64,
    /// The tracked coefficients (a, b), rad/s, at the first latch from `snapshot_s` on.
    pub tracked_at_snapshot: (f64, f64),
}

/// Runs `harness` to `end_s` with two compensations of the same half cycles: a static one (a
/// [`firmware::readout::Readout`] started with `start`, fed by `replay_into`) and the
/// harness's own readout, whose coefficients the tracking loop stages at every cycle. Both
/// rates are averaged over whole periods from `measure_from_s` on. `each_tracked_cycle` sees
/// every closed cycle's latch time and the loop after it.
#[allow(clippy::too_many_arguments)]
pub fn static_and_tracked(
    harness: &mut hal_sim::harness::Harness,
    start: firmware::signal::compensation::CompensationSettings,
    loop_config: &firmware::calibration::tracking::TrackingLoopConfig,
    scale_factor_arcsec: f64,
    end_s: f64,
    measure_from_s: f64,
    snapshot_s: f64,
    mut each_tracked_cycle: impl FnMut(f64, &firmware::calibration::tracking::TrackingLoop),
) -> StaticAndTracked {
    use firmware::calibration::tracking::TrackingLoop;
    use firmware::readout::Readout;
    use firmware::signal::compensation::CompensationSettings;
    use firmware::signal::output::{AveragerConfig, AveragingMode, RateAverager};
    let config = *harness.config();
    let mut fixed = Readout::new(&config, start);
    let mut tracking = TrackingLoop::new(loop_config, start.coefficients);
    let averager = AveragerConfig {
        window_cycles: u32::MAX,
        mode: AveragingMode::WholePeriods,
        timer_hz: harness.board().config().timer_hz,
        scale_factor_arcsec,
    };
    let (mut fixed_rate, mut tracked_rate) = (RateAverager::new(), RateAverager::new());
    let mut tracked_at_snapshot = None;
    harness.run_until(end_s, |h, half| {
        let t = half.latch_s();
        let measuring = t > measure_from_s;
        if let Some(c) = h.replay_into(&mut fixed) {
            if measuring {
                fixed_rate.push(&averager, c.output);
            }
        }
        if let Some(c) = &half.record {
            if let Some(coefficients) =
                tracking.on_cycle(loop_config, c, c.duration_s(&config.cycle))
            {
                h.readout_mut().stage_compensation(CompensationSettings {
                    coefficients,
                    enabled: true,
                });
            }
            if measuring {
                tracked_rate.push(&averager, c.output);
            }
            each_tracked_cycle(t, &tracking);
        }
        if tracked_at_snapshot.is_none() && t >= snapshot_s {
            tracked_at_snapshot = Some(
                tracking
                    .tracker()
                    .coefficients_rad_per_s(&loop_config.tracking),
            );
        }
    });
    StaticAndTracked {
        static_deg_h: fixed_rate.flush(&averager).rate_deg_per_h,
        tracked_deg_h: tracked_rate.flush(&averager).rate_deg_per_h,
        tracked_at_snapshot: tracked_at_snapshot.expect("the run reaches the snapshot"),
    }
}
