//! Online tracking of a and b (issue 5, beyond the paper) against a static calibration, on the
//! simulated gyro with a drifting lock-in threshold Omega_L and photodiode phase offset eps.
//!
//! Scenario (seeded, noise-free): 60 s outside the dead band (13.888 deg/h) while Omega_L
//! drifts by +5 % and eps by 0.15 rad (thermal drift, compressed in time), then 20 s inside it
//! (2 deg/h), where the
//! compensation is what makes the output follow the input at all and where tracking is frozen.
//! Both readouts start from the exact coefficients at t = 0 and see the same simulated board
//! (hal-sim's harness runs the tracked one; the static one is replayed the same half cycles).
//! Acceptance: inside the band the tracked compensation's error is well below the static
//! one's, and the tracked coefficients end within 1 % of Omega_L of the drifted truth.
//!
//! Regression bound (issue 11): "well below" (a third of the static error, 0.18 deg/h) is 16
//! times what tracking achieves, so the tracked error is also bounded at 0.03 deg/h. Measured
//! over eight seeds (41..=48; the seed changes the photodiode noise): tracked 0.0101 to
//! 0.0114 deg/h, static 0.530 deg/h, tracked coefficients 0.32 % to 0.36 % of Omega_L off
//! (bound 1 %, already within three times the measured value).

mod common;

use common::{paper_gyro, static_and_tracked, TAU};
use firmware::calibration::tracking::TrackingLoopConfig;
use firmware::signal::compensation::{Coefficients, CompensationSettings};
use hal_sim::harness::HarnessOptions;
use hal_sim::input::InputProfile;
use hal_sim::params::AmplitudeModulation;

const DRIFT_END_S: f64 = 60.0;
const EPS_DRIFT_RAD: f64 = 0.15;
const LOCK_IN_DRIFT: f64 = 0.05;
const INSIDE_DEG_H: f64 = 2.0;
const MEASURE_FROM_S: f64 = 65.0;
const END_S: f64 = 80.0;

/// What one run of the scenario gave.
struct Outcome {
    /// |compensated rate - input| inside the band, deg/h: static and tracked.
    static_err_deg_h: f64,
    tracked_err_deg_h: f64,
    /// The tracked coefficients at the end of the drift against the drifted truth, over Omega_L.
    coefficient_error: f64,
}

#[test]
fn tracking_beats_a_static_fit_when_lock_in_and_eps_drift() {
    let o = scenario(AmplitudeModulation::OFF);
    assert!(
        o.coefficient_error < 0.01,
        "tracked coefficients {}",
        o.coefficient_error
    );
    assert!(
        o.tracked_err_deg_h < o.static_err_deg_h / 3.0,
        "tracked {} vs static {}",
        o.tracked_err_deg_h,
        o.static_err_deg_h
    );
    assert!(
        o.tracked_err_deg_h < 0.03,
        "regression: tracked error {} deg/h",
        o.tracked_err_deg_h
    );
}

/// The same with the dither amplitude wandering 0.1 % rms at 0.1-2 Hz: the tracker sees the
/// cycle increments the calibration does (docs/physics.md section 8), which a wandering
/// amplitude does not move, so it tracks as well as with a steady dither: the coefficients
/// within 1 % of Omega_L of the drifted truth and the error inside the band within 0.03 deg/h,
/// as above. Measured (seed 41): coefficients 0.42 % off (0.34 % with a steady dither), error
/// 0.004 deg/h (0.011); regression bound 0.6 %.
#[test]
fn tracking_holds_under_a_wandering_dither() {
    let o = scenario(AmplitudeModulation::jitter(0.001));
    assert!(
        o.coefficient_error < 0.01,
        "tracked coefficients {}",
        o.coefficient_error
    );
    assert!(
        o.coefficient_error < 0.006,
        "regression: tracked coefficients {}",
        o.coefficient_error
    );
    assert!(
        o.tracked_err_deg_h < 0.03,
        "tracked error {} deg/h",
        o.tracked_err_deg_h
    );
}

/// The scenario of the module docs with `jitter` on the dither's amplitude.
fn scenario(jitter: AmplitudeModulation) -> Outcome {
    let params = hal_sim::params::GyroParams {
        lock_in_drift_per_s: LOCK_IN_DRIFT / DRIFT_END_S,
        lock_in_drift_until_s: DRIFT_END_S,
        amplitude_jitter: jitter,
        ..paper_gyro(41)
    };
    let input = InputProfile::steps(13.888, &[(DRIFT_END_S, INSIDE_DEG_H)]);
    let omega_l = params.derive().unwrap().omega_l_rad_per_s;
    let truth = |omega_l: f64, eps: f64| {
        (
            omega_l * (eps + TAU / 8.0).cos(),
            omega_l * (eps + TAU / 8.0).sin(),
        )
    };
    let (a0, b0) = truth(omega_l, params.eps_rad);
    let start = CompensationSettings {
        coefficients: Coefficients::from_rad_per_s(a0 as f32, b0 as f32).unwrap(),
        enabled: true,
    };
    // The harness's own readout is the tracked one; the static one is fed the same half cycles
    // (`replay_into`). The latch is exact, so the board does not depend on which one it follows.
    let mut options = HarnessOptions::new(params, input).compensation(start);
    options.board.eps_drift_rad_per_s = EPS_DRIFT_RAD / DRIFT_END_S;
    options.board.eps_drift_until_s = DRIFT_END_S;
    let mut harness = options.build().unwrap();
    // A memory of 500 cycles (1.3 s): this test compresses hours of drift into 60 s; the lag is
    // memory x drift per cycle (2.2 rad/s), the estimation noise about as much.
    let loop_config = TrackingLoopConfig::with_memory(500.0);
    let run = static_and_tracked(
        &mut harness,
        start,
        &loop_config,
        params.scale_factor_arcsec,
        END_S,
        MEASURE_FROM_S,
        DRIFT_END_S,
        |_, _| {},
    );

    let (a_end, b_end) = truth(
        omega_l * (1.0 + LOCK_IN_DRIFT),
        params.eps_rad + EPS_DRIFT_RAD,
    );
    let (a_t, b_t) = run.tracked_at_snapshot;
    let coefficient_error = (a_t - a_end).hypot(b_t - b_end) / omega_l;
    let fixed_err = (run.static_deg_h - INSIDE_DEG_H).abs();
    let tracked_err = (run.tracked_deg_h - INSIDE_DEG_H).abs();
    eprintln!(
        "jitter {:?}: inside the band: static error {fixed_err:.4} deg/h, tracked \
         {tracked_err:.4} deg/h; tracked coefficients off by {:.3} % of Omega_L (static: {:.1} %)",
        jitter.relative_rms,
        100.0 * coefficient_error,
        100.0 * (a0 - a_end).hypot(b0 - b_end) / omega_l
    );
    Outcome {
        static_err_deg_h: fixed_err,
        tracked_err_deg_h: tracked_err,
        coefficient_error,
    }
}
